//! A level, north-facing vehicle standing still (body axes = NED): the IMU increments it
//! measures (the earth rate, the reaction to gravity) and GNSS fixes at its place, generated
//! one at a time. The bounded-memory tests run hours of them through the engine without
//! storing any.

use nav_core::earth::{earth_rate_ned_radps, gravity_mps2, Llh};
use nav_core::types::{FixQuality, GnssFix, ImuSample};

/// `n` IMU increments at `rate_hz` of a vehicle standing at `pos`: sample `k` (1..=n) ends at
/// `t0_s + k / rate_hz` (GPS seconds of week).
pub fn imu(pos: Llh, t0_s: f64, rate_hz: f64, n: usize) -> impl Iterator<Item = ImuSample> {
    let dt = 1.0 / rate_hz;
    let w = earth_rate_ned_radps(pos.lat_rad);
    let g = gravity_mps2(pos.lat_rad, pos.h_m);
    (1..=n).map(move |k| ImuSample {
        t_s: t0_s + k as f64 * dt,
        dtheta_rad: [w.x * dt, w.y * dt, w.z * dt],
        dv_mps: [0.0, 0.0, -g * dt],
        temperature_c: f64::NAN,
    })
}

/// `n` single-point fixes at `rate_hz` at `pos` (sigmas 0.5, 0.5, 1.0 m N/E/D, 10
/// satellites, no velocity): fix `k` (1..=n) at `t0_s + k / rate_hz`.
pub fn fixes(pos: Llh, t0_s: f64, rate_hz: f64, n: usize) -> impl Iterator<Item = GnssFix> {
    (1..=n).map(move |k| GnssFix {
        t_s: t0_s + k as f64 / rate_hz,
        lat_rad: pos.lat_rad,
        lon_rad: pos.lon_rad,
        h_m: pos.h_m,
        pos_std_ned_m: [0.5, 0.5, 1.0],
        quality: FixQuality::Single,
        num_sats: 10,
        ..GnssFix::default()
    })
}
