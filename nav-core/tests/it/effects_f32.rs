//! The effect blocks in the MCU's precision: the f32-covariance filter with every effect
//! block (NBK-18 + 31 effect states = 49) against the f64 filter on the same 20-minute drive
//! with several effects in the data (lever arm, time offset, gyro misalignment, accelerometer
//! temperature coefficient and scale factors during a warm-up). The f32 covariance must stay
//! symmetric positive definite at every update (checked by a Cholesky in f32), the solutions
//! must agree to centimetres and the effect estimates to a small fraction of their sigma.

use nav_core::config::{units, FilterConfig, ScaleFactorNoise};
use nav_core::filter::Filter;
use nav_core::model::{Layout, EFFECT_BLOCKS};
use test_support::filter_sim::*;

const L_ALL: Layout = nbk_with_all_effects();
const N: usize = L_ALL.dim();

#[test]

fn f32_filter_with_all_effect_blocks_stays_positive_definite_and_agrees_with_f64() {
    let mut sc = SimConfig::nbk(100.0);
    sc.lever_arm_body_m = [0.7, -0.3, -1.0];
    sc.effects.gnss_time_offset_s = 0.05;
    sc.effects.gyro_mis_rad = [0.2, -0.3, 0.25, 0.3, -0.2, 0.1].map(|v| v * 1e-3);
    sc.effects.accel_temp_coeff = [30.0, -40.0, 25.0].map(units::mps2_from_ug);
    sc.effects.accel_sf = [800e-6, -600e-6, 500e-6];
    sc.effects.temperature = Some(TempProfile {
        start_c: 25.0,
        rise_c: 20.0,
        tau_s: 400.0,
    });
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.accel_scale = ScaleFactorNoise::from_ppm(1000.0, 1e7);
    cfg.gyro_scale = ScaleFactorNoise::from_ppm(1000.0, 1e7);
    let mut sim = Sim::new(sc, 61);
    let unc = test_uncertainty();
    let init = sim.perturbed_initial(&unc);
    let mut f64f: Filter<f64, N> = Filter::new(L_ALL, &cfg, init, &unc).unwrap();
    let mut f32f: Filter<f32, N> = Filter::new(L_ALL, &cfg, init, &unc).unwrap();
    let outages = outage_plan(600.0, 200.0, 60.0, 3);
    let (mut max_dp, mut max_err, mut updates) = (0.0f64, 0.0f64, 0u32);
    let mut spd_failures = 0u32;
    let t0 = sim.truth().t_s;
    let n_ep = 1200 * 100;
    let epochs: Vec<Epoch> = (0..n_ep).map(|_| sim.step()).collect();
    // fixes at the epoch nearest their tag (run_filters' rule)
    let mut due = vec![None; n_ep];
    for e in &epochs {
        if let Some(fix) = e.gnss {
            let k = ((fix.t_s - t0) * 100.0).round() as i64 - 1;
            if k >= 0 && (k as usize) < n_ep {
                due[k as usize] = Some(fix);
            }
        }
    }
    for (e, fix) in epochs.iter().zip(&due) {
        f64f.propagate(&e.imu).unwrap();
        f32f.propagate(&e.imu).unwrap();
        let tau = e.truth.t_s - t0;
        if let Some(fix) = fix {
            if !outages.iter().any(|(a, b)| tau >= *a && tau < *b) {
                f64f.update_gnss(fix).unwrap();
                f32f.update_gnss(fix).unwrap();
                updates += 1;
                if !f32f.covariance_is_positive_definite() {
                    spd_failures += 1;
                }
            }
        }
        let (_, _, dp) = nav_errors(f32f.nav_state(), f64f.nav_state());
        max_dp = max_dp.max((dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2]).sqrt());
        let (_, _, de) = nav_errors(f64f.nav_state(), &e.truth);
        max_err = max_err.max((de[0] * de[0] + de[1] * de[1]).sqrt());
    }
    println!(
        "{updates} updates, f32 SPD failures {spd_failures}; largest f32-f64 position difference {max_dp:.4} m (f64 error vs truth up to {max_err:.2} m); numerical failures f32 {} f64 {}",
        f32f.counters().numerical_failures,
        f64f.counters().numerical_failures
    );
    assert_eq!(spd_failures, 0);
    assert_eq!(f32f.counters().numerical_failures, 0);
    assert_eq!(f32f.counters().gnss_rejected, f64f.counters().gnss_rejected);
    assert!(max_dp < 0.05, "f32 vs f64 position {max_dp} m");
    // effect estimates: f32 - f64 within 0.1 of the f64 sigma
    for b in EFFECT_BLOCKS {
        let a = f64f.block_value(b.kind()).unwrap();
        let c = f32f.block_value(b.kind()).unwrap();
        for i in 0..a.dim {
            let d = (c.estimate[i] - a.estimate[i]) / a.sigma[i];
            let r = c.sigma[i] / a.sigma[i];
            println!(
                "{}[{i}]: f64 {:.4e} (sigma {:.3e})  f32 - f64 = {d:+.4} sigma, sigma ratio {r:.4}",
                b.name(),
                a.estimate[i],
                a.sigma[i]
            );
            assert!(d.abs() < 0.1, "{} [{i}]: {d} sigma", b.name());
            assert!(
                (r - 1.0).abs() < 0.05,
                "{} [{i}]: sigma ratio {r}",
                b.name()
            );
        }
    }
}
