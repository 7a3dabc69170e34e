//! Fault injection over captures and the command line: truncation at every byte (record
//! boundaries and inside records), bit flips, duplicated and reordered chunks, hostile
//! timestamps, empty, header-only and garbage-prefixed files, and hostile CLI values. Every
//! case ends without a panic, within a time bound, and with the counters
//! `docs/wire-protocol.md` promises: per stream `sent = delivered + lost` exactly where the
//! document says so (the stream's last frame arrived; with `streams_from_start` also when its
//! first frames are lost).

use hw_bridge::capture::{
    CaptureHeader, CaptureWriter, Record, LINK_RESET as LINK_RESET_FLAG, MAGIC,
};
use hw_bridge::cmd::{replay, ReplayOptions};
use hw_bridge::frames::case_payloads;
use nav_core::types::{FixQuality, GnssFix, ImuSample};
use nav_core::wire::{encode_raw, Encoder, Frame, MsgType, Payload, MAX_FRAME_LEN, MAX_RAW_LEN};
use proptest::prelude::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
use test_support::scenario::ScenarioToml;

use crate::simcase;

const BIN: &str = env!("CARGO_BIN_EXE_hw-bridge");
const IMU: usize = 0;
const GNSS: usize = 1;

/// `n` IMU samples at 200 Hz with a temperature, and a GNSS fix every 20 samples (10 Hz).
fn case(n: usize) -> Vec<(f64, Payload)> {
    let imu: Vec<ImuSample> = (1..=n)
        .map(|i| {
            let x = i as f64;
            ImuSample {
                t_s: 1000.0 + x * 0.005,
                dtheta_rad: [1e-5 * (x * 0.37).sin(), -2e-6, 3e-6 * x.sqrt()],
                dv_mps: [0.01 + 1e-7 * x, -0.002, -0.049 + 1e-6 / x],
                temperature_c: 25.0 + x / 3.0,
            }
        })
        .collect();
    let gnss: Vec<GnssFix> = (1..=n / 20)
        .map(|k| {
            let x = k as f64;
            GnssFix {
                t_s: 1000.0 + x * 0.1,
                lat_rad: 0.5 + x * 1e-8,
                lon_rad: 1.9 - x * 1e-8,
                h_m: 25.0 + x / 7.0,
                pos_std_ned_m: [0.5, 0.6, 1.1],
                vel_ned_mps: [1.0 + x / 3.0, -0.5, 0.01],
                vel_std_ned_mps: [0.05, 0.05, 0.1],
                has_velocity: true,
                quality: FixQuality::Single,
                num_sats: 9,
            }
        })
        .collect();
    case_payloads(&imu, &gnss)
}

/// What `send` writes for `payloads`: a leading 0x00, then every frame (one encoder). Returns
/// the bytes, the frames, and the end offset (after the delimiter) of each frame.
fn wire(payloads: &[(f64, Payload)]) -> (Vec<u8>, Vec<Frame>, Vec<usize>) {
    let mut enc = Encoder::new();
    let mut bytes = vec![0u8];
    let mut frames = Vec::new();
    let mut ends = Vec::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (_, p) in payloads {
        frames.push(enc.peek(p));
        let n = enc.encode(p, &mut buf).unwrap();
        bytes.extend_from_slice(&buf[..n]);
        ends.push(bytes.len());
    }
    (bytes, frames, ends)
}

fn raw(f: &Frame) -> Vec<u8> {
    let mut b = [0u8; MAX_RAW_LEN];
    let n = encode_raw(f, &mut b).unwrap();
    b[..n].to_vec()
}

fn header(from_start: bool) -> CaptureHeader {
    CaptureHeader {
        port: "/dev/pts/test".into(),
        baud: 921_600,
        start_unix_ns: 1,
        tool: "faults test".into(),
        streams_from_start: from_start,
    }
}

/// Records of `bytes` cut at `cuts` (offsets), 5 ms apart.
fn records_at(bytes: &[u8], cuts: &[usize]) -> Vec<Record> {
    let mut out = Vec::new();
    let mut at = 0;
    for (k, &c) in cuts.iter().chain([bytes.len()].iter()).enumerate() {
        if c > at {
            out.push(Record::Data {
                t_ns: 1_000_000 + k as u64 * 5_000_000,
                bytes: bytes[at..c].to_vec(),
            });
            at = c;
        }
    }
    out
}

/// Records of `bytes` in pseudo-random chunk sizes (1..=max), 5 ms apart.
fn records_random(bytes: &[u8], max: usize, seed: u64) -> Vec<Record> {
    let mut x = seed | 1;
    let mut cuts = Vec::new();
    let mut at = 0;
    loop {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        at += 1 + (x as usize % max);
        if at >= bytes.len() {
            break;
        }
        cuts.push(at);
    }
    records_at(bytes, &cuts)
}

fn capture_bytes(h: &CaptureHeader, recs: &[Record]) -> Vec<u8> {
    let mut w = CaptureWriter::new(Vec::new(), h).unwrap();
    for r in recs {
        w.write(r).unwrap();
    }
    w.into_inner()
}

