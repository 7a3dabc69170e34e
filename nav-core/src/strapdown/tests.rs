extern crate std;
use super::*;

/// Worst errors of the reference-point series against the earth module over offsets up to
/// the re-reference limits: (earth rate rad/s, gravity m/s^2, 1/(R_M+h) relative,
/// lon factor relative, transport rate relative).
fn earth_series_errors(lat_deg: f64, h_m: f64) -> [f64; 5] {
    let lat = lat_deg.to_radians();
    let r = EarthRef::new(lat, h_m);
    let mut worst = [0.0f64; 5];
    for &fd in &[-1.0f32, -0.37, 0.0, 0.5, 1.0] {
        for &fe in &[-1.0f32, 0.0, 0.3, 1.0] {
            // offsets exactly representable in f32, as the step uses them
            let d32 = fd * r.lat_tol_rad;
            let e32 = fe * EARTH_REF_H_TOL_M;
            let (la, h) = (lat + f64::from(d32), h_m + f64::from(e32));
            let loc = r.at(d32, e32);
            let w = earth::earth_rate_ned_radps(la);
            let wi = earth::OMEGA_IE_RADPS;
            let ew = (loc.cos * wi - w.x).abs().max((-loc.sin * wi - w.z).abs());
            let eg = (loc.g_mps2 - earth::gravity_mps2(la, h)).abs();
            let rr = earth::radii(la);
            let inv_m = 1.0 / (rr.meridian_m + h);
            let em = (r.inv_meridian(d32, e32) / inv_m - 1.0).abs();
            let lon_f = 1.0 / ((rr.transverse_m + h) * cos(la));
            let el = (r.lon_factor(d32, e32) / lon_f - 1.0).abs();
            let v = Vector3::new(12.0, -7.0, 0.5);
            let w_ref = earth::transport_rate_ned_radps(la, h, &v);
            let t = transport32(&loc, to32(&v));
            let et = (Vector3::new(f64::from(t[0]), f64::from(t[1]), f64::from(t[2])) - w_ref)
                .norm()
                / w_ref.norm();
            for (a, b) in worst.iter_mut().zip([ew, eg, em, el, et]) {
                *a = a.max(b);
            }
        }
    }
    worst
}

#[test]
fn earth_reference_series_matches_the_earth_module_within_the_re_reference_limits() {
    for &lat_deg in &[-89.0, -45.0, 0.0, 12.3, 48.0, 80.0] {
        for &h in &[-100.0, 0.0, 300.0, 10_000.0] {
            // at the reference itself: the earth module's formulas
            let lat = f64::to_radians(lat_deg);
            let r = EarthRef::new(lat, h);
            let radii = earth::radii(lat);
            assert!((1.0 / r.inv_m - radii.meridian_m - h).abs() < 1e-8);
            assert!((r.lon_f * (radii.transverse_m + h) * cos(lat) - 1.0).abs() < 1e-15);
            assert!((r.g_mps2 - earth::gravity_mps2(lat, h)).abs() < 1e-14);
            let [ew, eg, em, el, et] = earth_series_errors(lat_deg, h);
            // measured: earth rate <= 4.3e-17 rad/s (6e-13 relative), gravity <= 9e-12
            // m/s^2, radii <= 1.7e-12 relative (the f32 rounding of the corrections),
            // transport rate (f32) <= 1.3e-7 relative
            assert!(ew < 1e-16, "{lat_deg} {h}: earth rate {ew:e} rad/s");
            assert!(eg < 3e-11, "{lat_deg} {h}: gravity {eg:e} m/s^2");
            assert!(em < 3e-12, "{lat_deg} {h}: 1/(R_M+h) {em:e}");
            assert!(el < 5e-12, "{lat_deg} {h}: lon factor {el:e}");
            assert!(et < 3e-7, "{lat_deg} {h}: transport rate {et:e}");
        }
    }
}

