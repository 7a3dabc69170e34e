//! The `allan_params.toml` that `host-sim allan` writes is a `[noise]` section a run
//! configuration accepts verbatim. A static hour of a simulated tactical IMU is analysed, the
//! file is pasted into a run configuration of a simulated drive of the same IMU, and the run
//! is as accurate as with the simulator's true noise figures.
use std::path::Path;
use test_support::cli::Bin;
use test_support::runcase::{case_config, run_case, simulate_case, TACTICAL_NOISE};
use test_support::scenario::{four_minute_drive, ScenarioToml};

const HOST_SIM: Bin = Bin::new(env!("CARGO_BIN_EXE_host-sim"));

/// Runs the drive's configuration `cfg` (a 30 s outage from 120 s); its metrics.
fn run_metrics(dir: &Path, name: &str, cfg: &str) -> serde_json::Value {
    let (so, out) = run_case(HOST_SIM, dir, name, cfg);
    println!("{name}:\n{so}");
    serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap()
}

#[test]
fn allan_params_are_a_noise_section_a_run_accepts_verbatim() {
    let dir = tempfile::tempdir().unwrap();
    // one static hour at 50 Hz (the tactical preset's Gauss-Markov T_B is 300 s)
    let static_case = simulate_case(
        HOST_SIM,
        dir.path(),
        "static",
        &ScenarioToml::new("static-hour")
            .start(30.5, 114.3, 20.0, 0.0)
            .gps_time(2300, 100000.0)
            .imu_rate_hz(50.0)
            .stationary(3600.0)
            .build(),
        "tactical",
        1,
    );
    let adir = dir.path().join("allan");
    let so = HOST_SIM.run_ok_both([
        "allan",
        static_case.join("imu.txt").to_str().unwrap(),
        "--out-dir",
        adir.to_str().unwrap(),
        "--no-plot",
        "--quiet",
        "--accel-bias-init-ug",
        "200",
        "--gyro-bias-init-deg-per-h",
        "1",
    ]);
    let params = std::fs::read_to_string(adir.join("allan_params.toml")).unwrap();
    println!("{so}\n{params}");
    assert!(adir.join("allan_sim_errors.toml").exists());

    // the identified white noise against the preset: accel 50 ug/sqrt(Hz), gyro 0.1 deg/sqrt(h)
    let noise: nav_io::NoiseConfig = toml::from_str::<toml::Table>(&params)
        .unwrap()
        .get("noise")
        .expect("a [noise] table")
        .clone()
        .try_into()
        .unwrap();
    let acc = noise.accel.to_sensor_noise().unwrap();
    let gyr = noise.gyro.to_sensor_noise().unwrap();
    use nav_core::config::units;
    for k in 0..3 {
        let n_ug = acc.s_n[k].sqrt() / units::UG_MPS2;
        let arw = units::gyro_deg_per_sqrt_h_from_psd(gyr.s_n[k]);
        println!("axis {k}: accel N {n_ug:.2} ug/sqrt(Hz), gyro ARW {arw:.4} deg/sqrt(h)");
        assert!((n_ug / 50.0 - 1.0).abs() < 0.05, "accel N {n_ug}");
        assert!((arw / 0.1 - 1.0).abs() < 0.05, "gyro ARW {arw}");
        assert!((acc.bias_init_sigma[k] / (200.0 * units::UG_MPS2) - 1.0).abs() < 1e-12);
    }

    // pasted verbatim into the drive's configuration: it runs, as accurately as the truth
    let drive = simulate_case(
        HOST_SIM,
        dir.path(),
        "drive",
        &four_minute_drive("allan-params-drive").build(),
        "tactical",
        4,
    );
    let config = |noise: &str| case_config("allan-params", &drive, "gnss.txt", "text", "", noise);
    let identified = run_metrics(dir.path(), "identified", &config(&params));
    let reference = run_metrics(dir.path(), "true-noise", &config(TACTICAL_NOISE));
    let get = |m: &serde_json::Value| {
        (
            m["outside_outages"]["pos_horizontal_m"]["rms"]
                .as_f64()
                .unwrap(),
            m["per_outage"][0]["end"]["horizontal_m"].as_f64().unwrap(),
        )
    };
    let (rms_i, out_i) = get(&identified);
    let (rms_t, out_t) = get(&reference);
    println!(
        "with GNSS RMS {rms_i:.4} m (true noise {rms_t:.4}); 30 s outage end {out_i:.3} m ({out_t:.3})"
    );
    // measured 0.1015 m for both (the yaw from the GNSS course at the start dominates)
    assert!(rms_i < 0.15, "{rms_i}");
    assert!(rms_i < 1.2 * rms_t + 0.002, "{rms_i} vs {rms_t}");
    assert!(
        out_i.is_finite() && out_i < 1.5 * out_t + 0.1,
        "{out_i} vs {out_t}"
    );
}

