//! The effect blocks' linearised models against the nonlinear filter:
//!
//! * F coupling of the IMU-correction blocks (misalignments, temperature coefficients,
//!   g-sensitivity, scale factors): over 20 s of a turning, accelerating, rolling and pitching
//!   200 Hz drive with a temperature ramp, the product of the filter's transition matrices
//!   must match finite differences of two filters' nominal trajectories, one started with a
//!   small estimate in one effect state (the same check `filter_error_model` does for the base
//!   layouts). This checks the sign of every coupling, the IMU correction and the regressors.
//! * GNSS measurement columns of the lever-arm and time-offset blocks (and the gyro blocks'
//!   lever-arm velocity terms): the change of the innovation when one state's estimate is
//!   perturbed must equal `-H` times the perturbation, for position and velocity updates.

use nalgebra::Vector3;
use nav_core::config::{FilterConfig, ScaleFactorNoise, SensorNoise};
use nav_core::filter::{dcm_f64, Filter, InitialUncertainty};
use nav_core::model::{Block, BlockKind, Layout, LAYOUT_N};
use nav_core::strapdown::NavState;
use nav_core::types::ImuSample;
use test_support::filter_sim::*;
use test_support::transition::{err9, TransitionRun};

const T_REF_C: f64 = 25.0;

fn config() -> FilterConfig {
    let accel = SensorNoise::isotropic(6e-9, 0.0, 45.0, 3e-12, 1e-3);
    let gyro = SensorNoise::isotropic(5e-10, 0.0, 60.0, 0.0, 1e-5);
    let mut c = FilterConfig::with_noise(accel, gyro);
    c.accel_scale = ScaleFactorNoise::from_ppm(500.0, 1e6);
    c.gyro_scale = ScaleFactorNoise::from_ppm(500.0, 1e6);
    c.effects.temperature_ref_c = Some(T_REF_C);
    c
}

fn unc() -> InitialUncertainty {
    InitialUncertainty {
        att_sigma_rad: [1e-3; 3],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    }
}

/// 20 s of error-free increments of a wobbling drive (starting 20 s into the profile), with a
/// temperature ramp of 0.4 degC/s from 22 degC (so the regressor changes sign).
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
    let v = (0..(20 * 200))
        .map(|k| {
            let mut s = sim.step().imu;
            s.temperature_c = 22.0 + 0.4 * (k as f64 + 1.0) / 200.0;
            s
        })
        .collect();
    (start, v)
}

fn eps_of(b: Block) -> f64 {
    match b {
        Block::AccelMisalignment | Block::GyroMisalignment => 1e-4,
        Block::AccelScaleFactor | Block::GyroScaleFactor => 1e-4,
        Block::AccelTemperatureBias => 1e-5,
        Block::GyroTemperatureBias => 1e-7,
        Block::GyroGSensitivity => 1e-6,
        _ => 1e-4,
    }
}

/// Worst normalised column mismatch over the effect states of `layout`.
fn check_layout<const N: usize>(layout: Layout, name: &str) -> f64 {
    let cfg = config();
    let (start, samples) = samples();
    let unc = unc();
    let run = TransitionRun::<N>::new(layout, &cfg, &unc, start, &samples, Some(T_REF_C));
    let mut worst = 0.0f64;
    for j in LAYOUT_N.dim()..N {
        let (_, b) = layout
            .iter()
            .find(|(o, b)| j >= *o && j < o + b.dim())
            .unwrap();
        let c = run.check_column(j, eps_of(b), &format!("{name} {}", b.name()));
        // every effect state must actually move the solution on this drive
        assert!(c.moves, "{name}: state {j} ({}) has no effect", b.name());
        worst = worst.max(c.worst_rel);
    }
    worst
}

const L_GYRO: Layout = LAYOUT_N
    .with(Block::GyroMisalignment)
    .with(Block::GyroTemperatureBias)
    .with(Block::GyroGSensitivity)
    .with(Block::GyroScaleFactor);
const L_ACCEL: Layout = LAYOUT_N
    .with(Block::AccelMisalignment)
    .with(Block::AccelTemperatureBias)
    .with(Block::AccelScaleFactor);

#[test]
fn transition_product_matches_finite_differences_for_the_gyro_effect_blocks() {
    let w = check_layout::<{ L_GYRO.dim() }>(L_GYRO, "gyro-effects");
    assert!(w < 0.01, "worst column mismatch {w}");
}

#[test]
fn transition_product_matches_finite_differences_for_the_accel_effect_blocks() {
    let w = check_layout::<{ L_ACCEL.dim() }>(L_ACCEL, "accel-effects");
    assert!(w < 0.01, "worst column mismatch {w}");
}

