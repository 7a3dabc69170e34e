//! The `imu_clock_drift` and `gnss_position_gm` effect blocks, in f64 and f32:
//!
//! * propagation: the drift's offset `dt_0 + r (t - t_0)` grows by `r dt`, its states stay
//!   random constants; the GNSS Gauss-Markov estimate decays as `e^(-T/tau)` and its variance
//!   follows the exact discrete process `P' = phi^2 P + sigma^2 (1 - phi^2)`;
//! * measurement partials: the change of the GNSS innovation when one state's estimate is
//!   perturbed must equal `-H` times the perturbation (finite differences against the
//!   analytic columns: offset `v_ant + a tau`, rate `(v_ant + a tau)(t_fix - t_0)`, GNSS error
//!   `+I` on the position and nothing on the velocity), and the columns the filter's Jacobian
//!   code writes must be those.
#![allow(clippy::needless_range_loop)]
use nalgebra::Vector3;
use nav_core::config::{FilterConfig, SensorNoise};
use nav_core::filter::{dcm_f64, Filter, InitialUncertainty};
use nav_core::model::{Block, BlockKind, Layout, MeasContext, Rows3, LAYOUT_N};
use nav_core::scalar::Scalar;
use nav_core::strapdown::NavState;
use nav_core::types::{FixQuality, GnssFix, ImuSample};
use test_support::filter_sim::*;

const L: Layout = LAYOUT_N
    .with(Block::ImuClockDrift)
    .with(Block::GnssPositionGm);
const N: usize = L.dim();
const OFF_CLOCK: usize = 15;
const OFF_GM: usize = 17;

fn config() -> FilterConfig {
    let accel = SensorNoise::isotropic(6e-9, 0.0, 45.0, 3e-12, 1e-3);
    let gyro = SensorNoise::isotropic(5e-10, 0.0, 60.0, 0.0, 1e-5);
    let mut c = FilterConfig::with_noise(accel, gyro);
    c.lever_arm_body_m = [0.7, -0.4, -1.1];
    c.gating = nav_core::config::Gating::disabled();
    c.max_gnss_time_offset_s = 0.5;
    c.effects.gnss_position_gm.sigma_m = [0.3, 0.4, 0.8];
    c.effects.gnss_position_gm.t_s = 120.0;
    c
}

fn unc() -> InitialUncertainty {
    InitialUncertainty {
        att_sigma_rad: [1e-3; 3],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    }
}

/// 12 s of error-free increments of a turning, wobbling drive (20 s into the profile).
fn samples() -> (NavState, Vec<ImuSample>) {
    let mut sc = SimConfig::nbk(200.0);
    sc.truth = FilterConfig::with_noise(
        SensorNoise::isotropic(0.0, 0.0, 1.0, 0.0, 0.0),
        SensorNoise::isotropic(0.0, 0.0, 1.0, 0.0, 0.0),
    );
    sc.speed0_mps = 15.0;
    sc.wobble = true;
    let mut sim = Sim::new(sc, 1);
    for _ in 0..(5 * 200) {
        sim.step();
    }
    let start = *sim.truth();
    let v = (0..(12 * 200)).map(|_| sim.step().imu).collect();
    (start, v)
}

const DT0: f64 = 0.02;
const RATE: f64 = 4e-3;
const GM: [f64; 3] = [0.3, -0.2, 0.5];

/// A filter after `samples` at a non-zero operating point (offset 20 ms at the start, rate
/// 4000 ppm so that the offset is 68 ms after 12 s, GNSS error [0.3, -0.2, 0.5] m decaying
/// over the samples), with one estimate perturbed by `eps` after them.
fn filter_at<T: Scalar>(
    start: NavState,
    samples: &[ImuSample],
    velocity: bool,
    perturb: Option<(BlockKind, usize, f64)>,
) -> Filter<T, N> {
    let mut cfg = config();
    cfg.use_gnss_velocity = velocity;
    let mut f: Filter<T, N> = Filter::new(L, &cfg, start, &unc()).unwrap();
    f.set_block_estimate(BlockKind::TimeOffset, &[DT0, RATE])
        .unwrap();
    f.set_block_estimate(BlockKind::GnssPositionGm, &GM)
        .unwrap();
    for s in samples {
        f.propagate(s).unwrap();
    }
    // perturbed at the fix (the Gauss-Markov estimate decays over the samples)
    if let Some((k, i, eps)) = perturb {
        let mut v = f.block_estimate(k).unwrap().to_vec();
        v[i] += eps;
        f.set_block_estimate(k, &v).unwrap();
    }
    f
}

