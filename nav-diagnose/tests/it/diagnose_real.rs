//! `diagnose` on the real drive (`../shared/data/rtklibexplorer-drive0708`, consumer MEMS IMU +
//! RTK, `configs/drive0708.toml`, IMU ticks at face value from the tag start) with the reference
//! protocol: seven 20 s outages every 60 s, the first 120 s after the first GNSS fix
//! (`116.645:20:60` from the first IMU sample); the withheld RTK fixes are the reference.
//! Checks: an IMU-GNSS time offset is named first, of the size the RTK
//! fixes' prior residuals point to (0.095-0.141 s per minute of the drive, docs/diagnose.md;
//! the data's source corrects 0.125 s), every added effect is finite and significant, and
//! after is not worse than before in the outages and with GNSS against the RTK fixes on the
//! GNSS clock: the prior residuals (run without outages, the README's "with GNSS") and the
//! written solution against fixes it did not use (every fourth fix withheld), the after
//! model being the augmented configuration (time offset as `imu.time_offset_s`, so its
//! solution is on the GNSS clock).
use nav_diagnose::{diagnose, write_files, Decision, DiagnoseOptions};
use nav_engine::execute;
use nav_engine::run::{parse_periodic, Outage};
use nav_engine::RunSpec;
use std::path::Path;

