//! The data of a diagnosis: complex FRF estimates of every *segment* (a shake-table test,
//! or one impact of a hammer test) at a selected set of frequencies, each with its
//! Bendat & Piersol relative random error, plus what amplitude-dependent models need
//! (the equivalent-linearisation weight of each story's drift in each segment).
//!
//! # What is measured
//! Each value is the exact ratio *channel / input channel* as recorded (see DIAGNOSE.md):
//! hammer: displacement / force (receptance), absolute acceleration / force
//! (accelerance); shake table: displacement (relative to the table) / ground
//! acceleration, **absolute** acceleration / ground acceleration (the estimator's relative
//! accelerance plus 1, exact for H1). So a time offset or a sensor filter on one channel
//! is a factor on exactly that channel. Hammer estimates carry the exponential window:
//! they are the transfer function at `s = j omega + 1/tau`.
//!
//! # Segments
//! With [`DataOptions::per_impact`] every impact of a hammer test is its own segment
//! (one block, H1 = Y/F), so that impacts of different levels can disagree. All hammer
//! blocks of a campaign are cut to one common length, so they share one frequency grid
//! and one window time constant (the forward model then factorises each `s` once for all
//! hammer segments). Each record is cut just before the next impact's pre-trigger, with
//! up to 1 s of the preceding record as the quiet part that sets the sensor offsets.
//!
//! # Frequencies
//! Chosen per group of segments sharing a grid, see [`super::bins`]. A channel keeps a
//! point only where its coherence is at least `min_coherence`.
//!
//! # Amplitude
//! For story `r` with a displacement sensor or an accelerometer on floors `r - 1` (or
//! the ground) and `r` (accelerations integrated twice above half the segment's lowest
//! resonance where a floor has no displacement sensor), the drift `d(t)` over the analysed part of the record (the hammer block with its
//! exponential window `w`, or the whole shake-table record) and Caughey's
//! equivalent-linearisation weight `sum (w d)^2 d^2 / sum (w d)^2`: a cubic spring
//! `k3 d^3` acts on that segment's FRFs as the linear spring `k3` times this weight
//! ([`super::amplitude`]).

use super::amplitude::story_drift_weights;
use super::bins::{band_span, select_bins};
pub use super::data_options::{weight_bias, DataOptions, GainCarrier, MAX_WEIGHT_BIAS};
use super::input_noise::{input_gain_basis, per_bin_basis};
pub use super::input_noise::{InputGainBasis, MAX_COMMON_SHARE, MAX_GAIN_RANK};
use super::location::Location;
use super::reduction::{model_for_campaign, Reduction};
pub use super::time_domain::SegmentSource;
use crate::error::{Error, Result};
use crate::frf::FrfKind;
use crate::io::{Campaign, Channel, NominalModel, Quantity, Test, TestKind};
use crate::modal::Modes;
use crate::model::StructuralModel;
use crate::signal::hammer::detect_impacts;
use crate::signal::{
    bendat_piersol_rel_std, common_input_rel_var, estimate_test, Band, InputKind, TestFrf,
};
use num_complex::Complex64;
use std::sync::Arc;

/// The measured FRF of one response channel in one segment.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelData {
    pub channel: Channel,
    /// Receptance (displacement) or accelerance (acceleration; absolute in shake-table
    /// tests).
    pub kind: FrfKind,
    /// Index into the segment's `freq_hz` of each point.
    pub freq_index: Vec<usize>,
    /// Resonance band (index into the segment's `bands`) of each point, `None` off-band.
    pub band: Vec<Option<usize>>,
    /// Measured ratio channel / input at each point.
    pub h: Vec<Complex64>,
    /// Bendat & Piersol relative random error `eps` of each point: `std(Re) = std(Im) =
    /// eps |h|`.
    pub rel_err: Vec<f64>,
    /// The estimator's own systematic error at each point, added to the
    /// frequency-domain model's prediction (empty: none). Set by
    /// [`DiagnosisData::with_estimator_bias`] from a replay of the tests
    /// (see [`super::estimator_bias`]).
    pub estimator_bias: Vec<Complex64>,
}

