use super::*;

/// `||(I - P_phi) psi||^2 = 1 - MAC` for every pair of shapes, and the block is
/// invariant to the sign and scale of the prediction.
#[test]
fn mac_residual_norm_is_one_minus_mac() {
    let psi = [0.3, -0.7, 1.0, 0.2];
    let b = Block::shape_mac("s", 0..4, &psi, NoiseScale::Fixed(1.0)).unwrap();
    let phi = [0.25, -0.8, 0.9, 0.35];
    let mut r = [0.0; 4];
    b.residuals(&phi, &mut r);
    let ss: f64 = r.iter().map(|v| v * v).sum();
    let mac = crate::modal::mac(&psi, &phi);
    assert!((ss - (1.0 - mac)).abs() < 1e-15);
    let flipped: Vec<f64> = phi.iter().map(|v| -3.0 * v).collect();
    let mut r2 = [0.0; 4];
    b.residuals(&flipped, &mut r2);
    assert!(r.iter().zip(&r2).all(|(a, b)| (a - b).abs() < 1e-15));
}

/// A Values block is the Gaussian density of its observations: sum of
/// `ln N(t(y_i); t(pred_i), (sd_i sigma)^2)`.
#[test]
fn values_block_is_the_gaussian_density() {
    let (y, sd, pred, sigma) = ([2.0, 3.0], [0.1, 0.2], [2.1, 2.7], 1.5);
    let b = Block::values("v", 0..2, &y, &sd, Transform::Ln, NoiseScale::Fixed(sigma)).unwrap();
    let mut r = [0.0; 2];
    b.residuals(&pred, &mut r);
    let direct: f64 = (0..2)
        .map(|i| {
            let s = sd[i] * sigma;
            let z = pred[i].ln() - y[i].ln();
            -0.5 * (z / s).powi(2) - s.ln() - HALF_LN_2PI
        })
        .sum();
    assert!((b.ln_likelihood(&r, sigma) - direct).abs() < 1e-12);
}

/// The complex-gain block is the gain integral of the complex Gaussian density:
/// `ln int prod_k (pi s^2 v_k)^-1 exp(-|y_k - g h_k|^2 / (s^2 v_k)) dg`, by the
/// trapezoidal rule over the gain, equals `ln L_b + ln_marginal`.
#[test]
fn complex_gain_block_is_the_gain_integral() {
    let y = [1.0, 0.5, -0.3, 0.8, 0.2, -1.1];
    let h = [0.9, 0.6, -0.2, 0.7, 0.3, -1.0];
    let v = [0.04, 0.09, 0.05];
    let sd: Vec<f64> = v.iter().map(|x: &f64| x.sqrt()).collect();
    let sigma = 1.3;
    let b = Block::complex_gain("c", 0..6, &y, &sd, NoiseScale::Fixed(sigma)).unwrap();
    let mut r = [0.0; 6];
    b.residuals(&h, &mut r);
    let got = b.ln_likelihood(&r, sigma) + b.ln_marginal(&h);
    let density = |g: f64| -> f64 {
        (0..3)
            .map(|k| {
                let var = sigma * sigma * v[k];
                let e2 =
                    (y[2 * k] - g * h[2 * k]).powi(2) + (y[2 * k + 1] - g * h[2 * k + 1]).powi(2);
                -(std::f64::consts::PI * var).ln() - e2 / var
            })
            .sum::<f64>()
            .exp()
    };
    let (lo, hi, n) = (-3.0, 5.0, 200_000);
    let dg = (hi - lo) / n as f64;
    let integral: f64 = (0..=n)
        .map(|i| {
            let w = if i == 0 || i == n { 0.5 } else { 1.0 };
            w * density(lo + i as f64 * dg)
        })
        .sum::<f64>()
        * dg;
    assert!(
        (got - integral.ln()).abs() < 1e-9,
        "{got} vs {}",
        integral.ln()
    );
    let (g, sd_g) = b.conditional_gain(&h, sigma).unwrap();
    assert!(g > 0.9 && g < 1.3 && sd_g > 0.0);
}

