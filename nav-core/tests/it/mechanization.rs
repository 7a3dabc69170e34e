//! Accuracy of the strapdown mechanization against independent references:
//! at rest with perfect sensors, the Schuler period of the free-inertial
//! horizontal channels, 10 minutes of dynamic driving from error-free increments, and coning.

use test_support::trajectory;

use nalgebra::{UnitQuaternion, Vector3};
use nav_core::attitude;
use nav_core::earth::{self, Llh};
use nav_core::strapdown::{NavState, Strapdown};
use nav_core::types::ImuSample;
use trajectory::{Generator, Motion};

const T0_S: f64 = 345_600.0;
const DT_S: f64 = 0.005;

fn deg(x: f64) -> f64 {
    x.to_radians()
}

/// Attitude difference (rad): angle of q_a^-1 q_b.
fn att_err_rad(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    a.angle_to(b)
}

fn static_setup() -> (Llh, UnitQuaternion<f64>) {
    (
        Llh::from_deg(48.0, 11.0, 300.0),
        UnitQuaternion::from_euler_angles(deg(2.0), deg(-3.0), deg(135.0)),
    )
}

/// Exact increments at rest: the body is fixed in the earth frame, so omega_ib^b =
/// C_n^b omega_ie^n and f^b = -C_n^b g^n are constant in the body frame and their integrals
/// over an interval are exactly rate * dt (checked against the RK4 generator below).
fn static_increments(pos: &Llh, q_nb: &UnitQuaternion<f64>, dt: f64) -> ([f64; 3], [f64; 3]) {
    let q_bn = q_nb.inverse();
    let w = q_bn * earth::earth_rate_ned_radps(pos.lat_rad);
    let f = -(q_bn * earth::gravity_ned_mps2(pos.lat_rad, pos.h_m));
    ((w * dt).into(), (f * dt).into())
}

fn sample(k: u64, dth: [f64; 3], dv: [f64; 3]) -> ImuSample {
    ImuSample {
        t_s: T0_S + k as f64 * DT_S,
        dtheta_rad: dth,
        dv_mps: dv,
        temperature_c: f64::NAN,
    }
}

#[test]
fn static_increments_closed_form_equals_high_rate_integration() {
    let (pos, q) = static_setup();
    let (dth, dv) = static_increments(&pos, &q, DT_S);
    let mut g = Generator::new(trajectory::Static { q_nb: q }, pos, T0_S, DT_S, 50);
    for _ in 0..20 {
        let (imu, truth) = g.step();
        for i in 0..3 {
            assert!((imu.dtheta_rad[i] - dth[i]).abs() < 1e-20, "{imu:?}");
            assert!((imu.dv_mps[i] - dv[i]).abs() < 1e-16, "{imu:?}");
        }
        assert_eq!(truth.pos, pos);
    }
}

#[test]
fn at_rest_with_perfect_sensors_drift_is_below_1mm_after_1h() {
    let (pos, q) = static_setup();
    let (dth, dv) = static_increments(&pos, &q, DT_S);
    let s0 = NavState {
        t_s: T0_S,
        pos,
        vel_ned_mps: Vector3::zeros(),
        q_nb: q,
    };
    let mut m = Strapdown::new(s0);
    let n = 3600 * 200;
    let (mut max_pos, mut max_vel, mut max_att) = (0.0f64, 0.0f64, 0.0f64);
    for k in 1..=n {
        m.update(&sample(k, dth, dv)).expect("valid sample");
        if k % 200 == 0 {
            let s = m.state();
            max_pos = max_pos.max(earth::ned_offset_m(&pos, &s.pos).norm());
            max_vel = max_vel.max(s.vel_ned_mps.norm());
            max_att = max_att.max(att_err_rad(&q, &s.q_nb));
        }
    }
    let s = m.state();
    let d = earth::ned_offset_m(&pos, &s.pos);
    println!(
        "static 1 h: final NED offset {:.3e} {:.3e} {:.3e} m, max |dp| {max_pos:.3e} m, \
         max |v| {max_vel:.3e} m/s, max attitude drift {max_att:.3e} rad",
        d.x, d.y, d.z
    );
    assert!((s.t_s - (T0_S + 3600.0)).abs() < 1e-6);
    assert!(max_pos < 1e-3, "position drift {max_pos} m");
    assert!(max_vel < 1e-6, "velocity drift {max_vel} m/s");
    assert!(max_att < 1e-9, "attitude drift {max_att} rad");
}

