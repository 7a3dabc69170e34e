//! The truth streamed by `host-sim run` (read as the solution advances, never loaded) gives
//! the outputs of the in-memory engine, which loads it whole (`prepare` + `execute`, metrics
//! and coasting computed after the run over the whole truth, files written by
//! `output::write_all`): all five files byte-identical, on a simulated case with outages
//! (the case directory's truth at the IMU rate, a run configuration with a static alignment:
//! two coasting baselines), with a truth at another rate and phase (`--truth`: every third
//! record, 2.1 ms late, so every comparison interpolates), with the run configuration's own
//! `[truth]` (no case directory), and with the initialisation from the truth (its first
//! record read by a short read of its own, the IMU from memory). A truth file that turns bad
//! part-way (read only as the run gets there, or after its end) still stops the run with the
//! file and line named, and no output under a final name.

use nav_core::filter::InitialUncertainty;
use nav_engine::run::execute::{execute_streaming, metrics_json};
use nav_engine::run::output;
use nav_engine::run::truth::TruthFile;
use nav_engine::run::{InitSpec, Outage};
use nav_engine::RunSpec;
use nav_engine::{execute, Prepared};
use std::path::{Path, PathBuf};
use std::process::Command;
use test_support::cli::{run, run_ok, Bin};
use test_support::scenario::four_minute_drive;

fn host_sim() -> Command {
    Bin::new(env!("CARGO_BIN_EXE_host-sim")).command()
}

/// A run configuration for the simulated case (tactical-grade noise, static alignment);
/// `truth`: its `[truth]` line, paths relative to the configuration's folder.
fn config(imu: &str, gnss: &str, truth: Option<&str>) -> String {
    let mut s = format!(
        r#"name = "truthstream"
description = "simulated case, truth streamed"

[imu]
path = "{imu}"
format = "text"

[gnss]
path = "{gnss}"
format = "text"
lever_arm_m = [0.0, 0.0, 0.0]

[init]
pos_std_m = [0.5, 0.5, 1.0]
vel_std_mps = [0.05, 0.05, 0.05]
att_std_deg = [1.0, 1.0, 5.0]

[init.align]
static_s = 20.0

[noise]
model = "nbk"

[noise.accel]
n_ug_per_sqrt_hz = 50.0
k_ug_per_sqrt_hz = 5.0
bias_init_sigma = 0.01

[noise.gyro]
n_deg_per_s_per_sqrt_hz = 0.003
k_deg_per_s_per_sqrt_hz = 3.0e-5
bias_init_deg_per_s = 0.01
"#
    );
    if let Some(t) = truth {
        s.push_str(&format!(
            "\n[truth]\npath = \"{t}\"\nformat = \"nav_text\"\n"
        ));
    }
    s
}

/// The in-memory engine's five files for `p` in `out`.
fn in_memory(p: &Prepared, out: &Path) {
    assert!(
        p.case.truth.is_some(),
        "the in-memory engine loads the truth"
    );
    let (run, m) = execute(p, &mut |_, _| {}).unwrap();
    std::fs::create_dir_all(out).unwrap();
    let json = metrics_json(&m, &run, None).unwrap();
    output::write_all(out, &run, &run.nav, p.week, &json, true).unwrap();
}

/// `host-sim run` (streaming) with `args` and `--out out`.
fn streamed(args: &[&str], out: &Path) {
    let mut c = host_sim();
    c.arg("run").args(args).arg("--out").arg(out).arg("--quiet");
    run_ok(&mut c);
}

