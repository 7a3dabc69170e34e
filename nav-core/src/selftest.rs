//! The cross-platform self-test: fixed inputs run through the core's code, producing a vector
//! of `f64` outputs. The host computes it once and checks the result into the firmware
//! (`firmware/src/expected.rs`, written by `cargo xtask gen-vectors`); the firmware computes
//! it again on the MCU and compares, so any difference between the two builds of the same code
//! is caught. Add a case by appending to [`CASES`] and to [`compute`]; the vector grows with the
//! core.

use crate::earth;

/// Names of the self-test cases and how many `f64` outputs each produces, in output order.
pub const CASES: &[(&str, usize)] = &[
    ("earth::gravity_mps2 at 5 latitudes x 2 heights", 10),
    ("earth::radii at 5 latitudes", 10),
    ("earth::geodetic->ecef->geodetic round trip, 3 points", 9),
    ("earth::transport_rate_ned_radps, 2 velocities", 6),
];

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
    w.n
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
}
