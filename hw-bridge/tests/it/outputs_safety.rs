//! `hw-bridge replay --out` / `record --out` used carelessly or with hostile folders, through
//! the binary: `--out` at the folder of the replay's inputs, links placed under output names,
//! two replays into one folder. Each check compares content hashes: no input and no previous
//! output may change.
use hw_bridge::capture::{CaptureHeader, CaptureWriter, Record};
use hw_bridge::frames::case_payloads;
use nav_core::types::{FixQuality, GnssFix, ImuSample};
use nav_core::wire::{Encoder, MAX_FRAME_LEN};
use std::collections::BTreeMap;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
#[cfg(unix)]
use test_support::cli::{interrupt_when_ready, SIGINT, SIGTERM};
use test_support::runcase::{case_config, TACTICAL_NOISE};

const BIN: &str = env!("CARGO_BIN_EXE_hw-bridge");

/// A capture of `n` IMU samples at 200 Hz and a GNSS fix every 20, one record per 20 frames
/// at their recorded times (100 ms apart): `n / 200` s long at `--speed 1`.
fn capture(dir: &Path, n: usize) -> PathBuf {
    capture_with(dir, n, [0.5, 0.6, 1.1], 0.0)
}

/// `n` IMU samples at 200 Hz from t = 1000.005 s, the same increments in each.
fn still_imu(n: usize) -> Vec<ImuSample> {
    (1..=n)
        .map(|i| ImuSample {
            t_s: 1000.0 + i as f64 * 0.005,
            dtheta_rad: [1e-5, -2e-6, 3e-6],
            dv_mps: [0.01, -0.002, -0.049],
            temperature_c: 25.0,
        })
        .collect()
}

/// [`capture`] with the fixes' position sigmas `pos_std_ned_m` and their times moved by
/// `dt_s`.
fn capture_with(dir: &Path, n: usize, pos_std_ned_m: [f64; 3], dt_s: f64) -> PathBuf {
    let imu = still_imu(n);
    let gnss: Vec<GnssFix> = (1..=n / 20)
        .map(|k| GnssFix {
            t_s: 1000.0 + k as f64 * 0.1 + dt_s,
            lat_rad: 0.5,
            lon_rad: 1.9,
            h_m: 25.0,
            pos_std_ned_m,
            vel_ned_mps: [1.0, -0.5, 0.01],
            vel_std_ned_mps: [0.05, 0.05, 0.1],
            has_velocity: true,
            quality: FixQuality::Single,
            num_sats: 9,
        })
        .collect();
    let mut enc = Encoder::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let h = CaptureHeader {
        port: "/dev/pts/test".into(),
        baud: 921_600,
        start_unix_ns: 1,
        tool: "outputs safety test".into(),
        streams_from_start: true,
    };
    let mut w = CaptureWriter::new(Vec::new(), &h).unwrap();
    let mut chunk = vec![0u8];
    for (k, (_, p)) in case_payloads(&imu, &gnss).iter().enumerate() {
        let m = enc.encode(p, &mut buf).unwrap();
        chunk.extend_from_slice(&buf[..m]);
        if k % 20 == 19 {
            w.write(&Record::Data {
                t_ns: (k as u64 + 1) * 5_000_000,
                bytes: std::mem::take(&mut chunk),
            })
            .unwrap();
        }
    }
    let p = dir.join("c.cap");
    std::fs::write(&p, w.into_inner()).unwrap();
    p
}

fn hash_bytes(b: &[u8]) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    b.hash(&mut h);
    h.finish()
}

/// Name -> content hash of every entry of `d` (links: their target's path).
fn hashes(d: &Path) -> BTreeMap<String, u64> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(d).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let t = e.file_type().unwrap();
        let h = if t.is_symlink() {
            hash_bytes(
                std::fs::read_link(e.path())
                    .unwrap()
                    .as_os_str()
                    .as_encoded_bytes(),
            )
        } else if t.is_dir() {
            0
        } else {
            hash_bytes(&std::fs::read(e.path()).unwrap())
        };
        m.insert(name, h);
    }
    m
}

fn replay(args: &[&str], cap: &Path, out: &Path) -> Output {
    Command::new(BIN)
        .arg("replay")
        .args(args)
        .arg("--out")
        .arg(out)
        .arg(cap)
        .output()
        .unwrap()
}