fn put(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// Byte offset from which the stream must stay intact so that the last frame of the IMU and
/// GNSS streams arrives (the identity holds "once the stream's latest frame has arrived").
fn protect_from(frames: &[Frame], ends: &[usize]) -> usize {
    let last = |t: MsgType| {
        frames
            .iter()
            .rposition(|f| f.payload.msg_type() == t)
            .unwrap()
    };
    ends[last(MsgType::Imu).min(last(MsgType::Gnss)) - 1]
}

fn sent_per_stream(frames: &[Frame]) -> [u64; 5] {
    let mut n = [0u64; 5];
    for f in frames {
        n[f.payload.msg_type().stream_index()] += 1;
    }
    n
}

/// Asserts `sent = delivered + lost` for the IMU and GNSS streams.
fn assert_identity(o: &hw_bridge::cmd::ReplayOutcome, sent: [u64; 5], what: &str) {
    for s in [IMU, GNSS] {
        let d = u64::from(o.stats.frames_ok_by_stream[s]);
        let l = u64::from(o.stats.lost_by_stream[s]);
        assert_eq!(
            d + l,
            sent[s],
            "{what}: stream {s}: delivered {d} + lost {l} != sent {}",
            sent[s]
        );
    }
}

fn run_cli(args: &[&str], bound: Duration) -> Output {
    let t = Instant::now();
    let out = Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run hw-bridge");
    let el = t.elapsed();
    assert!(el < bound, "{args:?} took {el:?} (bound {bound:?})");
    out
}

#[test]
fn truncation_at_every_byte_replays_every_complete_record_and_says_incomplete() {
    let t0 = Instant::now();
    let payloads = case(60);
    let (bytes, frames, ends) = wire(&payloads);
    let recs = records_random(&bytes, 300, 3);
    let h = header(true);
    let full = capture_bytes(&h, &recs);
    let hlen = 12 + u32::from_le_bytes(full[8..12].try_into().unwrap()) as usize;
    // record boundaries in the file, and the data bytes before each
    let mut bounds = vec![(hlen, 0usize)];
    for r in &recs {
        let (off, data) = *bounds.last().unwrap();
        if let Record::Data { bytes, .. } = r {
            bounds.push((off + 12 + bytes.len(), data + bytes.len()));
        }
    }
    assert_eq!(bounds.last().unwrap().0, full.len());
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for cut in 0..=full.len() {
        let p = put(dir.path(), "cut.cap", &full[..cut]);
        let r = replay(&ReplayOptions::new(&p));
        if cut == 0 {
            let e = format!("{:#}", r.unwrap_err());
            assert!(e.ends_with("empty file"), "{e}");
            continue;
        }
        if cut < hlen {
            let e = format!("{:#}", r.unwrap_err());
            assert!(e.contains("header truncated"), "cut {cut}: {e}");
            continue;
        }
        let o = r.unwrap();
        // complete records before the cut, and their data bytes
        let k = bounds.iter().rposition(|b| b.0 <= cut).unwrap();
        let (off, data) = bounds[k];
        assert_eq!(o.records, k as u64, "cut {cut}");
        assert_eq!(o.bytes, data as u64, "cut {cut}");
        assert_eq!(
            o.incomplete.is_some(),
            off != cut,
            "cut {cut}: {:?}",
            o.incomplete
        );
        // exactly the frames whose delimiter came in the complete records, bit for bit
        let n = ends.iter().filter(|&&e| e <= data).count();
        assert_eq!(o.log.frames.len(), n, "cut {cut}");
        for (a, b) in o.log.frames.iter().zip(&frames) {
            assert_eq!(raw(a), raw(b), "cut {cut}");
        }
        assert_eq!(o.stats.rejected(), 0, "cut {cut}");
        assert_eq!(o.stats.lost(), 0, "cut {cut}");
        checked += 1;
    }
    assert!(checked > 4000, "{checked} cuts");
    assert!(t0.elapsed() < Duration::from_secs(60), "{:?}", t0.elapsed());
}

#[test]
fn bit_flips_in_the_data_keep_sent_equal_delivered_plus_lost_exactly() {
    let payloads = case(400);
    let (bytes, frames, ends) = wire(&payloads);
    let sent = sent_per_stream(&frames);
    // the last frame of each stream must arrive (see the doc): flip only before them
    let protect_from = protect_from(&frames, &ends);
    let dir = tempfile::tempdir().unwrap();
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let mut total_lost = 0u64;
    for trial in 0..200 {
        let mut b = bytes.clone();
        for _ in 0..1 + trial % 8 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let at = (x as usize) % protect_from;
            b[at] ^= 1 << ((x >> 32) % 8);
        }
        let cap = capture_bytes(&header(true), &records_random(&b, 500, trial + 1));
        let p = put(dir.path(), "flip.cap", &cap);
        let o = replay(&ReplayOptions::new(&p)).unwrap();
        assert!(o.incomplete.is_none());
        assert_identity(&o, sent, &format!("trial {trial}"));
        let delivered = u64::from(o.stats.frames_ok);
        assert!(delivered < frames.len() as u64 || o.stats.rejected() == 0);
        total_lost += u64::from(o.stats.lost());
    }
    assert!(total_lost > 200, "flips lost only {total_lost} frames");
}

#[test]
fn a_lost_first_frame_is_counted_when_the_capture_holds_the_streams_from_the_start() {
    let payloads = case(100);
    let (bytes, frames, ends) = wire(&payloads);
    let sent = sent_per_stream(&frames);
    // drop the first IMU frame (and, separately, the first three frames of every stream)
    let dir = tempfile::tempdir().unwrap();
    let mut b = vec![0u8];
    b.extend_from_slice(&bytes[ends[0]..]);
    for from_start in [true, false] {
        let cap = capture_bytes(&header(from_start), &records_random(&b, 200, 5));
        let p = put(dir.path(), "first.cap", &cap);
        let o = replay(&ReplayOptions::new(&p)).unwrap();
        assert_eq!(o.stats.frames_ok_by_stream[IMU] as u64, sent[IMU] - 1);
        if from_start {
            assert_identity(&o, sent, "first IMU frame lost, streams from start");
            assert_eq!(o.stats.lost_by_stream[IMU], 1);
        } else {
            // the documented blind spot without the header key: nothing counts it
            assert_eq!(o.stats.lost_by_stream[IMU], 0);
        }
    }
    // the first GNSS frame and the first 5 IMU frames lost
    let first_gnss = frames
        .iter()
        .position(|f| f.payload.msg_type() == MsgType::Gnss)
        .unwrap();
    let mut b = vec![0u8];
    for (i, f) in frames.iter().enumerate() {
        let start = if i == 0 { 1 } else { ends[i - 1] };
        let skip = i == first_gnss || (f.payload.msg_type() == MsgType::Imu && f.seq < 5);
        if !skip {
            b.extend_from_slice(&bytes[start..ends[i]]);
        }
    }
    let cap = capture_bytes(&header(true), &records_random(&b, 300, 6));
    let o = replay(&ReplayOptions::new(put(dir.path(), "first2.cap", &cap))).unwrap();
    assert_eq!(o.stats.lost_by_stream[IMU], 5);
    assert_eq!(o.stats.lost_by_stream[GNSS], 1);
    assert_identity(&o, sent, "first frames lost");
}

