//! `nav_core::imu_guard`: gaps bridged by the data's convention, implausible samples
//! rejected, faults reported; and the strapdown on a gapped record against the gapless one.
use nav_core::earth::Llh;
use nav_core::imu_guard::{
    FillUncertainty, GapIncrements, GuardConfig, GuardError, Implausible, ImuClass, ImuGuard,
    ImuLimits, Verdict, SLOPE_WINDOW_S,
};
use nav_core::strapdown::{NavState, Strapdown};
use nav_core::types::ImuSample;

const DT: f64 = 0.01;
const T0: f64 = 1000.0;

/// Sample k (ending at T0 + k DT) of smoothly varying rates: a turn of 10 deg/s modulated at
/// 0.5 Hz, specific force gravity plus a 1 m/s^2 oscillation. Increments are the exact
/// integrals of the rates over the interval.
fn rates(t: f64) -> ([f64; 3], [f64; 3]) {
    let w = 2.0 * std::f64::consts::PI * 0.5;
    (
        [0.01, -0.02, 0.1745 * (w * t).sin()],
        [(w * t).cos(), 0.3, -9.81 + 0.2 * (w * t).sin()],
    )
}

fn sample_between(t0: f64, t1: f64) -> ImuSample {
    // Simpson's rule per component: exact for the low frequencies here to ~1e-12
    let (wa, fa) = rates(t0);
    let (wm, fm) = rates(0.5 * (t0 + t1));
    let (wb, fb) = rates(t1);
    let h = t1 - t0;
    let simpson = |a: [f64; 3], m: [f64; 3], b: [f64; 3]| {
        [0, 1, 2].map(|i| h / 6.0 * (a[i] + 4.0 * m[i] + b[i]))
    };
    ImuSample {
        t_s: t1,
        dtheta_rad: simpson(wa, wm, wb),
        dv_mps: simpson(fa, fm, fb),
        temperature_c: 20.0,
    }
}

fn record(n: usize) -> Vec<ImuSample> {
    (1..=n)
        .map(|k| sample_between(T0 + (k - 1) as f64 * DT, T0 + k as f64 * DT))
        .collect()
}

fn guard(increments: GapIncrements) -> ImuGuard {
    let mut cfg = GuardConfig::new(DT);
    cfg.increments = increments;
    ImuGuard::new(cfg, T0, None).unwrap()
}

/// Runs the guard over `imu`; returns every sample to integrate, in order.
fn condition(g: &mut ImuGuard, imu: &[ImuSample]) -> Vec<ImuSample> {
    let mut out = Vec::new();
    for s in imu {
        match g.check(s).unwrap() {
            Verdict::Use(c) => {
                out.extend(c.fill);
                out.push(c.sample);
            }
            Verdict::Reject(_) => {}
        }
    }
    out
}

fn sum(v: &[ImuSample], f: impl Fn(&ImuSample) -> [f64; 3]) -> [f64; 3] {
    v.iter().fold([0.0; 3], |a, s| {
        let x = f(s);
        [a[0] + x[0], a[1] + x[1], a[2] + x[2]]
    })
}

#[test]
fn gapless_record_passes_unchanged() {
    let imu = record(500);
    let mut g = guard(GapIncrements::Auto);
    let out = condition(&mut g, &imu);
    assert!(out == imu, "samples changed");
    let c = g.counters();
    assert_eq!((c.passed, c.gaps, c.rejected), (500, 0, 0));
}

