//! `send` and `record` over pseudo-terminal pairs (no socat needed: `serialport`'s
//! `TTYPort::pair`): timeouts when nothing reads, nothing arrives or the port vanishes, and a
//! soak of `send` -> faulty link -> `record` whose counters must balance exactly at the end:
//! per stream, frames sent = delivered + lost (`record --streams-from-start`).
//!
//! The link is a relay thread between two pty pairs: it reads what `send` writes into the
//! first pair and writes it into the second, where `record` reads it through a symlink,
//! injecting random faults: bit flips, dropped byte runs, garbage, stalls, and link resets (the
//! second pair is closed, so `record` sees its port vanish, and reopened under the same symlink
//! after an outage whose bytes are lost). The last seconds are clean, so the last frame of each
//! stream arrives, which the identity needs (docs/wire-protocol.md).
//!
//! `soak_short` (20 s) runs in the normal suite; `soak_10_minutes` is ignored and run by
//! `cargo xtask soak` (`HW_BRIDGE_SOAK_S` sets its length).
#![cfg(unix)]

use rand::{Rng, SeedableRng};
use serialport::{SerialPort, TTYPort};
use std::io::{BufRead, Read, Write};
use std::os::fd::{FromRawFd, IntoRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_hw-bridge");

/// A case of `seconds` of 200 Hz IMU and 1 Hz GNSS (with velocity); returns (IMU, GNSS) counts.
fn write_case(dir: &Path, seconds: usize) -> (u64, u64) {
    let n = seconds * 200;
    let mut imu = String::with_capacity(n * 120);
    for i in 1..=n {
        let x = i as f64;
        imu.push_str(&format!(
            "{} {:e} {:e} {:e} {:e} {:e} {:e} {}\n",
            388_800.0 + x * 0.005,
            1e-5 * (x * 0.37).sin(),
            -2e-6,
            3e-6 * (x * 0.11).cos(),
            0.01 + 1e-9 * x,
            -0.002 * (x * 0.5).sin(),
            -0.049,
            25.0 + (x * 1e-3).sin()
        ));
    }
    std::fs::write(dir.join("imu.txt"), imu).unwrap();
    let mut gnss = String::new();
    for k in 1..=seconds {
        let x = k as f64;
        gnss.push_str(&format!(
            "{} {} {} {} 0.5 0.6 1.1 {} -0.5 0.01 0.05 0.05 0.1\n",
            388_800.0 + x,
            30.5 + x * 1.2e-6,
            114.3 - x * 9.8e-7,
            25.0 + x / 700.0,
            1.0 + (x * 0.01).sin()
        ));
    }
    std::fs::write(dir.join("gnss.txt"), gnss).unwrap();
    (n as u64, seconds as u64)
}

/// A pty pair (master, slave, slave path) whose descriptors are not inherited by the
/// programs this test starts: a child holding a copy of the master would keep the link up
/// after the test closes it.
/// The slave side is only held open (so the master never sees a hang-up before the program
/// under test opens the slave by its path).
pub(crate) fn pair() -> (TTYPort, OwnedFd, PathBuf) {
    let (m, s) = TTYPort::pair().expect("pty pair");
    let name = PathBuf::from(s.name().expect("pty name"));
    let m = cloexec(m);
    // SAFETY: `dup` is an open pty descriptor owned by nobody else; ownership moves to the
    // port (which also takes an exclusive flock on the master: nothing else opens it).
    let m = unsafe { TTYPort::from_raw_fd(m.into_raw_fd()) };
    (m, cloexec(s), name)
}

/// The port's descriptor duplicated with close-on-exec (the original is closed).
fn cloexec(p: TTYPort) -> OwnedFd {
    // SAFETY: the descriptor comes from `into_raw_fd`, so it is open and owned by nobody else.
    let fd = unsafe { OwnedFd::from_raw_fd(p.into_raw_fd()) };
    // `try_clone` duplicates with F_DUPFD_CLOEXEC
    fd.try_clone().expect("dup pty descriptor")
}

/// Points `link` at `target` atomically.
fn relink(link: &Path, target: &Path) {
    let tmp = link.with_extension("new");
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(target, &tmp).unwrap();
    std::fs::rename(&tmp, link).unwrap();
}

/// Starts `hw-bridge record` with `args` and waits for its "recording" line; returns the child
/// and a thread collecting the rest of its stderr.
pub(crate) fn start_record(
    args: &[&str],
) -> (std::process::Child, std::thread::JoinHandle<String>) {
    let mut rec = Command::new(BIN)
        .arg("record")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn record");
    let mut err = std::io::BufReader::new(rec.stderr.take().unwrap());
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    assert!(line.starts_with("recording"), "record said {line:?}");
    let drain = std::thread::spawn(move || std::io::read_to_string(err).unwrap_or_default());
    (rec, drain)
}

#[test]
fn send_fails_within_its_write_timeout_when_nothing_reads_the_port() {
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path(), 100); // 1.6 MB of frames: far more than a pty buffers
    let (_master, slave, name) = pair();
    drop(slave);
    let t = Instant::now();
    let out = Command::new(BIN)
        .args([
            "send",
            "--quiet",
            "--as-fast-as-possible",
            "--write-timeout",
            "1",
        ])
        .arg("--case")
        .arg(dir.path())
        .arg("--port")
        .arg(&name)
        .output()
        .unwrap();
    let wall = t.elapsed();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--write-timeout 1 s"), "{err}");
    assert!(wall < Duration::from_secs(8), "send took {wall:?}");
    assert!(wall >= Duration::from_millis(900), "send took {wall:?}");
}

