//! End to end over a real pseudo-terminal pair (socat): `hw-bridge send` into one end,
//! `hw-bridge record` on the other, then the capture decodes to exactly the frames sent
//! (bit-exact payloads), `replay` writes text files that read back bit-exactly, and
//! `replay --config` on a simulated drive gives the solution of the run engine (`nav-engine`,
//! what `host-sim run` runs) on the case files, bit for bit.

use hw_bridge::cmd::{decode_capture, read_case};
use nav_core::wire::{encode_raw, Frame, MAX_RAW_LEN};
use nav_engine::RunSpec;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use test_support::scenario::bridge_replay_drive;

use crate::simcase;

const BIN: &str = env!("CARGO_BIN_EXE_hw-bridge");

fn have_socat() -> bool {
    Command::new("socat")
        .arg("-V")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

/// Returns false (and prints SKIPPED) when socat is missing outside CI; panics in CI.
fn require_socat(test: &str) -> bool {
    if have_socat() {
        return true;
    }
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("{test}: socat is required in CI (cargo xtask setup installs it)");
    }
    println!("SKIPPED {test}: socat not found");
    false
}

struct Socat(Child);

impl Drop for Socat {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn pty_pair(dir: &Path) -> Socat {
    let a = dir.join("A");
    let b = dir.join("B");
    let child = Command::new("socat")
        .arg("-d")
        .arg("-d")
        .arg(format!("pty,raw,echo=0,link={}", a.display()))
        .arg(format!("pty,raw,echo=0,link={}", b.display()))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn socat");
    let s = Socat(child);
    let t = Instant::now();
    while !(a.exists() && b.exists()) {
        assert!(t.elapsed() < Duration::from_secs(10), "socat made no ptys");
        std::thread::sleep(Duration::from_millis(20));
    }
    s
}

/// A simulated case with values that need all 17 digits, NaN-free, 200 Hz IMU for 6 s and
/// 1 Hz GNSS with velocity columns.
fn write_case(dir: &Path) {
    let mut imu = String::new();
    for i in 1..=1200u32 {
        let x = f64::from(i);
        imu.push_str(&format!(
            "{} {} {} {} {} {} {} {}\n",
            388_800.0 + x * 0.005,
            1e-5 * (x * 0.37).sin(),
            -2e-6 + 1e-9 * x.sqrt(),
            3e-6 * (x * 0.11).cos(),
            0.01 + 1e-7 * x,
            -0.002 * (x * 0.5).sin(),
            -0.049 + 1e-6 / x,
            25.0 + x / 3.0
        ));
    }
    std::fs::write(dir.join("imu.txt"), imu).unwrap();
    let mut gnss = String::new();
    for k in 1..=6u32 {
        let x = f64::from(k);
        gnss.push_str(&format!(
            "{} {} {} {} 0.5 0.6 1.1 {} {} 0.01 0.05 0.05 0.1\n",
            388_800.0 + x,
            30.5 + x * 1.234_567_891e-6,
            114.3 - x * 9.87e-7,
            25.0 + x / 7.0,
            1.0 + x / 3.0,
            -0.5
        ));
    }
    std::fs::write(dir.join("gnss.txt"), gnss).unwrap();
}

fn raw(f: &Frame) -> Vec<u8> {
    let mut b = [0u8; MAX_RAW_LEN];
    let n = encode_raw(f, &mut b).unwrap();
    b[..n].to_vec()
}

#[test]
fn send_record_over_a_pty_pair_then_capture_decodes_to_exactly_the_frames_sent() {
    if !require_socat("send_record_over_a_pty_pair_then_capture_decodes_to_exactly_the_frames_sent")
    {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_case(d);
    let _socat = pty_pair(d);
    let cap = d.join("cap.bin");
    let rec = Command::new(BIN)
        .args([
            "record",
            "--quiet",
            "--idle-exit",
            "2",
            "--duration",
            "30",
            "--port",
        ])
        .arg(d.join("B"))
        .arg("--out")
        .arg(&cap)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn record");
    // Wait until the recorder has the port open, then keep draining its stderr.
    let mut rec = rec;
    let mut err = std::io::BufReader::new(rec.stderr.take().unwrap());
    let mut line = String::new();
    use std::io::BufRead;
    err.read_line(&mut line).unwrap();
    assert!(line.starts_with("recording"), "record said {line:?}");
    let drain = std::thread::spawn(move || std::io::read_to_string(err).unwrap_or_default());
    let t = Instant::now();
    let send = Command::new(BIN)
        .args(["send", "--quiet", "--rate-x", "4", "--case"])
        .arg(d)
        .arg("--port")
        .arg(d.join("A"))
        .output()
        .expect("run send");
    let send_wall = t.elapsed().as_secs_f64();
    assert!(send.status.success(), "send failed: {send:?}");
    // 6 s of data at 4x: at least 1.5 s; pacing must not be ignored.
    assert!(send_wall >= 1.45, "send took {send_wall} s");
    let rec_out = rec.wait_with_output().unwrap();
    let rec_err = drain.join().unwrap();
    assert!(
        rec_out.status.success(),
        "record failed: {rec_out:?} {rec_err}"
    );

    // What was sent: the same reader and merge as `send` uses, numbered like its encoder.
    let expected = read_case(d).unwrap();
    let got = decode_capture(&cap).unwrap();
    assert_eq!(got.stats.rejected(), 0);
    assert_eq!(got.stats.lost(), 0);
    assert_eq!(got.log.frames.len(), expected.len());
    for (i, (f, (_, p))) in got.log.frames.iter().zip(&expected).enumerate() {
        let mut want = *f;
        want.payload = *p;
        assert_eq!(raw(f), raw(&want), "frame {i} payload differs");
    }
    // IMU sequence numbers 0..n without gaps.
    let imu_seq: Vec<u16> = got
        .log
        .frames
        .iter()
        .filter(|f| f.payload.msg_type() == nav_core::wire::MsgType::Imu)
        .map(|f| f.seq)
        .collect();
    assert_eq!(imu_seq, (0..1200u16).collect::<Vec<_>>());

    // replay --out writes text files that read back to the very same values.
    let out = d.join("out");
    let st = Command::new(BIN)
        .args(["replay", "--as-fast-as-possible"])
        .arg(&cap)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(st.status.success(), "{st:?}");
    let imu_back = nav_io::read_imu_text(out.join("imu.txt")).unwrap().samples;
    let imu_sent = nav_io::read_imu_text(d.join("imu.txt")).unwrap().samples;
    assert_eq!(imu_back.len(), imu_sent.len());
    for (a, b) in imu_back.iter().zip(&imu_sent) {
        assert_eq!(a.t_s.to_bits(), b.t_s.to_bits());
        assert_eq!(
            a.dtheta_rad.map(f64::to_bits),
            b.dtheta_rad.map(f64::to_bits)
        );
        assert_eq!(a.dv_mps.map(f64::to_bits), b.dv_mps.map(f64::to_bits));
        assert_eq!(a.temperature_c.to_bits(), b.temperature_c.to_bits());
    }
    let gnss_back = nav_io::read_gnss_text(out.join("gnss.txt")).unwrap();
    assert_eq!(gnss_back.len(), 6);
    assert!(gnss_back.iter().all(|g| g.has_velocity));
}

#[test]
fn replay_with_speed_reproduces_the_recorded_timing() {
    // A synthetic capture: 5 chunks over 0.8 s; at --speed 2 the replay takes >= 0.4 s, and
    // --as-fast-as-possible much less.
    use hw_bridge::capture::{CaptureHeader, CaptureWriter, Record};
    let dir = tempfile::tempdir().unwrap();
    let cap = dir.path().join("c.bin");
    let f = std::fs::File::create(&cap).unwrap();
    let mut w = CaptureWriter::new(f, &CaptureHeader::default()).unwrap();
    for k in 0..5u64 {
        w.write(&Record::Data {
            t_ns: k * 200_000_000,
            bytes: vec![0],
        })
        .unwrap();
    }
    w.flush().unwrap();
    drop(w);
    let time = |args: &[&str]| {
        let t = Instant::now();
        let st = Command::new(BIN)
            .arg("replay")
            .arg(&cap)
            .args(args)
            .output()
            .unwrap();
        assert!(st.status.success(), "{st:?}");
        t.elapsed().as_secs_f64()
    };
    let slow = time(&["--speed", "2"]);
    let fast = time(&["--as-fast-as-possible"]);
    assert!(slow >= 0.4, "speed 2 replay took {slow} s");
    assert!(fast < slow, "fast {fast} s vs paced {slow} s");
}

/// Starts `hw-bridge record` on `port`, runs `hw-bridge send` with `send_args` on `peer`,
/// waits for the recorder to stop (idle 2 s) and returns the capture path.
fn send_and_record(d: &Path, port: &Path, peer: &Path, send_args: &[&str]) -> std::path::PathBuf {
    use std::io::BufRead;
    let cap = d.join("cap.bin");
    let mut rec = Command::new(BIN)
        .args([
            "record",
            "--quiet",
            "--idle-exit",
            "2",
            "--duration",
            "60",
            "--port",
        ])
        .arg(port)
        .arg("--out")
        .arg(&cap)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn record");
    let mut err = std::io::BufReader::new(rec.stderr.take().unwrap());
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    assert!(line.starts_with("recording"), "record said {line:?}");
    let drain = std::thread::spawn(move || std::io::read_to_string(err).unwrap_or_default());
    let send = Command::new(BIN)
        .arg("send")
        .args(send_args)
        .arg("--port")
        .arg(peer)
        .output()
        .expect("run send");
    assert!(send.status.success(), "send failed: {send:?}");
    let rec_out = rec.wait_with_output().unwrap();
    let rec_err = drain.join().unwrap();
    assert!(
        rec_out.status.success(),
        "record failed: {rec_out:?} {rec_err}"
    );
    cap
}

fn drive() -> nav_sim::Scenario {
    bridge_replay_drive("e2e-replay").scenario()
}

/// Every field of every solution as bits.
fn nav_bits(nav: &[nav_core::types::NavSolution]) -> Vec<u64> {
    nav.iter()
        .flat_map(|n| {
            let mut v = vec![n.t_s, n.lat_rad, n.lon_rad, n.h_m];
            v.extend(n.vel_ned_mps);
            v.extend(n.rpy_rad);
            v.into_iter()
                .map(f64::to_bits)
                .chain([u64::from(n.status)])
                .chain(
                    n.pos_std_ned_m
                        .iter()
                        .chain(&n.vel_std_ned_mps)
                        .chain(&n.att_std_rad)
                        .map(|x| x.to_bits()),
                )
                .collect::<Vec<_>>()
        })
        .collect()
}

#[test]
fn send_record_replay_with_config_equals_the_run_engine_on_the_case_files_bit_for_bit() {
    let name = "send_record_replay_with_config_equals_the_run_engine_on_the_case_files_bit_for_bit";
    if !require_socat(name) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // a simulated drive with a GNSS outage (50 s + 20 s) and its KF-GINS configuration
    let case = d.join("case");
    let config = simcase::write_case(&case, &drive(), 11, &[(50.0, 20.0)]);

    // hw-bridge send -> pty pair -> hw-bridge record
    let _socat = pty_pair(d);
    let case_s = case.display().to_string();
    let cap = send_and_record(
        d,
        &d.join("B"),
        &d.join("A"),
        &["--quiet", "--as-fast-as-possible", "--case", &case_s],
    );

    // the run engine on the case files, streaming the IMU file as `host-sim run` does (the
    // files it writes) ...
    let out_sim = d.join("out-sim");
    let loaded = nav_engine::load(&RunSpec::new(&config), true).unwrap();
    nav_engine::execute_streaming(
        &loaded.prepared,
        loaded.imu_stream.as_ref(),
        loaded.truth_stream.as_ref(),
        &out_sim,
        &loaded.inputs,
        None,
        &mut |_, _| {},
    )
    .unwrap();
    // ... and hw-bridge replay --config on the capture
    let out_rep = d.join("out-replay");
    let st = Command::new(BIN)
        .args(["replay", "--as-fast-as-possible"])
        .arg(&cap)
        .arg("--config")
        .arg(&config)
        .arg("--out")
        .arg(&out_rep)
        .output()
        .unwrap();
    assert!(st.status.success(), "{st:?}");
    let so = String::from_utf8_lossy(&st.stdout);
    assert!(
        so.contains("filter: model kf-gins-feedback (21 states)"),
        "{so}"
    );
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
        assert!(
            a == b,
            "{f}: replay differs from the run engine on the files"
        );
    }

    // in memory, every bit of every solution, f64 and f32 covariance
    let decoded = decode_capture(&cap).unwrap();
    assert_eq!(decoded.stats.rejected(), 0);
    assert_eq!(decoded.stats.lost(), 0);
    for f32 in [false, true] {
        let mut spec = RunSpec::new(&config);
        spec.set.precision = f32.then_some(nav_engine::run::Precision::F32);
        let p = nav_engine::load(&spec, false).unwrap().prepared;
        let (want, _) = nav_engine::execute(&p, &mut |_, _| {}).unwrap();
        let got = hw_bridge::cmd::run_filter_on_frames(&decoded.log, &spec).unwrap();
        let c = &got.output.counters;
        assert_eq!(got.output.nav.len(), p.case.imu.len() + 1, "f32 {f32}");
        assert_eq!(got.output.outages.len(), 1);
        // the simulator leaves the outage's fixes out of gnss.txt; every other fix is used
        assert!(
            c.gnss_accepted > 50 && c.gnss_accepted == c.gnss_total,
            "{c:?}"
        );
        assert_eq!(c.imu_epochs, want.counters.imu_epochs);
        assert_eq!(c.gnss_accepted, want.counters.gnss_accepted);
        assert!(
            nav_bits(&got.output.nav) == nav_bits(&want.nav),
            "f32 {f32}: solutions differ"
        );
    }
}

#[test]
fn stream_host_filter_live_over_a_pty_equals_the_same_filter_offline_on_the_case() {
    let name = "stream_host_filter_live_over_a_pty_equals_the_same_filter_offline_on_the_case";
    if !require_socat(name) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let case = d.join("case");
    simcase::write_case(&case, &drive(), 12, &[]);
    let _socat = pty_pair(d);
    let port = d.join("B").display().to_string();
    // live: stream --host-filter on one end (library call in a thread), send on the other
    let live = std::thread::spawn(move || {
        hw_bridge::cmd::stream(&hw_bridge::cmd::StreamOptions {
            duration_s: Some(6.0),
            host_filter: true,
            ..hw_bridge::cmd::StreamOptions::new(port)
        })
        .unwrap()
    });
    std::thread::sleep(Duration::from_millis(500));
    let send = Command::new(BIN)
        .args(["send", "--quiet", "--as-fast-as-possible", "--case"])
        .arg(&case)
        .arg("--port")
        .arg(d.join("A"))
        .output()
        .unwrap();
    assert!(send.status.success(), "{send:?}");
    let got = live.join().unwrap();
    // offline: the same filter on the same payloads
    let payloads: Vec<_> = read_case(&case).unwrap().into_iter().map(|p| p.1).collect();
    let (want, epochs, updates) = hw_bridge::cmd::host_filter_offline(&payloads).unwrap();
    assert_eq!(got.stats.rejected(), 0);
    assert_eq!(got.stats.lost(), 0);
    assert_eq!(u64::from(got.stats.frames_ok), payloads.len() as u64);
    assert!(
        epochs > 18_000 && updates > 50,
        "{epochs} epochs, {updates} updates"
    );
    assert_eq!(got.host_imu_epochs, epochs);
    assert_eq!(got.host_gnss_updates, updates);
    let (a, b) = (got.host_solution.unwrap(), want.unwrap());
    assert!(
        nav_bits(&[a]) == nav_bits(&[b]),
        "live {a:?} vs offline {b:?}"
    );
}
