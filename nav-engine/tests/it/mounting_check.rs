//! `run` warns when the data contradict the configured mounting: the body z gyro turning
//! against the GNSS course, gravity at rest not along body -z.

use crate::case_data;
use nav_engine::mounting::check_mounting;
use nav_engine::run::CaseData;
use nav_sim::{simulate, ErrorModel};
use test_support::scenario::ScenarioToml;

fn case() -> CaseData {
    let sc = ScenarioToml::new("mount-check")
        .description("rest, then turns")
        .start(48.1990, 16.3700, 220.0, 20.0)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(100.0)
        .stationary(10.0)
        .accelerate(10.0, 8.0)
        .turn(120.0, 40.0)
        .turn(-150.0, 50.0)
        .cruise(10.0)
        .scenario();
    case_data(&simulate(&sc, &ErrorModel::preset("consumer-mems").unwrap(), 7).unwrap())
}

#[test]
fn the_right_mounting_gives_no_warning() {
    let d = case();
    let c = check_mounting(&d.imu, &d.gnss);
    let (slope, n) = c.turn_slope.unwrap();
    println!(
        "slope {slope:.4} over {n} intervals, rest f {:?}",
        c.rest_f_body_mps2
    );
    assert!((slope - 1.0).abs() < 0.05, "{slope}");
    assert!(n >= 10, "{n}");
    let (f, t) = c.rest_f_body_mps2.unwrap();
    assert!(t > 5.0 && f[2] < -9.7, "{f:?} {t}");
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
}

#[test]
fn an_upside_down_imu_is_named() {
    let mut d = case();
    // IMU mounted with 180 deg of roll but configured as identity: y and z negated
    for s in &mut d.imu {
        s.dtheta_rad[1] = -s.dtheta_rad[1];
        s.dtheta_rad[2] = -s.dtheta_rad[2];
        s.dv_mps[1] = -s.dv_mps[1];
        s.dv_mps[2] = -s.dv_mps[2];
    }
    let c = check_mounting(&d.imu, &d.gnss);
    let (slope, _) = c.turn_slope.unwrap();
    assert!((slope + 1.0).abs() < 0.05, "{slope}");
    assert_eq!(c.warnings.len(), 2, "{:?}", c.warnings);
    assert!(c.warnings[0].contains("AGAINST the GNSS course"));
    assert!(
        c.warnings[1].contains("tilts the body by 180 deg"),
        "{}",
        c.warnings[1]
    );
}

#[test]
fn a_sideways_z_axis_is_named() {
    let mut d = case();
    // IMU x up: body z (down) is the IMU's -x; configured as identity
    for s in &mut d.imu {
        let (t, v) = (s.dtheta_rad, s.dv_mps);
        s.dtheta_rad = [-t[2], t[1], t[0]];
        s.dv_mps = [-v[2], v[1], v[0]];
    }
    let c = check_mounting(&d.imu, &d.gnss);
    let (slope, _) = c.turn_slope.unwrap();
    assert!(slope.abs() < 0.1, "{slope}");
    assert!(
        c.warnings.iter().any(|w| w.contains("hardly follows")),
        "{:?}",
        c.warnings
    );
    assert!(
        c.warnings
            .iter()
            .any(|w| w.contains("tilts the body by 90 deg")),
        "{:?}",
        c.warnings
    );
}

#[test]
fn gnss_position_outliers_do_not_blame_a_correct_mounting() {
    let mut d = case();
    // 30 m north, 30 m east, 100 m north: in the turns and at rest
    let n = d.gnss.len();
    for (k, dn, de) in [
        (n / 12, 30.0, 0.0),
        (n / 3, 30.0, 0.0),
        (n / 2, 0.0, 30.0),
        (3 * n / 4, 100.0, 0.0),
    ] {
        let g = &mut d.gnss[k];
        g.lat_rad += dn / 6.37e6;
        g.lon_rad += de / (6.37e6 * g.lat_rad.cos());
    }
    let c = check_mounting(&d.imu, &d.gnss);
    let (slope, n) = c.turn_slope.unwrap();
    assert!((slope - 1.0).abs() < 0.05, "{slope} over {n}");
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
}

#[test]
fn a_gnss_time_offset_is_estimated_and_named() {
    let d = case();
    let c = check_mounting(&d.imu, &d.gnss);
    let lag = c.gnss_lag_s.unwrap();
    assert!(lag.abs() < 0.05, "{lag}");
    for late in [0.3, 0.5, -0.4] {
        let mut d = case();
        for g in &mut d.gnss {
            g.t_s += late;
        }
        let c = check_mounting(&d.imu, &d.gnss);
        let lag = c.gnss_lag_s.unwrap();
        println!("GNSS {late:+} s late: estimate {lag:+.3} s");
        assert!((lag + late).abs() < 0.05, "{late}: {lag}");
        assert_eq!(c.warnings.len(), 1, "{:?}", c.warnings);
        assert!(
            c.warnings[0].contains("[gnss] time_offset_s"),
            "{}",
            c.warnings[0]
        );
    }
}