fn fix_at(nav: &NavState) -> GnssFix {
    GnssFix {
        t_s: nav.t_s + 0.03,
        lat_rad: nav.pos.lat_rad,
        lon_rad: nav.pos.lon_rad,
        h_m: nav.pos.h_m,
        pos_std_ned_m: [0.02, 0.02, 0.04],
        vel_ned_mps: nav.vel_ned_mps.into(),
        vel_std_ned_mps: [0.02, 0.02, 0.04],
        has_velocity: true,
        quality: FixQuality::RtkFixed,
        num_sats: 20,
    }
}

fn measurement_columns_match_finite_differences<T: Scalar>() {
    let (start, samples) = samples();
    let probe = filter_at::<T>(start, &samples, false, None);
    let nav = *probe.nav_state();
    let fix = fix_at(&nav);
    let span = fix.t_s - start.t_s;
    assert_eq!(probe.clock_ref_s(), start.t_s);
    // the offset at the fix time is dt_0 + r (t_fix - t_0)
    let dt_fix = DT0 + RATE * span;
    assert!((probe.time_offset_at_s(fix.t_s) - dt_fix).abs() < 1e-15);
    let c = dcm_f64(&nav.q_nb);
    let st = *probe.last_step();
    let w = st.omega_ib_body_radps;
    let l = Vector3::from(config().lever_arm_body_m);
    let tau = 0.03 + dt_fix;
    let acc = st.f_ned_mps2 + nav_core::earth::gravity_ned_mps2(nav.pos.lat_rad, nav.pos.h_m);
    let v_ant = nav.vel_ned_mps + c * w.cross(&l) + acc * tau;
    for velocity in [false, true] {
        let base = filter_at::<T>(start, &samples, velocity, None)
            .update_gnss(&fix)
            .unwrap()
            .innovation;
        for (k, i, eps) in [
            (BlockKind::TimeOffset, 0, 1e-4),
            (BlockKind::TimeOffset, 1, 1e-4 / span),
            (BlockKind::GnssPositionGm, 0, 1e-3),
            (BlockKind::GnssPositionGm, 1, 1e-3),
            (BlockKind::GnssPositionGm, 2, 1e-3),
        ] {
            let pert = filter_at::<T>(start, &samples, velocity, Some((k, i, eps)))
                .update_gnss(&fix)
                .unwrap()
                .innovation;
            // innovation = measured - predicted = -z: d(innovation) = -H d(x)
            let fd: Vec<f64> = (0..6).map(|r| -(pert[r] - base[r]) / eps).collect();
            let (hp, hv): (Vector3<f64>, Vector3<f64>) = match (k, i) {
                (BlockKind::TimeOffset, 0) => (v_ant, acc),
                (BlockKind::TimeOffset, _) => (v_ant * span, acc * span),
                _ => {
                    let mut e = Vector3::zeros();
                    e[i] = 1.0;
                    (e, Vector3::zeros())
                }
            };
            for r in 0..3 {
                let tol = 1e-3 * hp.norm() + 1e-6;
                assert!(
                    (fd[r] - hp[r]).abs() < tol,
                    "{k:?}[{i}] pos {r}: {} vs {}",
                    fd[r],
                    hp[r]
                );
                if velocity {
                    let tol = 1e-3 * hv.norm() + 1e-6;
                    assert!(
                        (fd[3 + r] - hv[r]).abs() < tol,
                        "{k:?}[{i}] vel {r}: {} vs {}",
                        fd[3 + r],
                        hv[r]
                    );
                }
            }
        }
    }
}

#[test]
fn measurement_columns_match_finite_differences_f64() {
    measurement_columns_match_finite_differences::<f64>();
}

#[test]
fn measurement_columns_match_finite_differences_f32() {
    measurement_columns_match_finite_differences::<f32>();
}

