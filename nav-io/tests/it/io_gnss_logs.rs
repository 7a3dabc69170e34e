//! NMEA and UBX log files as run inputs (`[gnss] format = "nmea"` / `"ubx"`): golden files
//! written by the tests, GPS time from the UTC time and RMC date, sigmas from GST / hAcc-vAcc
//! or the configured default, velocity from RMC/VTG or NAV-PVT, bad input naming the line or
//! byte offset, and the run configuration wiring.

use nav_core::types::FixQuality;
use nav_io::{
    parse_run_config, read_nmea_log, read_ubx_log, GnssFileKind, GnssLogOptions, IoError,
};
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// NMEA checksum (XOR of the characters between `$` and `*`), computed independently.
fn ck(body: &str) -> String {
    let c = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{c:02X}")
}

const KN: f64 = 1852.0 / 3600.0;
// 2024-03-13 is day 3 of GPS week 2305; GPS - UTC = 18 s.
const SOW_10_20_30: f64 = 3.0 * 86400.0 + 10.0 * 3600.0 + 20.0 * 60.0 + 30.0 + 18.0;

fn lat_field(k: usize) -> String {
    format!("53{:07.4}", 21.0 + k as f64 * 0.001)
}

/// Epoch k (1 s apart from 10:20:30 UTC): RMC (10 kn east) + GGA (+ GST).
fn epoch(k: usize, gst: bool) -> Vec<String> {
    let t = format!("1020{:02}.00", 30 + k);
    let lat = lat_field(k);
    let mut v = vec![
        ck(&format!(
            "GPRMC,{t},A,{lat},N,00630.3372,W,10.0,90.0,130324,,,A"
        )),
        ck(&format!(
            "GPGGA,{t},{lat},N,00630.3372,W,4,12,0.8,61.7,M,55.2,M,1.0,0001"
        )),
    ];
    if gst {
        v.push(ck(&format!("GPGST,{t},1.2,0.9,0.7,30.0,0.02,0.03,0.05")));
    }
    v
}

fn lines(v: &[String]) -> String {
    v.iter().map(|s| format!("{s}\r\n")).collect()
}

#[test]
fn nmea_log_with_gst_gives_gps_time_week_sigmas_and_velocity() {
    let dir = tempfile::tempdir().unwrap();
    let mut all = vec!["# a comment line".to_string()];
    all.extend(epoch(0, true));
    all.push(ck("GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1"));
    all.extend(epoch(1, true));
    // third epoch: RMC without speed/course, VTG (first, no time) with 20 kn due north
    let t = "102032.00";
    let lat = lat_field(2);
    all.push(ck("GPVTG,0.0,T,,M,20.0,N,37.0,K,A"));
    all.push(ck(&format!(
        "GPRMC,{t},A,{lat},N,00630.3372,W,,,130324,,,A"
    )));
    all.push(ck(&format!(
        "GPGGA,{t},{lat},N,00630.3372,W,5,12,0.8,61.7,M,55.2,M,1.0,0001"
    )));
    all.push(ck(&format!("GPGST,{t},1.2,0.9,0.7,30.0,0.2,0.3,0.5")));
    let p = write(dir.path(), "log.nmea", lines(&all).as_bytes());
    let opts = GnssLogOptions {
        vel_sigma_mps: Some([0.1, 0.3]),
        ..GnssLogOptions::default()
    };
    let r = read_nmea_log(&p, &opts, 6).unwrap();
    assert_eq!(r.fixes.len(), 3, "{r:?}");
    assert_eq!(r.week, Some(2305));
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_eq!(r.bad_skipped, 0);
    for (k, f) in r.fixes.iter().enumerate() {
        assert_eq!(f.t_s, SOW_10_20_30 + k as f64, "fix {k}");
        let lat = 53.0 + (21.0 + k as f64 * 0.001) / 60.0;
        assert!((f.lat_rad.to_degrees() - lat).abs() < 1e-9);
        assert!((f.lon_rad.to_degrees() + (6.0 + 30.3372 / 60.0)).abs() < 1e-9);
        assert!(
            (f.h_m - (61.7 + 55.2)).abs() < 1e-4,
            "MSL + geoid separation"
        );
        assert_eq!(f.num_sats, 12);
        assert!(f.has_velocity);
        assert_eq!(f.vel_std_ned_mps, [0.1, 0.1, 0.3]);
        assert!(f.is_valid());
    }
    assert_eq!(r.fixes[0].quality, FixQuality::RtkFixed);
    assert_eq!(r.fixes[2].quality, FixQuality::RtkFloat);
    assert_eq!(
        r.fixes[0].pos_std_ned_m,
        [0.02f32 as f64, 0.03f32 as f64, 0.05f32 as f64]
    );
    assert_eq!(
        r.fixes[2].pos_std_ned_m,
        [0.2f32 as f64, 0.3f32 as f64, 0.5f32 as f64]
    );
    // RMC: 10 kn at 90 deg; VTG: 20 kn at 0 deg
    let v0 = r.fixes[0].vel_ned_mps;
    assert!(v0[0].abs() < 1e-9 && (v0[1] - 10.0 * KN).abs() < 1e-6 && v0[2] == 0.0);
    let v2 = r.fixes[2].vel_ned_mps;
    assert!((v2[0] - 20.0 * KN).abs() < 1e-6 && v2[1].abs() < 1e-9);
    // the line of the sentence that completed each epoch
    assert_eq!(r.places, vec![6, 8, 12]);
    // max_q = 1 keeps the fixed epochs only
    let r1 = read_nmea_log(&p, &opts, 1).unwrap();
    assert_eq!(r1.fixes.len(), 2);
    assert_eq!(r1.dropped_by_quality, 1);
}