const L_MEAS: Layout = LAYOUT_N.with(Block::LeverArm).with(Block::TimeOffset);
const NM: usize = L_MEAS.dim();

fn meas_config(velocity: bool) -> FilterConfig {
    let mut cfg = config();
    cfg.lever_arm_body_m = [0.7, -0.4, -1.1];
    cfg.use_gnss_velocity = velocity;
    cfg.gating = nav_core::config::Gating::disabled();
    cfg.max_gnss_time_offset_s = 0.5;
    cfg
}

/// A filter after `samples` at a non-zero operating point (lever-arm correction
/// [0.2, 0.1, -0.3] m, time offset 60 ms), with one estimate perturbed by `eps`.
fn filter_at(
    start: NavState,
    samples: &[ImuSample],
    velocity: bool,
    perturb: Option<(Block, usize, f64)>,
) -> Filter<f64, NM> {
    let mut f: Filter<f64, NM> =
        Filter::new(L_MEAS, &meas_config(velocity), start, &unc()).unwrap();
    f.set_block_estimate(BlockKind::LeverArm, &[0.2, 0.1, -0.3])
        .unwrap();
    f.set_block_estimate(BlockKind::TimeOffset, &[0.06])
        .unwrap();
    if let Some((b, k, eps)) = perturb {
        let mut v = f.block_estimate(b.kind()).unwrap().to_vec();
        v[k] += eps;
        f.set_block_estimate(b.kind(), &v).unwrap();
    }
    for s in samples {
        f.propagate(s).unwrap();
    }
    f
}

#[test]
fn gnss_measurement_columns_of_lever_arm_and_time_offset_match_finite_differences() {
    let (start, samples) = samples();
    // 12 s into the window: turning, rolling and pitching
    let samples = &samples[..12 * 200];
    let probe = filter_at(start, samples, false, None);
    let nav = *probe.nav_state();
    // a fix 30 ms after the filter epoch, at the solution
    let fix = nav_core::types::GnssFix {
        t_s: nav.t_s + 0.03,
        lat_rad: nav.pos.lat_rad,
        lon_rad: nav.pos.lon_rad,
        h_m: nav.pos.h_m,
        pos_std_ned_m: [0.02, 0.02, 0.04],
        vel_ned_mps: nav.vel_ned_mps.into(),
        vel_std_ned_mps: [0.02, 0.02, 0.04],
        has_velocity: true,
        quality: nav_core::types::FixQuality::RtkFixed,
        num_sats: 20,
    };
    // analytic columns at the operating point: lever arm dz_pos = C e_k + tau C (w x e_k) (the
    // antenna velocity bridges tau), dz_vel = C (w x e_k) - w_in x (C e_k);
    // time offset dz_pos = d/d(dt) [v_ant tau + a tau^2 / 2] = v_ant + a tau, dz_vel = a
    let c = dcm_f64(&nav.q_nb);
    let st = *probe.last_step();
    let w = st.omega_ib_body_radps;
    let l = Vector3::new(0.9, -0.3, -1.4);
    let tau = 0.03 + 0.06;
    let w_in = nav_core::earth::earth_rate_ned_radps(nav.pos.lat_rad)
        + nav_core::earth::transport_rate_ned_radps(nav.pos.lat_rad, nav.pos.h_m, &nav.vel_ned_mps);
    let acc = st.f_ned_mps2 + nav_core::earth::gravity_ned_mps2(nav.pos.lat_rad, nav.pos.h_m);
    for velocity in [false, true] {
        let base = filter_at(start, samples, velocity, None)
            .update_gnss(&fix)
            .unwrap()
            .innovation;
        for (b, k, eps) in [
            (Block::LeverArm, 0, 1e-3),
            (Block::LeverArm, 1, 1e-3),
            (Block::LeverArm, 2, 1e-3),
            (Block::TimeOffset, 0, 1e-4),
        ] {
            let pert = filter_at(start, samples, velocity, Some((b, k, eps)))
                .update_gnss(&fix)
                .unwrap()
                .innovation;
            // innovation = measured - predicted = -(z): d(innovation) = -H d(x)
            let fd: Vec<f64> = (0..6).map(|i| -(pert[i] - base[i]) / eps).collect();
            let (hp, hv): (Vector3<f64>, Vector3<f64>) = match b {
                Block::LeverArm => {
                    let mut e = Vector3::zeros();
                    e[k] = 1.0;
                    let ce = c * e;
                    (
                        ce + c * w.cross(&e) * tau,
                        c * w.cross(&e) - w_in.cross(&ce),
                    )
                }
                _ => (nav.vel_ned_mps + c * w.cross(&l) + acc * tau, acc),
            };
            println!(
                "{} [{k}] velocity update {velocity}: fd {:?}\n   analytic pos {:?} vel {:?}",
                b.name(),
                fd.iter().map(|v| format!("{v:.6}")).collect::<Vec<_>>(),
                hp.as_slice(),
                hv.as_slice()
            );
            for i in 0..3 {
                let tol = 1e-3 * hp.norm() + 1e-6;
                assert!(
                    (fd[i] - hp[i]).abs() < tol,
                    "{} pos {i}: {} vs {}",
                    b.name(),
                    fd[i],
                    hp[i]
                );
                if velocity {
                    let tol = 1e-3 * hv.norm() + 1e-6;
                    assert!(
                        (fd[3 + i] - hv[i]).abs() < tol,
                        "{} vel {i}: {} vs {}",
                        b.name(),
                        fd[3 + i],
                        hv[i]
                    );
                }
            }
        }
    }
}