/// The decoded files of a replay (final names, no summary: it holds no timing but is
/// compared anyway), hashed.
fn decoded(out: &Path) -> BTreeMap<String, u64> {
    hashes(out)
        .into_iter()
        .filter(|(n, _)| !n.starts_with('.'))
        .collect()
}

#[test]
fn replay_into_its_inputs_folder_is_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let cap = capture(dir.path(), 400);
    // a case folder: its data, and the run configuration naming them
    let case = dir.path().join("case");
    std::fs::create_dir(&case).unwrap();
    std::fs::write(case.join("imu.txt"), "1000.005 0 0 0 0 0 -0.049\n").unwrap();
    std::fs::write(case.join("gnss.txt"), "1000.1 28.6 108.8 25 0.5 0.6 1.1\n").unwrap();
    std::fs::write(
        case.join("run.toml"),
        case_config("c", &case, "gnss.txt", "text", "", TACTICAL_NOISE),
    )
    .unwrap();
    let cfg = case.join("run.toml");
    let before = hashes(&case);
    let cap_before = hashes(dir.path());
    let mut tried = 0;
    for out in [case.clone(), case.join("..").join("case")] {
        let o = replay(
            &["--as-fast-as-possible", "--config", cfg.to_str().unwrap()],
            &cap,
            &out,
        );
        tried += 1;
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(
            err.contains("holds the input") && err.contains("nothing was written"),
            "{err}"
        );
        assert_eq!(hashes(&case), before, "the case folder changed");
    }
    // the capture's own folder
    let o = replay(&["--as-fast-as-possible"], &cap, dir.path());
    tried += 1;
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("c.cap"), "{err}");
    assert_eq!(
        hashes(dir.path()),
        cap_before,
        "the capture's folder changed"
    );
    // record --out at the port itself
    let port = dir.path().join("port");
    std::fs::write(&port, "not a port").unwrap();
    let o = Command::new(BIN)
        .args(["record", "--duration", "0.1", "--port"])
        .arg(&port)
        .arg("--out")
        .arg(&port)
        .output()
        .unwrap();
    tried += 1;
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("holds the input"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&port).unwrap(), "not a port");
    println!("{tried} refusals, inputs unchanged");
}

#[cfg(unix)]
/// `replay --config` with static alignment (`[init.align]`) on a capture whose fixes are all
/// unusable (sigmas zero; all after the IMU frames): the filter cannot start; the replay's
/// decoded files are written, the summary and stderr say "not a navigation solution" naming
/// where the fixes went, no filter output is left, exit 2 (incomplete).
#[test]
fn replay_config_with_static_alignment_and_no_usable_fix_is_not_a_navigation_solution() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("case");
    std::fs::create_dir(&case).unwrap();
    std::fs::write(case.join("imu.txt"), "1000.005 0 0 0 0 0 -0.049\n").unwrap();
    std::fs::write(case.join("gnss.txt"), "1000.1 28.6 108.8 25 0.5 0.6 1.1\n").unwrap();
    std::fs::write(
        case.join("truth.nav"),
        "2300 1000 28.6 108.8 25 0 0 0 0 0 0\n2300 1030 28.6 108.8 25 0 0 0 0 0 0\n",
    )
    .unwrap();
    std::fs::write(
        case.join("run.toml"),
        case_config("c", &case, "gnss.txt", "text", "", TACTICAL_NOISE),
    )
    .unwrap();
    let cfg = case.join("run.toml");
    // (249 and 240 fixes: the capture's last frames, 1 or 10 fixes among them, fill no record)
    for (name, sigma, dt, says) in [
        ("sigma0", [0.0; 3], 0.0, "249 fix(es) invalid"),
        (
            "after",
            [0.5, 0.6, 1.1],
            100.0,
            "240 of 240 fix(es) are after the IMU data",
        ),
    ] {
        let d = dir.path().join(name);
        std::fs::create_dir(&d).unwrap();
        let cap = capture_with(&d, 5000, sigma, dt);
        let out = d.join("out");
        let o = replay(
            &["--as-fast-as-possible", "--config", cfg.to_str().unwrap()],
            &cap,
            &out,
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(
            err.contains("not a navigation solution (nothing run, no output written")
                && err.contains("[init.align]")
                && err.contains(says),
            "{name}: {err}"
        );
        let summary = std::fs::read_to_string(out.join("replay-summary.txt")).unwrap();
        assert!(
            summary.starts_with(
                "status incomplete: the filter run on the capture: not a navigation solution"
            ),
            "{name}: {summary}"
        );
        assert!(out.join("imu.txt").exists());
        for f in [
            "nav.txt",
            "nav.txt.partial",
            "metrics.json",
            "metrics.json.partial",
        ] {
            assert!(!out.join(f).exists(), "{name}: {f} left");
        }
    }
}