#[test]
fn nmea_log_without_gst_needs_a_default_sigma_and_warns_once() {
    let dir = tempfile::tempdir().unwrap();
    let all: Vec<String> = (0..4).flat_map(|k| epoch(k, false)).collect();
    let p = write(dir.path(), "nogst.nmea", lines(&all).as_bytes());
    let e = read_nmea_log(&p, &GnssLogOptions::default(), 6).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("nogst.nmea") && msg.contains("default_sigma_ned_m"),
        "{msg}"
    );
    // the first epoch ends when the second starts (line 3)
    assert_eq!(e.line(), Some(3), "{msg}");
    assert!(
        msg.contains(&format!("GPS {SOW_10_20_30:.3} s of week")),
        "{msg}"
    );
    let opts = GnssLogOptions {
        default_sigma_ned_m: Some([1.5, 1.5, 3.0]),
        ..GnssLogOptions::default()
    };
    let r = read_nmea_log(&p, &opts, 6).unwrap();
    assert_eq!(r.fixes.len(), 4);
    assert!(r.fixes.iter().all(|f| f.pos_std_ned_m == [1.5, 1.5, 3.0]));
    let w: Vec<&String> = r
        .warnings
        .iter()
        .filter(|w| w.contains("default_sigma_ned_m"))
        .collect();
    assert_eq!(w.len(), 1, "{:?}", r.warnings);
    assert!(w[0].contains("4 NMEA epochs without GST"), "{}", w[0]);
    // speed/course present, no velocity sigma stated: not used, said once
    assert!(r.fixes.iter().all(|f| !f.has_velocity));
    assert!(r.warnings.iter().any(|w| w.contains("vel_sigma_mps")));
    // HDOP x UERE takes precedence over the default
    let r = read_nmea_log(
        &p,
        &GnssLogOptions {
            hdop_uere_m: Some(2.0),
            ..opts
        },
        6,
    )
    .unwrap();
    let s = 0.8f32 as f64 * 2.0;
    assert_eq!(r.fixes[0].pos_std_ned_m, [s, s, 1.5 * s]);
}

#[test]
fn nmea_bad_checksum_is_skipped_and_counted_or_an_error_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let mut all: Vec<String> = (0..3).flat_map(|k| epoch(k, true)).collect();
    // line 5 = GGA of the second epoch: spoil its checksum
    let n = all[4].len();
    let last = &all[4][n - 1..];
    let repl = if last == "0" { "1" } else { "0" };
    all[4].replace_range(n - 1.., repl);
    let p = write(dir.path(), "bad.nmea", lines(&all).as_bytes());
    let r = read_nmea_log(&p, &GnssLogOptions::default(), 6).unwrap();
    assert_eq!(r.bad_skipped, 1);
    assert_eq!(r.fixes.len(), 2, "the epoch without its GGA is skipped");
    assert_eq!(r.fixes[1].t_s, SOW_10_20_30 + 2.0);
    assert!(
        r.warnings.iter().any(|w| w.contains("bad.nmea")
            && w.contains("1 bad NMEA sentences skipped (first at line 5")
            && w.to_lowercase().contains("checksum")),
        "{:?}",
        r.warnings
    );
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("1 NMEA epochs skipped")),
        "{:?}",
        r.warnings
    );
    let strict = GnssLogOptions {
        strict: true,
        ..GnssLogOptions::default()
    };
    let e = read_nmea_log(&p, &strict, 6).unwrap_err();
    assert!(matches!(e, IoError::Format { line: 5, .. }), "{e}");
    assert!(
        e.to_string().contains("bad.nmea") && e.to_string().to_lowercase().contains("checksum"),
        "{e}"
    );
    // no RMC at all: no date, no GPS time
    let gga_only: Vec<String> = all.iter().filter(|s| s.contains("GGA")).cloned().collect();
    let p = write(dir.path(), "gga.nmea", lines(&gga_only).as_bytes());
    let e = read_nmea_log(&p, &GnssLogOptions::default(), 6).unwrap_err();
    assert!(e.to_string().contains("RMC"), "{e}");
}

