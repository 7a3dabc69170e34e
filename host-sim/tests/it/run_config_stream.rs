//! A run configuration's own IMU and GNSS files streamed by `host-sim run` (`nav_engine::load`
//! with streaming, `execute_streaming`) against the same configuration loaded (`load` without
//! streaming, the case in memory, the same writer):
//! - the real drive (`configs/drive0708.toml`, `drive0708_aided.toml`: an IMU CSV with a tick
//!   clock and a tag file, an RTKLIB `.pos`; skipped visibly without `../shared` unless
//!   CI=true): all five outputs byte-identical, with and without periodic outages, and the
//!   mounting check's warnings the same (none with the drive's mounting; with the roll
//!   flipped the same two warnings, the drive being shorter than the streamed check's
//!   prefix);
//! - a generated CSV + `.pos` case longer than the prefix with an upside-down mounting: the
//!   same warning, from the prefix, and the same again from the check made on the run's own
//!   reading (`load_checking_in_run`: after the run, the outputs unchanged);
//! - a generated CSV + `.pos` case with an IMU gap and periodic outages: outputs
//!   byte-identical, the gap in the run's IMU report;
//! - a simulated case directory and its KF-GINS file (IMU text streamed): the mounting
//!   check's warnings the same streamed and loaded, with the IMU upside down and without, and
//!   made on the run's own reading;
//! - a CSV row that does not parse in the middle of the streamed file: the error names the
//!   file and line, and the outputs up to it are kept as `*.partial`.

use nav_engine::run::output::{partial_path, OUTPUT_NAMES};
use nav_engine::run::streams::MOUNTING_PREFIX_S;
use nav_engine::{
    execute_streaming, load, load_checking_in_run, Loaded, Metrics, RunOutput, RunSpec,
};
use std::path::{Path, PathBuf};
use test_support::csvcase::{write_csv_pos_case, T0_S};

/// The real drive's folder, or None after the SKIPPED line (a failure under CI=true).
fn shared(test: &str) -> Option<PathBuf> {
    test_support::real_data_in(test, "rtklibexplorer-drive0708")
}

fn config(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../configs")
        .join(name)
}

/// Loads `spec` streamed or not and runs it into `out`.
fn run(spec: &RunSpec, stream: bool, out: &Path) -> Loaded {
    let l = load(spec, stream).unwrap();
    assert_eq!(l.imu_stream.is_some(), stream);
    assert_eq!(l.prepared.case.imu.is_empty(), stream);
    assert_eq!(l.prepared.case.gnss.is_empty(), stream);
    execute(&l, out).unwrap();
    l
}

/// Runs what `l` loaded into `out` (`nav.txt` at every IMU epoch), as `host-sim run` does.
fn execute(l: &Loaded, out: &Path) -> anyhow::Result<(RunOutput, Metrics)> {
    execute_streaming(
        &l.prepared,
        l.imu_stream.as_ref(),
        l.truth_stream.as_ref(),
        out,
        &l.inputs,
        None,
        &mut |_, _| {},
    )
}

/// Loads `spec` with the mounting check made on the run's own reading
/// (`load_checking_in_run`) and runs it into `out`: the warnings before the run, the
/// check's after it, and whether the run succeeded.
fn run_checking_in_run(spec: &RunSpec, out: &Path) -> (Vec<String>, Vec<String>, bool) {
    let l = load_checking_in_run(spec).unwrap();
    let ok = execute(&l, out).is_ok();
    (l.warnings.clone(), l.mounting_warnings(ok), ok)
}

fn assert_same_outputs(a: &Path, b: &Path) {
    for n in OUTPUT_NAMES {
        let (x, y) = (
            std::fs::read(a.join(n)).unwrap(),
            std::fs::read(b.join(n)).unwrap(),
        );
        assert!(x.len() > 100, "{n}: {} bytes", x.len());
        assert!(
            x == y,
            "{n} differs between the loaded and the streamed run"
        );
    }
}

