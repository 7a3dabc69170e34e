//! `hw-bridge record --out` used carelessly or with hostile paths, through the binary over a
//! pseudo-terminal pair: an existing capture, a link at the output name or at its `.partial`
//! name, a leftover `.partial` of a killed recording, two recorders into one file, and Ctrl-C
//! (the normal end of a recording). Each check compares content hashes: nothing that was
//! there may change unless `--force` says so, and a recording ended by a signal is complete.
#![cfg(unix)]

use super::link::{pair, start_record};
use hw_bridge::capture::{CaptureReader, Record};
use std::collections::BTreeMap;
use std::hash::{Hash, Hasher};
use std::io::Write;
use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_hw-bridge");

fn hash_bytes(b: &[u8]) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    b.hash(&mut h);
    h.finish()
}

/// Name -> hash of every entry of `d` (links: their target's path, marked).
fn hashes(d: &Path) -> BTreeMap<String, (bool, u64)> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(d).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let link = e.file_type().unwrap().is_symlink();
        let h = if link {
            hash_bytes(
                std::fs::read_link(e.path())
                    .unwrap()
                    .as_os_str()
                    .as_encoded_bytes(),
            )
        } else {
            hash_bytes(&std::fs::read(e.path()).unwrap())
        };
        m.insert(name, (link, h));
    }
    m
}