/// Deterministic standard normal samples (xorshift64* + Box-Muller).
fn normals(n: usize, mut s: u64) -> Vec<f64> {
    let mut u = || {
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        ((s.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        })
        .collect()
}

/// A single generic channel (`--columns x`) is reported in SI under SI headings,
/// or, with `--x-unit`, as the sensor that unit names (datasheet units, a `[noise.gyro]`
/// section with the channel for all three axes).
#[test]
fn a_single_channel_takes_its_unit_or_prints_si_with_si_headings() {
    let dir = tempfile::tempdir().unwrap();
    // a gyro in deg/s at 100 Hz: white noise 0.01 deg/s/sqrt(Hz) = 0.6 deg/sqrt(h)
    let (rate, n_dps) = (100.0, 0.01);
    let sigma = n_dps * rate_sqrt(rate);
    let text: String = normals(200_000, 99)
        .iter()
        .map(|v| format!("{:.6}\n", 0.2 + sigma * v))
        .collect();
    let file = dir.path().join("one.txt");
    std::fs::write(&file, text).unwrap();
    let allan = |unit: &str, out: &str| {
        let o = dir.path().join(out);
        let so = HOST_SIM.run_ok_both([
            "allan",
            file.to_str().unwrap(),
            "--columns",
            "x",
            "--rate-hz",
            "100",
            "--x-unit",
            unit,
            "--out-dir",
            o.to_str().unwrap(),
            "--no-plot",
            "--quiet",
        ]);
        let params = std::fs::read_to_string(o.join("allan_params.toml")).unwrap();
        println!("--x-unit {unit}:\n{so}\n{params}");
        (so, params)
    };
    // no unit: SI, SI headings, no gyro/accel units anywhere in the table
    let (so, params) = allan("si", "si");
    let row = |so: &str, head: &str| -> String {
        so.lines()
            .find(|l| l.contains(head))
            .unwrap_or_else(|| panic!("no row {head:?} in\n{so}"))
            .to_string()
    };
    let n_row = row(&so, "              N [");
    assert!(n_row.contains("N [U sqrt(s)]"), "{n_row}");
    assert!(
        !so.contains("deg/sqrt(h)") && !so.contains("ug/sqrt(Hz)"),
        "{so}"
    );
    let n_si: f64 = n_row
        .split('|')
        .nth(1)
        .unwrap()
        .split('±')
        .next()
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    assert!(
        (n_si / n_dps - 1.0).abs() < 0.03,
        "N {n_si} in the column's unit"
    );
    assert!(so.contains("U: the unit of the generic channel"), "{so}");
    assert!(!params.lines().any(|l| l.starts_with("[noise")), "{params}");
    assert!(params.contains("channel x has no unit"), "{params}");

    // deg/s: a gyro, ARW in deg/sqrt(h), a [noise.gyro] section a run accepts
    let (so, params) = allan("dps", "dps");
    let n_row = row(&so, "              N [");
    assert!(n_row.contains("N [deg/sqrt(h)]"), "{n_row}");
    assert!(!n_row.contains("ug/sqrt(Hz)"), "{n_row}");
    let arw: f64 = n_row
        .split('|')
        .nth(1)
        .unwrap()
        .split('±')
        .next()
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    assert!((arw / 0.6 - 1.0).abs() < 0.03, "ARW {arw} deg/sqrt(h)");
    let t: toml::Table = toml::from_str(&params).unwrap();
    let noise: nav_io::NoiseConfig = t["noise"].clone().try_into().unwrap();
    let g = noise.gyro.to_sensor_noise().unwrap();
    let arw_cfg = nav_core::config::units::gyro_deg_per_sqrt_h_from_psd(g.s_n[0]);
    assert!((arw_cfg / arw - 1.0).abs() < 1e-3, "{arw_cfg} vs {arw}");
    assert!(g.s_n[0] == g.s_n[1] && g.s_n[1] == g.s_n[2]);
    assert!(params.contains("the single channel x stands for all three axes"));
    assert!(noise.accel.s_n.is_none());
}

fn rate_sqrt(rate_hz: f64) -> f64 {
    rate_hz.sqrt()
}

/// A GNSS file given to `allan` as the IMU file (both are seven numeric columns): its
/// constant sigma columns, read as accelerometer increments, fail the reading with the file
/// and the channels named; nothing is written.
#[test]
fn allan_refuses_a_gnss_file_given_as_the_imu_file() {
    let dir = tempfile::tempdir().unwrap();
    let gnss = dir.path().join("gnss.txt");
    let lines: String = (0..600)
        .map(|i| {
            let d = f64::from(i) * 1e-7;
            format!(
                "{} {} {} {} 0.01 0.01 0.02\n",
                200000 + i,
                48.199 + d,
                16.37 - d,
                220.0 + d * 1e3
            )
        })
        .collect();
    std::fs::write(&gnss, lines).unwrap();
    let out = dir.path().join("allan");
    let ran = HOST_SIM.run([
        "allan",
        gnss.to_str().unwrap(),
        "--out-dir",
        out.to_str().unwrap(),
        "--no-plot",
        "--quiet",
    ]);
    println!("{}\n{}", ran.stdout, ran.stderr);
    assert!(!ran.ok, "a GNSS file analysed as IMU data with exit 0");
    assert!(ran.stderr.contains("gnss.txt"), "{}", ran.stderr);
    assert!(ran.stderr.contains("not IMU data"), "{}", ran.stderr);
    assert!(ran.stderr.contains("ax = 0.01"), "{}", ran.stderr);
    assert!(!out.join("allan_params.toml").exists());
}