#[test]
fn links_under_output_names_are_replaced_not_written_through() {
    let dir = tempfile::tempdir().unwrap();
    let cap = capture(dir.path(), 400);
    let want_dir = dir.path().join("ref");
    let o = replay(&["--as-fast-as-possible"], &cap, &want_dir);
    assert!(o.status.success(), "{o:?}");
    let want = decoded(&want_dir);
    assert!(want.contains_key("imu.txt") && want.contains_key("replay-summary.txt"));
    let victims = dir.path().join("victims");
    std::fs::create_dir(&victims).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let mut tried = 0;
    for n in want.keys() {
        for name in [n.clone(), format!("{n}.partial")] {
            let v = victims.join(&name);
            std::fs::write(&v, format!("victim {name}\n")).unwrap();
            std::os::unix::fs::symlink(&v, out.join(&name)).unwrap();
            tried += 1;
        }
    }
    let before = hashes(&victims);
    let o = replay(&["--as-fast-as-possible"], &cap, &out);
    assert!(o.status.success(), "{o:?}");
    assert_eq!(hashes(&victims), before, "a victim changed");
    let got: BTreeMap<String, u64> = decoded(&out)
        .into_iter()
        .filter(|(n, _)| !n.ends_with(".partial"))
        .collect();
    assert_eq!(got, want, "the outputs are not the reference replay's");
    println!("{tried} links placed, none written through");
}