/// Runs the reference (error-free) and the perturbed (initial north velocity error
/// `dv_n0_mps`) solutions side by side at rest at `pos` for `hours`, holding the perturbed
/// solution's vertical channel on the reference, and returns the north velocity error every
/// second (s, m/s).
fn schuler_north_velocity_error(pos: Llh, dv_n0_mps: f64, hours: f64) -> (Vec<f64>, Vec<f64>) {
    let (_, q) = static_setup();
    let (dth, dv) = static_increments(&pos, &q, DT_S);
    let s0 = NavState {
        t_s: T0_S,
        pos,
        vel_ned_mps: Vector3::zeros(),
        q_nb: q,
    };
    let mut reference = Strapdown::new(s0);
    let mut perturbed = Strapdown::new(NavState {
        vel_ned_mps: Vector3::new(dv_n0_mps, 0.0, 0.0),
        ..s0
    });
    let n = (hours * 3600.0 / DT_S).round() as u64;
    let (mut t, mut en) = (vec![0.0], vec![dv_n0_mps]);
    for k in 1..=n {
        let imu = sample(k, dth, dv);
        reference.update(&imu).expect("valid sample");
        perturbed.update(&imu).expect("valid sample");
        // The vertical channel of a free inertial solution is unstable (time constant
        // sqrt(R / 2g) = 570 s): without aiding, the Coriolis coupling of the east velocity
        // error drives it to thousands of km in 4 h (measured: 6.3e6 m) and that wrecks the
        // horizontal channels. A perfect vertical aid (what a barometer gives) is emulated by
        // setting the perturbed height and vertical velocity to the reference's every step;
        // the horizontal channels stay free-inertial.
        let r = *reference.state();
        let p = perturbed.state_mut();
        p.pos.h_m = r.pos.h_m;
        p.vel_ned_mps.z = r.vel_ned_mps.z;
        if k % 200 == 0 {
            t.push(k as f64 * DT_S);
            en.push(perturbed.state().vel_ned_mps.x - reference.state().vel_ned_mps.x);
        }
    }
    (t, en)
}

/// Times (s) of the sign changes of `y`, linearly interpolated.
fn zero_crossings(t: &[f64], y: &[f64]) -> Vec<f64> {
    let mut z = Vec::new();
    for i in 1..y.len() {
        if (y[i - 1] > 0.0) != (y[i] > 0.0) {
            let f = y[i - 1] / (y[i - 1] - y[i]);
            z.push(t[i - 1] + f * (t[i] - t[i - 1]));
        }
    }
    z
}