#[test]
fn lost_samples_are_filled_to_the_true_interval_for_1_4_and_50_missing() {
    for missing in [1usize, 4, 50] {
        let imu = record(400);
        let mut gapped = imu.clone();
        gapped.drain(200..200 + missing);
        // auto decides "lost" from the specific force; forcing it gives the same
        for mode in [GapIncrements::Auto, GapIncrements::Sample] {
            let mut g = guard(mode);
            let out = condition(&mut g, &gapped);
            let c = *g.counters();
            assert_eq!(c.gaps, 1, "{missing} {mode:?}");
            assert_eq!(c.gaps_filled, 1);
            assert_eq!(c.missing_samples, missing as u64);
            assert_eq!(c.synthetic_samples, missing as u64);
            // the integrated record covers every interval once, at the nominal step
            assert_eq!(out.len(), imu.len());
            for (a, b) in out.iter().zip(&imu) {
                assert!((a.t_s - b.t_s).abs() < 1e-9, "{} vs {}", a.t_s, b.t_s);
            }
            // the filled increments are the interpolated rates: over the gap the sums of
            // dtheta and dv match the lost ones to the curvature of the rates
            let lo = 199;
            let hi = 200 + missing + 1;
            let want_v = sum(&imu[lo..hi], |s| s.dv_mps);
            let got_v = sum(&out[lo..hi], |s| s.dv_mps);
            let want_a = sum(&imu[lo..hi], |s| s.dtheta_rad);
            let got_a = sum(&out[lo..hi], |s| s.dtheta_rad);
            let span = (hi - lo) as f64 * DT;
            // the fill's error model for a rate r(t) = A sin(w t): the quadratic through
            // the rates at both ends has the curvature error of an interpolation,
            // (w s)^2 / 8 x A x s, and its start slope, fitted over the last
            // SLOPE_WINDOW_S, is biased by about w^2 A x SLOPE_WINDOW_S / 2, which moves
            // the integral by that times s^2 / 6
            let w = std::f64::consts::PI;
            let k =
                (w * span).powi(2) / 8.0 * span + w * w * SLOPE_WINDOW_S / 2.0 * span * span / 6.0;
            for i in 0..3 {
                assert!(
                    (got_v[i] - want_v[i]).abs() <= 1.0 * k + 1e-12,
                    "{missing}: dv[{i}] {} vs {}",
                    got_v[i],
                    want_v[i]
                );
                assert!(
                    (got_a[i] - want_a[i]).abs() <= 0.1745 * k + 1e-12,
                    "{missing}: dtheta[{i}] {} vs {}",
                    got_a[i],
                    want_a[i]
                );
            }
            // gravity is not lost: the vertical increment over the gap is -9.81 x span
            assert!((got_v[2] / span + 9.81).abs() < 0.25, "{}", got_v[2] / span);
        }
    }
}

#[test]
fn an_increment_that_spans_the_gap_is_used_as_it_is() {
    // a sensor that keeps accumulating: the sample after the gap covers the whole gap
    for missing in [1usize, 4, 50] {
        let mut imu = record(300);
        let t_a = imu[149].t_s;
        let t_b = imu[150 + missing].t_s;
        imu.drain(150..150 + missing);
        imu[150] = sample_between(t_a, t_b);
        for mode in [GapIncrements::Auto, GapIncrements::Span] {
            let mut g = guard(mode);
            let out = condition(&mut g, &imu);
            assert!(out == imu, "{missing} {mode:?}: nothing added or changed");
            let c = g.counters();
            assert_eq!((c.gaps, c.gaps_spanned, c.gaps_filled), (1, 1, 0));
            assert_eq!(c.missing_samples, missing as u64);
        }
    }
}

#[test]
fn implausible_samples_are_rejected_and_their_interval_bridged() {
    let mut imu = record(300);
    imu[100].dv_mps[0] = 1e6; // 1e8 m/s^2
    imu[200].dtheta_rad[2] = 1e300;
    let mut g = guard(GapIncrements::Auto);
    let mut why = Vec::new();
    let mut out = Vec::new();
    for s in &imu {
        match g.check(s).unwrap() {
            Verdict::Use(c) => {
                out.extend(c.fill);
                out.push(c.sample);
            }
            Verdict::Reject(w) => why.push((s.t_s, w)),
        }
    }
    assert_eq!(why.len(), 2);
    assert!(matches!(why[0].1, Implausible::Accel { axis: 0, .. }));
    assert!(matches!(why[1].1, Implausible::Rate { axis: 2, .. }));
    assert_eq!(g.counters().rejected, 2);
    // each rejected interval is filled: the integrated record still covers every interval
    assert_eq!(out.len(), imu.len());
    assert_eq!(g.counters().gaps_filled, 2);
    // and the fills are plausible (interpolated between the neighbours)
    for s in &out {
        assert!(s.dv_mps.iter().all(|v| v.abs() < 0.2), "{s:?}");
    }
}

