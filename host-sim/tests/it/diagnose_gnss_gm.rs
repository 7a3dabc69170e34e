//! The GNSS Gauss-Markov error (`gnss_position_gm`) of the sweep's drives (10 minutes at 50 Hz,
//! the file's three 60 s gaps): what its time-correlated fix errors do to the normalised
//! position innovations of the base model (autocorrelation, Ljung-Box), with and without the
//! GNSS error state and a white inflation of the GNSS sigmas, against clean drives and drives
//! with other effects.
use super::diagnose_heldout::prepare;
use nav_core::model::Block;
use nav_diagnose::{options_with, residual_stats};
use nav_engine::run::{run_filter, RunOptions};
use nav_sim::undeclared::{DriveSpec, Effect};

/// The sweep's drive of `effect` (None: clean) and `seed`: 10 minutes at 50 Hz, truth RK4 x8,
/// three 60 s gaps in the GNSS file.
fn spec(effect: Option<Effect>, seed: u64) -> DriveSpec {
    DriveSpec {
        minutes: 10.0,
        rate_hz: 50.0,
        substeps: 8,
        seed,
        file_gaps: Some(3),
        ..DriveSpec::new(effect)
    }
}

/// One line per position component of a run: Ljung-Box Q (10 lags) and the autocorrelation
/// at lags 1, 2, 5, 10 of the normalised innovations, and the run's log-likelihood.
fn whiteness_line(label: &str, case: &nav_engine::run::CaseData, o: &RunOptions) -> String {
    let out = run_filter(case, o).expect("run");
    let rs = residual_stats(&out.innovations);
    // every position component judged on the fixes outside the file's gaps (418 fixes)
    assert!(
        rs.whiteness.len() >= 3 && rs.whiteness.iter().take(3).all(|w| w.n > 300),
        "{label}: {} components",
        rs.whiteness.len()
    );
    let mut s = format!(
        "    {label:<22} LL {:>9.1} NIS {:.2} |",
        rs.log_likelihood, rs.nis_mean
    );
    for w in rs.whiteness.iter().take(3) {
        let r = |k: usize| w.autocorr.get(k - 1).copied().unwrap_or(f64::NAN);
        s.push_str(&format!(
            " c{} Q {:>6.1} r1 {:+.2} r2 {:+.2} r5 {:+.2} r10 {:+.2} |",
            w.component,
            w.ljung_box_q,
            r(1),
            r(2),
            r(5),
            r(10)
        ));
    }
    s
}

/// Prints, for GNSS Gauss-Markov drives, clean drives and drives with other effects, the base
/// model's innovation whiteness with and without the GNSS error state, at the declared GNSS
/// sigmas and inflated x2.5, with the state's default prior and priors near the drives' truth
/// (a measurement: docs/diagnose.md, "GNSS-side effects").
#[test]
#[ignore = "a measurement: prints the innovation whiteness of the sweep's drives"]
fn gnss_error_innovation_whiteness() {
    let drives: Vec<(Option<Effect>, u64)> = [
        (Some(Effect::GnssCorrelatedError), 100..104),
        (None, 300..304),
        (Some(Effect::AccelScaleFactor), 100..102),
        (Some(Effect::LeverArm), 100..102),
        (Some(Effect::ImuClockDrift), 100..102),
    ]
    .into_iter()
    .flat_map(|(e, r)| r.map(move |s| (e, s)))
    .collect();
    for (e, seed) in drives {
        let (p, m) = prepare(&spec(e, seed));
        println!(
            "{} seed {seed}: GNSS white {:?} m, GM {:?} m / {:.0} s, fixes {}",
            e.map_or("clean".to_string(), |e| e.to_string()),
            m.gnss.white_sigma_ned_m.0,
            m.gnss.gm_sigma_ned_m.0,
            m.gnss.gm_tau_s,
            p.case.gnss.len()
        );
        let gm = options_with(&p.opts, &[Block::GnssPositionGm]);
        let scaled = |o: &RunOptions, k: f64| {
            let mut o = o.clone();
            o.gnss_sigma_scale.horizontal *= k;
            o.gnss_sigma_scale.vertical *= k;
            o
        };
        let gm_prior = |sigma: f64, t_s: f64| {
            let mut o = gm.clone();
            o.filter.effects.gnss_position_gm.sigma_m = [sigma, sigma, 2.0 * sigma];
            o.filter.effects.gnss_position_gm.t_s = t_s;
            o
        };
        for (label, o) in [
            ("base", p.opts.clone()),
            ("base + gm", gm.clone()),
            ("base + gm 0.1/200", gm_prior(0.1, 200.0)),
            ("base x2.5", scaled(&p.opts, 2.5)),
            ("base x2.5 + gm", scaled(&gm, 2.5)),
            ("x2.5 + gm 0.1/200", scaled(&gm_prior(0.1, 200.0), 2.5)),
            ("x2.5 + gm 0.05/200", scaled(&gm_prior(0.05, 200.0), 2.5)),
        ] {
            println!("{}", whiteness_line(label, &p.case, &o));
        }
    }
}

