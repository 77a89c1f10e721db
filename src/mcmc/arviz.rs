//! ArviZ's `InferenceData` from ensemble draws, written as one netCDF-4 (HDF5) file that
//! `az.from_netcdf(path)` opens directly ([`INFERENCE_DATA_FILE`]).
//!
//! Groups:
//! - `posterior`: one variable per named parameter, dims `(chain, draw)`;
//! - `sample_stats`: `lp` (log posterior density, as [`Draws::ln_density`]) and, when
//!   given, `acceptance_rate` (the acceptance fraction over the whole run of the walker
//!   that made the draw: the sampler keeps no per-step flag);
//! - `log_likelihood`: the pointwise log-likelihood, dims `(chain, draw, <obs dim>)`,
//!   so that `az.loo` works; it may hold every k-th draw of each walker only (its own
//!   `draw` dimension then is shorter);
//! - `observed_data`: the data, dim `<obs dim>`, with coordinates along it.
//!
//! ## What a chain is
//! An ArviZ chain is one *ensemble* of the sampler; its draws are all its walkers'
//! draws. They are laid out so that ArviZ's split halves are the halves in time: first
//! the first `n / 2` draws of walker 0, then of walker 1, ..., then (odd `n`) the middle
//! draw of every walker, then the last `n / 2` draws of every walker. Then `az.rhat` is
//! exactly the R-hat we report ([`super::ensemble_diagnostics`]: ensembles as chains,
//! their walkers pooled and split in time; for odd `n` the `W` middle draws fall into
//! ArviZ's halves, a difference of order `1 / n`).
//!
//! Our ESS treats every walker as a chain; no layout of one `(chain, draw)` array gives
//! both. `az.ess` of the walker chains (the coordinates below) matches ours within 1 %
//! (`tests/arviz.rs`); `az.ess` of the ensemble chains as stored reads each ensemble's
//! walkers end to end, so its autocovariance at lags beyond a walker's half length
//! pairs different walkers (about 0), where the per-walker estimate keeps the walkers'
//! between-mean variance in every `rho_t`: on a run with 150 draws per walker it came
//! out +4 to +29 % (bulk) and -7 to +24 % (tail) off ours (less with longer walker
//! chains). The other choice, walkers as ArviZ chains (`az.from_emcee`), would give the
//! walker ESS but an R-hat of 1.03-1.04 on the same converged run (short walker chains
//! bias split R-hat up).
//!
//! Non-index coordinates along `draw`: `walker` (walker within its ensemble) and
//! `walker_draw` (the draw's index along that walker's chain, as in `draws.npy`, whose
//! chain is `ensemble x walkers + walker`). In Python,
//! `idata.posterior.set_index(draw=["walker", "walker_draw"]).unstack("draw")` gives
//! `(chain, walker, walker_draw)` back.

use std::path::Path;

use netcdf_writer::{
    DimensionId, NcAttrValue, NcFileBuilder, NcWriteFormat, NcWriteOptions, NcWriteType,
};

use super::draws::Draws;
use crate::error::{Error, Result};
use crate::io::write_atomic_with;

/// The file name written beside `posterior.json`.
pub const INFERENCE_DATA_FILE: &str = "inference_data.nc";

/// The data of the `observed_data` group: one variable along one dimension.
#[derive(Debug, Clone, PartialEq)]
pub struct Observed {
    /// Variable name (as the `log_likelihood` variable, so that ArviZ pairs them).
    pub name: String,
    /// Dimension name (e.g. `point`).
    pub dim: String,
    /// Values, one per observation.
    pub values: Vec<f64>,
    /// Units of the values.
    pub unit: String,
    /// Coordinates along `dim` (name, one value per observation), e.g. `freq_hz`.
    pub coords: Vec<(String, Vec<f64>)>,
    /// Attributes of the variable (e.g. which tests the points come from).
    pub attrs: Vec<(String, String)>,
}

