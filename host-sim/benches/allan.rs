//! Overlapping ADEV with octave taus on 21.6 M samples (6 h at 1 kHz), single-threaded, and
//! the streaming Allan variance push.
//!
//! `cargo bench -p host-sim --bench allan` runs criterion. With `ALLAN_BENCH_ONCE=1` the bench
//! binary instead runs the OADEV job once and prints the time (for `/usr/bin/time -v`
//! memory measurements).
use criterion::{criterion_group, Criterion};
use host_sim::allan::{deviation_curve, CurveOptions, Deviation, Taus};
use host_sim::noise::White;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

const N: usize = 21_600_000;

fn data() -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut w = White::from_psd(1e-6, 1e-3);
    (0..N).map(|_| 9.81 + w.next(&mut rng)).collect()
}

fn oadev_octave(y: &[f64]) -> usize {
    let opt = CurveOptions {
        dev: Deviation::Oadev,
        taus: Taus::Octave,
        confidence: None,
        fixed_alpha: None,
    };
    deviation_curve(y, 1e-3, &opt).len()
}

fn bench(c: &mut Criterion) {
    let y = data();
    let mut g = c.benchmark_group("allan");
    g.sample_size(10);
    g.bench_function("oadev_octave_21.6M", |b| {
        b.iter(|| oadev_octave(black_box(&y)))
    });
    let small: Vec<f64> = y[..1_000_000].to_vec();
    g.bench_function("streaming_push_1M", |b| {
        b.iter(|| {
            let mut s = nav_core::allan::StreamingAllan::<24>::new();
            for &v in &small {
                s.push(black_box(v));
            }
            s.avar(0)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);

fn main() {
    if std::env::var("ALLAN_BENCH_ONCE").is_ok() {
        let y = data();
        let t0 = std::time::Instant::now();
        let n = oadev_octave(&y);
        println!(
            "oadev octave on {N} samples: {n} taus in {:.3} s",
            t0.elapsed().as_secs_f64()
        );
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