/// `record` into `out` from `port` for 0.3 s (nothing sent), with `extra` arguments.
fn record(port: &Path, out: &Path, extra: &[&str]) -> Output {
    Command::new(BIN)
        .args(["record", "--quiet", "--duration", "0.3", "--port"])
        .arg(port)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

/// The data bytes of a capture file, concatenated, and its link resets.
fn capture_data(p: &Path) -> (Vec<u8>, u64) {
    let f = std::fs::File::open(p).unwrap();
    let mut rd = CaptureReader::new(std::io::BufReader::new(f)).unwrap();
    let (mut data, mut resets) = (Vec::new(), 0);
    while let Some(r) = rd.next_record().unwrap() {
        match r {
            Record::Data { bytes, .. } => data.extend_from_slice(&bytes),
            Record::LinkReset { .. } => resets += 1,
        }
    }
    (data, resets)
}

/// Sends `sig` to `child`.
fn kill(sig: &str, child: &std::process::Child) {
    let k = Command::new("kill")
        .args([&format!("-{sig}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(k.success());
}

/// Records `payload` sent through a pty pair into `out` (with `extra` arguments), ended by
/// `sig` once the bytes are in; returns the recorder's output.
fn record_ended_by(sig: &str, out: &Path, payload: &[u8], extra: &[&str]) -> Output {
    let (mut master, _slave, name) = pair();
    let (port, out_s) = (name.display().to_string(), out.display().to_string());
    let mut args = vec![
        "--quiet",
        "--duration",
        "60",
        "--port",
        &port,
        "--out",
        &out_s,
    ];
    args.extend_from_slice(extra);
    let (rec, drain) = start_record(&args);
    master.write_all(payload).unwrap();
    master.flush().unwrap();
    std::thread::sleep(Duration::from_millis(400));
    kill(sig, &rec);
    let mut o = rec.wait_with_output().unwrap();
    o.stderr = drain.join().unwrap().into_bytes();
    o
}

#[test]
fn ctrl_c_and_sigterm_end_a_recording_with_every_byte_in_a_complete_capture() {
    let dir = tempfile::tempdir().unwrap();
    let payload: Vec<u8> = (0..3000u32).map(|i| (i * 7 % 251) as u8).collect();
    for (sig, name) in [("INT", "int.cap"), ("TERM", "term.cap")] {
        let cap = dir.path().join(name);
        let o = record_ended_by(sig, &cap, &payload, &[]);
        let (out, err) = (
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr),
        );
        assert_eq!(o.status.code(), Some(0), "SIG{sig}: {out}\n{err}");
        assert!(out.contains(&format!("stopped by SIG{sig}")), "{out}");
        // the signal's message says the recording ends complete, nothing kept as .partial
        assert!(
            err.contains(&format!(
                "SIG{sig}: stopping; the recording ends here, its capture complete (exit 0)"
            )),
            "{err}"
        );
        assert!(!err.contains("kept as"), "{err}");
        // as `hw-bridge --help` lists it under the exit status
        let help = Command::new(BIN).arg("--help").output().unwrap();
        let help = String::from_utf8_lossy(&help.stdout);
        assert!(
            help.contains("(record: SIGINT/SIGTERM end the recording normally, exit 0"),
            "{help}"
        );
        // complete: under its final name, nothing left as .partial, every byte in
        assert!(!dir.path().join(format!("{name}.partial")).exists());
        let (data, resets) = capture_data(&cap);
        assert_eq!(data, payload, "SIG{sig}: the capture lost bytes");
        assert_eq!(resets, 0);
        let r = hw_bridge::cmd::decode_capture(&cap).unwrap();
        assert!(r.incomplete.is_none(), "{:?}", r.incomplete);
    }
}

#[test]
fn an_existing_capture_is_kept_unless_force() {
    let dir = tempfile::tempdir().unwrap();
    let (_master, _slave, name) = pair();
    let cap = dir.path().join("c.cap");
    std::fs::write(&cap, b"an earlier capture").unwrap();
    let before = hashes(dir.path());
    let o = record(&name, &cap, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("c.cap exists") && err.contains("--force") && err.contains("nothing"),
        "{err}"
    );
    assert_eq!(
        hashes(dir.path()),
        before,
        "a refused record changed the folder"
    );
    // --force: replaced by the new (empty) capture, nothing else left
    let payload = b"new bytes".to_vec();
    let o = record_ended_by("INT", &cap, &payload, &["--force"]);
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    assert_eq!(capture_data(&cap).0, payload);
    assert_eq!(hashes(dir.path()).len(), 1);
}

#[test]
fn links_at_the_capture_or_its_partial_name_are_never_written_through() {
    let dir = tempfile::tempdir().unwrap();
    let (_master, _slave, name) = pair();
    let victim = dir.path().join("victim");
    std::fs::write(&victim, b"keep me").unwrap();
    let keep = hash_bytes(b"keep me");
    let mut tried = 0;
    for at in ["c.cap", "c.cap.partial"] {
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        std::os::unix::fs::symlink(&victim, out.join(at)).unwrap();
        let cap = out.join("c.cap");
        let before = hashes(&out);
        // refused without --force, the link and its target untouched
        let o = record(&name, &cap, &[]);
        tried += 1;
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{at}: {err}");
        assert!(
            err.contains("a link to") && err.contains("--force"),
            "{err}"
        );
        assert_eq!(hashes(&out), before, "{at}: the folder changed");
        assert_eq!(hash_bytes(&std::fs::read(&victim).unwrap()), keep);
        // --force: the link replaced by the capture, the target untouched
        let o = record_ended_by("INT", &cap, b"xyz", &["--force"]);
        tried += 1;
        assert_eq!(o.status.code(), Some(0), "{at}: {o:?}");
        assert_eq!(hash_bytes(&std::fs::read(&victim).unwrap()), keep);
        let m = std::fs::symlink_metadata(&cap).unwrap();
        assert!(m.is_file(), "{at}: c.cap is not a file of its own");
        assert_eq!(capture_data(&cap).0, b"xyz");
        assert!(!out.join("c.cap.partial").exists());
        std::fs::remove_dir_all(&out).unwrap();
    }
    println!("{tried} records with links placed, none written through");
}

#[test]
fn a_killed_recordings_partial_file_is_kept_and_a_second_recorder_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let (mut master, _slave, name) = pair();
    let cap = dir.path().join("c.cap");
    let (port, cap_s) = (name.display().to_string(), cap.display().to_string());
    let (rec, drain) = start_record(&[
        "--quiet",
        "--duration",
        "60",
        "--port",
        &port,
        "--out",
        &cap_s,
    ]);
    master.write_all(b"first recorder").unwrap();
    // a second recorder of the same file (from another port, so the port lock is not what
    // stops it) refuses, the first one's data untouched
    let (_m2, _s2, name2) = pair();
    let o = record(&name2, &cap, &["--force"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("another process is writing"), "{err}");
    std::thread::sleep(Duration::from_millis(400));
    // killed outright: what it received stays in c.cap.partial
    kill("KILL", &rec);
    let _ = rec.wait_with_output().unwrap();
    drop(drain);
    let partial = dir.path().join("c.cap.partial");
    assert!(!cap.exists());
    assert_eq!(capture_data(&partial).0, b"first recorder");
    let before = hashes(dir.path());
    // the next recorder refuses to remove those data without --force
    let o = record(&name2, &cap, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("interrupted writer"), "{err}");
    assert_eq!(hashes(dir.path()), before);
}