fn same_files(a: &Path, b: &Path, what: &str) -> serde_json::Value {
    for f in output::OUTPUT_NAMES {
        let x = std::fs::read(a.join(f)).unwrap();
        let y = std::fs::read(b.join(f)).unwrap();
        assert!(x.len() > 100, "{what}: {f}: {} bytes", x.len());
        assert!(x == y, "{what}: {f} differs");
    }
    serde_json::from_str(&std::fs::read_to_string(a.join("metrics.json")).unwrap()).unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_streamed_truth_gives_the_in_memory_engines_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = d.join("scenario.toml");
    std::fs::write(&sc, four_minute_drive("truthstream-test").build()).unwrap();
    let case = d.join("case");
    run_ok(host_sim().args([
        "simulate",
        "--scenario",
        s(&sc),
        "--errors",
        "tactical",
        "--seed",
        "3",
        "--outage",
        "70:20",
        "--outage",
        "150:30",
        "--out",
        s(&case),
    ]));
    let truth_nav = case.join("truth.nav");
    let truth_lines = std::fs::read_to_string(&truth_nav).unwrap();
    let n_truth = truth_lines.lines().count();
    let cfg = d.join("run.toml");
    std::fs::write(&cfg, config("case/imu.txt", "case/gnss.txt", None)).unwrap();

    // 1. the case directory's truth (at the IMU rate) and its two outages
    let mut args = RunSpec::new(&cfg);
    args.case = Some(case.clone());
    let (a, b) = (d.join("case-stream"), d.join("case-memory"));
    streamed(&["--config", s(&cfg), "--case", s(&case)], &a);
    in_memory(&args.prepare().unwrap(), &b);
    let m = same_files(&a, &b, "case truth");
    assert_eq!(m["reference"], "truth");
    // every truth epoch compared (the solution starts after the static alignment)
    let n = m["overall"]["pos_3d_m"]["n"].as_u64().unwrap() as usize;
    assert!(n > n_truth * 8 / 10 && n <= n_truth, "{n} of {n_truth}");
    assert_eq!(m["per_outage"].as_array().unwrap().len(), 2);
    let coast = m["coasting"].as_array().unwrap();
    assert_eq!(coast.len(), 2, "raw and static-gyro-bias coasting");
    for c in coast {
        assert_eq!(c["outages"].as_array().unwrap().len(), 2);
        for o in c["outages"].as_array().unwrap() {
            assert!(o["stats"]["pos_3d_m"]["n"].as_u64().unwrap() > 1000);
        }
    }

    // 2. a truth at another rate and phase: every third record, 2.1 ms late (interpolated)
    let shifted = d.join("truth-shifted.nav");
    let text: String = truth_lines
        .lines()
        .step_by(3)
        .map(|l| {
            let mut f: Vec<String> = l.split_whitespace().map(str::to_string).collect();
            let t: f64 = f[1].parse().unwrap();
            f[1] = format!("{:.4}", t + 0.0021);
            f.join(" ") + "\n"
        })
        .collect();
    std::fs::write(&shifted, text).unwrap();
    let mut args2 = args.clone();
    args2.truth = Some(shifted.clone());
    let (a, b) = (d.join("shift-stream"), d.join("shift-memory"));
    streamed(
        &[
            "--config",
            s(&cfg),
            "--case",
            s(&case),
            "--truth",
            s(&shifted),
        ],
        &a,
    );
    in_memory(&args2.prepare().unwrap(), &b);
    let m2 = same_files(&a, &b, "truth at a third of the rate, 2.1 ms late");
    let n2 = m2["overall"]["pos_3d_m"]["n"].as_u64().unwrap() as usize;
    assert!(n2 > n / 4 && n2 < n / 2, "{n2} interpolated comparisons");
    assert_eq!(m2["coasting"][0]["outages"].as_array().unwrap().len(), 2);

    // 3. the run configuration's own [truth], no case directory (outages from the command
    // line)
    let cfg3 = d.join("run-truth.toml");
    std::fs::write(
        &cfg3,
        config("case/imu.txt", "case/gnss.txt", Some("case/truth.nav")),
    )
    .unwrap();
    let mut args3 = RunSpec::new(&cfg3);
    args3.outages = vec![Outage {
        start_s: 100.0,
        duration_s: 15.0,
    }];
    let (a, b) = (d.join("cfg-stream"), d.join("cfg-memory"));
    streamed(&["--config", s(&cfg3), "--outage", "100:15"], &a);
    in_memory(&args3.prepare().unwrap(), &b);
    let m3 = same_files(&a, &b, "[truth] of the configuration");
    assert_eq!(m3["reference"], "truth");
    assert_eq!(m3["coasting"][0]["outages"].as_array().unwrap().len(), 1);

    // 4. the initialisation from the truth, the IMU from memory (streaming engine, in
    // process): the first truth record at or after the start from a short read
    let mut p = args.prepare().unwrap();
    p.opts.init = InitSpec::FromTruth {
        pos_err_m: [0.3, -0.2, 0.5],
        vel_err_mps: [0.02, 0.0, -0.01],
        att_err_rad: [1e-3, -1e-3, 5e-3],
        unc: InitialUncertainty {
            att_sigma_rad: [2e-3, 2e-3, 1e-2],
            vel_sigma_mps: [0.05; 3],
            pos_sigma_m: [0.5; 3],
        },
    };
    p.opts.start_s = Some(200_040.0);
    let (a, b) = (d.join("init-stream"), d.join("init-memory"));
    in_memory(&p, &b);
    let mut q = p.clone();
    q.case.truth = None;
    let tf = TruthFile::nav_text(PathBuf::from(&truth_nav));
    let (r4, _) = execute_streaming(&q, None, Some(&tf), &a, &[], None, &mut |_, _| {}).unwrap();
    assert_eq!(r4.init.method, "truth");
    assert!((r4.init.t_s - 200_040.0).abs() < 0.011, "{}", r4.init.t_s);
    let m4 = same_files(&a, &b, "initialisation from the truth");
    assert_eq!(m4["reference"], "truth");

    // 5. a bad line in the truth file, in the middle of the run and after its end (the rest
    // of the file is checked when the run is complete): the run fails naming file and line,
    // and leaves no output under a final name
    for (what, k) in [("mid-run", n_truth / 2), ("after the run", n_truth - 1)] {
        let bad = d.join("truth-bad.nav");
        let text: String = truth_lines
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i == k {
                    "2300 x\n".to_string()
                } else {
                    format!("{l}\n")
                }
            })
            .collect();
        std::fs::write(&bad, text).unwrap();
        let out = d.join("bad-out");
        let mut c = host_sim();
        c.args([
            "run",
            "--config",
            s(&cfg),
            "--case",
            s(&case),
            "--truth",
            s(&bad),
        ])
        .arg("--out")
        .arg(&out)
        .arg("--quiet");
        let r = run(&mut c);
        // a bad truth line skips that epoch with a warning naming file and line; the run
        // completes
        assert!(
            r.ok,
            "{what}: a bad truth line must not stop the run: {}",
            r.stderr
        );
        let line = format!("line {}", k + 1);
        assert!(
            r.stderr.contains("truth-bad.nav") && r.stderr.contains(&line),
            "{what}: {}",
            r.stderr
        );
        for f in output::OUTPUT_NAMES {
            assert!(out.join(f).exists(), "{what}: {f} not written");
        }
    }
}