impl ChannelData {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.h.len()
    }
    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.h.is_empty()
    }
}

/// One segment: a shake-table test, or one impact (or all impacts) of a hammer test.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentData {
    /// `test` or `test/impact<k>` (1-based).
    pub name: String,
    pub test: String,
    /// Impact index within the test (0-based) when the segment is one impact.
    pub impact: Option<usize>,
    /// Peak force of the impact(s), N (hammer).
    pub peak_force_n: Option<f64>,
    pub input: InputKind,
    /// The input channel.
    pub input_channel: Channel,
    /// Exponential window time constant, s (hammer); the data are at `s = j omega + 1/tau`.
    pub exp_window_tau_s: Option<f64>,
    /// Selected frequencies, Hz (ascending).
    pub freq_hz: Vec<f64>,
    /// Resonance bands found in this segment.
    pub bands: Vec<Band>,
    pub channels: Vec<ChannelData>,
    /// Equivalent-linearisation weight of each story's drift (index `r - 1`), m^2,
    /// where the sensors on its two levels allow it (see the module docs).
    pub story_drift_lin_sq_m2: Vec<Option<f64>>,
    /// How the segment was cut and estimated (for a time-domain model of the test).
    pub source: SegmentSource,
    /// Correlated relative error that the input channel's noise puts on every ratio of
    /// a single-impact segment, or of a shake-table record bin by bin (see
    /// [`InputGainBasis`]); `None` otherwise.
    pub input_gain: Option<InputGainBasis>,
}

impl SegmentData {
    /// The Laplace variable of each frequency: `j omega + 1/tau` (`j omega` unwindowed).
    pub fn laplace(&self) -> Vec<Complex64> {
        let eps = self.exp_window_tau_s.map_or(0.0, |t| 1.0 / t);
        self.freq_hz
            .iter()
            .map(|f| Complex64::new(eps, 2.0 * std::f64::consts::PI * f))
            .collect()
    }

    /// True for a shake-table (ground-excited) segment.
    pub fn is_ground(&self) -> bool {
        matches!(self.input, InputKind::Ground { .. })
    }

    /// Number of complex points over all channels.
    pub fn n_points(&self) -> usize {
        self.channels.iter().map(ChannelData::len).sum()
    }
}

/// All data of a diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosisData {
    pub title: String,
    pub nominal: NominalModel,
    /// The nominal model's parametrised matrices (paper Eqs. 20-21): the shear frame, or
    /// the general model read from its manifest once.
    pub model: Arc<StructuralModel>,
    /// Undamped natural frequencies of the nominal model, Hz (ascending).
    pub nominal_freq_hz: Vec<f64>,
    pub segments: Vec<SegmentData>,
    pub options: DataOptions,
    /// How a model too large for the dense forward solve was reduced onto the kept
    /// DOFs (`model` is then the reduced one); `None` when it was not.
    pub reduction: Option<Arc<Reduction>>,
}

impl DiagnosisData {
    /// Top of the analysed band, Hz, where it has one: the reduction's (`freq_max_hz`, or
    /// the anti-aliasing pass band), else [`DataOptions::freq_max_hz`].
    pub fn band_cap_hz(&self) -> Option<f64> {
        self.reduction
            .as_ref()
            .map(|r| r.freq_max_hz)
            .or(self.options.freq_max_hz)
    }

