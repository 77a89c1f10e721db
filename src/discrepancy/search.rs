//! Where could each hypothesis act? Every candidate location is fitted (MAP, from the
//! nominal fit plus a Latin hypercube over the effect's own box) and the best is kept.
//!
//! Within one hypothesis every location has the same parameters and priors of the same
//! width, so locations are ranked by their maximum log-likelihood. Hypotheses acting on
//! channels may act on any set of them: starting from the best single channel or
//! quantity, channels are added one at a time (greedy forward selection) while the
//! maximum log-likelihood rises by more than `ln C` per added channel, `C` the number of
//! channels: the log prior odds of one particular channel joining the set when every
//! subset size is equally likely a priori. When a whole quantity fits best the growth
//! also starts from that quantity's best single channel and grows within the quantity,
//! since growing only adds channels and would never reach a subset of it (coverage case
//! sensor_dynamics-c10: a filter on acc2 and acc3 was put on every accelerometer); of
//! the two grown sets the one with the higher log-likelihood less `ln C` per added
//! channel is kept. A set that covers every channel of one quantity is reported as that
//! quantity. A grown set is fitted from the fit of the set it grew from (its effect
//! parameters are the same ones, acting on one more channel), not from a fresh Latin
//! hypercube: one start instead of `n_effect_starts + 1`.

use super::data::DiagnosisData;
use super::fit::{effect_starts, fit_map, refit_at_map, MapFit, MapOptions};
use super::hypothesis::Hypothesis;
use super::location::Location;
use super::posterior::ModelPosterior;
use crate::error::Result;
use crate::io::Quantity;
use rayon::prelude::*;
use std::sync::Arc;

/// Settings of the location search.
#[derive(Debug, Clone, PartialEq)]
pub struct SearchOptions {
    /// Latin hypercube starts over the effect's box per location (plus the nominal fit's
    /// frame in each).
    pub n_effect_starts: usize,
    pub map: MapOptions,
    pub seed: u64,
}

impl Default for SearchOptions {
    fn default() -> Self {
        SearchOptions {
            n_effect_starts: 6,
            map: MapOptions::default(),
            seed: 1,
        }
    }
}

/// One fitted location.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct LocationFit {
    pub location: Location,
    pub map: MapFit,
}

/// The search of one hypothesis: every location tried, best first.
#[derive(Debug, Clone)]
pub struct HypothesisSearch {
    pub name: &'static str,
    pub tried: Vec<LocationFit>,
    /// Locations whose fit failed, with the reason.
    pub failed: Vec<(Location, String)>,
}

impl HypothesisSearch {
    /// The best location's fit.
    pub fn best(&self) -> Option<&LocationFit> {
        self.tried.first()
    }
}

/// MAP fit of `hypothesis` at `location`, starting from `nominal_z`, the fit of the model
/// it extends (frame, error floor and the effects already accepted).
pub fn fit_location(
    data: &Arc<DiagnosisData>,
    hypothesis: &Arc<dyn Hypothesis>,
    location: &Location,
    nominal_z: &[f64],
    opts: &SearchOptions,
) -> Result<LocationFit> {
    let post = ModelPosterior::new(data.clone(), Some((hypothesis.clone(), location.clone())))?;
    let starts = effect_starts(&post, nominal_z, opts.n_effect_starts, opts.seed)?;
    let map = fit_map(&post, &starts, &opts.map)?;
    let (_, map) = refit_at_map(post, map, &opts.map)?;
    Ok(LocationFit {
        location: location.clone(),
        map,
    })
}

/// Channels of `quantity` (responses and inputs) in the campaign.
fn channels_of(data: &DiagnosisData, quantity: Quantity) -> Vec<String> {
    data.channels()
        .into_iter()
        .filter(|c| c.quantity == quantity)
        .map(|c| c.name)
        .collect()
}

/// The channel set of a channel or quantity location.
fn channel_set(data: &DiagnosisData, loc: &Location) -> Option<Vec<String>> {
    match loc {
        Location::Channels(c) => Some(c.clone()),
        Location::Quantity(q) => Some(channels_of(data, *q)),
        _ => None,
    }
}

/// A channel set as a location: a quantity when it is exactly that quantity's channels.
fn as_location(data: &DiagnosisData, mut set: Vec<String>) -> Location {
    set.sort();
    for q in data.response_quantities() {
        let mut all = channels_of(data, q);
        all.sort();
        if all == set {
            return Location::Quantity(q);
        }
    }
    Location::Channels(set)
}