/// `b`'s residual Jacobian at `t` against central differences (step 1e-6) of its
/// residuals, to `tol`: the block's rows are written at row 2 of a larger matrix, so its
/// row offset is exercised too.
fn assert_jacobian_matches_differences(
    b: &Block,
    pred: impl Fn(&[f64]) -> Vec<f64>,
    dpred: &DMatrix<f64>,
    t: &[f64],
    tol: f64,
) {
    let (n, n_par, row0) = (b.n_residuals(), t.len(), 2);
    let mut jac = DMatrix::from_element(n + row0 + 1, n_par, f64::NAN);
    b.residual_jacobian(&pred(t), dpred, 1.0, row0, &mut jac);
    for j in 0..n_par {
        let (mut up, mut dn) = (t.to_vec(), t.to_vec());
        up[j] += 1e-6;
        dn[j] -= 1e-6;
        let (mut ru, mut rd) = (vec![0.0; n], vec![0.0; n]);
        b.residuals(&pred(&up), &mut ru);
        b.residuals(&pred(&dn), &mut rd);
        for i in 0..n {
            let (fd, got) = ((ru[i] - rd[i]) / 2e-6, jac[(row0 + i, j)]);
            assert!((got - fd).abs() < tol, "({i}, {j}): {got} vs {fd}");
        }
        // the rows outside the block are left as they were
        assert!(jac[(0, j)].is_nan() && jac[(n + row0, j)].is_nan());
    }
}

/// The complex-gain residual Jacobian against central differences, for predictions
/// `p(t) = (t0 + t1 k, sin(t0 k))` in k.
#[test]
fn complex_gain_residual_jacobian_matches_differences() {
    let y = [1.0, 0.5, -0.3, 0.8, 0.2, -1.1];
    let b = Block::complex_gain("c", 0..6, &y, &[0.2, 0.3, 0.25], NoiseScale::Fixed(1.0)).unwrap();
    let pred = |t: &[f64]| -> Vec<f64> {
        (0..3)
            .flat_map(|k| [t[0] + t[1] * k as f64, (t[0] * k as f64).sin()])
            .collect()
    };
    let t = [0.7, -0.4];
    let dpred = DMatrix::from_fn(6, 2, |i, j| {
        let k = (i / 2) as f64;
        match (i % 2, j) {
            (0, 0) => 1.0,
            (0, _) => k,
            (_, 0) => k * (t[0] * k).cos(),
            _ => 0.0,
        }
    });
    assert_jacobian_matches_differences(&b, pred, &dpred, &t, 1e-7);
}

#[test]
fn shape_difference_is_zero_for_a_scaled_copy_and_skips_the_reference() {
    let psi = [0.5, 1.0, -0.25];
    let b = Block::shape_difference("d", 0..3, &psi, 1, &[2.0, 9.0, 4.0], NoiseScale::Fixed(1.0))
        .unwrap();
    let mut r = [1.0; 2];
    b.residuals(&[-1.0, -2.0, 0.5], &mut r);
    assert_eq!(r, [0.0, 0.0]);
    b.residuals(&[0.6, 1.0, -0.25], &mut r);
    assert!((r[0] - 2.0 * 0.1).abs() < 1e-15 && r[1] == 0.0);
    assert!((b.ln_norm() - (-2.0 * HALF_LN_2PI + 2f64.ln() + 4f64.ln())).abs() < 1e-15);
}

/// A chained values block (log transform): its residual Jacobian against central
/// differences of its whitened residuals, for predictions `p(t) = exp(t0 + t1 k)`.
#[test]
fn chained_values_residual_jacobian_matches_differences() {
    let (y, sd) = ([1.0, 1.4, 2.1, 2.9, 4.2], [0.1, 0.12, 0.09, 0.2, 0.15]);
    let correlation = Correlation {
        shared: None,
        chain: &[0.0, 0.6, 0.4, 0.0, 0.7],
    };
    let scale = NoiseScale::Fixed(1.0);
    let b =
        Block::correlated_values("c", 0..5, &y, &sd, Transform::Ln, correlation, scale).unwrap();
    assert!(b.chain.is_some());
    let pred = |t: &[f64]| -> Vec<f64> { (0..5).map(|k| (t[0] + t[1] * k as f64).exp()).collect() };
    let t = [0.1, 0.35];
    let p = pred(&t);
    let dpred = DMatrix::from_fn(5, 2, |i, j| p[i] * if j == 0 { 1.0 } else { i as f64 });
    assert_jacobian_matches_differences(&b, pred, &dpred, &t, 1e-6);
}

/// A block's chain may not continue one from before it, and needs one correlation per
/// value.
#[test]
fn chained_values_reject_a_continued_chain_and_a_wrong_length() {
    let (y, sd, scale) = ([1.0, 2.0], [0.1, 0.1], NoiseScale::Fixed(1.0));
    let block = |chain: &[f64]| {
        let correlation = Correlation {
            shared: None,
            chain,
        };
        Block::correlated_values("c", 0..2, &y, &sd, Transform::Identity, correlation, scale)
    };
    let err = block(&[0.5, 0.5]).unwrap_err().to_string();
    assert!(err.contains("continue a chain"), "{err}");
    let err = block(&[0.0]).unwrap_err().to_string();
    assert!(err.contains("1 bin correlations for 2 values"), "{err}");
    assert!(block(&[0.0, 0.0]).unwrap().chain.is_none());
}
