//! `host-sim simulate` end to end: the files it writes can be read back with the project's
//! readers and describe exactly what was simulated.
use host_sim::sim::cli::{run, SimulateArgs};
use nav_io::{read_gnss_text, read_imu_text, read_nav_text};
use nav_sim::case::CaseFile;
use nav_sim::errors::Outage;
use nav_sim::{simulate, ErrorModel, Scenario};
use test_support::scenario::ScenarioToml;

fn scenario_toml() -> String {
    ScenarioToml::new("short")
        .start(30.4447873701, 114.4718632047, 20.899, 185.0)
        .gps_time(2100, 456300.0)
        .imu_rate_hz(100.0)
        .stationary(30.0)
        .accelerate(8.0, 6.0)
        .turn(-90.0, 30.0)
        .cruise(40.0)
        .build()
}

const ERRORS: &str = r#"
base = "seed-nbk"
[accel]
scale_factor_ppm = [800.0, 0.0, 0.0]
temp_coeff_per_c = 3e-4
[temperature]
start_c = 15.0
rise_c = 25.0
tau_s = 300.0
[gnss]
lever_arm_b_m = [0.5, -0.3, -1.1]
time_offset_s = 0.05
velocity = true
"#;

#[test]
fn simulate_writes_a_case_the_readers_and_kf_gins_config_agree_with() {
    let dir = tempfile::tempdir().unwrap();
    let sc = dir.path().join("short.toml");
    std::fs::write(&sc, scenario_toml()).unwrap();
    let er = dir.path().join("errors.toml");
    std::fs::write(&er, ERRORS).unwrap();
    let out = dir.path().join("case");
    run(SimulateArgs {
        scenario: sc.display().to_string(),
        errors: er.display().to_string(),
        seed: 42,
        out: out.clone(),
        outages: vec![Outage {
            start_s: 40.0,
            duration_s: 20.0,
        }],
        gnss_rate_hz: Some(2.0),
        kf_gins: true,
        plot: true,
        force: false,
    })
    .unwrap();

    // The same case in memory.
    let mut errors = ErrorModel::load(&er.display().to_string()).unwrap();
    errors.gnss.outages.push(Outage {
        start_s: 40.0,
        duration_s: 20.0,
    });
    errors.gnss.rate_hz = 2.0;
    let scenario = Scenario::from_toml_str(&scenario_toml(), "short").unwrap();
    let case = simulate(&scenario, &errors, 42).unwrap();

    let imu = read_imu_text(out.join("imu.txt")).unwrap().samples;
    assert_eq!(imu.len(), case.meas.imu.len());
    for (a, b) in imu.iter().zip(&case.meas.imu) {
        assert_eq!(a.t_s, b.t_s);
        assert_eq!(a.dv_mps, b.dv_mps);
        assert_eq!(a.dtheta_rad, b.dtheta_rad);
        assert!(a.temperature_c.is_finite() && (a.temperature_c - b.temperature_c).abs() < 1e-12);
    }
    let gnss = read_gnss_text(out.join("gnss.txt")).unwrap();
    assert_eq!(gnss.len(), case.meas.gnss.len());
    assert!(gnss.iter().all(|f| f.has_velocity));
    assert!(gnss.iter().all(|f| !(456340.0..456360.0).contains(&f.t_s)));
    let truth = read_nav_text(out.join("truth.nav")).unwrap();
    assert_eq!(truth.len(), case.trajectory.truth.len());
    assert_eq!(truth[0].week, 2100);

    let cf = CaseFile::from_file(&out.join("case.toml")).unwrap();
    assert_eq!(cf.seed, 42);
    assert_eq!(cf.errors, errors);
    assert_eq!(cf.scenario, scenario);
    assert_eq!(cf.realized, case.meas.realized);
    assert_eq!(cf.outages.len(), 1);
    assert_eq!(cf.outages[0].start_sow, 456340.0);
    assert_eq!(cf.summary.imu_samples, imu.len());
    assert!(cf.summary.temperature_column);
    assert_eq!(cf.errors.gnss.time_offset_s, 0.05);
    assert_eq!(cf.errors.accel.scale_factor_ppm.0, [800.0, 0.0, 0.0]);

    // KF-GINS configuration: its keys, its units, the truth's initial state.
    let y: serde_norway::Value =
        serde_norway::from_str(&std::fs::read_to_string(out.join("kf-gins.yaml")).unwrap())
            .unwrap();
    let imupath = y["imupath"].as_str().unwrap();
    assert!(std::path::Path::new(imupath).exists(), "{imupath}");
    assert!(std::path::Path::new(y["gnsspath"].as_str().unwrap()).exists());
    assert_eq!(y["imudatalen"].as_i64(), Some(8));
    assert_eq!(y["imudatarate"].as_f64(), Some(100.0));
    assert_eq!(y["starttime"].as_f64(), Some(456300.0));
    let initpos: Vec<f64> = serde_norway::from_value(y["initpos"].clone()).unwrap();
    assert!((initpos[0] - 30.4447873701).abs() < 1e-9 && (initpos[2] - 20.899).abs() < 1e-4);
    let initatt: Vec<f64> = serde_norway::from_value(y["initatt"].clone()).unwrap();
    assert!((initatt[2] - 185.0).abs() < 1e-6);
    let arw: Vec<f64> = serde_norway::from_value(y["imunoise"]["arw"].clone()).unwrap();
    let expect_arw = 5.3079e-10f64.sqrt().to_degrees() * 60.0;
    assert!((arw[0] / expect_arw - 1.0).abs() < 1e-12, "{arw:?}");
    let vrw: Vec<f64> = serde_norway::from_value(y["imunoise"]["vrw"].clone()).unwrap();
    assert!((vrw[1] / (6.2865e-9f64.sqrt() * 60.0) - 1.0).abs() < 1e-12);
    let lever: Vec<f64> = serde_norway::from_value(y["antlever"].clone()).unwrap();
    assert_eq!(lever, vec![0.5, -0.3, -1.1]);
    let asstd: Vec<f64> = serde_norway::from_value(y["imunoise"]["asstd"].clone()).unwrap();
    assert_eq!(asstd[0], 800.0);
    assert!(out.join("trajectory.png").metadata().unwrap().len() > 10_000);
}

