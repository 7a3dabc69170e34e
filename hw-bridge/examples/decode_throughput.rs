//! Decoder throughput without criterion: encodes a 200 Hz drive-like stream (IMU, GNSS at
//! 10 Hz, nav at 20 Hz, health at 2 Hz) and decodes it in 4 KiB chunks, printing MB/s.
//! Under `valgrind --tool=callgrind --toggle-collect=*decode_all*` it gives instructions per
//! byte, which do not depend on machine load.
//!
//! `cargo run --release -p hw-bridge --example decode_throughput [steps]`

use nav_core::types::{FixQuality, GnssFix, ImuSample, NavSolution};
use nav_core::wire::{Encoder, FrameDecoder, Health, ImuFrame, Payload, MAX_FRAME_LEN};
use std::time::Instant;

fn stream(steps: usize) -> Vec<u8> {
    let mut enc = Encoder::new();
    let mut out = Vec::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut push = |p: Payload| {
        let n = enc.encode(&p, &mut buf).expect("encode");
        out.extend_from_slice(&buf[..n]);
    };
    for i in 0..steps {
        let t = 388_800.0 + i as f64 * 0.005;
        push(Payload::Imu(ImuFrame {
            sample: ImuSample {
                t_s: t,
                dtheta_rad: [1e-5 * (i as f64).sin(), -2e-6, 3e-7],
                dv_mps: [0.01, -0.002, -0.049 + 1e-6 * i as f64],
                temperature_c: 25.0,
            },
            status: 0,
        }));
        if i % 20 == 0 {
            push(Payload::Gnss(GnssFix {
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
            push(Payload::Nav(NavSolution {
                t_s: t,
                lat_rad: 0.53,
                ..NavSolution::default()
            }));
        }
        if i % 100 == 0 {
            push(Payload::Health(Health::default()));
        }
    }
    out
}

#[inline(never)]
fn decode_all(bytes: &[u8]) -> u32 {
    let mut d = FrameDecoder::new();
    let mut n = 0;
    for piece in bytes.chunks(4096) {
        n += d.feed(piece).filter(|r| r.is_ok()).count() as u32;
    }
    n
}

fn main() {
    let steps: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(200_000);
    let bytes = stream(steps);
    let t = Instant::now();
    let frames = decode_all(std::hint::black_box(&bytes));
    let dt = t.elapsed().as_secs_f64();
    println!(
        "{} bytes, {frames} frames decoded in {:.4} s: {:.1} MB/s, {:.0} frames/s",
        bytes.len(),
        dt,
        bytes.len() as f64 / dt / 1e6,
        f64::from(frames) / dt
    );
}