/// An `InferenceData` under construction; [`InferenceData::write`] writes it.
#[derive(Debug, Clone)]
pub struct InferenceData<'a> {
    posterior: &'a Draws,
    names: Vec<String>,
    units: Vec<String>,
    acceptance: Option<Vec<f64>>,
    /// Further `sample_stats` variables (name, one value per draw, walker-chain order).
    stats: Vec<(String, Vec<f64>)>,
    observed: Option<Observed>,
    /// (variable name, observation dimension, draws holding the pointwise terms).
    log_likelihood: Option<(String, String, &'a Draws)>,
    attrs: Vec<(String, String)>,
}

impl<'a> InferenceData<'a> {
    /// The posterior of `draws` (walker chains, `n_walkers` per ensemble) with one name
    /// and unit per parameter.
    pub fn new(draws: &'a Draws, names: &[String], units: &[String]) -> Result<Self> {
        if names.len() != draws.dim || units.len() != draws.dim {
            return Err(Error::Usage(format!(
                "InferenceData: {} names and {} units for {} parameters",
                names.len(),
                units.len(),
                draws.dim
            )));
        }
        check_shape(draws)?;
        Ok(InferenceData {
            posterior: draws,
            names: names.to_vec(),
            units: units.to_vec(),
            acceptance: None,
            stats: Vec::new(),
            observed: None,
            log_likelihood: None,
            attrs: Vec::new(),
        })
    }

    /// Acceptance fraction of every walker chain (`n_chains` values, chain order of the
    /// draws), written to `sample_stats/acceptance_rate`.
    pub fn with_acceptance(mut self, per_chain: Vec<f64>) -> Result<Self> {
        if per_chain.len() != self.posterior.n_chains {
            return Err(Error::Usage(format!(
                "InferenceData: {} acceptance fractions for {} chains",
                per_chain.len(),
                self.posterior.n_chains
            )));
        }
        self.acceptance = Some(per_chain);
        Ok(self)
    }

    /// A further `sample_stats` variable: one value per draw, walker-chain order of the
    /// posterior draws (`chain * n_draws + draw`).
    pub fn with_stat(mut self, name: &str, per_draw: Vec<f64>) -> Result<Self> {
        let n = self.posterior.n_chains * self.posterior.n_draws;
        if per_draw.len() != n {
            return Err(Error::Usage(format!(
                "InferenceData: {} values of {name} for {n} draws",
                per_draw.len()
            )));
        }
        self.stats.push((name.to_string(), per_draw));
        Ok(self)
    }

    /// The `observed_data` group.
    pub fn with_observed(mut self, observed: Observed) -> Result<Self> {
        let n = observed.values.len();
        if let Some((c, v)) = observed.coords.iter().find(|(_, v)| v.len() != n) {
            return Err(Error::Usage(format!(
                "InferenceData: coordinate {c} has {} values for {n} observations",
                v.len()
            )));
        }
        self.observed = Some(observed);
        Ok(self)
    }

    /// The `log_likelihood` group: variable `name` with the pointwise terms of `draws`
    /// (the posterior's chains, possibly fewer draws per chain) along dimension `dim`.
    pub fn with_log_likelihood(mut self, name: &str, dim: &str, draws: &'a Draws) -> Result<Self> {
        if draws.n_pointwise == 0 || draws.pointwise.is_empty() {
            return Err(Error::Usage(
                "InferenceData: the draws hold no pointwise log-likelihood".into(),
            ));
        }
        if (draws.n_chains, draws.n_walkers) != (self.posterior.n_chains, self.posterior.n_walkers)
        {
            return Err(Error::Usage(
                "InferenceData: the log-likelihood draws have other chains than the posterior"
                    .into(),
            ));
        }
        check_shape(draws)?;
        self.log_likelihood = Some((name.to_string(), dim.to_string(), draws));
        Ok(self)
    }

