//! The aiding a user switches on from the run configuration, end to end through the
//! command line (`host-sim simulate` -> `host-sim run --config`):
//!
//! * odometer / wheel speed (`[aiding.odometer]`): a simulated tactical drive whose wheel
//!   speed has an undeclared 2 % scale factor, three 60 s GNSS outages: with the odometer and
//!   its scale-factor state the outage error is well below GNSS-only, and the scale factor is
//!   estimated; without the state the 2 % is a velocity error;
//! * dual-antenna heading (`[aiding.heading]`): a static vehicle with GNSS positions only
//!   (yaw unobservable) started with a 3 deg yaw error: the heading removes it; an outlier in
//!   the heading file is rejected by the gate; the same headings as an NMEA log (`HDT`) do
//!   as well;
//! * the GNSS velocity's own gate (`[gnss] velocity_gate`, `--velocity-gate`) reaches the
//!   filter: a Doppler velocity outlier is rejected by it (and only with it).
//!
//! Numbers are printed (`--nocapture`).
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use test_support::cli::{self, Bin};
use test_support::scenario::ScenarioToml;

fn host_sim() -> Command {
    Bin::new(env!("CARGO_BIN_EXE_host-sim")).command()
}

/// Runs `cmd`, which must succeed; its standard output and error.
fn run_ok(cmd: &mut Command) -> String {
    let r = cli::run(cmd);
    assert!(
        r.ok,
        "{cmd:?}\nstdout:\n{}\nstderr:\n{}",
        r.stdout, r.stderr
    );
    r.stdout + &r.stderr
}

/// Simulates `scenario` with the tactical preset (and `[gnss]` keys `gnss`, e.g. velocities).
fn simulate(dir: &Path, name: &str, scenario: &str, seed: u32, gnss: &str) -> PathBuf {
    let sc = dir.join(format!("{name}.toml"));
    std::fs::write(&sc, scenario).unwrap();
    let errors = dir.join(format!("{name}-errors.toml"));
    std::fs::write(&errors, format!("base = \"tactical\"\n[gnss]\n{gnss}\n")).unwrap();
    let case = dir.join(name);
    run_ok(host_sim().args([
        "simulate",
        "--scenario",
        sc.to_str().unwrap(),
        "--errors",
        errors.to_str().unwrap(),
        "--seed",
        &seed.to_string(),
        "--out",
        case.to_str().unwrap(),
    ]));
    case
}

/// The tactical preset's noise as the filter's model.
const TACTICAL_NOISE: &str = "[noise]\nmodel = \"nbk\"\n[noise.accel]\nn_ug_per_sqrt_hz = 50.0\n\
    gm_sigma_ug = 50.0\nt_b_s = 300.0\nbias_init_ug = 200.0\n[noise.gyro]\n\
    arw_deg_per_sqrt_h = 0.1\ngm_sigma_deg_per_h = 1.0\nt_b_s = 300.0\n\
    bias_init_deg_per_h = 1.0\n";

/// A run configuration of a case's files with `extra` appended (GNSS, init and aiding keys).
fn config(case: &Path, gnss_extra: &str, init: &str, extra: &str) -> String {
    format!(
        "name = \"aiding-inputs\"\n[imu]\npath = \"{imu}\"\nformat = \"text\"\n[gnss]\n\
         path = \"{gnss}\"\nformat = \"text\"\n{gnss_extra}\n[truth]\npath = \"{truth}\"\n\
         format = \"nav_text\"\n{init}\n{TACTICAL_NOISE}\n{extra}",
        imu = case.join("imu.txt").display(),
        gnss = case.join("gnss.txt").display(),
        truth = case.join("truth.nav").display(),
    )
}

/// Runs `cfg` (written as `<name>.toml`) with `args`; the summary and metrics.json.
fn run(dir: &Path, name: &str, cfg: &str, args: &[&str]) -> (String, Value) {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, cfg).unwrap();
    let out = dir.join(format!("out-{name}"));
    let mut cmd = host_sim();
    cmd.args([
        "run",
        "--config",
        p.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ])
    .args(args);
    let so = run_ok(&mut cmd);
    println!("--- {name}:\n{so}");
    let m =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    (so, m)
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

const ALIGN: &str = "[init]\npos_std_m = [0.05, 0.05, 0.1]\nvel_std_mps = [0.05, 0.05, 0.05]\n\
    att_std_deg = [1.0, 1.0, 5.0]\n[init.align]\nstatic_s = 20.0\n";

