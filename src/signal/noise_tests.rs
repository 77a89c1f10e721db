//! Unit tests of [`super`]: the local noise models, Bendat & Piersol's error and its
//! pooling over neighbouring bins.

use super::*;

fn sdof(k: usize, n: usize) -> Complex64 {
    // a pole half a bin from bin n/3, residue 1: H = 1 / (j (k - k0) + 0.5)
    let k0 = n as f64 / 3.0 + 0.3;
    Complex64::new(1.0, 0.0) / Complex64::new(0.5, k as f64 - k0)
}

#[test]
fn noise_free_sharp_peak_has_coherence_one() {
    // one block, input varying, FRF a pole narrower than one bin plus background
    let n = 300;
    let f: Vec<Complex64> = (0..n)
        .map(|k| Complex64::from_polar(1.0 + 0.2 * (k as f64 * 0.1).sin(), k as f64 * 1.3))
        .collect();
    let y: Vec<Complex64> = (0..n)
        .map(|k| (sdof(k, n) + Complex64::new(0.01 * k as f64, 0.0)) * f[k])
        .collect();
    let h1: Vec<Complex64> = (0..n).map(|k| y[k] / f[k]).collect();
    let est = local_rational_noise(&[f], &[y], &h1, 4, 1, None).unwrap();
    assert_eq!(est.dof, 6);
    for k in 0..n {
        assert!(
            est.coherence[k] > 1.0 - 1e-9,
            "bin {k}: {}",
            est.coherence[k]
        );
    }
}

#[test]
fn step_keeps_window_on_the_padding_grid() {
    let n = 200;
    let f: Vec<Complex64> = (0..n)
        .map(|k| Complex64::new(1.0, 0.01 * k as f64))
        .collect();
    let y: Vec<Complex64> = f.iter().map(|&v| v * 2.0).collect();
    let h1 = vec![Complex64::new(2.0, 0.0); n];
    for step in [1, 2, 4] {
        let est = local_rational_noise(
            std::slice::from_ref(&f),
            std::slice::from_ref(&y),
            &h1,
            3,
            step,
            None,
        )
        .unwrap();
        assert!(est.coherence.iter().all(|&g| g > 1.0 - 1e-9));
    }
    assert!(local_rational_noise(
        std::slice::from_ref(&f),
        std::slice::from_ref(&y),
        &h1,
        0,
        1,
        None
    )
    .is_err());
    assert!(local_rational_noise(&[f], &[y], &h1, 150, 1, None).is_err());
}

/// An SDOF receptance over 400 bins, a force spectrum falling 20 dB, and the
/// coherence that an output noise of auto-spectrum `g_nn[k]` gives with 1 average.
fn resonance_with_noise(g_nn: &[f64]) -> (Vec<Complex64>, Vec<f64>, Vec<f64>) {
    let n = g_nn.len();
    let h1: Vec<Complex64> = (0..n)
        .map(|k| {
            let r = k as f64 / 200.0;
            Complex64::new(1.0 - r * r, 0.02 * r).inv()
        })
        .collect();
    let power: Vec<f64> = (0..n)
        .map(|k| 10f64.powf(-2.0 * k as f64 / n as f64))
        .collect();
    let coherence = (0..n)
        .map(|k| {
            let s = h1[k].norm_sqr() * power[k];
            s / (s + g_nn[k])
        })
        .collect();
    (h1, power, coherence)
}

#[test]
fn pooled_noise_keeps_a_smooth_noise_spectrum_exactly() {
    // constant G_nn: each bin's own value is already exact, and pooling over a peak
    // of 34 dB (where |H1| and the coherence change fast) must not move it
    let at: Vec<usize> = (5..395).collect();
    let (h1, power, coh) = resonance_with_noise(&[1e-3; 400]);
    let own = pooled_rel_std(&h1, &coh, &power, 1, 0, &at);
    let pooled = pooled_rel_std(&h1, &coh, &power, 1, 8, &at);
    for (i, &k) in at.iter().enumerate() {
        assert_eq!(own[i], bendat_piersol_rel_std(coh[k], 1));
        assert!((pooled[i] / own[i] - 1.0).abs() < 1e-9, "bin {k}");
    }
}

#[test]
fn pooled_noise_averages_the_scatter_of_single_bins() {
    // each bin's noise power an exponential variable (a periodogram ordinate) of mean
    // 1e-3: its own sd estimate scatters with ln-sd about 0.64; pooled over 2w + 1 =
    // 17 bins, an average of 17 such, ln-sd about 1 / sqrt(17) = 0.24 (seeded)
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let g: Vec<f64> = (0..400)
        .map(|_| -1e-3 * (1.0 - rng.random::<f64>()).ln())
        .collect();
    let (h1, power, coh) = resonance_with_noise(&g);
    let at: Vec<usize> = (20..380).collect();
    let (_, _, coh_true) = resonance_with_noise(&[1e-3; 400]);
    let truth = pooled_rel_std(&h1, &coh_true, &power, 1, 0, &at);
    let ln_sd = |v: Vec<f64>| {
        let d: Vec<f64> = v.iter().zip(&truth).map(|(a, t)| (a / t).ln()).collect();
        let m = d.iter().sum::<f64>() / d.len() as f64;
        (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / d.len() as f64).sqrt()
    };
    let own = ln_sd(pooled_rel_std(&h1, &coh, &power, 1, 0, &at));
    let pooled = ln_sd(pooled_rel_std(&h1, &coh, &power, 1, 8, &at));
    // ln of an exponential's square root: sd pi / sqrt(24) = 0.641
    assert!((own - 0.641).abs() < 0.1, "own {own}");
    assert!(pooled < 0.16 && pooled > 0.08, "pooled {pooled}");
}

#[test]
fn bendat_piersol_formula() {
    assert!((bendat_piersol_rel_std(0.5, 2) - 0.5).abs() < 1e-15);
    assert_eq!(bendat_piersol_rel_std(1.0, 3), 0.0);
    assert!(bendat_piersol_rel_std(0.0, 3).is_infinite());
}