    /// An attribute of every group (e.g. the command that sampled).
    pub fn with_attr(mut self, key: &str, value: &str) -> Self {
        self.attrs.push((key.to_string(), value.to_string()));
        self
    }

    /// Writes the file atomically (netCDF-4 / HDF5).
    pub fn write(&self, path: &Path) -> Result<()> {
        let nc = |e: netcdf_writer::Error| {
            Error::Usage(format!("{}: InferenceData: {e}", path.display()))
        };
        let mut b = NcFileBuilder::new();
        self.add_posterior(&mut b).map_err(nc)?;
        self.add_sample_stats(&mut b).map_err(nc)?;
        if let Some((name, dim, draws)) = &self.log_likelihood {
            self.add_log_likelihood(&mut b, name, dim, draws)
                .map_err(nc)?;
        }
        if let Some(obs) = &self.observed {
            self.add_observed(&mut b, obs).map_err(nc)?;
        }
        let options = NcWriteOptions {
            format: NcWriteFormat::Nc4,
        };
        write_atomic_with(path, |w| {
            b.write(w, options)
                .map(|_| ())
                .map_err(std::io::Error::other)
        })
    }

    fn add_posterior(&self, b: &mut NcFileBuilder) -> NcResult<()> {
        let d = self.posterior;
        let (chain, draw) = chain_draw_dims(b, "posterior", d)?;
        let rows = ensemble_rows(d);
        for (p, (name, unit)) in self.names.iter().zip(&self.units).enumerate() {
            let values: Vec<f64> = rows.iter().map(|&r| d.values[r * d.dim + p]).collect();
            let v = add_draw_var(b, &format!("posterior/{name}"), &[chain, draw], &values)?;
            b.add_variable_attribute(v, "units", NcAttrValue::Chars(unit.clone()))?;
        }
        b.add_group_attribute(
            "posterior",
            "chain_mapping",
            NcAttrValue::Chars(CHAIN_MAPPING.into()),
        )?;
        self.group_attrs(b, "posterior")
    }

    fn add_sample_stats(&self, b: &mut NcFileBuilder) -> NcResult<()> {
        let d = self.posterior;
        let (chain, draw) = chain_draw_dims(b, "sample_stats", d)?;
        let rows = ensemble_rows(d);
        let lp: Vec<f64> = rows.iter().map(|&r| d.ln_density[r]).collect();
        let v = add_draw_var(b, "sample_stats/lp", &[chain, draw], &lp)?;
        b.add_variable_attribute(
            v,
            "long_name",
            NcAttrValue::Chars("log posterior density (unnormalised)".into()),
        )?;
        if let Some(acc) = &self.acceptance {
            let values: Vec<f64> = rows.iter().map(|&r| acc[r / d.n_draws]).collect();
            let v = add_draw_var(b, "sample_stats/acceptance_rate", &[chain, draw], &values)?;
            b.add_variable_attribute(
                v,
                "long_name",
                NcAttrValue::Chars(
                    "acceptance fraction over the run of the walker that made the draw".into(),
                ),
            )?;
        }
        for (name, per_draw) in &self.stats {
            let values: Vec<f64> = rows.iter().map(|&r| per_draw[r]).collect();
            add_draw_var(b, &format!("sample_stats/{name}"), &[chain, draw], &values)?;
        }
        self.group_attrs(b, "sample_stats")
    }

    fn add_log_likelihood(
        &self,
        b: &mut NcFileBuilder,
        name: &str,
        dim: &str,
        d: &Draws,
    ) -> NcResult<()> {
        let (chain, draw) = chain_draw_dims(b, "log_likelihood", d)?;
        let np = d.n_pointwise;
        let obs = index_dim(b, "log_likelihood", dim, np)?;
        let mut values = Vec::with_capacity(d.n_chains * d.n_draws * np);
        for r in ensemble_rows(d) {
            values.extend_from_slice(&d.pointwise[r * np..(r + 1) * np]);
        }
        add_draw_var(
            b,
            &format!("log_likelihood/{name}"),
            &[chain, draw, obs],
            &values,
        )?;
        b.add_group_attribute(
            "log_likelihood",
            "walker_draws_every",
            NcAttrValue::Int64s(vec![
                (d.thin_steps / self.posterior.thin_steps.max(1)) as i64,
            ]),
        )?;
        self.group_attrs(b, "log_likelihood")
    }