#[test]
fn simulate_rejects_bad_inputs_with_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let args = |scenario: &str, errors: &str| SimulateArgs {
        scenario: scenario.into(),
        errors: errors.into(),
        seed: 1,
        out: dir.path().join("x"),
        outages: vec![],
        gnss_rate_hz: None,
        kf_gins: false,
        plot: false,
        force: false,
    };
    let e = run(args("no/such/scenario.toml", "none"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no/such/scenario.toml"), "{e}");
    // a misspelt shipped name: the shipped names listed and the nearest one suggested
    let e = run(args("defualt", "none")).unwrap_err().to_string();
    assert!(e.contains("scenario `defualt`"), "{e}");
    assert!(
        e.contains("figure8, land_stops"),
        "lists the shipped names: {e}"
    );
    assert!(e.contains("did you mean `default`?"), "{e}");
    let e = run(args("static", "no-such-preset"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no-such-preset"), "{e}");
}

const HOST_SIM: test_support::cli::Bin =
    test_support::cli::Bin::new(env!("CARGO_BIN_EXE_host-sim"));

/// Name -> bytes of every entry of `d` (a folder's entries as empty).
fn contents(d: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(d)
        .unwrap()
        .flatten()
        .map(|e| {
            let bytes = std::fs::read(e.path()).unwrap_or_default();
            (e.file_name().to_string_lossy().into_owned(), bytes)
        })
        .collect()
}

/// `simulate --out` follows the output-folder policy of `run`: a folder already holding a case
/// is refused (named, with what to do) and left byte for byte as it was unless `--force`; a
/// folder holding the scenario file, or a file in the folder's place, is refused before
/// anything is written; with `--force` the case is replaced whole (an earlier `kf-gins.yaml`
/// that this case does not write goes too) and the KF-GINS YAML names the files at their
/// final place.
#[test]
fn simulate_refuses_to_write_over_an_existing_case_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let sc = dir.path().join("short.toml");
    std::fs::write(&sc, scenario_toml()).unwrap();
    let out = dir.path().join("case");
    let sim = |seed: &str, extra: &[&str]| {
        let mut a = vec![
            "simulate",
            "--scenario",
            sc.to_str().unwrap(),
            "--errors",
            "tactical",
            "--seed",
            seed,
            "--out",
            out.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        HOST_SIM.run(a)
    };
    let first = sim("1", &["--kf-gins"]);
    assert!(first.ok, "{}", first.stderr);
    let yaml = std::fs::read_to_string(out.join("kf-gins.yaml")).unwrap();
    let abs = std::path::absolute(&out).unwrap();
    assert!(
        yaml.contains(&abs.join("imu.txt").display().to_string())
            && !yaml.contains(".nav-out-stage"),
        "{yaml}"
    );
    let before = contents(&out);

    // a second case into the same folder: refused, exit 1, nothing changed
    let again = sim("2", &[]);
    assert_eq!(again.status.code(), Some(1), "{}", again.stderr);
    let want = format!(
        "error: --out {} already holds a case (imu.txt, gnss.txt, truth.nav, case.toml, \
         kf-gins.yaml): pass --force to replace it, or choose another output folder (nothing \
         was written)\n",
        out.display()
    );
    assert_eq!(again.stderr, want);
    assert_eq!(contents(&out), before);

    // the scenario file inside the output folder: refused even with --force
    let inside = out.join("short.toml");
    std::fs::copy(&sc, &inside).unwrap();
    let before = contents(&out);
    let mut a: Vec<&str> = vec!["simulate", "--scenario", inside.to_str().unwrap()];
    a.extend(["--out", out.to_str().unwrap(), "--force"]);
    let held = HOST_SIM.run(a);
    assert!(
        !held.ok && held.stderr.contains("holds the input") && held.stderr.contains("short.toml"),
        "{}",
        held.stderr
    );
    assert_eq!(contents(&out), before);
    std::fs::remove_file(&inside).unwrap();

    // a file in the folder's place
    let file = dir.path().join("afile");
    std::fs::write(&file, "keep").unwrap();
    let mut a: Vec<&str> = vec!["simulate", "--scenario", sc.to_str().unwrap()];
    a.extend(["--out", file.to_str().unwrap()]);
    let f = HOST_SIM.run(a);
    assert!(
        !f.ok
            && f.stderr
                .contains("afile is a file of 4 bytes, not a folder"),
        "{}",
        f.stderr
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");

    // --force: the case replaced whole, no stage folder left
    let forced = sim("2", &["--force"]);
    assert!(forced.ok, "{}", forced.stderr);
    let after = contents(&out);
    assert_ne!(after["imu.txt"], before["imu.txt"]);
    assert!(!after.contains_key("kf-gins.yaml"), "{:?}", after.keys());
    assert!(
        !after.keys().any(|k| k.starts_with(".nav-out-stage")),
        "{:?}",
        after.keys()
    );
}
