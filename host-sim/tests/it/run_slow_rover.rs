//! A slow rover from raw files and a configuration with the defaults: 0.2 m/s with
//! stops and turns, an IMU mounted Z-up with x pointing backwards, RTK fixes every 3 s as
//! lines `2015_11_26_15_00_02_617 RTK_FIXED lat lon h sN sE sD` (UTC), no velocity.
//! `[init.align]` gives only `static_s`: the heading must come from the GNSS course without a
//! hand setting. A fast car with fixes at 1 Hz aligns from the same rule.

use nav_core::types::{GnssFix, ImuSample};
use nav_engine::metrics::errors_vs_truth;
use nav_io::gnss::encode::utc_of_gps;
use nav_sim::{simulate, ErrorModel};
use std::path::Path;
use std::process::Command;
use test_support::runcase::TACTICAL_NOISE;
use test_support::scenario::ScenarioToml;

// 2015-11-26 15:00 UTC is Thursday of GPS week 1873; GPS - UTC = 17 s
const WEEK: u16 = 1873;
const SOW0: f64 = 4.0 * 86400.0 + 15.0 * 3600.0 + 17.0;

/// IMU axes of the rover: z up, x backwards (y to the right): x_imu = M x_body with
/// M = diag(-1, 1, -1), i.e. `[imu.mounting] rpy_deg = [180, 0, 180]`.
fn to_sensor(imu: &[ImuSample]) -> Vec<ImuSample> {
    imu.iter()
        .map(|s| {
            let mut o = *s;
            let [a, b, c] = s.dtheta_rad;
            o.dtheta_rad = [-a, b, -c];
            let [a, b, c] = s.dv_mps;
            o.dv_mps = [-a, b, -c];
            o
        })
        .collect()
}

/// The rover's GNSS lines: UTC date-time text, quality name, lat, lon, h, sigmas N/E/D.
fn rover_lines(fixes: &[GnssFix], every: usize) -> String {
    let mut s = String::new();
    for f in fixes.iter().step_by(every) {
        let (y, mo, d, h, mi, sec) = utc_of_gps(i64::from(WEEK), f.t_s, 17);
        let ms = (sec * 1000.0).round() as u32;
        s += &format!(
            "{y}_{mo:02}_{d:02}_{h:02}_{mi:02}_{:02}_{:03} RTK_FIXED {:.9} {:.9} {:.4} {:.4} {:.4} {:.4}\n",
            ms / 1000,
            ms % 1000,
            f.lat_rad.to_degrees(),
            f.lon_rad.to_degrees(),
            f.h_m,
            f.pos_std_ned_m[0],
            f.pos_std_ned_m[1],
            f.pos_std_ned_m[2]
        );
    }
    s
}

/// The configuration a new user writes: files, formats, mounting, `static_s`, noise (the
/// tactical preset's datasheet figures). Nothing about the heading.
fn config(dir: &Path) -> String {
    format!(
        r#"name = "slow-rover"
[imu]
path = "{imu}"
format = "text"
[imu.mounting]
rpy_deg = [180.0, 0.0, 180.0]
[gnss]
path = "{gnss}"
format = "csv"
[gnss.csv]
[gnss.csv.columns]
time = 1
lat = 3
lon = 4
h = 5
sigma_ned = [6, 7, 8]
[gnss.csv.time]
kind = "text"
format = "%Y_%m_%d_%H_%M_%S_%3f"
scale = "utc"
[gnss.csv.quality]
column = 2
accept = ["RTK_FIXED", "RTK_FLOAT"]
[truth]
path = "{truth}"
format = "nav_text"
[init]
pos_std_m = [0.05, 0.05, 0.1]
vel_std_mps = [0.05, 0.05, 0.05]
att_std_deg = [1.0, 1.0, 5.0]
[init.align]
static_s = 10.0
{TACTICAL_NOISE}"#,
        imu = dir.join("imu.txt").display(),
        gnss = dir.join("rover.txt").display(),
        truth = dir.join("truth.nav").display(),
    )
}

