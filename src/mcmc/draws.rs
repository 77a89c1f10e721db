//! Posterior draws after burn-in and thinning, their summaries, and writers: CSV, and
//! `.npy` shaped `(chain, draw, dim)` as ArviZ expects (`az.from_dict(posterior=...)`,
//! `log_likelihood=` from the pointwise array).

use std::path::Path;

use ndarray::{Array2, Array3};
use ndarray_npy::WriteNpyExt;
use rayon::prelude::*;
use serde::Serialize;

use super::convergence::{ensemble_diagnostics, ess_mean, quantile, Diagnostics};
use super::density::{checked_ln_density, LogDensity};
use super::ensemble::Ensemble;
use crate::error::{Error, Result};
use crate::io::write_atomic_with;

/// Draws of `n_chains` chains (every walker of every ensemble is a chain).
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct Draws {
    /// Chains (ensembles x walkers).
    pub n_chains: usize,
    /// Walkers per ensemble (consecutive chains form one ensemble).
    pub n_walkers: usize,
    /// Draws per chain.
    pub n_draws: usize,
    /// Parameters.
    pub dim: usize,
    /// Pointwise log-likelihood terms per draw (0 when not stored).
    pub n_pointwise: usize,
    /// Values, row-major `(chain, draw, dim)`.
    pub values: Vec<f64>,
    /// Log density, `(chain, draw)`.
    pub ln_density: Vec<f64>,
    /// Pointwise log-likelihood, `(chain, draw, term)`; empty when not stored.
    pub pointwise: Vec<f64>,
    /// Steps discarded as burn-in.
    pub discarded_steps: u64,
    /// Steps between kept draws.
    pub thin_steps: u64,
}

/// Summary of one parameter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ParamSummary {
    /// Posterior mean.
    pub mean: f64,
    /// Posterior standard deviation.
    pub sd: f64,
    /// Monte Carlo standard error of the mean, `sd / sqrt(ess_mean)`.
    pub mcse_mean: f64,
    /// 5%, 50%, 95% quantiles.
    pub q05: f64,
    /// Median.
    pub q50: f64,
    /// 95% quantile.
    pub q95: f64,
    /// R-hat (ensembles as chains) and ESS (walkers as chains); see
    /// [`ensemble_diagnostics`](super::ensemble_diagnostics).
    pub diagnostics: Diagnostics,
}

impl Draws {
    pub(crate) fn from_ensembles(
        ensembles: &[Ensemble],
        kept: &[usize],
        dim: usize,
        discarded_steps: u64,
        thin_steps: u64,
    ) -> Self {
        let w = ensembles[0].n_walkers();
        let np = ensembles[0].n_pointwise;
        let n_chains = ensembles.len() * w;
        let n_draws = kept.len();
        let mut values = Vec::with_capacity(n_chains * n_draws * dim);
        let mut ln_density = Vec::with_capacity(n_chains * n_draws);
        let mut pointwise = Vec::with_capacity(n_chains * n_draws * np);
        for e in ensembles {
            for i in 0..w {
                for &t in kept {
                    let s = t * w + i;
                    values.extend_from_slice(&e.chain[s * dim..(s + 1) * dim]);
                    ln_density.push(e.chain_ln_p[s]);
                    pointwise.extend_from_slice(&e.chain_pointwise[s * np..(s + 1) * np]);
                }
            }
        }
        Draws {
            n_chains,
            n_walkers: w,
            n_draws,
            dim,
            n_pointwise: np,
            values,
            ln_density,
            pointwise,
            discarded_steps,
            thin_steps,
        }
    }

    /// Draw `draw` of chain `chain`.
    pub fn draw(&self, chain: usize, draw: usize) -> &[f64] {
        let s = chain * self.n_draws + draw;
        &self.values[s * self.dim..(s + 1) * self.dim]
    }