/// Zero crossings of the north velocity error of the textbook linearised error model
/// (Groves ch. 14 / Titterton-Weston, phi-angle form) at rest with the vertical channel held:
/// phi' = -omega_ie x phi + delta omega_in(dv, dlat),
/// dv_N' = g phi_E - 2 W sinL dv_E, dv_E' = -g phi_N + 2 W sinL dv_N, dlat' = dv_N / (R_M + h),
/// integrated by RK4 at 1 s. Independent of the mechanization code.
fn linear_model_crossings(pos: &Llh, dv_n0_mps: f64, hours: f64) -> Vec<f64> {
    let lat = pos.lat_rad;
    let r = earth::radii(lat);
    let (rm, rn) = (r.meridian_m + pos.h_m, r.transverse_m + pos.h_m);
    let g = earth::gravity_mps2(lat, pos.h_m);
    let w = earth::OMEGA_IE_RADPS;
    let (sl, cl) = lat.sin_cos();
    let w_ie = Vector3::new(w * cl, 0.0, -w * sl);
    // x = [phi_N, phi_E, phi_D, dv_N, dv_E, dlat]
    let f = |x: &[f64; 6]| -> [f64; 6] {
        let phi = Vector3::new(x[0], x[1], x[2]);
        let (vn, ve, dl) = (x[3], x[4], x[5]);
        let d_w = Vector3::new(
            -w * sl * dl + ve / rn,
            -vn / rm,
            -w * cl * dl - ve * sl / cl / rn,
        );
        let dphi = -w_ie.cross(&phi) + d_w;
        [
            dphi.x,
            dphi.y,
            dphi.z,
            g * x[1] - 2.0 * w * sl * ve,
            -g * x[0] + 2.0 * w * sl * vn,
            vn / rm,
        ]
    };
    let mut x = [0.0, 0.0, 0.0, dv_n0_mps, 0.0, 0.0];
    let h = 1.0;
    let (mut t, mut en) = (vec![0.0], vec![dv_n0_mps]);
    let add = |a: &[f64; 6], b: &[f64; 6], s: f64| -> [f64; 6] {
        let mut c = *a;
        for i in 0..6 {
            c[i] += b[i] * s;
        }
        c
    };
    for k in 1..=(hours * 3600.0) as usize {
        let k1 = f(&x);
        let k2 = f(&add(&x, &k1, 0.5 * h));
        let k3 = f(&add(&x, &k2, 0.5 * h));
        let k4 = f(&add(&x, &k3, h));
        for i in 0..6 {
            x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        t.push(k as f64 * h);
        en.push(x[3]);
    }
    zero_crossings(&t, &en)
}

/// Full periods (min) from consecutive zero crossings, and the mean period (min) from the
/// first to the last crossing.
fn periods_min(z: &[f64]) -> (Vec<f64>, f64) {
    let each = z.windows(2).map(|w| 2.0 * (w[1] - w[0]) / 60.0).collect();
    let mean = 2.0 * (z[z.len() - 1] - z[0]) / (z.len() - 1) as f64 / 60.0;
    (each, mean)
}

#[test]
fn schuler_period_at_48_deg_is_within_half_percent_of_84_4_min() {
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    let hours = 4.0;
    let (t, en) = schuler_north_velocity_error(pos, 0.1, hours);
    let z = zero_crossings(&t, &en);
    let (each, mean) = periods_min(&z);
    let z_lin = linear_model_crossings(&pos, 0.1, hours);
    println!("Schuler at 48 deg: crossings {z:.2?} s");
    println!("  linear error model crossings {z_lin:.2?} s");
    println!(
        "  periods from consecutive crossings {each:.3?} min, mean {mean:.3} min ({:+.3}% vs 84.4)",
        (mean / 84.4 - 1.0) * 100.0
    );
    // 4 h = 2.8 Schuler periods: at least 5 crossings.
    assert!(z.len() >= 5, "{z:?}");
    assert!((mean / 84.4 - 1.0).abs() < 0.005, "mean period {mean} min");
    for p in &each {
        assert!((p / 84.4 - 1.0).abs() < 0.005, "period {p} min");
    }
    // The mechanization reproduces the textbook error dynamics, Foucault and earth-rate
    // couplings included (these shorten the zero-crossing period by 0.3% at 48 deg and make
    // it drift slowly; the linear model shows the same).
    assert_eq!(z.len(), z_lin.len());
    for (a, b) in z.iter().zip(&z_lin) {
        assert!((a - b).abs() < 1.0, "crossing {a} s vs linear model {b} s");
    }
}

#[test]
fn schuler_period_at_equator_matches_sqrt_meridian_radius_over_g() {
    // At the equator the Foucault term (W sin L) and the latitude coupling of the earth rate
    // into the tilt vanish, and the north channel oscillates at sqrt(g / (R_M + h)).
    let pos = Llh::from_deg(0.0, 11.0, 300.0);
    let hours = 3.5;
    let (t, en) = schuler_north_velocity_error(pos, 0.1, hours);
    let z = zero_crossings(&t, &en);
    let (each, mean) = periods_min(&z);
    let rm = earth::radii(0.0).meridian_m + pos.h_m;
    let expected = std::f64::consts::TAU * (rm / earth::gravity_mps2(0.0, pos.h_m)).sqrt() / 60.0;
    println!(
        "Schuler at equator: periods {each:.4?} min, mean {mean:.4} min, \
         2 pi sqrt((R_M + h) / g) = {expected:.4} min"
    );
    assert!(z.len() >= 4, "{z:?}");
    assert!((mean / expected - 1.0).abs() < 2e-5, "{mean} vs {expected}");
    assert!((mean / 84.4 - 1.0).abs() < 0.005, "{mean}");
}

/// Runs the mechanization on the generator's ideal increments from the true initial state and
/// returns the maximum position (m), velocity (m/s) and attitude (rad) errors over the
/// comparisons at every full second.
fn run_against_truth<M: Motion>(gen: &mut Generator<M>, seconds: u64) -> (f64, f64, f64) {
    let t0 = gen.truth();
    let mut m = Strapdown::new(NavState {
        t_s: t0.t_s,
        pos: t0.pos,
        vel_ned_mps: t0.vel_ned_mps,
        q_nb: t0.q_nb,
    });
    let per_s = (1.0 / DT_S).round() as u64;
    let (mut ep, mut ev, mut ea) = (0.0f64, 0.0f64, 0.0f64);
    for k in 1..=seconds * per_s {
        let (imu, truth) = gen.step();
        m.update(&imu).expect("valid sample");
        if k % per_s == 0 {
            let s = m.state();
            assert!((s.t_s - truth.t_s).abs() < 1e-9);
            ep = ep.max(earth::ned_offset_m(&truth.pos, &s.pos).norm());
            ev = ev.max((s.vel_ned_mps - truth.vel_ned_mps).norm());
            ea = ea.max(att_err_rad(&truth.q_nb, &s.q_nb));
        }
    }
    (ep, ev, ea)
}

#[test]
fn error_free_increments_integrate_back_to_truth_over_10_min_of_driving() {
    let start = Llh::from_deg(48.1, 11.6, 520.0);
    let mut gen = Generator::new(trajectory::driving_profile(), start, T0_S, DT_S, 5);
    let (ep, ev, ea) = run_against_truth(&mut gen, 600);
    let end = gen.truth();
    println!(
        "10 min driving at 200 Hz ({:.0} m from start): max position error {ep:.3e} m, max \
         velocity error {ev:.3e} m/s, max attitude error {ea:.3e} rad",
        earth::ned_offset_m(&start, &end.pos).norm()
    );
    assert!(ep < 0.02, "position error {ep} m");
    assert!(ev < 1e-4, "velocity error {ev} m/s");
    assert!(ea < 1e-8, "attitude error {ea} rad");
}

#[test]
fn driving_error_falls_with_the_sample_interval_like_an_algorithm_error() {
    // The truth generator is converged (its result does not change with more sub-steps), so
    // what remains is the mechanization's own truncation error: it must shrink by more than
    // 4x (second order or better) when the IMU interval halves from 10 ms to 5 ms.
    let start = Llh::from_deg(48.1, 11.6, 520.0);
    let run = |dt: f64, n_sub: usize| {
        let mut gen = Generator::new(trajectory::driving_profile(), start, T0_S, dt, n_sub);
        let t0 = gen.truth();
        let mut m = Strapdown::new(NavState {
            t_s: t0.t_s,
            pos: t0.pos,
            vel_ned_mps: t0.vel_ned_mps,
            q_nb: t0.q_nb,
        });
        let n = (300.0 / dt).round() as u64;
        let mut truth = t0;
        for _ in 0..n {
            let (imu, tr) = gen.step();
            m.update(&imu).expect("valid sample");
            truth = tr;
        }
        earth::ned_offset_m(&truth.pos, &m.state().pos).norm()
    };
    let e10 = run(0.01, 5);
    let e5 = run(0.005, 5);
    let e5_fine_truth = run(0.005, 20);
    println!(
        "5 min driving: position error {e10:.3e} m at 100 Hz, {e5:.3e} m at 200 Hz (truth with \
         4x the sub-steps: {e5_fine_truth:.3e} m), ratio {:.2}",
        e10 / e5
    );
    assert!(
        (e5 - e5_fine_truth).abs() < 1e-6,
        "truth generator not converged"
    );
    assert!(e10 / e5 > 4.0, "{e10} -> {e5}");
}

/// Classical coning (see `trajectory::Coning`): the increments are analytic,
/// dtheta = (-2 sin^2(a/2) W h, sin a [cos W t], sin a [sin W t]) over each interval, and the
/// true attitude is q_c(t). Integrates the body attitude with and without the two-sample
/// coning term and returns the drift rates (rad/s) about the cone axis (body x).
fn coning_drift_radps(a: f64, w: f64, h: f64, n: u64, with_coning: bool) -> f64 {
    let cone = trajectory::Coning {
        q0: UnitQuaternion::identity(),
        half_angle_rad: a,
        freq_radps: w,
    };
    let s = (0.5 * a).sin();
    let dth = |k: u64| {
        let (t0, t1) = ((k - 1) as f64 * h, k as f64 * h);
        Vector3::new(
            -2.0 * s * s * w * h,
            a.sin() * ((w * t1).cos() - (w * t0).cos()),
            a.sin() * ((w * t1).sin() - (w * t0).sin()),
        )
    };
    let mut q = cone.q_c(0.0);
    let mut prev = dth(1);
    for k in 1..=n {
        let d = dth(k);
        let phi = if with_coning && k > 1 {
            d + attitude::coning_correction(&prev, &d)
        } else {
            d
        };
        q *= attitude::quat_from_rotvec(&phi);
        prev = d;
    }
    let err = attitude::rotvec_from_quat(&(cone.q_c(n as f64 * h).inverse() * q));
    err.x / (n as f64 * h)
}

#[test]
fn coning_correction_removes_the_coning_drift_as_predicted() {
    // 10 Hz coning, half-angle 0.02 rad, at 200 Hz (W h = 0.314 rad), 20 s (200 cone periods).
    let (a, w, h, n): (f64, f64, f64, u64) = (0.02, std::f64::consts::TAU * 10.0, 0.005, 4000);
    let lam = w * h;
    let s2 = (0.5 * a).sin().powi(2);
    let c2 = 1.0 - s2;
    // Per step, the true rotation about x is -2 s^2 sin(lam) (to leading order in s) while
    // dtheta_x = -2 s^2 lam; the two-sample term adds (1/12) sin^2 a 4 sin^2(lam/2) sin(lam).
    let expect_without = -2.0 * s2 * (lam - lam.sin()) / h;
    let expect_with =
        2.0 * s2 * (-(lam - lam.sin()) + 2.0 / 3.0 * c2 * (0.5 * lam).sin().powi(2) * lam.sin())
            / h;
    let without = coning_drift_radps(a, w, h, n, false);
    let with = coning_drift_radps(a, w, h, n, true);
    println!(
        "coning 10 Hz, 0.02 rad, 200 Hz: drift without correction {without:.4e} rad/s \
         (predicted {expect_without:.4e}), with {with:.4e} rad/s (predicted {expect_with:.4e}, \
         ~ a^2 W (W h)^4 / 60 = {:.4e}), reduction {:.1}x",
        -a * a * w * lam.powi(4) / 60.0,
        without / with
    );
    assert!((without / expect_without - 1.0).abs() < 0.01);
    assert!((with / expect_with - 1.0).abs() < 0.02);
    assert!(without / with > 40.0);
}

#[test]
fn strapdown_applies_the_coning_correction_with_earth_rotation() {
    // The same coning relative to NED at rest on the rotating earth, through the full
    // mechanization, with increments from the RK4 generator: the attitude drift about the cone
    // axis must be the two-sample residual, not the 50x larger uncorrected drift.
    let (a, w): (f64, f64) = (0.02, std::f64::consts::TAU * 10.0);
    let (pos, q0) = static_setup();
    let cone = trajectory::Coning {
        q0,
        half_angle_rad: a,
        freq_radps: w,
    };
    let mut gen = Generator::new(cone, pos, T0_S, DT_S, 20);
    let t0 = gen.truth();
    let mut m = Strapdown::new(NavState {
        t_s: t0.t_s,
        pos: t0.pos,
        vel_ned_mps: t0.vel_ned_mps,
        q_nb: t0.q_nb,
    });
    let mut truth = t0;
    let n = 4000;
    for _ in 0..n {
        let (imu, tr) = gen.step();
        m.update(&imu).expect("valid sample");
        truth = tr;
    }
    let t = n as f64 * DT_S;
    // Error in the body frame at the end; the mean body x axis is q0's x axis.
    let err = attitude::rotvec_from_quat(&(truth.q_nb.inverse() * m.state().q_nb));
    let drift = err.x / t;
    let expect = coning_drift_radps(a, w, DT_S, n, true);
    let uncorrected = coning_drift_radps(a, w, DT_S, n, false);
    println!(
        "strapdown coning drift {drift:.4e} rad/s (body-only two-sample {expect:.4e}, \
         uncorrected {uncorrected:.4e}); error vector {:.3e} {:.3e} {:.3e} rad after {t} s",
        err.x, err.y, err.z
    );
    assert!((drift / expect - 1.0).abs() < 0.03, "{drift} vs {expect}");
}