// ---------------------------------------------------------------- UBX NAV-PVT

/// UBX frame with the 8-bit Fletcher checksum over class, id, length and payload.
fn ubx_frame(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
    let mut f = vec![0xB5, 0x62, class, id];
    f.extend((payload.len() as u16).to_le_bytes());
    f.extend(payload);
    let (mut a, mut b) = (0u8, 0u8);
    for &x in &f[2..] {
        a = a.wrapping_add(x);
        b = b.wrapping_add(a);
    }
    f.extend([a, b]);
    f
}

struct Pvt {
    itow_ms: u32,
    fix_type: u8,
    flags: u8,
    lat_deg: f64,
    lon_deg: f64,
    h_m: f64,
    h_acc_m: f64,
    v_acc_m: f64,
    vel_mps: [f64; 3],
    s_acc_mps: f64,
}

/// NAV-PVT packet (92-byte payload, u-blox interface description layout).
fn nav_pvt(p: &Pvt) -> Vec<u8> {
    let mut b = vec![0u8; 92];
    b[0..4].copy_from_slice(&p.itow_ms.to_le_bytes());
    b[4..6].copy_from_slice(&2024u16.to_le_bytes());
    b[6] = 3;
    b[7] = 13;
    b[20] = p.fix_type;
    b[21] = p.flags;
    b[23] = 17;
    let e7 = |d: f64| ((d * 1e7).round() as i32).to_le_bytes();
    let mm = |m: f64| ((m * 1e3).round() as i32).to_le_bytes();
    b[24..28].copy_from_slice(&e7(p.lon_deg));
    b[28..32].copy_from_slice(&e7(p.lat_deg));
    b[32..36].copy_from_slice(&mm(p.h_m));
    b[36..40].copy_from_slice(&mm(p.h_m - 30.0));
    b[40..44].copy_from_slice(&mm(p.h_acc_m));
    b[44..48].copy_from_slice(&mm(p.v_acc_m));
    for i in 0..3 {
        b[48 + 4 * i..52 + 4 * i].copy_from_slice(&mm(p.vel_mps[i]));
    }
    b[68..72].copy_from_slice(&mm(p.s_acc_mps));
    ubx_frame(0x01, 0x07, &b)
}

fn pvt(k: usize) -> Pvt {
    Pvt {
        // across the week rollover: 604799.6, 0.1 (next week), ...
        itow_ms: ((604_799_600 + k as u64 * 500) % 604_800_000) as u32,
        fix_type: 3,
        flags: 0x83, // gnssFixOK, diffSoln, carrier fixed
        lat_deg: 30.527_891_23 + k as f64 * 1e-5,
        lon_deg: -114.356_712_34,
        h_m: 21.456 + k as f64 * 0.1,
        h_acc_m: 0.014,
        v_acc_m: 0.021,
        vel_mps: [1.234, -2.345, 0.056],
        s_acc_mps: 0.033,
    }
}

