//! Host cost of the effect blocks (a plain timing harness, not a test): for the NBK-18 base,
//! the base plus each effect block, and the base plus all of them, the time per IMU epoch of
//! `propagate` (mechanisation + IMU correction + error-model accumulation + the amortised
//! 10 Hz covariance prediction) and per GNSS position update, in f32 and f64, on 60 s of a
//! 200 Hz drive whose data carry every effect (so the general IMU correction path runs).
//!
//! Run: `CARGO_TARGET_DIR=... cargo run -p nav-core --release --example effects_cost`
//! (the machine is shared: repeat and take the minimum; figures are +-20 %).

use test_support::filter_sim;

use filter_sim::{Sim, SimConfig, TempProfile};
use nav_core::config::FilterConfig;
use nav_core::filter::Filter;
use nav_core::model::{Block, Layout, EFFECT_BLOCKS, LAYOUT_NBK};
use nav_core::scalar::Scalar;
use nav_core::strapdown::NavState;
use nav_core::types::{GnssFix, ImuSample};
use std::hint::black_box;
use std::time::Instant;

/// 60 s of a 200 Hz drive with every effect in the data, and its 1 Hz fixes.
fn data() -> (NavState, Vec<ImuSample>, Vec<(usize, GnssFix)>) {
    let mut sc = SimConfig::nbk(200.0);
    sc.effects.gyro_mis_rad = [3e-4; 6];
    sc.effects.accel_mis_rad = [2e-4; 6];
    sc.effects.accel_temp_coeff = [4e-4; 3];
    sc.effects.gyro_temp_coeff = [2e-7; 3];
    sc.effects.gyro_g_sens = [2e-7; 3];
    sc.effects.temperature = Some(TempProfile {
        start_c: 20.0,
        rise_c: 25.0,
        tau_s: 300.0,
    });
    let mut sim = Sim::new(sc, 3);
    let init = *sim.truth();
    let mut imu = Vec::new();
    let mut fixes = Vec::new();
    for k in 0..(60 * 200) {
        let e = sim.step();
        imu.push(e.imu);
        if let Some(g) = e.gnss {
            fixes.push((k, g));
        }
    }
    (init, imu, fixes)
}

/// (ns per propagate, ns per GNSS update), best of `reps` passes over the data.
fn time_layout<T: Scalar, const N: usize>(
    layout: Layout,
    data: &(NavState, Vec<ImuSample>, Vec<(usize, GnssFix)>),
    reps: usize,
) -> (f64, f64) {
    let (init, imu, fixes) = data;
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = SimConfig::nbk(200.0).lever_arm_body_m;
    cfg.max_gnss_time_offset_s = 0.2;
    let unc = filter_sim::test_uncertainty();
    let mut best_p = f64::INFINITY;
    let mut best_u = f64::INFINITY;
    for _ in 0..reps {
        let mut f = Filter::<T, N>::new(layout, &cfg, *init, &unc).unwrap();
        let mut tp = 0.0;
        let mut tu = 0.0;
        let mut fi = 0;
        for (k, s) in imu.iter().enumerate() {
            let t0 = Instant::now();
            f.propagate(black_box(s)).unwrap();
            tp += t0.elapsed().as_secs_f64();
            if let Some((kf, fix)) = fixes.get(fi) {
                if *kf == k {
                    // the pending covariance prediction is part of propagate's cost
                    f.predict_covariance().unwrap();
                    let t1 = Instant::now();
                    let _ = black_box(f.update_gnss(fix));
                    tu += t1.elapsed().as_secs_f64();
                    fi += 1;
                }
            }
        }
        best_p = best_p.min(tp / imu.len() as f64 * 1e9);
        best_u = best_u.min(tu / fixes.len() as f64 * 1e9);
    }
    (best_p, best_u)
}

macro_rules! row {
    ($name:expr, $layout:expr, $data:expr, $base:expr) => {{
        const L: Layout = $layout;
        let (p32, u32_) = time_layout::<f32, { L.dim() }>(L, $data, 25);
        let (p64, u64_) = time_layout::<f64, { L.dim() }>(L, $data, 25);
        let (b32, b64): (f64, f64) = $base;
        println!(
            "| {:<34} | {:>3} | {:>7.0} | {:>+6.0} | {:>7.0} | {:>+6.0} | {:>7.0} | {:>7.0} |",
            $name,
            L.dim(),
            p32,
            p32 - b32,
            p64,
            p64 - b64,
            u32_,
            u64_
        );
        (p32, p64)
    }};
}

const fn all_effects() -> Layout {
    let mut l = LAYOUT_NBK;
    let mut i = 0;
    while i < EFFECT_BLOCKS.len() {
        l = l.with(EFFECT_BLOCKS[i]);
        i += 1;
    }
    l
}

fn main() {
    let d = data();
    println!("| layout | states | propagate f32 ns/epoch | +f32 | propagate f64 ns/epoch | +f64 | GNSS update f32 ns | GNSS update f64 ns |");
    println!("|---|---|---|---|---|---|---|---|");
    let base = row!("NBK-18 (base)", LAYOUT_NBK, &d, (0.0, 0.0));
    row!(
        "+ accel_scale_factor",
        LAYOUT_NBK.with(Block::AccelScaleFactor),
        &d,
        base
    );
    row!(
        "+ gyro_scale_factor",
        LAYOUT_NBK.with(Block::GyroScaleFactor),
        &d,
        base
    );
    row!(
        "+ accel_misalignment",
        LAYOUT_NBK.with(Block::AccelMisalignment),
        &d,
        base
    );
    row!(
        "+ gyro_misalignment",
        LAYOUT_NBK.with(Block::GyroMisalignment),
        &d,
        base
    );
    row!("+ lever_arm", LAYOUT_NBK.with(Block::LeverArm), &d, base);
    row!(
        "+ time_offset",
        LAYOUT_NBK.with(Block::TimeOffset),
        &d,
        base
    );
    row!(
        "+ accel_temperature_bias",
        LAYOUT_NBK.with(Block::AccelTemperatureBias),
        &d,
        base
    );
    row!(
        "+ gyro_temperature_bias",
        LAYOUT_NBK.with(Block::GyroTemperatureBias),
        &d,
        base
    );
    row!(
        "+ gyro_g_sensitivity",
        LAYOUT_NBK.with(Block::GyroGSensitivity),
        &d,
        base
    );
    row!("+ all nine effect blocks", all_effects(), &d, base);
}