/// Fits `hypothesis` at every candidate location (and, for channel hypotheses, grows the
/// best channel set greedily); `progress` is called after every fit.
pub fn search(
    data: &Arc<DiagnosisData>,
    hypothesis: &Arc<dyn Hypothesis>,
    nominal_z: &[f64],
    opts: &SearchOptions,
    progress: &mut dyn FnMut(&str, &Location),
) -> Result<HypothesisSearch> {
    let mut tried: Vec<LocationFit> = Vec::new();
    let mut failed = Vec::new();
    // The locations are fitted side by side (each fit's starts run in parallel too:
    // with one location's 7 starts on 2 cores one waits for the last), collected in
    // their order: the same result whatever the thread count.
    let locations = hypothesis.locations(data);
    let fits: Vec<Result<LocationFit>> = locations
        .par_iter()
        .map(|loc| fit_location(data, hypothesis, loc, nominal_z, opts))
        .collect();
    for (loc, fit) in locations.into_iter().zip(fits) {
        match fit {
            Ok(f) => tried.push(f),
            // A location the model cannot evaluate is not a candidate; it is reported.
            Err(e) => failed.push((loc.clone(), e.to_string())),
        }
        progress(hypothesis.name(), &loc);
    }
    sort_best_first(&mut tried);
    let channel_hypothesis = tried
        .first()
        .is_some_and(|f| channel_set(data, &f.location).is_some());
    if channel_hypothesis {
        let all: Vec<String> = data.channels().into_iter().map(|c| c.name).collect();
        let penalty = (all.len().max(2) as f64).ln();
        // (start, the channels it may grow by)
        let mut starts = vec![(tried[0].clone(), all.clone())];
        if let Location::Quantity(q) = tried[0].location {
            let within = channels_of(data, q);
            let single_within = |f: &&LocationFit| match &f.location {
                Location::Channels(c) => c.len() == 1 && within.contains(&c[0]),
                _ => false,
            };
            if let Some(f) = tried.iter().find(single_within) {
                starts.push((f.clone(), within.clone()));
            }
        }
        // Each start grown; kept: the highest log-likelihood less its added channels'
        // penalty (the first start on a tie).
        let mut best: (f64, LocationFit) = (f64::NEG_INFINITY, tried[0].clone());
        for (start, candidates) in starts {
            let grow = Growth {
                data,
                hypothesis,
                nominal_z,
                opts,
                all: &candidates,
                penalty,
            };
            let (grown, added) = grow.from(start, &mut tried, progress);
            let score = grown.map.ln_likelihood - added as f64 * penalty;
            if score > best.0 {
                best = (score, grown);
            }
        }
        let best = best.1;
        // The accepted set goes first even when a larger, rejected set fitted a little
        // better (it did not pay its prior odds).
        tried.retain(|f| f.location != best.location);
        sort_best_first(&mut tried);
        tried.insert(0, best);
    }
    Ok(HypothesisSearch {
        name: hypothesis.name(),
        tried,
        failed,
    })
}

/// Greedy forward selection of a channel set (see the module docs).
struct Growth<'a> {
    data: &'a Arc<DiagnosisData>,
    hypothesis: &'a Arc<dyn Hypothesis>,
    nominal_z: &'a [f64],
    opts: &'a SearchOptions,
    /// The channels a set may grow by.
    all: &'a [String],
    /// `ln C`: what one added channel must gain in maximum log-likelihood.
    penalty: f64,
}

impl Growth<'_> {
    /// Grows `start` one channel at a time while that pays its penalty; every fit is
    /// added to `tried`. Returns the grown set and the number of channels added.
    fn from(
        &self,
        start: LocationFit,
        tried: &mut Vec<LocationFit>,
        progress: &mut dyn FnMut(&str, &Location),
    ) -> (LocationFit, usize) {
        let (data, hypothesis, opts) = (self.data, self.hypothesis, self.opts);
        let mut best = start;
        let mut added = 0;
        loop {
            let set = channel_set(data, &best.location).unwrap_or_default();
            let mut improved: Option<LocationFit> = None;
            // A set already fitted (a candidate of its own) is not grown into.
            let grown: Vec<Location> = self
                .all
                .iter()
                .filter(|c| !set.contains(c))
                .map(|c| {
                    let mut grown = set.clone();
                    grown.push(c.clone());
                    as_location(data, grown)
                })
                .filter(|loc| !tried.iter().any(|f| f.location == *loc))
                .collect();
            // One more channel under the same effect parameters: the set's own fit is
            // the start (a fresh search of the effect's box would only find it again;
            // see the module docs). Single-start fits, so side by side.
            let fits: Vec<Option<LocationFit>> = grown
                .par_iter()
                .map(|loc| {
                    let warm = fit_location(data, hypothesis, loc, &best.map.z, opts);
                    let fresh = || {
                        let from = &best.map.z[..self.nominal_z.len()];
                        fit_location(data, hypothesis, loc, from, opts)
                    };
                    warm.or_else(|_| fresh()).ok()
                })
                .collect();
            for (loc, f) in grown.iter().zip(fits) {
                let Some(f) = f else {
                    continue;
                };
                progress(hypothesis.name(), loc);
                tried.push(f.clone());
                let gain = f.map.ln_likelihood - best.map.ln_likelihood;
                if gain > self.penalty
                    && improved
                        .as_ref()
                        .is_none_or(|i| f.map.ln_likelihood > i.map.ln_likelihood)
                {
                    improved = Some(f);
                }
            }
            match improved {
                Some(f) => {
                    best = f;
                    added += 1;
                }
                None => return (best, added),
            }
        }
    }
}

fn sort_best_first(fits: &mut [LocationFit]) {
    fits.sort_by(|a, b| b.map.ln_likelihood.total_cmp(&a.map.ln_likelihood));
}
