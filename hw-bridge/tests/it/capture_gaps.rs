//! A capture with one IMU frame lost (a flipped byte fails its CRC) through the path
//! `hw-bridge replay --config` uses (`decode_capture` then `run_filter_on_frames`, i.e.
//! the run engine, `nav-engine`): the lost frame is seen as a one-sample gap, its increment is
//! filled, and the solution stays with the one from the intact capture.
use hw_bridge::capture::{CaptureHeader, CaptureWriter, Record};
use hw_bridge::cmd::{decode_capture, read_case, run_filter_on_frames};
use nav_core::wire::{Encoder, Payload, MAX_FRAME_LEN};
use std::path::Path;
use test_support::scenario::ScenarioToml;

use crate::simcase;

fn scenario() -> nav_sim::Scenario {
    ScenarioToml::new("capture-gaps")
        .description("2 min drive")
        .start(30.5, 114.3, 20.0, 120.0)
        .gps_time(2300, 200000.0)
        .imu_rate_hz(100.0)
        .stationary(20.0)
        .accelerate(10.0, 10.0)
        .turn(90.0, 30.0)
        .cruise(60.0)
        .brake(0.0, 10.0)
        .scenario()
}

/// Writes a capture of the case's frames in 4 kB chunks; with `flip = Some(k)` one byte in
/// the middle of the k-th IMU frame is changed (never into the 0x00 delimiter).
fn write_capture(case: &Path, path: &Path, flip: Option<usize>) -> usize {
    let payloads = read_case(case).unwrap();
    let mut enc = Encoder::new();
    let mut bytes = vec![0u8];
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut imu_k = 0usize;
    let mut flipped_at = 0;
    for (_, p) in &payloads {
        let n = enc.encode(p, &mut buf).unwrap();
        let start = bytes.len();
        bytes.extend_from_slice(&buf[..n]);
        if matches!(p, Payload::Imu(_)) {
            if flip == Some(imu_k) {
                let i = start + n / 2;
                bytes[i] ^= if bytes[i] == 1 { 2 } else { 1 };
                flipped_at = i;
            }
            imu_k += 1;
        }
    }
    let f = std::fs::File::create(path).unwrap();
    let mut w = CaptureWriter::new(f, &CaptureHeader::default()).unwrap();
    for (k, c) in bytes.chunks(4096).enumerate() {
        w.write(&Record::Data {
            t_ns: k as u64 * 1_000_000,
            bytes: c.to_vec(),
        })
        .unwrap();
    }
    w.flush().unwrap();
    flipped_at
}

#[test]
fn a_lost_imu_frame_is_filled_and_the_solution_kept() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let case = d.join("case");
    let config = simcase::write_case(&case, &scenario(), 3, &[]);
    let n_imu = nav_io::read_imu_text(case.join("imu.txt"))
        .unwrap()
        .samples
        .len();

    let run = |flip: Option<usize>| {
        let cap = d.join(format!("cap-{flip:?}.bin"));
        write_capture(&case, &cap, flip);
        let dec = decode_capture(&cap).unwrap();
        let f = run_filter_on_frames(&dec.log, &nav_engine::RunSpec::new(&config)).unwrap();
        (dec, f)
    };
    let (dec0, intact) = run(None);
    assert_eq!(dec0.stats.lost(), 0);
    assert_eq!(dec0.log.imu.len(), n_imu);
    assert_eq!(intact.output.counters.imu_gaps, 0);

    // lose the IMU frame of t0 + 40.5 s: in the cruise after the turn
    let (dec, lossy) = run(Some(4049));
    assert_eq!(dec.log.imu.len(), n_imu - 1, "exactly one IMU frame lost");
    assert_eq!(dec.stats.lost(), 1, "the decoder counts it by sequence");
    let c = &lossy.output.counters;
    assert_eq!(c.imu_gaps, 1);
    assert_eq!(c.imu_missing_samples, 1);
    assert_eq!(c.imu_gaps_filled, 1, "a lost frame loses its increment");
    assert_eq!(c.imu_synthetic_samples, 1);
    // every IMU epoch is integrated, the fill included
    assert_eq!(c.imu_epochs, intact.output.counters.imu_epochs);
    assert!(c.gnss_rejected <= intact.output.counters.gnss_rejected);
    let (m, m0) = (&lossy.metrics.overall, &intact.metrics.overall);
    println!(
        "lost frame: h RMS {:.4} vs {:.4} m, D RMS {:.4} vs {:.4} m, rejected {} vs {}",
        m.pos_horizontal_m.rms,
        m0.pos_horizontal_m.rms,
        m.pos_d_m.rms,
        m0.pos_d_m.rms,
        c.gnss_rejected,
        intact.output.counters.gnss_rejected
    );
    assert!(m.pos_horizontal_m.rms <= 1.5 * m0.pos_horizontal_m.rms);
    assert!(m.pos_horizontal_m.max <= 1.5 * m0.pos_horizontal_m.max);
    assert!(m.pos_d_m.rms <= 1.5 * m0.pos_d_m.rms);
    assert!(m.pos_d_m.max <= 1.5 * m0.pos_d_m.max);
}
