//! `host-sim run` / `diagnose` used carelessly or with hostile folders, through the binary:
//! `--out` at the input folder, links placed under output names, two runs into one folder,
//! SIGTERM / SIGINT in the middle of a run. Each check compares content hashes: no input and
//! no previous complete output may change.
use std::collections::BTreeMap;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::sync::OnceLock;
use std::time::Duration;
use test_support::cli::{interrupt_at_stderr, interrupt_when_ready, Bin, SIGINT, SIGTERM};
use test_support::runcase::{case_config, simulate_case, TACTICAL_NOISE};
use test_support::scenario::four_minute_drive;

const OUTPUTS: [&str; 5] = [
    "nav.txt",
    "std.txt",
    "bias.txt",
    "innovations.txt",
    "metrics.json",
];

fn bin() -> Bin {
    Bin::new(env!("CARGO_BIN_EXE_host-sim"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A simulated 4-minute drive at 400 Hz (96,000 IMU epochs: long enough to be interrupted),
/// simulated once per test binary: `(folder, case folder)`.
fn case() -> &'static (PathBuf, PathBuf) {
    static CASE: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    CASE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap().keep();
        let sc = four_minute_drive("safety").imu_rate_hz(400.0).build();
        let case = simulate_case(bin(), &dir, "case", &sc, "tactical", 3);
        (dir, case)
    })
}

/// A fresh folder holding a copy of the case: `imu.txt`, `gnss.txt`, the truth as `nav.txt`
/// (an input named like an output) and `run.toml` naming them.
fn input_folder(name: &str) -> PathBuf {
    let (dir, case) = case();
    let d = dir.join(name);
    std::fs::create_dir_all(&d).unwrap();
    for (from, to) in [
        ("imu.txt", "imu.txt"),
        ("gnss.txt", "gnss.txt"),
        ("truth.nav", "nav.txt"),
    ] {
        std::fs::copy(case.join(from), d.join(to)).unwrap();
    }
    let cfg = case_config(name, &d, "gnss.txt", "text", "", TACTICAL_NOISE)
        .replace("truth.nav", "nav.txt");
    std::fs::write(d.join("run.toml"), cfg).unwrap();
    d
}

fn hash_bytes(b: &[u8]) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    b.hash(&mut h);
    h.finish()
}

/// Name -> content hash of every file in `d` (links: their target's path), recursively.
fn hashes(d: &Path) -> BTreeMap<String, u64> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(d).unwrap().flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        let t = e.file_type().unwrap();
        if t.is_symlink() {
            let target = std::fs::read_link(&p).unwrap();
            m.insert(name, hash_bytes(target.as_os_str().as_encoded_bytes()));
        } else if t.is_dir() {
            for (k, v) in hashes(&p) {
                m.insert(format!("{name}/{k}"), v);
            }
        } else {
            m.insert(name, hash_bytes(&std::fs::read(&p).unwrap()));
        }
    }
    m
}

fn run_args(cfg: &Path, out: &Path) -> Vec<String> {
    ["run", "--config", s(cfg), "--out", s(out), "--quiet"]
        .map(String::from)
        .to_vec()
}

/// The outputs of a complete run of `cfg` in a folder of its own (the reference).
fn reference(cfg: &Path, name: &str) -> BTreeMap<String, u64> {
    let out = case().0.join(name);
    bin().run_ok(run_args(cfg, &out));
    outputs_of(&out)
}

/// Hashes of the outputs under their final names in `out`, `metrics.json` without its
/// timing fields (the wall time differs between two runs of the same case).
fn outputs_of(out: &Path) -> BTreeMap<String, u64> {
    let mut m = BTreeMap::new();
    for n in OUTPUTS {
        let p = out.join(n);
        let Ok(b) = std::fs::read(&p) else { continue };
        let h = if n == "metrics.json" {
            let mut v: serde_json::Value = serde_json::from_slice(&b).unwrap();
            strip_times(&mut v);
            hash_bytes(v.to_string().as_bytes())
        } else {
            hash_bytes(&b)
        };
        m.insert(n.to_string(), h);
    }
    m
}