    /// Estimates and selects the data of `campaign` (see the module docs).
    pub fn from_campaign(campaign: &Campaign, options: &DataOptions) -> Result<Self> {
        options.check()?;
        let nominal = campaign.nominal.clone();
        let (reduced_campaign, model, reduction, nominal_freq_hz) =
            model_for_campaign(campaign, options)?;
        let campaign = reduced_campaign.as_ref().unwrap_or(campaign);
        let cap_hz = match &reduction {
            Some(r) => Some(r.freq_max_hz),
            None => options.freq_max_hz,
        };
        let n_floors = reduction
            .as_ref()
            .map_or(nominal.n_floors(), |r| r.kept_dof.len());
        // Stories (drift between neighbouring floors) exist on a shear frame only.
        let n_stories = if nominal.is_shear_frame() {
            n_floors
        } else {
            0
        };
        let mut est = options.estimate;
        est.bands.n_peaks = Some(nominal_freq_hz.len() + options.extra_peaks);
        let f1 = nominal_freq_hz[0];
        let range = (
            options.freq_range_rel.0 * f1,
            (options.freq_range_rel.1 * nominal_freq_hz[nominal_freq_hz.len() - 1])
                .min(cap_hz.unwrap_or(f64::INFINITY)),
        );

        // Hammer blocks: a common length over all impacts of all hammer tests.
        let mut plans: Vec<(usize, Vec<(usize, usize)>)> = Vec::new(); // test, (start, end)
        for (ti, t) in campaign.tests.iter().enumerate() {
            if let TestKind::Hammer { .. } = t.kind {
                let fi = t.find(Quantity::Force).ok_or_else(|| {
                    Error::invalid(
                        test_path(campaign, t),
                        "hammer test without a force channel",
                    )
                })?;
                let impacts = detect_impacts(&t.data[fi], t.sample_rate_hz, &est.hammer);
                if impacts.is_empty() {
                    return Err(Error::invalid(
                        test_path(campaign, t),
                        "no impact found in the force channel",
                    ));
                }
                let p = est.hammer.pretrigger_samples(t.sample_rate_hz);
                let starts: Vec<usize> = impacts
                    .iter()
                    .map(|i| i.trigger.saturating_sub(p))
                    .collect();
                let mut spans: Vec<(usize, usize)> = starts
                    .iter()
                    .enumerate()
                    .map(|(b, &s)| (s, starts.get(b + 1).copied().unwrap_or(t.n_samples())))
                    .collect();
                let longest = spans.iter().map(|(s, e)| e - s).max().unwrap_or(0);
                // As the hammer estimator does: a last block shorter than half the longest
                // is dropped.
                if spans.len() > 1 {
                    if let Some(&(s, e)) = spans.last() {
                        if 2 * (e - s) < longest {
                            spans.pop();
                        }
                    }
                }
                plans.push((ti, spans));
            }
        }
        let common_len = plans
            .iter()
            .flat_map(|(_, s)| s.iter().map(|(a, b)| b - a))
            .min();

        // Estimates: (segment skeleton, estimate, the test record it came from, block
        // start within that record).
        let mut raw: Vec<RawSegment> = Vec::new();
        for (ti, spans) in &plans {
            let t = &campaign.tests[*ti];
            let len = common_len.unwrap_or(0);
            let quiet_max = (t.sample_rate_hz.round() as usize).max(64);
            if options.per_impact {
                for (b, &(start, _)) in spans.iter().enumerate() {
                    let quiet = start.min(quiet_max);
                    let lo = start - quiet;
                    let hi = start + len;
                    let slice = slice_test(t, lo, hi);
                    let frf = estimate_test(&slice, &est).map_err(|e| with_root(campaign, e))?;
                    raw.push(RawSegment {
                        name: format!("{}/impact{}", t.name, b + 1),
                        impact: Some(b),
                        frf,
                        record: slice,
                        block_start: quiet,
                        block_len: len,
                        source: SegmentSource::new(lo, hi, est),
                    });
                }
            } else {
                let mut e = est;
                e.hammer.max_block_s = Some(len as f64 / t.sample_rate_hz);
                let frf = estimate_test(t, &e).map_err(|e| with_root(campaign, e))?;
                raw.push(RawSegment {
                    name: t.name.clone(),
                    impact: None,
                    frf,
                    record: t.clone(),
                    block_start: spans[0].0,
                    block_len: len,
                    source: SegmentSource::new(0, t.n_samples(), e),
                });
            }
        }
        for t in &campaign.tests {
            if t.kind == TestKind::ShakeTable {
                let frf = estimate_test(t, &est).map_err(|e| with_root(campaign, e))?;
                raw.push(RawSegment {
                    name: t.name.clone(),
                    impact: None,
                    frf,
                    record: t.clone(),
                    block_start: 0,
                    block_len: t.n_samples(),
                    source: SegmentSource::new(0, t.n_samples(), est),
                });
            }
        }
        if raw.is_empty() {
            return Err(Error::Usage("the campaign has no tests to diagnose".into()));
        }

        // Groups of segments on one grid: all hammer blocks share one; each shake-table
        // test is its own.
        let mut group_of: Vec<usize> = Vec::with_capacity(raw.len());
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, r) in raw.iter().enumerate() {
            let key = (
                r.frf.freq_hz.len(),
                r.frf.exp_window_tau_s.map(f64::to_bits),
            );
            let found = groups.iter().position(|g| {
                let o = &raw[g[0]];
                o.frf.exp_window_tau_s.is_some()
                    && (
                        o.frf.freq_hz.len(),
                        o.frf.exp_window_tau_s.map(f64::to_bits),
                    ) == key
            });
            match found {
                Some(g) if r.frf.exp_window_tau_s.is_some() => {
                    groups[g].push(i);
                    group_of.push(g);
                }
                _ => {
                    groups.push(vec![i]);
                    group_of.push(groups.len() - 1);
                }
            }
        }
        let selections: Vec<Vec<usize>> = groups
            .iter()
            .map(|g| {
                let frfs: Vec<&TestFrf> = g.iter().map(|&i| &raw[i].frf).collect();
                select_bins(&frfs, range, options)
            })
            .collect();

