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
