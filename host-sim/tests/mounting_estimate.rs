//! `host-sim mounting`: the IMU-to-body rotation from the data, in each of the 24 axis layouts
//! with a few degrees of misalignment, after a 5-minute drive with turns.

use host_sim::mounting::{axis_layouts, estimate_mounting};
use host_sim::run::CaseData;
use host_sim::sim::{simulate, ErrorModel, Scenario};
use nalgebra::{Matrix3, Vector3};
use nav_core::attitude::{dcm_from_euler_zyx, euler_zyx_from_dcm};

/// The drive; `vehicle` is appended as the scenario's `[vehicle]` table (body roll in turns).
fn drive(vehicle: &str) -> Scenario {
    Scenario::from_toml_str(
        &(r#"
name = "mounting-drive"
description = "20 s at rest, then about 5 minutes with turns, speed changes and hills"
[start]
lat_deg = 48.1990
lon_deg = 16.3700
h_m = 220.0
heading_deg = 40.0
gps_week = 2227
sow_s = 118800.0
[imu]
rate_hz = 100.0
[[segment]]
kind = "static"
duration_s = 20.0
[[segment]]
kind = "accelerate"
to_speed_mps = 12.0
duration_s = 10.0
[[segment]]
kind = "turn"
angle_deg = 90.0
radius_m = 40.0
[[segment]]
kind = "cruise"
duration_s = 50.0
[[segment]]
kind = "hill"
height_m = 4.0
length_m = 200.0
[[segment]]
kind = "turn"
angle_deg = -120.0
radius_m = 30.0
[[segment]]
kind = "accelerate"
to_speed_mps = 18.0
duration_s = 10.0
[[segment]]
kind = "cruise"
duration_s = 30.0
[[segment]]
kind = "turn"
angle_deg = 180.0
radius_m = 60.0
[[segment]]
kind = "brake"
to_speed_mps = 8.0
duration_s = 8.0
[[segment]]
kind = "turn"
angle_deg = -90.0
radius_m = 25.0
[[segment]]
kind = "accelerate"
to_speed_mps = 15.0
duration_s = 10.0
[[segment]]
kind = "cruise"
duration_s = 90.0
[[segment]]
kind = "turn"
angle_deg = 60.0
radius_m = 50.0
[[segment]]
kind = "brake"
to_speed_mps = 0.0
duration_s = 10.0
[[segment]]
kind = "static"
duration_s = 10.0
"#
        .to_string()
            + vehicle),
        "mounting-drive",
    )
    .unwrap()
}

#[test]
fn every_axis_layout_with_misalignment_is_found() {
    // the simulator's default body roll in turns: 4 deg per g outwards
    check_layouts("", "flat turns");
}

#[test]
fn every_axis_layout_is_found_with_banked_turns() {
    // a banked road: the body rolls INTO the turn, 20 deg per g of lateral acceleration
    // (up to 6.9 deg in the 0.34 g turns of this drive), and a car leaning out on soft springs,
    // 10 deg per g
    check_layouts(
        "[vehicle]\nroll_per_g_deg = -20.0\n",
        "banked turns, -20 deg/g",
    );
    check_layouts(
        "[vehicle]\nroll_per_g_deg = 10.0\n",
        "soft springs, +10 deg/g",
    );
}

fn check_layouts(vehicle: &str, label: &str) {
    let case = simulate(
        &drive(vehicle),
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
    let body = CaseData::from(&case);
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
