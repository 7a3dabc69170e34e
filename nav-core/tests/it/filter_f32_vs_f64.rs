//! The f32-covariance filter against the f64 filter on the same data: a 1-hour
//! 200 Hz drive with 1 Hz GNSS, the KF-GINS-equivalent 21-state model (Gauss-Markov biases and
//! scale factors; the MCU's model) on data with those errors. Positions must agree to 1 cm and
//! attitudes to 0.001 deg at every epoch; and over a 6-hour run (100 Hz) the f32 covariance
//! must stay symmetric positive definite (Cholesky in f32 at every GNSS update).

use nav_core::config::{units, FilterConfig, ScaleFactorNoise, SensorNoise};
use nav_core::filter::Filter;
use nav_core::model::LAYOUT_KF_GINS;
use test_support::filter_sim::*;

const N21: usize = LAYOUT_KF_GINS.dim();

/// A tactical-grade IMU with Gauss-Markov biases and scale factors (the NBK accelerometer
/// numbers with its random walk folded into a long-correlation Gauss-Markov bias).
fn config21() -> FilterConfig {
    let accel = SensorNoise::isotropic(
        nav_core::config::NBK_ACCEL_S_N,
        units::gm_psd_from_sigma(units::mps2_from_ug(30.0), 600.0),
        600.0,
        0.0,
        0.0,
    );
    let gyro = SensorNoise::isotropic(
        nav_core::config::NBK_GYRO_S_N,
        units::gm_psd_from_sigma(units::radps_from_deg_per_h(0.3), 3600.0),
        3600.0,
        0.0,
        0.0,
    );
    let mut c = FilterConfig::with_noise(accel, gyro);
    c.accel_scale = ScaleFactorNoise::from_ppm(300.0, 4.0 * 3600.0);
    c.gyro_scale = ScaleFactorNoise::from_ppm(300.0, 4.0 * 3600.0);
    c
}

fn sim21(imu_hz: f64) -> SimConfig {
    let truth = config21();
    SimConfig {
        truth,
        scale_factors: true,
        ..SimConfig::nbk(imu_hz)
    }
}

#[test]
fn f32_and_f64_filters_agree_to_1cm_and_1mdeg_over_a_1_hour_drive() {
    let sc = sim21(200.0);
    let mut cfg = config21();
    cfg.lever_arm_body_m = sc.lever_arm_body_m;
    let mut sim = Sim::new(sc, 77);
    let unc = test_uncertainty();
    let init = sim.perturbed_initial(&unc);
    let mut f64f: Filter<f64, N21> = Filter::new(LAYOUT_KF_GINS, &cfg, init, &unc).unwrap();
    let mut f32f: Filter<f32, N21> = Filter::new(LAYOUT_KF_GINS, &cfg, init, &unc).unwrap();
    let (mut max_dp, mut max_da, mut max_err) = (0.0f64, 0.0f64, 0.0f64);
    let mut epochs = 0u64;
    for _ in 0..(3600 * 200) {
        let e = sim.step();
        f64f.propagate(&e.imu).unwrap();
        f32f.propagate(&e.imu).unwrap();
        if let Some(fix) = e.gnss {
            let a = f64f.update_gnss(&fix).unwrap();
            let b = f32f.update_gnss(&fix).unwrap();
            assert_eq!(a.accepted, b.accepted);
        }
        let (phi, _, dr) = nav_errors(f32f.nav_state(), f64f.nav_state());
        let dp = (dr[0] * dr[0] + dr[1] * dr[1] + dr[2] * dr[2]).sqrt();
        let da = (phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
            .sqrt()
            .to_degrees();
        max_dp = max_dp.max(dp);
        max_da = max_da.max(da);
        epochs += 1;
        if epochs > 60 * 200 {
            // after the first minute (initial 0.3 m / 0.3 deg uncertainty converged)
            let (_, _, tr) = nav_errors(f64f.nav_state(), &e.truth);
            max_err = max_err.max((tr[0] * tr[0] + tr[1] * tr[1] + tr[2] * tr[2]).sqrt());
        }
        assert!(
            dp < 0.01 && da < 0.001,
            "epoch {epochs}: f32 vs f64 differ by {dp} m, {da} deg"
        );
    }
    println!(
        "1 h at 200 Hz: max |f32 - f64| position {:.3e} m, attitude {:.3e} deg; max f64 position error vs truth {:.3} m; gnss accepted {} rejected {}",
        max_dp,
        max_da,
        max_err,
        f64f.counters().gnss_accepted,
        f64f.counters().gnss_rejected
    );
    let c = f64f.counters();
    assert_eq!(c.gnss_accepted + c.gnss_rejected, 3600);
    assert!(
        c.gnss_rejected <= 3,
        "gate P = 0.9999 rejected {}",
        c.gnss_rejected
    );
    assert!(
        max_err < 0.1,
        "the filter itself must work: max error {max_err} m after 60 s"
    );
}

#[test]
fn f32_covariance_stays_positive_definite_over_6_hours() {
    let sc = sim21(100.0);
    let mut cfg = config21();
    cfg.lever_arm_body_m = sc.lever_arm_body_m;
    let mut sim = Sim::new(sc, 4242);
    let unc = test_uncertainty();
    let init = sim.perturbed_initial(&unc);
    let mut f: Filter<f32, N21> = Filter::new(LAYOUT_KF_GINS, &cfg, init, &unc).unwrap();
    let mut checks = 0;
    let mut min_ratio = f64::INFINITY;
    for _ in 0..(6 * 3600 * 100) {
        let e = sim.step();
        f.propagate(&e.imu).unwrap();
        if let Some(fix) = e.gnss {
            f.update_gnss(&fix).unwrap();
            assert!(
                f.covariance_is_positive_definite(),
                "f32 covariance not SPD at t = {}",
                fix.t_s
            );
            checks += 1;
            // smallest pivot ratio of the correlation matrix, for the report
            let p = f.covariance();
            let mut c = [[0.0f64; N21]; N21];
            for i in 0..N21 {
                for j in 0..N21 {
                    c[i][j] = p[i][j] as f64 / ((p[i][i] as f64) * (p[j][j] as f64)).sqrt();
                }
            }
            if checks % 600 == 0 {
                let m = nalgebra::SMatrix::<f64, N21, N21>::from_fn(|i, j| c[i][j]);
                let ev = m.symmetric_eigenvalues();
                min_ratio = min_ratio.min(ev.min());
            }
        }
    }
    let c = f.counters();
    println!(
        "6 h at 100 Hz: {checks} Cholesky checks passed, smallest correlation-matrix eigenvalue {min_ratio:.3e}, accepted {} rejected {} numerical failures {}",
        c.gnss_accepted, c.gnss_rejected, c.numerical_failures
    );
    assert_eq!(checks, 6 * 3600);
    assert_eq!(c.numerical_failures, 0);
    assert!(
        c.gnss_rejected <= 10,
        "gate P = 0.9999 rejected {}",
        c.gnss_rejected
    );
}