    fn add_observed(&self, b: &mut NcFileBuilder, obs: &Observed) -> NcResult<()> {
        let g = "observed_data";
        let dim = index_dim(b, g, &obs.dim, obs.values.len())?;
        for (name, values) in &obs.coords {
            add_var(b, &format!("{g}/{name}"), &[dim], values)?;
        }
        let v = add_var(b, &format!("{g}/{}", obs.name), &[dim], &obs.values)?;
        b.add_variable_attribute(v, "units", NcAttrValue::Chars(obs.unit.clone()))?;
        if !obs.coords.is_empty() {
            let names: Vec<&str> = obs.coords.iter().map(|(n, _)| n.as_str()).collect();
            b.add_variable_attribute(v, "coordinates", NcAttrValue::Chars(names.join(" ")))?;
        }
        for (k, a) in &obs.attrs {
            b.add_variable_attribute(v, k, NcAttrValue::Chars(a.clone()))?;
        }
        self.group_attrs(b, g)
    }

    fn group_attrs(&self, b: &mut NcFileBuilder, group: &str) -> NcResult<()> {
        let lib = [
            ("inference_library", "frfbayes"),
            ("inference_library_version", env!("CARGO_PKG_VERSION")),
        ];
        for (k, v) in lib
            .iter()
            .map(|&(k, v)| (k, v))
            .chain(self.attrs.iter().map(|(k, v)| (k.as_str(), v.as_str())))
        {
            b.add_group_attribute(group, k, NcAttrValue::Chars(v.to_string()))?;
        }
        Ok(())
    }
}

type NcResult<T> = std::result::Result<T, netcdf_writer::Error>;

/// The `chain_mapping` attribute of the posterior group.
const CHAIN_MAPPING: &str = "chain = one ensemble of the affine-invariant ensemble sampler; \
    draw = its walkers' draws, first halves (in time) of every walker, then (odd length) the \
    middle draws, then the second halves; coordinates walker and walker_draw locate each draw";

/// Walker chains must come in whole ensembles.
fn check_shape(d: &Draws) -> Result<()> {
    let ok = d.n_walkers > 0
        && d.n_chains.is_multiple_of(d.n_walkers)
        && d.values.len() == d.n_chains * d.n_draws * d.dim
        && d.ln_density.len() == d.n_chains * d.n_draws
        && (d.pointwise.is_empty() || d.pointwise.len() == d.n_chains * d.n_draws * d.n_pointwise);
    if ok {
        Ok(())
    } else {
        Err(Error::Usage(format!(
            "InferenceData: draws of {} chains x {} draws ({} walkers per ensemble) with \
             inconsistent arrays",
            d.n_chains, d.n_draws, d.n_walkers
        )))
    }
}

/// `(walker within its ensemble, draw along the walker's chain)` of each position of an
/// ensemble chain's draw axis: first halves, middle draws (odd `n_draws`), second halves.
pub fn draw_layout(n_walkers: usize, n_draws: usize) -> Vec<(usize, usize)> {
    let half = n_draws / 2;
    let mut out = Vec::with_capacity(n_walkers * n_draws);
    let ranges = [(0..half), (half..n_draws - half), (n_draws - half..n_draws)];
    for range in ranges {
        for w in 0..n_walkers {
            out.extend(range.clone().map(|d| (w, d)));
        }
    }
    out
}

