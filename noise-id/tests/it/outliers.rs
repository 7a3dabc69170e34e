//! Hampel outlier detection: white noise with 0.3 % spikes of 50 sigma; the spikes
//! are found, and with them replaced the white-noise level (ARW) is within 3 % of the
//! spike-free record's.

use crate::common::normals;
use noise_id::outliers::{hampel, HampelOptions};
use noise_id::{deviation_curve, CurveOptions};

fn arw(y: &[f64], tau0: f64) -> f64 {
    let opt = CurveOptions {
        confidence: None,
        ..CurveOptions::default()
    };
    let p = deviation_curve(y, tau0, &opt)
        .into_iter()
        .find(|p| p.m == 128)
        .unwrap();
    // white noise: sigma(tau) = N / sqrt(tau)
    p.dev * p.tau_s.sqrt()
}

#[test]
fn spikes_of_50_sigma_are_found_and_removing_them_restores_the_arw() {
    let (n, tau0) = (360_000usize, 0.01);
    let sigma = 2e-3; // rad/s
    let clean: Vec<f64> = normals(n, 0x9e37_79b9_7f4a_7c15)
        .into_iter()
        .map(|v| 1e-3 + sigma * v)
        .collect();
    // 0.3 % of the samples get a spike of +-50 sigma, at pseudo-random places
    let mut spiky = clean.clone();
    let mut placed = std::collections::BTreeSet::new();
    let mut s = 12345u64;
    while placed.len() < n * 3 / 1000 {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let i = (s >> 33) as usize % n;
        if placed.insert(i) {
            spiky[i] += if s & 1 == 0 { 50.0 } else { -50.0 } * sigma;
        }
    }
    let out = hampel(&spiky, &HampelOptions::default());
    let found: std::collections::BTreeSet<usize> = out.indices.iter().copied().collect();
    let hits = placed.intersection(&found).count();
    let false_pos = found.len() - hits;
    let (a_clean, a_spiky, a_fixed) = (
        arw(&clean, tau0),
        arw(&spiky, tau0),
        arw(&out.replaced(&spiky), tau0),
    );
    println!(
        "spikes {} found {} (hits {hits}, false {false_pos}); ARW clean {a_clean:.4e} spiky \
         {a_spiky:.4e} ({:+.1} %) excluded {a_fixed:.4e} ({:+.2} %)",
        placed.len(),
        found.len(),
        100.0 * (a_spiky / a_clean - 1.0),
        100.0 * (a_fixed / a_clean - 1.0)
    );
    assert_eq!(hits, placed.len(), "every spike found");
    assert!(false_pos <= n / 100_000, "{false_pos} false outliers");
    assert!((out.fraction() - 0.003).abs() < 1e-4);
    assert!(
        a_spiky / a_clean > 1.5,
        "the spikes matter: {a_spiky} vs {a_clean}"
    );
    assert!(
        (a_fixed / a_clean - 1.0).abs() < 0.03,
        "{a_fixed} vs {a_clean}"
    );
    // the spikes' sizes are about 50 robust sigmas (the median size: another spike or the
    // noise in a window moves single sizes a little)
    let mut sizes: Vec<f64> = out.sizes_sigma.iter().map(|z| z.abs()).collect();
    sizes.sort_by(f64::total_cmp);
    let med = sizes[sizes.len() / 2];
    println!("median outlier size {med:.2} robust sigma");
    assert!((45.0..55.0).contains(&med), "{med}");
}

#[test]
fn quantized_or_constant_records_have_no_outliers() {
    let y: Vec<f64> = (0..1000)
        .map(|i| if i % 7 == 0 { 1.0 } else { 0.0 })
        .collect();
    let out = hampel(&y, &HampelOptions::default());
    assert!(out.indices.is_empty(), "{:?}", out.indices.len());
    let mut z = vec![0.5; 200];
    z[100] = f64::NAN;
    let out = hampel(&z, &HampelOptions::default());
    assert_eq!(out.indices, vec![100]);
    assert_eq!(out.replaced(&z)[100], 0.5);
}

/// White noise (S_N, rad^2/s) plus a first-order Gauss-Markov process (S_B rad^2/s^3, T_B s)
/// sampled every `tau0` s.
fn white_gm(n: usize, tau0: f64, s_n: f64, s_b: f64, t_b: f64, seed: u64) -> Vec<f64> {
    let w = normals(n, seed);
    let g = normals(n, seed ^ 0x5851_f42d_4c95_7f2d);
    let sw = (s_n / tau0).sqrt();
    // exact discretization: b_k+1 = phi b_k + sqrt(sigma^2 (1 - phi^2)) e, sigma^2 = S_B T_B / 2
    let phi = (-tau0 / t_b).exp();
    let sd = (0.5 * s_b * t_b * (1.0 - phi * phi)).sqrt();
    let mut b = 0.0;
    w.iter()
        .zip(&g)
        .map(|(a, c)| {
            b = phi * b + sd * c;
            sw * a + b
        })
        .collect()
}