#[test]
fn real_drive_diagnosis_finds_the_logging_delay_and_after_is_not_worse() {
    if test_support::real_data("real_drive_diagnosis").is_none() {
        return;
    }
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/drive0708.toml");
    let mut a = RunSpec::new(config);
    a.periodic_outages = vec![parse_periodic("116.645:20:60").unwrap()];
    let p = a.prepare().expect("loading the drive");
    let out = diagnose(&p, &DiagnoseOptions::default()).expect("diagnose");
    let d = &out.diagnosis;
    println!("{}", d.verdict);
    for e in &d.added_effects {
        println!("{} {:?} +- {:?} [{}]", e.name, e.estimate, e.sigma, e.unit);
    }
    let (b, af) = (
        d.error_before.outage_max_3d_rms_m,
        d.error_after.outage_max_3d_rms_m,
    );
    println!("outage error before {b:.3} m after {af:.3} m");
    assert_eq!(d.error_before.reference, "withheld_gnss");
    assert_eq!(d.error_before.outages, 7);
    let first = d.added_effects.first().expect("effects on the real drive");
    assert_eq!(first.name, "time_offset");
    // the prior residuals' minimum over a grid of --imu-time-offset: 0.095-0.141 s per minute
    // (0.12 s over the drive); measured +0.1023 +- 0.0005 s
    assert!(
        (0.08..0.15).contains(&first.estimate[0]),
        "{:?}",
        first.estimate
    );
    for e in &d.added_effects {
        assert!(e.estimate.iter().chain(&e.sigma).all(|v| v.is_finite()));
        assert!(nav_diagnose::validate::max_z(&e.estimate, &e.sigma) >= 2.0);
        // added: its held-out window errors significantly lower (paired signed-rank test)
        assert!(
            e.heldout.p_better < 0.05 && e.heldout.gain > 0.0,
            "{}: {}",
            e.name,
            e.heldout.describe()
        );
    }
    for s in &d.steps {
        let e = &s.errors;
        println!(
            "step {} kept {}: held-out outage {:?} m, GNSS prior residual {:.3} m, NIS {:.2} {}",
            s.label,
            s.accepted,
            e.heldout_outage_m,
            e.gnss_prior_horizontal_rms_m,
            e.nis_mean,
            s.reason.as_deref().unwrap_or("")
        );
    }
    if let Some(t) = &d.noise_tuning {
        println!(
            "noise: {} (NIS {:.1} -> {:.1}, adopted {}); with effects: {:?}",
            t.chosen.describe(),
            t.nis_before,
            t.nis_after,
            t.adopted,
            t.with_effects
                .as_ref()
                .map(|t2| (t2.chosen.describe(), t2.nis_after, t2.adopted))
        );
    }
    for u in &d.undetected {
        println!(
            "not added {}: bound {:.3e} [{}]: {}",
            u.name, u.min_bound, u.unit, u.reason
        );
    }
    for w in &d.warnings {
        println!("warning: {w}");
    }
    assert!(af.is_finite() && af < b, "before {b} after {af}");
    let (gb, ga) = (
        d.error_before.gnss_residual_horizontal_rms_m,
        d.error_after.gnss_residual_horizontal_rms_m,
    );
    let (ob, oa) = (
        d.error_before.output_vs_fixes_horizontal_rms_m,
        d.error_after.output_vs_fixes_horizontal_rms_m,
    );
    println!("with GNSS: prior residual horizontal RMS {gb:.3} -> {ga:.3} m; written solution vs RTK fixes {ob:.3} -> {oa:.3} m (after on the GNSS clock, shift {:+.4} s)", d.output_clock_shift_s);
    assert!(ga <= gb, "GNSS prior residual {gb} -> {ga}");
    // The written solution against the fixes the filter USED (on its clock, at the model's
    // antenna) is reported but is no test of a time offset: the base solution is compared at
    // the epoch its own update pulled it onto the fix, the after solution 0.10 s of
    // propagation later (measured 0.102 -> 0.128 m). The fair comparisons follow, with fixes
    // the filter did not use. Still, on the GNSS clock it must be closer than left on the
    // IMU clock.
    let la = d
        .added_effects
        .iter()
        .find(|e| e.name == "lever_arm")
        .map_or([0.0; 3], |e| [e.estimate[0], e.estimate[1], e.estimate[2]]);
    let arm: [f64; 3] = [0, 1, 2].map(|i| out.after.lever_arm_m[i] + la[i]);
    let imu_clock = nav_diagnose::validate::output_vs_fixes_horizontal_rms_m(
        &out.after_nav.load().unwrap(),
        0.0,
        arm,
        &p.case.gnss,
        &out.after.outages,
    );
    println!("written after solution on the IMU clock: {imu_clock:.3} m");
    assert!(oa < imu_clock, "GNSS clock {oa} vs IMU clock {imu_clock}");
    assert_eq!(d.output_clock_shift_s, -first.estimate[0]);

    // the augmented configuration alone: lever arm and time offset folded into [gnss], the
    // IMU effects in its `effects` key
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path(), &p, &out, Some(Path::new(config))).unwrap();
    let aug = nav_io::read_run_config(dir.path().join("augmented.toml"))
        .expect("augmented.toml is a valid run configuration");
    // the IMU moved onto the GNSS clock: imu.time_offset_s = configured - estimate
    assert!((aug.imu.time_offset_s + first.estimate[0]).abs() < 1e-12);
    assert_eq!(aug.gnss.time_offset_s, 0.0);
    let imu_effects: Vec<String> = d
        .added_effects
        .iter()
        .map(|e| e.name.clone())
        .filter(|n| n != "lever_arm" && n != "time_offset")
        .collect();
    assert_eq!(aug.effects, imu_effects);
    let mut a2 = RunSpec::new(dir.path().join("augmented.toml"));
    a2.periodic_outages = a.periodic_outages.clone();
    let p2 = a2.prepare().expect("the augmented configuration loads");
    assert_eq!(p2.opts.extra_blocks.len(), imu_effects.len());
    let (_, m2) = execute(&p2, &mut |_, _| {}).expect("and runs");
    let e2 = nav_diagnose::outage_error_m(&m2);
    println!("run with the augmented configuration: outage error {e2:.3} m");
    assert!(e2.is_finite() && e2 < b, "augmented {e2} vs before {b}");

    // with GNSS, against the RTK fixes, on the GNSS clock: the configuration (before) and the
    // augmented configuration (after), (1) without outages, the prior residuals of the fixes;
    // (2) every fourth fix withheld (absolute windows of 0.1 s around it, the same fixes for
    // both runs), the written solution at the withheld fixes
    let with_gnss = |config: &Path, thin: bool| {
        let mut p = RunSpec::new(config).prepare().expect("loads");
        if thin {
            p.opts.outages = p
                .case
                .gnss
                .iter()
                .enumerate()
                .filter(|(k, _)| k % 4 == 2)
                .map(|(_, f)| Outage {
                    start_s: f.t_s - 0.05,
                    duration_s: 0.1,
                })
                .collect();
        }
        let (o, m) = execute(&p, &mut |_, _| {}).expect("runs");
        if thin {
            assert!(m.outage_summary.count > 500, "{}", m.outage_summary.count);
            assert!(o.counters.gnss_accepted > 1500);
            m.outage_summary.end_horizontal_m.rms
        } else {
            m.gnss_residuals.horizontal_m.rms
        }
    };
    let aug_path = dir.path().join("augmented.toml");
    let (pr_b, pr_a) = (
        with_gnss(Path::new(config), false),
        with_gnss(&aug_path, false),
    );
    let (ho_b, ho_a) = (
        with_gnss(Path::new(config), true),
        with_gnss(&aug_path, true),
    );
    println!(
        "with GNSS (no outages): prior residual horizontal RMS {pr_b:.3} -> {pr_a:.3} m; \
         written solution at withheld fixes (1 in 4) {ho_b:.3} -> {ho_a:.3} m"
    );
    assert!(pr_a <= pr_b, "prior residuals {pr_b} -> {pr_a}");
    assert!(ho_a <= ho_b, "withheld fixes {ho_b} -> {ho_a}");
}

