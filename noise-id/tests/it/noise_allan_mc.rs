//! Each simulated noise process measured back through the Allan variance: the mean overlapping
//! AVAR over Monte Carlo runs is within 1 +/- 3 / sqrt(runs * EDF) of the theory at every octave
//! tau (EDF: Greenhall's, for the noise type the pipeline identifies at that tau).
use nav_sim::noise::{flicker_avar_discrete, Flicker, GaussMarkov, Quantizer, RandomWalk, White};
use noise_id::{deviation_curve, edf, CurveOptions, Deviation};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

const DT: f64 = 0.01;
const N: usize = 1 << 16;
const RUNS: u64 = 400;

/// Runs `gen` RUNS times, returns per octave m: (m, mean AVAR, Greenhall EDF for the noise
/// exponent `alpha(m)` of the simulated process).
fn mc(
    gen: impl Fn(&mut ChaCha8Rng) -> Vec<f64> + Sync,
    alpha: impl Fn(usize) -> i32,
) -> Vec<(usize, f64, f64)> {
    let runs = std::env::var("NOISE_MC_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(RUNS);
    // Seeds seed0 + run; NOISE_MC_SEED sets seed0 (default 0xA11A) to try other seed sets.
    let seed0: u64 = std::env::var("NOISE_MC_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0xA11A);
    let curves: Vec<Vec<(usize, f64, f64)>> = (0..runs)
        .into_par_iter()
        .map(|r| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed0 + r);
            let y = gen(&mut rng);
            deviation_curve(&y, DT, &CurveOptions::default())
                .iter()
                .map(|p| (p.m, p.dev * p.dev, p.edf))
                .collect()
        })
        .collect();
    let n = curves[0].len();
    (0..n)
        .map(|i| {
            let mean = curves.iter().map(|c| c[i].1).sum::<f64>() / runs as f64;
            let m = curves[0][i].0;
            let e = edf::edf_for(Deviation::Oadev, alpha(m), m, N + 1) * runs as f64 / RUNS as f64;
            (m, mean, e)
        })
        .collect()
}

/// The criterion at every tau: |mean AVAR / theory - 1| < 3 / sqrt(runs EDF).
///
/// Statistically, the relative standard deviation of that mean is sqrt(2 / (runs EDF))
/// (chi-square), so the band is 2.12 sigma per tau, and with ~15 correlated taus per process a
/// correct generator fails it somewhere by chance in a fair share of seed sets. Measured with
/// `NOISE_MC_SEED` = 100000, 200000, ..., 800000: 6 of those 8 seed sets failed at one or more
/// taus, while the 531 normalized deviations z = (ratio - 1) / sqrt(2 / (runs EDF)) printed by
/// those runs had RMS 1.00 and mean -0.04 (per process RMS 0.85 - 1.06): the generators and
/// the EDF theory agree; the per-tau band is simply a 2-sigma test. This file's fixed seeds
/// (the default 0xA11A, kept as first written) pass; z is printed for every tau.
fn check(name: &str, res: &[(usize, f64, f64)], theory: impl Fn(usize) -> f64, max_m: usize) {
    let mut checked = 0;
    for &(m, mean, edf) in res.iter().filter(|r| r.0 <= max_m && r.2.is_finite()) {
        let th = theory(m);
        let tol = 3.0 / (RUNS as f64 * edf).sqrt();
        let ratio = mean / th;
        let z = (ratio - 1.0) / (2.0 / (RUNS as f64 * edf)).sqrt();
        println!("{name:10} m {m:6} ratio {ratio:.5} tol {tol:.5} edf {edf:.1} z {z:+.2}");
        assert!(
            (ratio - 1.0).abs() < tol,
            "{name}: m = {m}: mean AVAR / theory = {ratio:.5}, allowed 1 +/- {tol:.5}"
        );
        checked += 1;
    }
    assert!(checked >= 10, "{name}: only {checked} taus checked");
}

#[test]
fn white_noise_allan_variance_is_s_n_over_tau() {
    let s_n = 6.2865e-9;
    let res = mc(
        |rng| {
            let mut w = White::from_psd(s_n, DT);
            (0..N).map(|_| w.next(rng)).collect()
        },
        |_| 0,
    );
    check("white", &res, |m| s_n / (m as f64 * DT), N / 4);
}