fn strip_times(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(o) => {
            o.retain(|k, _| !k.contains("wall") && !k.ends_with("_s_run") && k != "run_time_s");
            o.values_mut().for_each(strip_times);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(strip_times),
        _ => {}
    }
}

#[test]
fn out_holding_an_input_is_refused_before_anything_is_written() {
    let d = input_folder("in-place");
    let before = hashes(&d);
    let cfg = d.join("run.toml");
    let mut tried = 0;
    // the folder itself, by another spelling, through a link, and diagnose
    let link = case().0.join("in-place-link");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(&d, &link).unwrap();
    let other = d.join("..").join("in-place");
    for out in [d.clone(), other, link.clone()] {
        for cmd in ["run", "diagnose"] {
            let ran = bin().run([cmd, "--config", s(&cfg), "--out", s(&out), "--quiet"]);
            tried += 1;
            assert!(!ran.ok, "{cmd} --out {}: {ran:?}", out.display());
            assert!(
                ran.stderr.contains("holds the input")
                    && ran.stderr.contains("(nothing was written)"),
                "{}",
                ran.stderr
            );
            assert_eq!(
                hashes(&d),
                before,
                "{cmd} --out {} changed the inputs",
                out.display()
            );
        }
    }
    // the configuration elsewhere, the truth given on the command line from the folder
    let cfg2 = case().0.join("in-place-elsewhere.toml");
    std::fs::copy(&cfg, &cfg2).unwrap();
    let ran = bin().run([
        "run",
        "--config",
        s(&cfg2),
        "--truth",
        s(&d.join("nav.txt")),
        "--out",
        s(&d),
        "--quiet",
    ]);
    tried += 1;
    assert!(!ran.ok && ran.stderr.contains("nav.txt"), "{}", ran.stderr);
    assert_eq!(hashes(&d), before);
    // an input hard-linked into another folder under an output's name
    let out = case().0.join("in-place-hardlink");
    std::fs::create_dir_all(&out).unwrap();
    let _ = std::fs::remove_file(out.join("nav.txt"));
    std::fs::hard_link(d.join("imu.txt"), out.join("nav.txt")).unwrap();
    let ran = bin().run(run_args(&cfg2, &out));
    tried += 1;
    assert!(
        !ran.ok && ran.stderr.contains("another name"),
        "{}",
        ran.stderr
    );
    assert_eq!(hashes(&d), before);
    println!("{tried} refusals, inputs unchanged");
}

#[cfg(unix)]
#[test]
fn links_under_output_names_are_replaced_not_written_through() {
    let d = input_folder("links");
    let cfg = d.join("run.toml");
    let want = reference(&cfg, "links-ref");
    let victims = case().0.join("links-victims");
    std::fs::create_dir_all(&victims).unwrap();
    let out = case().0.join("links-out");
    std::fs::create_dir_all(&out).unwrap();
    let mut tried = 0;
    for n in OUTPUTS {
        for name in [n.to_string(), format!("{n}.partial")] {
            let v = victims.join(&name);
            std::fs::write(&v, format!("victim {name}\n")).unwrap();
            let _ = std::fs::remove_file(out.join(&name));
            std::os::unix::fs::symlink(&v, out.join(&name)).unwrap();
            tried += 1;
        }
    }
    // a link named like a stage folder and one at the lock file's name
    std::os::unix::fs::symlink(&victims, out.join(".nav-out-stage-x")).unwrap();
    let before = hashes(&victims);
    let inputs = hashes(&d);
    bin().run_ok(run_args(&cfg, &out));
    assert_eq!(hashes(&victims), before, "a victim changed");
    assert_eq!(hashes(&d), inputs, "an input changed");
    assert_eq!(
        outputs_of(&out),
        want,
        "the outputs are not the reference run's"
    );
    // a run that stops at a fault mid-run (a 2 s hole in the IMU data, longer than the 1 s
    // bridged): its *.partial files replace links too
    for n in OUTPUTS {
        let name = format!("{n}.partial");
        std::os::unix::fs::symlink(victims.join(&name), out.join(&name)).unwrap();
    }
    let bad = d.join("imu-gap.txt");
    let imu = std::fs::read_to_string(d.join("imu.txt")).unwrap();
    let half = imu.lines().count() / 2;
    let text: String = imu
        .lines()
        .enumerate()
        .filter(|(i, _)| !(half..half + 800).contains(i))
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    std::fs::write(&bad, text).unwrap();
    let cfg_bad = d.join("run-gap.toml");
    let t = std::fs::read_to_string(&cfg).unwrap().replace(
        &format!("path = \"{}\"", d.join("imu.txt").display()),
        &format!("path = \"{}\"", bad.display()),
    );
    assert!(t.contains("imu-gap.txt"));
    std::fs::write(&cfg_bad, t).unwrap();
    let ran = bin().run(run_args(&cfg_bad, &out));
    tried += 5;
    assert!(
        !ran.ok && ran.stderr.contains("stopped there"),
        "{}",
        ran.stderr
    );
    assert_eq!(hashes(&victims), before, "a victim changed");
    // the previous complete outputs are still there, the partial ones beside them
    assert_eq!(outputs_of(&out), want);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json.partial")).unwrap())
            .unwrap();
    assert_eq!(m["complete"], serde_json::Value::Bool(false));
    assert!(!std::fs::symlink_metadata(out.join("nav.txt.partial"))
        .unwrap()
        .file_type()
        .is_symlink());
    println!("{tried} links placed, none written through");
}

