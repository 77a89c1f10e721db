//! The conclusions of the `wheel-frf` study, computed from the run: how much worse
//! damping is identified than frequency, per mode and against Au's law, from the
//! posterior and from the channel-to-channel scatter. [`super::wheel_report`] only
//! renders them; `findings.json` holds them.

use serde::Serialize;

use super::wheel_run::WheelStudy;
use super::wheel_scatter::{cov_comparison, CovComparison};

/// Smallest and largest of a set of values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Range {
    pub min: f64,
    pub max: f64,
}

impl Range {
    fn of(v: impl IntoIterator<Item = f64>) -> Range {
        v.into_iter().fold(
            Range {
                min: f64::MAX,
                max: f64::MIN,
            },
            |r, x| Range {
                min: r.min.min(x),
                max: r.max.max(x),
            },
        )
    }
}

/// How many orders of magnitude the damping's c.o.v. exceeds the frequency's, for the
/// least separated mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Separation {
    TwoOrdersOrMore,
    AtLeastOneOrder,
    LessThanOneOrderForSomeModes,
}

/// The channel-to-channel scatter against the posterior.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ScatterFindings {
    /// `cov(xi) / cov(f)` across channels.
    pub cov_ratio: Range,
    /// The same over `1 / xi`.
    pub cov_ratio_over_inverse_xi: Range,
    /// Scatter c.o.v. over posterior c.o.v., frequency and damping.
    pub f_scatter_over_posterior: Range,
    pub xi_scatter_over_posterior: Range,
}

/// See the module docs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Findings {
    /// Per mode, in band order.
    pub modes: Vec<CovComparison>,
    /// `cov(xi) / cov(f)` of the posterior.
    pub cov_ratio: Range,
    /// Measured over predicted (`1 / xi`) ratio.
    pub measured_over_predicted: Range,
    /// Modes whose measured / predicted ratio lies within a factor 2.
    pub n_within_factor_2: usize,
    pub separation: Separation,
    pub scatter: ScatterFindings,
}

/// Computes the findings of a run.
pub fn assess(s: &WheelStudy) -> Findings {
    let modes = cov_comparison(&s.bands);
    let cov_ratio = Range::of(modes.iter().map(|c| c.ratio));
    let rel: Vec<f64> = modes.iter().map(|c| c.ratio / c.predicted_ratio).collect();
    let separation = if cov_ratio.min >= 100.0 {
        Separation::TwoOrdersOrMore
    } else if cov_ratio.min >= 10.0 {
        Separation::AtLeastOneOrder
    } else {
        Separation::LessThanOneOrderForSomeModes
    };
    let pairs = || s.scatter.iter().zip(&modes);
    let scatter = ScatterFindings {
        cov_ratio: Range::of(s.scatter.iter().map(|sc| sc.cov_xi / sc.cov_f)),
        cov_ratio_over_inverse_xi: Range::of(
            s.scatter.iter().map(|sc| sc.cov_xi / sc.cov_f * sc.xi_mean),
        ),
        f_scatter_over_posterior: Range::of(pairs().map(|(a, c)| a.cov_f / c.cov_f)),
        xi_scatter_over_posterior: Range::of(pairs().map(|(a, c)| a.cov_xi / c.cov_xi)),
    };
    Findings {
        measured_over_predicted: Range::of(rel.iter().copied()),
        n_within_factor_2: rel.iter().filter(|&&q| (0.5..=2.0).contains(&q)).count(),
        modes,
        cov_ratio,
        separation,
        scatter,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_of_values_and_of_nothing() {
        let r = Range::of([3.0, -1.0, 2.0]);
        assert_eq!((r.min, r.max), (-1.0, 3.0));
        let e = Range::of(std::iter::empty());
        assert!(e.min > e.max);
    }
}
