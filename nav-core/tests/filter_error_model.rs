//! The linearised error model against the nonlinear mechanisation: over 20 s of a turning,
//! accelerating drive (200 Hz, covariance predicted every 0.1 s), the product of the filter's
//! transition matrices must match finite differences of two filters' nominal trajectories, one
//! started with a small error in one state (attitude, velocity, position, or a sensor-error
//! estimate), both fed the same raw increments and no GNSS. This checks every F entry that
//! matters over 20 s, every block's sign convention (F coupling, IMU correction, estimate
//! decay) and the discretisation, for the 21-state KF-GINS layout and the NBK layouts.

mod common_filter;

use common_filter::*;
use nalgebra::{SMatrix, Vector3};
use nav_core::config::{FilterConfig, ScaleFactorNoise, SensorNoise};
use nav_core::earth;
use nav_core::filter::{dcm_f64, Filter, InitialUncertainty};
use nav_core::model::discrete::{discretize, Accumulator};
use nav_core::model::{
    Block, BlockKind, Layout, Regressors, LAYOUT_KF_GINS, LAYOUT_NBK, LAYOUT_NBK_SINGLE,
};
use nav_core::nav::NavState;
use nav_core::types::ImuSample;

fn config() -> FilterConfig {
    // short correlation times so the estimate decay is visible within 20 s
    let accel = SensorNoise::isotropic(6e-9, 2e-11, 45.0, 3e-12, 1e-3);
    let gyro = SensorNoise::isotropic(5e-10, 1e-15, 60.0, 0.0, 1e-5);
    let mut c = FilterConfig::with_noise(accel, gyro);
    c.accel_scale = ScaleFactorNoise::from_ppm(500.0, 30.0);
    c.gyro_scale = ScaleFactorNoise::from_ppm(500.0, 30.0);
    c
}

fn unc() -> InitialUncertainty {
    InitialUncertainty {
        att_sigma_rad: [1e-3; 3],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    }
}

/// Error-state coordinates of `est` relative to `reference`: phi, dv, dr (NED m).
fn err9(est: &NavState, reference: &NavState) -> [f64; 9] {
    let (phi, dv, dr) = nav_errors(est, reference);
    [
        phi[0], phi[1], phi[2], dv[0], dv[1], dv[2], dr[0], dr[1], dr[2],
    ]
}