#[test]
fn record_fails_when_no_byte_arrives_within_first_byte_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let (_master, slave, name) = pair();
    drop(slave);
    let cap = dir.path().join("c.cap");
    let t = Instant::now();
    let out = Command::new(BIN)
        .args([
            "record",
            "--quiet",
            "--first-byte-timeout",
            "0.5",
            "--duration",
            "30",
        ])
        .arg("--port")
        .arg(&name)
        .arg("--out")
        .arg(&cap)
        .output()
        .unwrap();
    let wall = t.elapsed();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("within --first-byte-timeout 0.5 s"), "{err}");
    assert!(wall < Duration::from_secs(5), "record took {wall:?}");
    // the capture is a valid empty one
    let o = hw_bridge::cmd::decode_capture(&cap).unwrap();
    assert_eq!(o.records, 0);
}

#[test]
fn record_stops_incomplete_when_the_port_vanishes_beyond_reopen_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let (mut master, slave, name) = pair();
    let link = dir.path().join("port");
    relink(&link, &name);
    let cap = dir.path().join("c.cap");
    let link_s = link.display().to_string();
    let cap_s = cap.display().to_string();
    let (rec, drain) = start_record(&[
        "--quiet",
        "--reopen-timeout",
        "0.5",
        "--duration",
        "30",
        "--port",
        &link_s,
        "--out",
        &cap_s,
    ]);
    master.write_all(&[1, 2, 3, 0]).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let t = Instant::now();
    std::fs::remove_file(&link).unwrap();
    drop(master);
    drop(slave);
    let out = rec.wait_with_output().unwrap();
    let err = drain.join().unwrap();
    let wall = t.elapsed();
    assert_eq!(out.status.code(), Some(2), "{out:?} {err}");
    assert!(
        err.contains("not back within --reopen-timeout 0.5 s"),
        "{err}"
    );
    assert!(wall < Duration::from_secs(5), "record took {wall:?}");
    let so = String::from_utf8_lossy(&out.stdout);
    assert!(so.contains("1 link resets"), "{so}");
    let mut rd =
        hw_bridge::capture::CaptureReader::new(std::fs::File::open(&cap).unwrap()).unwrap();
    let recs: Vec<_> = rd.by_ref().map(|r| r.unwrap()).collect();
    let data: Vec<u8> = recs
        .iter()
        .flat_map(|r| match r {
            hw_bridge::capture::Record::Data { bytes, .. } => bytes.clone(),
            _ => vec![],
        })
        .collect();
    assert_eq!(data, vec![1, 2, 3, 0]);
    assert!(matches!(
        recs.last(),
        Some(hw_bridge::capture::Record::LinkReset { .. })
    ));
}

