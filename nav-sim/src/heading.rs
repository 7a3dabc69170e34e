//! Simulated dual-antenna GNSS heading (a scenario's `[vehicle.heading]`; the case's
//! `heading.txt`): the azimuth (from north, clockwise) of the antenna baseline, fixed in the
//! body frame, from the error-free attitude, plus white noise, at its own rate; each line
//! carries the sigma.

use crate::trajectory::{dcm_from_euler, Trajectory};
use nalgebra::Vector3;
use nav_io::HeadingSample;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// What the simulated heading measures (`[vehicle.heading]` of a scenario; in `nav-sim`).
pub use crate::scenario::HeadingSpec;

/// The heading samples of a trajectory (truth epochs nearest the sample times; the rate is
/// rounded to a whole number of IMU intervals), seeded, headings in [0, 360) deg.
pub fn dual_antenna_heading(
    traj: &Trajectory,
    spec: &HeadingSpec,
    seed: u64,
) -> Vec<HeadingSample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4ead_1e55);
    let step = ((1.0 / spec.rate_hz) / traj.dt_s).round().max(1.0) as usize;
    let b = Vector3::from(spec.baseline_m);
    traj.truth
        .iter()
        .step_by(step)
        .map(|s| {
            let [r, p, y] = s.rpy_rad;
            let bn = dcm_from_euler(r, p, y) * b;
            let n: f64 = StandardNormal.sample(&mut rng);
            let psi = bn.y.atan2(bn.x).to_degrees() + spec.sigma_deg * n;
            HeadingSample {
                t_s: s.t_s,
                heading_deg: psi.rem_euclid(360.0),
                sigma_deg: Some(spec.sigma_deg),
            }
        })
        .collect()
}