/// Row indices into the walker-chain arrays of `d` (`chain * n_draws + draw`) in the
/// order `(ensemble, position of `[draw_layout]`)`.
fn ensemble_rows(d: &Draws) -> Vec<usize> {
    let layout = draw_layout(d.n_walkers, d.n_draws);
    let n_ensembles = d.n_chains / d.n_walkers;
    let mut rows = Vec::with_capacity(d.n_chains * d.n_draws);
    for k in 0..n_ensembles {
        rows.extend(
            layout
                .iter()
                .map(|&(w, t)| (k * d.n_walkers + w) * d.n_draws + t),
        );
    }
    rows
}

/// The `chain` and `draw` dimensions of `group` with their coordinates, and the
/// non-index coordinates `walker` and `walker_draw` along `draw`.
fn chain_draw_dims(
    b: &mut NcFileBuilder,
    group: &str,
    d: &Draws,
) -> NcResult<(DimensionId, DimensionId)> {
    let chain = index_dim(b, group, "chain", d.n_chains / d.n_walkers)?;
    let draw = index_dim(b, group, "draw", d.n_walkers * d.n_draws)?;
    let layout = draw_layout(d.n_walkers, d.n_draws);
    let walker: Vec<i64> = layout.iter().map(|&(w, _)| w as i64).collect();
    let walker_draw: Vec<i64> = layout.iter().map(|&(_, t)| t as i64).collect();
    add_var(b, &format!("{group}/walker"), &[draw], &walker)?;
    add_var(b, &format!("{group}/walker_draw"), &[draw], &walker_draw)?;
    Ok((chain, draw))
}

/// A dimension of `n` with its coordinate variable `0..n`.
fn index_dim(b: &mut NcFileBuilder, group: &str, name: &str, n: usize) -> NcResult<DimensionId> {
    let path = format!("{group}/{name}");
    let dim = b.add_dimension_path(&path, n as u64)?;
    let index: Vec<i64> = (0..n as i64).collect();
    add_var(b, &path, &[dim], &index)?;
    Ok(dim)
}

/// A variable along `draw`, listing the non-index coordinates of [`chain_draw_dims`]
/// (without them xarray would read `walker` and `walker_draw` as data variables).
fn add_draw_var(
    b: &mut NcFileBuilder,
    path: &str,
    dims: &[DimensionId],
    values: &[f64],
) -> NcResult<netcdf_writer::VariableId> {
    let v = add_var(b, path, dims, values)?;
    b.add_variable_attribute(
        v,
        "coordinates",
        NcAttrValue::Chars("walker walker_draw".into()),
    )?;
    Ok(v)
}

fn add_var<T: NcWriteType>(
    b: &mut NcFileBuilder,
    path: &str,
    dims: &[DimensionId],
    values: &[T],
) -> NcResult<netcdf_writer::VariableId> {
    let v = b.add_variable_path::<T>(path, dims)?;
    b.write_variable(v, values)?;
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_puts_time_halves_in_arviz_halves() {
        let even = draw_layout(2, 4);
        assert_eq!(
            even,
            vec![
                (0, 0),
                (0, 1),
                (1, 0),
                (1, 1),
                (0, 2),
                (0, 3),
                (1, 2),
                (1, 3)
            ]
        );
        let odd = draw_layout(2, 3);
        assert_eq!(odd, vec![(0, 0), (1, 0), (0, 1), (1, 1), (0, 2), (1, 2)]);
    }

    #[test]
    fn rows_follow_ensembles_then_layout() {
        let d = Draws {
            n_chains: 4,
            n_walkers: 2,
            n_draws: 2,
            dim: 1,
            n_pointwise: 0,
            values: (0..8).map(f64::from).collect(),
            ln_density: vec![0.0; 8],
            pointwise: Vec::new(),
            discarded_steps: 0,
            thin_steps: 1,
        };
        // Ensemble 0 = chains 0, 1; ensemble 1 = chains 2, 3; rows chain * 2 + draw.
        assert_eq!(ensemble_rows(&d), vec![0, 2, 1, 3, 4, 6, 5, 7]);
    }
}