/// The columns the Jacobian code writes: the drift's rate column is its offset column times
/// `clock_span_s`, the GNSS error's position columns the identity, velocity columns zero.
fn jacobian_columns<T: Scalar>() {
    let ctx = MeasContext {
        c_l: [0.1, 0.2, 0.3],
        c_w_x_l: [0.01, -0.02, 0.03],
        c_lx: [[0.0; 3]; 3],
        omega_b_radps: [0.1, -0.05, 0.2],
        c_nb: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        f_b_mps2: [0.5, 0.2, -9.8],
        temperature_offset_c: f64::NAN,
        v_ant_ned_mps: [12.0, -3.0, 0.5],
        acc_ned_mps2: [1.5, 0.25, -0.125],
        bridge_s: 0.09,
        lever_bridge_s: 0.09,
        w_in_ned_radps: [5e-5, 0.0, -5e-5],
        f_ned_mps2: [1.5, 0.25, -9.9],
        clock_span_s: 250.0,
    };
    let mut hp = [[T::ZERO; N]; 3];
    let mut hv = [[T::ZERO; N]; 3];
    {
        let (mut p, mut v) = (Rows3::new(&mut hp), Rows3::new(&mut hv));
        for (off, b) in L.iter() {
            b.gnss_jacobian(off, &ctx, &mut p, &mut v);
        }
    }
    for r in 0..3 {
        let (va, a) = (ctx.v_ant_ned_mps[r], ctx.acc_ned_mps2[r]);
        assert_eq!(hp[r][OFF_CLOCK].to_f64(), T::of_f64(va).to_f64());
        assert_eq!(hv[r][OFF_CLOCK].to_f64(), T::of_f64(a).to_f64());
        assert_eq!(
            hp[r][OFF_CLOCK + 1].to_f64(),
            T::of_f64(va * 250.0).to_f64()
        );
        assert_eq!(hv[r][OFF_CLOCK + 1].to_f64(), T::of_f64(a * 250.0).to_f64());
        for j in 0..3 {
            let want = if r == j { 1.0 } else { 0.0 };
            assert_eq!(hp[r][OFF_GM + j].to_f64(), want);
            assert_eq!(hv[r][OFF_GM + j].to_f64(), 0.0);
        }
    }
}

#[test]
fn jacobian_columns_f64_and_f32() {
    jacobian_columns::<f64>();
    jacobian_columns::<f32>();
}

/// Propagation over 60 s of a standing IMU (no fixes): the drift's offset grows by r dt with
/// both states' variances unchanged (random constants), the GNSS error's estimate decays with
/// `e^(-T/tau)` and its variance follows `phi^2 P + sigma^2 (1 - phi^2)` from the prior.
fn propagation<T: Scalar>(rel_tol: f64) {
    let cfg = config();
    let start = initial_truth(0.0);
    let mut f: Filter<T, N> = Filter::new(L, &cfg, start, &unc()).unwrap();
    f.set_block_estimate(BlockKind::TimeOffset, &[DT0, RATE])
        .unwrap();
    f.set_block_estimate(BlockKind::GnssPositionGm, &GM)
        .unwrap();
    // halve the GNSS error variance, to see it grow back towards sigma^2
    let p0 = f.state_std();
    let dt = 0.01;
    let g = nav_core::earth::gravity_ned_mps2(start.pos.lat_rad, start.pos.h_m);
    let (secs, n) = (60.0, 6000);
    for k in 0..n {
        f.propagate(&ImuSample {
            t_s: start.t_s + (k + 1) as f64 * dt,
            dtheta_rad: [0.0; 3],
            dv_mps: [0.0, 0.0, -g.z * dt],
            temperature_c: f64::NAN,
        })
        .unwrap();
    }
    f.predict_covariance().unwrap();
    let t = f.nav_state().t_s;
    assert!((t - start.t_s - secs).abs() < 1e-6);
    let off = f.time_offset_s();
    let want = DT0 + RATE * secs;
    assert!((off - want).abs() < 1e-12, "offset {off} vs {want}");
    let est = f.block_estimate(BlockKind::TimeOffset).unwrap();
    assert_eq!(est, &[DT0, RATE]);
    let s = f.state_std();
    for i in [OFF_CLOCK, OFF_CLOCK + 1] {
        assert!(
            (s[i] - p0[i]).abs() <= rel_tol * p0[i],
            "{i}: {} {}",
            s[i],
            p0[i]
        );
    }
    let phi = (-secs / cfg.effects.gnss_position_gm.t_s).exp();
    let e = f.gnss_position_error_ned_m().unwrap();
    for j in 0..3 {
        let want = GM[j] * phi;
        assert!(
            (e[j] - want).abs() <= rel_tol * want.abs(),
            "gm {j}: {} vs {want}",
            e[j]
        );
        // started at the stationary variance: stays there
        let sg = cfg.effects.gnss_position_gm.sigma_m[j];
        assert!(
            (s[OFF_GM + j] - sg).abs() <= rel_tol * sg,
            "{}",
            s[OFF_GM + j]
        );
    }
}