#[test]
fn the_real_drive_streamed_writes_the_loaded_runs_files() {
    if shared("the_real_drive_streamed_writes_the_loaded_runs_files").is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut specs = Vec::new();
    for name in ["drive0708.toml", "drive0708_aided.toml"] {
        specs.push((name, RunSpec::new(config(name))));
    }
    // periodic outages: the last IMU time read by a pass of its own, coasting over the stream
    let mut with_outages = RunSpec::new(config("drive0708.toml"));
    with_outages.periodic_outages = vec![nav_engine::run::PeriodicOutages {
        first_start_s: 116.645,
        duration_s: 20.0,
        period_s: 60.0,
    }];
    specs.push(("drive0708.toml + periodic outages", with_outages));
    for (k, (name, spec)) in specs.iter().enumerate() {
        let (a, b) = (
            dir.path().join(format!("{k}-loaded")),
            dir.path().join(format!("{k}-streamed")),
        );
        let t = std::time::Instant::now();
        let loaded = run(spec, false, &a);
        let t_loaded = t.elapsed().as_secs_f64();
        let t = std::time::Instant::now();
        let streamed = run(spec, true, &b);
        let t_streamed = t.elapsed().as_secs_f64();
        println!("{name}: loaded {t_loaded:.2} s, streamed {t_streamed:.2} s");
        assert_same_outputs(&a, &b);
        assert_eq!(loaded.prepared.week, streamed.prepared.week);
        assert!(streamed.prepared.week > 2000);
        assert_eq!(loaded.prepared.opts.outages, streamed.prepared.opts.outages);
        // the drive's mounting agrees with the data: no warning either way
        assert_eq!(loaded.warnings, streamed.warnings);
        assert!(streamed.warnings.is_empty(), "{:?}", streamed.warnings);
        let st = streamed.imu_stream.as_ref().unwrap();
        assert!(st.file.increments_span_gaps());
        assert!(st.file.path().ends_with("imu_1934.csv"));
        let g = st.gnss.as_ref().unwrap();
        assert_eq!(
            g.summary.dropped_by_quality, 8,
            "8 float epochs dropped (max_q = 1)"
        );
        assert_eq!(g.fixes, 2189);
        if k == 2 {
            assert!(streamed.prepared.opts.outages.len() >= 7);
        }
    }
}

#[test]
fn the_real_drive_against_an_rtklib_pos_truth_streamed_writes_the_loaded_runs_files() {
    // `[truth] format = "rtklib_pos"` (all qualities, positions and velocities, no attitude):
    // loaded whole by `load(.., false)`, read line by line (nav_io::PosReader) by the
    // streamed run; with periodic outages so that the coasting tracks are scored too
    let Some(data) =
        shared("the_real_drive_against_an_rtklib_pos_truth_streamed_writes_the_loaded_runs_files")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let data = data.canonicalize().unwrap();
    let mut text = std::fs::read_to_string(config("drive0708.toml"))
        .unwrap()
        .replace(
            "../../shared/data/rtklibexplorer-drive0708",
            data.to_str().unwrap(),
        );
    text.push_str(&format!(
        "\n[truth]\npath = \"{}\"\nformat = \"rtklib_pos\"\n",
        data.join("gnss_1934_sf.pos").display()
    ));
    // `[truth]` must be a top-level table: appended after every other table it is one
    let p = dir.path().join("with_truth.toml");
    std::fs::write(&p, text).unwrap();
    let mut spec = RunSpec::new(&p);
    spec.periodic_outages = vec![nav_engine::run::PeriodicOutages {
        first_start_s: 116.645,
        duration_s: 20.0,
        period_s: 60.0,
    }];
    let (a, b) = (dir.path().join("loaded"), dir.path().join("streamed"));
    let loaded = run(&spec, false, &a);
    let streamed = run(&spec, true, &b);
    assert!(loaded
        .prepared
        .case
        .truth
        .as_ref()
        .is_some_and(|t| t.len() > 2000));
    let tf = streamed.truth_stream.as_ref().expect("truth streamed");
    assert!(streamed.prepared.case.truth.is_none());
    assert!(tf.path.ends_with("gnss_1934_sf.pos"));
    assert_same_outputs(&a, &b);
    // scored against the truth: position errors at the truth epochs, coasting tracks per outage
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(b.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["reference"], "truth");
    // every .pos epoch inside the run, bar the alignment's and the start's, is compared
    let n = m["overall"]["pos_horizontal_m"]["n"].as_u64().unwrap();
    assert!(n > 2000, "{n} truth epochs compared");
}

