//! The cross-platform self-test: fixed inputs run through the core's code, producing a vector
//! of `f64` outputs. The host computes it once and checks the result into the firmware
//! (`firmware/src/expected.rs`, written by `cargo xtask gen-vectors`); the firmware computes
//! it again on the MCU and compares, so any difference between the two builds of the same code
//! is caught. Add a case by appending to [`CASES`] and to [`compute`]; the vector grows with the
//! core.

use crate::config::{units, FilterConfig};
use crate::earth;
use crate::filter::{Filter, InitialUncertainty};
use crate::model::{Block, BlockKind, Layout, LAYOUT_KF_GINS, LAYOUT_NBK};
use crate::scalar::Scalar;
use crate::strapdown::NavState;
use crate::types::{FixQuality, GnssFix, ImuSample};

/// Names of the self-test cases and how many `f64` outputs each produces, in output order.
pub const CASES: &[(&str, usize)] = &[
    ("earth::gravity_mps2 at 5 latitudes x 2 heights", 10),
    ("earth::radii at 5 latitudes", 10),
    ("earth::geodetic->ecef->geodetic round trip, 3 points", 9),
    ("earth::transport_rate_ned_radps, 2 velocities", 6),
    (
        "filter f64 NBK-18: 3 s at 100 Hz, 3 position+velocity fixes (state, sigmas, biases, NIS)",
        FILTER_CASE_OUTPUTS,
    ),
    (
        "filter f32 KF-GINS-21: 3 s at 100 Hz, 3 position fixes (state, sigmas, biases, NIS)",
        FILTER_CASE_OUTPUTS,
    ),
    (
        "config: datasheet-unit conversions of the source's table",
        5,
    ),
    (
        "filter f32 NBK-18 + lever_arm, time_offset, gyro_misalignment, accel_temperature_bias, gyro_g_sensitivity (34 states): 3 s at 100 Hz with a temperature ramp, 3 late position+velocity fixes (state, effect estimates, NIS)",
        EFFECTS_CASE_OUTPUTS,
    ),
];

/// The effect-block layout of the self-test (34 states).
const EFFECTS_LAYOUT: Layout = LAYOUT_NBK
    .with(Block::LeverArm)
    .with(Block::TimeOffset)
    .with(Block::GyroMisalignment)
    .with(Block::AccelTemperatureBias)
    .with(Block::GyroGSensitivity);

/// Outputs of the effects case: lat, lon, h, velocity (3), roll/pitch/yaw (3), the 16 effect
/// estimates (lever arm 3, time offset 1, gyro misalignment 6, accelerometer temperature
/// coefficient 3, g-sensitivity 3), the last NIS, the accepted-fix count.
const EFFECTS_CASE_OUTPUTS: usize = 27;

/// Outputs of one filter case: lat, lon, h, velocity (3), roll/pitch/yaw (3), the 9 core
/// sigmas, the accelerometer bias estimate (3), the last NIS, the accepted-fix count.
const FILTER_CASE_OUTPUTS: usize = 23;

/// Total number of outputs of [`compute`].
#[allow(clippy::indexing_slicing)] // const evaluation: an out-of-range index fails the build
pub const N_OUTPUTS: usize = {
    let mut n = 0;
    let mut i = 0;
    while i < CASES.len() {
        n += CASES[i].1;
        i += 1;
    }
    n
};

