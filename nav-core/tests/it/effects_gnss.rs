//! The GNSS-side effect blocks on simulated drives that contain the effect while the
//! configuration does not declare it: `lever_arm` (antenna offset not configured) and
//! `time_offset` (GNSS time tags off by tens of ms). NBK truth and NBK-18 base filter, 100 Hz
//! IMU, 1 Hz RTK-grade fixes (2 cm / 4 cm), 60 s outages after the convergence. Each test
//! asserts the estimate against the truth (every component within 3 sigma; the observable
//! ones within 20 %) and that the block lowers the position error during the outages.

use nav_core::config::FilterConfig;
use nav_core::model::{Block, BlockKind, Layout, LAYOUT_NBK};
use test_support::filter_sim::*;

const L_LEVER: Layout = LAYOUT_NBK.with(Block::LeverArm);
const L_TIME: Layout = LAYOUT_NBK.with(Block::TimeOffset);

#[test]
fn lever_arm_block_estimates_an_undeclared_antenna_offset_and_lowers_outage_errors() {
    for (seed, lever, velocity) in [
        (11, [1.1, -0.4, -1.3], false),
        (12, [-0.3, 0.6, -0.8], true),
    ] {
        // the configuration says 0
        let mut sc = SimConfig::nbk(100.0);
        sc.lever_arm_body_m = lever;
        sc.gnss_velocity = velocity;
        let mut cfg = FilterConfig::source_nbk_model();
        cfg.use_gnss_velocity = velocity;
        let outages = outage_plan(600.0, 170.0, 60.0, 5);
        let r = effect_run::<{ L_LEVER.dim() }>(sc, seed, &cfg, L_LEVER, 1500.0, &outages);
        println!("lever arm {lever:?} m, velocity updates {velocity}:");
        let (a, b) = check_outage_improvement("lever_arm", &r.with_stats, &r.without_stats);
        // the vertical component is not observable on a level drive (C l has a constant
        // vertical part that the height absorbs): it must only stay inside its sigma
        check_block_estimate(&r.with, BlockKind::LeverArm, &lever, 1.0, "m", &[0, 1], &[]);
        assert!(a < 0.7 * b, "with {a} m without {b} m");
    }
}

#[test]
fn time_offset_block_estimates_an_imu_gnss_delay_and_lowers_outage_errors() {
    for (seed, offset_s, velocity) in [(21, 0.08, false), (22, 0.035, true), (23, 0.14, false)] {
        let mut sc = SimConfig::nbk(100.0);
        sc.effects.gnss_time_offset_s = offset_s;
        sc.gnss_velocity = velocity;
        let mut cfg = FilterConfig::source_nbk_model();
        cfg.lever_arm_body_m = sc.lever_arm_body_m;
        cfg.use_gnss_velocity = velocity;
        let outages = outage_plan(500.0, 170.0, 60.0, 4);
        let r = effect_run::<{ L_TIME.dim() }>(sc, seed, &cfg, L_TIME, 1200.0, &outages);
        println!("offset {offset_s} s, velocity updates {velocity}:");
        let (a, b) = check_outage_improvement("time_offset", &r.with_stats, &r.without_stats);
        check_block_estimate(
            &r.with,
            BlockKind::TimeOffset,
            &[offset_s],
            1e-3,
            "ms",
            &[0],
            &[],
        );
        assert!(a < 0.7 * b, "with {a} m without {b} m");
    }
}