#[test]
fn limits_follow_the_class_and_can_be_disabled() {
    let nav = ImuLimits::for_class(ImuClass::Navigation);
    let mems = ImuLimits::for_class(ImuClass::ConsumerMems);
    assert!(nav.max_rate_radps < mems.max_rate_radps);
    assert!((nav.max_rate_radps.to_degrees() - 550.0).abs() < 1e-9);
    // 800 deg/s: beyond a navigation-grade range, within a MEMS one
    let mut s = sample_between(T0, T0 + DT);
    s.dtheta_rad[0] = 800f64.to_radians() * DT;
    let mut cfg = GuardConfig::new(DT);
    cfg.limits = nav;
    assert!(matches!(
        ImuGuard::new(cfg, T0, None).unwrap().check(&s),
        Ok(Verdict::Reject(Implausible::Rate { axis: 0, .. }))
    ));
    cfg.limits = mems;
    assert!(matches!(
        ImuGuard::new(cfg, T0, None).unwrap().check(&s),
        Ok(Verdict::Use(_))
    ));
    cfg.limits = ImuLimits::none();
    s.dv_mps[1] = 1e300;
    assert!(matches!(
        ImuGuard::new(cfg, T0, None).unwrap().check(&s),
        Ok(Verdict::Use(_))
    ));
    s.dv_mps[1] = f64::NAN;
    assert!(matches!(
        ImuGuard::new(cfg, T0, None).unwrap().check(&s),
        Ok(Verdict::Reject(Implausible::NonFinite))
    ));
}

#[test]
fn long_gaps_and_time_reversals_are_faults() {
    let imu = record(10);
    let mut g = guard(GapIncrements::Auto);
    g.check(&imu[0]).unwrap();
    let mut late = imu[1];
    late.t_s += 10.0;
    assert!(matches!(
        g.check(&late),
        Err(GuardError::GapTooLong { dt_s, .. }) if (dt_s - 10.01).abs() < 1e-9
    ));
    let mut early = imu[1];
    early.t_s = imu[0].t_s;
    assert!(matches!(
        g.check(&early),
        Err(GuardError::NotIncreasing { .. })
    ));
    assert!(ImuGuard::new(GuardConfig::new(0.0), T0, None).is_err());
}

/// The strapdown's state after integrating `imu` from a start at 10 m/s north.
fn strapdown_end(imu: &[ImuSample]) -> NavState {
    let start = NavState::from_rpy(
        T0,
        Llh::from_deg(48.2, 16.37, 220.0),
        nalgebra::Vector3::new(10.0, 0.0, 0.0),
        [0.0, 0.0, 0.0],
    );
    let mut sd = Strapdown::new(start);
    for s in imu {
        sd.update(s).unwrap();
    }
    *sd.state()
}

#[test]
fn strapdown_on_a_filled_record_stays_with_the_gapless_one() {
    let imu = record(2000);
    let reference = strapdown_end(&imu);
    for missing in [1usize, 4, 50] {
        let mut gapped = imu.clone();
        gapped.drain(1000..1000 + missing);
        let mut g = guard(GapIncrements::Auto);
        let filled = strapdown_end(&condition(&mut g, &gapped));
        // today's behaviour: the sample after the gap integrated over the whole gap
        let mut g = guard(GapIncrements::Span);
        let naive = strapdown_end(&condition(&mut g, &gapped));
        let dh = |s: &NavState| (s.pos.h_m - reference.pos.h_m).abs();
        let dvd = |s: &NavState| (s.vel_ned_mps.z - reference.vel_ned_mps.z).abs();
        println!(
            "{missing} missing: height error filled {:.2e} m, naive {:.2e} m; v_D error {:.2e} vs {:.2e} m/s",
            dh(&filled),
            dh(&naive),
            dvd(&filled),
            dvd(&naive)
        );
        // the naive integration loses missing x 9.81 x 0.01 m/s of vertical velocity
        assert!(dvd(&naive) > 0.8 * missing as f64 * 9.81 * DT);
        // the fill keeps it to the interpolation error of the rates (1e-3 of that at 50)
        assert!(dvd(&filled) < 1e-2 * dvd(&naive), "{missing}");
        assert!(dh(&filled) < 1e-2 * dh(&naive), "{missing}");
    }
}