/// The default command (`host-sim diagnose --config configs/drive0708.toml`, no outage
/// imposed): the diagnosis withholds its own held-out windows and still names the time offset
/// first, with a significant held-out gain. (With 12 windows judged by their largest error the
/// time offset's gain was +11.8 % [-1.9, +27.1], p 0.117, and the lever arm was named first:
/// see `validate::TARGET_WINDOWS` and `validate::window_errors_m`.)
#[test]
fn real_drive_default_command_names_the_time_offset_first() {
    if test_support::real_data("real_drive_default_command").is_none() {
        return;
    }
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/drive0708.toml");
    let p = RunSpec::new(config).prepare().expect("loading the drive");
    assert!(p.opts.outages.is_empty());
    let out = diagnose(&p, &DiagnoseOptions::default()).expect("diagnose");
    let d = &out.diagnosis;
    println!("{}\n{}", d.verdict, d.heldout_windows.how);
    for r in &d.rounds {
        for c in &r.candidates {
            println!("  {} {:?}: {}", c.name, c.decision, c.reason);
        }
    }
    for s in &d.steps {
        println!(
            "step {} kept {}: held-out windows RMS {:?} m, {}",
            s.label,
            s.accepted,
            s.errors.heldout_windows_rms_m,
            s.heldout.map_or(String::new(), |h| h.describe())
        );
    }
    assert!(d.heldout_windows.windows.len() >= 10);
    let first = d.added_effects.first().expect("effects on the real drive");
    assert_eq!(first.name, "time_offset");
    // the estimate when it was added (the model of its round): the size the prior residuals
    // point to (0.095-0.141 s per minute, docs/diagnose.md); measured 0.11 s
    let added = d
        .rounds
        .iter()
        .flat_map(|r| &r.candidates)
        .find(|c| c.name == "time_offset" && c.decision == Decision::Added)
        .expect("time_offset added in a round");
    println!(
        "time_offset when added {:?} +- {:?} s; in the final model {:?} +- {:?} s",
        added.estimate, added.sigma, first.estimate, first.sigma
    );
    assert!(
        (0.08..0.15).contains(&added.estimate[0]),
        "{:?}",
        added.estimate
    );
    // the final model (with the re-tuned noise) keeps it positive and significant
    assert!(first.estimate[0] > 0.0 && first.estimate[0] > 2.0 * first.sigma[0]);
    assert!(
        first.heldout.p_better < 0.05,
        "{}",
        first.heldout.describe()
    );
    augmented_not_worse_on_the_reference_outage_plan(&p, &out, Path::new(config));
}

