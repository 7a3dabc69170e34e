//! Static coarse alignment: levelling, gyrocompassing, static detection.

use test_support::trajectory;

use nalgebra::{UnitQuaternion, Vector3};
use nav_core::align::{coarse_align, AlignConfig, AlignError, HeadingSource, MotionCue};
use nav_core::earth::{self, Llh};
use nav_core::strapdown::Strapdown;
use nav_core::types::ImuSample;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use trajectory::Generator;

const T0_S: f64 = 345_600.0;
const DT_S: f64 = 0.005;
const DEG: f64 = std::f64::consts::PI / 180.0;

/// Sensor errors added to exact static increments.
#[derive(Clone, Copy, Default)]
struct Errors {
    accel_bias_mps2: [f64; 3],
    gyro_bias_radps: [f64; 3],
    /// Velocity random walk, m/s/sqrt(s).
    vrw: f64,
    /// Angle random walk, rad/sqrt(s).
    arw: f64,
}

/// `seconds` of 200 Hz samples at rest (exact increments: at rest the body-frame rate and
/// specific force are constant, see tests/it/mechanization.rs) plus sensor errors; n + 1 samples.
fn static_window(pos: &Llh, rpy: [f64; 3], seconds: f64, e: Errors, seed: u64) -> Vec<ImuSample> {
    let q = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    let q_bn = q.inverse();
    let w = q_bn * earth::earth_rate_ned_radps(pos.lat_rad) + Vector3::from(e.gyro_bias_radps);
    let f =
        -(q_bn * earth::gravity_ned_mps2(pos.lat_rad, pos.h_m)) + Vector3::from(e.accel_bias_mps2);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n01 = Normal::new(0.0, 1.0).expect("valid normal");
    let n = (seconds / DT_S).round() as usize;
    (0..=n)
        .map(|k| {
            let mut dth = w * DT_S;
            let mut dv = f * DT_S;
            for i in 0..3 {
                dth[i] += e.arw * DT_S.sqrt() * n01.sample(&mut rng);
                dv[i] += e.vrw * DT_S.sqrt() * n01.sample(&mut rng);
            }
            ImuSample {
                t_s: T0_S + k as f64 * DT_S,
                dtheta_rad: dth.into(),
                dv_mps: dv.into(),
                temperature_c: f64::NAN,
            }
        })
        .collect()
}

