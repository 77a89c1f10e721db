//! The extended forward model: the nominal model (the campaign's parametrised model,
//! paper Eqs. 20-21, at the sampled stiffness and mass scales, with modal damping of its
//! own modes; a shear frame or a general model) plus, optionally, one hypothesis at one
//! location, predicting every measured ratio of a [`DiagnosisData`].
//!
//! # Physics (the simulator's conventions)
//! The model is a [`LinearSystem`] `M x'' + C x' + K x = f - M iota a_g`, `x` relative
//! to the ground; `C = (M Phi) diag(2 xi_i omega_i) (M Phi)^T` from its own
//! mass-normalised modes. The hypothesis changes it ([`Hypothesis::modify_system`],
//! extra DOFs allowed). At each Laplace variable `s` (`j omega`, or `j omega + 1/tau`
//! under an exponential window) the dynamic stiffness `D(s) = K + s C + s^2 M` is
//! factorised once and solved for every right-hand side needed there: a unit force at
//! each excited floor (hammer) and `-M iota` (shake table). Then
//! - displacement / force = `x_f`, absolute acceleration / force = `s^2 x_f`;
//! - displacement / ground acceleration = `x_f` (relative), absolute acceleration /
//!   ground acceleration = `s^2 x_f + 1`;
//! - times `sensor(response, s) / sensor(input, s)` ([`Hypothesis::sensor_factor`]).
//!
//! Segments on the same grid with the same window (all hammer blocks of a campaign)
//! share their factorisations unless the hypothesis is amplitude dependent.
//!
//! Output layout ("flat"): segment by segment, channel by channel, point by point, as in
//! [`DiagnosisData`]; [`ExtendedModel::layout`] gives the ranges.

use super::data::DiagnosisData;
use super::hypothesis::Hypothesis;
use super::location::Location;
use crate::error::{Error, Result};
use crate::frf::FrfKind;
use crate::io::Channel;
use crate::modal::Modes;
use crate::model::StructuralModel;
use crate::simulate::LinearSystem;
use num_complex::Complex64;
use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;

/// Largest number of DOFs of an extended system (model plus extra DOFs): the dense
/// solve per frequency costs `n^3 / 3`; larger models need a reduced basis first.
pub const MAX_DOF: usize = crate::predict::choice::DENSE_MAX_DOF;

/// The nominal model's parameters: the updating variables of paper Eqs. (20)-(21) as
/// scales, and the modal damping ratios.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseParams {
    /// `1 + alpha_r` of each stiffness group (story r's `k_r / k_r0` in a shear frame).
    pub stiffness_scale: Vec<f64>,
    /// `1 + beta_r` of each mass group (floor r's `m_r / m_r0` in a shear frame).
    pub mass_scale: Vec<f64>,
    /// Modal damping ratios of the model's modes (ascending frequency).
    pub xi: Vec<f64>,
}

impl BaseParams {
    /// The scales of physical group values (`k_r` and `m_r` of a shear frame) against
    /// `model`'s nominal ones. Errors when a group has no single physical value.
    pub fn from_physical(
        model: &StructuralModel,
        stiffness: &[f64],
        mass: &[f64],
        xi: Vec<f64>,
    ) -> Result<Self> {
        let scale = |ps: &[crate::model::Parameter], v: &[f64], what: &str| {
            if ps.len() != v.len() {
                return Err(Error::Usage(format!(
                    "{} {what} values for {} groups",
                    v.len(),
                    ps.len()
                )));
            }
            ps.iter()
                .zip(v)
                .map(|(p, x)| match p.nominal {
                    Some(n) => Ok(x / n),
                    None => Err(Error::Usage(format!(
                        "group {} has no physical {what}; give its scale",
                        p.name
                    ))),
                })
                .collect::<Result<Vec<_>>>()
        };
        Ok(BaseParams {
            stiffness_scale: scale(model.alpha_parameters(), stiffness, "stiffness")?,
            mass_scale: scale(model.beta_parameters(), mass, "mass")?,
            xi,
        })
    }

    /// The updating variables `alpha_r = scale_r - 1` and `beta_r`.
    pub fn alpha_beta(&self) -> (Vec<f64>, Vec<f64>) {
        let minus_one = |v: &[f64]| v.iter().map(|s| s - 1.0).collect::<Vec<_>>();
        (
            minus_one(&self.stiffness_scale),
            minus_one(&self.mass_scale),
        )
    }
}

