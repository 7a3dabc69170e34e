//! `nav_diagnose::diagnose` on simulated drives (about 11 min at 100 Hz, RTK at 1 Hz, a tactical
//! IMU with the source's NBK noise, 30 s GNSS outages every 100 s from 150 s): for each effect
//! of the vocabulary, a drive whose data contain it while the configuration does not declare
//! it must have that effect named first, estimated within 20 % of the truth (or 3 sigma) per
//! state, and the outage position error must drop by at least 30 %. A drive with only
//! declared errors must give "none detectable" (nothing added) in at least 19 of 20 seeds, and two
//! simultaneous effects must both be found. Every drive carries a temperature column (a
//! 25 degC warm-up), so all 9 candidates compete in every test.
use host_sim::diagnose::write_outputs;
use host_sim::run::case_data;
use nav_core::config::FilterConfig;
use nav_diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use nav_engine::run::{CaseData, InitSpec, Model, PeriodicOutages, RunOptions};
use nav_engine::Prepared;
use nav_sim::errors::{Axes3, Temperature, DEG_PER_H_RADPS, UG_MPS2};
use nav_sim::{simulate, Case, ErrorModel, Scenario};
use rayon::prelude::*;
use test_support::scenario::ScenarioToml;
use test_support::truth_start::TRUTH_START_UNCERTAINTY;

/// A drive of about 11 minutes: a static start, then three laps of accelerations, turns both
/// ways, hills and stops; `v` varies speeds, radii and the start heading.
fn scenario(v: u32) -> Scenario {
    let k = f64::from(v % 4);
    let mut s = ScenarioToml::new("diagnose-test")
        .description("11 min test drive")
        .start(48.0 + 0.3 * k, 16.37, 220.0, 30.0 + 70.0 * k)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(100.0)
        .stationary(30.0);
    for lap in 0..3 {
        let l = f64::from(lap);
        let sp = 12.0 + 2.0 * k + 2.0 * l;
        let r1 = 30.0 + 5.0 * k;
        s = s
            .accelerate(sp, 8.0)
            .turn(90.0, r1)
            .cruise(15.0)
            .turn(-135.0, 25.0 + 4.0 * l)
            .hill(6.0 + 2.0 * l, 300.0)
            .accelerate(sp + 6.0, 6.0)
            .turn(180.0, 40.0 + 5.0 * k)
            .brake(4.0, 6.0)
            .turn(-90.0, 12.0)
            .accelerate(sp, 7.0)
            .turn(60.0, r1)
            .hill(-5.0 - l, 250.0)
            .stop()
            .stationary(8.0);
    }
    Scenario::from_toml_str(&s.build(), "diagnose-test").unwrap()
}

/// The source's tactical IMU (NBK noise), RTK GNSS at 1 Hz, a 25 degC warm-up with a
/// temperature column (no temperature coefficient unless a test sets one).
fn base_errors() -> ErrorModel {
    let mut e = ErrorModel::preset("seed-nbk").unwrap();
    e.temperature = Some(Temperature {
        start_c: 15.0,
        rise_c: 25.0,
        tau_s: 240.0,
        reference_c: None,
        report_noise_c: 0.02,
    });
    e
}

/// The case, the NBK filter configured with the declared lever arm, 30 s outages every 100 s
/// from 150 s.
fn prepared(v: u32, errors: &ErrorModel, declared_lever_arm_m: [f64; 3], seed: u64) -> Prepared {
    let case = simulate(&scenario(v), errors, seed).unwrap();
    let mut p = nbk_with_outages(&case, "diagnose test");
    p.opts.lever_arm_m = declared_lever_arm_m;
    p
}

/// 30 s GNSS outages every 100 s, the first 150 s after the first IMU epoch.
const OUTAGES_EVERY_100_S: PeriodicOutages = PeriodicOutages {
    first_start_s: 150.0,
    duration_s: 30.0,
    period_s: 100.0,
};

/// A simulated case for the NBK filter (the source's configuration, started at the truth)
/// with [`OUTAGES_EVERY_100_S`], the last one ending at least 10 s before the last IMU epoch;
/// the GPS week of the test drives.
pub(crate) fn nbk_with_outages(case: &Case, description: &str) -> Prepared {
    let t0 = case.meas.imu[0].t_s;
    let t_end = case.meas.imu.last().unwrap().t_s;
    let mut opts = RunOptions::new(
        Model::Nbk,
        FilterConfig::source_nbk_model(),
        InitSpec::exact_truth(TRUTH_START_UNCERTAINTY),
    );
    opts.outages = OUTAGES_EVERY_100_S.expand(t0, t_end - 10.0);
    Prepared {
        case: case_data(case),
        opts,
        week: 2227,
        description: description.into(),
    }
}

/// Checks the imposed outages of [`nbk_with_outages`]: 30 s each, the first 150 s after the
/// first IMU epoch, one every 100 s, the last ending more than 10 s before the last IMU epoch
/// and no further one fitting.
pub(crate) fn assert_outages_every_100_s(p: &Prepared) {
    let t0 = p.case.imu[0].t_s;
    let t_end = p.case.imu.last().unwrap().t_s;
    let o = &p.opts.outages;
    assert!(!o.is_empty(), "no outage");
    for (k, x) in o.iter().enumerate() {
        let want = t0 + 150.0 + 100.0 * k as f64;
        assert!(
            (x.start_s - want).abs() < 1e-6,
            "outage {k} at {}",
            x.start_s
        );
        assert_eq!(x.duration_s, 30.0);
    }
    let last = o.last().unwrap().end_s();
    assert!(
        last < t_end - 10.0,
        "last outage ends at {last}, data at {t_end}"
    );
    assert!(last + 100.0 >= t_end - 10.0, "an outage left out");
}

#[test]
fn the_test_drives_have_30_s_outages_every_100_s() {
    for v in 0..4 {
        assert_outages_every_100_s(&prepared(v, &base_errors(), [0.0; 3], 1));
    }
}