#[test]
fn a_repeated_record_is_replayed_and_its_frames_counted_backwards_by_sequence_number() {
    let payloads = case(200);
    let (bytes, frames, ends) = wire(&payloads);
    let sent = sent_per_stream(&frames);
    // frame-aligned records of 10 frames
    let cuts: Vec<usize> = ends.iter().step_by(10).copied().collect();
    let recs = records_at(&bytes, &cuts);
    let dir = tempfile::tempdir().unwrap();
    let clean = replay(&ReplayOptions::new(put(
        dir.path(),
        "clean.cap",
        &capture_bytes(&header(true), &recs),
    )))
    .unwrap();
    assert_identity(&clean, sent, "clean");
    // the same record twice (same time, same bytes): the capture format has no record
    // sequence number, so both are replayed; the frames' sequence numbers say it
    let mut dup = recs.clone();
    dup.insert(6, recs[5].clone());
    let o = replay(&ReplayOptions::new(put(
        dir.path(),
        "dup.cap",
        &capture_bytes(&header(true), &dup),
    )))
    .unwrap();
    assert_eq!(o.records, dup.len() as u64);
    assert_eq!(o.stats.backwards_by_stream[IMU], 1);
    assert_eq!(o.stats.backwards_by_stream[GNSS], 1);
    assert_eq!(o.stats.lost(), 0);
    assert_eq!(o.log.imu, clean.log.imu);
    assert_eq!(o.log.gnss, clean.log.gnss);
    assert!(o.incomplete.is_none(), "{:?}", o.incomplete);
    // the documented blind spot: the repeated frames are delivered twice (record 5 holds 9
    // IMU frames and 1 GNSS frame)
    assert_eq!(u64::from(o.stats.frames_ok_by_stream[IMU]), sent[IMU] + 9);
    assert_eq!(u64::from(o.stats.frames_ok_by_stream[GNSS]), sent[GNSS] + 1);
    // the same bytes again 1 ms later: the frames arrive twice; the IMU samples of the second
    // copy are not after the previous sample and are left out of imu.txt
    let Record::Data { t_ns, bytes: b5 } = recs[5].clone() else {
        unreachable!()
    };
    // record 0 is the leading 0x00 and frame 0; record k >= 1 holds frames 10k-9 ..= 10k
    let imu_in_5 = frames[41..51]
        .iter()
        .filter(|f| f.payload.msg_type() == MsgType::Imu)
        .count();
    assert_eq!(imu_in_5, 9, "frame 41 is the second GNSS fix");
    let mut shifted = recs.clone();
    shifted.insert(
        6,
        Record::Data {
            t_ns: t_ns + 1_000_000,
            bytes: b5,
        },
    );
    let o = replay(&ReplayOptions::new(put(
        dir.path(),
        "dup2.cap",
        &capture_bytes(&header(true), &shifted),
    )))
    .unwrap();
    assert_eq!(o.stats.backwards_by_stream[IMU], 1);
    assert_eq!(o.stats.backwards_by_stream[GNSS], 1);
    assert_eq!(
        o.stats.lost(),
        0,
        "the copy ends where the next record starts"
    );
    assert_eq!(o.imu_out_of_order, imu_in_5 as u64);
    assert_eq!(o.gnss_out_of_order, 1);
    assert_eq!(o.log.imu, clean.log.imu);
    assert_eq!(o.log.gnss, clean.log.gnss);
    assert_eq!(
        u64::from(o.stats.frames_ok),
        frames.len() as u64 + 10,
        "every copy is delivered"
    );
}

#[test]
fn reordered_records_deliver_every_frame_and_the_counters_say_what_happened() {
    let payloads = case(200);
    let (bytes, frames, ends) = wire(&payloads);
    let sent = sent_per_stream(&frames);
    let cuts: Vec<usize> = ends.iter().step_by(10).copied().collect();
    let mut recs = records_at(&bytes, &cuts);
    // swap records 3 and 4 (frames 21..=30 and 31..=40, all IMU), with their timestamps
    recs.swap(3, 4);
    let imu_in = |a: usize| {
        frames[a..a + 10]
            .iter()
            .filter(|f| f.payload.msg_type() == MsgType::Imu)
            .count() as u64
    };
    let dir = tempfile::tempdir().unwrap();
    let o = replay(&ReplayOptions::new(put(
        dir.path(),
        "swap.cap",
        &capture_bytes(&header(true), &recs),
    )))
    .unwrap();
    assert_eq!(u64::from(o.stats.frames_ok), frames.len() as u64);
    assert_eq!(o.stats.rejected(), 0);
    assert_eq!(o.timing.backwards, 1);
    assert_eq!(o.stats.backwards_by_stream[IMU], 1);
    // the documented blind spot: the early chunk's frames and the late chunk's are both
    // counted as lost (a gap before each), though every frame arrived
    assert_eq!(
        u64::from(o.stats.lost_by_stream[IMU]),
        imu_in(21) + imu_in(31)
    );
    assert_eq!(imu_in(21) + imu_in(31), 20);
    assert_eq!(o.stats.lost_by_stream[GNSS], 0);
    assert_eq!(o.imu_out_of_order, imu_in(21));
    assert_eq!(o.log.imu.len() as u64, sent[IMU] - imu_in(21));
}