/// Runs the comparison for one layout; returns the worst normalised column mismatch.
fn check_layout<const N: usize>(layout: Layout, name: &str) -> f64 {
    let cfg = config();
    // raw increments of an error-free drive, starting 20 s into the profile (accelerating,
    // then turning at 0.12 rad/s)
    let mut sc = SimConfig::nbk(200.0);
    sc.truth = FilterConfig::with_noise(
        SensorNoise::isotropic(0.0, 0.0, 1.0, 0.0, 0.0),
        SensorNoise::isotropic(0.0, 0.0, 1.0, 0.0, 0.0),
    );
    sc.speed0_mps = 15.0;
    let mut sim = Sim::new(sc, 1);
    for _ in 0..(5 * 200) {
        sim.step();
    }
    let start = *sim.truth();
    let samples: Vec<ImuSample> = (0..(20 * 200)).map(|_| sim.step().imu).collect();

    // reference filter and the model's transition product along it
    let mut reference: Filter<f64, N> = Filter::new(layout, &cfg, start, &unc()).unwrap();
    let mut acc: Accumulator<f64, N> = Accumulator::default();
    let mut phi_total = SMatrix::<f64, N, N>::identity();
    for s in &samples {
        reference.propagate(s).unwrap();
        let st = *reference.last_step();
        let nav = *reference.nav_state();
        let c = dcm_f64(&nav.q_nb);
        let reg = Regressors {
            dt: st.dt_s,
            c_nb: c.transpose().into(),
            f_b: st.f_body_mps2.into(),
            omega_b: st.omega_ib_body_radps.into(),
            temperature_c: f64::NAN,
        };
        acc.add(&layout, &reg, st.dt_s, &st.f_ned_mps2.into());
        if reference.pending_prediction_s() == 0.0 {
            let d = discretize(&layout, &cfg, &nav, &acc);
            acc = Accumulator::default();
            let p = d.phi.to_dense();
            let m = SMatrix::<f64, N, N>::from_fn(|i, j| p[i][j]);
            phi_total = m * phi_total;
        }
    }
    assert_eq!(
        acc.epochs, 0,
        "20 s is a whole number of prediction intervals"
    );

    // finite differences, one state at a time
    let mut worst = 0.0f64;
    for j in 0..N {
        let mut init = start;
        let mut est_kind: Option<(BlockKind, usize, usize)> = None;
        let eps;
        match j {
            0..=2 => {
                eps = 1e-6;
                let mut phi = Vector3::zeros();
                phi[j] = eps;
                init.q_nb = nav_core::attitude::quat_from_rotvec(&(-phi)) * init.q_nb;
            }
            3..=5 => {
                eps = 1e-3;
                init.vel_ned_mps[j - 3] += eps;
            }
            6..=8 => {
                eps = 0.1;
                let mut d = Vector3::zeros();
                d[j - 6] = eps;
                init.pos = earth::displace(&init.pos, &d);
            }
            _ => {
                let (off, b) = layout
                    .iter()
                    .find(|(o, b)| j >= *o && j < o + b.dim())
                    .unwrap();
                eps = match b {
                    Block::GyroBias(_) => 1e-6,
                    Block::AccelBias(_) => 1e-4,
                    _ => 1e-4,
                };
                est_kind = Some((b.kind(), j - off, b.dim()));
            }
        }
        let mut f: Filter<f64, N> = Filter::new(layout, &cfg, init, &unc()).unwrap();
        if let Some((kind, k, dim)) = est_kind {
            let mut v = vec![0.0; dim];
            v[k] = eps;
            f.set_block_estimate(kind, &v).unwrap();
        }
        for s in &samples {
            f.propagate(s).unwrap();
        }
        let e = err9(f.nav_state(), reference.nav_state());
        // column j of the model vs the finite difference, core rows
        let mut col_fd = [0.0; 9];
        let mut col_m = [0.0; 9];
        for i in 0..9 {
            col_fd[i] = e[i] / eps;
            col_m[i] = phi_total[(i, j)];
        }
        // sensor-state row: the estimate's own decay
        if let Some((kind, k, _)) = est_kind {
            let est = f.block_estimate(kind).unwrap()[k];
            let decay_fd = est / eps;
            let decay_m = phi_total[(j, j)];
            assert!(
                (decay_fd - decay_m).abs() < 1e-9,
                "{name}: state {j} estimate decay {decay_fd} vs model {decay_m}"
            );
        }
        // normalise by the column's scale per row group (attitude, velocity, position)
        let mut col_worst = 0.0f64;
        for g in 0..3 {
            let r = 3 * g..3 * g + 3;
            let scale = r.clone().map(|i| col_fd[i].abs()).fold(0.0, f64::max);
            let diff = r.map(|i| (col_fd[i] - col_m[i]).abs()).fold(0.0, f64::max);
            // groups that stay (numerically) zero are compared absolutely
            let tiny = [1e-9, 1e-7, 1e-6][g];
            let rel = if scale > tiny {
                diff / scale
            } else {
                diff / tiny
            };
            col_worst = col_worst.max(rel);
        }
        println!(
            "{name} state {j:2}: fd [{}]\n              model [{}]  worst rel {col_worst:.2e}",
            col_fd
                .iter()
                .map(|v| format!("{v:10.3e}"))
                .collect::<Vec<_>>()
                .join(" "),
            col_m
                .iter()
                .map(|v| format!("{v:10.3e}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        worst = worst.max(col_worst);
    }
    worst
}

#[test]
fn transition_product_matches_finite_differences_of_the_mechanisation_kf_gins_21() {
    let w = check_layout::<{ LAYOUT_KF_GINS.dim() }>(LAYOUT_KF_GINS, "kf-gins-21");
    assert!(w < 0.01, "worst column mismatch {w}");
}

#[test]
fn transition_product_matches_finite_differences_of_the_mechanisation_nbk_18_and_single_15() {
    let w = check_layout::<{ LAYOUT_NBK.dim() }>(LAYOUT_NBK, "nbk-18");
    assert!(w < 0.01, "worst column mismatch {w}");
    let w = check_layout::<{ LAYOUT_NBK_SINGLE.dim() }>(LAYOUT_NBK_SINGLE, "nbk-single-15");
    assert!(w < 0.01, "worst column mismatch {w}");
}
