//! A general model too large for the diagnosis's dense forward solve
//! ([`super::forward::MAX_DOF`]) is diagnosed on its reduction onto the campaign's
//! instrumented and excited DOFs ([`crate::predict::kept`]: static constraint modes
//! plus the lowest modes over the prior box). The kept DOFs stay physical, so channels,
//! impacts and the hypotheses' oscillators attach to them one to one; inside the
//! diagnosis they are numbered `1..=kept` (as floors), and [`Reduction`] maps them back
//! to the model's DOFs for every location it reports.

use super::data::{model_frequencies, DataOptions, DiagnosisData};
use super::forward::BaseParams;
use super::posterior::MULTIPLIER_BOUNDS;
use crate::error::{Error, Result};
use crate::io::{Campaign, TestKind};
use crate::modal::condensed::lowest_modes_condensed;
use crate::model::StructuralModel;
use crate::predict::kept::{reduce_keeping, BasisAnchor, KeptDofModel};
use crate::predict::reduced::BasisOptions;
use serde::Serialize;
use std::sync::Arc;

/// Modes kept from each snapshot beyond those in the analysed band.
const EXTRA_MODES: usize = 4;
/// Modes of the full model searched for the analysed band.
const MAX_BAND_MODES: usize = 40;
/// Step of the snapshots around an anchor, in each `alpha_r` (and `beta_r`).
const ANCHOR_STEP: f64 = 0.05;
/// The POD part of the interior basis holds at most this many times the modes per
/// snapshot (beside the anchor's own modes).
const BASIS_SIZE_FACTOR: usize = 1;
/// Relative energy below which a POD direction is dropped.
const BASIS_REL_TOL: f64 = 1e-8;
/// The anchor's modes up to this multiple of the band's top are kept whole.
const ANCHOR_MODES_REL: f64 = 2.5;

/// How a diagnosis's model was reduced.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Reduction {
    /// The model's DOF (1-based) of each kept DOF (the diagnosis's "floor" `j + 1`).
    pub kept_dof: Vec<usize>,
    /// Generalised coordinates beside the kept DOFs.
    pub n_generalised: usize,
    /// Pairs of kept DOFs (diagnosis numbering, 1-based) joined by a term of the full
    /// nominal `K`: the connections a damper can act across.
    pub connections: Vec<[usize; 2]>,
    /// Top of the analysed band, Hz.
    pub freq_max_hz: f64,
    /// Where the basis is exact: the stiffness variables `alpha`...
    pub anchor_alpha: Vec<f64>,
    /// ... and the mass variables `beta`.
    pub anchor_beta: Vec<f64>,
    /// Modes taken from each snapshot: those in the band and `EXTRA_MODES` (4) more.
    pub modes_per_snapshot: usize,
    /// Modes of the anchor kept whole: those below `ANCHOR_MODES_REL` (2.5) x the band's top
    /// (their dynamics above the static correction reach into the band).
    pub anchor_modes: usize,
    /// The full model.
    #[serde(skip)]
    pub full: Arc<StructuralModel>,
}

impl Reduction {
    /// `campaign` with its channels and impacts renumbered onto the kept DOFs, as the
    /// diagnosis's data and model number them (what a replay of its tests needs).
    pub fn renumber(&self, campaign: &Campaign) -> Campaign {
        let kept: Vec<usize> = self.kept_dof.iter().map(|d| d - 1).collect();
        renumbered(campaign, &kept)
    }

    /// The model's DOF (1-based) of the diagnosis's DOF `j` (1-based); `j` itself when
    /// out of range (the ground, 0).
    pub fn model_dof(&self, j: usize) -> usize {
        match j.checked_sub(1).and_then(|i| self.kept_dof.get(i)) {
            Some(&d) => d,
            None => j,
        }
    }
}

/// The kept DOFs (0-based, ascending): every response channel's and every impact's.
fn kept_dofs(campaign: &Campaign) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    for t in &campaign.tests {
        kept.extend(t.channels.iter().filter_map(|c| c.dof()));
        if let TestKind::Hammer { excited_floor } = t.kind {
            kept.extend(excited_floor.checked_sub(1));
        }
    }
    kept.sort_unstable();
    kept.dedup();
    kept
}