/// Runs every case and writes the outputs into `out` in order. Returns the number written
/// (fewer than [`N_OUTPUTS`] only if `out` is too short).
pub fn compute(out: &mut [f64]) -> usize {
    let mut w = Writer { out, n: 0 };
    let lats_deg = [-60.0, -12.5, 0.0, 40.097, 78.9];
    for lat in lats_deg {
        for h in [0.0, 1601.0] {
            w.push(earth::gravity_mps2(lat * core::f64::consts::PI / 180.0, h));
        }
    }
    for lat in lats_deg {
        let r = earth::radii(lat * core::f64::consts::PI / 180.0);
        w.push(r.meridian_m);
        w.push(r.transverse_m);
    }
    for (lat, lon, h) in [
        (40.097, -105.147, 1601.0),
        (-33.9, 151.2, -30.0),
        (89.9, 10.0, 5e3),
    ] {
        let p = earth::Llh::from_deg(lat, lon, h);
        let q = earth::ecef_to_geodetic(&earth::geodetic_to_ecef_m(&p));
        w.push(q.lat_rad);
        w.push(q.lon_rad);
        w.push(q.h_m);
    }
    for v in [[10.0, -3.0, 0.2], [-25.0, 14.0, -1.0]] {
        let r = earth::transport_rate_ned_radps(0.7, 250.0, &nalgebra::Vector3::from(v));
        w.push(r.x);
        w.push(r.y);
        w.push(r.z);
    }
    filter_case::<f64, { LAYOUT_NBK.dim() }>(LAYOUT_NBK, true, &mut w);
    filter_case::<f32, { LAYOUT_KF_GINS.dim() }>(LAYOUT_KF_GINS, false, &mut w);
    w.push(units::accel_ug_per_sqrt_hz_from_psd(6.2865e-9));
    w.push(units::accel_ug_per_sqrt_h_from_rw_psd(2.6731e-12));
    w.push(units::gyro_deg_per_sqrt_h_from_psd(5.3079e-10));
    w.push(units::ug_from_mps2(units::flicker_b_from_gm(
        2.4360e-11, 45.0,
    )));
    w.push(units::accel_psd_from_ug_per_sqrt_hz(50.0));
    effects_case::<f32, { EFFECTS_LAYOUT.dim() }>(EFFECTS_LAYOUT, &mut w);
    w.n
}

/// A deterministic 3-second f32 run with effect blocks: non-zero starting effect estimates (the
/// general IMU correction runs), a temperature ramp, fixes 40 ms late against their tag
/// (bridged through the time-offset block) with position and velocity.
fn effects_case<T: Scalar, const N: usize>(layout: Layout, w: &mut Writer<'_>) {
    let init = NavState {
        t_s: 1000.0,
        pos: earth::Llh::from_deg(47.1, 15.4, 350.0),
        vel_ned_mps: nalgebra::Vector3::new(6.0, -3.0, 0.1),
        q_nb: crate::attitude::quat_from_euler_zyx([0.02, 0.01, -0.4]),
    };
    let unc = InitialUncertainty {
        att_sigma_rad: [1e-3, 1e-3, 5e-3],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    };
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = [0.4, 0.2, -1.0];
    cfg.use_gnss_velocity = true;
    cfg.effects.temperature_ref_c = Some(20.0);
    let Ok(mut f) = Filter::<T, N>::new(layout, &cfg, init, &unc) else {
        (0..EFFECTS_CASE_OUTPUTS).for_each(|_| w.push(f64::NAN));
        return;
    };
    let start: [(BlockKind, &[f64]); 5] = [
        (BlockKind::LeverArm, &[0.1, -0.05, 0.2]),
        (BlockKind::TimeOffset, &[0.03]),
        (
            BlockKind::GyroMisalignment,
            &[2e-4, -3e-4, 1e-4, 4e-4, -2e-4, 3e-4],
        ),
        (BlockKind::AccelTemperatureBias, &[3e-4, -2e-4, 4e-4]),
        (BlockKind::GyroGSensitivity, &[2e-6, -1e-6, 5e-7]),
    ];
    for (k, v) in start {
        if f.set_block_estimate(k, v).is_err() {
            (0..EFFECTS_CASE_OUTPUTS).for_each(|_| w.push(f64::NAN));
            return;
        }
    }
    let dt = 0.01;
    let mut nis = f64::NAN;
    for k in 1..=300u32 {
        let a = ((k * 7) % 13) as f64 - 6.0;
        let b = ((k * 5) % 11) as f64 - 5.0;
        let imu = ImuSample {
            t_s: 1000.0 + k as f64 * dt,
            dtheta_rad: [
                (2e-3 + 1e-4 * a) * dt,
                (-1e-3 + 1e-4 * b) * dt,
                (-0.08 + 1e-4 * a) * dt,
            ],
            dv_mps: [
                (0.5 + 0.01 * b) * dt,
                (0.4 + 0.01 * a) * dt,
                (-9.8 + 0.005 * b) * dt,
            ],
            temperature_c: 21.0 + 0.02 * k as f64,
        };
        if f.propagate(&imu).is_err() {
            nis = f64::INFINITY;
        }
        if k % 100 == 0 {
            let s = *f.nav_state();
            let c = crate::filter::dcm_f64(&s.q_nb);
            let l = nalgebra::Vector3::from(f.lever_arm_body_m());
            let p = earth::displace(
                &s.pos,
                &(c * l + nalgebra::Vector3::new(0.02 * a, -0.01 * b, 0.004 * a)),
            );
            let v = s.vel_ned_mps
                + c * f.last_step().omega_ib_body_radps.cross(&l)
                + nalgebra::Vector3::new(0.003 * b, -0.002 * a, 0.0);
            let fix = GnssFix {
                t_s: s.t_s - 0.04,
                lat_rad: p.lat_rad,
                lon_rad: p.lon_rad,
                h_m: p.h_m,
                pos_std_ned_m: [0.05, 0.05, 0.1],
                vel_ned_mps: v.into(),
                vel_std_ned_mps: [0.05, 0.05, 0.1],
                has_velocity: true,
                quality: FixQuality::RtkFixed,
                num_sats: 12,
            };
            nis = match f.update_gnss(&fix) {
                Ok(o) => o.nis,
                Err(_) => f64::INFINITY,
            };
        }
    }
    let sol = f.solution();
    w.push(sol.lat_rad);
    w.push(sol.lon_rad);
    w.push(sol.h_m);
    sol.vel_ned_mps.iter().for_each(|v| w.push(*v));
    sol.rpy_rad.iter().for_each(|v| w.push(*v));
    for (k, _) in start {
        match f.block_estimate(k) {
            Some(e) => e.iter().for_each(|v| w.push(*v)),
            None => w.push(f64::NAN),
        }
    }
    w.push(nis);
    w.push(f.counters().gnss_accepted as f64);
}