        let mut segments = Vec::with_capacity(raw.len());
        for (i, r) in raw.iter().enumerate() {
            let sel = &selections[group_of[i]];
            segments.push(build_segment(r, sel, options, n_floors, n_stories)?);
        }
        let data = DiagnosisData {
            title: campaign.title.clone(),
            nominal,
            model,
            nominal_freq_hz,
            segments,
            options: *options,
            reduction: reduction.map(Arc::new),
        };
        if data.n_points() == 0 {
            return Err(Error::Usage(
                "no FRF point passed the coherence and range selection".into(),
            ));
        }
        Ok(data)
    }

    /// Number of floors of the nominal model (of DOFs of a general model: DOF `d`,
    /// 1-based, is "floor" `d` in the campaign format).
    pub fn n_floors(&self) -> usize {
        self.reduction
            .as_ref()
            .map_or(self.nominal.n_floors(), |r| r.kept_dof.len())
    }

    /// `loc` as the user's model numbers it: on a reduced model the diagnosis's DOFs
    /// `1..=kept` are mapped back to the model's DOFs ([`Reduction::model_dof`]); other
    /// locations, and every location of a model that is not reduced, unchanged.
    pub fn shown(&self, loc: &Location) -> Location {
        match (&self.reduction, loc) {
            (Some(r), Location::Floor(f)) => Location::Floor(r.model_dof(*f)),
            (Some(r), Location::Dofs([a, b])) => Location::Dofs([r.model_dof(*a), r.model_dof(*b)]),
            _ => loc.clone(),
        }
    }

    /// True when the nominal model is a shear frame (it has stories and a base under
    /// story 1); false for a general model.
    pub fn is_shear_frame(&self) -> bool {
        self.nominal.is_shear_frame()
    }

    /// Number of complex points over all segments and channels.
    pub fn n_points(&self) -> usize {
        self.segments.iter().map(SegmentData::n_points).sum()
    }

    /// Every distinct channel (inputs included), by name, in order of appearance.
    pub fn channels(&self) -> Vec<Channel> {
        let mut out: Vec<Channel> = Vec::new();
        for s in &self.segments {
            for c in std::iter::once(&s.input_channel).chain(s.channels.iter().map(|c| &c.channel))
            {
                if !out.iter().any(|o| o.name == c.name) {
                    out.push(c.clone());
                }
            }
        }
        out
    }

    /// Response quantities present (acceleration and/or displacement).
    pub fn response_quantities(&self) -> Vec<Quantity> {
        let mut q: Vec<Quantity> = Vec::new();
        for s in &self.segments {
            for c in &s.channels {
                if !q.contains(&c.channel.quantity) {
                    q.push(c.channel.quantity);
                }
            }
        }
        q
    }

    /// The largest equivalent-linearisation weight of story `story` (1-based) over the
    /// segments, m^2, if any segment has it.
    pub fn max_story_drift_lin_sq_m2(&self, story: usize) -> Option<f64> {
        self.segments
            .iter()
            .filter_map(|s| {
                s.story_drift_lin_sq_m2
                    .get(story.checked_sub(1)?)
                    .copied()
                    .flatten()
            })
            .reduce(f64::max)
    }
}

