//! The capture families of [`super`]: `hw-bridge replay` of damaged captures and into
//! hostile folders, and `hw-bridge record --out` at an existing capture, a link or the port.

use super::families::interrupted;
use super::{bounded, hashes, Bins, Expect, Tally};
use anyhow::{Context, Result};
use hw_bridge::capture::{CaptureHeader, CaptureWriter, Record};
use nav_core::wire::{Encoder, MAX_FRAME_LEN};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The first `seconds` of the case's IMU and GNSS as a capture of 20-frame records at their
/// recorded times; returns (path, records' data bytes in order).
fn write_capture(case: &Path, dir: &Path, seconds: f64) -> Result<(PathBuf, Vec<Vec<u8>>)> {
    let imu = nav_io::read_imu_text(case.join("imu.txt"))?.samples;
    let gnss = nav_io::read_gnss_text(case.join("gnss.txt"))?;
    let t0 = imu.first().map_or(0.0, |s| s.t_s);
    let imu: Vec<_> = imu.into_iter().filter(|s| s.t_s < t0 + seconds).collect();
    let gnss: Vec<_> = gnss.into_iter().filter(|g| g.t_s < t0 + seconds).collect();
    let mut enc = Encoder::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut chunks = Vec::new();
    let mut chunk = Vec::new();
    for (k, (_, p)) in hw_bridge::frames::case_payloads(&imu, &gnss)
        .iter()
        .enumerate()
    {
        let m = enc.encode(p, &mut buf).context("encoding a frame")?;
        chunk.extend_from_slice(buf.get(..m).unwrap_or_default());
        if k % 20 == 19 {
            chunks.push(std::mem::take(&mut chunk));
        }
    }
    let p = dir.join("drive.cap");
    std::fs::write(&p, capture_bytes(&chunks)?)?;
    Ok((p, chunks))
}

/// A capture file of `chunks`, one record each, 100 ms apart.
fn capture_bytes(chunks: &[Vec<u8>]) -> Result<Vec<u8>> {
    let h = CaptureHeader {
        port: "/dev/hostile".into(),
        baud: 921_600,
        start_unix_ns: 1,
        tool: "cargo xtask hostile".into(),
        streams_from_start: true,
    };
    let mut w = CaptureWriter::new(Vec::new(), &h)?;
    for (k, c) in chunks.iter().enumerate() {
        w.write(&Record::Data {
            t_ns: (k as u64 + 1) * 100_000_000,
            bytes: c.clone(),
        })?;
    }
    Ok(w.into_inner())
}

fn replay_cmd(b: &Bins, cap: &Path, out: &Path, args: &[&str]) -> Command {
    let mut c = Command::new(&b.hw_bridge);
    c.arg("replay").args(args).arg("--out").arg(out).arg(cap);
    c
}

/// Damaged captures and hostile output folders of `replay`.
pub(super) fn captures(b: &Bins, root: &Path, case: &Path, t: &mut Tally) -> Result<()> {
    const F: &str = "captures (replay)";
    let dir = root.join("captures");
    std::fs::create_dir_all(&dir)?;
    let (cap, chunks) = write_capture(case, &dir, 120.0)?;
    let fast = ["--as-fast-as-possible"];
    let refd = root.join("replay-ref");
    let r = bounded(&mut replay_cmd(b, &cap, &refd, &fast));
    t.judge(F, "undamaged", &r, &Expect::new(&[0], &[]));
    let want = std::fs::read(refd.join("imu.txt")).unwrap_or_default();
    // the same bytes in other chunks (1 to 997 bytes): the same frames
    let all: Vec<u8> = chunks.concat();
    let mut rechunked = Vec::new();
    let mut at = 0;
    let mut k = 0usize;
    while at < all.len() {
        let n = (1 + (k * 7919) % 997).min(all.len() - at);
        rechunked.push(all.get(at..at + n).unwrap_or_default().to_vec());
        at += n;
        k += 1;
    }
    let p = dir.join("chunked.cap");
    std::fs::write(&p, capture_bytes(&rechunked)?)?;
    let out = root.join("replay-chunked");
    let r = bounded(&mut replay_cmd(b, &p, &out, &fast));
    t.judge(F, "re-chunked", &r, &Expect::new(&[0], &[]));
    if std::fs::read(out.join("imu.txt")).unwrap_or_default() != want {
        t.differs(
            F,
            "re-chunked",
            "imu.txt differs from the undamaged capture's",
        );
    }
    // corrupt: 16 bytes overwritten at 40 %; truncated at 70 % (+3 bytes)
    let bytes = std::fs::read(&cap)?;
    let mut bad = bytes.clone();
    let k = bad.len() * 2 / 5;
    for x in bad.iter_mut().skip(k).take(16) {
        *x = 0xff;
    }
    let p = dir.join("corrupt.cap");
    std::fs::write(&p, &bad)?;
    let r = bounded(&mut replay_cmd(b, &p, &root.join("replay-corrupt"), &fast));
    // corrupt record framing: resynchronised, incomplete; corrupt frame bytes inside a
    // record: rejected by the frame decoder (the capture itself complete), a warning
    let e = if r.code() == Some(2) {
        Expect::new(&[2], &["incomplete"])
    } else {
        Expect::new(&[0], &["rejected by the frame decoder"])
    };
    t.judge(F, "corrupt stretch", &r, &e.at(&["corrupt.cap", "byte"]));
    let p = dir.join("truncated.cap");
    std::fs::write(
        &p,
        bytes.get(..bytes.len() * 7 / 10 + 3).unwrap_or_default(),
    )?;
    let r = bounded(&mut replay_cmd(b, &p, &root.join("replay-trunc"), &fast));
    t.judge(
        F,
        "truncated",
        &r,
        &Expect::new(&[2], &["incomplete"]).at(&["truncated.cap", "byte"]),
    );
    hostile_folders(b, root, &cap, &want, t)
}

