//! Generated truth and ideal increments are consistent with `nav-core`'s mechanization: the
//! strapdown algorithm on the error-free increments of the default scenario follows the truth.
use nav_core::earth::{ned_offset_m, Llh};
use nav_core::strapdown::Strapdown;
use nav_sim::{Scenario, Trajectory};
use std::path::Path;

fn default_trajectory() -> Trajectory {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/default.toml");
    let sc = Scenario::from_file(&p).expect("scenarios/default.toml");
    Trajectory::generate(&sc).expect("default trajectory")
}

/// Runs the mechanization over the first `n` samples; returns the largest position error (m,
/// 3-D) and velocity error (m/s, 3-D) against the truth at every IMU epoch, and their epochs.
fn drift(tr: &Trajectory, n: usize) -> (f64, f64, f64, f64) {
    let mut sd = Strapdown::new(tr.nav_state(0).expect("truth[0]"));
    let (mut max_p, mut max_v, mut t_p, mut t_v) = (0.0f64, 0.0f64, 0.0, 0.0);
    for k in 0..n {
        sd.update(&tr.imu[k]).expect("mechanization step");
        let s = sd.state();
        let t = &tr.truth[k + 1];
        assert!((s.t_s - t.t_s).abs() < 1e-9);
        let truth = Llh {
            lat_rad: t.lat_rad,
            lon_rad: t.lon_rad,
            h_m: t.h_m,
        };
        let dp = ned_offset_m(&truth, &s.pos).norm();
        let dv = (s.vel_ned_mps - nalgebra::Vector3::from(t.vel_ned_mps)).norm();
        if dp > max_p {
            (max_p, t_p) = (dp, t.t_s - tr.t0_s);
        }
        if dv > max_v {
            (max_v, t_v) = (dv, t.t_s - tr.t0_s);
        }
    }
    (max_p, max_v, t_p, t_v)
}

#[test]
fn strapdown_on_ideal_increments_of_default_scenario_stays_within_2cm_and_0p1mmps_for_10_min() {
    let tr = default_trajectory();
    let n = (600.0 / tr.dt_s).round() as usize;
    assert!(tr.len() >= n);
    let (max_p, max_v, t_p, t_v) = drift(&tr, n);
    println!(
        "10 min of the default scenario: max position error {max_p:.3e} m (at {t_p:.1} s), \
         max velocity error {max_v:.3e} m/s (at {t_v:.1} s)"
    );
    assert!(max_p < 0.02, "position error {max_p} m");
    assert!(max_v < 1e-4, "velocity error {max_v} m/s");
}

#[test]
fn strapdown_on_ideal_increments_of_turn_rich_scenario_stays_within_2cm_and_0p1mmps() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/turns.toml");
    let sc = Scenario::from_file(&p).expect("scenarios/turns.toml");
    let tr = Trajectory::generate(&sc).expect("turns trajectory");
    let (max_p, max_v, t_p, t_v) = drift(&tr, tr.len());
    println!(
        "{:.0} s of the turn-rich scenario: max position error {max_p:.3e} m (at {t_p:.1} s), \
         max velocity error {max_v:.3e} m/s (at {t_v:.1} s)",
        tr.duration_s()
    );
    assert!(max_p < 0.02, "position error {max_p} m");
    assert!(max_v < 1e-4, "velocity error {max_v} m/s");
}
