//! Effective mean-square story drift of a segment, for amplitude-dependent hypotheses
//! (see the docs of [`super::data`]).

use crate::io::{Quantity, Test};

/// Effective mean-square drift of `story` over `[start, start + len)` of `t` (see the
/// module docs); `None` without displacement channels on both of its levels.
pub(super) fn story_drift_ms(
    t: &Test,
    story: usize,
    start: usize,
    len: usize,
    tau_s: Option<f64>,
    f1_hz: f64,
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
    let drift: Vec<f64> = (start..end)
        .map(|k| {
            let l = lower.map_or(0.0, |i| t.data[i][k] - ol);
            t.data[upper][k] - ou - l
        })
        .collect();
    let n = drift.len();
    let half = ((t.sample_rate_hz / f1_hz) / 2.0).round().max(1.0) as usize;
    let mut prefix = vec![0.0; n + 1];
    for (i, d) in drift.iter().enumerate() {
        prefix[i + 1] = prefix[i] + d * d;
    }
    let dt = 1.0 / t.sample_rate_hz;
    let (mut num, mut den) = (0.0, 0.0);
    for (i, d) in drift.iter().enumerate() {
        let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
        let ms = (prefix[b] - prefix[a]) / (b - a) as f64;
        let w = tau_s.map_or(1.0, |tau| (-(i as f64) * dt / tau).exp());
        let u2 = (w * d).powi(2);
        num += u2 * ms;
        den += u2;
    }
    (den > 0.0).then(|| num / den)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{Channel, TestKind};

    #[test]
    fn effective_drift_of_a_steady_sinusoid_is_its_mean_square() {
        // d = A sin(2 pi f t) on floor 1 (story 1 relative to the ground): m_eff = A^2/2
        // up to the edge effect of the moving window (one period over 100 s: 1 %).
        let fs = 200.0;
        let (a, f) = (2e-3, 1.3);
        let n = 20_000;
        let d: Vec<f64> = (0..n)
            .map(|k| a * (2.0 * std::f64::consts::PI * f * k as f64 / fs).sin())
            .collect();
        let t = Test {
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
        };
        let m = story_drift_ms(&t, 1, 0, n, None, f).unwrap();
        assert!((m / (a * a / 2.0) - 1.0).abs() < 0.01, "{m}");
        assert!(story_drift_ms(&t, 2, 0, n, None, f).is_none());
        // An exponentially decaying envelope A e^{-t/T} under a window e^{-t/tau}: the
        // weights are A^2 e^{-2t/T} e^{-2t/tau}, so m_eff = (A^2/2) (1/T + 1/tau) /
        // (2/T + 1/tau) (ratio of the integrals of e^{-4t/T - 2t/tau} and
        // e^{-2t/T - 2t/tau}).
        let (big_t, tau) = (20.0, 30.0);
        let d: Vec<f64> = (0..n)
            .map(|k| {
                let tt = k as f64 / fs;
                a * (-tt / big_t).exp() * (2.0 * std::f64::consts::PI * f * tt).sin()
            })
            .collect();
        let t2 = Test { data: vec![d], ..t };
        let m = story_drift_ms(&t2, 1, 0, n, Some(tau), f).unwrap();
        let expect = a * a / 2.0 * (1.0 / big_t + 1.0 / tau) / (2.0 / big_t + 1.0 / tau);
        assert!((m / expect - 1.0).abs() < 0.02, "{m} vs {expect}");
    }
}