#[test]
fn the_real_drive_with_its_roll_flipped_warns_the_same_streamed_and_loaded() {
    let Some(data) =
        shared("the_real_drive_with_its_roll_flipped_warns_the_same_streamed_and_loaded")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(config("drive0708.toml")).unwrap();
    let data = data.canonicalize().unwrap();
    let text = text
        .replace(
            "../../shared/data/rtklibexplorer-drive0708",
            data.to_str().unwrap(),
        )
        .replace(
            "rpy_deg = [180.0, -6.79, 185.35]",
            "rpy_deg = [0.0, -6.79, 185.35]",
        );
    let p = dir.path().join("flipped.toml");
    std::fs::write(&p, text).unwrap();
    let spec = RunSpec::new(&p);
    let loaded = load(&spec, false).unwrap();
    let streamed = load(&spec, true).unwrap();
    println!("{:#?}", streamed.warnings);
    // the drive (549 s) is within the streamed check's prefix: the same words and figures
    let last = loaded.prepared.case.imu.last().unwrap().t_s;
    let first = loaded.prepared.case.imu[0].t_s;
    assert!(last - first < MOUNTING_PREFIX_S);
    assert_eq!(loaded.warnings, streamed.warnings);
    assert_eq!(streamed.warnings.len(), 2, "{:?}", streamed.warnings);
    assert!(streamed.warnings[0].contains("AGAINST the GNSS course"));
    assert!(streamed.warnings[1].contains("tilts the body by 17"));
}

#[test]
fn an_upside_down_imu_is_named_from_the_streamed_prefix_of_a_longer_record() {
    let dir = tempfile::tempdir().unwrap();
    let minutes = 2.0 * MOUNTING_PREFIX_S / 60.0;
    let case = write_csv_pos_case(dir.path(), minutes, 50.0, None);
    let text = std::fs::read_to_string(&case.config).unwrap();
    // the IMU configured upside down: body z up
    let text = text.replace(
        "[imu.csv]",
        "[imu.mounting]\nrpy_deg = [180.0, 0.0, 0.0]\n[imu.csv]",
    );
    std::fs::write(&case.config, text).unwrap();
    let spec = RunSpec::new(&case.config);
    let loaded = load(&spec, false).unwrap();
    let streamed = load(&spec, true).unwrap();
    println!(
        "loaded: {:?}\nstreamed: {:?}",
        loaded.warnings, streamed.warnings
    );
    let rest = |w: &str| -> f64 {
        let s = w.split("at rest (").nth(1).unwrap();
        s.split(" s)").next().unwrap().parse().unwrap()
    };
    for w in [&loaded.warnings, &streamed.warnings] {
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("tilts the body by 180 deg"), "{}", w[0]);
    }
    // the loaded check saw the whole record, the streamed one its first 600 s (1 Hz fixes
    // from 1 s after the first IMU row: 1198 and 599 intervals at rest)
    let (a, b) = (rest(&loaded.warnings[0]), rest(&streamed.warnings[0]));
    assert_eq!(a, 2.0 * MOUNTING_PREFIX_S - 2.0);
    assert_eq!(b, MOUNTING_PREFIX_S - 1.0);
    // the check made on the run's own reading: the same warning, after the run, and the
    // same outputs as the run checked before it
    let (before, after, ok) = run_checking_in_run(&spec, &dir.path().join("in-run"));
    assert!(before.is_empty(), "{before:?}");
    assert_eq!(after, streamed.warnings);
    assert!(ok);
    run(&spec, true, &dir.path().join("before"));
    assert_same_outputs(&dir.path().join("before"), &dir.path().join("in-run"));
}

