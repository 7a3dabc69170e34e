//! Hampel outlier detection: white noise with 0.3 % spikes of 50 sigma; the spikes
//! are found, and with them replaced the white-noise level (ARW) is within 3 % of the
//! spike-free record's.

use noise_id::outliers::{hampel, HampelOptions};
use noise_id::{deviation_curve, CurveOptions};

/// Deterministic standard normal samples (xorshift64* + Box-Muller).
fn normals(n: usize, mut s: u64) -> Vec<f64> {
    let mut u = || {
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        ((s.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        })
        .collect()
}

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