#[test]
fn two_runs_into_one_folder_refuse_or_finish_whole() {
    let d = input_folder("two");
    let cfg = d.join("run.toml");
    let want = reference(&cfg, "two-ref");
    let out = case().0.join("two-out");
    let (mut refused, mut both) = (0, 0);
    for trial in 0..3 {
        let spawn = || {
            bin()
                .command()
                .args(run_args(&cfg, &out))
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (a, b) = (spawn(), spawn());
        let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
        let errs: Vec<String> = [&a, &b]
            .iter()
            .filter(|o| !o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stderr).into_owned())
            .collect();
        assert!(errs.len() < 2, "trial {trial}: both failed: {errs:?}");
        for e in &errs {
            assert!(
                e.contains("another run (pid ") && e.contains("nothing was written"),
                "{e}"
            );
            refused += 1;
        }
        if errs.is_empty() {
            both += 1;
        }
        assert_eq!(
            outputs_of(&out),
            want,
            "trial {trial}: the outputs mix two runs"
        );
        let stray: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains("partial") || n.starts_with(".nav-out-stage"))
            .collect();
        assert!(stray.is_empty(), "{stray:?}");
    }
    println!("3 trials: {refused} refused with the owner's pid, {both} with both finishing");
}

/// Sends `sig` to a run into a folder holding a complete earlier run once its outputs are
/// being written; the run keeps what it did as `*.partial` and the earlier outputs stay.
fn interrupt_mid_run(sig: &str, signal: i32) {
    let d = input_folder(&format!("sig-{sig}"));
    let cfg = d.join("run.toml");
    let out = case().0.join(format!("sig-{sig}-out"));
    bin().run_ok(run_args(&cfg, &out));
    let before = hashes(&out);
    let inputs = hashes(&d);
    // signalled at the first written bytes in the stage folder
    let mut ready = || {
        std::fs::read_dir(&out).unwrap().flatten().any(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with(".nav-out-stage")
                && std::fs::metadata(e.path().join("nav.txt.partial")).is_ok_and(|m| m.len() > 0)
        })
    };
    let r = interrupt_when_ready(
        bin()
            .command()
            .args(run_args(&cfg, &out))
            .args(["--outage", "100:30"]),
        &mut ready,
        signal,
        Duration::from_secs(60),
        Duration::from_secs(30),
    )
    .unwrap_or_else(|e| panic!("the run wrote nothing: {e}"));
    r.assert_interrupted_by(signal);
    // the earlier complete outputs and the inputs unchanged
    let after = hashes(&out);
    // (the lock file holds the last owner's pid)
    for (k, v) in before
        .iter()
        .filter(|(k, _)| !k.starts_with(".nav-out.lock"))
    {
        assert_eq!(after.get(k), Some(v), "{k} changed");
    }
    assert_eq!(hashes(&d), inputs);
    // what was processed, marked incomplete with the signal
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json.partial")).unwrap())
            .unwrap();
    assert_eq!(m["complete"], serde_json::Value::Bool(false));
    assert!(
        m["fault"].as_str().unwrap().contains(&format!("SIG{sig}")),
        "{}",
        m["fault"]
    );
    let nav = std::fs::read_to_string(out.join("nav.txt.partial")).unwrap();
    let full = std::fs::read_to_string(out.join("nav.txt")).unwrap();
    let n = nav.lines().count();
    assert!(n > 0 && n < full.lines().count(), "{n} lines");
    // nothing else left behind (no stage folder)
    let names: Vec<String> = after.keys().cloned().collect();
    assert!(
        names.iter().all(|n| !n.starts_with(".nav-out-stage")),
        "{names:?}"
    );
    println!(
        "SIG{sig}: exit {:?}, {n} of {} nav lines kept as partial, {:.2} s after the signal",
        r.code(),
        full.lines().count(),
        r.wall_s
    );
}

