//! Overlapping ADEV with octave taus on 21.6 M samples (6 h at 1 kHz), single-threaded, and
//! the streaming Allan variance push.
//!
//! `cargo bench -p host-sim --bench allan` runs criterion. With `ALLAN_BENCH_ONCE=1` the bench
//! binary instead runs the OADEV job once and prints the time (for `/usr/bin/time -v`
//! memory measurements).
use criterion::{criterion_group, Criterion};
use nav_sim::noise::White;
use noise_id::{deviation_curve, CurveOptions, Deviation, Phase, Taus};
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

/// Time this thread has run on a CPU (s), from /proc/thread-self/schedstat (Linux; NaN
/// elsewhere): on a shared machine it excludes the time spent waiting for a core.
fn cpu_s() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |ns| ns * 1e-9)
}

fn main() {
    if std::env::var("ALLAN_BENCH_ONCE").is_ok() {
        let y = data();
        let t0 = std::time::Instant::now();
        let c0 = cpu_s();
        let n = oadev_octave(&y);
        println!(
            "oadev octave on {N} samples: {n} taus in {:.3} s ({:.3} s on the CPU)",
            t0.elapsed().as_secs_f64(),
            cpu_s() - c0
        );
        // Breakdown: the phase buffer, then the sums of all taus in one sweep.
        let t1 = std::time::Instant::now();
        let phase = Phase::from_rate(&y);
        let tp = t1.elapsed().as_secs_f64();
        let ms = Taus::Octave.factors(N, Deviation::Oadev);
        let t2 = std::time::Instant::now();
        let v = phase.oavar_many(&ms);
        drop(phase);
        println!(
            "  phase buffer {tp:.3} s, {} octave sums {:.3} s",
            v.len(),
            t2.elapsed().as_secs_f64()
        );
        // What `host-sim allan` computes: with noise identification, EDF and 68% bounds.
        let t3 = std::time::Instant::now();
        let c = deviation_curve(&y, 1e-3, &CurveOptions::default());
        println!(
            "  with noise id + EDF + chi-square bounds: {} taus in {:.3} s",
            c.len(),
            t3.elapsed().as_secs_f64()
        );
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