/// Its `augmented.toml` against the configuration on the reference outage plan (20 s outages
/// every 60 s) at six phases 10 s apart over the period, the reference's (116.645 s) first:
/// the per-outage maxima of the 3D error against the withheld RTK fixes, pooled over the 42
/// outages, RMS not higher. One phase alone is 7 outages and decided by one of them: at the
/// reference phase the configuration has its best figure of the twelve phases 5 s apart
/// (9.77 m, the others 12.6-35.5 m) and the augmented configuration (white noise x512) 11.83 m,
/// 19.6 m of it in the first outage; the augmented configuration is lower at the 11 other
/// phases (docs/diagnose.md, "The drive0708 clock").
fn augmented_not_worse_on_the_reference_outage_plan(
    p: &nav_engine::Prepared,
    out: &nav_diagnose::DiagnoseOutput,
    config: &Path,
) {
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path(), p, out, Some(config)).unwrap();
    let aug = dir.path().join("augmented.toml");
    let maxima = |c: &Path, phase: f64| -> Vec<f64> {
        let mut a = RunSpec::new(c);
        a.periodic_outages = vec![parse_periodic(&format!("{phase}:20:60")).unwrap()];
        let (_, m) = execute(&a.prepare().expect("loads"), &mut |_, _| {}).expect("runs");
        assert_eq!(m.reference, "withheld_gnss");
        m.per_outage.iter().map(|o| o.max.d3_m).collect()
    };
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let (mut all_c, mut all_a) = (Vec::new(), Vec::new());
    for k in 0..6 {
        let phase = 116.645 + 10.0 * f64::from(k);
        let (c, a) = (maxima(config, phase), maxima(&aug, phase));
        assert_eq!(c.len(), 7);
        assert_eq!(a.len(), 7);
        println!(
            "outages {phase:.3}:20:60: configuration {:.2} m, augmented {:.2} m (RMS of the maxima)",
            rms(&c),
            rms(&a)
        );
        all_c.extend(c);
        all_a.extend(a);
    }
    let (c, a) = (rms(&all_c), rms(&all_a));
    println!("pooled over the six phases: configuration {c:.2} m, augmented {a:.2} m");
    assert!(
        a.is_finite() && a <= c,
        "augmented {a} vs configuration {c}"
    );
}

/// The nested clock models: a drift (offset + rate) is named beside a constant offset only
/// when its rate is 2 sigma from zero, its extra likelihood pays the rate's BIC penalty and its
/// held-out errors are significantly lower than the offset's (no data needed).
#[test]
fn a_clock_drift_is_named_only_when_its_rate_beats_the_constant_offset() {
    use nav_diagnose::drift_beside_offset;
    use nav_diagnose::validate::compare_windows;
    let offset: Vec<f64> = (1..=20).map(|i| 1.0 + 0.1 * f64::from(i)).collect();
    let better = compare_windows(&offset, &offset.iter().map(|e| e * 0.8).collect::<Vec<_>>());
    // not significant either way: 10 windows lower, 10 higher
    let mixed: Vec<f64> = offset
        .iter()
        .enumerate()
        .map(|(i, e)| if i % 2 == 0 { e * 0.9 } else { e / 0.9 })
        .collect();
    let mixed = compare_windows(&offset, &mixed);
    // a rate within 2 sigma: a constant offset
    let why = drift_beside_offset(1.5, Some(&(400.0, better)), 5.0).expect("refused");
    assert!(why.contains("not significant"), "{why}");
    // the rate's extra gain below its BIC penalty
    let why = drift_beside_offset(10.0, Some(&(3.0, better)), 5.0).expect("refused");
    assert!(why.contains("does not pay"), "{why}");
    // pays but predicts the withheld fixes no better than the offset
    let why = drift_beside_offset(10.0, Some(&(400.0, mixed)), 5.0).expect("refused");
    assert!(why.contains("withheld"), "{why}");
    assert_eq!(mixed.verdict, nav_diagnose::HeldoutVerdict::NotSignificant);
    // significant on every count: a drift
    assert_eq!(drift_beside_offset(10.0, Some(&(400.0, better)), 5.0), None);
    // no offset in the round (already in the model): the rate's significance decides
    assert_eq!(drift_beside_offset(10.0, None, 5.0), None);
    assert!(drift_beside_offset(f64::NAN, None, 5.0).is_some());
}
