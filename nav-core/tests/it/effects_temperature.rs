//! The temperature effect blocks on simulated drives whose IMU warms up by 25 degC
//! (`T = 20 + 25 (1 - e^(-t/500 s))`, the samples carry the temperature) while the base
//! configuration has no temperature model: `accel_temperature_bias` and
//! `gyro_temperature_bias`. NBK truth and NBK-18 base filter, 100 Hz IMU, 1 Hz RTK-grade
//! fixes, 60 s outages during and after the warm-up. Each test asserts the estimated
//! coefficients against the truth (within 3 sigma and within 20 %, sigma below 20 %) and that
//! the block lowers the horizontal position error during the outages.

use nav_core::config::{units, EffectNoise, FilterConfig};
use nav_core::model::{Block, BlockKind, Layout, LAYOUT_NBK};
use test_support::filter_sim::*;

const L_AT: Layout = LAYOUT_NBK.with(Block::AccelTemperatureBias);
const L_GT: Layout = LAYOUT_NBK.with(Block::GyroTemperatureBias);

fn warm_up() -> TempProfile {
    TempProfile {
        start_c: 20.0,
        rise_c: 25.0,
        tau_s: 500.0,
    }
}

#[test]
fn accel_temperature_bias_block_estimates_the_coefficients_and_lowers_outage_errors() {
    // 20-60 ug/degC over the 25 degC warm-up: up to 1.4 mg of bias change
    let truth = [40.0, -25.0, 55.0].map(units::mps2_from_ug);
    let mut sc = SimConfig::nbk(100.0);
    sc.effects.temperature = Some(warm_up());
    sc.effects.accel_temp_coeff = truth;
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = sc.lever_arm_body_m;
    cfg.effects.accel_temperature = EffectNoise::constant(units::mps2_from_ug(100.0));
    let outages = outage_plan(300.0, 170.0, 60.0, 5);
    let r = effect_run::<{ L_AT.dim() }>(sc, 41, &cfg, L_AT, 1200.0, &outages);
    let (a, b) =
        check_outage_improvement("accel_temperature_bias", &r.with_stats, &r.without_stats);
    check_block_estimate(
        &r.with,
        BlockKind::AccelTemperatureBias,
        &truth,
        units::UG_MPS2,
        "ug/degC",
        &[0, 1, 2],
        &[],
    );
    // T_ref = the first sample's temperature (10 ms into the warm-up)
    assert_eq!(r.with.temperature_ref_c(), warm_up().at(0.01));
    assert!(a < 0.7 * b, "with {a} m without {b} m");
}

#[test]
fn gyro_temperature_bias_block_detects_tactical_coefficients_without_hurting() {
    // 0.04-0.06 deg/h/degC: 1-1.5 deg/h of bias change over the warm-up, comparable to the
    // angle random walk's effect (0.079 deg/sqrt(h)) on a 60 s outage
    let truth = [0.06, -0.04, 0.05].map(units::radps_from_deg_per_h);
    let mut sc = SimConfig::nbk(100.0);
    sc.effects.temperature = Some(warm_up());
    sc.effects.gyro_temp_coeff = truth;
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = sc.lever_arm_body_m;
    cfg.effects.gyro_temperature = EffectNoise::constant(units::radps_from_deg_per_h(0.1));
    let outages = outage_plan(300.0, 170.0, 60.0, 8);
    let r = effect_run::<{ L_GT.dim() }>(sc, 42, &cfg, L_GT, 1800.0, &outages);
    let (a, b) = check_outage_improvement("gyro_temperature_bias", &r.with_stats, &r.without_stats);
    check_block_estimate(
        &r.with,
        BlockKind::GyroTemperatureBias,
        &truth,
        units::radps_from_deg_per_h(1.0),
        "deg/h/degC",
        &[],
        &[0, 1, 2],
    );
    assert!(a < 1.05 * b, "with {a} m without {b} m");
}

#[test]
fn gyro_temperature_bias_block_estimates_mems_size_coefficients_and_lowers_outage_errors() {
    // 0.2-0.3 deg/h/degC (a MEMS-grade gyro): 5-7.5 deg/h over the warm-up
    let truth = [0.3, -0.2, 0.25].map(units::radps_from_deg_per_h);
    let mut sc = SimConfig::nbk(100.0);
    sc.effects.temperature = Some(warm_up());
    sc.effects.gyro_temp_coeff = truth;
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = sc.lever_arm_body_m;
    cfg.effects.gyro_temperature = EffectNoise::constant(units::radps_from_deg_per_h(0.5));
    let outages = outage_plan(300.0, 170.0, 60.0, 5);
    let r = effect_run::<{ L_GT.dim() }>(sc, 43, &cfg, L_GT, 1200.0, &outages);
    let (a, b) = check_outage_improvement("gyro_temperature_bias", &r.with_stats, &r.without_stats);
    check_block_estimate(
        &r.with,
        BlockKind::GyroTemperatureBias,
        &truth,
        units::radps_from_deg_per_h(1.0),
        "deg/h/degC",
        &[0, 1, 2],
        &[],
    );
    assert!(a < 0.7 * b, "with {a} m without {b} m");
}
