//! Decoder throughput on the host (MB/s of wire bytes): a realistic stream (200 Hz IMU,
//! 10 Hz GNSS, 20 Hz nav, health) fed in 64-byte and 4 KiB chunks, plus the encoder.
//! Run: `cargo bench -p hw-bridge --bench decoder`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use nav_core::types::{FixQuality, GnssFix, ImuSample, NavSolution};
use nav_core::wire::{Encoder, FrameDecoder, Health, ImuFrame, Payload, MAX_FRAME_LEN};
use std::hint::black_box;

fn stream_payloads(steps: usize) -> Vec<Payload> {
    let mut v = Vec::new();
    for i in 0..steps {
        let t = 388_800.0 + i as f64 * 0.005;
        v.push(Payload::Imu(ImuFrame {
            sample: ImuSample {
                t_s: t,
                dtheta_rad: [1e-5 * (i as f64).sin(), -2e-6, 3e-7],
                dv_mps: [0.01, -0.002, -0.049 + 1e-6 * i as f64],
                temperature_c: 25.0,
            },
            status: 0,
        }));
        if i % 20 == 0 {
            v.push(Payload::Gnss(GnssFix {
                t_s: t,
                lat_rad: 0.53,
                lon_rad: 1.99,
                h_m: 25.0,
                pos_std_ned_m: [0.5, 0.5, 1.0],
                vel_ned_mps: [1.0, 2.0, 0.1],
                vel_std_ned_mps: [0.05; 3],
                has_velocity: true,
                quality: FixQuality::Single,
                num_sats: 12,
            }));
        }
        if i % 10 == 0 {
            v.push(Payload::Nav(NavSolution {
                t_s: t,
                lat_rad: 0.53,
                ..NavSolution::default()
            }));
        }
        if i % 100 == 0 {
            v.push(Payload::Health(Health::default()));
        }
    }
    v
}

fn bench(c: &mut Criterion) {
    let payloads = stream_payloads(20_000);
    let mut enc = Encoder::new();
    let mut bytes = Vec::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for p in &payloads {
        let n = enc.encode(p, &mut buf).unwrap();
        bytes.extend_from_slice(&buf[..n]);
    }
    let mut g = c.benchmark_group("wire");
    g.throughput(Throughput::Bytes(bytes.len() as u64));
    for chunk in [64usize, 4096] {
        g.bench_function(format!("decode_chunks_{chunk}"), |b| {
            b.iter(|| {
                let mut d = FrameDecoder::new();
                let mut n = 0usize;
                for piece in black_box(&bytes).chunks(chunk) {
                    n += d.feed(piece).filter(|r| r.is_ok()).count();
                }
                assert_eq!(n, payloads.len());
                n
            })
        });
    }
    g.bench_function("decode_byte_at_a_time", |b| {
        b.iter(|| {
            let mut d = FrameDecoder::new();
            black_box(&bytes)
                .iter()
                .filter_map(|&x| d.push_byte(x))
                .count()
        })
    });
    g.bench_function("encode", |b| {
        b.iter(|| {
            let mut e = Encoder::new();
            let mut out = [0u8; MAX_FRAME_LEN];
            let mut total = 0usize;
            for p in black_box(&payloads) {
                total += e.encode(p, &mut out).unwrap();
            }
            total
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