/// The campaign with every channel and impact renumbered to the kept DOFs.
fn renumbered(campaign: &Campaign, kept: &[usize]) -> Campaign {
    let local = |floor: usize| match floor.checked_sub(1) {
        Some(d) => kept.binary_search(&d).map_or(floor, |j| j + 1),
        None => 0,
    };
    let mut out = campaign.clone();
    for t in &mut out.tests {
        for c in &mut t.channels {
            c.floor = local(c.floor);
        }
        if let TestKind::Hammer { excited_floor } = &mut t.kind {
            *excited_floor = local(*excited_floor);
        }
    }
    out
}

/// Top of the analysed band: `freq_max_hz`, or the anti-aliasing pass band of the
/// slowest test (0.4 of its sample rate).
pub fn band_top_hz(campaign: &Campaign, freq_max_hz: Option<f64>) -> f64 {
    freq_max_hz.unwrap_or_else(|| {
        let fs = campaign
            .tests
            .iter()
            .map(|t| t.sample_rate_hz)
            .fold(f64::INFINITY, f64::min);
        0.4 * fs
    })
}

/// `full` reduced onto `campaign`'s kept DOFs for a band up to `freq_max_hz`, exact at
/// the nominal point, the campaign renumbered onto it, and the map back.
pub fn reduce_for_campaign(
    campaign: &Campaign,
    full: &StructuralModel,
    freq_max_hz: Option<f64>,
) -> Result<(Campaign, KeptDofModel, Reduction)> {
    let kept = kept_dofs(campaign);
    let top_hz = band_top_hz(campaign, freq_max_hz);
    let k0 = full.stiffness(&full.alpha_zero());
    let m0 = full.mass(&full.beta_zero());
    let n_with_mass = full.n_dof() - crate::model::condense::massless_dofs(&m0).len();
    let n_search = MAX_BAND_MODES.min(n_with_mass);
    let modes = lowest_modes_condensed(&k0, &m0, n_search)?;
    let two_pi = 2.0 * std::f64::consts::PI;
    let n_band = modes
        .eigenvalues
        .iter()
        .filter(|l| l.sqrt() / two_pi <= top_hz)
        .count();
    if n_band == 0 {
        return Err(Error::Usage(format!(
            "the model has no mode below the analysed band's top, {top_hz:.3} Hz \
             (raise --freq-max-hz)"
        )));
    }
    let mut connections = Vec::new();
    for (i, &a) in kept.iter().enumerate() {
        for (j, &b) in kept.iter().enumerate().skip(i + 1) {
            if k0[(a, b)] != 0.0 {
                connections.push([i + 1, j + 1]);
            }
        }
    }
    let mut reduction = Reduction {
        kept_dof: kept.iter().map(|d| d + 1).collect(),
        n_generalised: 0,
        connections,
        freq_max_hz: top_hz,
        anchor_alpha: full.alpha_zero(),
        anchor_beta: full.beta_zero(),
        modes_per_snapshot: (n_band + EXTRA_MODES).min(n_search),
        anchor_modes: modes
            .eigenvalues
            .iter()
            .filter(|l| l.sqrt() / two_pi <= ANCHOR_MODES_REL * top_hz)
            .count()
            .max(n_band + EXTRA_MODES)
            .min(n_search),
        full: Arc::new(full.clone()),
    };
    let reduced = reduction.reduce_at(&full.alpha_zero(), &full.beta_zero())?;
    reduction.n_generalised = reduced.n_generalised();
    Ok((renumbered(campaign, &kept), reduced, reduction))
}

impl Reduction {
    /// The full model reduced onto the same kept DOFs with its interior exact at
    /// `(alpha, beta)`: the lowest modes there and at `+- ANCHOR_STEP` in each variable
    /// (within the prior box), so that the basis holds the modes and their first
    /// derivatives at that point.
    pub fn reduce_at(&self, alpha: &[f64], beta: &[f64]) -> Result<KeptDofModel> {
        let full = &self.full;
        let (lo, hi) = (MULTIPLIER_BOUNDS.0 - 1.0, MULTIPLIER_BOUNDS.1 - 1.0);
        let center: Vec<f64> = alpha.iter().chain(beta).copied().collect();
        let mut snaps = vec![center.clone()];
        for j in 0..center.len() {
            for sign in [-1.0, 1.0] {
                let mut v = center.clone();
                v[j] = (v[j] + sign * ANCHOR_STEP).clamp(lo, hi);
                snaps.push(v);
            }
        }
        let n_alpha = full.n_alpha();
        let pairs: Vec<_> = snaps
            .iter()
            .map(|v| (v[..n_alpha].to_vec(), v[n_alpha..].to_vec()))
            .collect();
        let opts = BasisOptions {
            modes_per_snapshot: self.modes_per_snapshot,
            rel_tol: BASIS_REL_TOL,
            max_size: BASIS_SIZE_FACTOR * self.modes_per_snapshot,
        };
        let kept: Vec<usize> = self.kept_dof.iter().map(|d| d - 1).collect();
        let anchor = BasisAnchor {
            alpha: alpha.to_vec(),
            beta: beta.to_vec(),
            n_modes: self.anchor_modes,
        };
        reduce_keeping(full, &kept, &anchor, &pairs, &opts)
    }

