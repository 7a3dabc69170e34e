//! Truth trajectory and ideal increments: exact static values, quadrature convergence,
//! kinematic consistency, segment targets, smoothness, scenario errors.
use nalgebra::Vector3;
use nav_core::earth::{self, ned_offset_m, Llh};
use nav_sim::trajectory::{dcm_from_euler, nav_state_of};
use nav_sim::{Scenario, Trajectory};
use std::path::Path;
use std::sync::OnceLock;

fn scenario(name: &str) -> Scenario {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(name);
    Scenario::from_file(&p).unwrap()
}

fn turns() -> &'static Trajectory {
    static T: OnceLock<Trajectory> = OnceLock::new();
    T.get_or_init(|| Trajectory::generate(&scenario("turns.toml")).unwrap())
}

const HEAD: &str = r#"
[start]
lat_deg = 48.199
lon_deg = 16.37
h_m = 220.0
heading_deg = 30.0
gps_week = 2227
sow_s = 118800.0
"#;

fn pos(s: &nav_core::types::NavSolution) -> Llh {
    Llh {
        lat_rad: s.lat_rad,
        lon_rad: s.lon_rad,
        h_m: s.h_m,
    }
}

#[test]
fn shipped_scenarios_parse_and_have_the_documented_durations() {
    for (name, minutes) in [
        ("default.toml", 25.0),
        ("static.toml", 60.0),
        ("turns.toml", 15.6),
        ("long.toml", 60.0),
        ("figure8.toml", 9.3),
    ] {
        let d = scenario(name).duration_s().unwrap() / 60.0;
        assert!((d - minutes).abs() < 0.05, "{name}: {d} min");
    }
}

#[test]
fn static_increments_are_earth_rate_and_gravity_exactly() {
    let text = format!("{HEAD}[[segment]]\nkind = \"static\"\nduration_s = 10.0\n");
    let tr = Trajectory::generate(&Scenario::from_toml_str(&text, "static").unwrap()).unwrap();
    let s0 = nav_state_of(&tr.truth[0]);
    let c_nb = s0.q_nb.inverse();
    let w = c_nb * earth::earth_rate_ned_radps(s0.pos.lat_rad) * tr.dt_s;
    let f = c_nb * -earth::gravity_ned_mps2(s0.pos.lat_rad, s0.pos.h_m) * tr.dt_s;
    assert_eq!(tr.len(), 2000);
    for s in &tr.imu {
        assert!((Vector3::from(s.dtheta_rad) - w).norm() < 1e-18);
        assert!((Vector3::from(s.dv_mps) - f).norm() < 1e-15);
    }
    assert_eq!(pos(tr.truth.last().unwrap()), s0.pos);
}

#[test]
fn increments_converge_with_the_internal_rate_far_below_sensor_noise() {
    // RK4 with 2 vs 16 sub-steps per IMU interval on the turn-rich drive: the increments agree
    // to 1e-13 (the seed's gyro white noise per 5 ms sample is 1.6e-6 rad, the accelerometer's
    // 5.6e-6 m/s): the default 4 sub-steps are exact for every purpose.
    let mut sc = scenario("turns.toml");
    sc.segments.truncate(30);
    sc.imu.substeps = 2;
    let a = Trajectory::generate(&sc).unwrap();
    sc.imu.substeps = 16;
    let b = Trajectory::generate(&sc).unwrap();
    let (mut mth, mut mv) = (0f64, 0f64);
    for (x, y) in a.imu.iter().zip(&b.imu) {
        for i in 0..3 {
            mth = mth.max((x.dtheta_rad[i] - y.dtheta_rad[i]).abs());
            mv = mv.max((x.dv_mps[i] - y.dv_mps[i]).abs());
        }
    }
    let dp = ned_offset_m(&pos(b.truth.last().unwrap()), &pos(a.truth.last().unwrap())).norm();
    println!("2 vs 16 sub-steps: max |d dtheta| {mth:e} rad, max |d dv| {mv:e} m/s, end {dp:e} m");
    assert!(mth < 1e-13 && mv < 1e-12, "{mth} {mv}");
    assert!(dp < 1e-3, "{dp}");
}

