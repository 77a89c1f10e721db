//! The nominal model of a diagnosis as a [`LinearSystem`]: the campaign's parametrised
//! model (paper Eqs. 20-21) at the sampled stiffness and mass scales, with modal damping
//! of its own modes.

use super::forward_modal::ModalDamping;
use crate::error::{Error, Result};
use crate::modal::Modes;
use crate::model::StructuralModel;
use crate::simulate::LinearSystem;

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
    Ok(frame_system_modal(model, base)?.0)
}

/// [`frame_system`] and the modes and damping it was built from.
pub fn frame_system_modal(
    model: &StructuralModel,
    base: &BaseParams,
) -> Result<(LinearSystem, ModalDamping)> {
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
    let mut two_xi_omega = Vec::with_capacity(n);
    for (j, w) in modes.omega_rad_s.iter().enumerate() {
        let x = base.xi.get(j).copied().unwrap_or(last_xi);
        two_xi_omega.push(2.0 * x * w);
        scaled.column_mut(j).scale_mut(2.0 * x * w);
    }
    let c = scaled * m_phi.transpose();
    let c = (&c + c.transpose()) * 0.5;
    let sys = LinearSystem::on_rigid_ground(m, k, c, iota);
    let modal = ModalDamping {
        omega_sq: modes.omega_rad_s.iter().map(|w| w * w).collect(),
        two_xi_omega,
        phi: modes.phi,
    };
    Ok((sys, modal))
}
