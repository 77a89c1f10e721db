//! A cubic story spring: the story's force becomes `k d + k3 d^3` for the drift `d`
//! across it (hardening for `k3 > 0`, softening for `k3 < 0`), so the response, and the
//! FRFs estimated from it, depend on the excitation level. The simulation integrates it
//! with [`crate::simulate::nonlinear`]; the linear system (modes, `truth.json`) is the
//! small-amplitude linearisation.
//!
//! Harmonic balance on one mode (mass-normalised shape `phi`, drift shape
//! `delta = phi_s - phi_{s-1}`) gives the backbone `omega^2 ~ omega0^2 + (3/4) k3
//! delta^4 A^2` for a modal amplitude `A` (drift amplitude `delta A`).

use crate::error::Result;
use crate::simulate::nonlinear::CubicSpring;
use crate::simulate::system::{LinearSystem, SystemEffect};
use serde::{Deserialize, Serialize};

/// Cubic spring `k3_n_per_m3 d^3` across story `story` (between floors `story - 1` and
/// `story`; floor 0 is the base, flexible or not).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StiffnessNonlinearity {
    pub story: usize,
    pub k3_n_per_m3: f64,
}

impl StiffnessNonlinearity {
    pub(super) fn check(&self, n_floors: usize) -> std::result::Result<(), String> {
        if self.story == 0 || self.story > n_floors {
            return Err(format!(
                "stiffness_nonlinearity story must be in 1..={n_floors} (got {})",
                self.story
            ));
        }
        if !self.k3_n_per_m3.is_finite() {
            return Err("stiffness_nonlinearity k3_n_per_m3 must be finite".into());
        }
        Ok(())
    }

    /// The spring on the DOFs of `system` (resolve after all effects, so that story 1
    /// ends on the base DOF when the base is flexible); `story_stiffness_n_per_m` is the
    /// linear stiffness of the story.
    pub fn spring(
        &self,
        system: &LinearSystem,
        story_stiffness_n_per_m: f64,
    ) -> Result<CubicSpring> {
        Ok(CubicSpring {
            upper_dof: system.dof_of_floor(self.story)?,
            lower_dof: system.dof_of_level(self.story - 1)?,
            k3_n_per_m3: self.k3_n_per_m3,
            linear_stiffness_n_per_m: story_stiffness_n_per_m,
        })
    }
}

impl SystemEffect for StiffnessNonlinearity {
    /// The linear part is the story's own spring: nothing changes in `M`, `K`, `C`.
    fn apply(&self, system: &mut LinearSystem) -> Result<()> {
        system.dof_of_floor(self.story).map(|_| ())
    }
}