#[test]
fn hostile_timestamps_are_paced_within_max_gap_and_counted() {
    let payloads = case(100);
    let (bytes, frames, _) = wire(&payloads);
    let mut recs = records_random(&bytes, 700, 9);
    let n = recs.len();
    assert!(n >= 8, "{n} records");
    // first timestamp u64::MAX, then back to 0, a jump of 2^62, a step back, normal again
    let stamps = [
        u64::MAX,
        0,
        1 << 62,
        5,
        6_000_000,
        u64::MAX - 1,
        u64::MAX,
        7,
    ];
    for (r, t) in recs.iter_mut().zip(stamps) {
        if let Record::Data { t_ns, .. } = r {
            *t_ns = t;
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let p = put(
        dir.path(),
        "hostile.cap",
        &capture_bytes(&header(true), &recs),
    );
    let mut a = ReplayOptions::new(&p);
    a.as_fast_as_possible = false;
    a.speed = Some(1.0);
    a.max_gap_s = 0.05;
    let t = Instant::now();
    let o = replay(&a).unwrap();
    let wall = t.elapsed();
    // jumps over 50 ms: 0 -> u64::MAX, 0 -> 2^62, 6 ms -> u64::MAX - 1; steps back:
    // u64::MAX -> 0, 2^62 -> 5, u64::MAX -> 7; then 7 ns -> the 9th record's own 41 ms and
    // 5 ms steps
    assert_eq!(o.timing.clamped_gaps, 3);
    assert_eq!(o.timing.backwards, 3);
    assert!(wall < Duration::from_secs(3), "replay took {wall:?}");
    assert_eq!(o.log.frames.len(), frames.len());
    // the CLI: u64::MAX as the first timestamp at --speed 1 (the default --max-gap, 10 s,
    // bounds the first wait)
    let recs2 = vec![
        Record::Data {
            t_ns: u64::MAX,
            bytes: bytes.clone(),
        },
        Record::Data {
            t_ns: 1,
            bytes: vec![0],
        },
    ];
    let p2 = put(dir.path(), "max.cap", &capture_bytes(&header(true), &recs2));
    let p2s = p2.to_str().unwrap();
    let out = run_cli(
        &["replay", p2s, "--speed", "1", "--max-gap", "0.2"],
        Duration::from_secs(5),
    );
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let out = run_cli(&["replay", p2s, "--speed", "1000"], Duration::from_secs(5));
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let so = String::from_utf8_lossy(&out.stdout);
    assert!(
        so.contains(&format!("frames delivered {}", frames.len())),
        "{so}"
    );
}

#[test]
fn empty_header_only_and_garbage_prefixed_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let empty = put(d, "empty.cap", b"");
    let out = run_cli(&["replay", empty.to_str().unwrap()], Duration::from_secs(5));
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.trim(),
        format!("error: reading capture {}: empty file", empty.display())
    );
    // magic only, magic and half a header length
    for cut in [8usize, 10] {
        let h = capture_bytes(&header(false), &[]);
        let p = put(d, "short.cap", &h[..cut]);
        let e = format!("{:#}", replay(&ReplayOptions::new(&p)).unwrap_err());
        assert!(
            e.ends_with("file ends in the header field at byte 8"),
            "{e}"
        );
    }
    // header only: a valid capture with nothing in it
    let p = put(d, "hdr.cap", &capture_bytes(&header(false), &[]));
    let out = d.join("out-hdr");
    let st = run_cli(
        &[
            "replay",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        Duration::from_secs(5),
    );
    assert_eq!(st.status.code(), Some(0), "{st:?}");
    let summary = std::fs::read_to_string(out.join("replay-summary.txt")).unwrap();
    assert!(
        summary.starts_with("status complete\ncapture records 0\n"),
        "{summary}"
    );
    assert!(!out.join("imu.txt").exists());
    // 1 MB of garbage before the header: found, skipped, counted
    let payloads = case(100);
    let (bytes, frames, _) = wire(&payloads);
    let cap = capture_bytes(&header(true), &records_random(&bytes, 400, 2));
    let mut g: Vec<u8> = (0..1_000_000u32).map(|i| (i * 7 + 3) as u8 | 1).collect();
    g.extend_from_slice(&MAGIC[..5]); // a false start too
    let skipped = g.len() as u64;
    g.extend_from_slice(&cap);
    let o = replay(&ReplayOptions::new(put(d, "garbage.cap", &g))).unwrap();
    assert_eq!(o.skipped_bytes, skipped);
    assert_eq!(o.log.frames.len(), frames.len());
    assert!(o.incomplete.is_none());
    // no magic in the first 64 MiB: refused after a bounded scan
    let t = Instant::now();
    let junk = vec![0x55u8; (64 << 20) + 64];
    let p = put(d, "junk.cap", &junk);
    let e = format!("{:#}", replay(&ReplayOptions::new(&p)).unwrap_err());
    assert!(e.contains("not a hw-bridge capture"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(20), "{:?}", t.elapsed());
}

#[test]
fn cli_refuses_hostile_speeds_and_durations_quickly_with_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let payloads = case(20);
    let (bytes, _, _) = wire(&payloads);
    let p = put(
        dir.path(),
        "c.cap",
        &capture_bytes(&header(true), &records_random(&bytes, 100, 1)),
    );
    let ps = p.to_str().unwrap();
    for bad in [
        "0", "NaN", "nan", "1e-300", "1e300", "-1", "inf", "0.0009", "1e6x",
    ] {
        let arg = format!("--speed={bad}");
        let out = run_cli(&["replay", ps, &arg], Duration::from_secs(5));
        assert_eq!(out.status.code(), Some(1), "--speed {bad}: {out:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--speed"), "{err}");
    }
    // the limits themselves are accepted (one record at time 0: nothing to wait for)
    let p0 = put(
        dir.path(),
        "c0.cap",
        &capture_bytes(
            &header(true),
            &[Record::Data {
                t_ns: 0,
                bytes: bytes.clone(),
            }],
        ),
    );
    for good in ["0.001", "1e6"] {
        let out = run_cli(
            &["replay", p0.to_str().unwrap(), "--speed", good],
            Duration::from_secs(5),
        );
        assert_eq!(out.status.code(), Some(0), "--speed {good}: {out:?}");
    }
    for bad in ["0", "NaN", "1e300", "-1"] {
        let out = run_cli(
            &[
                "send",
                "--case",
                ps,
                "--port",
                "/nonexistent",
                &format!("--rate-x={bad}"),
            ],
            Duration::from_secs(5),
        );
        assert_eq!(out.status.code(), Some(1), "--rate-x {bad}: {out:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("--rate-x"));
    }
    for (flag, bad) in [
        ("--duration", "nan"),
        ("--duration", "-1"),
        ("--duration", "inf"),
        ("--idle-exit", "0"),
        ("--first-byte-timeout", "nan"),
        ("--reopen-timeout", "1e300"),
    ] {
        let out = run_cli(
            &[
                "record",
                "--port",
                "/nonexistent",
                "--out",
                ps,
                &format!("{flag}={bad}"),
            ],
            Duration::from_secs(5),
        );
        assert_eq!(out.status.code(), Some(1), "{flag} {bad}: {out:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(flag));
    }
    for bad in ["0", "nan", "-3"] {
        let arg = format!("--max-gap={bad}");
        let out = run_cli(&["replay", ps, &arg], Duration::from_secs(5));
        assert_eq!(out.status.code(), Some(1), "--max-gap {bad}: {out:?}");
    }
    // the capture is untouched by the refused record commands
    assert_eq!(&std::fs::read(&p).unwrap()[..8], MAGIC);
}

#[test]
fn error_messages_say_each_cause_once() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.cap");
    let out = run_cli(
        &["replay", missing.to_str().unwrap()],
        Duration::from_secs(5),
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
    // a nav-io reader error (its message contains its source) through send
    let out = run_cli(
        &[
            "send",
            "--case",
            dir.path().to_str().unwrap(),
            "--port",
            "/nonexistent",
        ],
        Duration::from_secs(5),
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("imu.txt"), "{err}");
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
}

#[test]
fn a_truncated_capture_exits_2_with_complete_outputs_marked_incomplete() {
    let payloads = case(200);
    let (bytes, frames, _) = wire(&payloads);
    let dir = tempfile::tempdir().unwrap();
    let cap = capture_bytes(&header(true), &records_random(&bytes, 300, 4));
    let p = put(dir.path(), "t.cap", &cap[..cap.len() - 5]);
    let out = dir.path().join("out");
    let st = run_cli(
        &[
            "replay",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        Duration::from_secs(10),
    );
    assert_eq!(st.status.code(), Some(2), "{st:?}");
    let summary = std::fs::read_to_string(out.join("replay-summary.txt")).unwrap();
    assert!(
        summary.starts_with("status incomplete: capture truncated in record"),
        "{summary}"
    );
    let imu = nav_io::read_imu_text(out.join("imu.txt")).unwrap().samples;
    let lib = replay(&ReplayOptions::new(&p)).unwrap();
    assert_eq!(imu, lib.log.imu);
    // records are at most 300 bytes: at most 4 frames go with the truncated one
    assert!(imu.len() > 195, "{} IMU samples", imu.len());
    assert!(lib.log.frames.len() < frames.len() && lib.log.frames.len() + 4 >= frames.len());
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.ends_with(".partial")), "{names:?}");
}

#[test]
fn streamed_outputs_equal_nav_io_writers_byte_for_byte() {
    // the temperature column decided by a first sample without temperature, then changed
    let mut payloads = case(300);
    for (t, p) in payloads.iter_mut().take(3) {
        if let Payload::Imu(i) = p {
            i.sample.temperature_c = f64::NAN;
            assert!(*t > 0.0);
        }
    }
    for variant in 0..3 {
        let flip_temp = variant == 2;
        let mut pl = if variant == 0 {
            case(300)
        } else {
            payloads.clone()
        };
        if flip_temp {
            for (_, p) in &mut pl {
                if let Payload::Imu(i) = p {
                    i.sample.temperature_c = f64::NAN;
                }
            }
        }
        let (bytes, _, _) = wire(&pl);
        let dir = tempfile::tempdir().unwrap();
        let p = put(
            dir.path(),
            "s.cap",
            &capture_bytes(&header(true), &records_random(&bytes, 500, 8)),
        );
        let mut a = ReplayOptions::new(&p);
        let out = dir.path().join("out");
        a.out = Some(out.clone());
        let o = replay(&a).unwrap();
        nav_io::write_imu_text(dir.path().join("imu.txt"), &o.log.imu).unwrap();
        nav_io::write_gnss_text(dir.path().join("gnss.txt"), &o.log.gnss).unwrap();
        for f in ["imu.txt", "gnss.txt"] {
            let a = std::fs::read(out.join(f)).unwrap();
            let b = std::fs::read(dir.path().join(f)).unwrap();
            assert!(!a.is_empty());
            assert!(
                a == b,
                "{f} differs from nav-io's writer (variant {variant})"
            );
        }
    }
}

#[test]
fn a_killed_replay_leaves_checkpointed_partial_files_and_no_final_names() {
    let payloads = case(1000); // 5 s of IMU
    let (bytes, _, ends) = wire(&payloads);
    // one record per 20 frames, at the recorded times of their last frame (100 ms apart)
    let mut recs = Vec::new();
    let mut at = 0;
    for (k, &e) in ends.iter().enumerate().skip(19).step_by(20) {
        recs.push(Record::Data {
            t_ns: (k as u64 + 1) * 5_000_000,
            bytes: bytes[at..e].to_vec(),
        });
        at = e;
    }
    let dir = tempfile::tempdir().unwrap();
    let p = put(dir.path(), "k.cap", &capture_bytes(&header(true), &recs));
    let out = dir.path().join("out");
    let mut child = Command::new(BIN)
        .args(["replay", "--speed", "1", "--out"])
        .arg(&out)
        .arg(&p)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(2600));
    child.kill().unwrap();
    let _ = child.wait();
    assert!(!out.join("imu.txt").exists());
    assert!(!out.join("replay-summary.txt").exists());
    let partial = std::fs::read_to_string(out.join("imu.txt.partial")).unwrap();
    let lines = partial.lines().count();
    // at least the first checkpoint (1 s of wall time = 1 s of data at --speed 1)
    assert!(lines >= 190, "{lines} lines in imu.txt.partial");
    assert!(lines < 1000, "{lines} lines: the replay was not paced");
    // the lines are the complete replay's first lines
    let full = dir.path().join("full");
    let mut a = ReplayOptions::new(&p);
    a.out = Some(full.clone());
    replay(&a).unwrap();
    let want = std::fs::read_to_string(full.join("imu.txt")).unwrap();
    assert!(want.starts_with(&partial), "partial file is not a prefix");
}