#[test]
fn truth_is_kinematically_consistent_and_non_holonomic() {
    let tr = turns();
    let mut max_dp = 0f64;
    let mut max_lat = 0f64;
    for k in 0..tr.len() {
        let (a, b) = (&tr.truth[k], &tr.truth[k + 1]);
        // Position step = trapezoidal integral of the velocity (error dt^3/12 * jerk, ~1e-8 m).
        let d = ned_offset_m(&pos(a), &pos(b));
        let v = (Vector3::from(a.vel_ned_mps) + Vector3::from(b.vel_ned_mps)) * 0.5 * tr.dt_s;
        max_dp = max_dp.max((d - v).norm());
        // Velocity along the body x axis: no lateral or vertical body velocity.
        let c = dcm_from_euler(b.rpy_rad[0], b.rpy_rad[1], b.rpy_rad[2]);
        let vb = c.transpose() * Vector3::from(b.vel_ned_mps);
        max_lat = max_lat.max(vb.y.abs()).max(vb.z.abs());
        assert!(vb.x >= -1e-12);
    }
    assert!(max_dp < 1e-6, "position vs velocity {max_dp} m");
    assert!(max_lat < 1e-12, "side/vertical body velocity {max_lat} m/s");
}

#[test]
fn segments_reach_their_speed_heading_and_height_targets() {
    let text = format!(
        "{HEAD}[[segment]]\nkind = \"static\"\nduration_s = 5.0\n\
         [[segment]]\nkind = \"accelerate\"\nto_speed_mps = 12.0\nduration_s = 8.0\n\
         [[segment]]\nkind = \"turn\"\nangle_deg = 90.0\nradius_m = 60.0\n\
         [[segment]]\nkind = \"turn\"\nangle_deg = -30.0\nrate_deg_s = 5.0\n\
         [[segment]]\nkind = \"hill\"\nheight_m = 7.5\nlength_m = 300.0\n\
         [[segment]]\nkind = \"brake\"\ndelta_speed_mps = 4.0\nduration_s = 4.0\n\
         [[segment]]\nkind = \"stop\"\n\
         [[segment]]\nkind = \"static\"\nduration_s = 5.0\n"
    );
    let sc = Scenario::from_toml_str(&text, "targets").unwrap();
    let prof = sc.compile().unwrap();
    let tr = Trajectory::generate(&sc).unwrap();
    let at = |t: f64| &tr.truth[(t / tr.dt_s).round() as usize];
    let span = |i: usize| prof.segment_span_s(i).unwrap();
    let speed = |s: &nav_core::types::NavSolution| Vector3::from(s.vel_ned_mps).norm();
    assert!((speed(at(span(1).1)) - 12.0).abs() < 1e-9);
    // Turn by radius at 12 m/s: yaw rate 0.2 rad/s on the plateau, +90 deg in total.
    let mid = 0.5 * (span(2).0 + span(2).1);
    let w = tr.imu[(mid / tr.dt_s) as usize].dtheta_rad[2] / tr.dt_s;
    assert!((w - 12.0 / 60.0).abs() < 1e-3, "yaw rate {w}");
    let yaw = |t: f64| at(t).rpy_rad[2].to_degrees();
    assert!((yaw(span(2).1) - yaw(span(2).0) - 90.0).abs() < 1e-9);
    assert!((yaw(span(3).1) - yaw(span(3).0) + 30.0).abs() < 1e-9);
    // The hill climbs 7.5 m and ends level.
    let (h0, h1) = (at(span(4).0).h_m, at(span(4).1).h_m);
    assert!((h1 - h0 - 7.5).abs() < 1e-4, "climb {}", h1 - h0);
    assert!(at(span(4).1).rpy_rad[1].abs() < 1e-12);
    assert!((speed(at(span(5).1)) - 8.0).abs() < 1e-9);
    assert!(speed(at(span(6).1)) < 1e-9);
    // Default stop duration: speed / 1.5 m/s^2.
    assert!((span(6).1 - span(6).0 - 8.0 / 1.5).abs() < 1e-12);
    // Right turn: body rolls left (outward), 4 deg/g of lateral acceleration.
    let roll = at(mid).rpy_rad[0];
    let expect = -(4f64.to_radians()) * (12.0 * 0.2) / 9.80665;
    assert!((roll - expect).abs() < 1e-6, "roll {roll} vs {expect}");
}