#[test]
fn two_replays_into_one_folder_one_refuses_with_the_owners_pid() {
    let dir = tempfile::tempdir().unwrap();
    // 1.5 s at --speed 1: the two replays overlap
    let cap = capture(dir.path(), 300);
    let want_dir = dir.path().join("ref");
    assert!(replay(&["--as-fast-as-possible"], &cap, &want_dir)
        .status
        .success());
    let want = decoded(&want_dir);
    let out = dir.path().join("out");
    let spawn = || {
        Command::new(BIN)
            .args(["replay", "--speed", "1", "--out"])
            .arg(&out)
            .arg(&cap)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let a = spawn();
    std::thread::sleep(std::time::Duration::from_millis(300));
    let b = spawn();
    let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
    assert!(a.status.success(), "{a:?}");
    let err = String::from_utf8_lossy(&b.stderr);
    assert_eq!(b.status.code(), Some(1), "{err}");
    assert!(err.contains("another run (pid "), "{err}");
    assert_eq!(decoded(&out), want, "the outputs mix two replays");
}

/// SIGTERM / SIGINT in the middle of a paced replay into a folder holding a complete earlier
/// replay: the replay stops at the next record, keeps what it decoded as `*.partial` with
/// `replay-summary.txt.partial` saying why it is incomplete, leaves the earlier outputs as
/// they were and exits 128 + the signal.
#[cfg(unix)]
fn interrupt_mid_replay(sig: &str, signal: i32) {
    let dir = tempfile::tempdir().unwrap();
    // 10 s at --speed 1
    let cap = capture(dir.path(), 2000);
    let out = dir.path().join("out");
    assert!(replay(&["--as-fast-as-possible"], &cap, &out)
        .status
        .success());
    let before = hashes(&out);
    let full = std::fs::read_to_string(out.join("imu.txt")).unwrap();
    // signalled at the first checkpoint of the decoded files (after 1 s)
    let mut ready = || std::fs::metadata(out.join("imu.txt.partial")).is_ok_and(|m| m.len() > 0);
    let r = interrupt_when_ready(
        Command::new(BIN)
            .args(["replay", "--speed", "1", "--out"])
            .arg(&out)
            .arg(&cap),
        &mut ready,
        signal,
        std::time::Duration::from_secs(30),
        std::time::Duration::from_secs(20),
    )
    .unwrap_or_else(|e| panic!("the replay wrote nothing: {e}"));
    let err = &r.stderr;
    // it stops at the next record
    assert!(r.wall_s < 7.0, "{r:?}");
    r.assert_interrupted_by(signal);
    assert!(err.contains(".partial"), "{err}");
    // the earlier complete outputs unchanged (the lock file holds the last owner's pid)
    let after = hashes(&out);
    for (k, v) in before.iter().filter(|(k, _)| *k != ".nav-out.lock") {
        assert_eq!(after.get(k), Some(v), "{k} changed");
    }
    // what was decoded, marked incomplete with the signal
    let summary = std::fs::read_to_string(out.join("replay-summary.txt.partial")).unwrap();
    assert!(
        summary.starts_with(&format!("status incomplete: interrupted by SIG{sig}")),
        "{summary}"
    );
    let part = std::fs::read_to_string(out.join("imu.txt.partial")).unwrap();
    let n = part.lines().count();
    assert!(n > 0 && n < full.lines().count(), "{n} lines");
    assert!(
        full.starts_with(&part),
        "imu.txt.partial is not a prefix of the whole"
    );
    assert!(out.join("gnss.txt.partial").exists());
    assert!(
        after.keys().all(|n| !n.starts_with(".nav-out-stage")),
        "{after:?}"
    );
    println!(
        "SIG{sig}: exit {:?}, {n} of {} IMU lines kept as partial, {:.2} s after the signal",
        r.code(),
        full.lines().count(),
        r.wall_s
    );
}

#[cfg(unix)]
#[test]
fn sigterm_mid_replay_keeps_the_partial_replay_and_the_previous_outputs() {
    interrupt_mid_replay("TERM", SIGTERM);
}

#[cfg(unix)]
#[test]
fn sigint_mid_replay_keeps_the_partial_replay_and_the_previous_outputs() {
    interrupt_mid_replay("INT", SIGINT);
}

/// `replay --config` with a misspelt key in the configuration: exit 1 naming the file, line and
/// column and the nearest key, the parser's message said once (not repeated after the hint),
/// and nothing written into `--out`.
#[test]
fn a_misspelt_configuration_key_is_named_once() {
    let tmp = tempfile::tempdir().unwrap();
    let cap = capture(tmp.path(), 400);
    let cfg = tmp.path().join("typo.toml");
    std::fs::write(
        &cfg,
        "name = \"typo\"\n[imu]\npath = \"imu.txt\"\nformat = \"text\"\n[gnss]\n\
         path = \"gnss.txt\"\nformat = \"text\"\nmaxq = 1\n[noise]\nmodel = \"nbk\"\n",
    )
    .unwrap();
    let out = tmp.path().join("out");
    let o = replay(&["--config", cfg.to_str().unwrap()], &cap, &out);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("typo.toml"), "names the file: {err}");
    assert!(
        err.contains("line 8, column 1"),
        "names line and column: {err}"
    );
    assert!(err.contains("did you mean `max_q`?"), "{err}");
    assert_eq!(
        err.matches("unknown field `maxq`").count(),
        1,
        "said once: {err}"
    );
    assert_eq!(
        err.matches("TOML parse error").count(),
        1,
        "said once: {err}"
    );
    assert!(!out.exists() || decoded(&out).is_empty(), "nothing written");
}

/// `send --copy-to` naming one of the case's own files (or a link to one) is refused before
/// the port is opened, the case unchanged: the copy would truncate the data it sends.
#[test]
fn send_copy_to_a_file_of_its_own_case_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("case");
    std::fs::create_dir(&case).unwrap();
    let imu = still_imu(400);
    nav_io::write_imu_text(case.join("imu.txt"), &imu).unwrap();
    std::fs::write(case.join("gnss.txt"), "1000.1 0.5 1.9 25 0.5 0.6 1.1\n").unwrap();
    std::os::unix::fs::symlink(case.join("imu.txt"), dir.path().join("copy.bin")).unwrap();
    let before = hashes(&case);
    let port = dir.path().join("no-such-port");
    for copy in [
        case.join("imu.txt"),
        case.join("gnss.txt"),
        dir.path().join("copy.bin"),
    ] {
        let out = Command::new(BIN)
            .args(["send", "--quiet", "--case"])
            .arg(&case)
            .arg("--port")
            .arg(&port)
            .arg("--copy-to")
            .arg(&copy)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{}: {err}", copy.display());
        assert!(
            err.contains("holds the input") && !err.contains("no-such-port"),
            "{}: {err}",
            copy.display()
        );
        assert_eq!(hashes(&case), before, "{}", copy.display());
    }
}