/// A deterministic 3-second run of the filter (no random numbers: increments and fixes follow
/// fixed patterns), exercising mechanisation, error-model accumulation, the 10 Hz covariance
/// prediction, gated Joseph updates with a lever arm, feedback and the accessors.
fn filter_case<T: Scalar, const N: usize>(layout: Layout, velocity: bool, w: &mut Writer<'_>) {
    let init = NavState {
        t_s: 1000.0,
        pos: earth::Llh::from_deg(47.1, 15.4, 350.0),
        vel_ned_mps: nalgebra::Vector3::new(5.0, 2.0, 0.0),
        q_nb: crate::attitude::quat_from_euler_zyx([0.01, -0.02, 0.5]),
    };
    let unc = InitialUncertainty {
        att_sigma_rad: [1e-3, 1e-3, 5e-3],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    };
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = [0.5, -0.3, -1.2];
    cfg.use_gnss_velocity = velocity;
    let Ok(mut f) = Filter::<T, N>::new(layout, &cfg, init, &unc) else {
        (0..FILTER_CASE_OUTPUTS).for_each(|_| w.push(f64::NAN));
        return;
    };
    let dt = 0.01;
    let mut nis = f64::NAN;
    for k in 1..=300u32 {
        let a = ((k * 7) % 13) as f64 - 6.0;
        let b = ((k * 5) % 11) as f64 - 5.0;
        let imu = ImuSample {
            t_s: 1000.0 + k as f64 * dt,
            dtheta_rad: [
                (1e-4 + 1e-5 * a) * dt,
                (-2e-4 + 1e-5 * b) * dt,
                (0.05 + 1e-4 * a) * dt,
            ],
            dv_mps: [
                (0.3 + 0.01 * b) * dt,
                (-0.1 + 0.01 * a) * dt,
                (-9.81 + 0.005 * b) * dt,
            ],
            temperature_c: f64::NAN,
        };
        if f.propagate(&imu).is_err() {
            nis = f64::INFINITY;
        }
        if k % 100 == 0 {
            // the antenna as the filter predicts it, offset by a few centimetres
            let s = *f.nav_state();
            let c = crate::filter::dcm_f64(&s.q_nb);
            let l = nalgebra::Vector3::from(cfg.lever_arm_body_m);
            let p = earth::displace(
                &s.pos,
                &(c * l + nalgebra::Vector3::new(0.01 * a, -0.005 * b, 0.002 * a)),
            );
            let v = s.vel_ned_mps
                + c * f.last_step().omega_ib_body_radps.cross(&l)
                + nalgebra::Vector3::new(0.002 * b, 0.0, -0.002 * a);
            let fix = GnssFix {
                t_s: s.t_s,
                lat_rad: p.lat_rad,
                lon_rad: p.lon_rad,
                h_m: p.h_m,
                pos_std_ned_m: [0.05, 0.05, 0.1],
                vel_ned_mps: v.into(),
                vel_std_ned_mps: [0.05, 0.05, 0.1],
                has_velocity: true,
                quality: FixQuality::RtkFixed,
                num_sats: 12,
            };
            nis = match f.update_gnss(&fix) {
                Ok(o) => o.nis,
                Err(_) => f64::INFINITY,
            };
        }
    }
    let sol = f.solution();
    w.push(sol.lat_rad);
    w.push(sol.lon_rad);
    w.push(sol.h_m);
    sol.vel_ned_mps.iter().for_each(|v| w.push(*v));
    sol.rpy_rad.iter().for_each(|v| w.push(*v));
    f.state_std().iter().take(9).for_each(|v| w.push(*v));
    match f.imu_error(BlockKind::AccelBias) {
        Some((b, _)) => b.iter().for_each(|v| w.push(*v)),
        None => (0..3).for_each(|_| w.push(f64::NAN)),
    }
    w.push(nis);
    w.push(f.counters().gnss_accepted as f64);
}