/// Increments of a lively synthetic motion (not a consistent trajectory: the test compares
/// two implementations of the same step, not against truth): speed-up to ~30 m/s, turns,
/// climbs, body wobble and vibration, some seconds of 2-3 rad/s rotation, and a few
/// irregular intervals.
fn lively_sample(t_s: f64, dt: f64) -> ImuSample {
    let t = t_s - 1000.0;
    let g = 9.81;
    let (sw, cw) = (sin(1.7 * t), cos(1.3 * t));
    let fast = if (20.0..23.0).contains(&t) { 2.5 } else { 0.0 };
    let w = [
        0.05 * sw + 0.01 * sin(90.0 * t) + fast,
        0.03 * cw,
        0.15 * sin(0.2 * t) + 0.7 * fast,
    ];
    let f = [
        if t < 15.0 { 2.0 } else { 0.3 * sin(0.1 * t) },
        0.4 * cw + 0.2 * sin(70.0 * t),
        -g + 0.3 * sw,
    ];
    ImuSample {
        t_s,
        dtheta_rad: w.map(|x| x * dt),
        dv_mps: f.map(|x| x * dt),
        temperature_c: f64::NAN,
    }
}

/// Runs the optimised and the plain step side by side; returns the worst differences
/// (position m, velocity m/s, attitude rad).
fn compare_with_plain(start: NavState, seconds: f64) -> (f64, f64, f64) {
    let mut a = Strapdown::new(start);
    let mut b = plain::PlainStrapdown::new(start);
    let mut t = start.t_s;
    let (mut ep, mut ev, mut ea) = (0.0f64, 0.0f64, 0.0f64);
    let mut k = 0u64;
    while t < start.t_s + seconds {
        k += 1;
        // 200 Hz with a few irregular intervals (no two-sample terms after them)
        let dt = match k % 5000 {
            1000 => 0.0125,
            1001 => 0.002,
            _ => 0.005,
        };
        t += dt;
        let s = lively_sample(t, dt);
        a.update(&s).expect("valid sample");
        b.update(&s).expect("valid sample");
        let (sa, sb) = (a.state(), b.state());
        ep = ep.max(earth::ned_offset_m(&sb.pos, &sa.pos).norm());
        ev = ev.max((sa.vel_ned_mps - sb.vel_ned_mps).norm());
        ea = ea.max(sa.q_nb.angle_to(&sb.q_nb));
    }
    (ep, ev, ea)
}

#[test]
fn optimised_step_matches_the_plain_f64_step() {
    for (lat_deg, v0, seconds) in [
        (48.0, [0.0, 0.0, 0.0], 60.0),
        (-33.9, [5.0, -3.0, 0.2], 60.0),
        (0.0, [250.0, 30.0, -5.0], 30.0),
        (89.5, [20.0, 10.0, 0.0], 30.0),
    ] {
        let start = NavState::from_rpy(
            1000.0,
            Llh::from_deg(lat_deg, 11.0, 500.0),
            Vector3::from(v0),
            [0.01, -0.02, 0.7],
        );
        let (ep, ev, ea) = compare_with_plain(start, seconds);
        std::println!(
            "lat {lat_deg}, v0 {v0:?}, {seconds} s: optimised vs plain f64 step: position \
             {ep:.3e} m, velocity {ev:.3e} m/s, attitude {ea:.3e} rad"
        );
        // measured: <= 3.4e-7 m, 3.1e-8 m/s, 5.5e-10 rad (the 89.5 deg case, where the
        // f32 transport rate is larger than the earth rate); <= 1.1e-7 m, 1.3e-8 m/s,
        // 3e-11 rad elsewhere (most of it from the f32 rotation compensation during the
        // 2.5 rad/s spin)
        assert!(ep < 1e-6, "position {ep} m");
        assert!(ev < 1e-7, "velocity {ev} m/s");
        assert!(ea < 2e-9, "attitude {ea} rad");
    }
}

#[test]
fn rejects_bad_samples_and_keeps_the_state() {
    let s0 = NavState::from_rpy(
        10.0,
        Llh::from_deg(48.0, 11.0, 300.0),
        Vector3::zeros(),
        [0.0; 3],
    );
    let mut m = Strapdown::new(s0);
    let mut imu = ImuSample {
        t_s: 10.005,
        dtheta_rad: [f64::NAN, 0.0, 0.0],
        ..Default::default()
    };
    assert_eq!(m.update(&imu), Err(MechError::NonFinite));
    imu.dtheta_rad = [0.0; 3];
    imu.t_s = 10.0;
    assert_eq!(m.update(&imu), Err(MechError::BadTimeStep));
    imu.t_s = 11.5;
    assert_eq!(m.update(&imu), Err(MechError::BadTimeStep));
    assert_eq!(*m.state(), s0);
}

