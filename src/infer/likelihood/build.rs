//! The constructors of [`Block`]: each observation kind from its data, with its
//! inputs checked (finite, positive, matching lengths).

use std::ops::Range;

use super::{shared_factors, Block, BlockKind, Chain, Correlation, NoiseScale, Transform};
use crate::error::{Error, Result};

impl Block {
    /// Values observed with standard deviations `sd`, compared after `transform`
    /// (`sd` is in the transformed unit).
    pub fn values(
        name: &str,
        predictions: Range<usize>,
        observed: &[f64],
        sd: &[f64],
        transform: Transform,
        scale: NoiseScale,
    ) -> Result<Self> {
        let n = predictions.len();
        if observed.len() != n || sd.len() != n {
            return Err(Error::Usage(format!(
                "{name}: {} predictions, {} observations, {} standard deviations",
                n,
                observed.len(),
                sd.len()
            )));
        }
        check_positive(name, sd)?;
        let observed: Vec<f64> = observed.iter().map(|&v| transform.apply(v)).collect();
        check_finite(name, "observed (transformed)", &observed)?;
        Self::checked(
            name,
            predictions,
            BlockKind::Values {
                observed,
                inv_sd: sd.iter().map(|s| 1.0 / s).collect(),
                transform,
            },
            scale,
        )
    }

    /// Values as [`Self::values`] with noise shared at a known size: `loadings` is `L`
    /// (`n x rank`, row-major, in the transformed unit), `cov = sigma^2 diag(sd^2) + L L^T`.
    pub fn shared_noise(
        name: &str,
        predictions: Range<usize>,
        observed: &[f64],
        sd: &[f64],
        transform: Transform,
        loadings: (&[f64], usize),
        scale: NoiseScale,
    ) -> Result<Self> {
        let correlation = Correlation {
            shared: Some(loadings),
            chain: &[],
        };
        Self::correlated_values(
            name,
            predictions,
            observed,
            sd,
            transform,
            correlation,
            scale,
        )
    }

    /// Values as [`Self::values`] whose noise is correlated as `correlation` says: a
    /// [`BlockKind::SharedNoise`] block when it has shared loadings, and the values' own
    /// noise whitened along a [`Chain`] when it has one (the chain must start a run at
    /// the block's first value).
    pub fn correlated_values(
        name: &str,
        predictions: Range<usize>,
        observed: &[f64],
        sd: &[f64],
        transform: Transform,
        correlation: Correlation<'_>,
        scale: NoiseScale,
    ) -> Result<Self> {
        let mut block = Self::values(name, predictions, observed, sd, transform, scale)?;
        let n = block.predictions.len();
        if !correlation.chain.is_empty() && correlation.chain.len() != n {
            return Err(Error::Usage(format!(
                "{name}: {} bin correlations for {n} values",
                correlation.chain.len()
            )));
        }
        let chain =
            Chain::new(correlation.chain).map_err(|e| Error::Usage(format!("{name}: {e}")))?;
        if chain.as_ref().is_some_and(|c| !c.starts_a_run()) {
            return Err(Error::Usage(format!(
                "{name}: its correlated bins continue a chain from before the block"
            )));
        }
        if let Some((loadings, rank)) = correlation.shared {
            let BlockKind::Values {
                observed, inv_sd, ..
            } = block.kind
            else {
                unreachable!("Block::values builds a Values block")
            };
            let factors = shared_factors(loadings, rank, &inv_sd, chain.as_ref())
                .map_err(|e| Error::Usage(format!("{name}: {e}")))?;
            block.kind = BlockKind::SharedNoise {
                observed,
                inv_sd,
                transform,
                factors,
            };
        }
        block.chain = chain;
        Ok(block)
    }

    /// A measured shape against a predicted one, amplitude integrated out.
    pub fn shape_mac(
        name: &str,
        predictions: Range<usize>,
        observed: &[f64],
        scale: NoiseScale,
    ) -> Result<Self> {
        check_finite(name, "shape", observed)?;
        let norm = observed.iter().map(|v| v * v).sum::<f64>().sqrt();
        if observed.len() != predictions.len() || observed.len() < 2 || norm == 0.0 {
            return Err(Error::Usage(format!(
                "{name}: a shape needs at least 2 non-zero entries, one per predicted DOF ({})",
                predictions.len()
            )));
        }
        let observed_unit = observed.iter().map(|v| v / norm).collect();
        Self::checked(
            name,
            predictions,
            BlockKind::ShapeMac { observed_unit },
            scale,
        )
    }

