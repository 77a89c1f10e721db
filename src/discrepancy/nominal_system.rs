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
/// beyond `base.xi`, above the analysed band, take the ratios of `OutOfBandDamping`,
/// below). A model DOF `d` (0-based) is "floor" `d + 1` (the campaign format's
/// convention).
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
    let above = OutOfBandDamping::fit(&modes.omega_rad_s[..base.xi.len()], &base.xi);
    let mut two_xi_omega = Vec::with_capacity(n);
    for (j, w) in modes.omega_rad_s.iter().enumerate() {
        let x = base.xi.get(j).copied().unwrap_or_else(|| above.ratio(*w));
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

/// Damping ratios of the modes above the analysed band, which the data see only through
/// their residual flexibility (at a light driving point, the accelerance's feedthrough
/// is most of the response and their damping sets its phase): Rayleigh's law
/// `xi(omega) = a / (2 omega) + b omega / 2` (`a, b >= 0`) fitted by least squares to the
/// band's ratios when it fits them better than one constant ratio does, else that
/// constant (the band's mean ratio).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OutOfBandDamping {
    /// `a / (2 omega) + b omega / 2`, `a` in 1/s, `b` in s.
    Rayleigh { a_per_s: f64, b_s: f64 },
    /// One ratio for every mode above the band.
    Constant(f64),
}

impl OutOfBandDamping {
    /// The law for modes above the band from the band's modes' `omega_rad_s` and ratios
    /// `xi` (module docs); a constant with fewer than two ratios.
    pub fn fit(omega_rad_s: &[f64], xi: &[f64]) -> Self {
        let n = xi.len().min(omega_rad_s.len());
        let mean = xi[..n].iter().sum::<f64>() / n.max(1) as f64;
        let constant = OutOfBandDamping::Constant(if n == 0 { 0.0 } else { mean });
        if n < 2 {
            return constant;
        }
        let (w, x) = (&omega_rad_s[..n], &xi[..n]);
        let ssr = |law: &OutOfBandDamping| -> f64 {
            w.iter()
                .zip(x)
                .map(|(w, x)| (law.ratio(*w) - x).powi(2))
                .sum()
        };
        // Columns 1/(2 omega) and omega/2; normal equations of the 2-parameter fit.
        let (p, q): (Vec<f64>, Vec<f64>) = w.iter().map(|w| (0.5 / w, 0.5 * w)).unzip();
        let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
        let (pp, pq, qq, px, qx) = (
            dot(&p, &p),
            dot(&p, &q),
            dot(&q, &q),
            dot(&p, x),
            dot(&q, x),
        );
        let det = pp * qq - pq * pq;
        let mut candidates = vec![
            OutOfBandDamping::Rayleigh {
                a_per_s: (px / pp).max(0.0),
                b_s: 0.0,
            },
            OutOfBandDamping::Rayleigh {
                a_per_s: 0.0,
                b_s: (qx / qq).max(0.0),
            },
        ];
        if det > 1e-12 * pp * qq {
            let (a, b) = ((qq * px - pq * qx) / det, (pp * qx - pq * px) / det);
            if a >= 0.0 && b >= 0.0 {
                candidates.push(OutOfBandDamping::Rayleigh { a_per_s: a, b_s: b });
            }
        }
        let best = candidates
            .into_iter()
            .min_by(|l, r| ssr(l).total_cmp(&ssr(r)))
            .unwrap_or(constant);
        // (A NaN fit, as from a rigid-body mode at omega = 0, compares false.)
        if ssr(&best) < ssr(&constant) {
            best
        } else {
            constant
        }
    }

    /// The damping ratio of a mode at `omega_rad_s`.
    pub fn ratio(&self, omega_rad_s: f64) -> f64 {
        match *self {
            OutOfBandDamping::Rayleigh { a_per_s, b_s } => {
                0.5 * a_per_s / omega_rad_s + 0.5 * b_s * omega_rad_s
            }
            OutOfBandDamping::Constant(xi) => xi,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::OutOfBandDamping;

    #[test]
    fn a_rayleigh_band_extrapolates_by_its_law_and_a_flat_one_stays_flat() {
        let w = [10.0, 30.0, 55.0, 80.0];
        let law = |w: f64| 0.5 * 0.4 / w + 0.5 * 6e-4 * w;
        let xi: Vec<f64> = w.iter().map(|w| law(*w)).collect();
        let fit = OutOfBandDamping::fit(&w, &xi);
        for w in [200.0, 1000.0] {
            assert!((fit.ratio(w) - law(w)).abs() < 1e-12 * law(w), "{fit:?}");
        }
        let flat = OutOfBandDamping::fit(&w, &[0.02; 4]);
        assert_eq!(flat, OutOfBandDamping::Constant(0.02));
        assert_eq!(
            OutOfBandDamping::fit(&w[..1], &[0.03]),
            OutOfBandDamping::Constant(0.03)
        );
        // Stiffness-proportional only: the mass term is clamped at zero.
        let xi: Vec<f64> = w.iter().map(|w| 0.5 * 1e-3 * w).collect();
        match OutOfBandDamping::fit(&w, &xi) {
            OutOfBandDamping::Rayleigh { a_per_s, b_s } => {
                assert!(a_per_s.abs() < 1e-12 && (b_s - 1e-3).abs() < 1e-12)
            }
            other => panic!("{other:?}"),
        }
    }
}
