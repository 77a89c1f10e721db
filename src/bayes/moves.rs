//! The sampler's move mixtures of `frfbayes sample` (re-exported by [`super::run`]).

use crate::mcmc::{MoveSpec, WeightedMove};

/// The default move mixture: 0.5 differential evolution + 0.5 independence
/// ([`crate::mcmc::Independence`], a multivariate t with 10 degrees of freedom fitted to
/// the complementary half-ensemble), with 12 x dim walkers per ensemble.
///
/// Measured on the four-story campaign (hammer tests, Caughey receptance, 13 parameters,
/// 4 ensembles, seed 1, one thread, `tests/bayes_bench.rs`; smallest bulk ESS per second
/// of sampling, same session): 0.9 DE + 0.1 stretch with 4 x dim walkers 2318/s (the
/// former default; 8 x dim: 2838/s), 0.5 DE + 0.5 independence with 4 x dim 2826/s,
/// 8 x dim 7789/s, 12 x dim 10656/s, 0.3 DE + 0.7 independence with 8 x dim 8936/s. The
/// independence proposal needs a complement well above the dimension (its covariance
/// estimate), hence the larger ensembles; DE keeps the local exploration and the
/// burn-in. Earlier measurements without it (integrated autocorrelation time in steps,
/// mean over parameters, hammer / shake table, 4 x 52 walkers): DE alone 45 / 45,
/// 0.9 DE + 0.1 stretch 47 / 46, 0.9 DE + 0.1 snooker 50 / 48, 0.5 DE + 0.5 stretch
/// 64 / 67, stretch alone 170 / 176.
pub fn default_moves() -> Vec<WeightedMove> {
    vec![
        WeightedMove {
            spec: MoveSpec::De {
                gamma0: None,
                sigma: 1e-5,
            },
            weight: 0.5,
        },
        WeightedMove {
            spec: MoveSpec::Independence {
                nu: 10.0,
                gaussian: false,
                scale: 1.0,
            },
            weight: 0.5,
        },
    ]
}

/// The former default, 0.9 differential evolution + 0.1 stretch (4 x dim walkers): the
/// moves emcee also has, for like-for-like comparisons (`benches/emcee_vs_rust.py`).
pub fn de_stretch_moves() -> Vec<WeightedMove> {
    vec![
        WeightedMove {
            spec: MoveSpec::De {
                gamma0: None,
                sigma: 1e-5,
            },
            weight: 0.9,
        },
        WeightedMove {
            spec: MoveSpec::Stretch { a: 2.0 },
            weight: 0.1,
        },
    ]
}