    /// `f(theta)` for every draw, one vector per chain (input to the diagnostics).
    pub fn map_chains(&self, f: impl Fn(&[f64]) -> f64 + Sync) -> Vec<Vec<f64>> {
        (0..self.n_chains)
            .into_par_iter()
            .map(|c| (0..self.n_draws).map(|d| f(self.draw(c, d))).collect())
            .collect()
    }

    /// Parameter `p` as chains.
    pub fn param_chains(&self, p: usize) -> Vec<Vec<f64>> {
        self.map_chains(|x| x[p])
    }

    /// Posterior mean of every parameter.
    pub fn mean(&self) -> Vec<f64> {
        let n = (self.n_chains * self.n_draws) as f64;
        let mut m = vec![0.0; self.dim];
        for x in self.values.chunks(self.dim) {
            for (a, b) in m.iter_mut().zip(x) {
                *a += b;
            }
        }
        m.iter_mut().for_each(|a| *a /= n);
        m
    }

    /// Posterior covariance (denominator `n - 1`), row-major `dim x dim`.
    pub fn covariance(&self) -> Vec<f64> {
        let n = (self.n_chains * self.n_draws) as f64;
        let m = self.mean();
        let d = self.dim;
        let mut c = vec![0.0; d * d];
        for x in self.values.chunks(d) {
            for i in 0..d {
                for j in 0..d {
                    c[i * d + j] += (x[i] - m[i]) * (x[j] - m[j]);
                }
            }
        }
        c.iter_mut().for_each(|a| *a /= n - 1.0);
        c
    }