/// What the relay did.
#[derive(Debug, Default)]
struct RelayLog {
    bytes_in: u64,
    bytes_out: u64,
    flips: u64,
    drops: u64,
    bytes_dropped: u64,
    garbage: u64,
    stalls: u64,
    resets: u64,
    bytes_lost_in_outages: u64,
    write_timeouts: u64,
}

/// Relays `m1` -> a pty pair behind `link`, with faults until `clean_after`.
fn relay(
    mut m1: TTYPort,
    link: PathBuf,
    clean_after: Duration,
    seed: u64,
    stop: Arc<AtomicBool>,
) -> RelayLog {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut log = RelayLog::default();
    m1.set_timeout(Duration::from_millis(20)).unwrap();
    let (mut m2, mut s2, name) = pair();
    m2.set_timeout(Duration::from_millis(200)).unwrap();
    relink(&link, &name);
    let start = Instant::now();
    let mut next_reset = start + Duration::from_secs_f64(rng.random_range(4.0..20.0));
    let mut outage_until: Option<Instant> = None;
    let mut buf = vec![0u8; 4096];
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        let faulty = now.duration_since(start) < clean_after;
        if let Some(t) = outage_until {
            if now >= t {
                let (m, s, name) = pair();
                m2 = m;
                s2 = s;
                m2.set_timeout(Duration::from_millis(200)).unwrap();
                relink(&link, &name);
                outage_until = None;
            }
        } else if faulty && now >= next_reset {
            // the port vanishes: record sees a hang-up and reopens the symlink later
            log.resets += 1;
            let (m, s, _) = pair();
            drop(std::mem::replace(&mut m2, m));
            drop(std::mem::replace(&mut s2, s));
            let _ = std::fs::remove_file(&link);
            outage_until = Some(now + Duration::from_secs_f64(rng.random_range(0.1..1.0)));
            next_reset = now + Duration::from_secs_f64(rng.random_range(5.0..30.0));
        }
        let n = match m1.read(&mut buf) {
            Ok(0) => panic!("relay read: end of file"),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) => panic!("relay read: {e}"),
        };
        log.bytes_in += n as u64;
        let mut chunk = buf[..n].to_vec();
        if outage_until.is_some() {
            log.bytes_lost_in_outages += n as u64;
            continue;
        }
        if faulty {
            if rng.random_bool(0.02) {
                for _ in 0..rng.random_range(1..4) {
                    let i = rng.random_range(0..chunk.len());
                    chunk[i] ^= 1 << rng.random_range(0..8);
                }
                log.flips += 1;
            }
            if rng.random_bool(0.02) {
                let i = rng.random_range(0..chunk.len());
                let j = (i + rng.random_range(1..200)).min(chunk.len());
                log.bytes_dropped += (j - i) as u64;
                chunk.drain(i..j);
                log.drops += 1;
            }
            if rng.random_bool(0.01) {
                let i = rng.random_range(0..=chunk.len());
                let g: Vec<u8> = (0..rng.random_range(1..64)).map(|_| rng.random()).collect();
                chunk.splice(i..i, g);
                log.garbage += 1;
            }
            if rng.random_bool(0.005) {
                std::thread::sleep(Duration::from_millis(rng.random_range(50..300)));
                log.stalls += 1;
            }
        }
        match m2.write_all(&chunk) {
            Ok(()) => log.bytes_out += chunk.len() as u64,
            Err(_) => log.write_timeouts += 1,
        }
    }
    drop(s2);
    log
}

