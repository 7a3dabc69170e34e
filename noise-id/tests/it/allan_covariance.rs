//! The model covariance of overlapping Allan variance estimates (used for the fit's
//! uncertainties) against independent results: the exact variance of OAVAR(1) for white
//! noise, and Greenhall's EDF for pure white and pure random-walk noise.
use noise_id::fit::oavar_covariance;
use noise_id::{edf, Deviation};

const N: usize = 2_160_000;

fn exact_edf(c: [f64; 5], ms: &[usize]) -> Vec<f64> {
    let dt = 0.01;
    let pairs: Vec<(usize, usize)> = ms.iter().map(|&m| (m, N + 1 - 2 * m)).collect();
    let v = oavar_covariance(&pairs, dt, &c, f64::NAN);
    ms.iter()
        .enumerate()
        .map(|(i, &m)| {
            let tau = m as f64 * dt;
            let avar = c[1] / tau + c[3] * tau / 3.0;
            2.0 * avar * avar / v[(i, i)]
        })
        .collect()
}

#[test]
fn white_noise_oavar_1_has_two_thirds_n_degrees_of_freedom() {
    // d_i = y_{i+1} - y_i: Var(sum d^2) = n (8 + 2 * 2) sigma^4 -> EDF = 2 n / 3.
    let e = exact_edf([0.0, 1e-6, 0.0, 0.0, 0.0], &[1]);
    let want = 2.0 * (N - 1) as f64 / 3.0;
    assert!((e[0] / want - 1.0).abs() < 1e-4, "{} vs {want}", e[0]);
}

#[test]
fn covariance_diagonal_matches_greenhall_edf_for_white_and_random_walk() {
    let ms = [64usize, 256, 1024, 4096];
    let e = exact_edf([0.0, 1e-6, 0.0, 0.0, 0.0], &ms);
    for (&m, got) in ms.iter().zip(&e) {
        let g = edf::edf_for(Deviation::Oadev, 0, m, N + 1);
        assert!(
            (got / g - 1.0).abs() < 0.03,
            "white m={m}: {got} vs Greenhall {g}"
        );
    }
    let ms = [16384usize, 65536, 262_144, 524_288];
    let e = exact_edf([0.0, 0.0, 0.0, 1e-12, 0.0], &ms);
    for (&m, got) in ms.iter().zip(&e) {
        let g = edf::edf_for(Deviation::Oadev, -2, m, N + 1);
        assert!(
            (got / g - 1.0).abs() < 0.05,
            "random walk m={m}: {got} vs Greenhall {g}"
        );
    }
}

#[test]
fn neighbouring_octave_estimates_are_correlated() {
    let ms = [64usize, 128];
    let pairs: Vec<(usize, usize)> = ms.iter().map(|&m| (m, N + 1 - 2 * m)).collect();
    let v = oavar_covariance(&pairs, 0.01, &[0.0, 1e-6, 0.0, 0.0, 0.0], f64::NAN);
    let r = v[(0, 1)] / (v[(0, 0)] * v[(1, 1)]).sqrt();
    assert!(r > 0.4 && r < 0.7, "correlation {r}");
}