/// Undamped natural frequencies of the nominal model, Hz.
pub fn nominal_frequencies(nominal: &NominalModel) -> Result<Vec<f64>> {
    model_frequencies(&nominal.structural_model()?)
}

/// Undamped natural frequencies of `model` at its nominal values, Hz (ascending).
pub fn model_frequencies(model: &StructuralModel) -> Result<Vec<f64>> {
    let modes = Modes::solve(
        &model.stiffness(&model.alpha_zero()),
        &model.mass(&model.beta_zero()),
        model.ground_influence(),
        None,
    )?;
    Ok(modes.freq_hz())
}

struct RawSegment {
    name: String,
    impact: Option<usize>,
    frf: TestFrf,
    /// The record the estimate was made from (a slice for one impact).
    record: Test,
    /// First sample of the analysed block in `record`.
    block_start: usize,
    block_len: usize,
    /// Where `record` was cut from its test, and the estimator's settings.
    source: SegmentSource,
}

fn test_path(c: &Campaign, t: &Test) -> std::path::PathBuf {
    c.root.join("tests").join(&t.name).join("data.csv")
}

fn with_root(c: &Campaign, e: Error) -> Error {
    match e {
        Error::Invalid { path, what } => Error::invalid(c.root.join(path), what),
        other => other,
    }
}

fn slice_test(t: &Test, lo: usize, hi: usize) -> Test {
    let hi = hi.min(t.n_samples());
    Test {
        name: t.name.clone(),
        kind: t.kind,
        sample_rate_hz: t.sample_rate_hz,
        channels: t.channels.clone(),
        data: t.data.iter().map(|d| d[lo..hi].to_vec()).collect(),
    }
}