fn soak(seconds_wall: f64, seed: u64) {
    let rate_x = 5.0;
    let data_s = (seconds_wall * rate_x).ceil() as usize;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let case = d.join("case");
    std::fs::create_dir_all(&case).unwrap();
    let (imu_sent, gnss_sent) = write_case(&case, data_s);
    let (m1, s1, name1) = pair();
    let link = d.join("rx");
    let stop = Arc::new(AtomicBool::new(false));
    // faults until 4 s before the end of sending: the last frames arrive intact
    let clean_after = Duration::from_secs_f64((seconds_wall - 4.0).max(1.0));
    let relay_thread = {
        let (link, stop) = (link.clone(), stop.clone());
        std::thread::spawn(move || relay(m1, link, clean_after, seed, stop))
    };
    while !link.exists() {
        std::thread::sleep(Duration::from_millis(10));
    }
    let cap = d.join("soak.cap");
    let (link_s, cap_s) = (link.display().to_string(), cap.display().to_string());
    let bound = format!("{}", seconds_wall + 120.0);
    let t0 = Instant::now();
    let (rec, drain) = start_record(&[
        "--quiet",
        "--streams-from-start",
        "--idle-exit",
        "3",
        "--duration",
        &bound,
        "--port",
        &link_s,
        "--out",
        &cap_s,
    ]);
    let send = Command::new(BIN)
        .args(["send", "--quiet", "--linger-s", "0.5", "--rate-x"])
        .arg(rate_x.to_string())
        .arg("--case")
        .arg(&case)
        .arg("--port")
        .arg(&name1)
        .output()
        .unwrap();
    let send_wall = t0.elapsed().as_secs_f64();
    assert!(send.status.success(), "send failed: {send:?}");
    let rec_out = rec.wait_with_output().unwrap();
    let rec_err = drain.join().unwrap();
    stop.store(true, Ordering::Relaxed);
    let log = relay_thread.join().unwrap();
    drop(s1);
    let wall = t0.elapsed().as_secs_f64();
    assert!(
        rec_out.status.success(),
        "record failed: {rec_out:?} {rec_err}"
    );
    let rec_so = String::from_utf8_lossy(&rec_out.stdout);
    let o = hw_bridge::cmd::decode_capture(&cap).unwrap();
    let s = &o.stats;
    let resets_in_cap = hw_bridge::capture::CaptureReader::new(std::io::BufReader::new(
        std::fs::File::open(&cap).unwrap(),
    ))
    .unwrap()
    .filter(|r| matches!(r, Ok(hw_bridge::capture::Record::LinkReset { .. })))
    .count() as u64;
    println!(
        "soak {seconds_wall} s (seed {seed}): send {send_wall:.1} s, total {wall:.1} s; relay {log:?}"
    );
    println!("record: {}", rec_so.lines().next().unwrap_or(""));
    println!(
        "IMU sent {imu_sent} = delivered {} + lost {}; GNSS sent {gnss_sent} = delivered {} + lost {}; rejected chunks {} (crc {}, cobs {}, length {}, truncated {}, other {}); link resets in capture {}",
        s.frames_ok_by_stream[0],
        s.lost_by_stream[0],
        s.frames_ok_by_stream[1],
        s.lost_by_stream[1],
        s.rejected(),
        s.crc_errors,
        s.cobs_errors,
        s.length_errors,
        s.truncated,
        s.rejected() - s.crc_errors - s.cobs_errors - s.length_errors - s.truncated,
        resets_in_cap
    );
    assert!(o.incomplete.is_none(), "{:?}", o.incomplete);
    assert_eq!(
        u64::from(s.frames_ok_by_stream[0]) + u64::from(s.lost_by_stream[0]),
        imu_sent,
        "IMU: delivered + lost != sent"
    );
    assert_eq!(
        u64::from(s.frames_ok_by_stream[1]) + u64::from(s.lost_by_stream[1]),
        gnss_sent,
        "GNSS: delivered + lost != sent"
    );
    assert_eq!(s.backwards_by_stream, [0; 5]);
    assert!(s.restarts_by_stream[0] <= 1 && s.restarts_by_stream[1] <= 1);
    // every port loss the relay caused was seen and recorded once
    assert_eq!(resets_in_cap, log.resets);
    assert!(
        rec_so.contains(&format!("{} link resets", log.resets)),
        "{rec_so}"
    );
    // the faults did happen and cost frames
    assert!(log.flips + log.drops + log.garbage > 0, "{log:?}");
    assert!(s.lost() > 0 && s.rejected() > 0, "{s:?}");
    if seconds_wall >= 20.0 {
        assert!(log.resets >= 1, "{log:?}");
    }
    // the live counters of record agree with the replay of its capture
    assert!(
        rec_so.contains(&format!("frames delivered {}", s.frames_ok)),
        "{rec_so}"
    );
}

#[test]
fn soak_short() {
    soak(20.0, 1);
}

#[test]
#[ignore = "10 minutes; run by `cargo xtask soak`"]
fn soak_10_minutes() {
    let secs = std::env::var("HW_BRIDGE_SOAK_S")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(600.0);
    soak(secs, 10);
}