#[test]
fn a_bad_csv_row_mid_stream_names_file_and_line_and_keeps_the_outputs_before_it() {
    let dir = tempfile::tempdir().unwrap();
    let rate = 200.0;
    let bad = 20_000;
    let case = write_csv_pos_case(dir.path(), 3.0, rate, Some(bad));
    let spec = RunSpec::new(&case.config);
    let want = format!("imu.csv: line {}, column 2", bad + 1);
    // loaded: refused before the run
    let e = format!("{:#}", load(&spec, false).unwrap_err());
    assert!(e.contains(&want), "{e}");
    // streamed: the files open, the run stops at the row
    let l = load(&spec, true).unwrap();
    let out = dir.path().join("out");
    let e = execute(&l, &out).unwrap_err();
    let e = format!("{e:#}");
    println!("{e}");
    assert!(e.contains(&want), "{e}");
    assert!(
        e.contains("the run stopped there") && e.contains(".partial"),
        "{e}"
    );
    // nothing under a final name; every output kept as .partial
    for n in OUTPUT_NAMES {
        assert!(!out.join(n).exists(), "{n} under its final name");
        assert!(partial_path(&out, n).exists(), "{n}.partial missing");
    }
    // nav up to the last increment before the row: rows 1 .. bad-1, the first opening the
    // first interval (bad - 2 increments, one record each: the first is the given state)
    let nav = std::fs::read_to_string(partial_path(&out, "nav.txt")).unwrap();
    let last: f64 = nav
        .lines()
        .last()
        .unwrap()
        .split_whitespace()
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let t_want = T0_S + (bad - 2) as f64 / rate;
    assert!((last - t_want).abs() < 1e-6, "{last} vs {t_want}");
    assert_eq!(nav.lines().count(), bad - 2);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(partial_path(&out, "metrics.json")).unwrap())
            .unwrap();
    assert_eq!(m["complete"], serde_json::Value::Bool(false));
    assert!(
        m["fault"].as_str().unwrap().contains(&want),
        "{}",
        m["fault"]
    );
    // the fixes up to the row were used
    let inn = std::fs::read_to_string(partial_path(&out, "innovations.txt")).unwrap();
    let used = inn.lines().filter(|l| !l.starts_with('#')).count();
    let fixes_before = ((bad - 2) as f64 / rate) as usize;
    assert!(
        used + 1 >= fixes_before && used <= fixes_before + 1,
        "{used} innovations, {fixes_before} fixes before the row"
    );
}

#[test]
fn a_generated_csv_and_pos_case_with_a_gap_outages_and_an_offset_streams_the_loaded_runs_files() {
    let dir = tempfile::tempdir().unwrap();
    let case = write_csv_pos_case(dir.path(), 4.0, 200.0, None);
    // 11 rows lost after data row 4998 (file lines 5000 to 5010)
    let text = std::fs::read_to_string(&case.imu).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(i, _)| !(4999..5010).contains(i))
        .map(|(_, l)| l)
        .collect();
    std::fs::write(&case.imu, kept.join("\n") + "\n").unwrap();
    let mut spec = RunSpec::new(&case.config);
    spec.periodic_outages = vec![nav_engine::run::PeriodicOutages {
        first_start_s: 60.0,
        duration_s: 20.0,
        period_s: 60.0,
    }];
    // the run's own extra IMU time offset on top of the reader's
    spec.imu_time_offset_s = Some(-0.0125);
    let (a, b) = (dir.path().join("loaded"), dir.path().join("streamed"));
    let loaded = run(&spec, false, &a);
    let streamed = run(&spec, true, &b);
    assert_same_outputs(&a, &b);
    assert_eq!(loaded.prepared.week, test_support::csvcase::WEEK);
    assert_eq!(streamed.prepared.week, test_support::csvcase::WEEK);
    assert_eq!(loaded.prepared.opts.outages, streamed.prepared.opts.outages);
    assert_eq!(streamed.prepared.opts.outages.len(), 3);
    // the loaded description reports the gap from the whole file; the streamed run reports
    // it as the engine meets it (metrics.json "imu", the same in both)
    assert!(loaded
        .prepared
        .description
        .contains("IMU time gaps: 1 time gap"));
    assert!(!streamed.prepared.description.contains("IMU time gaps"));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(b.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["imu"]["gaps"], 1);
    assert_eq!(m["imu"]["missing_samples"], 11);
    let ev = m["imu"]["events"][0]["location"].as_str().unwrap();
    assert!(ev.ends_with("imu.csv line 5000"), "{ev}");
}