/// Exact AVAR of the point-sampled AR(1) Gauss-Markov sequence: `(4 D(m) - D(2m)) / (2 m^2)`
/// with `D(t) = sigma^2 [t (1+phi)/(1-phi) - 2 phi (1 - phi^t) / (1-phi)^2]` the variance of a
/// sum of t consecutive samples.
fn gm_discrete_avar(s_b: f64, t_b: f64, m: usize) -> f64 {
    let sig2 = s_b * t_b / 2.0;
    let phi = (-DT / t_b).exp();
    let d = |t: f64| {
        sig2 * (t * (1.0 + phi) / (1.0 - phi)
            - 2.0 * phi * (1.0 - phi.powf(t)) / (1.0 - phi).powi(2))
    };
    let mf = m as f64;
    (4.0 * d(mf) - d(2.0 * mf)) / (2.0 * mf * mf)
}

#[test]
fn gauss_markov_allan_variance_matches_exact_discrete_theory() {
    let (s_b, t_b) = (2.4360e-11, 1.0);
    // Random walk below T_B, white above: the smaller (conservative) EDF of the two regimes
    // in between.
    let res = mc(
        |rng| {
            let mut g = GaussMarkov::new(s_b, t_b, DT);
            (0..N).map(|_| g.next(rng)).collect()
        },
        |m| if (m as f64) * DT < 4.0 * t_b { -2 } else { 0 },
    );
    check("gm", &res, |m| gm_discrete_avar(s_b, t_b, m), N / 4);
    // The continuous formula (docs/DESIGN.md, corrected) agrees once tau >> dt.
    for m in [64usize, 256, 1024] {
        let c = noise_id::gauss_markov_avar(s_b, t_b, m as f64 * DT);
        let d = gm_discrete_avar(s_b, t_b, m);
        assert!((c / d - 1.0).abs() < 0.02, "m {m}: {c} vs {d}");
    }
}

#[test]
fn random_walk_allan_variance_is_s_k_tau_over_3() {
    let s_k = 2.6731e-12;
    let res = mc(
        |rng| {
            let mut k = RandomWalk::new(s_k, DT);
            (0..N).map(|_| k.next(rng)).collect()
        },
        |_| -2,
    );
    // Sampled walk: S_K dt (2 m^2 + 1) / (6 m) = S_K tau / 3 + S_K dt^2 / (6 tau).
    check(
        "rw",
        &res,
        |m| s_k * DT * (2.0 * (m * m) as f64 + 1.0) / (6.0 * m as f64),
        N / 4,
    );
}

#[test]
fn flicker_allan_variance_is_the_ieee_floor() {
    let b = 1e-4;
    let res = mc(
        |rng| {
            let mut f = Flicker::new(b, DT, N);
            (0..N).map(|_| f.next(rng)).collect()
        },
        |_| -1,
    );
    // Each block has N samples of past (warm-up): 1/f holds to tau ~ N dt / 10.
    check("flicker", &res, |m| flicker_avar_discrete(b, m), N / 16);
    let floor = 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI * b * b;
    let big = res.iter().find(|r| r.0 == 1024).expect("m = 1024");
    assert!(
        (big.1 / floor - 1.0).abs() < 0.05,
        "floor {}",
        big.1 / floor
    );
}

#[test]
fn quantization_error_allan_variance_is_3_q2_over_tau2() {
    let step = 1e-4; // m/s per LSB
    let q2 = step * step / 12.0;
    let res = mc(
        |rng| {
            // A noisy signal (dithers the residual) quantized with carry; the error rate is
            // (quantized increment - true increment) / dt.
            let mut w = White::from_psd(1e-3, DT);
            let mut q = Quantizer::new(step);
            (0..N)
                .map(|_| {
                    let inc = (0.3 + w.next(rng)) * DT;
                    (q.quantize(inc) - inc) / DT
                })
                .collect()
        },
        |_| 2,
    );
    check("quant", &res, |m| 3.0 * q2 / (m as f64 * DT).powi(2), N / 4);
}
