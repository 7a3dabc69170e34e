//! `allan` warns when the selected model misses the curve beyond its confidence
//! bands and names the better-fitting alternative ([`noise_id::fit::check_model`]); it stays
//! quiet when the model fits.
use crate::common::normals;
use noise_id::fit::{check_model, fit_select, FitOptions, Terms};
use noise_id::{deviation_curve, edf, CurveOptions, DevPoint};

const TAU0: f64 = 0.01;
const N: usize = 360_000; // one hour at 100 Hz
const S_N: f64 = 1e-6; // rad^2/s: N = 1e-3 rad/s/sqrt(Hz)

/// White noise plus a rate random walk with S_K (rad^2/s^3).
fn record(s_k: f64, seed: u64) -> Vec<f64> {
    let w = normals(N, seed);
    let k = normals(N, seed ^ 0x5851_f42d_4c95_7f2d);
    let (sw, sk) = ((S_N / TAU0).sqrt(), (s_k * TAU0).sqrt());
    let mut b = 0.0;
    w.iter()
        .zip(&k)
        .map(|(a, c)| {
            b += sk * c;
            sw * a + b
        })
        .collect()
}

fn curve(y: &[f64]) -> Vec<DevPoint> {
    let opt = CurveOptions {
        confidence: Some(edf::ONE_SIGMA),
        ..CurveOptions::default()
    };
    deviation_curve(y, TAU0, &opt)
}

fn terms(white: bool, gm: bool, rw: bool, flicker: bool) -> Terms {
    Terms {
        quant: false,
        white,
        gm,
        rw,
        flicker,
    }
}

#[test]
fn a_bias_instability_model_on_a_strong_random_walk_is_flagged_and_the_random_walk_named() {
    // random walk crossing the white noise at tau = sqrt(3 S_N / S_K) = 10 s
    let s_k = 3.0 * S_N / 100.0;
    let pts = curve(&record(s_k, 7));
    // what a user gets with `--terms white,gm` (a bias-instability model)
    let opt = FitOptions {
        terms: terms(true, true, false, false),
        ..FitOptions::default()
    };
    let sel = fit_select(&pts, &opt).unwrap();
    let chk = check_model(&pts, &sel.fit, &opt).unwrap();
    let msg = chk.warning("gx", &sel.fit.terms);
    println!("selected {}: {chk:#?}\n{msg:?}", sel.fit.terms.label());
    assert!(!chk.misses.is_empty(), "no miss found: {chk:?}");
    // the miss is at the long taus, where the random walk rises and the model cannot
    assert!(chk.misses.iter().any(|m| m.tau_to_s > 100.0), "{chk:?}");
    let alt = chk.alternative.as_ref().expect("an alternative");
    // the simplest model that follows the curve
    assert_eq!(alt.terms, terms(true, false, true, false), "{alt:?}");
    assert!(alt.misses.is_empty(), "{alt:?}");
    assert!(alt.chi2 < 0.2 * chk.chi2, "{} vs {}", alt.chi2, chk.chi2);
    let msg = msg.expect("a warning");
    assert!(msg.contains("misses the Allan deviation beyond its 95 % confidence band"));
    assert!(
        msg.contains(&format!("Better: {}", alt.terms.label())),
        "{msg}"
    );
}

#[test]
fn no_warning_when_the_model_fits() {
    for (seed, s_k, label) in [(11u64, 3.0 * S_N / 100.0, "white + rw"), (12, 0.0, "white")] {
        let pts = curve(&record(s_k, seed));
        let opt = FitOptions {
            terms: terms(true, true, true, true),
            ..FitOptions::default()
        };
        let sel = fit_select(&pts, &opt).unwrap();
        let chk = check_model(&pts, &sel.fit, &opt).unwrap();
        println!(
            "{label}: selected {}, {} of {} outside, chi2 {:.1}",
            sel.fit.terms.label(),
            chk.n_outside,
            chk.n_points,
            chk.chi2
        );
        assert!(chk.misses.is_empty(), "{label}: {chk:?}");
        assert!(chk.warning("gx", &sel.fit.terms).is_none());
        assert!(chk.alternative.is_none());
    }
}