#[test]
fn time_offset_bridge_core_columns_match_finite_differences_of_the_innovation() {
    // with a time offset the fix is predicted tau = t_fix + dt_hat - t ahead with the antenna
    // velocity and the acceleration: the attitude, velocity and position columns change too
    let (start, samples) = samples();
    let samples = &samples[..12 * 200];
    let reference = filter_at(start, samples, false, None);
    let nav = *reference.nav_state();
    let fix = nav_core::types::GnssFix {
        t_s: nav.t_s + 0.03,
        lat_rad: nav.pos.lat_rad,
        lon_rad: nav.pos.lon_rad,
        h_m: nav.pos.h_m,
        pos_std_ned_m: [0.02, 0.02, 0.04],
        vel_ned_mps: nav.vel_ned_mps.into(),
        vel_std_ned_mps: [0.02, 0.02, 0.04],
        has_velocity: true,
        quality: nav_core::types::FixQuality::RtkFixed,
        num_sats: 20,
    };
    let c = dcm_f64(&nav.q_nb);
    let st = *reference.last_step();
    let l = Vector3::new(0.9, -0.3, -1.4);
    let tau = 0.03 + 0.06;
    let skew = |v: Vector3<f64>| v.cross_matrix();
    let cwl = c * st.omega_ib_body_radps.cross(&l);
    let h_pos_phi = skew(c * l) + skew(cwl) * tau + skew(st.f_ned_mps2) * (0.5 * tau * tau);
    let h_vel_phi = skew(cwl) + skew(st.f_ned_mps2) * tau;
    for velocity in [false, true] {
        let base = filter_at(start, samples, velocity, None)
            .update_gnss(&fix)
            .unwrap()
            .innovation;
        for j in 0..9 {
            let mut init = start;
            match j {
                0..=2 => {
                    let mut phi = Vector3::zeros();
                    phi[j] = 1e-4;
                    init.q_nb = nav_core::attitude::quat_from_rotvec(&(-phi)) * init.q_nb;
                }
                3..=5 => init.vel_ned_mps[j - 3] += 1e-2,
                _ => {
                    let mut d = Vector3::zeros();
                    d[j - 6] = 0.1;
                    init.pos = nav_core::earth::displace(&init.pos, &d);
                }
            }
            let mut f = filter_at(init, samples, velocity, None);
            let e = err9(f.nav_state(), &nav);
            let (phi, dv, dr) = (
                Vector3::new(e[0], e[1], e[2]),
                Vector3::new(e[3], e[4], e[5]),
                Vector3::new(e[6], e[7], e[8]),
            );
            let pert = f.update_gnss(&fix).unwrap().innovation;
            let want_p = -(h_pos_phi * phi + dv * tau + dr);
            let want_v = -(h_vel_phi * phi + dv);
            let scale_p = want_p.norm();
            let scale_v = want_v.norm();
            println!(
                "state {j} velocity update {velocity}: d(innovation) pos [{:.3e} {:.3e} {:.3e}] vs H dx [{:.3e} {:.3e} {:.3e}]",
                pert[0] - base[0],
                pert[1] - base[1],
                pert[2] - base[2],
                want_p[0],
                want_p[1],
                want_p[2]
            );
            for i in 0..3 {
                let dp = pert[i] - base[i];
                assert!(
                    (dp - want_p[i]).abs() < 2e-3 * scale_p + 1e-9,
                    "state {j} pos {i}: {dp:e} vs {:e}",
                    want_p[i]
                );
                if velocity {
                    let dvel = pert[3 + i] - base[3 + i];
                    assert!(
                        // + the neglected height slope of gravity in a tau (3e-8 m/s here)
                        (dvel - want_v[i]).abs() < 2e-3 * scale_v + 1e-7,
                        "state {j} vel {i}: {dvel:e} vs {:e}",
                        want_v[i]
                    );
                }
            }
        }
    }
}
