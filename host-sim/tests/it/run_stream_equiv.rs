//! The streaming `host-sim run` (IMU read while the filter runs, outputs written as they are
//! made, metrics and coasting online) against the in-memory engine (`prepare` + `execute`:
//! every record kept, metrics and coasting computed after the run, files written by
//! `output::write_all`) on a generated case with imposed outages: all five output files must
//! be byte-identical, at the IMU rate and decimated.
use nav_engine::execute;
use nav_engine::run::execute::{decimate, metrics_json};
use nav_engine::run::output;
use nav_engine::run::Outage;
use nav_engine::run::PeriodicOutages;
use nav_engine::RunSpec;
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

fn in_memory(yaml: &Path, out: &Path, nav_rate: Option<f64>) {
    let mut args = RunSpec::new(yaml);
    args.outages = vec![Outage {
        start_s: 60.0,
        duration_s: 20.0,
    }];
    args.periodic_outages = vec![PeriodicOutages {
        first_start_s: 100.0,
        duration_s: 10.0,
        period_s: 40.0,
    }];
    let p = args.prepare().unwrap();
    let (run, m) = execute(&p, &mut |_, _| {}).unwrap();
    let nav = match nav_rate {
        Some(r) => decimate(&run.nav, r),
        None => run.nav.clone(),
    };
    std::fs::create_dir_all(out).unwrap();
    let json = metrics_json(&m, &run, None).unwrap();
    output::write_all(out, &run, &nav, p.week, &json, true).unwrap();
}

#[test]
fn streaming_run_writes_the_in_memory_engines_files() {
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
        "7",
        "--kf-gins",
        "--out",
        case.to_str().unwrap(),
    ]));
    let yaml = case.join("kf-gins.yaml");
    for rate in [None, Some(1.0)] {
        let a = dir.path().join(format!("stream-{rate:?}"));
        let b = dir.path().join(format!("memory-{rate:?}"));
        let mut cmd = host_sim();
        cmd.args([
            "run",
            "--config",
            yaml.to_str().unwrap(),
            "--outage",
            "60:20",
            "--periodic-outage",
            "100:10:40",
            "--out",
            a.to_str().unwrap(),
            "--quiet",
        ]);
        if let Some(r) = rate {
            cmd.args(["--nav-rate", &r.to_string()]);
        }
        run_ok(&mut cmd);
        in_memory(&yaml, &b, rate);
        for f in output::OUTPUT_NAMES {
            let x = std::fs::read(a.join(f)).unwrap();
            let y = std::fs::read(b.join(f)).unwrap();
            assert!(x.len() > 100, "{f}: {} bytes", x.len());
            assert!(x == y, "{f} differs (nav rate {rate:?})");
        }
        // the case carries its truth and the outages withheld fixes: metrics against the
        // truth, with a coasting baseline over every outage
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(a.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["reference"], "truth");
        assert_eq!(m["per_outage"].as_array().unwrap().len(), 5);
        assert_eq!(m["coasting"][0]["outages"].as_array().unwrap().len(), 5);
    }
}
