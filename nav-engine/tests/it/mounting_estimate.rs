//! The mounting estimate (`nav_engine::mounting`, what `host-sim mounting` runs): the IMU-to-body rotation from the data, in each of the 24 axis layouts
//! with a few degrees of misalignment, after a 5-minute drive with turns.

use crate::case_data;
use nalgebra::{Matrix3, Vector3};
use nav_core::attitude::{dcm_from_euler_zyx, euler_zyx_from_dcm};
use nav_engine::mounting::{axis_layouts, estimate_mounting};
use nav_sim::{simulate, ErrorModel, Scenario};
use test_support::scenario::ScenarioToml;

/// The drive; `roll_per_g_deg` replaces the scenario's default body roll in turns, deg per g.
fn drive(roll_per_g_deg: Option<f64>) -> Scenario {
    let mut sc = ScenarioToml::new("mounting-drive")
        .description("20 s at rest, then about 5 minutes with turns, speed changes and hills")
        .start(48.199, 16.37, 220.0, 40.0)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(100.0)
        .stationary(20.0)
        .accelerate(12.0, 10.0)
        .turn(90.0, 40.0)
        .cruise(50.0)
        .hill(4.0, 200.0)
        .turn(-120.0, 30.0)
        .accelerate(18.0, 10.0)
        .cruise(30.0)
        .turn(180.0, 60.0)
        .brake(8.0, 8.0)
        .turn(-90.0, 25.0)
        .accelerate(15.0, 10.0)
        .cruise(90.0)
        .turn(60.0, 50.0)
        .brake(0.0, 10.0)
        .stationary(10.0)
        .scenario();
    if let Some(r) = roll_per_g_deg {
        sc.vehicle.roll_per_g_deg = r;
    }
    sc
}

#[test]
fn every_axis_layout_with_misalignment_is_found() {
    // the simulator's default body roll in turns: 4 deg per g outwards
    check_layouts(None, "flat turns");
}

#[test]
fn every_axis_layout_is_found_with_banked_turns() {
    // a banked road: the body rolls INTO the turn, 20 deg per g of lateral acceleration
    // (up to 6.9 deg in the 0.34 g turns of this drive), and a car leaning out on soft springs,
    // 10 deg per g
    check_layouts(Some(-20.0), "banked turns, -20 deg/g");
    check_layouts(Some(10.0), "soft springs, +10 deg/g");
}