fn summary(d: &Diagnosis) -> String {
    let mut s = format!(
        "verdict: {}; outage error before {:.3} m after {:.3} m\n",
        d.verdict, d.error_before.outage_max_3d_rms_m, d.error_after.outage_max_3d_rms_m
    );
    for e in &d.added_effects {
        s.push_str(&format!(
            "  added {} est {:?} sigma {:?} evidence {:.1} runner-up {:?}\n",
            e.name, e.estimate, e.sigma, e.evidence, e.runner_up
        ));
    }
    for (i, r) in d.rounds.iter().enumerate() {
        s.push_str(&format!("  round {i}:"));
        for c in &r.candidates {
            s.push_str(&format!(
                " {}={:.1}{}",
                c.name,
                c.evidence.unwrap_or(f64::NAN),
                c.refused
                    .as_ref()
                    .filter(|_| c.evidence.is_some_and(|e| e > 0.0))
                    .map_or(String::new(), |r| format!(" [refused: {r}]"))
            ));
        }
        for n in r.ambiguous.iter().chain(&r.unexplained) {
            s.push_str(&format!("\n    {n}"));
        }
        s.push('\n');
    }
    for st in &d.steps {
        let e = &st.errors;
        s.push_str(&format!(
            "  step {} kept {}: held-out {:?} gnss {:.4} truth outage {:?} NIS {:.2} {}\n",
            st.label,
            st.accepted,
            e.heldout_outage_m,
            e.gnss_prior_horizontal_rms_m,
            e.truth_outage_m,
            e.nis_mean,
            st.reason.as_deref().unwrap_or("")
        ));
    }
    s
}

/// After is never worse than before: the outage error against the truth; no kept step whose
/// held-out window errors are significantly higher than the step before's (paired signed-rank
/// test); every added effect significantly lowers them.
fn assert_never_worse(d: &Diagnosis) {
    let (b, a) = (
        d.error_before.outage_max_3d_rms_m,
        d.error_after.outage_max_3d_rms_m,
    );
    assert!(
        a <= b,
        "outage error vs truth: before {b} after {a}\n{}",
        summary(d)
    );
    for st in d.steps.iter().filter(|s| s.accepted) {
        if let Some(h) = &st.heldout {
            assert!(
                h.verdict != nav_diagnose::HeldoutVerdict::Worse,
                "{}: {}",
                st.label,
                h.describe()
            );
        }
    }
    for e in &d.added_effects {
        assert!(
            e.heldout.p_better < 0.05 && e.heldout.gain > 0.0,
            "{}: {}",
            e.name,
            e.heldout.describe()
        );
    }
}

/// Asserts the effect is named first, every state is within 20 % of the truth or 3 sigma, and
/// the outage error dropped by at least 30 %.
fn check_first(d: &Diagnosis, name: &str, truth: &[f64]) {
    check_first_ratio(d, name, truth, 0.7);
}

/// [`check_first`] with the largest allowed outage-error ratio after / before.
fn check_first_ratio(d: &Diagnosis, name: &str, truth: &[f64], max_ratio: f64) {
    println!("{name}: truth {truth:?}\n{}", summary(d));
    let first = d.added_effects.first().expect("an effect must be added");
    assert_eq!(first.name, name);
    assert_eq!(first.estimate.len(), truth.len());
    for ((est, sig), tr) in first.estimate.iter().zip(&first.sigma).zip(truth) {
        let err = (est - tr).abs();
        assert!(
            err <= 0.2 * tr.abs() || err <= 3.0 * sig,
            "{name}: estimate {est} sigma {sig} truth {tr}"
        );
    }
    let (b, a) = (
        d.error_before.outage_max_3d_rms_m,
        d.error_after.outage_max_3d_rms_m,
    );
    println!("{name}: outage error ratio after/before {:.3}", a / b);
    assert!(
        a <= max_ratio * b,
        "{name}: outage error before {b} m after {a} m"
    );
    assert!(d.residuals_after.log_likelihood > d.residuals_before.log_likelihood);
    assert_never_worse(d);
}

fn run(v: u32, e: &ErrorModel, lever: [f64; 3], seed: u64) -> Diagnosis {
    let p = prepared(v, e, lever, seed);
    diagnose(&p, &DiagnoseOptions::default()).unwrap().diagnosis
}

#[test]
fn undeclared_accel_scale_factor_is_found() {
    let mut e = base_errors();
    let ppm = [1500.0, -900.0, 1200.0];
    e.accel.scale_factor_ppm = Axes3(ppm);
    let d = run(0, &e, [0.0; 3], 101);
    check_first(&d, "accel_scale_factor", &ppm.map(|p| p * 1e-6));
}

#[test]
fn undeclared_gyro_scale_factor_is_found() {
    let mut e = base_errors();
    let ppm = [-700.0, 1100.0, 1800.0];
    e.gyro.scale_factor_ppm = Axes3(ppm);
    let d = run(1, &e, [0.0; 3], 202);
    check_first(&d, "gyro_scale_factor", &ppm.map(|p| p * 1e-6));
}

/// `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]` from a row-major matrix.
fn off_diag(m: [[f64; 3]; 3]) -> [f64; 6] {
    [m[0][1], m[0][2], m[1][0], m[1][2], m[2][0], m[2][1]]
}

#[test]
fn undeclared_accel_misalignment_is_found() {
    let mut e = base_errors();
    let m = [
        [0.0, 0.3e-3, -0.2e-3],
        [-0.4e-3, 0.0, 0.15e-3],
        [0.25e-3, -0.3e-3, 0.0],
    ];
    e.accel.misalignment_rad = m;
    let d = run(2, &e, [0.0; 3], 303);
    check_first(&d, "accel_misalignment", &off_diag(m));
}

#[test]
fn undeclared_gyro_misalignment_is_found() {
    let mut e = base_errors();
    let m = [
        [0.0, -0.45e-3, 0.2e-3],
        [0.3e-3, 0.0, -0.35e-3],
        [0.4e-3, 0.1e-3, 0.0],
    ];
    e.gyro.misalignment_rad = m;
    let d = run(3, &e, [0.0; 3], 404);
    check_first(&d, "gyro_misalignment", &off_diag(m));
}