/// A link fault applied to the byte stream.
#[derive(Debug, Clone)]
enum Fault {
    Flip { at: usize, bit: u8 },
    Drop { at: usize, len: usize },
    Garbage { at: usize, bytes: Vec<u8> },
    Reset { at: usize },
}

fn fault() -> impl Strategy<Value = Fault> {
    prop_oneof![
        (any::<usize>(), 0u8..8).prop_map(|(at, bit)| Fault::Flip { at, bit }),
        (any::<usize>(), 1usize..400).prop_map(|(at, len)| Fault::Drop { at, len }),
        (
            any::<usize>(),
            proptest::collection::vec(any::<u8>(), 1..200)
        )
            .prop_map(|(at, bytes)| Fault::Garbage { at, bytes }),
        any::<usize>().prop_map(|at| Fault::Reset { at }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// Random flips, dropped byte runs, garbage and link resets anywhere before the last
    /// frame: the capture replays without panic and per stream sent = delivered + lost.
    #[test]
    fn random_link_faults_keep_the_counter_identity(
        faults in proptest::collection::vec(fault(), 0..12),
        chunk in 1usize..600,
        seed in any::<u64>(),
    ) {
        let payloads = case(300);
        let (bytes, frames, ends) = wire(&payloads);
        let sent = sent_per_stream(&frames);
        // the last frame of each stream arrives intact: faults only before them
        let limit = protect_from(&frames, &ends);
        let (mut head, tail) = (bytes[..limit].to_vec(), bytes[limit..].to_vec());
        let mut resets = Vec::new();
        for f in &faults {
            match f {
                Fault::Flip { at, bit } => {
                    let i = at % head.len();
                    head[i] ^= 1 << bit;
                }
                Fault::Drop { at, len } => {
                    let i = at % head.len();
                    let j = (i + len).min(head.len());
                    head.drain(i..j);
                    if head.is_empty() { head.push(0); }
                }
                Fault::Garbage { at, bytes } => {
                    let i = at % head.len();
                    head.splice(i..i, bytes.iter().copied());
                }
                Fault::Reset { at } => resets.push(at % head.len()),
            }
        }
        // a link reset ends the previous record: split the head there
        resets.sort_unstable();
        resets.dedup();
        let mut recs = Vec::new();
        let mut at = 0;
        let mut t = 1u64;
        for &r in resets.iter().chain([head.len()].iter()) {
            // a reset drawn before later drops shortened the head lies past its end now
            let r = r.min(head.len());
            for rec in records_random(&head[at..r.max(at)], chunk, seed) {
                if let Record::Data { bytes, .. } = rec {
                    t += 1;
                    recs.push(Record::Data { t_ns: t, bytes });
                }
            }
            at = r.max(at);
            if r < head.len() {
                t += 1;
                recs.push(Record::LinkReset { t_ns: t });
            }
        }
        recs.push(Record::Data { t_ns: t + 1, bytes: vec![0] });
        recs.push(Record::Data { t_ns: t + 2, bytes: tail });
        let dir = tempfile::tempdir().unwrap();
        let p = put(dir.path(), "p.cap", &capture_bytes(&header(true), &recs));
        let start = Instant::now();
        let o = replay(&ReplayOptions::new(&p)).unwrap();
        prop_assert!(start.elapsed() < Duration::from_secs(5));
        for s in [IMU, GNSS] {
            prop_assert_eq!(
                u64::from(o.stats.frames_ok_by_stream[s]) + u64::from(o.stats.lost_by_stream[s]),
                sent[s],
                "stream {} faults {:?}", s, faults
            );
        }
        prop_assert_eq!(o.stats.backwards_by_stream, [0; 5]);
    }

    /// Any bytes at all as a capture file: no panic, an error or an outcome, quickly.
    #[test]
    fn arbitrary_files_never_panic(prefix in proptest::collection::vec(any::<u8>(), 0..64),
                                    body in proptest::collection::vec(any::<u8>(), 0..600),
                                    with_magic in any::<bool>()) {
        let mut f = prefix;
        if with_magic {
            f.extend_from_slice(&capture_bytes(&header(true), &[])[..]);
        }
        f.extend_from_slice(&body);
        let dir = tempfile::tempdir().unwrap();
        let p = put(dir.path(), "a.cap", &f);
        let mut a = ReplayOptions::new(&p);
        a.as_fast_as_possible = false;
        a.speed = Some(1.0);
        a.max_gap_s = 0.01;
        let start = Instant::now();
        let _ = replay(&a);
        prop_assert!(start.elapsed() < Duration::from_secs(10));
    }
}

fn drive() -> nav_sim::Scenario {
    ScenarioToml::new("faults-config")
        .description("40 s drive for the duplicated-chunk replay --config test")
        .start(48.2, 16.37, 220.0, 30.0)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(200.0)
        .stationary(15.0)
        .accelerate(10.0, 8.0)
        .turn(90.0, 40.0)
        .cruise(8.0)
        .scenario()
}

#[test]
fn replay_config_on_a_capture_with_a_duplicated_chunk_writes_every_output_and_the_clean_solution() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let case_dir = d.join("case");
    let config = simcase::write_case(&case_dir, &drive(), 3, &[]);
    let payloads = hw_bridge::cmd::read_case(&case_dir).unwrap();
    let (bytes, frames, ends) = wire(&payloads);
    // records of 50 frames; record 40 again, 1 ms later (a duplicated chunk)
    let cuts: Vec<usize> = ends.iter().step_by(50).copied().collect();
    let recs = records_at(&bytes, &cuts);
    let Record::Data { t_ns, bytes: b40 } = recs[40].clone() else {
        unreachable!()
    };
    let mut dup = recs.clone();
    dup.insert(
        41,
        Record::Data {
            t_ns: t_ns + 1_000_000,
            bytes: b40,
        },
    );
    let mut outs = Vec::new();
    for (name, rs) in [("clean", &recs), ("dup", &dup)] {
        let p = put(d, &format!("{name}.cap"), &capture_bytes(&header(true), rs));
        let out = d.join(format!("out-{name}"));
        let st = run_cli(
            &[
                "replay",
                p.to_str().unwrap(),
                "--config",
                config.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            Duration::from_secs(120),
        );
        assert_eq!(st.status.code(), Some(0), "{name}: {st:?}");
        outs.push((out, String::from_utf8_lossy(&st.stdout).into_owned()));
    }
    let (clean, dupd) = (&outs[0], &outs[1]);
    assert!(dupd.1.contains("filter: model kf-gins"), "{}", dupd.1);
    let summary = std::fs::read_to_string(dupd.0.join("replay-summary.txt")).unwrap();
    assert!(summary.starts_with("status complete\n"), "{summary}");
    // the duplicated record's IMU samples are left out: the filter sees the clean input
    let n_imu_40 = frames[50 * 39 + 1..50 * 40 + 1]
        .iter()
        .filter(|f| f.payload.msg_type() == MsgType::Imu)
        .count();
    assert!(
        summary.contains(&format!("imu samples out of order (left out) {n_imu_40}\n")),
        "{summary}"
    );
    for f in [
        "imu.txt",
        "gnss.txt",
        "nav.txt",
        "std.txt",
        "bias.txt",
        "innovations.txt",
        "metrics.json",
    ] {
        let a = std::fs::read(clean.0.join(f)).unwrap();
        let b = std::fs::read(dupd.0.join(f)).unwrap();
        assert!(!a.is_empty(), "{f} is empty");
        assert!(a == b, "{f}: the duplicated chunk changed it");
    }
}

/// Records of `len` bytes each (the last one shorter), `per_tick` consecutive records sharing
/// one time stamp (a logger with a coarse clock), 1 ms between ticks.
fn records_fixed(bytes: &[u8], len: usize, per_tick: usize) -> Vec<Record> {
    bytes
        .chunks(len)
        .enumerate()
        .map(|(k, c)| Record::Data {
            t_ns: 1_000_000 * (1 + (k / per_tick) as u64),
            bytes: c.to_vec(),
        })
        .collect()
}

#[test]
fn captures_chunked_in_1_and_16_byte_records_at_one_time_stamp_decode_every_fix() {
    let t0 = Instant::now();
    // 116 fixes, as in the field report
    let payloads = case(2320);
    let (bytes, frames, _) = wire(&payloads);
    let sent = sent_per_stream(&frames);
    assert_eq!(sent[GNSS], 116);
    let dir = tempfile::tempdir().unwrap();
    let whole = replay(&ReplayOptions::new(put(
        dir.path(),
        "whole.cap",
        &capture_bytes(&header(true), &records_fixed(&bytes, bytes.len(), 1)),
    )))
    .unwrap();
    assert_eq!(whole.log.gnss.len(), 116);
    for (len, per_tick) in [(1usize, 100_000usize), (1, 1), (16, 1000), (16, 1)] {
        let recs = records_fixed(&bytes, len, per_tick);
        // consecutive records with the same time and bytes exist in these captures
        let repeats = recs.windows(2).filter(|w| w[0] == w[1]).count();
        assert!(
            len > 1 || per_tick == 1 || repeats > 0,
            "{len}-byte records: no repeats"
        );
        let name = format!("chunk{len}-{per_tick}.cap");
        let p = put(dir.path(), &name, &capture_bytes(&header(true), &recs));
        let o = replay(&ReplayOptions::new(&p)).unwrap();
        assert_eq!(o.records, recs.len() as u64, "{name}");
        assert_eq!(o.bytes, bytes.len() as u64, "{name}");
        assert_eq!(o.log.gnss, whole.log.gnss, "{name}: every fix decodes");
        assert_eq!(o.log.imu, whole.log.imu, "{name}");
        assert_eq!(o.stats.lost(), 0, "{name}");
        assert!(o.incomplete.is_none(), "{name}: {:?}", o.incomplete);
        assert_identity(&o, sent, &name);
    }
    // through the command line: exit 0 and every fix in gnss.txt
    let p = dir.path().join("chunk16-1000.cap");
    let out = dir.path().join("out16");
    let st = run_cli(
        &[
            "replay",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        Duration::from_secs(30),
    );
    assert_eq!(st.status.code(), Some(0), "{st:?}");
    let g = nav_io::read_gnss_text(out.join("gnss.txt")).unwrap();
    assert_eq!(g.len(), 116);
    assert!(t0.elapsed() < Duration::from_secs(60), "{:?}", t0.elapsed());
}

#[test]
fn a_capture_ending_with_the_link_lost_is_incomplete_and_exits_2() {
    let payloads = case(200);
    let (bytes, frames, _) = wire(&payloads);
    let dir = tempfile::tempdir().unwrap();
    let mut recs = records_random(&bytes, 300, 9);
    let t_end = recs.last().unwrap().t_ns();
    // a link reset in the middle, the data going on after it: complete
    let mid = recs.len() / 2;
    let t_mid = recs[mid].t_ns();
    recs.insert(mid, Record::LinkReset { t_ns: t_mid });
    let o = replay(&ReplayOptions::new(put(
        dir.path(),
        "mid.cap",
        &capture_bytes(&header(true), &recs),
    )))
    .unwrap();
    assert!(o.incomplete.is_none(), "{:?}", o.incomplete);
    assert!(!o.ended_link_lost);
    // the same capture ending with the link lost: incomplete, every frame still decoded
    recs.push(Record::LinkReset { t_ns: t_end + 1 });
    let p = put(dir.path(), "lost.cap", &capture_bytes(&header(true), &recs));
    let o = replay(&ReplayOptions::new(&p)).unwrap();
    assert!(o.ended_link_lost);
    let why = o.incomplete.clone().expect("incomplete");
    assert!(why.contains("link lost"), "{why}");
    assert_eq!(o.records, recs.len() as u64);
    assert!(
        o.log.frames.len() + 2 >= frames.len(),
        "{}",
        o.log.frames.len()
    );
    let out = dir.path().join("out");
    let st = run_cli(
        &[
            "replay",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        Duration::from_secs(10),
    );
    assert_eq!(st.status.code(), Some(2), "{st:?}");
    let summary = std::fs::read_to_string(out.join("replay-summary.txt")).unwrap();
    assert!(summary.starts_with("status incomplete: "), "{summary}");
    assert!(summary.contains("ends with link lost yes\n"), "{summary}");
    assert!(
        String::from_utf8_lossy(&st.stderr).contains("link lost"),
        "{st:?}"
    );
}

#[test]
fn a_bad_length_in_record_0_resynchronises_on_the_next_record_and_counts_the_skipped_bytes() {
    let payloads = case(400);
    let (bytes, frames, ends) = wire(&payloads);
    let sent = sent_per_stream(&frames);
    // frame-aligned records of 5 frames: record 0 is the leading 0x00 and frame 0
    let cuts: Vec<usize> = ends.iter().step_by(5).copied().collect();
    let recs = records_at(&bytes, &cuts);
    let Record::Data { bytes: b0, .. } = &recs[0] else {
        unreachable!()
    };
    let len0 = b0.len() as u32;
    let good = capture_bytes(&header(false), &recs);
    let hlen = 12 + u32::from_le_bytes(good[8..12].try_into().unwrap()) as usize;
    let dir = tempfile::tempdir().unwrap();
    // absurd, past the end of the file, too short, a link reset with length bits
    for bad in [0xFFFF_FFF0u32, 5_000_000, len0 - 7, LINK_RESET_FLAG | 3] {
        let mut cap = good.clone();
        cap[hlen + 8..hlen + 12].copy_from_slice(&bad.to_le_bytes());
        let p = put(dir.path(), &format!("bad{bad:x}.cap"), &cap);
        let o = replay(&ReplayOptions::new(&p)).unwrap();
        assert_eq!(o.resync.resyncs, 1, "length {bad:#x}");
        // too short: the reader takes len0 - 7 bytes, then finds the next header invalid
        let skipped = if bad == len0 - 7 { 7 } else { 12 + len0 as u64 };
        assert_eq!(o.resync.skipped_bytes, skipped, "length {bad:#x}");
        let why = o.incomplete.clone().expect("incomplete");
        assert!(why.contains("resynchronising"), "{why}");
        // frame 0 is lost at most; every later frame is delivered
        assert!(o.log.frames.len() + 1 >= frames.len(), "length {bad:#x}");
        assert_eq!(o.log.gnss.len() as u64, sent[GNSS], "length {bad:#x}");
        assert_eq!(o.stats.lost(), 0, "length {bad:#x}");
    }
    // the command line: exit 2, the summary counts it
    let p = dir.path().join("badfffffff0.cap");
    let out = dir.path().join("out");
    let st = run_cli(
        &[
            "replay",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        Duration::from_secs(10),
    );
    assert_eq!(st.status.code(), Some(2), "{st:?}");
    let summary = std::fs::read_to_string(out.join("replay-summary.txt")).unwrap();
    assert!(
        summary.contains(&format!(
            "corrupt stretches skipped 1 ({} bytes)\n",
            12 + len0
        )),
        "{summary}"
    );
    assert!(
        String::from_utf8_lossy(&st.stderr).contains("record 0, byte"),
        "{st:?}"
    );
}

/// The exit codes under `--help` (exit 0, as `--version`); a usage error exits 1, not 2 (which
/// means "finished but incomplete").
#[test]
fn exit_codes_are_listed_under_help_and_a_usage_error_exits_1() {
    let help = Command::new(BIN).arg("--help").output().unwrap();
    let text = String::from_utf8_lossy(&help.stdout);
    assert_eq!(help.status.code(), Some(0), "{text}");
    for want in ["Exit status:", "  1 ", "  2 ", "incomplete", "130/143"] {
        assert!(text.contains(want), "no {want:?} in {text}");
    }
    let v = Command::new(BIN).arg("--version").output().unwrap();
    assert_eq!(v.status.code(), Some(0));
    for args in [&["replay", "--no-such-option"][..], &["record"], &[]] {
        let out = Command::new(BIN).args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("error:") && err.contains("--help"),
            "{args:?}: {err}"
        );
    }
}
