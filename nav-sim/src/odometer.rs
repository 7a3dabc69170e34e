//! Simulated wheel speed (a scenario's `[vehicle.odometer]`; the case's `odometer.txt`): the
//! forward (body x) speed of a point on the vehicle, from the error-free truth, times
//! `1 + scale` (an undeclared scale factor: tyre radius) plus white noise, at its own rate.
//! The body frame of the simulator is the vehicle frame (side slip makes the velocity point
//! off the body x axis: the forward speed is then `speed cos(slip)`).

use crate::trajectory::{dcm_from_euler, Trajectory};
use nalgebra::Vector3;
use nav_io::OdometerSample;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// What the simulated odometer measures (`[vehicle.odometer]` of a scenario; in `nav-sim`).
pub use crate::scenario::WheelSpeedSpec;

/// The wheel-speed samples of a trajectory (truth epochs nearest the sample times; the rate
/// is rounded to a whole number of IMU intervals), seeded.
pub fn wheel_speed(traj: &Trajectory, spec: &WheelSpeedSpec, seed: u64) -> Vec<OdometerSample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0d0_3e7e5);
    let step = ((1.0 / spec.rate_hz) / traj.dt_s).round().max(1.0) as usize;
    let l = Vector3::from(spec.lever_arm_m);
    let mut out = Vec::with_capacity(traj.truth.len() / step + 1);
    for (k, s) in traj.truth.iter().enumerate().step_by(step) {
        let [r, p, y] = s.rpy_rad;
        let c = dcm_from_euler(r, p, y);
        // body rate of the interval ending here (ideal increments), rad/s
        let w = k
            .checked_sub(1)
            .and_then(|i| traj.imu.get(i))
            .map_or(Vector3::zeros(), |imu| {
                Vector3::from(imu.dtheta_rad) / traj.dt_s
            });
        let v_b = c.transpose() * Vector3::from(s.vel_ned_mps) + w.cross(&l);
        let n: f64 = StandardNormal.sample(&mut rng);
        out.push(OdometerSample {
            t_s: s.t_s,
            speed_mps: (1.0 + spec.scale) * v_b.x + spec.sigma_mps * n,
        });
    }
    out
}