#[test]
fn undeclared_lever_arm_is_found() {
    let mut e = base_errors();
    let lever = [1.1, -0.4, -0.7];
    e.gnss.lever_arm_b_m = Axes3(lever);
    // the configuration declares part of it: the effect is the correction
    let declared = [0.3, 0.0, -0.2];
    let p = prepared(0, &e, declared, 505);
    let out = diagnose(&p, &DiagnoseOptions::default()).unwrap();
    let corr = [0, 1, 2].map(|i| lever[i] - declared[i]);
    check_first(&out.diagnosis, "lever_arm", &corr);
    check_written_solution_metric(&p, &out, corr);
    // the files: diagnosis.json per the contract, both solutions, the report and its plots
    let dir = tempfile::tempdir().unwrap();
    write_outputs(dir.path(), &p, &out, None).unwrap();
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("diagnosis.json")).unwrap())
            .unwrap();
    let added = j["added_effects"].as_array().unwrap();
    assert_eq!(added[0]["name"], "lever_arm");
    for k in ["estimate", "sigma"] {
        let v = added[0][k].as_array().unwrap();
        assert_eq!(v.len(), 3);
        assert!(v.iter().all(|x| x.as_f64().unwrap().is_finite()));
    }
    assert!(added[0]["evidence"].as_f64().unwrap() > 0.0);
    for f in ["nav_before.txt", "nav_after.txt"] {
        let text = std::fs::read_to_string(dir.path().join(f)).unwrap();
        let rows = text.lines().filter(|l| !l.starts_with('#')).count();
        assert_eq!(rows, out.before_nav.len(), "{f}");
    }
    for f in [
        "report.md",
        "innovations.png",
        "nis.png",
        "evidence.png",
        "errors.png",
    ] {
        assert!(
            std::fs::metadata(dir.path().join(f)).unwrap().len() > 1000,
            "{f}"
        );
    }
}

#[test]
fn undeclared_time_offset_is_found() {
    let mut e = base_errors();
    // simulator: a fix tagged t is the antenna at IMU time t - 0.07 s (GNSS tags late);
    // filter state: the fix is the antenna at t + dt, so dt = -0.07 s
    e.gnss.time_offset_s = 0.07;
    let p = prepared(1, &e, [0.0; 3], 606);
    let out = diagnose(&p, &DiagnoseOptions::default()).unwrap();
    let d = &out.diagnosis;
    check_first(d, "time_offset", &[-0.07]);
    // the output on the GNSS clock: nav_after.txt stamped IMU time - estimate, and closer to
    // the fixes than the before solution on the IMU clock
    let dt = d.added_effects[0].estimate[0];
    assert_eq!(d.output_clock_shift_s, -dt);
    let dir = tempfile::tempdir().unwrap();
    write_outputs(dir.path(), &p, &out, None).unwrap();
    let first_t = |f: &str| -> f64 {
        let text = std::fs::read_to_string(dir.path().join(f)).unwrap();
        let row = text.lines().find(|l| !l.starts_with('#')).unwrap();
        let cols: Vec<f64> = row
            .split_whitespace()
            .map(|x| x.parse::<f64>().unwrap())
            .collect();
        cols[1]
    };
    let shift = first_t("nav_after.txt") - first_t("nav_before.txt");
    assert!((shift + dt).abs() < 1e-6, "shift {shift} estimate {dt}");
    let (b, a) = (
        d.error_before.output_vs_fixes_horizontal_rms_m,
        d.error_after.output_vs_fixes_horizontal_rms_m,
    );
    println!("solution vs fixes outside outages: before {b:.4} m after (GNSS clock) {a:.4} m");
    assert!(a < b, "before {b} after {a}");
}

#[test]
fn undeclared_accel_temperature_coefficient_is_found() {
    let mut e = base_errors();
    let k = [40.0 * UG_MPS2, -30.0 * UG_MPS2, 55.0 * UG_MPS2];
    e.accel.temp_coeff_per_c = Axes3(k);
    let d = run(2, &e, [0.0; 3], 707);
    check_first(&d, "accel_temperature_bias", &k);
}

/// The gyro temperature coefficient at 0.3-0.5 deg/h/degC (7-12 deg/h over the warm-up).
/// Measured detection limit on this drive: 0.1 deg/h/degC (2.5 deg/h over the warm-up, 25x
/// the gyro's turn-on bias sigma) is NOT found (evidence -4.5 nats, inside the clean-seed
/// range), 0.3 deg/h/degC is (evidence +575, estimate within 13 %).
#[test]
fn undeclared_gyro_temperature_coefficient_is_found() {
    let mut e = base_errors();
    let k = [
        0.4 * DEG_PER_H_RADPS,
        -0.3 * DEG_PER_H_RADPS,
        0.5 * DEG_PER_H_RADPS,
    ];
    e.gyro.temp_coeff_per_c = Axes3(k);
    let d = run(3, &e, [0.0; 3], 808);
    check_first(&d, "gyro_temperature_bias", &k);
}

/// A g-sensitivity of 0.5 deg/h/g on the diagonal, is below what a land drive can
/// show: on the z gyro it acts as a constant 0.5 deg/h bias (f_z = -g; the gyro-bias states
/// absorb it), on x/y it is 0.1 deg/h during 0.2 g accelerations. Measured: the diagnosis adds
/// nothing and the outage error is unchanged; the target (named first, 30 % better) is
/// NOT met at this size.
#[test]
fn gyro_g_sensitivity_of_half_deg_per_h_per_g_is_not_detectable_on_a_land_drive() {
    let mut e = base_errors();
    let g = 0.5 * DEG_PER_H_RADPS / nav_core::earth::G0_MPS2;
    e.gyro.g_sensitivity_radps_per_mps2 = [[g, 0.0, 0.0], [0.0, -g, 0.0], [0.0, 0.0, g]];
    let d = run(0, &e, [0.0; 3], 909);
    println!("{}", summary(&d));
    let top = &d.rounds[0].candidates[0];
    println!(
        "strongest candidate {} evidence {:?}",
        top.name, top.evidence
    );
    assert!(d.added_effects.is_empty(), "{}", summary(&d));
    assert_eq!(
        d.error_before.outage_max_3d_rms_m,
        d.error_after.outage_max_3d_rms_m
    );
    // "none detectable", with a bound above the effect's size
    assert_eq!(d.verdict, "none detectable");
    let u = d
        .undetected
        .iter()
        .find(|u| u.name == "gyro_g_sensitivity")
        .expect("a bound for the g-sensitivity");
    let per_g = DEG_PER_H_RADPS / nav_core::earth::G0_MPS2;
    println!(
        "g-sensitivity detectability bound: {:.2} deg/h/g (per axis {:?})",
        u.min_bound / per_g,
        u.bound.iter().map(|b| b / per_g).collect::<Vec<_>>()
    );
    assert!(
        u.min_bound > 0.5 * per_g,
        "bound {} deg/h/g",
        u.min_bound / per_g
    );
    assert_eq!(u.bound.len(), 3);
    // every candidate has a finite bound
    assert_eq!(d.undetected.len(), d.candidates_considered.len());
    assert!(d
        .undetected
        .iter()
        .all(|u| u.min_bound.is_finite() && u.min_bound > 0.0));
}