/// Runs `host-sim run` on the case in `dir`; returns (run output, yaw error after the
/// alignment (deg), worst yaw error from `settle_s` after the start on (deg), worst
/// horizontal error (m), heading source line).
fn run(
    dir: &Path,
    truth: &[nav_core::types::NavSolution],
    settle_s: f64,
) -> (String, f64, f64, f64) {
    let cfg = dir.join("rover.toml");
    std::fs::write(&cfg, config(dir)).unwrap();
    let out_dir = dir.join("out");
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args([
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    let nav = nav_io::read_nav_text(out_dir.join("nav.txt")).unwrap();
    let e = errors_vs_truth(&nav, truth);
    assert!(e.len() > 1000, "{} compared epochs", e.len());
    let t_start = e[0].t_s;
    let yaw0 = e[0].att_deg[2];
    let worst_yaw = e
        .iter()
        .filter(|x| x.t_s >= t_start + settle_s)
        .map(|x| x.att_deg[2].abs())
        .fold(0.0, f64::max);
    let worst_h = e
        .iter()
        .map(|x| x.pos_ned_m[0].hypot(x.pos_ned_m[1]))
        .fold(0.0, f64::max);
    (text, yaw0, worst_yaw, worst_h)
}

fn write_case(
    dir: &Path,
    sc: &ScenarioToml,
    errors: &ErrorModel,
    every: usize,
) -> Vec<nav_core::types::NavSolution> {
    let case = simulate(&sc.scenario(), errors, 7).unwrap();
    nav_io::write_imu_text(dir.join("imu.txt"), &to_sensor(&case.meas.imu)).unwrap();
    std::fs::write(dir.join("rover.txt"), rover_lines(&case.meas.gnss, every)).unwrap();
    nav_io::write_nav_text(dir.join("truth.nav"), &case.trajectory.truth).unwrap();
    case.trajectory.truth.clone()
}

/// A turn at 5 deg/s (the simulator's turn by radius needs 0.5 m/s).
fn slow_turn(angle_deg: f64) -> nav_sim::scenario::Segment {
    nav_sim::scenario::Segment::Turn {
        angle_deg,
        rate_deg_s: Some(5.0),
        radius_m: None,
        ramp_s: None,
    }
}

#[test]
fn a_slow_rover_with_rtk_fixes_every_3_s_aligns_with_the_default_configuration() {
    let dir = tempfile::tempdir().unwrap();
    // 0.2 m/s, a first turn 2.2 m after the start, turns at 5 deg/s (2.3 m radius), two
    // stops; about 5 minutes
    let sc = ScenarioToml::new("slow-rover")
        .start(48.1990, 16.3700, 220.0, 130.0)
        .gps_time(WEEK, SOW0)
        .imu_rate_hz(125.0)
        .stationary(20.0)
        .accelerate(0.2, 2.0)
        .cruise(10.0)
        .segment(slow_turn(90.0))
        .cruise(30.0)
        .brake(0.0, 2.0)
        .stationary(15.0)
        .accelerate(0.2, 2.0)
        .segment(slow_turn(-120.0))
        .cruise(40.0)
        .brake(0.0, 2.0)
        .stationary(15.0)
        .accelerate(0.2, 2.0)
        .cruise(30.0)
        .segment(slow_turn(60.0))
        .cruise(40.0)
        .brake(0.0, 2.0)
        .stationary(5.0);
    // RTK fixes at 1 Hz from the simulator, every third written: one every 3 s
    let truth = write_case(dir.path(), &sc, &ErrorModel::preset("tactical").unwrap(), 3);
    let (text, yaw0, worst_yaw, worst_h) = run(dir.path(), &truth, 0.0);
    println!("{text}");
    println!(
        "slow rover: yaw error at the start {yaw0:.3} deg, worst yaw error {worst_yaw:.3} deg, \
         worst horizontal error {worst_h:.3} m"
    );
    assert!(yaw0.abs() < 3.0, "initial yaw error {yaw0} deg");
    assert!(worst_yaw < 3.0, "worst yaw error {worst_yaw} deg");
    assert!(worst_h < 0.2, "worst horizontal error {worst_h} m");
}

#[test]
fn a_fast_car_with_fixes_at_1_hz_aligns_from_the_same_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let sc = ScenarioToml::new("car")
        .start(48.1990, 16.3700, 220.0, 130.0)
        .gps_time(WEEK, SOW0)
        .imu_rate_hz(125.0)
        .stationary(20.0)
        .accelerate(15.0, 8.0)
        .turn(90.0, 60.0)
        .cruise(30.0)
        .turn(-60.0, 80.0)
        .cruise(30.0)
        .brake(0.0, 8.0)
        .stationary(5.0);
    let truth = write_case(dir.path(), &sc, &ErrorModel::preset("tactical").unwrap(), 1);
    let (text, yaw0, worst_yaw, worst_h) = run(dir.path(), &truth, 30.0);
    println!("{text}");
    println!(
        "car: yaw error at the start {yaw0:.3} deg, worst yaw error after 30 s {worst_yaw:.3} \
         deg, worst horizontal error {worst_h:.3} m"
    );
    assert!(yaw0.abs() < 3.0, "initial yaw error {yaw0} deg");
    assert!(worst_yaw < 0.5, "worst yaw error {worst_yaw} deg");
    assert!(worst_h < 0.2, "worst horizontal error {worst_h} m");
}