#[test]
fn ubx_log_round_trip_within_the_format_resolution() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = Vec::new();
    for k in 0..4 {
        bytes.extend(nav_pvt(&pvt(k)));
        // other UBX traffic (class 1 id 3, NAV-STATUS-like) between the fixes
        bytes.extend(ubx_frame(0x01, 0x03, &[0u8; 16]));
    }
    // a no-fix packet is dropped and counted
    bytes.extend(nav_pvt(&Pvt {
        fix_type: 0,
        flags: 0,
        ..pvt(4)
    }));
    let p = write(dir.path(), "log.ubx", &bytes);
    let r = read_ubx_log(&p, &GnssLogOptions::default(), 6).unwrap();
    assert_eq!(r.fixes.len(), 4, "{r:?}");
    assert_eq!(r.dropped_by_quality, 1);
    // these packets do not flag their UTC date valid: the week is unknown, and said so
    assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
    assert!(
        r.warnings[0].contains("GPS week is unknown"),
        "{:?}",
        r.warnings
    );
    assert_eq!(r.week, None);
    for (k, f) in r.fixes.iter().enumerate() {
        let want = pvt(k);
        // times continue past the end of the week
        assert!(
            (f.t_s - (604_799.6 + k as f64 * 0.5)).abs() < 1e-9,
            "{}",
            f.t_s
        );
        // resolution: 1e-7 deg, 1 mm, 1 mm/s
        assert!((f.lat_rad.to_degrees() - want.lat_deg).abs() <= 0.5e-7 + 1e-12);
        assert!((f.lon_rad.to_degrees() - want.lon_deg).abs() <= 0.5e-7 + 1e-12);
        assert!((f.h_m - want.h_m).abs() <= 0.5e-3 + 1e-12);
        for i in 0..3 {
            assert!((f.vel_ned_mps[i] - want.vel_mps[i]).abs() <= 0.5e-3 + 1e-12);
            assert!((f.vel_std_ned_mps[i] - 0.033).abs() <= 0.5e-3 + 1e-12);
        }
        assert!((f.pos_std_ned_m[0] - 0.014).abs() < 1e-9);
        assert!((f.pos_std_ned_m[1] - 0.014).abs() < 1e-9);
        assert!((f.pos_std_ned_m[2] - 0.021).abs() < 1e-9);
        assert!(f.has_velocity && f.is_valid());
        assert_eq!(f.quality, FixQuality::RtkFixed);
        assert_eq!(f.num_sats, 17);
    }
    // each fix named by the byte offset of its packet's last byte (100 + 24 bytes per step)
    assert_eq!(r.places, vec![99, 223, 347, 471]);
}

#[test]
fn ubx_bad_checksum_names_the_byte_offset_and_nmea_is_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = nav_pvt(&pvt(0));
    let mut bad = nav_pvt(&pvt(1));
    let n = bad.len();
    bad[n - 1] ^= 0xFF;
    bytes.extend(bad);
    bytes.extend(nav_pvt(&pvt(2)));
    for s in epoch(0, true) {
        bytes.extend(s.as_bytes());
        bytes.extend(b"\r\n");
    }
    bytes.extend(nav_pvt(&pvt(3)));
    let p = write(dir.path(), "bad.ubx", &bytes);
    let r = read_ubx_log(&p, &GnssLogOptions::default(), 6).unwrap();
    assert_eq!(r.fixes.len(), 3);
    assert_eq!(r.bad_skipped, 1);
    assert!(
        r.warnings.iter().any(|w| w.contains("bad.ubx")
            && w.contains("1 bad UBX packets skipped (first ending at byte offset 199")),
        "{:?}",
        r.warnings
    );
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("NMEA epochs in the UBX log ignored")),
        "{:?}",
        r.warnings
    );
    let e = read_ubx_log(
        &p,
        &GnssLogOptions {
            strict: true,
            ..GnssLogOptions::default()
        },
        6,
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("bad.ubx") && e.to_string().contains("byte offset 199"),
        "{e}"
    );
    // nothing but garbage: a clear error
    let p = write(dir.path(), "empty.ubx", b"not a ubx log");
    let e = read_ubx_log(&p, &GnssLogOptions::default(), 6).unwrap_err();
    assert!(e.to_string().contains("no NAV-PVT fixes"), "{e}");
}