/// At 10 deg/h/g (20x that size) the g-sensitivity is named first and the outage error
/// drops; its estimate is NOT within 20 % / 3 sigma (measured: x 0.2e-6 +- 0.5e-6 for 4.9e-6,
/// z 3.7e-6 +- 0.25e-6): x/y are barely excited on land and z is separated from the z gyro
/// bias only by the bias prior. Only the naming and the improvement are asserted.
#[test]
fn undeclared_large_gyro_g_sensitivity_is_named_first() {
    let mut e = base_errors();
    let g = 10.0 * DEG_PER_H_RADPS / nav_core::earth::G0_MPS2;
    e.gyro.g_sensitivity_radps_per_mps2 = [[g, 0.0, 0.0], [0.0, -g, 0.0], [0.0, 0.0, g]];
    let d = run(0, &e, [0.0; 3], 909);
    println!(
        "g-sensitivity 10 deg/h/g, truth [{g}, {}, {g}]\n{}",
        -g,
        summary(&d)
    );
    assert_eq!(d.added_effects[0].name, "gyro_g_sensitivity");
    assert!(d.error_after.outage_max_3d_rms_m < d.error_before.outage_max_3d_rms_m);
}

#[test]
fn two_undeclared_effects_are_both_found() {
    let mut e = base_errors();
    e.gnss.lever_arm_b_m = Axes3([0.5, 0.35, -0.9]);
    e.gyro.scale_factor_ppm = Axes3([0.0, 0.0, 1400.0]);
    let d = run(2, &e, [0.0; 3], 1111);
    println!("{}", summary(&d));
    let names: Vec<&str> = d.added_effects.iter().map(|e| e.name.as_str()).collect();
    assert!(names.contains(&"lever_arm"), "{names:?}");
    let la = d
        .added_effects
        .iter()
        .find(|e| e.name == "lever_arm")
        .unwrap();
    for ((est, sig), tr) in la.estimate.iter().zip(&la.sigma).zip([0.5, 0.35, -0.9]) {
        let err = (est - tr).abs();
        assert!(
            err <= 0.2 * f64::abs(tr) || err <= 3.0 * sig,
            "{est} {sig} {tr}"
        );
    }
    assert!(d.error_after.outage_max_3d_rms_m <= 0.7 * d.error_before.outage_max_3d_rms_m);
    assert_never_worse(&d);
    // The gyro z scale factor (1400 ppm) is seen (its likelihood gain is large and its
    // estimate significant) but, with the lever arm in the model, adding it RAISES the
    // held-out outage error on this drive (measured: 0.518 -> 0.604 m against the withheld
    // fixes), so the rule "after never worse" refuses it: it must be either added
    // with its estimate within 20 % / 3 sigma, or reported as refused by the held-out check
    // with the likelihood gain it leaves unexplained.
    match d
        .added_effects
        .iter()
        .find(|e| e.name == "gyro_scale_factor")
    {
        Some(sf) => {
            assert!((sf.estimate[2] - 1400e-6).abs() <= (0.2 * 1400e-6f64).max(3.0 * sf.sigma[2]))
        }
        None => {
            let c = d
                .rounds
                .last()
                .and_then(|r| r.candidates.iter().find(|c| c.name == "gyro_scale_factor"))
                .expect("gyro_scale_factor tried in the last round");
            assert!(c.evidence.unwrap() > 0.0 && c.max_z >= 2.0, "{c:?}");
            assert!(
                c.refused.as_deref().unwrap().starts_with("held-out"),
                "{c:?}"
            );
            assert!(
                d.warnings.iter().any(|w| w.contains("gyro_scale_factor")),
                "{:?}",
                d.warnings
            );
            let z = c.estimate[2] / c.sigma[2];
            println!(
                "gyro z scale factor refused: estimate {:.0} ppm ({z:.1} sigma) for 1400 ppm; {}",
                c.estimate[2] * 1e6,
                c.refused.as_deref().unwrap()
            );
        }
    }
}

