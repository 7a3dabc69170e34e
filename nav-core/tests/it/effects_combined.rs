//! All effect blocks at once: the NBK-18 base plus every IMU-side effect block of the
//! vocabulary, the lever arm and the time offset (49 states) on a drive that contains four
//! undeclared effects at once (lever arm, GNSS time offset, gyro misalignment, accelerometer temperature coefficient, with a warm-up). The
//! blocks whose effect is present must find it (observable parts within 20 %), the blocks
//! whose effect is absent must stay at zero within their 3 sigma (no false attribution), and
//! the outage errors must be lower than the base filter's.

use nav_core::config::{units, FilterConfig, ScaleFactorNoise};
use nav_core::model::{Block, BlockKind, Layout, EFFECT_BLOCKS};
use test_support::filter_sim::*;

/// Without the GNSS position Gauss-Markov block: with it (52 states) the relative rotation of
/// the two triads is no longer determined on this drive (the combination gyro m_xz + accel
/// m_zx: -0.27 +- 0.50 mrad against a truth of -0.35 mrad; these 49 states give -0.338 +- 0.035
/// mrad), because a slowly varying antenna error absorbs part of what the misalignment
/// explains. The GNSS block's own tests are in `effects_clock_gnss.rs`.
const L_ALL: Layout = nbk_with_all_imu_side_effects();

#[test]

fn all_effect_blocks_together_find_the_four_present_effects_and_leave_the_others_at_zero() {
    assert_eq!(L_ALL.dim(), 49);
    let lever = [0.9, 0.5, -1.2];
    let offset_s = 0.06;
    let gyro_mis = [0.3, -0.35, 0.2, 0.4, -0.25, 0.3].map(|v| v * 1e-3);
    let accel_k = [-35.0, 45.0, 30.0].map(units::mps2_from_ug);
    let mut sc = SimConfig::nbk(100.0);
    sc.lever_arm_body_m = lever;
    sc.effects.gnss_time_offset_s = offset_s;
    sc.effects.gyro_mis_rad = gyro_mis;
    sc.effects.accel_temp_coeff = accel_k;
    sc.effects.temperature = Some(TempProfile {
        start_c: 15.0,
        rise_c: 25.0,
        tau_s: 600.0,
    });
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.accel_scale = ScaleFactorNoise::from_ppm(1000.0, 1e7);
    cfg.gyro_scale = ScaleFactorNoise::from_ppm(1000.0, 1e7);
    let outages = outage_plan(700.0, 170.0, 60.0, 5);
    let r = effect_run::<{ L_ALL.dim() }>(sc, 51, &cfg, L_ALL, 1600.0, &outages);
    let (a, b) = check_outage_improvement("all blocks", &r.with_stats, &r.without_stats);
    let f = &r.with;
    check_block_estimate(f, BlockKind::LeverArm, &lever, 1.0, "m", &[0, 1], &[]);
    check_block_estimate(f, BlockKind::TimeOffset, &[offset_s], 1e-3, "ms", &[0], &[]);
    // with both misalignment blocks a common rotation of the two triads is an attitude offset
    // (unobservable): the individual gyro terms stay near their prior, the relative rotation
    // gyro m_xz + accel m_zx (about y) and gyro m_yz + accel m_zy (about x) is what the drive
    // determines (the accelerometer misalignment is zero in the data)
    check_block_estimate(
        f,
        BlockKind::GyroMisalignment,
        &gyro_mis,
        1e-3,
        "mrad",
        &[],
        &[],
    );
    check_terms(
        f,
        &[
            (BlockKind::GyroMisalignment, 1, 1.0),
            (BlockKind::AccelMisalignment, 4, 1.0),
        ],
        "gyro m_xz + accel m_zx",
        gyro_mis[1],
        1e-3,
        "mrad",
    );
    check_terms(
        f,
        &[
            (BlockKind::GyroMisalignment, 3, 1.0),
            (BlockKind::AccelMisalignment, 5, 1.0),
        ],
        "gyro m_yz + accel m_zy",
        gyro_mis[3],
        1e-3,
        "mrad",
    );
    check_block_estimate(
        f,
        BlockKind::AccelTemperatureBias,
        &accel_k,
        units::UG_MPS2,
        "ug/degC",
        &[0, 1, 2],
        &[],
    );
    // the accelerometer misalignment is absent but shares the common-rotation null space with
    // the gyro's: its estimates must still be within 3 sigma of zero
    check_block_estimate(
        f,
        BlockKind::AccelMisalignment,
        &[0.0; 6],
        1e-3,
        "mrad",
        &[],
        &[],
    );
    // absent effects (every effect block of the layout): estimates within 3 sigma of zero
    for b in EFFECT_BLOCKS {
        if !L_ALL.blocks().contains(&b)
            || matches!(
                b,
                Block::LeverArm
                    | Block::TimeOffset
                    | Block::GyroMisalignment
                    | Block::AccelMisalignment
                    | Block::AccelTemperatureBias
            )
        {
            continue;
        }
        let v = f.block_value(b.kind()).unwrap();
        for i in 0..v.dim {
            println!(
                "{}[{i}] (absent): estimate {:.3e} sigma {:.3e} {} ({:.2} sigma)",
                b.name(),
                v.estimate[i],
                v.sigma[i],
                b.unit(),
                v.estimate[i] / v.sigma[i]
            );
            assert!(v.estimate[i].abs() < 3.0 * v.sigma[i], "{} [{i}]", b.name());
        }
    }
    assert!(a < 0.7 * b, "with {a} m without {b} m");
}