#[test]
fn sigterm_mid_run_keeps_the_partial_run_and_the_previous_outputs() {
    interrupt_mid_run("TERM", SIGTERM);
}

#[test]
fn sigint_mid_run_keeps_the_partial_run_and_the_previous_outputs() {
    interrupt_mid_run("INT", SIGINT);
}

/// The arguments of `host-sim diagnose` of `cfg` into `out`.
fn diagnose_args<'a>(cfg: &'a Path, out: &'a Path) -> [&'a str; 5] {
    ["diagnose", "--config", s(cfg), "--out", s(out)]
}

/// SIGINT while a diagnosis makes its base run: nothing is decided yet, so nothing is kept,
/// and it says so; exit 130, its runs end at once, its temporary folder goes, and the folder
/// of an earlier complete run stays as it was.
#[test]
fn sigint_during_the_base_run_of_diagnose_keeps_nothing_and_leaves_no_temporary_files() {
    let d = input_folder("sig-diag");
    let cfg = d.join("run.toml");
    let out = case().0.join("sig-diag-out");
    bin().run_ok(run_args(&cfg, &out));
    let before = hashes(&out);
    let tmp = tempfile::tempdir().unwrap();
    // signalled once the base run is writing its navigation
    let mut ready = || {
        std::fs::read_dir(tmp.path()).unwrap().flatten().any(|e| {
            std::fs::read_dir(e.path()).is_ok_and(|rd| {
                rd.flatten()
                    .any(|f| f.file_name().to_string_lossy().starts_with("before"))
            })
        })
    };
    let r = interrupt_when_ready(
        bin()
            .command()
            .env("TMPDIR", tmp.path())
            .args(diagnose_args(&cfg, &out))
            .arg("--quiet"),
        &mut ready,
        SIGINT,
        Duration::from_secs(120),
        Duration::from_secs(30),
    )
    .unwrap_or_else(|e| panic!("the diagnosis never ran: {e}"));
    assert_eq!(r.code(), Some(130), "{r:?}");
    assert!(
        r.stderr.contains(
            "SIGINT: stopping; the diagnosis ends its runs and keeps the search rounds decided"
        ),
        "{}",
        r.stderr
    );
    assert!(
        r.stderr.contains(
            "error: SIGINT: stopped before the search decided its first round; nothing kept, \
             the output folder as it was"
        ),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("decided: "), "{}", r.stderr);
    let left: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().flatten().collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
    let after = hashes(&out);
    let changed: Vec<_> = after
        .iter()
        .filter(|(k, v)| !k.starts_with(".nav-out.lock") && before.get(*k) != Some(v))
        .collect();
    assert!(changed.is_empty(), "{changed:?}");
    println!(
        "SIGINT during the base run: exit {:?}, ended {:.2} s after the signal",
        r.code(),
        r.wall_s
    );
}