/// A case configured from its `kf-gins.yaml` alone (21-state KF-GINS model, as KF-GINS runs
/// it: `kf-gins-feedback`) whose scale
/// factors are declared absent (`gsstd`, `asstd`, `initsgstd`, `initsastd` = 0: the states
/// exist but are frozen), 30 s outages every 100 s from 150 s.
fn kf_gins_prepared(v: u32, e: &ErrorModel, seed: u64, dir: &std::path::Path) -> Prepared {
    let case = simulate(&scenario(v), e, seed).unwrap();
    case.write(dir, true).unwrap();
    let yp = dir.join("kf-gins.yaml");
    let y = std::fs::read_to_string(&yp).unwrap();
    let y: String = y
        .lines()
        .map(|l| {
            let t = l.trim_start();
            for k in ["gsstd:", "asstd:", "initsgstd:", "initsastd:"] {
                if t.starts_with(k) {
                    let indent = &l[..l.len() - t.len()];
                    return format!("{indent}{k} [ 0, 0, 0 ]");
                }
            }
            l.to_string()
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&yp, y).unwrap();
    let mut a = nav_engine::RunSpec::new(&yp);
    a.periodic_outages = vec![nav_engine::run::parse_periodic("150:30:100").unwrap()];
    let p = a.prepare().unwrap();
    assert_eq!(p.opts.model, Model::KfGinsFeedback);
    assert_eq!(p.opts.filter.gyro_scale.sigma, [0.0; 3]);
    assert_eq!(p.opts.filter.accel_scale.sigma, [0.0; 3]);
    assert!(p.case.truth.is_some());
    p
}

/// An undeclared scale factor under a KF-GINS configuration that freezes the
/// scale-factor states is named (the frozen block is freed), estimated within 20 % / 3 sigma,
/// and the outage error drops by at least 30 %, never worse in any step.
#[test]
fn kf_gins_frozen_scale_factors_are_freed_and_named() {
    let gyro = [-600.0, 800.0, 1000.0];
    let accel = [1200.0, -1000.0, 900.0];
    let cases = [
        ("gyro_scale_factor", gyro, 2u32, 1401u64),
        ("accel_scale_factor", accel, 1, 1402),
    ];
    let res: Vec<(&str, [f64; 3], Diagnosis)> = cases
        .par_iter()
        .map(|&(name, ppm, v, seed)| {
            let mut e = base_errors();
            if name == "gyro_scale_factor" {
                e.gyro.scale_factor_ppm = Axes3(ppm);
            } else {
                e.accel.scale_factor_ppm = Axes3(ppm);
            }
            let dir = tempfile::tempdir().unwrap();
            let p = kf_gins_prepared(v, &e, seed, dir.path());
            assert!(nav_diagnose::candidates(&p.case, &p.opts)
                .iter()
                .any(|b| b.name() == name));
            let d = diagnose(&p, &DiagnoseOptions::default()).unwrap().diagnosis;
            (name, ppm, d)
        })
        .collect();
    for (name, ppm, d) in &res {
        let first = d.added_effects.first().expect("an effect must be added");
        println!(
            "KF-GINS {name}: estimate {:?} ppm",
            first.estimate.iter().map(|x| x * 1e6).collect::<Vec<_>>()
        );
        assert!(first.freed, "{name} was frozen in the configuration");
        check_first(d, name, &ppm.map(|p| p * 1e-6));
    }
}

fn grade(d: &Diagnosis, name: &str, truth: &[f64]) -> (bool, bool, bool, f64, f64) {
    let first = d.added_effects.first();
    let named = first.is_some_and(|f| f.name == name);
    let est_ok = first.is_some_and(|f| {
        f.name == name
            && f.estimate
                .iter()
                .zip(&f.sigma)
                .zip(truth)
                .all(|((e, s), t)| {
                    let err = (e - t).abs();
                    err <= 0.2 * t.abs() || err <= 3.0 * s
                })
    });
    let (b, a) = (
        d.error_before.outage_max_3d_rms_m,
        d.error_after.outage_max_3d_rms_m,
    );
    (named, est_ok, a <= 0.7 * b, b, a)
}

/// 40 more drives (8 effects x 4 seeds, magnitudes x0.6 to x1.33 of the per-effect tests'
/// sizes, other trajectories and seeds, plus the two scale factors x 4 seeds configured from a
/// KF-GINS YAML with frozen scale-factor states): the median outage-error ratio after/before
/// at most 0.7 and no case worse than before; in every case the effect is named
/// first with its estimate within 20 % / 3 sigma, or its refusal is right
/// ([`refusal_is_right`]: it was the strongest candidate, estimated within those limits, and
/// even the exact effect raises the held-out error on that drive; measured: 2 of the 40, the
/// KF-GINS accel seed 95000 and gyro seed 95122, see
/// [`refused_scale_factors_help_over_noise_seeds`]). The 30 % improvement per case is counted
/// and printed. `DIAGNOSE_SWEEP_SEEDS=95000,95122` runs only those seeds;
/// `DIAGNOSE_SWEEP_SMOOTH=1` scores on the smoothed solutions (`diagnose --smooth`). Run with
/// `--ignored` (measured numbers in the README's diagnose section).
#[test]
#[ignore]
fn robustness_sweep_over_seeds_and_magnitudes() {
    let g = |x: f64| x * DEG_PER_H_RADPS;
    type Mk = Box<dyn Fn(&mut ErrorModel, f64) -> (String, Vec<f64>) + Sync>;
    let cases: Vec<Mk> = vec![
        Box::new(|e, k| {
            let p = [1200.0 * k, -700.0 * k, 900.0];
            e.accel.scale_factor_ppm = Axes3(p);
            ("accel_scale_factor".into(), p.map(|x| x * 1e-6).to_vec())
        }),
        Box::new(|e, k| {
            let p = [600.0, -900.0 * k, 1500.0 * k];
            e.gyro.scale_factor_ppm = Axes3(p);
            ("gyro_scale_factor".into(), p.map(|x| x * 1e-6).to_vec())
        }),
        Box::new(|e, k| {
            let m = [
                [0.0, 0.25e-3 * k, 0.2e-3],
                [-0.3e-3 * k, 0.0, 0.1e-3],
                [0.2e-3, -0.35e-3, 0.0],
            ];
            e.accel.misalignment_rad = m;
            ("accel_misalignment".into(), off_diag(m).to_vec())
        }),
        Box::new(|e, k| {
            let m = [
                [0.0, 0.3e-3 * k, -0.25e-3],
                [0.2e-3, 0.0, 0.4e-3 * k],
                [-0.3e-3, 0.15e-3, 0.0],
            ];
            e.gyro.misalignment_rad = m;
            ("gyro_misalignment".into(), off_diag(m).to_vec())
        }),
        Box::new(|e, k| {
            let l = [0.7 * k, 0.3, -0.5 * k];
            e.gnss.lever_arm_b_m = Axes3(l);
            ("lever_arm".into(), l.to_vec())
        }),
        Box::new(|e, k| {
            e.gnss.time_offset_s = -0.04 * k;
            ("time_offset".into(), vec![0.04 * k])
        }),
        Box::new(|e, k| {
            let c = [25.0 * UG_MPS2 * k, 45.0 * UG_MPS2, -35.0 * UG_MPS2 * k];
            e.accel.temp_coeff_per_c = Axes3(c);
            ("accel_temperature_bias".into(), c.to_vec())
        }),
        Box::new(move |e, k| {
            let c = [g(0.3) * k, g(0.4), -g(0.35) * k];
            e.gyro.temp_coeff_per_c = Axes3(c);
            ("gyro_temperature_bias".into(), c.to_vec())
        }),
    ];
    // 8 effects x 4 seeds from our TOML-style NBK configuration, plus the two scale factors
    // x 4 seeds from a KF-GINS YAML with frozen (zero-sigma) scale-factor states
    let jobs: Vec<(usize, u64, bool)> = (0..cases.len())
        .flat_map(|c| (0..4u64).map(move |s| (c, s, false)))
        .chain((0..2usize).flat_map(|c| (0..4u64).map(move |s| (c, s, true))))
        .filter(|&(c, s, kf)| {
            // DIAGNOSE_SWEEP_SEEDS=95000,95122: only those drives (to study a case)
            std::env::var("DIAGNOSE_SWEEP_SEEDS").map_or(true, |v| {
                let seed = 90000 + 101 * c as u64 + 7 * s + if kf { 5000 } else { 0 };
                v.split(',').any(|x| x.trim().parse() == Ok(seed))
            })
        })
        .collect();
    let n_jobs = jobs.len();
    #[allow(clippy::type_complexity)]
    let res: Vec<(String, bool, bool, bool, f64, bool)> = jobs
        .par_iter()
        .map(|&(c, s, kf)| {
            let mut e = base_errors();
            let k = 1.0 + 0.5 * (s as f64) / 3.0 * if s % 2 == 0 { 1.0 } else { -0.8 };
            let (name, truth) = cases[c](&mut e, k);
            let seed = 90000 + 101 * c as u64 + 7 * s + if kf { 5000 } else { 0 };
            let v = (s + c as u64) as u32 % 4;
            let dir = tempfile::tempdir().unwrap();
            let p = if kf {
                kf_gins_prepared(v, &e, seed, dir.path())
            } else {
                prepared(v, &e, [0.0; 3], seed)
            };
            // DIAGNOSE_SWEEP_SMOOTH=1: the held-out check scored on the smoothed solutions
            let o = DiagnoseOptions {
                smooth: std::env::var("DIAGNOSE_SWEEP_SMOOTH").is_ok_and(|v| v == "1"),
                ..DiagnoseOptions::default()
            };
            let d = diagnose(&p, &o).unwrap().diagnosis;
            let (n, eo, imp, b, a) = grade(&d, &name, &truth);
            let right = n && eo;
            let refusal = (!right).then(|| refusal_is_right(&p, &d, &name, &truth));
            if !right || std::env::var("DIAGNOSE_SWEEP_SEEDS").is_ok() {
                println!(
                    "NOT NAMED FIRST {name} seed {seed}: {refusal:?}\n{}",
                    summary(&d)
                );
            }
            let line = format!(
                "{}{name} seed {seed} k {k:.2}: named {n} est {eo} improved30 {imp} \
             before {b:.3} after {a:.3} ratio {:.3} verdict {}",
                if kf { "KF-GINS " } else { "" },
                a / b,
                d.verdict
            );
            (line, n, eo, imp, a / b, refusal.is_some_and(|r| r.is_ok()))
        })
        .collect();
    for r in &res {
        println!("{}", r.0);
    }
    let improved = res.iter().filter(|r| r.3).count();
    let mut ratios: Vec<f64> = res.iter().map(|r| r.4).collect();
    ratios.sort_by(f64::total_cmp);
    let median = 0.5 * (ratios[(n_jobs - 1) / 2] + ratios[n_jobs / 2]);
    let worst = ratios[n_jobs - 1];
    println!(
        "named first {} / {n_jobs}, estimate {} / {n_jobs}, improved 30 % {improved} / {n_jobs}; \
         outage-error ratio after/before: median {median:.3}, worst {worst:.3}",
        res.iter().filter(|r| r.1).count(),
        res.iter().filter(|r| r.2).count()
    );
    assert!(median <= 0.7, "median ratio {median}");
    assert!(worst <= 1.0, "a case worse than before: {worst}");
    let right_refusals = res.iter().filter(|r| !(r.1 && r.2) && r.5).count();
    println!(
        "not named first but refused rightly (the exact effect raises the held-out error): \
         {right_refusals}"
    );
    assert!(res.iter().all(|r| (r.1 && r.2) || r.5));
}

/// Whether a sweep case whose effect was not added was refused rightly: the true effect was
/// the strongest candidate of the first round, its estimate within 20 % / 3 sigma of the truth,
/// refused by the held-out check; and the oracle agrees: the diagnosis's final model run on
/// the data with the true effect removed exactly (a scale factor divided out of the
/// increments: the model then has the effect right with no estimation error) predicts the
/// withheld fixes no better than the final model on the data as they are. Then adding the
/// effect, however well estimated, would make the outage error worse on this drive, and the
/// rule "never worse" forbids it. Err: why not (other effects have no exact correction
/// here).
fn refusal_is_right(
    p: &Prepared,
    d: &Diagnosis,
    name: &str,
    truth: &[f64],
) -> Result<String, String> {
    let gyro = match name {
        "gyro_scale_factor" => true,
        "accel_scale_factor" => false,
        _ => return Err(format!("no exact correction of {name} in the oracle")),
    };
    let r0 = d.rounds.first().ok_or("no round")?;
    let top = r0
        .candidates
        .iter()
        .max_by(|a, b| {
            a.evidence
                .unwrap_or(f64::NEG_INFINITY)
                .total_cmp(&b.evidence.unwrap_or(f64::NEG_INFINITY))
        })
        .ok_or("no candidate")?;
    if top.name != name {
        return Err(format!("strongest candidate {} not {name}", top.name));
    }
    let within = top.estimate.len() == truth.len()
        && top
            .estimate
            .iter()
            .zip(&top.sigma)
            .zip(truth)
            .all(|((e, s), t)| (e - t).abs() <= (0.2 * t.abs()).max(3.0 * s));
    if !within {
        return Err(format!("estimate {:?} vs truth {truth:?}", top.estimate));
    }
    let why = top.refused.clone().unwrap_or_default();
    if !why.starts_with("held-out") {
        return Err(format!("refused for another reason: {why}"));
    }
    let corrected = without_scale_factor(&p.case, gyro, truth);
    let mut o = p.opts.clone();
    if let Some(t) = d.noise_tuning.as_ref().filter(|t| t.adopted) {
        t.chosen.apply(&mut o);
    }
    let out = nav_engine::run::run_filter(&corrected, &o).map_err(|e| e.to_string())?;
    let m = nav_engine::metrics::compute(&out, p.case.truth.as_deref());
    let exact = nav_diagnose::validate::step_errors(&out, &m)
        .heldout_outage_m
        .ok_or("no held-out error")?;
    let fin = d
        .steps
        .iter()
        .rev()
        .find(|s| s.accepted)
        .and_then(|s| s.errors.heldout_outage_m)
        .ok_or("no final held-out error")?;
    if exact < fin {
        return Err(format!(
            "the exact effect would lower the held-out error ({fin:.3} -> {exact:.3} m)"
        ));
    }
    Ok(format!(
        "{why}; the exact effect also raises it ({fin:.3} -> {exact:.3} m)"
    ))
}

#[test]
fn clean_drive_gives_no_missing_effect_in_19_of_20_seeds() {
    let e = base_errors();
    let results: Vec<(u64, Diagnosis)> = (0..20u64)
        .into_par_iter()
        .map(|i| {
            let seed = 5000 + 37 * i;
            (seed, run(i as u32, &e, [0.0; 3], seed))
        })
        .collect();
    let mut clean = 0;
    for (seed, d) in &results {
        println!("seed {seed}: {}", summary(d));
        if d.added_effects.is_empty() {
            clean += 1;
            assert_eq!(d.residuals_before.updates, d.residuals_after.updates);
            assert_eq!(d.verdict, "none detectable");
        }
        assert_never_worse(d);
    }
    println!("no missing effect in {clean} of 20 seeds");
    assert!(clean >= 19, "no missing effect in only {clean} of 20 seeds");
}

/// `diagnose --tune-noise` on the drive of `v` with the white noise declared `understate`
/// times too small (PSD).
fn tuned(v: u32, e: &ErrorModel, seed: u64, understate: f64) -> Diagnosis {
    let mut p = prepared(v, e, [0.0; 3], seed);
    // the classic 0.9999 gate: the robust gating (the default) adapts to a mismatch by
    // itself and hides part of the understated noise this test measures (with its first
    // version, which inflated Q: base NIS 3.84 instead of 8.57)
    p.opts.filter.gating = host_sim::run::cli::parse_gate("0.9999").unwrap();
    nav_engine::run::prepare::scale_white_noise(&mut p.opts.filter, 1.0 / understate);
    let o = DiagnoseOptions {
        tune_noise: true,
        ..DiagnoseOptions::default()
    };
    diagnose(&p, &o).unwrap().diagnosis
}

fn print_tuning(name: &str, d: &Diagnosis) {
    let t = d.noise_tuning.as_ref().expect("tuning ran");
    println!(
        "{name}: factor {} (final {}, evidence {:.1}); NIS before {:.2} after {:.2}\n{}",
        t.chosen_scale,
        t.final_scale(),
        t.evidence,
        d.residuals_before.nis_mean,
        d.residuals_after.nis_mean,
        summary(d)
    );
    assert_eq!(t.scales.len(), t.log_likelihood.len());
}

/// `--tune-noise`: with the white noise declared 16 times too small (PSD), the likelihood
/// search finds the factor (within one grid step), the tuned base model is consistent and
/// nothing is reported missing; with the right noise it keeps the configuration's (within
/// one grid step).
#[test]
fn tune_noise_recovers_an_understated_white_noise_and_keeps_a_right_one() {
    let e = base_errors();
    let a = tuned(3, &e, 7001, 16.0);
    let b = tuned(2, &e, 7002, 1.0);
    print_tuning("understated x16", &a);
    print_tuning("right noise", &b);
    let k = |d: &Diagnosis| d.noise_tuning.as_ref().unwrap().chosen_scale;
    assert!(
        (8.0..=32.0).contains(&k(&a)),
        "understated: factor {}",
        k(&a)
    );
    assert!(a.added_effects.is_empty(), "{}", summary(&a));
    let exp = a.residuals_after.nis_expected;
    assert!(a.residuals_before.nis_mean > 2.0 * exp);
    assert!(
        (0.5 * exp..=1.5 * exp).contains(&a.residuals_after.nis_mean),
        "tuned NIS {}",
        a.residuals_after.nis_mean
    );
    assert!(
        (0.5..=2.0).contains(&k(&b)),
        "right noise: factor {}",
        k(&b)
    );
    assert!(b.added_effects.is_empty(), "{}", summary(&b));
}

/// With an undeclared time offset on top of understated noise the tuned search names the
/// time offset and the re-fit finds the understated factor again.
///
/// Alone, neither is added: the time offset (35,034 nats, held-out gain +91.1 % [+81.7,
/// +93.7], 12 of 13 windows lower) has its estimate at 1.55 sigma in the overconfident model
/// (NIS 302), and the tuned noise (x512, GNSS x32) raises the windows' RMS 1.837 -> 2.028 m.
/// Judged together (the noise and the paying candidate whose windows alone are significantly
/// lower) they are added: the offset -0.0501 +- 0.0001 s at 15 sigma, held-out gain +91.8 %,
/// 13 of 13 windows lower; the re-fit with the offset finds x16 (5 s of CPU in release).
#[test]
fn tune_noise_with_a_time_offset_names_the_offset_and_refits_the_factor() {
    let mut e_dt = base_errors();
    e_dt.gnss.time_offset_s = 0.05;
    let c = tuned(1, &e_dt, 7003, 16.0);
    print_tuning("understated x16 + time offset", &c);
    let k = |d: &Diagnosis| d.noise_tuning.as_ref().unwrap().chosen_scale;
    // the first search absorbs the time offset's residual into noise (an upper bound); the
    // re-fit with the effect in the model finds the understated factor again
    let kc = c.noise_tuning.as_ref().unwrap().final_scale();
    assert!(
        (8.0..=32.0).contains(&kc),
        "with time offset: first factor {}, final {kc}",
        k(&c)
    );
    let first = c.added_effects.first().expect("time offset found");
    assert_eq!(first.name, "time_offset");
    assert!((first.estimate[0] + 0.05).abs() <= 0.01_f64.max(3.0 * first.sigma[0]));
}

/// The case with a scale factor divided out of the increments exactly (`truth`: per axis,
/// dimensionless): the data a model with that effect known exactly sees.
fn without_scale_factor(case: &CaseData, gyro: bool, truth: &[f64]) -> CaseData {
    let mut c = case.clone();
    for smp in &mut c.imu {
        for (i, t) in truth.iter().enumerate().take(3) {
            if gyro {
                smp.dtheta_rad[i] /= 1.0 + t;
            } else {
                smp.dv_mps[i] /= 1.0 + t;
            }
        }
    }
    c
}

/// The sweep's two KF-GINS drives where the true scale factor is refused (accel seed 95000,
/// gyro seed 95122), over 12 noise seeds each on the same trajectory with the same scale
/// factor: freeing the block lowers the held-out outage error in most seeds, and in every seed
/// it lands near the exact model (the data with the scale factor divided out); the two sweep
/// seeds are realisations where the model WITHOUT the scale factor predicts the three
/// outages better than the exact one (the unmodelled error happens to cancel the others).
/// Measured: accel 9 of 12 better, geometric means base 0.914, freed 0.615, exact 0.592 m;
/// gyro 10 of 12, 0.985, 0.677, 0.651 m. Run with `--ignored` (about 20 s).
#[test]
#[ignore]
fn refused_scale_factors_help_over_noise_seeds() {
    use nav_core::model::Block;
    use nav_diagnose::{options_with, validate};
    let cases: Vec<(&str, [f64; 3], u32, u64)> = vec![
        ("accel_scale_factor", [1200.0, -700.0, 900.0], 0, 95000),
        ("gyro_scale_factor", [600.0, -540.0, 900.0], 0, 95122),
    ];
    for (name, ppm, v, seed0) in cases {
        let rows: Vec<[f64; 4]> = (0..12u64)
            .into_par_iter()
            .map(|i| {
                let seed = seed0 + 1000 * i;
                let mut e = base_errors();
                let b = if name == "gyro_scale_factor" {
                    e.gyro.scale_factor_ppm = Axes3(ppm);
                    Block::GyroScaleFactor
                } else {
                    e.accel.scale_factor_ppm = Axes3(ppm);
                    Block::AccelScaleFactor
                };
                let dir = tempfile::tempdir().unwrap();
                let p = kf_gins_prepared(v, &e, seed, dir.path());
                let corrected = without_scale_factor(
                    &p.case,
                    b == Block::GyroScaleFactor,
                    &ppm.map(|x| x * 1e-6),
                );
                let h = |case: &nav_engine::run::CaseData, o: &RunOptions| {
                    let out = nav_engine::run::run_filter(case, o).unwrap();
                    let m = nav_engine::metrics::compute(&out, p.case.truth.as_deref());
                    validate::step_errors(&out, &m).heldout_outage_m.unwrap()
                };
                let r = [
                    h(&p.case, &p.opts),
                    h(&p.case, &options_with(&p.opts, &[b])),
                    h(&corrected, &p.opts),
                    p.opts.outages.len() as f64,
                ];
                println!(
                    "{name} seed {seed}: base {:.3} freed {:.3} corrected-data base {:.3} ({} outages)",
                    r[0], r[1], r[2], r[3]
                );
                r
            })
            .collect();
        let better = rows.iter().filter(|r| r[1] < r[0]).count();
        let g = |k: usize| (rows.iter().map(|r| r[k].ln()).sum::<f64>() / rows.len() as f64).exp();
        println!(
            "{name}: freed better than base in {better} of {}; geometric means base {:.3} freed {:.3} corrected {:.3}",
            rows.len(),
            g(0),
            g(1),
            g(2)
        );
        assert!(better >= 9, "{name}: freed better in only {better} of 12");
        assert!(
            g(1) < 0.75 * g(0),
            "{name}: geometric means {} vs {}",
            g(1),
            g(0)
        );
        // the sweep's seed: the exact model predicts worse than the model without the block
        assert!(
            rows[0][2] > 0.95 * rows[0][0],
            "{name} seed {seed0}: {:?}",
            rows[0]
        );
    }
}

/// The written solution's metric (`error_before/after.output_vs_fixes_horizontal_rms_m`) places
/// the antenna as the after model does: with an undeclared lever arm, a time offset, or both,
/// the after solution (GNSS clock, configured + estimated lever arm) lies on the fixes within a
/// few cm, and the configured arm alone would not (measured: 0.011 m vs 0.764 m for the 0.86 m
/// lever arm). Checked on the diagnosis of `undeclared_lever_arm_is_found` and here on drives
/// with a time offset alone and with both.
/// `undeclared` is the true lever arm minus the configured one.
fn check_written_solution_metric(
    p: &Prepared,
    out: &nav_diagnose::DiagnoseOutput,
    undeclared: [f64; 3],
) {
    let d = &out.diagnosis;
    let configured = p.opts.lever_arm_m;
    let la = d
        .added_effects
        .iter()
        .find(|e| e.name == "lever_arm")
        .map_or(configured, |e| {
            [0, 1, 2].map(|i| configured[i] + e.estimate[i])
        });
    let (nav_before, nav_after) = (
        out.before_nav.load().unwrap(),
        out.after_nav.load().unwrap(),
    );
    let f = |run: &nav_engine::run::RunOutput, nav, shift: f64, l: [f64; 3]| {
        nav_diagnose::validate::output_vs_fixes_horizontal_rms_m(
            nav,
            shift,
            l,
            &p.case.gnss,
            &run.outages,
        )
    };
    let sh = d.output_clock_shift_s;
    let (before, cfg, est) = (
        f(&out.before, &nav_before, 0.0, configured),
        f(&out.after, &nav_after, sh, configured),
        f(&out.after, &nav_after, sh, la),
    );
    println!(
        "undeclared lever {undeclared:?}: {} configured + estimate {la:?} shift {sh:+.4}: before {before:.4} after \
         configured arm {cfg:.4} after configured + estimate {est:.4}",
        d.verdict
    );
    assert_eq!(d.error_before.output_vs_fixes_horizontal_rms_m, before);
    assert_eq!(d.error_after.output_vs_fixes_horizontal_rms_m, est);
    assert!(est < 0.05, "{est}");
    assert!(est < before);
    if undeclared != [0.0; 3] {
        assert!(cfg > 5.0 * est, "configured arm {cfg} vs estimate {est}");
    }
}

#[test]
fn written_solution_metric_uses_the_estimated_lever_arm_and_time_offset() {
    for (lever, dt) in [([0.0; 3], -0.05), ([0.3, 0.1, -0.2], -0.05)] {
        let mut e = base_errors();
        e.gnss.lever_arm_b_m = Axes3(lever);
        e.gnss.time_offset_s = dt;
        let p = prepared(1, &e, [0.0; 3], 4242);
        let out = diagnose(&p, &DiagnoseOptions::default()).unwrap();
        check_written_solution_metric(&p, &out, lever);
    }
}

/// The `diagnose` command line parses (its arguments and `run`'s flattened ones must not
/// collide: a duplicated `--smooth` made every `host-sim diagnose` call fail) and offers
/// `--smooth`.
#[test]
fn diagnose_command_line_parses() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["diagnose", "--help"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("--smooth") && text.contains("--max-effects"),
        "{text}"
    );
}
