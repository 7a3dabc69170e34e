//! Host benchmarks of the error-state filter: propagation per IMU epoch (mechanisation +
//! error-model accumulation + the amortised 10 Hz covariance prediction), one covariance
//! prediction, and one GNSS update, for the 15-, 18- and 21-state models in f32 and f64.
//!
//! Run: `CARGO_TARGET_DIR=... cargo bench -p nav-core --bench filter -- --warm-up-time 1
//! --measurement-time 3`.

use test_support::filter_sim;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use filter_sim::{Sim, SimConfig};
use nav_core::config::FilterConfig;
use nav_core::filter::Filter;
use nav_core::model::{Layout, LAYOUT_KF_GINS, LAYOUT_N, LAYOUT_NBK};
use nav_core::scalar::Scalar;
use nav_core::strapdown::{NavState, Strapdown};
use nav_core::types::{GnssFix, ImuSample};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// 60 s of a 200 Hz drive with 1 Hz fixes.
fn data() -> (NavState, Vec<ImuSample>, Vec<(usize, GnssFix)>) {
    let mut sim = Sim::new(SimConfig::nbk(200.0), 3);
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

fn config() -> FilterConfig {
    let mut c = FilterConfig::source_nbk_model();
    c.lever_arm_body_m = SimConfig::nbk(200.0).lever_arm_body_m;
    c
}

fn bench_model<T: Scalar, const N: usize>(c: &mut Criterion, layout: Layout, tag: &str) {
    let (init, imu, fixes) = data();
    let cfg = config();
    let unc = filter_sim::test_uncertainty();
    let fresh = Filter::<T, N>::new(layout, &cfg, init, &unc).unwrap();

    // propagate: average per IMU epoch over 1 s blocks (200 epochs, 10 predictions)
    c.bench_function(&format!("propagate/{tag}"), |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            let mut f = fresh.clone();
            let mut k = 0usize;
            for _ in 0..iters {
                if k == imu.len() {
                    f = fresh.clone();
                    k = 0;
                }
                let s = &imu[k];
                let t0 = Instant::now();
                f.propagate(black_box(s)).unwrap();
                total += t0.elapsed();
                k += 1;
            }
            total
        })
    });

    // one covariance prediction over 0.1 s (20 epochs accumulated)
    let mut warm = fresh.clone();
    for s in &imu[..(30 * 200)] {
        warm.propagate(s).unwrap();
    }
    let mut pending = warm.clone();
    let mut cfg_slow = cfg;
    cfg_slow.cov_predict_interval_s = 10.0;
    let mut slow = Filter::<T, N>::new(layout, &cfg_slow, *warm.nav_state(), &unc).unwrap();
    for s in &imu[(30 * 200)..(30 * 200 + 20)] {
        slow.propagate(s).unwrap();
        pending.propagate(s).unwrap();
    }
    c.bench_function(&format!("predict_covariance_0.1s/{tag}"), |b| {
        b.iter_batched_ref(
            || slow.clone(),
            |f| f.predict_covariance().unwrap(),
            BatchSize::SmallInput,
        )
    });

    // one GNSS position update (no pending prediction)
    let (k, fix) = fixes[30];
    let mut at_fix = fresh.clone();
    for (i, s) in imu[..=k].iter().enumerate() {
        at_fix.propagate(s).unwrap();
        if let Some((_, g)) = fixes.iter().find(|(j, _)| *j == i) {
            if i < k {
                at_fix.update_gnss(g).unwrap();
            }
        }
    }
    at_fix.predict_covariance().unwrap();
    c.bench_function(&format!("update_gnss/{tag}"), |b| {
        b.iter_batched_ref(
            || at_fix.clone(),
            |f| black_box(f.update_gnss(&fix).unwrap()),
            BatchSize::SmallInput,
        )
    });
}

fn bench_mech(c: &mut Criterion) {
    let (init, imu, _) = data();
    c.bench_function("strapdown_update_only", |b| {
        b.iter_custom(|iters| {
            let mut m = Strapdown::new(init);
            let mut k = 0usize;
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                if k == imu.len() {
                    m = Strapdown::new(init);
                    k = 0;
                }
                let t0 = Instant::now();
                black_box(m.update(&imu[k]).unwrap());
                total += t0.elapsed();
                k += 1;
            }
            total
        })
    });
}

fn benches(c: &mut Criterion) {
    bench_mech(c);
    bench_model::<f32, { LAYOUT_N.dim() }>(c, LAYOUT_N, "N15/f32");
    bench_model::<f64, { LAYOUT_N.dim() }>(c, LAYOUT_N, "N15/f64");
    bench_model::<f32, { LAYOUT_NBK.dim() }>(c, LAYOUT_NBK, "NBK18/f32");
    bench_model::<f64, { LAYOUT_NBK.dim() }>(c, LAYOUT_NBK, "NBK18/f64");
    bench_model::<f32, { LAYOUT_KF_GINS.dim() }>(c, LAYOUT_KF_GINS, "KFGINS21/f32");
    bench_model::<f64, { LAYOUT_KF_GINS.dim() }>(c, LAYOUT_KF_GINS, "KFGINS21/f64");
}

criterion_group!(filter_benches, benches);
criterion_main!(filter_benches);
