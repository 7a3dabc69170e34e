//! The static test scenario shared by the `bench` and `ontarget` binaries: a level IMU at
//! rest, heading north, at 48 deg N, 11 deg E, 500 m, measuring gravity and earth rate plus
//! deterministic uniform white noise (1e-3 m/s^2, 1e-5 rad/s).
use nav_core::earth::{self, Llh};
use nav_core::types::ImuSample;

/// Deterministic noise in [-1, 1) (64-bit LCG, top 53 bits).
pub struct Lcg(pub u64);

impl Lcg {
    /// The next value in [-1, 1).
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// Latitude of the scenario, deg.
pub const LAT_DEG: f64 = 48.0;

/// Where the IMU stands (geodetic).
pub fn start_pos() -> Llh {
    Llh::from_deg(LAT_DEG, 11.0, 500.0)
}

/// IMU sample `k` at `imu_hz` (time tag `t0_s + k / imu_hz`, s): increments of gravity and
/// earth rate at [`start_pos`] plus noise from `rng`, 25 degC.
pub fn imu_sample(k: u32, t0_s: f64, imu_hz: f64, rng: &mut Lcg) -> ImuSample {
    let p = start_pos();
    let dt = 1.0 / imu_hz;
    let g = earth::gravity_mps2(p.lat_rad, p.h_m);
    let w = earth::OMEGA_IE_RADPS;
    let rate = [
        w * libm::cos(p.lat_rad) + 1e-5 * rng.next(),
        1e-5 * rng.next(),
        -w * libm::sin(p.lat_rad) + 1e-5 * rng.next(),
    ];
    let f = [1e-3 * rng.next(), 1e-3 * rng.next(), -g + 1e-3 * rng.next()];
    ImuSample {
        t_s: t0_s + f64::from(k) * dt,
        dtheta_rad: rate.map(|r| r * dt),
        dv_mps: f.map(|a| a * dt),
        temperature_c: 25.0,
    }
}