/// Largest second difference of the mean specific force and angular rate between IMU epochs.
fn max_second_difference(tr: &Trajectory) -> (f64, f64) {
    let (mut mf, mut mw) = (0f64, 0f64);
    for w in tr.imu.windows(3) {
        for i in 0..3 {
            let d = |k: usize| w[k].dv_mps[i] / tr.dt_s;
            let r = |k: usize| w[k].dtheta_rad[i] / tr.dt_s;
            mf = mf.max((d(2) - 2.0 * d(1) + d(0)).abs());
            mw = mw.max((r(2) - 2.0 * r(1) + r(0)).abs());
        }
    }
    (mf, mw)
}

#[test]
fn specific_force_and_angular_rate_are_smooth_between_imu_epochs() {
    // For a C2 signal the second difference between epochs is x'' dt^2: it drops by 4 when
    // the rate doubles. A jump between epochs would not drop at all, a kink only by 2.
    let mut sc = scenario("turns.toml");
    sc.segments.truncate(40);
    let a = Trajectory::generate(&sc).unwrap();
    sc.imu.rate_hz = 400.0;
    let b = Trajectory::generate(&sc).unwrap();
    let (fa, wa) = max_second_difference(&a);
    let (fb, wb) = max_second_difference(&b);
    println!("max 2nd difference at 200 Hz: {fa:e} m/s^2, {wa:e} rad/s; at 400 Hz: {fb:e}, {wb:e}");
    assert!(
        (3.5..4.5).contains(&(fa / fb)),
        "specific force ratio {}",
        fa / fb
    );
    assert!(
        (3.5..4.5).contains(&(wa / wb)),
        "angular rate ratio {}",
        wa / wb
    );
    // Absolute size: below 1e-3 m/s^2 and 1e-4 rad/s (the seed's white noise per sample is
    // 1.1e-3 m/s^2 and 3.3e-4 rad/s).
    assert!(fa < 1e-3 && wa < 1e-4, "{fa} {wa}");
}

#[test]
fn scenario_errors_name_the_segment_and_the_problem() {
    let bad = |segs: &str| {
        Scenario::from_toml_str(&format!("{HEAD}{segs}"), "bad.toml")
            .unwrap_err()
            .to_string()
    };
    let e = bad("[[segment]]\nkind = \"accelerate\"\nto_speed_mps = 5.0\nduration_s = 5.0\n[[segment]]\nkind = \"static\"\nduration_s = 5.0\n");
    assert!(
        e.contains("segment 1 (static)") && e.contains("stop"),
        "{e}"
    );
    let e = bad("[[segment]]\nkind = \"turn\"\nangle_deg = 90.0\nradius_m = 10.0\n");
    assert!(e.contains("segment 0 (turn)") && e.contains("speed"), "{e}");
    let e = bad("[[segment]]\nkind = \"cruise\"\nduration_s = -1.0\n");
    assert!(e.contains("duration_s"), "{e}");
    let e = bad("[[segment]]\nkind = \"jump\"\nduration_s = 1.0\n");
    assert!(
        e.contains("bad.toml") && e.contains("jump") && e.contains("line"),
        "{e}"
    );
    let e = bad("[[segment]]\nkind = \"static\"\nduration_s = 604800.0\n");
    assert!(e.contains("week"), "{e}");
}