    /// The same reduction re-anchored at `(alpha, beta)` ([`Self::reduce_at`]).
    pub fn reanchored(&self, alpha: &[f64], beta: &[f64]) -> Result<(KeptDofModel, Reduction)> {
        let reduced = self.reduce_at(alpha, beta)?;
        let mut r = self.clone();
        r.anchor_alpha = alpha.to_vec();
        r.anchor_beta = beta.to_vec();
        r.n_generalised = reduced.n_generalised();
        Ok((reduced, r))
    }
}

/// Re-anchoring stops when no stiffness or mass variable moved more than this between
/// two anchors (a fifth of the snapshots' step, where the basis error is about 1e-3).
pub const REANCHOR_TOL: f64 = 0.2 * ANCHOR_STEP;

impl DiagnosisData {
    /// On a reduced model, the same data on the reduction re-anchored at `base`'s
    /// stiffness and mass variables ([`Reduction::reanchored`]), and the largest change
    /// of a variable from the old anchor; `None` when the model is not reduced or no
    /// variable moved more than [`REANCHOR_TOL`]. The hypotheses' priors keep the
    /// nominal model's frequencies.
    pub fn reanchored(&self, base: &BaseParams) -> Result<Option<(DiagnosisData, f64)>> {
        let Some(reduction) = &self.reduction else {
            return Ok(None);
        };
        let (alpha, beta) = base.alpha_beta();
        let moved = alpha
            .iter()
            .zip(&reduction.anchor_alpha)
            .chain(beta.iter().zip(&reduction.anchor_beta))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if moved <= REANCHOR_TOL {
            return Ok(None);
        }
        let (reduced, r) = reduction.reanchored(&alpha, &beta)?;
        let mut out = self.clone();
        out.model = Arc::new(reduced.model);
        out.reduction = Some(Arc::new(r));
        Ok(Some((out, moved)))
    }
}

/// The diagnosis's model of `campaign`: its nominal model as it is, or (a general model
/// of more than [`super::forward::MAX_DOF`] DOFs) reduced onto the kept DOFs with the
/// campaign renumbered onto it; and the model's natural frequencies, Hz (of a reduced
/// model only those in the analysed band).
#[allow(clippy::type_complexity)]
pub(super) fn model_for_campaign(
    campaign: &Campaign,
    options: &DataOptions,
) -> Result<(
    Option<Campaign>,
    Arc<StructuralModel>,
    Option<Reduction>,
    Vec<f64>,
)> {
    let nominal = &campaign.nominal;
    let full = nominal.structural_model()?;
    if nominal.is_shear_frame() || full.n_dof() <= super::forward::MAX_DOF {
        if nominal.n_floors() != full.n_dof() {
            return Err(Error::Usage(format!(
                "the campaign's nominal model has {} DOFs but its matrices have {}",
                nominal.n_floors(),
                full.n_dof()
            )));
        }
        let freq_hz = model_frequencies(&full)?;
        return Ok((None, Arc::new(full), None, freq_hz));
    }
    let (renumbered, reduced, reduction) =
        reduce_for_campaign(campaign, &full, options.freq_max_hz)?;
    let mut freq_hz = model_frequencies(&reduced.model)?;
    // The band's modes: above it the reduced model's modes stand for residual
    // flexibility, not for modes of the structure.
    let n = freq_hz
        .iter()
        .filter(|&&f| f <= reduction.freq_max_hz)
        .count()
        .max(1);
    freq_hz.truncate(n);
    Ok((
        Some(renumbered),
        Arc::new(reduced.model),
        Some(reduction),
        freq_hz,
    ))
}