#[test]
fn propagation_f64() {
    propagation::<f64>(1e-9);
}

#[test]
fn propagation_f32() {
    propagation::<f32>(2e-4);
}

#[test]
fn gnss_gauss_markov_discretisation_is_exact_from_any_variance() {
    // P' = phi^2 P + q with q = sigma^2 (1 - phi^2) over one interval (f64 and f32)
    let cfg = config();
    let (mut f, mut p, mut q) = ([0.0; 3], [0.0; 3], [0.0; 3]);
    Block::GnssPositionGm.discretize(&cfg, 0.5, &mut f, &mut p, &mut q);
    let (mut f32_, mut p32, mut q32) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 3]);
    Block::GnssPositionGm.discretize(&cfg, 0.5f32, &mut f32_, &mut p32, &mut q32);
    let e = (-0.5f64 / 120.0).exp();
    for j in 0..3 {
        let s = cfg.effects.gnss_position_gm.sigma_m[j];
        assert!((p[j] - e).abs() < 1e-15);
        assert!((f[j] + 0.5 / 120.0).abs() < 1e-15);
        assert!((q[j] - s * s * (1.0 - e * e)).abs() < 1e-12 * q[j]);
        assert!((f64::from(p32[j]) - e).abs() < 1e-6);
        assert!((f64::from(q32[j]) - s * s * (1.0 - e * e)).abs() < 1e-5 * q[j]);
    }
    // the clock drift: two random walks with the configured PSDs
    let mut c2 = cfg;
    c2.effects.time_offset.rw_psd = 1e-8;
    c2.effects.imu_clock_drift.rw_psd = 1e-14;
    let (mut f, mut p, mut q) = ([9.0f64; 2], [9.0f64; 2], [9.0f64; 2]);
    Block::ImuClockDrift.discretize(&c2, 0.5, &mut f, &mut p, &mut q);
    assert_eq!((f, p), ([0.0; 2], [1.0; 2]));
    assert!((q[0] - 0.5e-8).abs() < 1e-22 && (q[1] - 0.5e-14).abs() < 1e-28);
    let mut v = [0.0; 5];
    Block::ImuClockDrift.initial_variance(&c2, &mut v);
    assert_eq!(v[..2], [0.1 * 0.1, 1e-4 * 1e-4]);
    Block::GnssPositionGm.initial_variance(&c2, &mut v);
    assert_eq!(v[..3], [0.3f64 * 0.3, 0.4 * 0.4, 0.8 * 0.8]);
}

#[test]
fn drift_replaces_the_time_offset_and_names_are_the_vocabulary() {
    assert_eq!(
        LAYOUT_N
            .with(Block::TimeOffset)
            .with(Block::ImuClockDrift)
            .validate(LAYOUT_N.dim() + 3),
        Err(nav_core::model::LayoutError::DuplicateKind)
    );
    assert_eq!(
        Block::effect_from_name("imu_clock_drift"),
        Some(Block::ImuClockDrift)
    );
    assert_eq!(
        Block::effect_from_name("gnss_position_gm"),
        Some(Block::GnssPositionGm)
    );
    assert_eq!(Block::ImuClockDrift.dim(), 2);
    assert_eq!(Block::GnssPositionGm.dim(), 3);
}