/// Negates the y and z increments of every sample of a case's `imu.txt` (an IMU mounted
/// upside down, as roll 180 deg).
fn flip_imu_text(case: &Path) {
    let p = case.join("imu.txt");
    let text = std::fs::read_to_string(&p).unwrap();
    let mut out = String::with_capacity(text.len() + text.len() / 10);
    for line in text.lines() {
        if line.starts_with('#') || line.trim().is_empty() {
            out.push_str(line);
        } else {
            let f: Vec<&str> = line.split_whitespace().collect();
            assert!(f.len() >= 7, "{line}");
            let neg = |s: &str| match s.strip_prefix('-') {
                Some(r) => r.to_string(),
                None => format!("-{s}"),
            };
            let mut g: Vec<String> = f.iter().map(|s| s.to_string()).collect();
            for k in [2, 3, 5, 6] {
                g[k] = neg(f[k]);
            }
            out.push_str(&g.join(" "));
        }
        out.push('\n');
    }
    std::fs::write(&p, out).unwrap();
}

#[test]
fn case_directories_and_kf_gins_files_streamed_warn_as_loaded() {
    let dir = tempfile::tempdir().unwrap();
    let sc = dir.path().join("scenario.toml");
    std::fs::write(
        &sc,
        test_support::scenario::four_minute_drive("mount").build(),
    )
    .unwrap();
    let case = dir.path().join("case");
    test_support::cli::Bin::new(env!("CARGO_BIN_EXE_host-sim")).run_ok([
        "simulate",
        "--scenario",
        sc.to_str().unwrap(),
        "--errors",
        "tactical",
        "--seed",
        "5",
        "--kf-gins",
        "--out",
        case.to_str().unwrap(),
    ]);
    let cfg = dir.path().join("run.toml");
    std::fs::write(
        &cfg,
        test_support::runcase::case_config(
            "mount",
            &case,
            "gnss.txt",
            "text",
            "",
            test_support::runcase::TACTICAL_NOISE,
        ),
    )
    .unwrap();
    let mut as_case = RunSpec::new(&cfg);
    as_case.case = Some(case.clone());
    let kf = RunSpec::new(case.join("kf-gins.yaml"));
    let specs = [("case directory", as_case), ("KF-GINS", kf)];
    // the right mounting: no warning either way
    for (name, spec) in &specs {
        let (l, s) = (load(spec, false).unwrap(), load(spec, true).unwrap());
        assert!(
            s.imu_stream.is_some() && s.prepared.case.imu.is_empty(),
            "{name}"
        );
        assert!(
            l.warnings.is_empty() && s.warnings.is_empty(),
            "{name}: {:?}",
            s.warnings
        );
    }
    // upside down: the same two warnings (the 5.4-minute drive is within the prefix)
    flip_imu_text(&case);
    for (name, spec) in &specs {
        let (l, s) = (load(spec, false).unwrap(), load(spec, true).unwrap());
        println!("{name}: {:?}", s.warnings);
        assert_eq!(l.warnings, s.warnings, "{name}");
        assert_eq!(s.warnings.len(), 2, "{name}: {:?}", s.warnings);
        assert!(s.warnings[0].contains("AGAINST the GNSS course"), "{name}");
        assert!(
            s.warnings[1].contains("tilts the body by 180 deg"),
            "{name}"
        );
        // made on the run's own reading of the IMU text file: the same two, after the run
        let out = dir
            .path()
            .join(format!("in-run-{}", name.replace(' ', "-")));
        let (before, after, _) = run_checking_in_run(spec, &out);
        assert!(before.is_empty(), "{name}: {before:?}");
        assert_eq!(after, s.warnings, "{name}");
    }
}