    /// Mean, sd, MCSE, quantiles, R-hat and ESS of every parameter.
    pub fn summary(&self) -> Vec<ParamSummary> {
        (0..self.dim)
            .into_par_iter()
            .map(|p| {
                let chains = self.param_chains(p);
                let mut all: Vec<f64> = chains.iter().flatten().copied().collect();
                let n = all.len() as f64;
                let mean = all.iter().sum::<f64>() / n;
                let sd = (all.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
                all.sort_by(f64::total_cmp);
                ParamSummary {
                    mean,
                    sd,
                    mcse_mean: sd / ess_mean(&chains).sqrt(),
                    q05: quantile(&all, 0.05),
                    q50: quantile(&all, 0.5),
                    q95: quantile(&all, 0.95),
                    diagnostics: ensemble_diagnostics(&chains, self.n_walkers),
                }
            })
            .collect()
    }

    /// Every `every`-th draw of each chain (draws 0, every, 2 every, ...), with its log
    /// density and pointwise terms; `thin_steps` scaled accordingly. `every = 1` is a copy.
    pub fn thinned(&self, every: usize) -> Draws {
        let every = every.max(1);
        let kept: Vec<usize> = (0..self.n_draws).step_by(every).collect();
        let (dim, np) = (self.dim, self.n_pointwise);
        let mut out = Draws {
            n_draws: kept.len(),
            values: Vec::with_capacity(self.n_chains * kept.len() * dim),
            ln_density: Vec::with_capacity(self.n_chains * kept.len()),
            pointwise: Vec::with_capacity(self.n_chains * kept.len() * np),
            thin_steps: self.thin_steps * every as u64,
            ..self.clone_header()
        };
        for c in 0..self.n_chains {
            for &d in &kept {
                let r = c * self.n_draws + d;
                out.values
                    .extend_from_slice(&self.values[r * dim..(r + 1) * dim]);
                out.ln_density.push(self.ln_density[r]);
                if np > 0 && !self.pointwise.is_empty() {
                    out.pointwise
                        .extend_from_slice(&self.pointwise[r * np..(r + 1) * np]);
                }
            }
        }
        out
    }

    /// The shape fields without the arrays.
    fn clone_header(&self) -> Draws {
        Draws {
            values: Vec::new(),
            ln_density: Vec::new(),
            pointwise: Vec::new(),
            ..*self
        }
    }

    /// Evaluates `density`'s pointwise log-likelihood at every draw (in parallel) and
    /// stores it in [`Draws::pointwise`]. An alternative to `store_pointwise` when the
    /// terms are many: storing them for every stored step costs
    /// `steps / thin_by x walkers x terms` values, this only `draws x terms`.
    pub fn compute_pointwise<D: LogDensity + ?Sized>(&mut self, density: &D) -> Result<()> {
        let np = density.n_pointwise();
        if np == 0 {
            return Err(Error::Usage(
                "the density gives no pointwise log-likelihood (n_pointwise() = 0)".into(),
            ));
        }
        let rows: Vec<Result<Vec<f64>>> = self
            .values
            .par_chunks(self.dim)
            .map(|theta| {
                let mut pw = vec![0.0; np];
                checked_ln_density(density, theta, &mut pw)?;
                Ok(pw)
            })
            .collect();
        let mut pointwise = Vec::with_capacity(rows.len() * np);
        for r in rows {
            pointwise.extend(r?);
        }
        self.pointwise = pointwise;
        self.n_pointwise = np;
        Ok(())
    }

    /// CSV with columns `chain, draw, <names...>, ln_density` (written atomically).
    pub fn write_csv(&self, path: &Path, names: &[String]) -> Result<()> {
        if names.len() != self.dim {
            return Err(Error::Usage(format!(
                "{} parameter names for {} parameters",
                names.len(),
                self.dim
            )));
        }
        write_atomic_with(path, |w| {
            let mut out = csv::Writer::from_writer(w);
            let mut header = vec!["chain".to_string(), "draw".to_string()];
            header.extend(names.iter().cloned());
            header.push("ln_density".into());
            out.write_record(&header)?;
            for c in 0..self.n_chains {
                for d in 0..self.n_draws {
                    let mut rec = vec![c.to_string(), d.to_string()];
                    rec.extend(self.draw(c, d).iter().map(|v| format!("{v:e}")));
                    rec.push(format!("{:e}", self.ln_density[c * self.n_draws + d]));
                    out.write_record(&rec)?;
                }
            }
            out.flush()
        })
    }

    /// `.npy` of the draws, shape `(chain, draw, dim)`.
    pub fn write_npy(&self, path: &Path) -> Result<()> {
        let a =
            Array3::from_shape_vec((self.n_chains, self.n_draws, self.dim), self.values.clone())
                .map_err(|e| Error::Numerical(e.to_string()))?;
        write_npy_atomic(path, |w| a.write_npy(w))
    }

    /// `.npy` of the log density, shape `(chain, draw)`.
    pub fn write_ln_density_npy(&self, path: &Path) -> Result<()> {
        let a = Array2::from_shape_vec((self.n_chains, self.n_draws), self.ln_density.clone())
            .map_err(|e| Error::Numerical(e.to_string()))?;
        write_npy_atomic(path, |w| a.write_npy(w))
    }

    /// `.npy` of the pointwise log-likelihood, shape `(chain, draw, term)`.
    pub fn write_pointwise_npy(&self, path: &Path) -> Result<()> {
        if self.n_pointwise == 0 {
            return Err(Error::Usage(
                "no pointwise log-likelihood stored (set store_pointwise and implement \
                 ln_density_with_pointwise)"
                    .into(),
            ));
        }
        let a = Array3::from_shape_vec(
            (self.n_chains, self.n_draws, self.n_pointwise),
            self.pointwise.clone(),
        )
        .map_err(|e| Error::Numerical(e.to_string()))?;
        write_npy_atomic(path, |w| a.write_npy(w))
    }
}

fn write_npy_atomic(
    path: &Path,
    f: impl FnOnce(&mut dyn std::io::Write) -> std::result::Result<(), ndarray_npy::WriteNpyError>,
) -> Result<()> {
    write_atomic_with(path, |w| f(w).map_err(std::io::Error::other))
}