#[test]
fn odometer_with_its_scale_state_shrinks_the_outage_error_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    // 7 min at 100 Hz: turns and speed changes; wheel speed at 10 Hz, 2 % too fast, 0.02 m/s
    let scenario = ScenarioToml::new("odometer-drive")
        .start(30.5, 114.3, 20.0, 30.0)
        .gps_time(2300, 200000.0)
        .imu_rate_hz(100.0)
        .odometer(nav_sim::scenario::WheelSpeedSpec {
            rate_hz: 10.0,
            scale: 0.02,
            sigma_mps: 0.02,
            lever_arm_m: [0.0; 3],
        })
        .stationary(30.0)
        .accelerate(15.0, 10.0)
        .cruise(30.0)
        .turn(90.0, 50.0)
        .cruise(40.0)
        .turn(-120.0, 40.0)
        .accelerate(20.0, 10.0)
        .cruise(60.0)
        .turn(60.0, 80.0)
        .cruise(60.0)
        .brake(10.0, 10.0)
        .turn(-90.0, 40.0)
        .cruise(60.0)
        .turn(45.0, 60.0)
        .accelerate(15.0, 5.0)
        .cruise(40.0)
        .brake(0.0, 10.0)
        .stationary(10.0)
        .build();
    let case = simulate(dir.path(), "drive", &scenario, 3, "");
    assert!(case.join("odometer.txt").exists());
    let outages = [
        "--outage", "90:60", "--outage", "210:60", "--outage", "330:60",
    ];
    let case_arg = ["--case", case.to_str().unwrap()];
    let args: Vec<&str> = outages.iter().chain(case_arg.iter()).copied().collect();
    let gnss = "";
    let (_, base) = run(
        dir.path(),
        "gnss-only",
        &config(&case, gnss, ALIGN, ""),
        &args,
    );
    // the file named here is replaced by the case's own odometer.txt (--case)
    let odo = |scale: bool| {
        format!(
            "[aiding.odometer]\nenabled = true\nfile = \"not-this-one.txt\"\nsigma_mps = 0.02\n\
             scale_factor = {scale}\nscale_sigma = 0.05\n"
        )
    };
    let (so_sf, with_sf) = run(
        dir.path(),
        "odometer-scale",
        &config(&case, gnss, ALIGN, &odo(true)),
        &args,
    );
    let (_, no_sf) = run(
        dir.path(),
        "odometer-no-scale",
        &config(&case, gnss, ALIGN, &odo(false)),
        &args,
    );
    let rms = |m: &Value| f(&m["outage_summary"]["max_horizontal_m"]["rms"]);
    let (b, a, n) = (rms(&base), rms(&with_sf), rms(&no_sf));
    let a_odo = &with_sf["aiding"];
    let k = &a_odo["odometer_scale"];
    println!(
        "60 s outages, RMS of per-outage max horizontal error: GNSS only {b:.3} m, odometer \
         with scale state {a:.3} m ({:.2}x), without it {n:.3} m; scale factor {:.5} +- {:.5} \
         (true 0.02); odometer {} used / {} rejected / {} failed",
        a / b,
        f(&k[0]),
        f(&k[1]),
        a_odo["odometer"]["used"],
        a_odo["odometer"]["rejected"],
        a_odo["odometer"]["failed"],
    );
    for m in [&base, &with_sf, &no_sf] {
        assert_eq!(m["per_outage"].as_array().unwrap().len(), 3);
    }
    assert!(a <= 0.5 * b, "odometer + scale {a} vs GNSS only {b}");
    assert!(a < n, "with the scale state {a} vs without {n}");
    assert!((f(&k[0]) - 0.02).abs() < 2e-3, "scale factor {k}");
    assert!((f(&k[0]) - 0.02).abs() < 3.0 * f(&k[1]), "scale factor {k}");
    // 10 Hz aiding epochs from the end of the alignment while the wheel speed is there
    let used = a_odo["odometer"]["used"].as_u64().unwrap();
    assert!(used > 3500, "{used}");
    assert_eq!(a_odo["odometer"]["failed"].as_u64(), Some(0));
    assert!(a_odo["odometer"]["enabled"].as_bool().unwrap());
    assert!(base["aiding"]["odometer"]["used"].as_u64() == Some(0));
    assert!(
        so_sf.contains("aiding: odometer ") && so_sf.contains("odometer scale factor +"),
        "{so_sf}"
    );
}