struct Writer<'a> {
    out: &'a mut [f64],
    n: usize,
}

impl Writer<'_> {
    fn push(&mut self, v: f64) {
        if let Some(slot) = self.out.get_mut(self.n) {
            *slot = v;
            self.n += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compute_fills_exactly_n_outputs_and_all_are_finite() {
        let mut out = [f64::NAN; N_OUTPUTS + 4];
        assert_eq!(compute(&mut out), N_OUTPUTS);
        assert!(out[..N_OUTPUTS].iter().all(|v| v.is_finite()));
        assert!(out[N_OUTPUTS..].iter().all(|v| v.is_nan()));
    }

    #[test]
    fn filter_cases_accept_all_fixes_and_stay_near_the_fixes() {
        let mut out = [f64::NAN; N_OUTPUTS];
        compute(&mut out);
        let base = N_OUTPUTS - EFFECTS_CASE_OUTPUTS - 5 - 2 * FILTER_CASE_OUTPUTS;
        for c in 0..2 {
            let o = &out[base + c * FILTER_CASE_OUTPUTS..base + (c + 1) * FILTER_CASE_OUTPUTS];
            assert_eq!(o[22], 3.0, "case {c}: accepted fixes");
            assert!(o[21] > 0.0 && o[21] < 30.0, "case {c}: NIS {}", o[21]);
            // position sigmas after 3 fixes of 5-10 cm
            assert!(o[15] < 0.1 && o[17] < 0.2, "case {c}: {:?}", &o[15..18]);
        }
        // the source's table
        let t = N_OUTPUTS - EFFECTS_CASE_OUTPUTS;
        assert!((out[t - 5] - 8.085).abs() < 2e-3);
        assert!((out[t - 2] - 2.219).abs() < 2e-3);
        // effects case: every fix used, plausible NIS, estimates near their start values
        let o = &out[t..];
        assert_eq!(o[26], 3.0, "effects case: accepted fixes");
        assert!(o[25] > 0.0 && o[25] < 40.0, "effects case: NIS {}", o[25]);
        assert!((o[12] - 0.03).abs() < 0.03, "time offset {}", o[12]);
    }
}
