//! `stiffness_nonlinearity`: a cubic story spring, force `k d + k3 d^3` for the drift `d`
//! (hardening for `k3 > 0`), so the FRFs depend on the excitation level.
//!
//! Forward model: equivalent linearisation per segment (Caughey 1963). In each segment
//! the cubic term acts as the linear spring `k3 c` added across the story, where
//! `c = sum (w d)^2 d^2 / sum (w d)^2` is measured from the segment's displacement
//! channels (or its accelerometers, integrated twice) under the estimator's window `w`
//! ([`SegmentData::story_drift_lin_sq_m2`]):
//! the `k_eq` minimising the windowed mean square of `k3 d^3 - k_eq d`, which is what the
//! least-squares H1 estimate sees. It is `3 A^2 / 4` for a sinusoid (harmonic balance),
//! `3 sigma^2` for Gaussian drift, and in between for a hammer's decaying modes.
//! Neglected: the frequency dependence of the equivalent stiffness within a segment
//! (one `k_eq` for all modes; a chirp's amplitude changes along the sweep), and the
//! harmonics (the third harmonic of mode 1 can drive a mode near three times its
//! frequency). A segment without sensors on both levels of the story is treated as
//! linear. Every story is a candidate location; one where no segment has that weight
//! cannot be tested, and its search reports why (it is not dropped in silence).
//!
//! Prior: the relative stiffness change at the largest measured weight,
//! `r = k3 c_max / k_s0` (`k_s0` nominal), uniform on -0.4..0.5 (so the linearised
//! story keeps at least 60 % of its nominal stiffness); reported as `k3` (N/m^3). The
//! nominal model is `k3 = 0`.

use crate::discrepancy::data::{DiagnosisData, SegmentData};
use crate::discrepancy::hypothesis::{
    shear_frame_locations, shear_frame_only, Coordinate, EffectParam, Hypothesis,
};
use crate::discrepancy::location::Location;
use crate::error::{Error, Result};
use crate::simulate::{CubicSpring, LinearSystem};

#[derive(Debug, Clone, Copy, Default)]
pub struct StiffnessNonlinearityHypothesis;

/// Lower and upper bound of the relative stiffness change `r`.
const REL_CHANGE: (f64, f64) = (-0.4, 0.5);

fn story_of(loc: &Location, n_floors: usize) -> Result<usize> {
    match loc {
        Location::Story(s) if (1..=n_floors).contains(s) => Ok(*s),
        other => Err(Error::Usage(format!(
            "stiffness_nonlinearity acts on a story 1..={n_floors}, not on {other}"
        ))),
    }
}

impl Hypothesis for StiffnessNonlinearityHypothesis {
    fn name(&self) -> &'static str {
        "stiffness_nonlinearity"
    }

    fn physics(&self) -> &'static str {
        "a story spring is nonlinear (cubic): its stiffness changes with the vibration amplitude"
    }

    fn locations(&self, data: &DiagnosisData) -> Vec<Location> {
        shear_frame_locations(data, (1..=data.n_floors()).map(Location::Story).collect())
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        shear_frame_only(self.name(), data)?;
        let s = story_of(loc, data.n_floors())?;
        let c_max = data
            .max_story_drift_lin_sq_m2(s)
            .filter(|m| *m > 0.0)
            .ok_or_else(|| {
                let floors = match s {
                    1 => "floor 1".to_string(),
                    _ => format!("floors {} and {s}", s - 1),
                };
                Error::Usage(format!(
                    "not testable: the drift of story {s} is not measured in any segment \
                     (it needs a displacement sensor or an accelerometer on {floors})"
                ))
            })?;
        let factor = data.nominal.story_stiffness_n_per_m[s - 1] / c_max;
        Ok(vec![EffectParam {
            name: "k3".into(),
            unit: "N/m^3",
            coordinate_name: "rel_stiffness_change".into(),
            lower: REL_CHANGE.0,
            upper: REL_CHANGE.1,
            coordinate: Coordinate::Linear { factor },
            no_effect: Some(0.0),
        }])
    }

    fn amplitude_dependent(&self) -> bool {
        true
    }

    /// Adds `k3 c` across the story (`effect[0] = k3`, N/m^3; `c` the segment's weight).
    fn modify_for_segment(
        &self,
        loc: &Location,
        effect: &[f64],
        seg: &SegmentData,
        sys: &mut LinearSystem,
    ) -> Result<()> {
        let s = story_of(loc, sys.n_floors())?;
        let Some(c) = seg.story_drift_lin_sq_m2.get(s - 1).copied().flatten() else {
            return Ok(());
        };
        let dk = effect[0] * c;
        let a = sys.dof_of_floor(s)?;
        let b = sys.dof_of_level(s - 1)?;
        let k = &mut sys.stiffness_n_per_m;
        k[(a, a)] += dk;
        if let Some(b) = b {
            k[(b, b)] += dk;
            k[(a, b)] -= dk;
            k[(b, a)] -= dk;
        }
        Ok(())
    }

    /// The cubic spring across the story (`effect[0] = k3`, N/m^3), for the replay of
    /// the tests; its linear stiffness (for the stability check) is read off `sys`.
    fn cubic_springs(
        &self,
        loc: &Location,
        effect: &[f64],
        sys: &LinearSystem,
    ) -> Result<Vec<CubicSpring>> {
        let s = story_of(loc, sys.n_floors())?;
        let a = sys.dof_of_floor(s)?;
        let b = sys.dof_of_level(s - 1)?;
        let k = &sys.stiffness_n_per_m;
        // Story s's spring is the coupling -K[a, b]; story 1 on a rigid base is what
        // K[a, a] holds beyond the coupling to the floor above.
        let linear = match b {
            Some(b) => -k[(a, b)],
            None => {
                let above = sys.dof_of_floor(s + 1).ok().map_or(0.0, |u| -k[(a, u)]);
                k[(a, a)] - above
            }
        };
        Ok(vec![CubicSpring {
            upper_dof: a,
            lower_dof: b,
            k3_n_per_m3: effect[0],
            linear_stiffness_n_per_m: linear,
        }])
    }
}