#[test]
fn dual_antenna_heading_fixes_an_unobservable_yaw_and_rejects_an_outlier() {
    let dir = tempfile::tempdir().unwrap();
    // 5 static minutes at 100 Hz: with GNSS positions only the yaw is not observable (the
    // tactical gyro cannot gyrocompass in minutes); heading at 5 Hz, 0.3 deg, baseline to
    // the right (its azimuth is the yaw + 90 deg)
    let scenario = ScenarioToml::new("static-heading")
        .start(30.5, 114.3, 20.0, 30.0)
        .gps_time(2300, 200000.0)
        .imu_rate_hz(100.0)
        .heading(nav_sim::scenario::HeadingSpec {
            rate_hz: 5.0,
            sigma_deg: 0.3,
            baseline_m: [0.0, 1.2, 0.0],
        })
        .stationary(300.0)
        .build();
    let case = simulate(dir.path(), "static", &scenario, 5, "");
    let heading = case.join("heading.txt");
    let text = std::fs::read_to_string(&heading).unwrap();
    // the same file with one sample 25 deg off, 100 s in
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let (i, l) = lines
        .iter()
        .enumerate()
        .filter(|(_, l)| !l.starts_with('#'))
        .nth(500)
        .unwrap();
    let mut v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
    v[1] += 25.0;
    lines[i] = format!("{} {} {}", v[0], v[1], v[2]);
    let outlier = dir.path().join("heading-outlier.txt");
    std::fs::write(&outlier, lines.join("\n")).unwrap();
    // the alignment's yaw 3 deg off the truth (30 deg), 5 deg sigma
    let init = ALIGN.replace("static_s = 20.0", "static_s = 20.0\nyaw_deg = 33.0");
    let aid = |file: &Path| {
        format!(
            "[aiding.heading]\nenabled = true\nfile = \"{}\"\nbaseline_m = [0.0, 1.2, 0.0]\n",
            file.display()
        )
    };
    let (_, base) = run(dir.path(), "no-heading", &config(&case, "", &init, ""), &[]);
    let (so, with) = run(
        dir.path(),
        "heading",
        &config(&case, "", &init, &aid(&heading)),
        &[],
    );
    let (_, with_out) = run(
        dir.path(),
        "heading-outlier",
        &config(&case, "", &init, &aid(&outlier)),
        &[],
    );
    // the same headings as a receiver's NMEA log: RMC/GGA/GST of the epoch, then HDT
    let nmea: String = nav_io::read_heading(&heading)
        .unwrap()
        .iter()
        .flat_map(|h| {
            let fix = nav_core::types::GnssFix {
                t_s: h.t_s,
                quality: nav_core::types::FixQuality::RtkFixed,
                ..Default::default()
            };
            let body = format!("GPHDT,{:.3},T", h.heading_deg);
            let cs = body.bytes().fold(0u8, |a, b| a ^ b);
            let mut lines = nav_io::gnss::encode::nmea_epoch(&fix, 2300, 18).to_vec();
            lines.push(format!("${body}*{cs:02X}"));
            lines
        })
        .map(|l| l + "\r\n")
        .collect();
    let nmea_file = dir.path().join("heading.nmea");
    std::fs::write(&nmea_file, nmea).unwrap();
    let (_, with_nmea) = run(
        dir.path(),
        "heading-nmea",
        &config(
            &case,
            "",
            &init,
            &(aid(&nmea_file) + "format = \"nmea\"\nsigma_deg = 0.3\n"),
        ),
        &[],
    );
    let yaw = |m: &Value| {
        (
            f(&m["overall"]["yaw_deg"]["rms"]),
            f(&m["overall"]["yaw_deg"]["max"]),
        )
    };
    let ((b_rms, b_max), (h_rms, h_max), (o_rms, _)) = (yaw(&base), yaw(&with), yaw(&with_out));
    let (n_rms, _) = yaw(&with_nmea);
    let hn = &with_nmea["aiding"]["heading"];
    let h = &with["aiding"]["heading"];
    let ho = &with_out["aiding"]["heading"];
    println!(
        "static, GNSS position only: yaw error RMS {b_rms:.3} deg (max {b_max:.3}) without the \
         heading, {h_rms:.4} deg (max {h_max:.3}) with it ({:.3}x), {o_rms:.4} deg with an \
         outlier, {n_rms:.4} deg from the NMEA log (HDT); heading {} used / {} rejected, with the \
         outlier {} used / {} rejected, NMEA {} used",
        h_rms / b_rms,
        h["used"],
        h["rejected"],
        ho["used"],
        ho["rejected"],
        hn["used"],
    );
    assert!(b_rms > 2.0, "the yaw error stays without heading: {b_rms}");
    assert!(h_rms < 0.1 * b_rms, "{h_rms} vs {b_rms}");
    let n = |v: &Value| v.as_u64().unwrap();
    // 5 Hz over the 280 s after the alignment
    assert!(n(&h["used"]) > 1350, "{h}");
    assert_eq!(n(&ho["rejected"]), n(&h["rejected"]) + 1, "{ho} vs {h}");
    assert_eq!(n(&ho["used"]) + 1, n(&h["used"]), "{ho} vs {h}");
    assert!((o_rms - h_rms).abs() < 0.01, "{o_rms} vs {h_rms}");
    assert!(so.contains("aiding: heading "), "{so}");
    // the NMEA log: every sample, the same accuracy
    assert_eq!(n(&hn["used"]), n(&h["used"]), "{hn} vs {h}");
    assert!((n_rms - h_rms).abs() < 0.005, "{n_rms} vs {h_rms}");
}