/// The base model with the GNSS sigmas scaled by `k`.
fn scaled(o: &RunOptions, k: f64) -> RunOptions {
    let mut o = o.clone();
    o.gnss_sigma_scale.horizontal *= k;
    o.gnss_sigma_scale.vertical *= k;
    o
}

/// The model `o` with the GNSS error state of per-axis sigma `sigma` (m, N E D) and
/// correlation time `t_s`.
fn with_gm(o: &RunOptions, sigma: [f64; 3], t_s: f64) -> RunOptions {
    let mut o = options_with(o, &[Block::GnssPositionGm]);
    o.filter.effects.gnss_position_gm.sigma_m = sigma;
    o.filter.effects.gnss_position_gm.t_s = t_s;
    o
}

/// Prints, for GNSS Gauss-Markov drives and clean drives, the log-likelihood and innovation
/// whiteness of the white-noise model at the GNSS noise scale that fits best (a grid) against
/// the model with the GNSS error state at the drive's true Gauss-Markov sigma and correlation
/// time and at the candidate's default prior, each with the true white-noise scale
/// (a measurement: docs/diagnose.md, "GNSS-side effects").
#[test]
#[ignore = "a measurement: prints likelihood and whiteness with the noise scale in the model"]
fn gnss_error_against_the_noise_scale() {
    let seeds: Vec<u64> = std::env::var("GNSS_GM_SEEDS")
        .ok()
        .map(|s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![100, 101, 102, 103]);
    let clean = std::env::var("GNSS_GM_CLEAN").is_ok_and(|v| v == "true");
    for seed in seeds {
        let e = (!clean).then_some(Effect::GnssCorrelatedError);
        let (p, m) = prepare(&spec(e, seed));
        let (w, r) = (m.gnss.white_sigma_ned_m.0, m.gnss.reported_std());
        let k_true = w[0] / r[0];
        println!(
            "{} seed {seed}: GNSS white {:?} m (x{k_true:.2}), GM {:?} m / {:.0} s",
            e.map_or("clean".to_string(), |e| e.to_string()),
            w,
            m.gnss.gm_sigma_ned_m.0,
            m.gnss.gm_tau_s,
        );
        let mut best = (f64::NEG_INFINITY, 0.0);
        for i in 0..12 {
            let k = 2f64.powf(i as f64 / 4.0);
            let ll = residual_stats(
                &run_filter(&p.case, &scaled(&p.opts, k))
                    .expect("run")
                    .innovations,
            )
            .log_likelihood;
            if ll > best.0 {
                best = (ll, k);
            }
        }
        let k = best.1;
        let truth = m.gnss.gm_sigma_ned_m.0;
        let tau = m.gnss.gm_tau_s;
        let mut rows = vec![
            (format!("white x{k:.2} (best)"), scaled(&p.opts, k)),
            (format!("white x{k_true:.2}"), scaled(&p.opts, k_true)),
            (
                format!("x{k_true:.2} + gm truth"),
                with_gm(&scaled(&p.opts, k_true), truth, tau),
            ),
            (
                format!("x{k_true:.2} + gm default"),
                scaled(&options_with(&p.opts, &[Block::GnssPositionGm]), k_true),
            ),
            (
                format!("x{k:.2} + gm default"),
                scaled(&options_with(&p.opts, &[Block::GnssPositionGm]), k),
            ),
        ];
        for s in [0.05, 0.1, 0.2] {
            for t in [100.0, 300.0] {
                rows.push((
                    format!("x{k_true:.2} + gm {s}/{t}"),
                    with_gm(&scaled(&p.opts, k_true), [s, s, s], t),
                ));
            }
        }
        for (label, o) in rows {
            println!("{}", whiteness_line(&label, &p.case, &o));
        }
    }
}
