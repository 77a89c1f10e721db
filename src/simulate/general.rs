//! A general linear model as the simulated truth (`[structure] kind = "general"`): the
//! model manifest (`src/model/mtx.rs`) at the true `alpha`, `beta` (paper Eqs. 20-21),
//! sensors on DOFs (1-based, as in the campaign format, `docs/recording-format.md`).
//!
//! ```toml
//! [structure]
//! kind = "general"
//! manifest = "ten-story/model.toml"   # relative to the simulation model file
//! alpha = [0.05, -0.03, ...]          # true stiffness parameters (zeros when absent)
//! beta = [0.02, ...]                  # true mass parameters (zeros when absent)
//! acceleration_dofs = [1, 4, 7, 10]   # accelerometers: channels acc<k>
//! displacement_dofs = [10]            # displacement sensors: channels disp<k>
//! modal_cutoff_hz = 400.0             # optional, see below
//! ```
//!
//! Hammer tests name the impacted DOF (`excited_dof = k`); shake-table tests drive the
//! base through the manifest's ground influence vector. The nominal model written to
//! `campaign.toml` is the manifest itself (`structure = "general"`), so `[nominal]` and
//! the shear-frame effects are not allowed.
//!
//! **Modal basis.** The response is simulated in the truncated basis of the lowest
//! undamped modes ([`super::ModalBasis`], one dense eigensolution): every mode with a
//! natural frequency up to `modal_cutoff_hz`, by default the internal Nyquist frequency
//! `oversampling * output_rate_hz / 2` (modes above it are `oversampling` times past the
//! output Nyquist frequency, where the anti-aliasing filter has removed their dynamics;
//! what is lost is their quasi-static response in the pass band, `phi_r phi_e / omega_i^2`
//! per mode). The number of modes kept and the cutoff are written to `truth.json` and
//! `run.json`.

use super::config::StructureSpec;
use crate::error::{Error, Result};
use crate::model::{ModelManifest, StructuralModel};
use std::path::Path;

/// Loads the manifest of a `kind = "general"` structure and checks the spec against it;
/// returns the model and its parameter vectors (zeros filled in). Errors name `path`.
pub fn load(
    structure: &StructureSpec,
    path: &Path,
) -> Result<(StructuralModel, Vec<f64>, Vec<f64>)> {
    let StructureSpec::General {
        manifest,
        alpha,
        beta,
        acceleration_dofs,
        displacement_dofs,
        modal_cutoff_hz,
    } = structure
    else {
        return Err(Error::Usage("not a general structure".into()));
    };
    let bad = |what: String| Error::invalid(path, format!("structure: {what}"));
    if !manifest.is_file() {
        return Err(bad(format!(
            "manifest {} not found; give the model's TOML manifest relative to this file",
            manifest.display()
        )));
    }
    let model = ModelManifest::load(manifest)
        .map_err(|e| bad(format!("manifest {}: {e}", manifest.display())))?;
    let n = model.n_dof();
    let fill = |given: &[f64], len: usize, key: &str| -> Result<Vec<f64>> {
        match given.len() {
            0 => Ok(vec![0.0; len]),
            l if l == len => Ok(given.to_vec()),
            l => Err(bad(format!(
                "{key} has {l} values but the manifest defines {len} {key} parameters"
            ))),
        }
    };
    let alpha = fill(alpha, model.n_alpha(), "alpha")?;
    let beta = fill(beta, model.n_beta(), "beta")?;
    model
        .validate(&alpha, &beta)
        .map_err(|e| bad(format!("at the true alpha and beta: {e}")))?;
    if acceleration_dofs.is_empty() && displacement_dofs.is_empty() {
        return Err(bad(
            "no sensors; add acceleration_dofs = [...] and/or displacement_dofs = [...] \
             (DOFs 1-based)"
                .into(),
        ));
    }
    for (key, dofs) in [
        ("acceleration_dofs", acceleration_dofs),
        ("displacement_dofs", displacement_dofs),
    ] {
        if let Some(d) = dofs.iter().find(|&&d| d == 0 || d > n) {
            return Err(bad(format!(
                "{key} has DOF {d}, outside 1..={n} (DOFs are 1-based; the model has {n})"
            )));
        }
        if let Some(d) = dofs
            .iter()
            .enumerate()
            .find(|(i, d)| dofs[..*i].contains(d))
        {
            return Err(bad(format!("{key} lists DOF {} twice", d.1)));
        }
    }
    if let Some(f) = modal_cutoff_hz {
        if !(f.is_finite() && *f > 0.0) {
            return Err(bad(format!("modal_cutoff_hz must be positive (got {f})")));
        }
    }
    Ok((model, alpha, beta))
}

/// Resolves a relative manifest path against `dir` (the simulation model's folder).
pub fn resolve_manifest(structure: &mut StructureSpec, dir: &Path) {
    if let StructureSpec::General { manifest, .. } = structure {
        if manifest.is_relative() {
            *manifest = dir.join(&*manifest);
        }
    }
}
