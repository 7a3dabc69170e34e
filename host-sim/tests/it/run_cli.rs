//! `host-sim run` end to end through the binary: a case written by `host-sim simulate
//! --kf-gins` runs from its `kf-gins.yaml` alone, and the outputs are complete and right.
use nav_engine::metrics::errors_vs_truth;
use nav_io::read_nav_text;
use std::path::Path;
use std::process::Command;
use test_support::cli::{run_ok, Bin};
use test_support::scenario::four_minute_drive;

fn scenario_toml() -> String {
    four_minute_drive("run-cli-test").build()
}

fn host_sim() -> Command {
    Bin::new(env!("CARGO_BIN_EXE_host-sim")).command()
}

fn count_data_lines(p: &Path) -> usize {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .count()
}

#[test]
fn simulated_kf_gins_case_runs_from_its_yaml_alone() {
    let dir = tempfile::tempdir().unwrap();
    let sc = dir.path().join("scenario.toml");
    std::fs::write(&sc, scenario_toml()).unwrap();
    let case = dir.path().join("case");
    run_ok(host_sim().args([
        "simulate",
        "--scenario",
        sc.to_str().unwrap(),
        "--errors",
        "tactical",
        "--seed",
        "4",
        "--kf-gins",
        "--outage",
        "120:30",
        "--out",
        case.to_str().unwrap(),
    ]));
    let yaml = case.join("kf-gins.yaml");
    assert!(yaml.exists());
    let out = dir.path().join("out");
    let so = run_ok(host_sim().args([
        "run",
        "--config",
        yaml.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]));
    println!("{so}");
    assert!(so.contains("model kf-gins-feedback (21 states)"), "{so}");
    for f in [
        "nav.txt",
        "std.txt",
        "bias.txt",
        "innovations.txt",
        "metrics.json",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    // nav.txt at the IMU rate: one record per IMU sample plus the initial epoch
    let imu_n = count_data_lines(&case.join("imu.txt"));
    let nav = read_nav_text(out.join("nav.txt")).unwrap();
    assert_eq!(nav.len(), imu_n + 1);
    assert_eq!(nav[0].week, 2300);
    // std.txt header names the 21 states
    let std_txt = std::fs::read_to_string(out.join("std.txt")).unwrap();
    let head = std_txt.lines().nth(1).unwrap();
    assert_eq!(head.split_whitespace().count(), 2 + 21, "{head}");
    assert!(head.contains("gyro_scale_factor_x") && head.contains("accel_bias_z_mps2"));
    // metrics against the case's truth, the case's outage covered, numbers consistent with
    // an independent comparison of nav.txt with truth.nav
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["reference"], "truth");
    assert_eq!(m["per_outage"].as_array().unwrap().len(), 1);
    let truth = read_nav_text(case.join("truth.nav")).unwrap();
    let e = errors_vs_truth(&nav, &truth);
    let t_out = (200_120.0, 200_150.0);
    let outside: Vec<_> = e
        .iter()
        .filter(|x| x.t_s < t_out.0 || x.t_s >= t_out.1)
        .collect();
    let rms_h = (outside
        .iter()
        .map(|x| x.horizontal_m().powi(2))
        .sum::<f64>()
        / outside.len() as f64)
        .sqrt();
    let json_h = m["outside_outages"]["pos_horizontal_m"]["rms"]
        .as_f64()
        .unwrap();
    // nav.txt is written with shortest round-trip degrees: identical statistics
    assert!((rms_h - json_h).abs() < 1e-6, "{rms_h} vs {json_h}");
    assert!(rms_h < 0.05, "horizontal RMS outside the outage {rms_h}");
    let end_h = m["per_outage"][0]["end"]["horizontal_m"].as_f64().unwrap();
    assert!(end_h.is_finite() && end_h < 20.0, "{end_h}");
    // innovations: one line per fix, none withheld (the simulator removed the outage's
    // fixes), all used
    let gnss_n = count_data_lines(&case.join("gnss.txt"));
    let inn = std::fs::read_to_string(out.join("innovations.txt")).unwrap();
    let lines: Vec<&str> = inn.lines().filter(|l| !l.starts_with('#')).collect();
    assert!(lines.len() <= gnss_n && lines.len() + 2 >= gnss_n);
    assert!(lines
        .iter()
        .all(|l| l.split_whitespace().nth(1) == Some("accepted")));
}