fn build_segment(
    r: &RawSegment,
    sel: &[usize],
    o: &DataOptions,
    n_floors: usize,
    n_stories: usize,
) -> Result<SegmentData> {
    let frf = &r.frf;
    let ground = matches!(frf.input, InputKind::Ground { .. });
    let input_name = match &frf.input {
        InputKind::Force { channel, .. } | InputKind::Ground { channel } => channel,
    };
    let input_channel = r
        .record
        .channels
        .iter()
        .find(|c| &c.name == input_name)
        .cloned()
        .ok_or_else(|| {
            Error::Usage(format!(
                "input channel {input_name} not in test {}",
                frf.test
            ))
        })?;
    let freq_hz: Vec<f64> = sel.iter().map(|&k| frf.freq_hz[k]).collect();
    let spans: Vec<(f64, f64)> = frf
        .bands
        .iter()
        .map(|b| band_span(b, o.band_factor))
        .collect();
    let band_of = |f: f64| spans.iter().position(|&(lo, hi)| f >= lo && f <= hi);
    let mut channels = Vec::with_capacity(frf.responses.len());
    for resp in &frf.responses {
        if resp.channel.floor == 0 || resp.channel.floor > n_floors {
            continue;
        }
        let mut c = ChannelData {
            channel: resp.channel.clone(),
            kind: resp.kind,
            freq_index: Vec::new(),
            band: Vec::new(),
            h: Vec::new(),
            rel_err: Vec::new(),
            estimator_bias: Vec::new(),
        };
        for (i, &k) in sel.iter().enumerate() {
            let g2 = resp.coherence[k];
            if g2.is_nan() || g2 < o.min_coherence {
                continue;
            }
            let h_rel = resp.h1[k];
            let eps = bendat_piersol_rel_std(g2, frf.n_averages);
            // Shake table: absolute acceleration / ground = relative + 1; the error is
            // the relative estimate's, re-expressed relative to the absolute ratio.
            let (h, eps) = if ground && resp.kind == FrfKind::Accelerance {
                let h = h_rel + 1.0;
                (h, eps * h_rel.norm() / h.norm())
            } else {
                (h_rel, eps)
            };
            if !(h.norm() > 0.0 && h.is_finite() && eps.is_finite()) {
                continue;
            }
            c.freq_index.push(i);
            c.band.push(band_of(freq_hz[i]));
            c.h.push(h);
            c.rel_err.push(eps);
        }
        if !c.is_empty() {
            channels.push(c);
        }
    }
    let window = frf.exp_window_tau_s;
    // Accelerometers stand in for missing displacement sensors, integrated above half the
    // lowest resonance found in the segment (below it the response is quasi-static and
    // small, and twice-integrated noise is not).
    let lowest_peak_hz = frf
        .bands
        .iter()
        .map(|b| b.peak_hz)
        .fold(f64::INFINITY, f64::min);
    let high_pass_hz = match lowest_peak_hz.is_finite() {
        true => 0.5 * lowest_peak_hz,
        false => 0.5 * freq_hz.first().copied().unwrap_or(0.0),
    };
    let block = (r.block_start, r.block_len);
    let story_drift_lin_sq_m2 =
        story_drift_weights(&r.record, n_stories, block, window, high_pass_hz);
    let peak_force_n = if ground {
        None
    } else {
        r.record.find(Quantity::Force).map(|fi| {
            let d = &r.record.data[fi];
            let base = d[..r.block_start.max(1).min(d.len())].iter().sum::<f64>()
                / r.block_start.max(1) as f64;
            d[r.block_start..]
                .iter()
                .map(|v| (v - base).abs())
                .fold(0.0, f64::max)
        })
    };
    let input_gain = match (&frf.input, r.impact) {
        (InputKind::Force { .. }, Some(_)) => input_gain_basis(
            &r.record,
            r.block_start,
            r.block_len,
            window,
            &freq_hz,
            &o.estimate,
        ),
        (InputKind::Ground { .. }, _) if o.common_input_error => {
            let rel_var = common_input_rel_var(&r.record, &r.source.estimate, sel)?;
            let rel_var = match rel_var.is_empty() {
                true => vec![f64::NAN; sel.len()],
                false => rel_var,
            };
            let mut min_rel_err = vec![f64::INFINITY; sel.len()];
            for c in &channels {
                for (&i, &e) in c.freq_index.iter().zip(&c.rel_err) {
                    min_rel_err[i] = min_rel_err[i].min(e);
                }
            }
            per_bin_basis(&rel_var, &min_rel_err)
        }
        _ => None,
    };
    Ok(SegmentData {
        source: SegmentSource {
            bins: sel.to_vec(),
            ..r.source.clone()
        },
        input_gain,
        name: r.name.clone(),
        test: frf.test.clone(),
        impact: r.impact,
        peak_force_n,
        input: frf.input.clone(),
        input_channel,
        exp_window_tau_s: window,
        freq_hz,
        bands: frf.bands.clone(),
        channels,
        story_drift_lin_sq_m2,
    })
}