/// Runs the guard over `imu` with `lost` samples removed at `at`; returns the fill's
/// uncertainty and its error (fill minus the lost increments, summed) per axis.
fn fill_error(imu: &[ImuSample], at: usize, lost: usize) -> (FillUncertainty, [f64; 6]) {
    let mut g = guard(GapIncrements::Sample);
    let mut unc = None;
    let mut err = [0.0; 6];
    for (k, s) in imu.iter().enumerate() {
        if (at..at + lost).contains(&k) {
            for i in 0..3 {
                err[i] -= s.dtheta_rad[i];
                err[3 + i] -= s.dv_mps[i];
            }
            continue;
        }
        if let Verdict::Use(c) = g.check(s).unwrap() {
            if k == at + lost {
                unc = Some(c.fill.uncertainty());
                for f in c.fill {
                    for i in 0..3 {
                        err[i] += f.dtheta_rad[i];
                        err[3 + i] += f.dv_mps[i];
                    }
                }
            }
        }
    }
    (unc.unwrap(), err)
}

#[test]
fn the_fill_uncertainty_covers_a_rate_that_bends_inside_the_gap_and_not_a_steady_ramp() {
    // yaw rate and lateral force: a steady ramp (the fill is exact), then a turn that ends
    // inside the gap (rate 0.3 rad/s easing to 0 with a 0.1 s time constant at the gap's middle)
    let ramp = |t: f64| ([0.0, 0.0, 0.05 * t], [0.0, 0.2 * t, -9.81]);
    let bend = |t: f64| {
        let x = 0.5 * (1.0 - ((t - 1.25) / 0.1).tanh());
        ([0.0, 0.0, 0.3 * x], [0.0, 3.0 * x, -9.81])
    };
    for (name, f, bends) in [
        ("ramp", &ramp as &dyn Fn(f64) -> ([f64; 3], [f64; 3]), false),
        ("bend", &bend, true),
    ] {
        // exact integrals by a fine Simpson sum
        let imu: Vec<ImuSample> = (1..=200)
            .map(|k| {
                let (t0, t1) = ((k - 1) as f64 * DT, k as f64 * DT);
                let h = (t1 - t0) / 20.0;
                let mut a = [0.0; 6];
                for j in 0..20 {
                    let (u0, um, u1) = (
                        t0 + j as f64 * h,
                        t0 + (j as f64 + 0.5) * h,
                        t0 + (j + 1) as f64 * h,
                    );
                    let (wa, fa) = f(u0);
                    let (wm, fm) = f(um);
                    let (wb, fb) = f(u1);
                    for i in 0..3 {
                        a[i] += h / 6.0 * (wa[i] + 4.0 * wm[i] + wb[i]);
                        a[3 + i] += h / 6.0 * (fa[i] + 4.0 * fm[i] + fb[i]);
                    }
                }
                ImuSample {
                    t_s: T0 + t1,
                    dtheta_rad: [a[0], a[1], a[2]],
                    dv_mps: [a[3], a[4], a[5]],
                    temperature_c: 20.0,
                }
            })
            .collect();
        // 50 samples (0.5 s) lost from t = 1.0 s
        let (u, e) = fill_error(&imu, 100, 50);
        println!(
            "{name}: yaw error {:.3e} rad, sigma {:.3e}; lateral dv error {:.3e} m/s, sigma {:.3e}",
            e[2], u.dtheta_rad[2], e[4], u.dv_mps[1]
        );
        assert!((u.span_s - 0.5).abs() < 1e-9, "{}", u.span_s);
        if bends {
            // the error is real (the fill does not know the turn ended) and within 2 sigma,
            // and the sigma is not more than 5x the error (no blanket widening)
            assert!(e[2].abs() > 1e-3, "{}", e[2]);
            assert!(e[2].abs() <= 2.0 * u.dtheta_rad[2]);
            assert!(u.dtheta_rad[2] <= 5.0 * e[2].abs());
            assert!(e[4].abs() <= 2.0 * u.dv_mps[1]);
        } else {
            // a steady ramp: the fill is exact and nothing is widened
            assert!(e[2].abs() < 1e-9 && e[4].abs() < 1e-9, "{e:?}");
            assert!(u.dtheta_rad[2] < 1e-9, "{:?}", u.dtheta_rad);
            assert!(u.dv_mps[1] < 1e-9, "{:?}", u.dv_mps);
        }
    }
}