#[test]
fn the_gnss_velocity_gate_reaches_the_filter() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = ScenarioToml::new("vel-gate")
        .start(30.5, 114.3, 20.0, 30.0)
        .gps_time(2300, 200000.0)
        .imu_rate_hz(100.0)
        .stationary(30.0)
        .accelerate(10.0, 10.0)
        .turn(90.0, 30.0)
        .cruise(60.0)
        .build();
    let case = simulate(dir.path(), "drive", &scenario, 7, "velocity = true");
    // one fix's velocity 5 m/s off north, 80 s in (position untouched)
    let gnss = case.join("gnss.txt");
    let text = std::fs::read_to_string(&gnss).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let (i, l) = lines
        .iter()
        .enumerate()
        .filter(|(_, l)| !l.starts_with('#'))
        .nth(80)
        .unwrap();
    let mut cols: Vec<String> = l.split_whitespace().map(str::to_string).collect();
    let header = text.lines().find(|l| l.starts_with('#')).unwrap_or("");
    // the text GNSS format: week? sow lat lon h sn se sd [vn ve vd svn sve svd]
    let n_col = cols.len();
    assert!(n_col >= 13, "a GNSS line with velocity: {l} ({header})");
    let vn = n_col - 6;
    let v: f64 = cols[vn].parse().unwrap();
    cols[vn] = format!("{}", v + 5.0);
    lines[i] = cols.join(" ");
    std::fs::write(&gnss, lines.join("\n")).unwrap();
    let gnss_keys = |gate: &str| format!("use_velocity = true\n{gate}");
    let (so_hard, hard) = run(
        dir.path(),
        "hard",
        &config(&case, &gnss_keys("velocity_gate = \"hard\""), ALIGN, ""),
        &[],
    );
    let (so_robust, _) = run(
        dir.path(),
        "robust",
        &config(&case, &gnss_keys("velocity_gate = \"robust\""), ALIGN, ""),
        &[],
    );
    // the command line overrides the configuration
    let (so_off, off) = run(
        dir.path(),
        "cli-off",
        &config(&case, &gnss_keys("velocity_gate = \"hard\""), ALIGN, ""),
        &["--velocity-gate", "off"],
    );
    let (so_joint, joint) = run(
        dir.path(),
        "joint",
        &config(&case, &gnss_keys(""), ALIGN, ""),
        &[],
    );
    // the summary's line (none when no velocity was rejected)
    let rej = |so: &str| {
        so.split("GNSS velocity gate: ").nth(1).map_or(0, |r| {
            r.split_whitespace().next().unwrap().parse::<u64>().unwrap()
        })
    };
    let pos = |m: &Value| f(&m["overall"]["pos_horizontal_m"]["max"]);
    println!(
        "velocity outlier of 5 m/s: velocities rejected hard {}, robust {}, off {}, joint {}; \
         max horizontal error hard {:.3} m, off {:.3} m, joint {:.3} m",
        rej(&so_hard),
        rej(&so_robust),
        rej(&so_off),
        rej(&so_joint),
        pos(&hard),
        pos(&off),
        pos(&joint)
    );
    assert_eq!(rej(&so_hard), 1, "{so_hard}");
    assert_eq!(rej(&so_robust), 1, "{so_robust}");
    assert!(!so_off.contains("GNSS velocity gate"), "{so_off}");
    assert!(!so_joint.contains("GNSS velocity gate"), "{so_joint}");
    assert!(pos(&hard) < pos(&off), "{} vs {}", pos(&hard), pos(&off));
}
