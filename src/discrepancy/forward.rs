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
//! share their factorisations unless the hypothesis is amplitude dependent. Models of
//! `forward_modal::MODAL_MIN_DOF` (16) DOFs or more skip the factorisation: the
//! nominal modal sum plus the hypothesis' change as a low-rank update gives the same
//! responses (`forward_modal.rs`).
//!
//! Output layout ("flat"): segment by segment, channel by channel, point by point, as in
//! [`DiagnosisData`]; [`ExtendedModel::layout`] gives the ranges.

use super::data::DiagnosisData;
pub(crate) use super::forward_modal::solve_in_place;
use super::forward_modal::{LowRankModal, ModalDamping, MODAL_MIN_DOF};
use super::hypothesis::Hypothesis;
use super::location::Location;
pub use super::nominal_system::{frame_system, frame_system_modal, BaseParams};
use crate::error::{Error, Result};
use crate::frf::FrfKind;
use crate::io::Channel;
use crate::simulate::LinearSystem;
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;

/// Largest number of DOFs of an extended system (model plus extra DOFs): the dense
/// solve per frequency costs `n^3 / 3`; larger models need a reduced basis first.
pub const MAX_DOF: usize = crate::predict::choice::DENSE_MAX_DOF;

/// A right-hand side `b` and its modal coordinates `Phi^T b` (the modal fast path).
type ModalRhs = (Vec<f64>, Vec<f64>);

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
    /// Always the dense solve (the modal path's oracle, [`Self::dense`]).
    force_dense: bool,
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
            force_dense: false,
        })
    }

    /// The same model solved densely at every size (the oracle and baseline of the
    /// modal fast path, `forward_modal.rs`).
    pub fn dense(mut self) -> Self {
        self.force_dense = true;
        self
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
        let (nominal, modal, variants) = self.variants(base, effect)?;
        if let Some(low_rank) = self.low_rank(&nominal, &modal, &variants) {
            return self.modal_solutions(&variants, &low_rank);
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
        // (K, C, M) of each variant, row-major.
        let row_major = |m: &DMatrix<f64>| -> Vec<f64> { m.transpose().as_slice().to_vec() };
        let kcm: Vec<[Vec<f64>; 3]> = variants
            .iter()
            .map(|v| {
                [
                    row_major(&v.stiffness_n_per_m),
                    row_major(&v.damping_n_s_per_m),
                    row_major(&v.mass_kg),
                ]
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
            let [k, c, m] = &kcm[slot.variant];
            for (e, ae) in a.iter_mut().enumerate() {
                *ae = k[e] + s * c[e] + s2 * m[e];
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

    /// The nominal system and its modes, and the systems to solve: the hypothesis'
    /// segment-independent change, then (amplitude dependent) each segment's own.
    fn variants(
        &self,
        base: &BaseParams,
        effect: &[f64],
    ) -> Result<(LinearSystem, ModalDamping, Vec<LinearSystem>)> {
        let (nominal, modal) = frame_system_modal(&self.data.model, base)?;
        let mut sys = nominal.clone();
        if let Some((h, loc)) = &self.hypothesis {
            h.modify_system(loc, effect, &mut sys)?;
        }
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
        Ok((nominal, modal, variants))
    }

    /// Every variant as the nominal modal sum plus a change on at most a quarter of the
    /// nominal DOFs, on models of [`MODAL_MIN_DOF`] DOFs or more; `None`: solve densely.
    fn low_rank<'a>(
        &self,
        nominal: &LinearSystem,
        modal: &'a ModalDamping,
        variants: &[LinearSystem],
    ) -> Option<Vec<LowRankModal<'a>>> {
        if nominal.n_dof() < MODAL_MIN_DOF || self.force_dense {
            return None;
        }
        let max_rank = nominal.n_dof() / 4;
        variants
            .iter()
            .map(|v| LowRankModal::new(nominal, modal, v, max_rank))
            .collect()
    }

    /// True when an evaluation at `(base, effect)` takes the modal fast path.
    pub fn is_modal_at(&self, base: &BaseParams, effect: &[f64]) -> Result<bool> {
        let (nominal, modal, variants) = self.variants(base, effect)?;
        Ok(self.low_rank(&nominal, &modal, &variants).is_some())
    }

    /// The responses at the floors of every slot's right-hand sides (as the dense
    /// solve's), each system (`variants`) solved as its low-rank form `low`.
    fn modal_solutions(
        &self,
        variants: &[LinearSystem],
        low: &[LowRankModal],
    ) -> Result<Vec<Complex64>> {
        let n_floors = self.data.n_floors();
        let zero = Complex64::new(0.0, 0.0);
        let mut sol = vec![zero; self.n_solutions];
        // Each variant's right-hand sides and their modal coordinates.
        let mut cache: Vec<HashMap<Rhs, ModalRhs>> = vec![HashMap::new(); low.len()];
        for slot in &self.slots {
            let v = &variants[slot.variant];
            for r in &slot.rhs {
                cache[slot.variant].entry(*r).or_insert_with(|| {
                    let b: Vec<f64> = match r {
                        Rhs::Force(f) => {
                            let mut b = vec![0.0; v.n_dof()];
                            b[v.floor_dof[f - 1]] = 1.0;
                            b
                        }
                        Rhs::Ground => (&v.mass_kg * &v.ground_influence)
                            .iter()
                            .map(|x| -x)
                            .collect(),
                    };
                    let q = low[slot.variant].project(&b);
                    (b, q)
                });
            }
        }
        for slot in &self.slots {
            let v = &variants[slot.variant];
            let rows = &v.floor_dof[..n_floors];
            let cached = &cache[slot.variant];
            let rhs: Vec<(&[f64], &[f64])> = slot
                .rhs
                .iter()
                .map(|r| {
                    let (b, q) = &cached[r];
                    (b.as_slice(), q.as_slice())
                })
                .collect();
            let out = &mut sol[slot.offset..slot.offset + rhs.len() * n_floors];
            low[slot.variant]
                .solve(slot.s, &rhs, rows, out)
                .map_err(|_| {
                    Error::Numerical(format!("dynamic stiffness singular at s = {}", slot.s))
                })?;
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