#[test]
fn run_configuration_reads_nmea_and_ubx_logs() {
    let dir = tempfile::tempdir().unwrap();
    let all: Vec<String> = (0..3).flat_map(|k| epoch(k, false)).collect();
    write(dir.path(), "rx.nmea", lines(&all).as_bytes());
    let ubx: Vec<u8> = (0..3).flat_map(|k| nav_pvt(&pvt(k))).collect();
    write(dir.path(), "rx.ubx", &ubx);
    let imu: String = (0..=300)
        .map(|k| {
            let t = SOW_10_20_30 + k as f64 * 0.01;
            format!("{t:.3} 0 0 0 0 0 -0.0980665\n")
        })
        .collect();
    write(dir.path(), "imu.txt", imu.as_bytes());
    let rest = "[init]\npos_std_m = [1, 1, 1]\nvel_std_mps = [1, 1, 1]\natt_std_deg = [1, 1, 5]\n[init.align]\nstatic_s = 1.0\n[noise.accel]\nvrw_mps_per_sqrt_h = 0.1\n[noise.gyro]\narw_deg_per_sqrt_h = 0.3\n";
    let cfg = |gnss: &str| format!("[imu]\npath = \"imu.txt\"\nformat = \"text\"\n{gnss}\n{rest}");
    let cfg_path = dir.path().join("run.toml");

    let text = cfg("[gnss]\npath = \"rx.nmea\"\nformat = \"nmea\"\n[gnss.log]\ndefault_sigma_ned_m = [2, 2, 4]\nvel_sigma_mps = [0.2, 0.4]\n");
    let c = parse_run_config(&cfg_path, &text).unwrap();
    assert_eq!(c.gnss.format, GnssFileKind::Nmea);
    let inp = c.load_inputs(dir.path()).unwrap();
    assert_eq!(inp.gnss.len(), 3);
    assert_eq!(inp.gnss_week, Some(2305));
    assert_eq!(inp.gnss[0].t_s, SOW_10_20_30);
    assert!(inp.gnss.iter().all(|f| f.has_velocity));
    assert_eq!(
        inp.warnings
            .iter()
            .filter(|w| w.contains("default_sigma_ned_m"))
            .count(),
        1
    );
    // the writer keeps [gnss.log]
    let back: nav_io::RunConfig = toml::from_str(&toml::to_string_pretty(&c).unwrap()).unwrap();
    assert_eq!(back.gnss.log, c.gnss.log);

    // without [gnss.log] and without GST: the error names the file and the line
    let text = cfg("[gnss]\npath = \"rx.nmea\"\nformat = \"nmea\"\n");
    let e = parse_run_config(&cfg_path, &text)
        .unwrap()
        .load_inputs(dir.path())
        .unwrap_err();
    assert!(
        e.to_string().contains("rx.nmea") && e.line() == Some(3),
        "{e}"
    );

    let text = cfg("[gnss]\npath = \"rx.ubx\"\nformat = \"ubx\"\ntime_offset_s = 0.25\n");
    let inp = parse_run_config(&cfg_path, &text)
        .unwrap()
        .load_inputs(dir.path())
        .unwrap();
    assert_eq!(inp.gnss.len(), 3);
    assert_eq!(inp.gnss_week, None);
    assert!((inp.gnss[1].t_s - (604_800.1 + 0.25)).abs() < 1e-9);

    // [gnss.log] with another format is refused; unknown keys in it too
    let text = cfg("[gnss]\npath = \"rx.txt\"\nformat = \"text\"\n[gnss.log]\nstrict = true\n");
    let e = parse_run_config(&cfg_path, &text).unwrap_err();
    assert!(e.to_string().contains("[gnss.log]"), "{e}");
    let text =
        cfg("[gnss]\npath = \"rx.nmea\"\nformat = \"nmea\"\n[gnss.log]\ndefault_sigma = 1\n");
    let e = parse_run_config(&cfg_path, &text).unwrap_err();
    assert!(e.to_string().contains("default_sigma"), "{e}");
}

#[test]
fn ubx_log_of_an_hour_at_10_hz_reads_every_fix() {
    let dir = tempfile::tempdir().unwrap();
    let n = 36_000usize;
    let mut bytes = Vec::with_capacity(n * 100);
    for k in 0..n {
        bytes.extend(nav_pvt(&Pvt {
            itow_ms: 200_000_000 + k as u32 * 100,
            ..pvt(0)
        }));
    }
    let p = write(dir.path(), "hour.ubx", &bytes);
    let t0 = std::time::Instant::now();
    let r = read_ubx_log(&p, &GnssLogOptions::default(), 6).unwrap();
    let dt = t0.elapsed().as_secs_f64();
    println!(
        "{} bytes, {} fixes read in {dt:.3} s",
        bytes.len(),
        r.fixes.len()
    );
    assert_eq!(r.fixes.len(), n);
    assert!(r
        .fixes
        .windows(2)
        .all(|w| (w[1].t_s - w[0].t_s - 0.1).abs() < 1e-9));
}

/// A UTF-8 byte-order mark at the start of an NMEA log (a Windows logger) is skipped: the
/// same fixes as without it.
#[test]
fn nmea_log_with_a_utf8_byte_order_mark_reads_the_same_fixes() {
    let dir = tempfile::tempdir().unwrap();
    let mut all = epoch(0, true);
    all.extend(epoch(1, true));
    let text = lines(&all);
    let plain = write(dir.path(), "a.nmea", text.as_bytes());
    let bom = write(dir.path(), "b.nmea", format!("\u{feff}{text}").as_bytes());
    let opts = GnssLogOptions::default();
    let (a, b) = (
        read_nmea_log(&plain, &opts, 6).unwrap(),
        read_nmea_log(&bom, &opts, 6).unwrap(),
    );
    assert_eq!(a.fixes.len(), 2);
    // (compared as text: the velocity sigmas of fixes without a velocity are NaN)
    assert_eq!(format!("{:?}", a.fixes), format!("{:?}", b.fixes));
}