/// The nominal model as a [`LinearSystem`]: `K(alpha)`, `M(beta)` (paper Eqs. 20-21) and
/// modal damping of its own modes (as the simulator's `damping.model = "modal"`; modes
/// beyond `base.xi`, above the analysed band, take its last ratio). A model DOF `d`
/// (0-based) is "floor" `d + 1` (the campaign format's convention).
pub fn frame_system(model: &StructuralModel, base: &BaseParams) -> Result<LinearSystem> {
    let n = model.n_dof();
    if base.stiffness_scale.len() != model.n_alpha()
        || base.mass_scale.len() != model.n_beta()
        || base.xi.is_empty()
        || base.xi.len() > n
    {
        return Err(Error::Usage(format!(
            "the model needs {} stiffness scales, {} mass scales and 1..={n} damping ratios; got {}, {} and {}",
            model.n_alpha(),
            model.n_beta(),
            base.stiffness_scale.len(),
            base.mass_scale.len(),
            base.xi.len()
        )));
    }
    let (alpha, beta) = base.alpha_beta();
    let k = model.stiffness(&alpha);
    let m = model.mass(&beta);
    let iota = model.ground_influence().clone();
    let modes = Modes::solve(&k, &m, &iota, None)?;
    let m_phi = &m * &modes.phi;
    let mut scaled = m_phi.clone();
    let last_xi = base.xi[base.xi.len() - 1];
    for (j, w) in modes.omega_rad_s.iter().enumerate() {
        let x = base.xi.get(j).copied().unwrap_or(last_xi);
        scaled.column_mut(j).scale_mut(2.0 * x * w);
    }
    let c = scaled * m_phi.transpose();
    let c = (&c + c.transpose()) * 0.5;
    Ok(LinearSystem {
        mass_kg: m,
        stiffness_n_per_m: k,
        damping_n_s_per_m: c,
        floor_dof: (0..n).collect(),
        ground_influence: iota,
        base_dof: None,
    })
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Rhs {
    /// Unit force at floor (1-based).
    Force(usize),
    /// `-M iota` (ground acceleration).
    Ground,
}

#[derive(Debug, Clone)]
struct Slot {
    s: Complex64,
    /// Which system: 0 the shared one, `1 + segment` a segment's own.
    variant: usize,
    rhs: Vec<Rhs>,
    /// Offset of the slot's solutions (rhs-major, floors within).
    offset: usize,
}

#[derive(Debug, Clone, Copy)]
struct Point {
    slot: u32,
    rhs: u16,
    /// Floor of the response (1-based).
    floor: u16,
    /// Power of `s` (0 receptance, 2 accelerance).
    power: u8,
    /// Add 1 (absolute acceleration over ground acceleration).
    add_one: bool,
    /// Index into `sensors` of the response channel, if the hypothesis filters it.
    resp_sensor: Option<u16>,
    /// Index into `sensors` of the input channel, if the hypothesis filters it.
    input_sensor: Option<u16>,
}

/// Nominal frame plus an optional hypothesis at a location (see the module docs).
#[derive(Debug, Clone)]
pub struct ExtendedModel {
    data: Arc<DiagnosisData>,
    hypothesis: Option<(Arc<dyn Hypothesis>, Location)>,
    slots: Vec<Slot>,
    points: Vec<Point>,
    n_solutions: usize,
    /// Channels the hypothesis filters.
    sensors: Vec<Channel>,
    /// Per segment, per channel: range in the flat output.
    layout: Vec<Vec<Range<usize>>>,
    /// The estimator's bias added to every prediction (flat; empty: none), from the
    /// data's [`super::data::ChannelData::estimator_bias`].
    bias: Vec<Complex64>,
}

impl ExtendedModel {
    /// The model of `data` with `hypothesis` at its location (`None`: the nominal model).
    pub fn new(
        data: Arc<DiagnosisData>,
        hypothesis: Option<(Arc<dyn Hypothesis>, Location)>,
    ) -> Result<Self> {
        if let Some((h, loc)) = &hypothesis {
            h.parameters(&data, loc)?;
        }
        let per_segment = hypothesis
            .as_ref()
            .is_some_and(|(h, _)| h.amplitude_dependent());
        let mut sensors: Vec<Channel> = Vec::new();
        let mut sensor_index = |c: &Channel| -> Option<u16> {
            let (h, loc) = hypothesis.as_ref()?;
            if !h.affects_channel(loc, c) {
                return None;
            }
            let i = match sensors.iter().position(|o| o == c) {
                Some(i) => i,
                None => {
                    sensors.push(c.clone());
                    sensors.len() - 1
                }
            };
            Some(i as u16)
        };
        let mut slots: Vec<Slot> = Vec::new();
        let mut slot_of: HashMap<(u64, u64, usize), usize> = HashMap::new();
        let mut points = Vec::with_capacity(data.n_points());
        let mut layout = Vec::with_capacity(data.segments.len());
        for (si, seg) in data.segments.iter().enumerate() {
            let rhs = match seg.input {
                crate::signal::InputKind::Force { floor, .. } => Rhs::Force(floor),
                crate::signal::InputKind::Ground { .. } => Rhs::Ground,
            };
            if let Rhs::Force(f) = rhs {
                if f == 0 || f > data.n_floors() {
                    return Err(Error::Usage(format!(
                        "segment {}: force at floor {f}, outside 1..={}",
                        seg.name,
                        data.n_floors()
                    )));
                }
            }
            let variant = if per_segment { 1 + si } else { 0 };
            let s_all = seg.laplace();
            let seg_slots: Vec<(usize, u16)> = s_all
                .iter()
                .map(|s| {
                    let key = (s.re.to_bits(), s.im.to_bits(), variant);
                    let slot = *slot_of.entry(key).or_insert_with(|| {
                        slots.push(Slot {
                            s: *s,
                            variant,
                            rhs: Vec::new(),
                            offset: 0,
                        });
                        slots.len() - 1
                    });
                    let r = match slots[slot].rhs.iter().position(|x| *x == rhs) {
                        Some(r) => r,
                        None => {
                            slots[slot].rhs.push(rhs);
                            slots[slot].rhs.len() - 1
                        }
                    };
                    (slot, r as u16)
                })
                .collect();
            let input_sensor = sensor_index(&seg.input_channel);
            let mut ranges = Vec::with_capacity(seg.channels.len());
            for ch in &seg.channels {
                let start = points.len();
                let floor = ch.channel.floor;
                if floor == 0 || floor > data.n_floors() {
                    return Err(Error::Usage(format!(
                        "channel {} is on floor {floor}, outside 1..={}",
                        ch.channel.name,
                        data.n_floors()
                    )));
                }
                let power = match ch.kind {
                    FrfKind::Receptance => 0,
                    FrfKind::Mobility => 1,
                    FrfKind::Accelerance => 2,
                };
                let resp_sensor = sensor_index(&ch.channel);
                for &k in &ch.freq_index {
                    let (slot, r) = seg_slots[k];
                    points.push(Point {
                        slot: slot as u32,
                        rhs: r,
                        floor: floor as u16,
                        power,
                        add_one: rhs == Rhs::Ground && ch.kind == FrfKind::Accelerance,
                        resp_sensor,
                        input_sensor,
                    });
                }
                ranges.push(start..points.len());
            }
            layout.push(ranges);
        }
        let bias = flat_bias(&data);
        let n_floors = data.n_floors();
        let mut offset = 0;
        for s in &mut slots {
            s.offset = offset;
            offset += s.rhs.len() * n_floors;
        }
        Ok(ExtendedModel {
            data,
            hypothesis,
            slots,
            points,
            n_solutions: offset,
            sensors,
            layout,
            bias,
        })
    }

    /// The data.
    pub fn data(&self) -> &Arc<DiagnosisData> {
        &self.data
    }

    /// The hypothesis and its location (`None` for the nominal model).
    pub fn hypothesis(&self) -> Option<&(Arc<dyn Hypothesis>, Location)> {
        self.hypothesis.as_ref()
    }

    /// Length of the flat output.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Per segment, per channel: its range in the flat output.
    pub fn layout(&self) -> &[Vec<Range<usize>>] {
        &self.layout
    }

    /// Number of distinct `(s, system)` factorisations per evaluation.
    pub fn n_factorisations(&self) -> usize {
        self.slots.len()
    }

    /// The system of the frame with the hypothesis' segment-independent change.
    pub fn system(&self, base: &BaseParams, effect: &[f64]) -> Result<LinearSystem> {
        let mut sys = frame_system(&self.data.model, base)?;
        if let Some((h, loc)) = &self.hypothesis {
            h.modify_system(loc, effect, &mut sys)?;
        }
        Ok(sys)
    }

    /// Predicted ratios into `out` (flat layout, length [`Self::len`]); `effect` holds
    /// the hypothesis' physical values (empty for the nominal model).
    pub fn predict_into(
        &self,
        base: &BaseParams,
        effect: &[f64],
        out: &mut [Complex64],
    ) -> Result<()> {
        self.fill(base, effect, out, true)
    }

    /// The structure's ratios alone (flat layout): the prediction without the data's
    /// estimator bias and without the hypothesis' sensor factors, which is what a
    /// time-domain replay of the tests ([`super::time_domain`]) estimates.
    pub fn predict_structure(&self, base: &BaseParams, effect: &[f64]) -> Result<Vec<Complex64>> {
        let mut out = vec![Complex64::new(0.0, 0.0); self.points.len()];
        self.fill(base, effect, &mut out, false)?;
        Ok(out)
    }

    /// [`Self::predict_into`], with (`measured`) or without the estimator bias and the
    /// sensor factors.
    fn fill(
        &self,
        base: &BaseParams,
        effect: &[f64],
        out: &mut [Complex64],
        measured: bool,
    ) -> Result<()> {
        if out.len() != self.points.len() {
            return Err(Error::Usage(format!(
                "prediction buffer of {} for {} points",
                out.len(),
                self.points.len()
            )));
        }
        let sol = self.solutions(base, effect)?;
        self.assemble(&sol, effect, out, measured);
        Ok(())
    }

    /// The responses at the floors of every slot's right-hand sides (`slot.offset` +
    /// rhs-major, floors within): one factorisation of the dynamic stiffness per slot.
    fn solutions(&self, base: &BaseParams, effect: &[f64]) -> Result<Vec<Complex64>> {
        let sys = self.system(base, effect)?;
        let mut variants: Vec<LinearSystem> = vec![sys];
        if let Some((h, loc)) = &self.hypothesis {
            if h.amplitude_dependent() {
                for seg in &self.data.segments {
                    let mut s = variants[0].clone();
                    h.modify_for_segment(loc, effect, seg, &mut s)?;
                    variants.push(s);
                }
            }
        }
        let n = variants[0].n_dof();
        if n > MAX_DOF {
            return Err(Error::Usage(format!(
                "extended system of {n} DOFs; at most {MAX_DOF}"
            )));
        }
        let n_floors = self.data.n_floors();
        // -M iota of each variant.
        let ground: Vec<Vec<f64>> = variants
            .iter()
            .map(|v| {
                (&v.mass_kg * &v.ground_influence)
                    .iter()
                    .map(|x| -x)
                    .collect()
            })
            .collect();
        let mut sol = vec![Complex64::new(0.0, 0.0); self.n_solutions];
        let max_rhs = self.slots.iter().map(|s| s.rhs.len()).max().unwrap_or(0);
        let mut a = vec![Complex64::new(0.0, 0.0); n * n];
        let mut b = vec![Complex64::new(0.0, 0.0); n * max_rhs];
        for slot in &self.slots {
            let v = &variants[slot.variant];
            let s = slot.s;
            let s2 = s * s;
            for i in 0..n {
                for j in 0..n {
                    a[i * n + j] = v.stiffness_n_per_m[(i, j)]
                        + s * v.damping_n_s_per_m[(i, j)]
                        + s2 * v.mass_kg[(i, j)];
                }
            }
            let nr = slot.rhs.len();
            for (r, rhs) in slot.rhs.iter().enumerate() {
                for i in 0..n {
                    b[i * nr + r] = Complex64::new(0.0, 0.0);
                }
                match rhs {
                    Rhs::Force(f) => b[v.floor_dof[f - 1] * nr + r] = Complex64::new(1.0, 0.0),
                    Rhs::Ground => {
                        for i in 0..n {
                            b[i * nr + r] = Complex64::new(ground[slot.variant][i], 0.0);
                        }
                    }
                }
            }
            solve_in_place(n, &mut a[..n * n], &mut b[..n * nr], nr)
                .map_err(|_| Error::Numerical(format!("dynamic stiffness singular at s = {s}")))?;
            for r in 0..nr {
                for f in 0..n_floors {
                    sol[slot.offset + r * n_floors + f] = b[v.floor_dof[f] * nr + r];
                }
            }
        }
        Ok(sol)
    }

    /// The points' ratios from the slots' solutions `sol`: the FRF kind's power of `s`,
    /// and (`measured`) the estimator's bias and the hypothesis' sensor factors.
    fn assemble(&self, sol: &[Complex64], effect: &[f64], out: &mut [Complex64], measured: bool) {
        let n_floors = self.data.n_floors();
        // Sensor factors per (sensor, slot), computed once.
        let n_slots = self.slots.len();
        let mut factors = Vec::new();
        if let Some((hy, l)) = self.hypothesis.as_ref().filter(|_| measured) {
            factors.reserve(self.sensors.len() * n_slots);
            for c in &self.sensors {
                factors.extend(
                    self.slots
                        .iter()
                        .map(|slot| hy.sensor_factor(l, effect, c, slot.s)),
                );
            }
        }
        let one = Complex64::new(1.0, 0.0);
        let zero = Complex64::new(0.0, 0.0);
        for (k, (o, p)) in out.iter_mut().zip(&self.points).enumerate() {
            let slot = &self.slots[p.slot as usize];
            let s = slot.s;
            let x = sol[slot.offset + p.rhs as usize * n_floors + p.floor as usize - 1];
            let mut h = match p.power {
                0 => x,
                1 => x * s,
                _ => x * s * s,
            };
            if p.add_one {
                h += one;
            }
            // The estimator's bias belongs to the structure's response: a sensor filter
            // (linear, time-invariant) shapes the carried-over ringing as it shapes the
            // rest, so the sensor factors apply to both.
            if measured {
                h += self.bias.get(k).copied().unwrap_or(zero);
                if let Some(i) = p.resp_sensor {
                    h *= factors[i as usize * n_slots + p.slot as usize];
                }
                if let Some(i) = p.input_sensor {
                    h /= factors[i as usize * n_slots + p.slot as usize];
                }
            }
            *o = h;
        }
    }

    /// Predicted ratios (flat layout).
    pub fn predict(&self, base: &BaseParams, effect: &[f64]) -> Result<Vec<Complex64>> {
        let mut out = vec![Complex64::new(0.0, 0.0); self.points.len()];
        self.predict_into(base, effect, &mut out)?;
        Ok(out)
    }
}

/// The data's estimator bias in the flat layout (empty when no channel has one).
fn flat_bias(data: &DiagnosisData) -> Vec<Complex64> {
    if !data.has_estimator_bias() {
        return Vec::new();
    }
    let zero = Complex64::new(0.0, 0.0);
    let mut out = Vec::with_capacity(data.n_points());
    for ch in data.segments.iter().flat_map(|s| &s.channels) {
        match ch.estimator_bias.len() == ch.len() {
            true => out.extend_from_slice(&ch.estimator_bias),
            false => out.extend(std::iter::repeat_n(zero, ch.len())),
        }
    }
    out
}

/// Solves `A X = B` in place by Gaussian elimination with partial pivoting: `a` is
/// `n x n` row-major (destroyed), `b` is `n x nr` row-major and receives `X`.
pub(crate) fn solve_in_place(
    n: usize,
    a: &mut [Complex64],
    b: &mut [Complex64],
    nr: usize,
) -> std::result::Result<(), ()> {
    for c in 0..n {
        let mut p = c;
        let mut best = a[c * n + c].norm_sqr();
        for r in c + 1..n {
            let v = a[r * n + c].norm_sqr();
            if v > best {
                best = v;
                p = r;
            }
        }
        if best == 0.0 || !best.is_finite() {
            return Err(());
        }
        if p != c {
            for j in 0..n {
                a.swap(c * n + j, p * n + j);
            }
            for j in 0..nr {
                b.swap(c * nr + j, p * nr + j);
            }
        }
        let inv = a[c * n + c].inv();
        for r in c + 1..n {
            let f = a[r * n + c] * inv;
            if f == Complex64::new(0.0, 0.0) {
                continue;
            }
            for j in c + 1..n {
                let v = a[c * n + j];
                a[r * n + j] -= f * v;
            }
            for j in 0..nr {
                let v = b[c * nr + j];
                b[r * nr + j] -= f * v;
            }
        }
    }
    for c in (0..n).rev() {
        let inv = a[c * n + c].inv();
        for j in 0..nr {
            let mut v = b[c * nr + j];
            for k in c + 1..n {
                v -= a[c * n + k] * b[k * nr + j];
            }
            b[c * nr + j] = v * inv;
        }
    }
    Ok(())
}