#[test]
fn run_imposes_outages_and_decimates_nav() {
    let dir = tempfile::tempdir().unwrap();
    let sc = dir.path().join("scenario.toml");
    std::fs::write(&sc, scenario_toml()).unwrap();
    let case = dir.path().join("case");
    run_ok(host_sim().args([
        "simulate",
        "--scenario",
        sc.to_str().unwrap(),
        "--errors",
        "tactical",
        "--kf-gins",
        "--out",
        case.to_str().unwrap(),
    ]));
    let out = dir.path().join("out");
    run_ok(host_sim().args([
        "run",
        "--config",
        case.join("kf-gins.yaml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--outage",
        "60:20",
        "--periodic-outage",
        "100:10:40",
        "--nav-rate",
        "1",
        "--quiet",
    ]));
    let nav = read_nav_text(out.join("nav.txt")).unwrap();
    // 1 Hz from the initial epoch over a ~250 s case
    for w in nav.windows(2) {
        assert!(
            (w[1].t_s - w[0].t_s - 1.0).abs() < 1e-6,
            "{} {}",
            w[0].t_s,
            w[1].t_s
        );
    }
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    // outage times count from the first IMU epoch (`--outage` help): the first increment
    // ends at 200000.01 s
    let t0 = nav_io::read_imu_text(case.join("imu.txt")).unwrap().samples[0].t_s;
    assert!((t0 - 200_000.01).abs() < 1e-6, "{t0}");
    let starts: Vec<f64> = m["outages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["start_s"].as_f64().unwrap() - t0)
        .collect();
    // 60 s, then 100, 140, 180, 220 s (each ends before the data end)
    assert_eq!(starts.len(), 5, "{starts:?}");
    for (a, b) in starts.iter().zip([60.0, 100.0, 140.0, 180.0, 220.0]) {
        assert!((a - b).abs() < 1e-6, "{starts:?}");
    }
    let inn = std::fs::read_to_string(out.join("innovations.txt")).unwrap();
    let withheld = inn
        .lines()
        .filter(|l| l.split_whitespace().nth(1) == Some("withheld"))
        .count();
    assert_eq!(withheld, 20 + 4 * 10);
    // coasting baselines are in the metrics
    assert_eq!(m["coasting"].as_array().unwrap().len(), 1);
}

/// The command line's options are parsed and typed by clap: a wrong effect name, gate or
/// velocity gate fails at argument parsing (exit 1, an input error like any other: 2 means
/// "not a navigation solution"; the valid names listed), before any file is read (the
/// configuration named does not exist).
#[test]
fn wrong_option_values_fail_at_argument_parsing_before_any_file_is_read() {
    let missing = "no-such-folder/run.toml";
    for (args, want) in [
        (
            ["--effects", "time_offset,lever_arms"],
            "`lever_arms` is not an effect name; the effects are accel_scale_factor",
        ),
        (["--effects", "lever_arms"], "did you mean `lever_arm`?"),
        (["--gate", "0.5"], "expected robust, off, 0.95"),
        (["--velocity-gate", "soft"], "expected joint, robust, hard"),
    ] {
        let out = host_sim()
            .args(["run", "--config", missing])
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(
            err.contains(&format!("for '{} <", args[0])),
            "names the option: {err}"
        );
        assert!(!err.contains("no-such-folder"), "nothing read: {err}");
    }
}

/// A misspelt key in a run configuration: exit 1, the file, line and column, the valid keys
/// and the nearest one, each said once (the parser's message is not repeated after the hint),
/// and nothing written.
#[test]
fn a_misspelt_configuration_key_is_named_once_with_the_nearest_key() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("typo.toml");
    std::fs::write(
        &cfg,
        "# written by hand\nname = \"typo\"\n[imu]\npath = \"imu.txt\"\nformat = \"text\"\n\
         [gnss]\npath = \"gnss.txt\"\nformat = \"text\"\nmaxq = 1  # RTK fixed only\n\
         [noise]\nmodel = \"nbk\"\n",
    )
    .unwrap();
    let out_dir = tmp.path().join("out");
    let out = host_sim()
        .args(["run", "--config", cfg.to_str().unwrap(), "--out"])
        .arg(&out_dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("typo.toml"), "names the file: {err}");
    assert!(
        err.contains("line 9, column 1"),
        "names line and column: {err}"
    );
    assert!(err.contains("did you mean `max_q`?"), "{err}");
    assert_eq!(
        err.matches("unknown field `maxq`").count(),
        1,
        "said once: {err}"
    );
    assert_eq!(
        err.matches("TOML parse error").count(),
        1,
        "said once: {err}"
    );
    assert!(!out_dir.exists(), "nothing written");
}

/// `RunArgs::to_spec`: each command-line option lands in its typed `RunSpec` field.
#[test]
fn run_arguments_become_the_typed_run_spec() {
    use clap::Parser;
    use host_sim::run::cli::RunArgs;
    use nav_core::config::{GateProbability, Gating, VelocityGating};
    use nav_engine::run::prepare::{FilterOverrides, ImuChecksOverrides, Overrides};
    use nav_engine::run::{Effect, Model, Precision, RecordOptions};
    let a = RunArgs::try_parse_from([
        "run",
        "--config",
        "c.toml",
        "--effects",
        "time_offset, lever_arm",
        "--effects",
        "imu_clock_drift",
        "--gate",
        "0.99",
        "--velocity-gate",
        "hard",
        "--model",
        "nbk",
        "--std-rate",
        "5",
        "--nav-rate",
        "20",
        "--smooth",
        "--imu-time-offset",
        "-0.125",
        "--f32",
        "--noise-scale",
        "2.5",
        "--gnss-velocity",
        "false",
        "--imu-class",
        "tactical",
        "--imu-max-rate-dps",
        "400",
        "--imu-max-accel-g",
        "8",
        "--imu-max-gap",
        "0.5",
        "--imu-gaps",
        "span",
        "--imu-strict",
        "--no-imu-limits",
    ])
    .unwrap();
    let s = a.to_spec();
    assert_eq!(s.config, Path::new("c.toml"));
    assert_eq!(
        s.set.effects,
        [Effect::TimeOffset, Effect::LeverArm, Effect::ImuClockDrift]
    );
    let max_rej = Gating::default().max_consecutive_rejections;
    assert_eq!(
        s.set.filter,
        FilterOverrides {
            gating: Some(Gating::with_probability(GateProbability::P99, max_rej)),
            velocity_gating: Some(Some(VelocityGating::hard(GateProbability::P9999))),
            use_gnss_velocity: Some(false),
            white_noise_scale: Some(2.5),
        }
    );
    assert_eq!(s.set.model, Some(Model::Nbk));
    assert_eq!(s.set.precision, Some(Precision::F32));
    assert_eq!(
        s.record,
        RecordOptions {
            nav_rate_hz: Some(20.0),
            epoch_rate_hz: Some(5.0)
        }
    );
    assert_eq!(s.imu_time_offset_s, Some(-0.125));
    assert!(s.set.smoother_history);
    assert_eq!(
        s.set.imu_checks,
        ImuChecksOverrides {
            table: nav_io::ImuChecksConfig {
                class: Some(nav_io::ImuClassName::Tactical),
                max_rate_deg_s: Some(400.0),
                max_accel_g: Some(8.0),
                max_gap_s: Some(0.5),
                stop_on_implausible: true,
            },
            no_limits: true,
            increments: Some(nav_core::imu_guard::GapIncrements::Span),
        }
    );
    // the defaults are the engine's
    let d = RunArgs::try_parse_from(["run", "--config", "c.toml", "--velocity-gate", "joint"])
        .unwrap()
        .to_spec();
    let e = nav_engine::RunSpec::new("c.toml");
    assert_eq!(d.set.filter.velocity_gating, Some(None));
    assert_eq!(d.record, e.record);
    assert_eq!(
        Overrides {
            filter: FilterOverrides {
                velocity_gating: None,
                ..d.set.filter
            },
            ..d.set
        },
        e.set
    );
}

/// The exit codes under `--help`; `--help` and `--version` exit 0, a usage error 1 (an
/// unknown option, a missing value, no command).
#[test]
fn exit_codes_are_listed_under_help_and_a_usage_error_exits_1() {
    let help = host_sim().arg("--help").output().unwrap();
    let text = String::from_utf8_lossy(&help.stdout);
    assert_eq!(help.status.code(), Some(0), "{text}");
    for want in [
        "Exit status:",
        "  1 ",
        "  2 ",
        "not a navigation solution",
        "130/143",
    ] {
        assert!(text.contains(want), "no {want:?} in {text}");
    }
    assert_eq!(
        host_sim().arg("--version").output().unwrap().status.code(),
        Some(0)
    );
    for args in [
        &["run", "--no-such-option"][..],
        &["run", "--config"],
        &[],
        &["run", "--config", "x.toml", "--nav-rate", "fast"],
    ] {
        let out = host_sim().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("error:") && err.contains("--help"),
            "{args:?}: {err}"
        );
    }
}