fn navigation_grade() -> AlignConfig {
    AlignConfig {
        accel_bias_mps2: 25e-6 * earth::G0_MPS2,
        gyro_bias_radps: 0.005 * DEG / 3600.0,
        max_gyrocompass_std_rad: 0.5 * DEG,
        ..AlignConfig::default()
    }
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

const ATTITUDES_DEG: [[f64; 3]; 6] = [
    [2.0, -3.0, 135.0],
    [0.0, 0.0, 0.0],
    [-30.0, 20.0, -60.0],
    [170.0, -45.0, 10.0],
    [5.0, 80.0, -150.0],
    [-90.0, 10.0, 270.0],
];

#[test]
fn levelling_with_perfect_data_is_within_0_01_deg_at_several_attitudes() {
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    for rpy_deg in ATTITUDES_DEG {
        let rpy = rpy_deg.map(|x| x * DEG);
        let w = static_window(&pos, rpy, 20.0, Errors::default(), 1);
        let given = HeadingSource::Given {
            yaw_rad: rpy[2],
            std_rad: 1.0 * DEG,
        };
        let a = coarse_align(&w, &pos, given, &AlignConfig::default()).expect("static window");
        let err_r = wrap(a.rpy_rad[0] - rpy[0]) / DEG;
        let err_p = (a.rpy_rad[1] - rpy[1]) / DEG;
        println!(
            "levelling at {rpy_deg:?} deg: roll error {err_r:.2e} deg, pitch error {err_p:.2e} deg"
        );
        assert!(
            err_r.abs() < 0.01 && err_p.abs() < 0.01,
            "{rpy_deg:?}: {a:?}"
        );
        // The given heading is passed through; the attitude reproduces the truth.
        let q = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
        assert!(a.q_nb().angle_to(&q) < 1e-9, "{rpy_deg:?}");
        assert_eq!(a.att_std_rad[2], 1.0 * DEG);
    }
}

#[test]
fn gyrocompassing_with_perfect_navigation_grade_data_is_within_0_1_deg() {
    for &lat in &[0.0, 48.0, -60.0] {
        let pos = Llh::from_deg(lat, 11.0, 300.0);
        for rpy_deg in ATTITUDES_DEG {
            let rpy = rpy_deg.map(|x| x * DEG);
            let w = static_window(&pos, rpy, 120.0, Errors::default(), 1);
            let a = coarse_align(&w, &pos, HeadingSource::Gyrocompass, &navigation_grade())
                .expect("navigation-grade gyrocompassing");
            let q = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
            let err = a.q_nb().angle_to(&q) / DEG;
            let yaw_err = wrap(a.rpy_rad[2] - rpy[2]) / DEG;
            println!(
                "gyrocompass lat {lat} at {rpy_deg:?}: yaw error {yaw_err:.2e} deg, total \
                 attitude error {err:.2e} deg, reported yaw std {:.4} deg",
                a.att_std_rad[2] / DEG
            );
            // Near pitch 80 deg yaw and roll trade off; compare the attitude as a whole.
            assert!(err < 0.1, "lat {lat}, {rpy_deg:?}: {a:?}");
        }
    }
}

#[test]
fn gyrocompassing_with_navigation_grade_noise_and_bias_is_within_its_uncertainty() {
    // 0.005 deg/h gyro bias, 0.002 deg/sqrt(h) ARW, 25 ug accelerometer bias,
    // 10 ug/sqrt(Hz) accelerometer noise; 5 minutes at 48 deg.
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    let rpy = [2.0 * DEG, -3.0 * DEG, 135.0 * DEG];
    let b_g = 0.005 * DEG / 3600.0 / 3f64.sqrt();
    let b_a = 25e-6 * earth::G0_MPS2 / 3f64.sqrt();
    let e = Errors {
        accel_bias_mps2: [b_a, -b_a, b_a],
        gyro_bias_radps: [-b_g, b_g, b_g],
        vrw: 10e-6 * earth::G0_MPS2,
        arw: 0.002 * DEG / 60.0,
    };
    let mut worst = 0.0f64;
    for seed in 0..5 {
        let w = static_window(&pos, rpy, 300.0, e, seed);
        let a = coarse_align(&w, &pos, HeadingSource::Gyrocompass, &navigation_grade())
            .expect("navigation-grade gyrocompassing");
        let err = [
            wrap(a.rpy_rad[0] - rpy[0]),
            a.rpy_rad[1] - rpy[1],
            wrap(a.rpy_rad[2] - rpy[2]),
        ];
        println!(
            "seed {seed}: errors r/p/y {:.4} {:.4} {:.4} deg, reported std {:.4} {:.4} {:.4} deg",
            err[0] / DEG,
            err[1] / DEG,
            err[2] / DEG,
            a.att_std_rad[0] / DEG,
            a.att_std_rad[1] / DEG,
            a.att_std_rad[2] / DEG
        );
        for i in 0..3 {
            assert!(
                err[i].abs() < 3.0 * a.att_std_rad[i],
                "axis {i}: {err:?} {a:?}"
            );
        }
        worst = worst.max(err[2].abs());
    }
    assert!(worst < 0.1 * DEG, "worst heading error {} deg", worst / DEG);
}

#[test]
fn levelling_with_tactical_noise_is_within_its_uncertainty() {
    // 1 mg forward bias, 50 ug/sqrt(Hz) noise, 0.3 deg/s of
    // 200 Hz gyro noise: the tilt error is about bias / g.
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    let rpy = [-30.0 * DEG, 20.0 * DEG, -60.0 * DEG];
    let e = Errors {
        accel_bias_mps2: [1e-3 * earth::G0_MPS2, 0.0, 0.0],
        gyro_bias_radps: [0.0; 3],
        vrw: 50e-6 * earth::G0_MPS2,
        arw: 0.3 * DEG * DT_S.sqrt(),
    };
    let w = static_window(&pos, rpy, 30.0, e, 7);
    let cfg = AlignConfig {
        accel_bias_mps2: 1e-3 * earth::G0_MPS2,
        ..AlignConfig::default()
    };
    let given = HeadingSource::Given {
        yaw_rad: rpy[2],
        std_rad: 2.0 * DEG,
    };
    let a = coarse_align(&w, &pos, given, &cfg).expect("static window");
    let err_p = a.rpy_rad[1] - rpy[1];
    let err_r = wrap(a.rpy_rad[0] - rpy[0]);
    println!(
        "tactical levelling: roll {:.4} deg (std {:.4}), pitch {:.4} deg (std {:.4})",
        err_r / DEG,
        a.att_std_rad[0] / DEG,
        err_p / DEG,
        a.att_std_rad[1] / DEG
    );
    // A forward bias b tilts pitch by d/db atan2(g sin(p) + b, g cos(p)) b = b cos(p) / g.
    let expect_p = 1e-3 * earth::G0_MPS2 * rpy[1].cos() / earth::gravity_mps2(pos.lat_rad, pos.h_m);
    assert!(
        (err_p - expect_p).abs() < 0.1 * expect_p,
        "{err_p} vs {expect_p}"
    );
    assert!(err_p.abs() < 3.0 * a.att_std_rad[1] && err_r.abs() < 3.0 * a.att_std_rad[0]);
}

#[test]
fn a_driving_window_is_rejected_as_not_static() {
    let start = Llh::from_deg(48.1, 11.6, 520.0);
    let mut gen = Generator::new(trajectory::driving_profile(), start, T0_S, DT_S, 2);
    let mut w = vec![ImuSample {
        t_s: T0_S,
        ..Default::default()
    }];
    w.extend((0..(30.0 / DT_S) as usize).map(|_| gen.step().0));
    let r = coarse_align(&w, &start, HeadingSource::Gyrocompass, &navigation_grade());
    println!("driving window: {r:?}");
    match r {
        Err(e @ AlignError::NotStatic { .. }) => println!("  {e}"),
        other => panic!("expected NotStatic, got {other:?}"),
    }
}

#[test]
fn a_slow_steady_turn_is_rejected_by_the_mean_rate() {
    // Turning at 2 deg/s about the vertical: constant specific force, no segment variation.
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    let mut w = static_window(&pos, [0.0; 3], 20.0, Errors::default(), 1);
    for s in &mut w {
        s.dtheta_rad[2] += 2.0 * DEG * DT_S;
    }
    let r = coarse_align(&w, &pos, HeadingSource::Gyrocompass, &navigation_grade());
    assert!(
        matches!(
            r,
            Err(AlignError::NotStatic {
                cue: MotionCue::MeanRate,
                ..
            })
        ),
        "{r:?}"
    );
}

#[test]
fn a_pushed_vehicle_is_rejected_by_the_specific_force_variation() {
    // A 0.3 m/s^2 push along x during the last quarter of the window.
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    let mut w = static_window(&pos, [0.0; 3], 20.0, Errors::default(), 1);
    let n = w.len();
    for s in &mut w[3 * n / 4..] {
        s.dv_mps[0] += 0.3 * DT_S;
    }
    let r = coarse_align(&w, &pos, HeadingSource::Gyrocompass, &navigation_grade());
    assert!(
        matches!(
            r,
            Err(AlignError::NotStatic {
                cue: MotionCue::SpecificForceVariation,
                ..
            })
        ),
        "{r:?}"
    );
}

#[test]
fn bad_windows_give_typed_errors() {
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    let cfg = AlignConfig::default();
    let given = HeadingSource::Given {
        yaw_rad: 0.0,
        std_rad: 0.1,
    };
    let w = static_window(&pos, [0.0; 3], 5.0, Errors::default(), 1);
    assert!(matches!(
        coarse_align(&w, &pos, given, &cfg),
        Err(AlignError::TooShort { .. })
    ));
    assert!(matches!(
        coarse_align(&[], &pos, given, &cfg),
        Err(AlignError::TooShort { samples: 0, .. })
    ));
    let mut w = static_window(&pos, [0.0; 3], 20.0, Errors::default(), 1);
    w[100].dv_mps[1] = f64::NAN;
    assert_eq!(
        coarse_align(&w, &pos, given, &cfg),
        Err(AlignError::NonFinite { index: 100 })
    );
    let mut w = static_window(&pos, [0.0; 3], 20.0, Errors::default(), 1);
    w[200].t_s = w[199].t_s;
    assert_eq!(
        coarse_align(&w, &pos, given, &cfg),
        Err(AlignError::BadTimeStep { index: 200 })
    );
    // Standing on a lift accelerating up at 0.5 m/s^2: |f| != g.
    let mut w = static_window(&pos, [0.0; 3], 20.0, Errors::default(), 1);
    for s in &mut w {
        s.dv_mps[2] -= 0.5 * DT_S;
    }
    assert!(matches!(
        coarse_align(&w, &pos, given, &cfg),
        Err(AlignError::NotStatic {
            cue: MotionCue::GravityMismatch,
            ..
        })
    ));
}

#[test]
fn gyrocompassing_is_refused_for_a_tactical_gyro() {
    // Default configuration assumes a 1 deg/h gyro: at 48 deg that is a 5.7 deg heading
    // uncertainty, above the 5 deg limit.
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    let w = static_window(&pos, [0.0; 3], 60.0, Errors::default(), 1);
    let r = coarse_align(
        &w,
        &pos,
        HeadingSource::Gyrocompass,
        &AlignConfig::default(),
    );
    match r {
        Err(e @ AlignError::GyrocompassInaccurate { std_rad, .. }) => {
            println!("{e}");
            let expect = 1.0 * DEG / 3600.0 / (earth::OMEGA_IE_RADPS * pos.lat_rad.cos());
            assert!(
                (std_rad / expect - 1.0).abs() < 0.01,
                "{std_rad} vs {expect}"
            );
        }
        other => panic!("expected GyrocompassInaccurate, got {other:?}"),
    }
}

#[test]
fn an_aligned_strapdown_stays_at_rest() {
    let pos = Llh::from_deg(48.0, 11.0, 300.0);
    let rpy = [2.0 * DEG, -3.0 * DEG, 135.0 * DEG];
    let w = static_window(&pos, rpy, 120.0, Errors::default(), 1);
    let a = coarse_align(&w, &pos, HeadingSource::Gyrocompass, &navigation_grade())
        .expect("static window");
    let mut m = Strapdown::new(a.nav_state(pos));
    let more = static_window(&pos, rpy, 60.0, Errors::default(), 1);
    for s in &more[1..] {
        let mut s = *s;
        s.t_s += a.t_end_s - T0_S;
        m.update(&s).expect("valid sample");
    }
    let d = earth::ned_offset_m(&pos, &m.state().pos).norm();
    println!("aligned from perfect data, 60 s later: {d:.3e} m from the start");
    assert!(d < 1e-4, "{d} m");
}

/// In-motion alignment: yaw and pitch from the GNSS velocity, roll levelled with the specific
/// force predicted from the GNSS acceleration (a car in a banked turn, climbing).
#[test]
fn motion_alignment_recovers_the_attitude_from_gnss_velocity_and_specific_force() {
    use nav_core::align::{motion_align, MotionAlignConfig, MotionLevelling};
    let g = 9.81;
    for (roll, pitch, yaw) in [
        (0.0, 0.0, 30.0),
        (3.0, 2.0, -120.0),
        (-5.0, -4.0, 179.0),
        (8.0, 1.0, 90.0),
    ] {
        let rpy = [roll * DEG, pitch * DEG, yaw * DEG];
        let q = nav_core::attitude::quat_from_euler_zyx(rpy);
        let c_bn = q.to_rotation_matrix().into_inner();
        // velocity along the body x axis at 15 m/s
        let v = c_bn * Vector3::new(15.0, 0.0, 0.0);
        // turning left at 0.2 rad/s: centripetal acceleration along body -y, plus braking
        let a = c_bn * Vector3::new(-1.0, -3.0, 0.0);
        let f_b = c_bn.transpose() * (a - Vector3::new(0.0, 0.0, g));
        let lv = MotionLevelling {
            mean_f_body_mps2: f_b.into(),
            accel_ned_mps2: a.into(),
            accel_std_mps2: 0.05,
            gravity_mps2: g,
        };
        let al = motion_align(v.into(), 0.05, Some(&lv), &MotionAlignConfig::default()).unwrap();
        for (k, (got, want)) in al.rpy_rad.iter().zip(rpy).enumerate() {
            assert!(
                wrap(got - want).abs() < 1e-9,
                "axis {k}: {} vs {}",
                got / DEG,
                want / DEG
            );
        }
        // yaw sigma: course noise 0.05 / |v_H| rad with the 2 deg side-slip allowance
        let vh = v.x.hypot(v.y);
        let want = ((0.05 / vh).powi(2) + (2.0 * DEG).powi(2)).sqrt();
        assert!((al.att_std_rad[2] - want).abs() < 1e-12);
        // without levelling: roll 0 and the configured 10 deg
        let al = motion_align(v.into(), 0.05, None, &MotionAlignConfig::default()).unwrap();
        assert_eq!(al.rpy_rad[0], 0.0);
        assert!((al.att_std_rad[0] - 10.0 * DEG).abs() < 1e-12);
    }
    let e = motion_align([1.0, 1.0, 0.0], 0.05, None, &MotionAlignConfig::default()).unwrap_err();
    assert!(matches!(e, AlignError::TooSlow { .. }));
    assert!(e.to_string().contains("1.414"), "{e}");
    let e = motion_align(
        [f64::NAN, 1.0, 0.0],
        0.05,
        None,
        &MotionAlignConfig::default(),
    );
    assert!(e.is_err());
}

#[test]
fn course_from_displacement_needs_a_length_from_the_position_noise() {
    use nav_core::align::{course_from_displacement, CourseRule};
    let rule = CourseRule::default();
    // RTK: 2 cm per axis at both ends -> 2.83 cm, 1 deg needs 1.62 m
    let s = 0.02f64.hypot(0.02);
    let need = s / 1f64.to_radians();
    assert!((need - 1.6205).abs() < 1e-3, "{need}");
    // the slow rover: 0.6 m per 3-s fix interval is not enough, 1.2 m neither, 1.8 m is
    assert!(course_from_displacement(0.6, 0.0, s, &rule).is_none());
    assert!(course_from_displacement(0.0, 1.2, s, &rule).is_none());
    let c = course_from_displacement(-1.8 * 0.6, 1.8 * 0.8, s, &rule).unwrap();
    assert!((c.yaw_rad - 0.8f64.atan2(-0.6)).abs() < 1e-12);
    assert!((c.distance_m - 1.8).abs() < 1e-12);
    assert!((c.std_rad - s / 1.8).abs() < 1e-15 && c.std_rad < 1f64.to_radians());
    // single point (1.5 m): the 5 m cap applies, and the course says how poor it is
    let sp = 1.5f64.hypot(1.5);
    assert!(course_from_displacement(4.9, 0.0, sp, &rule).is_none());
    let c = course_from_displacement(5.0, 0.0, sp, &rule).unwrap();
    assert!(
        (c.std_rad.to_degrees() - 24.3).abs() < 0.1,
        "{}",
        c.std_rad.to_degrees()
    );
    // no movement, or bad input: no course
    assert!(course_from_displacement(0.0, 0.0, 0.0, &rule).is_none());
    assert!(course_from_displacement(f64::NAN, 1.0, s, &rule).is_none());
    assert!(course_from_displacement(10.0, 1.0, -1.0, &rule).is_none());
}

#[test]
fn the_track_course_extends_on_a_straight_start_and_stops_at_a_turn() {
    use nav_core::align::{CourseRule, TrackCourse};
    let (s, f) = (0.02f64.hypot(0.02), 0.02);
    let yaw = 130f64.to_radians();
    // straight at 130 deg, a fix every 0.6 m: the course over the first fix >= 5 m (5.4 m),
    // as a fixed 5 m look-ahead gives
    let mut t = TrackCourse::new(CourseRule::default());
    let mut settled_at = None;
    for k in 1..20 {
        let d = 0.6 * k as f64;
        if t.push(d * yaw.cos(), d * yaw.sin(), s, f) {
            settled_at = Some(d);
            break;
        }
    }
    let c = t.course().unwrap();
    assert!((settled_at.unwrap() - 5.4).abs() < 1e-9, "{settled_at:?}");
    assert!((c.distance_m - 5.4).abs() < 1e-9 && (c.yaw_rad - yaw).abs() < 1e-12);
    // 2.4 m straight, then a 90 deg right turn of 2.3 m radius at 0.6 m per fix: the course
    // of the straight part, not the chord across the turn
    let mut t = TrackCourse::new(CourseRule::default());
    let (mut n, mut e, mut h) = (0.0f64, 0.0f64, yaw);
    let mut settled = false;
    for k in 1..20 {
        if k > 4 {
            h += 0.6 / 2.3;
        }
        n += 0.6 * h.cos();
        e += 0.6 * h.sin();
        if t.push(n, e, s, f) {
            settled = true;
            break;
        }
    }
    let c = t.course().unwrap();
    assert!(settled);
    assert!(
        (c.yaw_rad - yaw).abs() < 0.5f64.to_radians(),
        "course {} deg",
        c.yaw_rad.to_degrees()
    );
    assert!((c.distance_m - 2.4).abs() < 1e-9, "{}", c.distance_m);
}
