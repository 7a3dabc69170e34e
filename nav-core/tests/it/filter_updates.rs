//! GNSS update behaviour: innovation gating (outliers, forced recovery), bad inputs, the
//! Joseph-form update against an independent computation, closed-loop feedback and reset,
//! the velocity update with a lever arm, construction errors, and the covariance
//! prediction rate.

use nalgebra::{SMatrix, Vector3};
use nav_core::config::{FilterConfig, GateProbability, Gating};
use nav_core::earth;
use nav_core::filter::{Filter, FilterError, InitialUncertainty, STATUS_LAST_FIX_REJECTED};
use nav_core::model::{LayoutError, IDX_POS, LAYOUT_N, LAYOUT_NBK};
use nav_core::types::FixQuality;
use test_support::filter_sim::*;
use test_support::stats::chi2_inv;

const N18: usize = LAYOUT_NBK.dim();

fn nbk_cfg(sc: &SimConfig) -> FilterConfig {
    FilterConfig {
        lever_arm_body_m: sc.lever_arm_body_m,
        ..FilterConfig::source_nbk_model()
    }
}

fn horiz(d: &[f64]) -> f64 {
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

#[test]
fn a_5_m_gnss_outlier_is_rejected_counted_and_the_solution_does_not_jump() {
    let sc = SimConfig::nbk(100.0);
    let cfg = nbk_cfg(&sc);
    let mut sim = Sim::new(sc, 5);
    let mut f: Filter<f64, N18> = start_filter(&mut sim, LAYOUT_NBK, &cfg, &test_uncertainty());
    let mut fixes = 0;
    while fixes < 150 {
        let e = sim.step();
        f.propagate(&e.imu).unwrap();
        let Some(mut fix) = e.gnss else { continue };
        fixes += 1;
        if fixes == 120 {
            let (_, _, dr) = nav_errors(f.nav_state(), &e.truth);
            let err_before = horiz(&dr);
            let p = earth::displace(
                &earth::Llh {
                    lat_rad: fix.lat_rad,
                    lon_rad: fix.lon_rad,
                    h_m: fix.h_m,
                },
                &Vector3::new(3.0, 4.0, 0.0),
            );
            fix.lat_rad = p.lat_rad;
            fix.lon_rad = p.lon_rad;
            let out = f.update_gnss(&fix).unwrap();
            let (_, _, dr) = nav_errors(f.nav_state(), &e.truth);
            println!(
                "outlier: innovation [{:.3}, {:.3}, {:.3}] m, NIS {:.0} vs {:.2}; error before {:.3} m after {:.3} m",
                out.innovation[0], out.innovation[1], out.innovation[2], out.nis, out.nis_threshold, err_before, horiz(&dr)
            );
            assert!(!out.accepted);
            assert!(out.nis > out.nis_threshold);
            assert!((out.innovation[0] - 3.0).abs() < 0.2 && (out.innovation[1] - 4.0).abs() < 0.2);
            assert_eq!(f.counters().gnss_rejected, 1);
            assert_ne!(f.status() & STATUS_LAST_FIX_REJECTED, 0);
            // the solution is untouched by the outlier: same error as just before it
            assert!((horiz(&dr) - err_before).abs() < 1e-12);
            assert!(horiz(&dr) < 0.1);
            continue;
        }
        let out = f.update_gnss(&fix).unwrap();
        assert!(out.accepted, "fix {fixes}: NIS {}", out.nis);
        if fixes > 120 {
            let (_, _, dr) = nav_errors(f.nav_state(), &e.truth);
            assert!(horiz(&dr) < 0.1, "fix {fixes}: error {} m", horiz(&dr));
            assert_eq!(f.status() & STATUS_LAST_FIX_REJECTED, 0);
        }
    }
    assert_eq!(f.counters().gnss_rejected, 1);
    assert_eq!(f.counters().gnss_accepted, 149);
}

#[test]
fn a_permanent_gnss_jump_is_accepted_after_the_configured_number_of_rejections() {
    let sc = SimConfig::nbk(100.0);
    let mut cfg = nbk_cfg(&sc);
    cfg.gating = Gating::with_probability(GateProbability::P999, 5);
    let mut sim = Sim::new(sc, 6);
    let mut f: Filter<f64, N18> = start_filter(&mut sim, LAYOUT_NBK, &cfg, &test_uncertainty());
    let mut fixes = 0;
    let mut outcomes = Vec::new();
    while fixes < 80 {
        let e = sim.step();
        f.propagate(&e.imu).unwrap();
        let Some(mut fix) = e.gnss else { continue };
        fixes += 1;
        if fixes > 60 {
            // reference station change: every later fix is 5 m east
            let p = earth::displace(
                &earth::Llh {
                    lat_rad: fix.lat_rad,
                    lon_rad: fix.lon_rad,
                    h_m: fix.h_m,
                },
                &Vector3::new(0.0, 5.0, 0.0),
            );
            fix.lat_rad = p.lat_rad;
            fix.lon_rad = p.lon_rad;
            outcomes.push(f.update_gnss(&fix).unwrap());
        } else {
            f.update_gnss(&fix).unwrap();
        }
    }
    let rejected: Vec<bool> = outcomes.iter().map(|o| !o.accepted).collect();
    assert_eq!(&rejected[..5], &[true; 5]);
    assert!(outcomes[5].accepted && outcomes[5].forced);
    assert_eq!(f.counters().gnss_forced, 1);
    assert_eq!(f.counters().gnss_rejected, 5);
    // afterwards the filter follows the new reference
    let last = outcomes.last().unwrap();
    assert!(last.accepted && !last.forced, "{last:?}");
    assert!(horiz(&last.innovation[..3]) < 0.5);
}

#[test]
fn nan_inf_and_mistimed_inputs_are_rejected_and_the_filter_keeps_working() {
    let sc = SimConfig::nbk(100.0);
    let cfg = nbk_cfg(&sc);
    let mut sim = Sim::new(sc, 7);
    let mut f: Filter<f32, N18> = start_filter(&mut sim, LAYOUT_NBK, &cfg, &test_uncertainty());
    let mut fixes = 0;
    let mut max_err: f64 = 0.0;
    while fixes < 60 {
        let e = sim.step();
        if let (20, Some(fix)) = (fixes, e.gnss) {
            let before = *f.nav_state();
            let p_before = *f.covariance();
            let mut bad = e.imu;
            bad.dv_mps[1] = f64::NAN;
            assert_eq!(f.propagate(&bad), Err(FilterError::NonFiniteImu));
            bad = e.imu;
            bad.dtheta_rad[2] = f64::INFINITY;
            assert_eq!(f.propagate(&bad), Err(FilterError::NonFiniteImu));
            bad = e.imu;
            bad.t_s = f64::NAN;
            assert_eq!(f.propagate(&bad), Err(FilterError::NonFiniteImu));
            bad = e.imu;
            bad.t_s = before.t_s - 0.01;
            assert!(matches!(
                f.propagate(&bad),
                Err(FilterError::ImuTimeStep { .. })
            ));
            bad.t_s = before.t_s + 5.0;
            assert!(matches!(
                f.propagate(&bad),
                Err(FilterError::ImuTimeStep { .. })
            ));
            assert_eq!(*f.nav_state(), before);
            assert_eq!(*f.covariance(), p_before);
            assert_eq!(f.counters().imu_rejected, 5);
            let mut g = fix;
            g.lat_rad = f64::NAN;
            assert_eq!(f.update_gnss(&g), Err(FilterError::InvalidGnss));
            g = fix;
            g.pos_std_ned_m[0] = 0.0;
            assert_eq!(f.update_gnss(&g), Err(FilterError::InvalidGnss));
            g = fix;
            g.quality = FixQuality::NoFix;
            assert_eq!(f.update_gnss(&g), Err(FilterError::InvalidGnss));
            g = fix;
            g.has_velocity = true;
            g.vel_ned_mps = [f64::NAN; 3];
            assert_eq!(f.update_gnss(&g), Err(FilterError::InvalidGnss));
            g = fix;
            g.t_s += 0.5;
            assert!(matches!(
                f.update_gnss(&g),
                Err(FilterError::GnssTime { .. })
            ));
            assert_eq!(f.counters().gnss_invalid, 5);
            assert_eq!(*f.nav_state(), before);
            let s = f.solution();
            assert!(s.lat_rad.is_finite() && s.pos_std_ned_m.iter().all(|v| v.is_finite()));
        }
        f.propagate(&e.imu).unwrap();
        if let Some(fix) = e.gnss {
            let out = f.update_gnss(&fix).unwrap();
            assert!(out.accepted);
            fixes += 1;
            if fixes > 10 {
                let (_, _, dr) = nav_errors(f.nav_state(), &e.truth);
                max_err = max_err.max(horiz(&dr));
            }
        }
    }
    println!("after rejected inputs: max position error {max_err:.3} m");
    assert!(max_err < 0.1);
    assert_eq!(f.counters().numerical_failures, 0);
}

#[test]
fn joseph_update_matches_an_independent_computation_and_is_exactly_symmetric() {
    // no lever arm: H = [0 0 I 0], z = predicted - measured
    let mut sc = SimConfig::nbk(100.0);
    sc.lever_arm_body_m = [0.0; 3];
    let cfg = nbk_cfg(&sc);
    let mut sim = Sim::new(sc, 8);
    let mut f: Filter<f64, N18> = start_filter(&mut sim, LAYOUT_NBK, &cfg, &test_uncertainty());
    let mut fixes = 0;
    while fixes < 30 {
        let e = sim.step();
        f.propagate(&e.imu).unwrap();
        let Some(fix) = e.gnss else { continue };
        fixes += 1;
        if fixes < 30 {
            f.update_gnss(&fix).unwrap();
            continue;
        }
        f.predict_covariance().unwrap();
        let p0 = SMatrix::<f64, N18, N18>::from_fn(|i, j| f.covariance()[i][j]);
        let nav0 = *f.nav_state();
        // z = predicted - measured through the local curvilinear map (radii at the estimate)
        let r = earth::radii(nav0.pos.lat_rad);
        let z = Vector3::new(
            (nav0.pos.lat_rad - fix.lat_rad) * (r.meridian_m + nav0.pos.h_m),
            (nav0.pos.lon_rad - fix.lon_rad)
                * (r.transverse_m + nav0.pos.h_m)
                * nav0.pos.lat_rad.cos(),
            fix.h_m - nav0.pos.h_m,
        );
        // which agrees with the exact ECEF offset to far below the GNSS noise
        let exact = earth::ned_offset_m(
            &earth::Llh {
                lat_rad: fix.lat_rad,
                lon_rad: fix.lon_rad,
                h_m: fix.h_m,
            },
            &nav0.pos,
        );
        assert!((z - exact).norm() < 1e-6, "{z:?} vs {exact:?}");
        let out = f.update_gnss(&fix).unwrap();
        assert!(out.accepted);
        // independent textbook computation
        let mut h = SMatrix::<f64, 3, N18>::zeros();
        for i in 0..3 {
            h[(i, IDX_POS + i)] = 1.0;
        }
        let r =
            SMatrix::<f64, 3, 3>::from_diagonal(&Vector3::from(fix.pos_std_ned_m.map(|s| s * s)));
        let s = h * p0 * h.transpose() + r;
        let k = p0 * h.transpose() * s.try_inverse().unwrap();
        let a = SMatrix::<f64, N18, N18>::identity() - k * h;
        let p1 = a * p0 * a.transpose() + k * r * k.transpose();
        let dx = k * z;
        let p = f.covariance();
        let mut max_rel = 0.0f64;
        for i in 0..N18 {
            for j in 0..N18 {
                assert_eq!(
                    p[i][j].to_bits(),
                    p[j][i].to_bits(),
                    "not exactly symmetric at {i},{j}"
                );
                let scale = (p1[(i, i)] * p1[(j, j)]).sqrt();
                max_rel = max_rel.max((p[i][j] - p1[(i, j)]).abs() / scale);
            }
        }
        println!(
            "Joseph update vs nalgebra: max |dP| / sqrt(Pii Pjj) = {max_rel:.2e}; NIS {:.3}",
            out.nis
        );
        assert!(max_rel < 1e-9);
        let nis_ref = (z.transpose() * s.try_inverse().unwrap() * z)[0];
        assert!((out.nis - nis_ref).abs() < 1e-9 * nis_ref.max(1.0));
        for i in 0..3 {
            assert!((out.innovation_var[i] - s[(i, i)]).abs() < 1e-12);
            assert!((out.innovation[i] + z[i]).abs() < 1e-12);
        }
        // feedback: nominal position moved by -dx_r, velocity by -dx_v
        let nav1 = f.nav_state();
        let moved = earth::ned_offset_m(&nav0.pos, &nav1.pos);
        for i in 0..3 {
            assert!(
                (moved[i] + dx[IDX_POS + i]).abs() < 1e-6,
                "{moved:?} vs {dx:?}"
            );
            let dv = nav1.vel_ned_mps[i] - nav0.vel_ned_mps[i];
            assert!((dv + dx[3 + i]).abs() < 1e-12);
        }
        // accelerometer bias estimate moved by -dx_b (b_GM + b_RW)
        assert!(f.covariance_is_positive_definite());
    }
}

#[test]
fn feedback_resets_the_error_state_so_a_repeated_fix_has_a_small_innovation() {
    // static vehicle, filter started 3 m north / 2 m east of the truth with a 10 m sigma
    let mut sc = SimConfig::nbk(100.0);
    sc.motion = Motion::Static;
    sc.lever_arm_body_m = [0.0; 3];
    let cfg = nbk_cfg(&sc);
    let mut sim = Sim::new(sc, 9);
    let unc = InitialUncertainty {
        pos_sigma_m: [10.0; 3],
        ..test_uncertainty()
    };
    let mut init = *sim.truth();
    init.pos = earth::displace(&init.pos, &Vector3::new(3.0, 2.0, 0.0));
    let mut f: Filter<f64, N18> = Filter::new(LAYOUT_NBK, &cfg, init, &unc).unwrap();
    let fix = loop {
        let e = sim.step();
        f.propagate(&e.imu).unwrap();
        if let Some(g) = e.gnss {
            break g;
        }
    };
    let first = f.update_gnss(&fix).unwrap();
    let second = f.update_gnss(&fix).unwrap();
    println!(
        "first innovation {:?}, second {:?}",
        &first.innovation[..3],
        &second.innovation[..3]
    );
    assert!((first.innovation[0] + 3.0).abs() < 0.1 && (first.innovation[1] + 2.0).abs() < 0.1);
    // after feedback the nominal sits where the update put it; the same fix again is within a
    // few sigma of its (now small) innovation covariance
    assert!(
        horiz(&second.innovation[..3]) < 0.03,
        "{:?}",
        second.innovation
    );
    assert!(f
        .block_estimate(nav_core::model::BlockKind::AccelBias)
        .unwrap()
        .iter()
        .all(|v| v.is_finite()));
}

#[test]
fn velocity_updates_with_a_lever_arm_have_consistent_innovations() {
    // 10 runs of 300 s with 6-dimensional (position + velocity) updates, antenna 1.3 m away:
    // the average NIS must be 6 within its 99% band
    let mut sc = SimConfig::nbk(100.0);
    sc.gnss_velocity = true;
    let mut cfg = nbk_cfg(&sc);
    cfg.use_gnss_velocity = true;
    cfg.gating = Gating::disabled();
    let mut nis_sum = 0.0;
    let mut n = 0usize;
    for run in 0..10 {
        let mut sim = Sim::new(sc, 300 + run);
        let mut f: Filter<f64, N18> = start_filter(&mut sim, LAYOUT_NBK, &cfg, &test_uncertainty());
        let mut fixes = 0;
        while fixes < 300 {
            let e = sim.step();
            f.propagate(&e.imu).unwrap();
            if let Some(fix) = e.gnss {
                let out = f.update_gnss(&fix).unwrap();
                assert_eq!(out.dim, 6);
                nis_sum += out.nis;
                n += 1;
                fixes += 1;
            }
        }
    }
    let avg = nis_sum / n as f64;
    let dof = 6.0 * n as f64;
    let lo = chi2_inv(0.005, dof) / n as f64;
    let hi = chi2_inv(0.995, dof) / n as f64;
    println!("velocity+position updates: average NIS {avg:.3} over {n} fixes (99% band [{lo:.3}, {hi:.3}])");
    assert!(avg > lo && avg < hi);
}

#[test]
fn construction_errors_are_typed() {
    let cfg = FilterConfig::source_nbk_model();
    let init = initial_truth(0.0);
    let unc = test_uncertainty();
    let e = Filter::<f32, 15>::new(LAYOUT_NBK, &cfg, init, &unc).unwrap_err();
    assert_eq!(
        e,
        FilterError::Layout(LayoutError::DimensionMismatch {
            layout: 18,
            filter: 15
        })
    );
    assert!(format!("{e}").contains("18 states"));
    let mut bad = cfg;
    bad.accel.s_n[0] = -1.0;
    assert!(matches!(
        Filter::<f32, 15>::new(LAYOUT_N, &bad, init, &unc),
        Err(FilterError::Config(_))
    ));
    let mut nan_init = init;
    nan_init.vel_ned_mps.x = f64::NAN;
    assert_eq!(
        Filter::<f32, 15>::new(LAYOUT_N, &cfg, nan_init, &unc).unwrap_err(),
        FilterError::InitialState
    );
    assert!(Filter::<f32, 15>::new(LAYOUT_N, &cfg, init, &unc).is_ok());
}

#[test]
fn covariance_prediction_at_10_hz_matches_prediction_every_epoch() {
    // same 10-minute 200 Hz drive: prediction every IMU epoch vs every 0.1 s (the default)
    let sc = SimConfig::nbk(200.0);
    let cfg_fast = FilterConfig {
        cov_predict_interval_s: 0.0,
        ..nbk_cfg(&sc)
    };
    let cfg_slow = nbk_cfg(&sc);
    let mut sim = Sim::new(sc, 11);
    let unc = test_uncertainty();
    let init = sim.perturbed_initial(&unc);
    let mut a: Filter<f64, N18> = Filter::new(LAYOUT_NBK, &cfg_fast, init, &unc).unwrap();
    let mut b: Filter<f64, N18> = Filter::new(LAYOUT_NBK, &cfg_slow, init, &unc).unwrap();
    let (mut max_dp, mut max_sd_rel) = (0.0f64, 0.0f64);
    for _ in 0..(600 * 200) {
        let e = sim.step();
        a.propagate(&e.imu).unwrap();
        b.propagate(&e.imu).unwrap();
        if let Some(fix) = e.gnss {
            a.update_gnss(&fix).unwrap();
            b.update_gnss(&fix).unwrap();
            let (_, _, dr) = nav_errors(b.nav_state(), a.nav_state());
            max_dp = max_dp.max(horiz(&dr));
            for (x, y) in a.state_std().iter().zip(b.state_std().iter()) {
                max_sd_rel = max_sd_rel.max((x - y).abs() / x);
            }
        }
    }
    println!(
        "10 Hz vs 200 Hz covariance prediction: max position difference {max_dp:.2e} m, max relative sigma difference {max_sd_rel:.2e}; predictions {} vs {}",
        b.counters().cov_predictions,
        a.counters().cov_predictions
    );
    assert_eq!(a.counters().cov_predictions as usize, 600 * 200);
    assert!(b.counters().cov_predictions as usize >= 600 * 10);
    assert!(max_dp < 1e-3);
    assert!(max_sd_rel < 0.02);
}
