//! Equivalent-linearisation weight of a story's drift in a segment, for
//! amplitude-dependent hypotheses (see the docs of [`super::data`]).

use crate::io::{Quantity, Test};

/// Caughey's equivalent-linearisation weight `sum (w d)^2 d^2 / sum (w d)^2` (m^2) of the
/// drift `d` of `story` over `[start, start + len)` of `t`, with the estimator's
/// exponential window `w = exp(-t / tau)` (none: 1). A cubic spring `k3 d^3` acts in that
/// segment as the linear spring `k3` times this weight: it is the `k_eq` that minimises
/// the windowed mean square of `k3 d^3 - k_eq d`, the error that the H1 estimate (a
/// least-squares fit of a linear relation to the windowed records) averages over.
/// `3 A^2 / 4` for a sinusoid of amplitude `A` (harmonic balance), `3 sigma^2` for
/// Gaussian drift (statistical linearisation); a hammer response, a sum of decaying
/// modes, lies between. `None` without displacement channels on both of its levels.
pub(super) fn story_drift_lin_sq(
    t: &Test,
    story: usize,
    start: usize,
    len: usize,
    tau_s: Option<f64>,
) -> Option<f64> {
    let disp = |floor: usize| {
        t.channels
            .iter()
            .position(|c| c.quantity == Quantity::Displacement && c.floor == floor)
    };
    let upper = disp(story)?;
    let lower = if story == 1 {
        None
    } else {
        Some(disp(story - 1)?)
    };
    let end = (start + len).min(t.n_samples());
    if end <= start + 2 {
        return None;
    }
    // Offsets: the mean of the quiet part before the block (as the hammer estimator
    // does), else of the analysed part.
    let offset = |i: usize| {
        let d = &t.data[i];
        if start >= 64 {
            d[..start].iter().sum::<f64>() / start as f64
        } else {
            d[start..end].iter().sum::<f64>() / (end - start) as f64
        }
    };
    let (ou, ol) = (offset(upper), lower.map_or(0.0, offset));
    let dt = 1.0 / t.sample_rate_hz;
    let (mut num, mut den) = (0.0, 0.0);
    for (i, k) in (start..end).enumerate() {
        let d = t.data[upper][k] - ou - lower.map_or(0.0, |l| t.data[l][k] - ol);
        let w = tau_s.map_or(1.0, |tau| (-(i as f64) * dt / tau).exp());
        let u2 = (w * d).powi(2);
        num += u2 * d * d;
        den += u2;
    }
    (den > 0.0).then(|| num / den)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{Channel, TestKind};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    /// A record with the drift of story 1 (floor 1 against the ground) as its only
    /// channel.
    fn record(fs: f64, d: Vec<f64>) -> Test {
        Test {
            name: "t".into(),
            kind: TestKind::ShakeTable,
            sample_rate_hz: fs,
            channels: vec![Channel {
                name: "disp1".into(),
                quantity: Quantity::Displacement,
                floor: 1,
                unit: "m".into(),
            }],
            data: vec![d],
        }
    }

    #[test]
    fn weight_of_a_sinusoid_is_the_harmonic_balance_value() {
        // d = A sin(2 pi f t): mean d^4 / mean d^2 = (3 A^4 / 8) / (A^2 / 2) = 3 A^2 / 4,
        // exact over whole periods (130 periods here).
        let fs = 200.0;
        let (a, f) = (2e-3, 1.3);
        let n = 20_000;
        let d: Vec<f64> = (0..n)
            .map(|k| a * (2.0 * std::f64::consts::PI * f * k as f64 / fs).sin())
            .collect();
        let t = record(fs, d);
        let m = story_drift_lin_sq(&t, 1, 0, n, None).unwrap();
        assert!((m / (0.75 * a * a) - 1.0).abs() < 1e-3, "{m}");
        assert!(story_drift_lin_sq(&t, 2, 0, n, None).is_none());
        // A decaying envelope A e^{-t/T} under a window e^{-t/tau}: the integrals of
        // A^4 e^{-4t/T - 2t/tau} sin^4 and A^2 e^{-2t/T - 2t/tau} sin^2 give
        // (3 A^2 / 4) (1/T + 1/tau) / (2/T + 1/tau) (the record, 100 s, is 5 T long:
        // the truncated tails are below 1e-4).
        let (big_t, tau) = (20.0, 30.0);
        let d: Vec<f64> = (0..n)
            .map(|k| {
                let tt = k as f64 / fs;
                a * (-tt / big_t).exp() * (2.0 * std::f64::consts::PI * f * tt).sin()
            })
            .collect();
        let m = story_drift_lin_sq(&record(fs, d), 1, 0, n, Some(tau)).unwrap();
        let expect = 0.75 * a * a * (1.0 / big_t + 1.0 / tau) / (2.0 / big_t + 1.0 / tau);
        assert!((m / expect - 1.0).abs() < 0.01, "{m} vs {expect}");
    }

    #[test]
    fn weight_of_gaussian_drift_is_the_statistical_linearisation() {
        // E d^4 / E d^2 = 3 sigma^2. For n independent draws the ratio of sample means
        // has relative variance (delta method, moments 1, 3, 15, 105 sigma^{2k})
        // (1/n) [96/9 + 2/1 - 2 (15 - 3) / 3] = 4.667 / n: SE 0.48 % at n = 200 000;
        // the tolerance is 4 SE.
        let n = 200_000;
        let sigma = 3e-4;
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let d: Vec<f64> = (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                sigma * z
            })
            .collect();
        let m = story_drift_lin_sq(&record(500.0, d), 1, 0, n, None).unwrap();
        let se = (4.667 / n as f64).sqrt();
        let rel = m / (3.0 * sigma * sigma) - 1.0;
        assert!(rel.abs() < 4.0 * se, "{rel} vs SE {se}");
    }
}
