//! The simulator and the filter share one earth model: a point displaced by a NED offset and
//! measured back through ECEF recovers the offset.
use nav_core::earth::{displace, ned_offset_m, Llh};

#[test]
fn displace_and_ned_offset_are_inverse_to_millimetres_over_a_kilometre() {
    let p = Llh::from_deg(40.097, -105.147, 1601.0);
    let d = nalgebra::Vector3::new(700.0, -650.0, 10.0);
    let back = ned_offset_m(&p, &displace(&p, &d));
    // First-order curvilinear map: the error grows as d^2 / R (about 0.1 m at 1 km).
    assert!((back - d).norm() < 0.2, "{back:?}");
}