    /// SMU's eigenvector difference about entry `reference`, weights per entry (the
    /// reference entry's weight is not used).
    pub fn shape_difference(
        name: &str,
        predictions: Range<usize>,
        observed: &[f64],
        reference: usize,
        weight: &[f64],
        scale: NoiseScale,
    ) -> Result<Self> {
        check_finite(name, "shape", observed)?;
        check_finite(name, "weight", weight)?;
        let n = predictions.len();
        if observed.len() != n || weight.len() != n || reference >= n {
            return Err(Error::Usage(format!(
                "{name}: {} shape entries, {} weights, reference {reference}, {n} predicted DOFs",
                observed.len(),
                weight.len()
            )));
        }
        if observed[reference] == 0.0 || weight.iter().any(|w| *w <= 0.0) {
            return Err(Error::Usage(format!(
                "{name}: the reference entry must be non-zero and every weight positive"
            )));
        }
        let observed = observed.iter().map(|v| v / observed[reference]).collect();
        let kind = BlockKind::ShapeDifference {
            observed,
            reference,
            weight: weight.to_vec(),
        };
        Self::checked(name, predictions, kind, scale)
    }

    /// Complex values (`observed`: real and imaginary parts interleaved, `2n` entries)
    /// with complex standard deviations `sd_complex` (`n` entries, `sqrt(E|e|^2)`) against
    /// predictions times an unknown real gain, integrated out (see the module docs).
    pub fn complex_gain(
        name: &str,
        predictions: Range<usize>,
        observed: &[f64],
        sd_complex: &[f64],
        scale: NoiseScale,
    ) -> Result<Self> {
        Self::complex_linear(name, predictions, observed, sd_complex, 1, scale)
    }

    /// Complex values as in [`Self::complex_gain`] against `n_columns` real columns of
    /// predictions (`n_columns x 2n`, column-major) with unknown coefficients integrated
    /// out (see [`linear`]).
    pub fn complex_linear(
        name: &str,
        predictions: Range<usize>,
        observed: &[f64],
        sd_complex: &[f64],
        n_columns: usize,
        scale: NoiseScale,
    ) -> Result<Self> {
        check_finite(name, "observed", observed)?;
        let n = sd_complex.len();
        if observed.len() != 2 * n || predictions.len() != 2 * n * n_columns || 2 * n <= n_columns {
            return Err(Error::Usage(format!(
                "{name}: {} predictions and {} observed parts for {n} complex values and \
                 {n_columns} columns (need 2n > columns)",
                predictions.len(),
                observed.len()
            )));
        }
        check_positive(name, sd_complex)?;
        let inv_sd: Vec<f64> = sd_complex
            .iter()
            .flat_map(|s| [2f64.sqrt() / s; 2])
            .collect();
        let observed = observed.iter().zip(&inv_sd).map(|(y, w)| y * w).collect();
        let kind = BlockKind::LinearMarginal {
            observed,
            inv_sd,
            n_columns,
        };
        Self::checked(name, predictions, kind, scale)
    }

    fn checked(
        name: &str,
        predictions: Range<usize>,
        kind: BlockKind,
        scale: NoiseScale,
    ) -> Result<Self> {
        if let NoiseScale::Fixed(s) = scale {
            if !(s.is_finite() && s > 0.0) {
                return Err(Error::Usage(format!(
                    "{name}: noise scale {s} must be positive"
                )));
            }
        }
        Ok(Block {
            name: name.to_string(),
            predictions,
            kind,
            scale,
            chain: None,
        })
    }
}

fn check_finite(name: &str, what: &str, v: &[f64]) -> Result<()> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(Error::Usage(format!(
            "{name}: {what} entry {i} is {}",
            v[i]
        ))),
        None => Ok(()),
    }
}

fn check_positive(name: &str, sd: &[f64]) -> Result<()> {
    match sd.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
        Some(i) => Err(Error::Usage(format!(
            "{name}: standard deviation {i} is {}; it must be positive",
            sd[i]
        ))),
        None => Ok(()),
    }
}