/// Adds spikes of 10-50 sigma (random sign and size) to 0.3 % of the samples; their indices.
fn add_spikes(y: &mut [f64], sigma: f64, seed: u64) -> std::collections::BTreeSet<usize> {
    let n = y.len();
    let mut placed = std::collections::BTreeSet::new();
    let mut s = seed;
    while placed.len() < n * 3 / 1000 {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let i = (s >> 33) as usize % n;
        let size = 10.0 + 40.0 * ((s >> 8) & 0xffff) as f64 / 65536.0;
        if placed.insert(i) {
            y[i] += if s & 1 == 0 { size } else { -size } * sigma;
        }
    }
    placed
}

#[test]
fn spiky_white_plus_gauss_markov_selects_white_plus_gm_with_the_true_arw() {
    use noise_id::fit::{check_model, fit_select, FitOptions, Terms};
    let (n, tau0) = (180_000usize, 0.01); // 30 min at 100 Hz
    let s_n: f64 = 1e-6; // rad^2/s: ARW 3.44 deg/sqrt(h)
    let sigma = (s_n / tau0).sqrt();
    let all = Terms {
        quant: true,
        white: true,
        gm: true,
        rw: true,
        flicker: true,
    };
    let white_gm_terms = Terms {
        quant: false,
        white: true,
        gm: true,
        rw: false,
        flicker: false,
    };
    for (k, (s_b, t_b)) in [(1e-7, 5.0), (1e-7, 20.0)].into_iter().enumerate() {
        let clean = white_gm(n, tau0, s_n, s_b, t_b, 0x1234_5678 + k as u64);
        let mut spiky = clean.clone();
        let placed = add_spikes(&mut spiky, sigma, 777 + k as u64);
        let opt = HampelOptions::default();
        let out = hampel(&spiky, &opt);
        let found: std::collections::BTreeSet<usize> = out.indices.iter().copied().collect();
        let hits = placed.intersection(&found).count();
        let false_spiky = found.len() - hits;
        let false_clean = hampel(&clean, &opt).indices.len();
        let pts = noise_id::deviation_curve(
            &out.replaced(&spiky),
            tau0,
            &noise_id::CurveOptions::default(),
        );
        let fo = FitOptions {
            terms: all,
            ..FitOptions::default()
        };
        let sel = fit_select(&pts, &fo).unwrap();
        let chk = check_model(&pts, &sel.fit, &fo).unwrap();
        let arw_err = (sel.fit.s_n.value / s_n).sqrt() - 1.0;
        println!(
            "S_B {s_b:e} T_B {t_b}: threshold {:.2} sigma; spikes {} found {hits}, false {} \
             (spiky) {} (clean) of {n}; selected {} ARW {:+.2} %, T_B {:.2} s, {} of {} taus \
             outside the band",
            opt.n_sigma,
            placed.len(),
            false_spiky,
            false_clean,
            sel.fit.terms.label(),
            100.0 * arw_err,
            sel.fit.t_b_s.value,
            chk.n_outside,
            chk.n_points
        );
        for c in &sel.candidates {
            println!(
                "  {:26} BIC {:9.1} {:?}",
                c.terms.label(),
                c.bic,
                c.rejected
            );
        }
        assert!(false_clean as f64 <= 1e-4 * n as f64, "{false_clean}");
        assert!(false_spiky as f64 <= 1e-4 * n as f64, "{false_spiky}");
        // spikes hidden in the noise (10 sigma against -3 sigma of noise) may stay
        assert!(hits as f64 >= 0.99 * placed.len() as f64, "{hits}");
        assert_eq!(sel.fit.terms, white_gm_terms, "{}", sel.fit.terms.label());
        assert!(arw_err.abs() < 0.03, "ARW {:+.2} %", 100.0 * arw_err);
        assert!(chk.misses.is_empty(), "{chk:?}");
    }
}

#[test]
fn the_stated_false_positive_rate_is_what_gaussian_noise_gives() {
    use noise_id::outliers::{gaussian_false_positive_rate, n_sigma_for_rate};
    // the default: 1e-6 of the samples at 6.96 robust sigma (8 sigma would be 1.2e-7)
    let d = HampelOptions::default();
    assert!((d.n_sigma - 6.96).abs() < 0.05, "{}", d.n_sigma);
    assert!((d.false_positive_rate() / 1e-6 - 1.0).abs() < 1e-6);
    let r8 = gaussian_false_positive_rate(25, 8.0);
    println!(
        "default threshold {:.3} sigma; 8 sigma flags {r8:.2e}",
        d.n_sigma
    );
    assert!((1e-7..1.5e-7).contains(&r8), "{r8}");
    // a rate that a short record can count: 1e-3 of 400,000 Gaussian samples, 400 expected
    let opt = HampelOptions {
        half_window: 25,
        n_sigma: n_sigma_for_rate(25, 1e-3),
    };
    let y = normals(400_000, 0xdead_beef);
    let got = hampel(&y, &opt).indices.len();
    println!(
        "threshold {:.3} sigma: {got} of 400000 flagged, 400 stated",
        opt.n_sigma
    );
    // Poisson scatter of 400 is 20: 3 sigma
    assert!((340..=460).contains(&got), "{got}");
}
