//! `hw-bridge replay --config` against `host-sim run` on a case of host-sim's simulator (the
//! `tactical` error model: white noise, Gauss-Markov and turn-on biases, RTK GNSS with
//! Gauss-Markov errors, a GNSS outage): the frames of the case written into a capture, the
//! replay's filter outputs equal the files `host-sim run` writes from the case files, byte for
//! byte. (hw-bridge's own end-to-end test, `e2e_pty`, checks the serial link and the replay
//! against the run engine on a case of its own; this one needs host-sim's simulator and CLI,
//! which hw-bridge does not depend on.)
use clap::Parser;
use hw_bridge::capture::{CaptureHeader, CaptureWriter, Record};
use hw_bridge::cmd::{read_case, replay, ReplayOptions};
use nav_core::wire::{Encoder, MAX_FRAME_LEN};
use std::ffi::OsStr;
use std::path::Path;
use test_support::scenario::bridge_replay_drive;

fn drive() -> String {
    bridge_replay_drive("bridge-replay").build()
}

/// The case's frames, one encoder (as `hw-bridge send` writes them), in a capture of 4 kB
/// records.
fn write_capture(case: &Path, path: &Path) {
    let mut enc = Encoder::new();
    let mut bytes = vec![0u8];
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (_, p) in &read_case(case).unwrap() {
        let n = enc.encode(p, &mut buf).unwrap();
        bytes.extend_from_slice(&buf[..n]);
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
}

#[test]
fn replay_with_config_on_a_capture_of_a_simulated_case_equals_host_sim_run_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = d.join("drive.toml");
    std::fs::write(&sc, drive()).unwrap();
    let case = d.join("case");
    host_sim::sim::cli::run(host_sim::sim::cli::SimulateArgs {
        scenario: sc.display().to_string(),
        errors: "tactical".into(),
        seed: 11,
        out: case.clone(),
        outages: vec![nav_sim::errors::Outage {
            start_s: 50.0,
            duration_s: 20.0,
        }],
        gnss_rate_hz: None,
        kf_gins: true,
        plot: false,
        force: false,
    })
    .unwrap();
    let config = case.join("kf-gins.yaml");
    let cap = d.join("case.cap");
    write_capture(&case, &cap);

    // host-sim run on the case files (the CLI function: the files it writes) ...
    let out_sim = d.join("out-sim");
    let ra = host_sim::run::cli::RunArgs::try_parse_from([
        OsStr::new("run"),
        OsStr::new("--config"),
        config.as_os_str(),
        OsStr::new("--quiet"),
        OsStr::new("--out"),
        out_sim.as_os_str(),
    ])
    .unwrap();
    host_sim::run::cli::run(ra).unwrap();
    // ... and hw-bridge replay --config on the capture
    let out_rep = d.join("out-replay");
    let mut a = ReplayOptions::new(&cap);
    a.filter = Some(nav_engine::RunSpec::new(&config));
    a.out = Some(out_rep.clone());
    let o = replay(&a).unwrap();
    assert_eq!(o.stats.rejected(), 0);
    assert_eq!(o.stats.lost(), 0);
    let n_imu = nav_io::read_imu_text(case.join("imu.txt"))
        .unwrap()
        .samples
        .len();
    assert_eq!(o.log.imu.len(), n_imu);
    for f in [
        "nav.txt",
        "std.txt",
        "bias.txt",
        "innovations.txt",
        "metrics.json",
    ] {
        let a = std::fs::read(out_sim.join(f)).unwrap();
        let b = std::fs::read(out_rep.join(f)).unwrap();
        assert!(!a.is_empty(), "{f} is empty");
        assert!(a == b, "{f}: replay differs from host-sim run");
    }
    // the command line's replay keeps no frame (the filter is fed as the frames are decoded,
    // in both): the same outputs
    let out_cli = d.join("out-replay-cli");
    a.keep_frames = false;
    a.out = Some(out_cli.clone());
    let o = replay(&a).unwrap();
    assert!(o.log.frames.is_empty() && o.log.imu.is_empty() && o.log.gnss.is_empty());
    assert!(o.filter.is_some());
    for f in [
        "nav.txt",
        "std.txt",
        "bias.txt",
        "innovations.txt",
        "metrics.json",
        "imu.txt",
        "gnss.txt",
    ] {
        let a = std::fs::read(out_rep.join(f)).unwrap();
        let b = std::fs::read(out_cli.join(f)).unwrap();
        assert!(a == b, "{f}: the replay keeping no frame differs");
    }
    // the run used the outage and the fixes around it
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_rep.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["per_outage"].as_array().map(Vec::len), Some(1), "{m}");
}