fn check_layouts(roll_per_g_deg: Option<f64>, label: &str) {
    let case = simulate(
        &drive(roll_per_g_deg),
        &ErrorModel::preset("tactical").unwrap(),
        11,
    )
    .unwrap();
    let roll_max = case
        .trajectory
        .truth
        .iter()
        .map(|s| s.rpy_rad[0].to_degrees().abs())
        .fold(0.0, f64::max);
    let body = case_data(&case);
    let dur = body.imu.last().unwrap().t_s - body.imu[0].t_s;
    assert!(dur > 300.0, "{dur}");
    let layouts = axis_layouts();
    assert_eq!(layouts.len(), 24);
    let (mut worst_tilt, mut worst_yaw, mut min_margin) = (0.0f64, 0.0f64, f64::INFINITY);
    for (k, l) in layouts.iter().enumerate() {
        // a few degrees of misalignment, different for each layout
        let kf = k as f64;
        let small = [
            (2.0 + 0.3 * kf).to_radians() * if k % 2 == 0 { 1.0 } else { -1.0 },
            (-3.0 + 0.25 * kf).to_radians(),
            (4.0 - 0.35 * kf).to_radians(),
        ];
        // x_body = m_true x_imu
        let m_true: Matrix3<f64> = dcm_from_euler_zyx(small) * l;
        let mut imu = body.imu.clone();
        let to_imu = m_true.transpose();
        for s in &mut imu {
            let a = to_imu * Vector3::from(s.dtheta_rad);
            let v = to_imu * Vector3::from(s.dv_mps);
            s.dtheta_rad = a.into();
            s.dv_mps = v.into();
        }
        let est = estimate_mounting(&imu, &body.gnss).unwrap();
        assert_eq!(&est.layout, l, "{label}: layout {k}");
        // the estimate as configured: x_body = C(rpy)^T x_imu
        let m_est = dcm_from_euler_zyx(est.rpy_deg.map(f64::to_radians)).transpose();
        let err = euler_zyx_from_dcm(&(m_est * m_true.transpose())).map(f64::to_degrees);
        worst_tilt = worst_tilt.max(err[0].abs()).max(err[1].abs());
        worst_yaw = worst_yaw.max(err[2].abs());
        min_margin = min_margin.min(est.runner_up_residual_mps2 / est.best_residual_mps2);
        if k == 0 || k == 23 {
            print!("layout {k}:\n{}", est.toml_section());
        }
        assert!(
            err[0].abs() < 0.3 && err[1].abs() < 0.3,
            "{label}: layout {k}: {err:?}"
        );
        assert!(err[2].abs() < 1.0, "{label}: layout {k}: {err:?}");
    }
    println!(
        "{label} (largest body roll {roll_max:.2} deg): 24 layouts: worst roll/pitch error {worst_tilt:.4} deg, worst yaw error {worst_yaw:.4} \
         deg, smallest runner-up/best residual ratio {min_margin:.2}"
    );
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

/// A slow rover: 0.2 m/s, turns at 5 deg/s, two stops; about 2.5 minutes.
fn rover() -> Scenario {
    ScenarioToml::new("slow-rover-mounting")
        .description("0.2 m/s with turns and stops")
        .start(48.199, 16.37, 220.0, 130.0)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(125.0)
        .stationary(15.0)
        .accelerate(0.2, 2.0)
        .cruise(12.0)
        .segment(slow_turn(90.0))
        .cruise(12.0)
        .brake(0.0, 2.0)
        .stationary(12.0)
        .accelerate(0.2, 2.0)
        .cruise(12.0)
        .segment(slow_turn(-120.0))
        .cruise(12.0)
        .brake(0.0, 2.0)
        .stationary(8.0)
        .scenario()
}

#[test]
fn every_axis_layout_is_found_on_a_slow_rover_with_stops() {
    let case = simulate(&rover(), &ErrorModel::preset("tactical").unwrap(), 5).unwrap();
    // RTK fixes every 3 s, positions only
    let gnss: Vec<_> = case
        .meas
        .gnss
        .iter()
        .step_by(3)
        .map(|f| nav_core::types::GnssFix {
            has_velocity: false,
            ..*f
        })
        .collect();
    let imu0 = &case.meas.imu;
    let (mut worst_tilt, mut worst_yaw) = (0.0f64, 0.0f64);
    for (k, l) in axis_layouts().iter().enumerate() {
        let kf = k as f64;
        let small = [
            (2.0 + 0.3 * kf).to_radians() * if k % 2 == 0 { 1.0 } else { -1.0 },
            (-3.0 + 0.25 * kf).to_radians(),
            (4.0 - 0.35 * kf).to_radians(),
        ];
        let m_true: Matrix3<f64> = dcm_from_euler_zyx(small) * l;
        let to_imu = m_true.transpose();
        let imu: Vec<_> = imu0
            .iter()
            .map(|s| {
                let mut o = *s;
                o.dtheta_rad = (to_imu * Vector3::from(s.dtheta_rad)).into();
                o.dv_mps = (to_imu * Vector3::from(s.dv_mps)).into();
                o
            })
            .collect();
        let est = estimate_mounting(&imu, &gnss).unwrap_or_else(|e| panic!("layout {k}: {e}"));
        let m_est = dcm_from_euler_zyx(est.rpy_deg.map(f64::to_radians)).transpose();
        let err = euler_zyx_from_dcm(&(m_est * m_true.transpose())).map(f64::to_degrees);
        if k == 0 || k == 23 {
            print!("layout {k}:\n{}", est.toml_section());
        }
        worst_tilt = worst_tilt.max(err[0].abs()).max(err[1].abs());
        worst_yaw = worst_yaw.max(err[2].abs());
        assert_eq!(
            &est.layout,
            l,
            "layout {k}: {err:?}\n{}",
            est.toml_section()
        );
        assert!(
            err[0].abs() < 0.5 && err[1].abs() < 0.5,
            "layout {k}: {err:?}"
        );
        assert!(err[2].abs() < 3.0, "layout {k}: {err:?}");
        assert!(
            est.notes.iter().any(|n| n.contains("slow vehicle")),
            "{:?}",
            est.notes
        );
    }
    println!(
        "slow rover, 24 layouts: worst roll/pitch error {worst_tilt:.3} deg, worst yaw error \
         {worst_yaw:.3} deg"
    );
}

#[test]
fn a_rover_that_never_stops_says_what_is_missing() {
    let sc = ScenarioToml::new("slow-no-stop")
        .start(48.199, 16.37, 220.0, 130.0)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(125.0)
        .accelerate(0.2, 2.0)
        .cruise(40.0)
        .scenario();
    let case = simulate(&sc, &ErrorModel::preset("tactical").unwrap(), 5).unwrap();
    let e = estimate_mounting(&case.meas.imu, &case.meas.gnss).unwrap_err();
    let msg = e.to_string();
    println!("{msg}");
    assert!(msg.contains("0 starts or stops next to 0 rests"), "{msg}");
}