/// SIGINT once the first round of a diagnosis's search is decided (the progress line on
/// stderr), on a drive whose declared lever arm is wrong: the decided round is kept as
/// `report.md.partial` and `diagnosis.json.partial` (incomplete, saying after which round),
/// with the base run's solution as `nav_before.txt.partial`; the round in progress is not
/// listed; no file takes a finished diagnosis's name; exit 130; no temporary file left.
#[test]
fn sigint_after_a_decided_round_of_diagnose_keeps_that_round_as_a_partial_diagnosis() {
    let d = input_folder("sig-diag-round");
    let cfg = d.join("run.toml");
    let text = std::fs::read_to_string(&cfg)
        .unwrap()
        .replace("[gnss]\n", "[gnss]\nlever_arm_m = [0.8, -0.6, -1.0]\n");
    std::fs::write(&cfg, text).unwrap();
    let out = case().0.join("sig-diag-round-out");
    let tmp = tempfile::tempdir().unwrap();
    let r = interrupt_at_stderr(
        bin()
            .command()
            .env("TMPDIR", tmp.path())
            .args(diagnose_args(&cfg, &out)),
        &mut |err| err.contains("round 1 decided: "),
        SIGINT,
        Duration::from_secs(300),
        Duration::from_secs(30),
    )
    .unwrap_or_else(|e| panic!("the diagnosis decided no round: {e}"));
    assert_eq!(r.code(), Some(130), "{r:?}");
    assert!(
        r.stderr.contains(
            "error: SIGINT: stopped after round 1 of the search; the decided rounds are kept in"
        ),
        "{}",
        r.stderr
    );
    for name in [
        "report.md.partial",
        "diagnosis.json.partial",
        "nav_before.txt.partial",
    ] {
        assert!(r.stderr.contains(name), "{name} not named: {}", r.stderr);
    }
    // no file under a finished diagnosis's name
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !n.starts_with(".nav-out.lock"))
        .collect();
    let mut expected = vec![
        "diagnosis.json.partial".to_string(),
        "nav_before.txt.partial".to_string(),
        "report.md.partial".to_string(),
    ];
    let mut sorted = names.clone();
    sorted.sort();
    expected.sort();
    assert_eq!(sorted, expected);
    let left: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().flatten().collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
    // the JSON: incomplete, interrupted after round 1, that round only
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("diagnosis.json.partial")).unwrap())
            .unwrap();
    assert_eq!(j["complete"], serde_json::Value::Bool(false));
    assert_eq!(j["interrupted"], "SIGINT");
    assert_eq!(j["after_round"], 1);
    let rounds = j["rounds"].as_array().unwrap();
    assert_eq!(rounds.len(), 1, "{rounds:?}");
    // every candidate of the decided round run and decided (no cut run among them)
    let round = &rounds[0];
    let candidates = round["candidates"].as_array().unwrap();
    assert!(!candidates.is_empty());
    for c in candidates {
        assert_ne!(c["decision"], "failed", "{c}");
        assert!(!c["reason"].as_str().unwrap().contains("SIGINT"), "{c}");
    }
    let said = r
        .stderr
        .lines()
        .find(|l| l.starts_with("round 1 decided: "))
        .unwrap();
    let added = round["added"].as_str();
    assert_eq!(
        said,
        format!(
            "round 1 decided: {}",
            added.map_or("nothing added".into(), |a| format!("{a} added"))
        )
    );
    // the report: headed interrupted, round 1 listed, no second round
    let md = std::fs::read_to_string(out.join("report.md.partial")).unwrap();
    assert!(
        md.starts_with("# Diagnosis: INTERRUPTED, INCOMPLETE"),
        "{}",
        &md[..md.len().min(400)]
    );
    assert!(md.contains("Interrupted by SIGINT after round 1 of the search."));
    assert!(md.contains("Round 1 (model effects: []"), "{md}");
    assert!(!md.contains("Round 2"), "{md}");
    // the base run's solution whole: as many lines as a run of the configuration writes
    let nav = std::fs::read_to_string(out.join("nav_before.txt.partial")).unwrap();
    assert!(nav.lines().count() > 1000, "{} lines", nav.lines().count());
    println!(
        "SIGINT after round 1 (added {added:?}): exit {:?}, ended {:.2} s after the signal",
        r.code(),
        r.wall_s
    );
}
