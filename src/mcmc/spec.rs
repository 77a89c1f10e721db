//! Moves as configuration data (e.g. a TOML experiment file):
//!
//! ```toml
//! [[moves]]
//! kind = "stretch"
//! weight = 0.8
//! [[moves]]
//! kind = "de"
//! weight = 0.2
//! ```

use serde::{Deserialize, Serialize};

use super::independence::Independence;
use super::moves::{DifferentialEvolution, Move, Moves, Snooker, Stretch, Walk};
use crate::error::{Error, Result};

/// One built-in move with its parameters (defaults as emcee's).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum MoveSpec {
    /// [`Stretch`] with scale `a` (default 2).
    Stretch {
        #[serde(default = "default_a")]
        a: f64,
    },
    /// [`DifferentialEvolution`]: `gamma0` (default `2.38 / sqrt(2 d)`), `sigma` (1e-5).
    De {
        #[serde(default)]
        gamma0: Option<f64>,
        #[serde(default = "default_sigma")]
        sigma: f64,
    },
    /// [`Snooker`] with step factor `gamma` (default 1.7).
    Snooker {
        #[serde(default = "default_gamma")]
        gamma: f64,
    },
    /// [`Walk`] with a complement subset of `subset` walkers (default: all).
    Walk {
        #[serde(default)]
        subset: Option<usize>,
    },
    /// [`Independence`]: multivariate t proposal with `nu` degrees of freedom (default
    /// 10; `gaussian = true` for a Gaussian) fitted to the complement, covariance
    /// scaled by `scale^2` (default 1).
    Independence {
        #[serde(default = "default_nu")]
        nu: f64,
        #[serde(default)]
        gaussian: bool,
        #[serde(default = "default_scale")]
        scale: f64,
    },
}

fn default_nu() -> f64 {
    10.0
}
fn default_scale() -> f64 {
    1.0
}

fn default_a() -> f64 {
    2.0
}
fn default_sigma() -> f64 {
    1e-5
}
fn default_gamma() -> f64 {
    1.7
}

/// A move and its selection weight.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WeightedMove {
    /// The move.
    #[serde(flatten)]
    pub spec: MoveSpec,
    /// Relative selection probability (> 0; default 1).
    #[serde(default = "default_weight")]
    pub weight: f64,
}

fn default_weight() -> f64 {
    1.0
}

impl MoveSpec {
    /// Builds the move, checking its parameters.
    pub fn build(&self) -> Result<Box<dyn Move>> {
        let bad = |what: String| Err(Error::Usage(what));
        Ok(match *self {
            MoveSpec::Stretch { a } => Box::new(Stretch::new(a)?),
            MoveSpec::De { gamma0, sigma } => {
                if gamma0.is_some_and(|g| !(g.is_finite() && g > 0.0)) {
                    return bad(format!("de: gamma0 must be positive, got {gamma0:?}"));
                }
                if !(sigma.is_finite() && sigma >= 0.0) {
                    return bad(format!("de: sigma must be >= 0, got {sigma}"));
                }
                Box::new(DifferentialEvolution { gamma0, sigma })
            }
            MoveSpec::Snooker { gamma } => {
                if !(gamma.is_finite() && gamma > 0.0) {
                    return bad(format!("snooker: gamma must be positive, got {gamma}"));
                }
                Box::new(Snooker { gamma })
            }
            MoveSpec::Walk { subset } => {
                if subset.is_some_and(|s| s < 2) {
                    return bad("walk: subset must be at least 2".into());
                }
                Box::new(Walk { subset })
            }
            MoveSpec::Independence {
                nu,
                gaussian,
                scale,
            } => Box::new(Independence::new((!gaussian).then_some(nu), scale)?),
        })
    }
}

impl Moves {
    /// A mixture from configuration entries.
    pub fn from_specs(specs: &[WeightedMove]) -> Result<Self> {
        let entries = specs
            .iter()
            .map(|w| Ok((w.spec.build()?, w.weight)))
            .collect::<Result<Vec<_>>>()?;
        Moves::mixture(entries)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct File {
        moves: Vec<WeightedMove>,
    }

    #[test]
    fn moves_from_toml_with_defaults() {
        let f: File = toml::from_str(
            "[[moves]]\nkind = \"stretch\"\nweight = 0.8\n\
             [[moves]]\nkind = \"de\"\nweight = 0.1\n\
             [[moves]]\nkind = \"snooker\"\ngamma = 1.5\nweight = 0.1\n\
             [[moves]]\nkind = \"walk\"\nsubset = 5\n",
        )
        .unwrap();
        assert_eq!(
            f.moves[0],
            WeightedMove {
                spec: MoveSpec::Stretch { a: 2.0 },
                weight: 0.8
            }
        );
        assert_eq!(f.moves[3].weight, 1.0);
        let moves = Moves::from_specs(&f.moves).unwrap();
        assert_eq!(
            moves.describe(),
            "stretch(a=2):0.4, de(gamma0=2.38/sqrt(2d),sigma=0.00001):0.05, \
             snooker(gamma=1.5):0.05, walk(s=5):0.5"
        );
        let ind: File = toml::from_str(
            "[[moves]]\nkind = \"independence\"\n\
             [[moves]]\nkind = \"independence\"\ngaussian = true\nscale = 1.3\n",
        )
        .unwrap();
        assert_eq!(
            Moves::from_specs(&ind.moves).unwrap().describe(),
            "independence(t,nu=10,scale=1):0.5, independence(gaussian,scale=1.3):0.5"
        );
        let bad: File = toml::from_str("[[moves]]\nkind = \"stretch\"\na = 0.5\n").unwrap();
        assert!(Moves::from_specs(&bad.moves).is_err());
        assert!(toml::from_str::<File>("[[moves]]\nkind = \"hop\"\n").is_err());
    }

    #[test]
    fn sampler_config_from_toml_uses_defaults() {
        use crate::mcmc::SamplerConfig;
        let c: SamplerConfig = toml::from_str("n_walkers = 40\nseed = 7\n").unwrap();
        assert_eq!(c, SamplerConfig::new(40, 7));
        assert!(toml::from_str::<SamplerConfig>("n_walkers = 40\nseed = 7\nsteps = 3\n").is_err());
    }
}