/// `replay --out` at the capture's folder, links at output names, two replays at once,
/// SIGTERM mid-replay.
fn hostile_folders(b: &Bins, root: &Path, cap: &Path, want: &[u8], t: &mut Tally) -> Result<()> {
    const F: &str = "outputs (replay)";
    let fast = ["--as-fast-as-possible"];
    let dir = cap.parent().context("a folder")?;
    let before = hashes(dir);
    let r = bounded(&mut replay_cmd(b, cap, dir, &fast));
    t.judge(
        F,
        "--out at the capture's folder",
        &r,
        &Expect::new(&[1], &["holds the input"]),
    );
    t.protect(F, "--out at the capture's folder", &before, &hashes(dir));
    let victims = root.join("replay-victims");
    let out = root.join("replay-links");
    std::fs::create_dir_all(&victims)?;
    std::fs::create_dir_all(&out)?;
    for n in [
        "imu.txt",
        "imu.txt.partial",
        "gnss.txt",
        "replay-summary.txt",
        "replay-summary.txt.partial",
    ] {
        std::fs::write(victims.join(n), format!("victim {n}\n"))?;
        std::os::unix::fs::symlink(victims.join(n), out.join(n))?;
    }
    let before = hashes(&victims);
    let r = bounded(&mut replay_cmd(b, cap, &out, &fast));
    t.judge(F, "links at output names", &r, &Expect::new(&[0], &[]));
    t.protect(F, "links at output names", &before, &hashes(&victims));
    // two at once (12 s at --speed 10)
    let out = root.join("replay-two");
    let (r1, r2) = std::thread::scope(|s| {
        let a = s.spawn(|| bounded(&mut replay_cmd(b, cap, &out, &["--speed", "10"])));
        std::thread::sleep(std::time::Duration::from_millis(300));
        let c = s.spawn(|| bounded(&mut replay_cmd(b, cap, &out, &["--speed", "10"])));
        (a.join(), c.join())
    });
    for r in [r1, r2].into_iter().flatten() {
        let e = if r.code() == Some(0) {
            Expect::new(&[0], &[])
        } else {
            Expect::new(&[1], &["another run (pid "])
        };
        t.judge(F, "two replays at once", &r, &e);
    }
    if std::fs::read(out.join("imu.txt")).unwrap_or_default() != want {
        t.differs(
            F,
            "two replays at once",
            "imu.txt is not the reference replay's",
        );
    }
    // SIGTERM mid-replay into the folder of a complete replay
    let before = hashes(&out);
    let ready = || std::fs::metadata(out.join("imu.txt.partial")).is_ok_and(|m| m.len() > 0);
    if let Some(r) = interrupted(
        &mut replay_cmd(b, cap, &out, &["--speed", "10"]),
        &ready,
        libc::SIGTERM,
    ) {
        t.judge(
            F,
            "SIGTERM mid-replay",
            &r,
            &Expect::new(&[143], &["interrupted by SIGTERM"]),
        );
        let after = hashes(&out);
        t.protect(F, "SIGTERM mid-replay", &before, &after);
        let s = std::fs::read_to_string(out.join("replay-summary.txt.partial")).unwrap_or_default();
        if !s.starts_with("status incomplete: interrupted by SIGTERM") {
            t.differs(
                F,
                "SIGTERM mid-replay",
                "replay-summary.txt.partial does not say interrupted",
            );
        }
    }
    Ok(())
}

/// `record --out` at an existing capture, a link at it or at its `.partial` name, the port.
pub(super) fn record(b: &Bins, root: &Path, t: &mut Tally) -> Result<()> {
    const F: &str = "record --out";
    let dir = root.join("record");
    std::fs::create_dir_all(&dir)?;
    let rec = |out: &Path, port: &Path| {
        let mut c = Command::new(&b.hw_bridge);
        c.args(["record", "--quiet", "--duration", "0.2", "--port"])
            .arg(port)
            .arg("--out")
            .arg(out);
        bounded(&mut c)
    };
    let none = Path::new("/nonexistent-port");
    let cap = dir.join("old.cap");
    std::fs::write(&cap, b"an earlier capture")?;
    let before = hashes(&dir);
    let r = rec(&cap, none);
    t.judge(
        F,
        "an existing capture",
        &r,
        &Expect::new(&[1], &["exists", "--force"]),
    );
    t.protect(F, "an existing capture", &before, &hashes(&dir));
    let victim = dir.join("victim");
    std::fs::write(&victim, b"keep")?;
    for at in ["link.cap", "link2.cap.partial"] {
        std::os::unix::fs::symlink(&victim, dir.join(at))?;
        let before = hashes(&dir);
        let r = rec(&dir.join(at.trim_end_matches(".partial")), none);
        t.judge(
            F,
            &format!("a link at {at}"),
            &r,
            &Expect::new(&[1], &["a link to"]),
        );
        t.protect(F, &format!("a link at {at}"), &before, &hashes(&dir));
    }
    let port = dir.join("port");
    std::fs::write(&port, b"not a port")?;
    let before = hashes(&dir);
    let r = rec(&port, &port);
    t.judge(
        F,
        "--out at the port",
        &r,
        &Expect::new(&[1], &["holds the input"]),
    );
    t.protect(F, "--out at the port", &before, &hashes(&dir));
    Ok(())
}