/// Runs the single-precision and the mixed-precision step side by side on the same
/// increments (rounded to `f32` for both); returns the worst differences (position m, velocity
/// m/s, attitude rad) and the worst |norm of the single-precision quaternion - 1|.
fn compare_single_with_mixed(start: NavState, seconds: f64) -> [f64; 4] {
    let mut a = Strapdown::new(start);
    let mut b = Strapdown::new(start);
    let mut t = start.t_s;
    let mut worst = [0.0f64; 4];
    let mut k = 0u64;
    while t < start.t_s + seconds {
        k += 1;
        let dt = match k % 5000 {
            1000 => 0.0125,
            1001 => 0.002,
            _ => 0.005,
        };
        t += dt;
        let mut s = lively_sample(t, dt);
        let dth = s.dtheta_rad.map(|x| x as f32);
        let dv = s.dv_mps.map(|x| x as f32);
        s.dtheta_rad = dth.map(f64::from);
        s.dv_mps = dv.map(f64::from);
        let info = a.update_single(t, dth, dv).expect("valid sample");
        let info_b = b.update(&s).expect("valid sample");
        assert_eq!(info.dt_s, info_b.dt_s);
        let (sa, sb) = (a.state(), b.state());
        let d = [
            earth::ned_offset_m(&sb.pos, &sa.pos).norm(),
            (sa.vel_ned_mps - sb.vel_ned_mps).norm(),
            sa.q_nb.angle_to(&sb.q_nb),
            (sa.q_nb.quaternion().norm() - 1.0).abs(),
        ];
        for (w, x) in worst.iter_mut().zip(d) {
            *w = w.max(x);
        }
    }
    worst
}

#[test]
fn single_precision_step_matches_the_mixed_precision_step() {
    for (lat_deg, v0, seconds) in [
        (48.0, [0.0, 0.0, 0.0], 60.0),
        (-33.9, [5.0, -3.0, 0.2], 60.0),
        (0.0, [250.0, 30.0, -5.0], 30.0),
        (89.5, [20.0, 10.0, 0.0], 30.0),
    ] {
        let start = NavState::from_rpy(
            1000.0,
            Llh::from_deg(lat_deg, 11.0, 500.0),
            Vector3::from(v0),
            [0.01, -0.02, 0.7],
        );
        let [ep, ev, ea, en] = compare_single_with_mixed(start, seconds);
        std::println!(
            "lat {lat_deg}, v0 {v0:?}, {seconds} s: single vs mixed precision step: position \
             {ep:.3e} m, velocity {ev:.3e} m/s, attitude {ea:.3e} rad, |q| - 1 {en:.1e}"
        );
        // measured: <= 4.8e-4 m, 2.8e-5 m/s, 9.2e-8 rad, |q| - 1 <= 9.5e-8 (free inertial;
        // mostly the rotation of dv by the f32-rounded attitude, an attitude error of ~3e-8
        // rad acting as a 0.3 ug accelerometer error: see docs/precision.md)
        assert!(ep < 1e-3, "position {ep} m");
        assert!(ev < 5e-5, "velocity {ev} m/s");
        assert!(ea < 2e-7, "attitude {ea} rad");
        assert!(en < 2e-7, "quaternion norm {en}");
    }
}

#[test]
fn single_precision_step_rejects_bad_samples_and_keeps_the_state() {
    let s0 = NavState::from_rpy(
        10.0,
        Llh::from_deg(48.0, 11.0, 300.0),
        Vector3::zeros(),
        [0.0; 3],
    );
    let mut m = Strapdown::new(s0);
    let z = [0.0f32; 3];
    assert_eq!(
        m.update_single(10.005, [f32::NAN, 0.0, 0.0], z),
        Err(MechError::NonFinite)
    );
    assert_eq!(
        m.update_single(f64::INFINITY, z, z),
        Err(MechError::NonFinite)
    );
    assert_eq!(m.update_single(10.0, z, z), Err(MechError::BadTimeStep));
    assert_eq!(m.update_single(11.5, z, z), Err(MechError::BadTimeStep));
    assert_eq!(*m.state(), s0);
}
