//! GNSS files read one fix at a time (`RunConfig::open_gnss` and the per-format readers
//! `PosReader`, `GnssCsvReader`, `NmeaLogReader`, `UbxLogReader`) give exactly what the
//! whole-file readers give: the same fixes bit for bit (the `[gnss] time_offset_s` added),
//! the same week, drops and warnings once exhausted, the same errors naming file and line
//! (or UBX byte offset), with the fixes before an error returned first. The inputs: files
//! generated in every format, the inputs of the format tests (io_pos, io_gnsscsv,
//! io_gnss_logs, io_gnss_leap), the real drive's `.pos`; UBX bytes split into random chunks.

mod gnss_gen;

use gnss_gen::{Fmt, WEEK};
use nav_core::types::{FixQuality, GnssFix};
use nav_io::gnss::encode::{nmea_epoch, ubx_frame, ubx_nav_pvt};
use nav_io::runcfg::{GnssFixReader, GnssReadSummary};
use nav_io::{
    GnssCsvReader, GnssFileKind, GnssLogOptions, IoError, NmeaLogReader, PosOptions, PosReader,
    RunConfig, UbxLogReader,
};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

/// The fields of a fix as bits (bit-identical comparison, NaN included).
fn bits(f: &GnssFix) -> Vec<u64> {
    let mut v = vec![
        f.t_s.to_bits(),
        f.lat_rad.to_bits(),
        f.lon_rad.to_bits(),
        f.h_m.to_bits(),
    ];
    for a in [f.pos_std_ned_m, f.vel_ned_mps, f.vel_std_ned_mps] {
        v.extend(a.iter().map(|x| x.to_bits()));
    }
    v.extend([
        u64::from(f.has_velocity),
        f.quality as u64,
        u64::from(f.num_sats),
    ]);
    v
}

fn assert_same_fixes(a: &[GnssFix], b: &[GnssFix], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: fix count");
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert_eq!(bits(x), bits(y), "{what}: fix {i}: {x:?} vs {y:?}");
    }
}

/// What the whole-file reader of the configuration's format gives (as `open_gnss` did before
/// it streamed): fixes, week, drops, warnings.
type Whole = Result<(Vec<GnssFix>, Option<i64>, usize, Vec<String>), IoError>;

fn whole(cfg: &RunConfig, dir: &Path) -> Whole {
    let p = RunConfig::resolve(dir, &cfg.gnss.path);
    let opts = cfg.gnss.log.clone().unwrap_or_default();
    let q = cfg.gnss.max_q;
    Ok(match cfg.gnss.format {
        GnssFileKind::Text => (nav_io::read_gnss_text(&p)?, None, 0, Vec::new()),
        GnssFileKind::RtklibPos => {
            let r = nav_io::read_rtklib_pos(&p, &PosOptions { max_q: q })?;
            (r.fixes, r.week, r.dropped_by_quality, Vec::new())
        }
        GnssFileKind::Csv => {
            let r = nav_io::read_gnss_csv(&p, cfg.gnss.csv.as_ref().expect("mapping"))?;
            (r.fixes, r.week, r.dropped_by_quality, r.warnings)
        }
        GnssFileKind::Nmea => {
            let r = nav_io::read_nmea_log(&p, &opts, q)?;
            (r.fixes, r.week, r.dropped_by_quality, r.warnings)
        }
        GnssFileKind::Ubx => {
            let r = nav_io::read_ubx_log(&p, &opts, q)?;
            (r.fixes, r.week, r.dropped_by_quality, r.warnings)
        }
    })
}

/// Everything `open_gnss` yields: the fixes, the error that ended it (if any; nothing may
/// follow it), the summary at the end.
struct Streamed {
    fixes: Vec<GnssFix>,
    error: Option<IoError>,
    summary: GnssReadSummary,
}

fn streamed(rd: GnssFixReader) -> Streamed {
    let mut rd = rd;
    let mut fixes = Vec::new();
    let mut error = None;
    for r in &mut rd {
        assert!(error.is_none(), "an item after the error {error:?}");
        match r {
            Ok(f) => fixes.push(f),
            Err(e) => error = Some(e),
        }
    }
    assert!(rd.next().is_none(), "the reader ended");
    Streamed {
        fixes,
        error,
        summary: rd.summary().clone(),
    }
}

/// Streamed (with `[gnss] time_offset_s = 0.25`) and whole-file reads of the configuration's
/// GNSS file agree: same fixes (times + 0.25 s), same summary, or the same error. Returns the
/// streamed read.
fn check_same(dir: &Path, gnss_section: &str) -> Streamed {
    let cfg = gnss_gen::config(dir, gnss_section);
    let w = whole(&cfg, dir);
    let mut shifted = cfg.clone();
    shifted.gnss.time_offset_s = 0.25;
    let s = match shifted.open_gnss(dir) {
        Ok(rd) => streamed(rd),
        Err(e) => Streamed {
            fixes: Vec::new(),
            error: Some(e),
            summary: GnssReadSummary::default(),
        },
    };
    match w {
        Ok((fixes, week, dropped, warnings)) => {
            assert!(s.error.is_none(), "{gnss_section}: {:?}", s.error);
            let want: Vec<GnssFix> = fixes
                .iter()
                .map(|f| GnssFix {
                    t_s: f.t_s + 0.25,
                    ..*f
                })
                .collect();
            assert_same_fixes(&s.fixes, &want, gnss_section);
            let summary = GnssReadSummary {
                week,
                dropped_by_quality: dropped,
                warnings,
            };
            assert_eq!(s.summary, summary, "{gnss_section}");
        }
        Err(e) => {
            let got = s.error.as_ref().map(|e| format!("{e:?}"));
            assert_eq!(got, Some(format!("{e:?}")), "{gnss_section}");
        }
    }
    s
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn the_readers_can_move_to_another_thread() {
    fn send<T: Send>() {}
    send::<GnssFixReader>();
    send::<PosReader>();
    send::<GnssCsvReader>();
    send::<NmeaLogReader>();
    send::<UbxLogReader>();
    send::<nav_io::GnssTextReader>();
}

#[test]
fn generated_files_in_every_format_stream_as_they_read_whole() {
    let dir = tempfile::tempdir().unwrap();
    for fmt in Fmt::ALL {
        gnss_gen::write_file(dir.path(), fmt, 2_000);
        let s = check_same(dir.path(), &fmt.gnss_section(""));
        assert_eq!(s.fixes.len(), gnss_gen::kept(fmt, 2_000), "{fmt:?}");
        assert_eq!(s.summary.week, fmt.has_week().then_some(WEEK), "{fmt:?}");
        // the summary's week is known with the first fix; `max_q` (not used by the text and
        // CSV formats: no quality, or the mapping's own filter) keeps the fixed ones
        let cfg = gnss_gen::config(dir.path(), &fmt.gnss_section("max_q = 1\n"));
        let mut rd = cfg.open_gnss(dir.path()).unwrap();
        let first = rd.next().unwrap().unwrap();
        let q = match fmt {
            Fmt::Text => FixQuality::Single,
            Fmt::Csv => FixQuality::RtkFloat,
            _ => FixQuality::RtkFixed,
        };
        assert_eq!(first.quality, q, "{fmt:?}");
        assert_eq!(rd.summary().week, fmt.has_week().then_some(WEEK), "{fmt:?}");
        check_same(dir.path(), &fmt.gnss_section("max_q = 1\n"));
    }
}

#[test]
fn the_format_readers_give_the_lines_and_offsets_of_the_whole_file_records() {
    let dir = tempfile::tempdir().unwrap();
    let p = gnss_gen::write_file(dir.path(), Fmt::Pos, 500);
    let rd = PosReader::open(&p, &PosOptions { max_q: 6 }).unwrap();
    let lines: Vec<usize> = rd.map(|r| r.unwrap().1).collect();
    // two header lines; record k on line k + 3; the no-fix records (k % 50 == 7) dropped
    let want: Vec<usize> = (0..500).filter(|k| k % 50 != 7).map(|k| k + 3).collect();
    assert_eq!(lines, want);

    let p = gnss_gen::write_file(dir.path(), Fmt::Csv, 500);
    let cfg = gnss_gen::config(dir.path(), &Fmt::Csv.gnss_section(""));
    let rd = GnssCsvReader::open(&p, cfg.gnss.csv.as_ref().unwrap()).unwrap();
    let lines: Vec<usize> = rd.map(|r| r.unwrap().1).collect();
    let whole = nav_io::read_gnss_csv(&p, cfg.gnss.csv.as_ref().unwrap()).unwrap();
    assert_eq!(lines, whole.lines);
    assert_eq!(lines[0], 2);

    let opts = GnssLogOptions::default();
    let p = gnss_gen::write_file(dir.path(), Fmt::Nmea, 500);
    let places: Vec<usize> = NmeaLogReader::open(&p, &opts, 6)
        .unwrap()
        .map(|r| r.unwrap().1)
        .collect();
    assert_eq!(places, nav_io::read_nmea_log(&p, &opts, 6).unwrap().places);
    // RMC, GGA, GST per epoch: epoch k ends on line 3k + 3 (the first one when the second
    // starts, line 4; then each as soon as its GST arrives)
    assert_eq!(places[..3], [4, 6, 9]);

    let p = gnss_gen::write_file(dir.path(), Fmt::Ubx, 500);
    let places: Vec<usize> = UbxLogReader::open(&p, &opts, 6)
        .unwrap()
        .map(|r| r.unwrap().1)
        .collect();
    assert_eq!(places, nav_io::read_ubx_log(&p, &opts, 6).unwrap().places);
    // 100-byte NAV-PVT frames: packet k ends at byte 100k + 99
    assert_eq!(places[..3], [99, 199, 299]);
}

// ------------------------------------------------------------ inputs of the format tests

fn ck(body: &str) -> String {
    let c = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{c:02X}")
}

/// io_gnss_logs's epoch k (1 s apart from 10:20:30 UTC, 2024-03-13): RMC + GGA (+ GST).
fn nmea_test_epoch(k: usize, gst: bool) -> Vec<String> {
    let t = format!("1020{:02}.00", 30 + k);
    let lat = format!("53{:07.4}", 21.0 + k as f64 * 0.001);
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

fn lines(v: &[String]) -> Vec<u8> {
    v.iter()
        .map(|s| format!("{s}\r\n"))
        .collect::<String>()
        .into_bytes()
}

#[test]
fn the_nmea_and_ubx_inputs_of_the_format_tests_stream_as_they_read_whole() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nmea = |log: &str| format!("[gnss]\npath = \"log.nmea\"\nformat = \"nmea\"\n{log}");
    // GST, GSA, VTG without a time; then without GST; a bad checksum; no RMC
    let mut all = vec!["# a comment line".to_string()];
    all.extend(nmea_test_epoch(0, true));
    all.push(ck("GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1"));
    all.extend(nmea_test_epoch(1, true));
    all.push(ck("GPVTG,0.0,T,,M,20.0,N,37.0,K,A"));
    all.extend(nmea_test_epoch(2, true));
    write(d, "log.nmea", &lines(&all));
    for log in [
        "[gnss.log]\nvel_sigma_mps = [0.1, 0.3]\n",
        "max_q = 1\n[gnss.log]\nvel_sigma_mps = [0.1, 0.3]\n",
        "",
    ] {
        check_same(d, &nmea(log));
    }
    let nogst: Vec<String> = (0..4).flat_map(|k| nmea_test_epoch(k, false)).collect();
    write(d, "log.nmea", &lines(&nogst));
    for log in [
        "",
        "[gnss.log]\ndefault_sigma_ned_m = [1.5, 1.5, 3.0]\n",
        "[gnss.log]\ndefault_sigma_ned_m = [1.5, 1.5, 3.0]\nhdop_uere_m = 2.0\n",
    ] {
        check_same(d, &nmea(log));
    }
    let mut bad: Vec<String> = (0..3).flat_map(|k| nmea_test_epoch(k, true)).collect();
    let n = bad[4].len();
    let repl = if &bad[4][n - 1..] == "0" { "1" } else { "0" };
    bad[4].replace_range(n - 1.., repl);
    write(d, "log.nmea", &lines(&bad));
    let s = check_same(d, &nmea(""));
    assert!(s.summary.warnings.iter().any(|w| w.contains("line 5")));
    let s = check_same(d, &nmea("[gnss.log]\nstrict = true\n"));
    // strict: the first epoch is returned, then the error naming line 5
    assert_eq!(s.fixes.len(), 1);
    assert!(matches!(s.error, Some(IoError::Format { line: 5, .. })));
    let gga: Vec<String> = bad.iter().filter(|s| s.contains("GGA")).cloned().collect();
    write(d, "log.nmea", &lines(&gga));
    check_same(d, &nmea(""));
    // io_gnss_leap: 2016-12-31 23:59:58 .. 2017-01-01 00:00:02
    let leap_fix = |date: &str, time: &str| {
        [
            ck(&format!(
                "GPRMC,{time},A,4811.9400,N,01622.2000,E,0.4,90.0,{date},,,A"
            )),
            ck(&format!(
                "GPGGA,{time},4811.9400,N,01622.2000,E,4,12,0.8,220.0,M,0.0,M,1.0,0001"
            )),
            ck(&format!("GPGST,{time},0.03,0.02,0.02,0.0,0.02,0.02,0.04")),
        ]
    };
    let mut leap = Vec::new();
    for t in ["235958.00", "235959.00", "235960.00"] {
        leap.extend(leap_fix("311216", t));
    }
    for t in ["000000.00", "000001.00", "000002.00"] {
        leap.extend(leap_fix("010117", t));
    }
    write(d, "log.nmea", &lines(&leap));
    let s = check_same(d, &nmea(""));
    assert!(s.summary.warnings.iter().any(|w| w.contains("leap second")));
    assert_eq!(s.summary.week, Some(1930));
    check_same(d, &nmea("[gnss.log]\nleap_seconds = 17\n"));

    // UBX: io_gnss_leap's log (valid UTC dates), with other packets, NMEA, a bad checksum
    let ubx = "[gnss]\npath = \"log.ubx\"\nformat = \"ubx\"\n";
    let mut bytes = Vec::new();
    for k in 0..30u32 {
        let (week, sow) = if 604_795 + k < 604_800 {
            (1929, f64::from(604_795 + k))
        } else {
            (1930, f64::from(604_795 + k - 604_800))
        };
        let f = GnssFix {
            t_s: sow,
            lat_rad: 48.199f64.to_radians(),
            lon_rad: 16.37f64.to_radians(),
            h_m: 220.0,
            pos_std_ned_m: [0.02, 0.02, 0.04],
            quality: if k == 3 {
                FixQuality::NoFix
            } else {
                FixQuality::RtkFixed
            },
            num_sats: 12,
            ..GnssFix::default()
        };
        bytes.extend(ubx_nav_pvt(&f, week, if k > 22 { 18 } else { 17 }));
        if k % 7 == 0 {
            bytes.extend(ubx_frame(0x01, 0x03, &[0u8; 16]));
        }
    }
    write(d, "log.ubx", &bytes);
    let s = check_same(d, ubx);
    assert_eq!(s.summary.week, Some(1929));
    assert_eq!(s.summary.dropped_by_quality, 1);
    let mut spoilt = bytes.clone();
    spoilt[250] ^= 0xFF;
    for l in nmea_test_epoch(0, true) {
        spoilt.extend(l.as_bytes());
        spoilt.extend(b"\r\n");
    }
    write(d, "log.ubx", &spoilt);
    let s = check_same(d, ubx);
    assert_eq!(s.summary.warnings.len(), 2, "{:?}", s.summary.warnings);
    let s = check_same(d, &format!("{ubx}[gnss.log]\nstrict = true\n"));
    assert!(s.error.unwrap().to_string().contains("byte offset"));
    write(d, "log.ubx", b"not a ubx log");
    check_same(d, ubx);
}

#[test]
fn the_csv_and_pos_inputs_of_the_format_tests_stream_as_they_read_whole() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "rover.txt", b"2015_11_26_15_00_02_617 RTK_FIXED 40.0123456789 -105.2345678901 1650.123 0.012 0.013 0.030\n2015_11_26_15_00_05_617 RTK_FLOAT 40.0123466789 -105.2345668901 1650.223 0.112 0.113 0.230\n2015_11_26_15_00_08_617 RTK_FIXED 40.0123476789 -105.2345658901 1650.323 0.014 0.015 0.031\n2015_11_26_15_00_11_617 SINGLE 40.0123486789 -105.2345648901 1652.000 1.5 1.5 3.0\n");
    let s = check_same(d, "[gnss]\npath = \"rover.txt\"\nformat = \"csv\"\n[gnss.csv.columns]\ntime = 1\nlat = 3\nlon = 4\nh = 5\nsigma_ned = [6, 7, 8]\n[gnss.csv.time]\nkind = \"text\"\nformat = \"%Y_%m_%d_%H_%M_%S_%3f\"\nscale = \"gps\"\n[gnss.csv.quality]\ncolumn = 2\naccept = [\"RTK_FIXED\", \"rtk_float\"]\n");
    assert_eq!((s.fixes.len(), s.summary.dropped_by_quality), (3, 1));
    write(d, "fixes.csv", b"time_ms,lat,lon,alt,speed,bearing\n1700000000000,48.1000000,11.5000000,520.5,15.0,90.0\n1700000000100,48.1000000,11.5000203,520.5,15.0,90.0\n1700000000200,48.1000000,11.5000406,520.6,15.2,45.0\n");
    let ublox = "[gnss]\npath = \"fixes.csv\"\nformat = \"csv\"\n[gnss.csv]\nskip_lines = 1\nspeed_unit = \"m/s\"\ndefault_sigma_ned_m = [2.0, 2.0, 4.0]\ndefault_vel_sigma_ned_mps = [0.3, 0.3, 0.6]\n[gnss.csv.columns]\ntime = \"time_ms\"\nlat = \"lat\"\nlon = \"lon\"\nh = \"alt\"\nspeed = \"speed\"\ncourse = \"bearing\"\n[gnss.csv.time]\nkind = \"unix_ms\"\n";
    let s = check_same(d, ublox);
    assert_eq!(s.summary.week, Some(2288));
    assert_eq!(s.summary.warnings.len(), 3, "{:?}", s.summary.warnings);
    // a bad record after the first: that fix, then the error naming line 3, column 2
    write(d, "fixes.csv", b"time_ms,lat,lon,alt,speed,bearing\n1700000000000,48.1000000,11.5000000,520.5,15.0,90.0\n1700000000100,north,11.5000203,520.5,15.0,90.0\n");
    let s = check_same(d, ublox);
    assert_eq!(s.fixes.len(), 1);
    assert!(matches!(
        s.error,
        Some(IoError::NotANumber {
            line: 3,
            column: 2,
            ..
        })
    ));

    let hdr = "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio    vn(m/s)    ve(m/s)    vu(m/s)      sdvn     sdve     sdvu    sdvne    sdveu    sdvun\n";
    let pos = "[gnss]\npath = \"a.pos\"\nformat = \"rtklib_pos\"\n";
    let body = "2025/07/08 19:34:18.499  40.096626800 -105.147448300  1601.4740   1  21   0.0099   0.0098   0.0100   0.0010  -0.0020   0.0030   0.00    0.0   0.0100  -0.0020   0.0090   0.0587   0.0586   0.0585   0.0000   0.0000   0.0000\n2025/07/08 19:34:18.749  40.096626900 -105.147448300  1601.4760   2  21   0.0200   0.0200   0.0300   0.0000   0.0000   0.0000   0.00    0.0   0.0010   0.0020  -0.0060   0.0558   0.0558   0.0558   0.0000   0.0000   0.0000\n";
    write(d, "a.pos", format!("{hdr}{body}").as_bytes());
    check_same(d, pos);
    check_same(d, &format!("{pos}max_q = 1\n"));
    let utc = "%  UTC                   latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n2025/07/12 23:59:40.000   40.0 -105.0  1600.0   1  12   0.01 0.01 0.02 0 0 0 0 0\n2025/07/12 23:59:50.000   40.0 -105.0  1600.0   1  12   0.01 0.01 0.02 0 0 0 0 0\n";
    write(d, "a.pos", utc.as_bytes());
    let s = check_same(d, pos);
    assert_eq!(s.summary.week, Some(2374));
    let dms = "%  GPST                  latitude(d'\")   longitude(d'\")  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n2025/07/08 19:34:18.500   40 05 47.85648 -105 08 50.81388  1601.4740   1  21   0.0099   0.0099   0.0100   0.0000   0.0000   0.0000   0.00    0.0\n2025/07/08 19:34:18.750   -0 30 00.00000  -0 15 00.00000  10.0   1  21   0.0099   0.0099   0.0100   0.0000   0.0000   0.0000   0.00    0.0\n";
    write(d, "a.pos", dms.as_bytes());
    check_same(d, pos);
    // time going back on line 5: the first fix, then the error
    let back = format!("{hdr}{body}2025/07/08 19:34:18.499  40.096626800 -105.147448300  1601.4740   1  21   0.0099   0.0098   0.0100   0.0010  -0.0020   0.0030   0.00    0.0   0.0100  -0.0020   0.0090   0.0587   0.0586   0.0585   0.0000   0.0000   0.0000\n");
    write(d, "a.pos", back.as_bytes());
    let s = check_same(d, pos);
    assert_eq!(s.fixes.len(), 2);
    assert!(matches!(
        s.error,
        Some(IoError::NonMonotonicTime { line: 4, .. })
    ));
}

// ------------------------------------------------------------------------- real data

#[test]
fn the_real_drive_pos_streams_as_it_reads_whole() {
    let Some(d) = test_support::real_data("the_real_drive_pos_streams_as_it_reads_whole") else {
        return;
    };
    let p = d.join("rtklibexplorer-drive0708/gnss_1934_sf.pos");
    let gnss = format!(
        "[gnss]\npath = \"{}\"\nformat = \"rtklib_pos\"\n",
        p.display()
    );
    let dir = tempfile::tempdir().unwrap();
    let s = check_same(dir.path(), &gnss);
    // io_pos: 2197 epochs, 2189 fixed
    assert_eq!(s.fixes.len(), 2197);
    assert_eq!(s.summary.week, Some(2374));
    let s = check_same(dir.path(), &format!("{gnss}max_q = 1\n"));
    assert_eq!(s.fixes.len(), 2189);
    assert_eq!(s.summary.dropped_by_quality, 8);
    // the format's reader on its own: the counters of the whole-file record
    let mut rd = PosReader::open(&p, &PosOptions { max_q: 1 }).unwrap();
    let fixes: Vec<GnssFix> = rd.by_ref().map(|r| r.unwrap().0).collect();
    let w = nav_io::read_rtklib_pos(&p, &PosOptions { max_q: 1 }).unwrap();
    assert_same_fixes(&fixes, &w.fixes, "PosReader");
    assert_eq!(
        (rd.epochs(), rd.count_by_q(), rd.has_velocity()),
        (w.epochs, w.count_by_q, w.has_velocity)
    );
}

// ---------------------------------------------------------------- errors mid-file

/// A file of 3000 records in `fmt` with record `BAD` replaced by `bad`: the stream returns the
/// kept fixes of the records before it (bit-identical to the whole-file read of those records
/// alone), then the whole-file read's error, then nothing. `strict`: `[gnss.log] strict`.
fn error_after_fixes(fmt: Fmt, strict: bool, bad: &[u8]) -> IoError {
    const BAD: usize = 1234;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut section = fmt.gnss_section("");
    if strict {
        if section.contains("[gnss.log]\n") {
            section = section.replace("[gnss.log]\n", "[gnss.log]\nstrict = true\n");
        } else {
            section += "[gnss.log]\nstrict = true\n";
        }
    }
    let cfg = gnss_gen::config(d, &section);
    // the records before the bad one, read whole
    gnss_gen::write_file(d, fmt, BAD);
    let before = whole(&cfg, d).expect("the records before the bad one").0;
    assert_eq!(before.len(), gnss_gen::kept(fmt, BAD));
    gnss_gen::write_file_with(d, fmt, 3000, |k| (k == BAD).then(|| bad.to_vec()));
    let s = check_same(d, &section);
    let want: Vec<GnssFix> = before
        .iter()
        .map(|f| GnssFix {
            t_s: f.t_s + 0.25,
            ..*f
        })
        .collect();
    assert_same_fixes(&s.fixes, &want, &format!("{fmt:?} before the error"));
    let e = s.error.expect("an error");
    assert!(e.to_string().contains("gnss."), "{e}");
    e
}

#[test]
fn an_error_mid_file_comes_after_every_fix_before_it_and_ends_the_stream() {
    // text and .pos: record k is on line k + 1 (text) or k + 3 (two header lines)
    let e = error_after_fixes(Fmt::Text, false, b"300000.1 30.5 abc 20 0.1 0.1 0.1\n");
    assert!(
        matches!(
            e,
            IoError::NotANumber {
                line: 1235,
                column: 3,
                ..
            }
        ),
        "{e:?}"
    );
    let mut pos = gnss_gen::record_bytes(Fmt::Pos, 1234);
    pos.truncate(120);
    pos.push(b'\n');
    let e = error_after_fixes(Fmt::Pos, false, &pos);
    assert!(
        matches!(e, IoError::TooFewFields { line: 1237, .. }),
        "{e:?}"
    );
    let csv = String::from_utf8(gnss_gen::record_bytes(Fmt::Csv, 1234))
        .unwrap()
        .replacen(",0.02,", ",-0.02,", 1);
    let e = error_after_fixes(Fmt::Csv, false, csv.as_bytes());
    assert!(
        matches!(
            e,
            IoError::InvalidValue {
                line: 1236,
                column: 7,
                ..
            }
        ),
        "{e:?}"
    );
    // NMEA: a line that is not text (3 lines per epoch: record 1234 starts on line 3703)
    let e = error_after_fixes(Fmt::Nmea, false, b"$GP\xff\xfe\r\n");
    assert!(matches!(e, IoError::NotText { line: 3703, .. }), "{e:?}");
    // strict: a bad checksum is an error naming the line
    let mut s = gnss_gen::record_bytes(Fmt::Nmea, 1234);
    s[10] = b'9';
    let e = error_after_fixes(Fmt::Nmea, true, &s);
    assert!(matches!(e, IoError::Format { line: 3703, .. }), "{e:?}");
    // UBX strict: a bad checksum names the byte offset of the packet's end
    let mut u = gnss_gen::record_bytes(Fmt::Ubx, 1234);
    let n = u.len();
    u[n - 1] ^= 0x55;
    let e = error_after_fixes(Fmt::Ubx, true, &u);
    assert!(
        e.to_string().contains("byte offset 123499"),
        "{e}: 100-byte packets"
    );
}

#[test]
fn a_truncated_gzip_ubx_log_gives_its_decoded_fixes_then_the_read_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = gnss_gen::write_file(d, Fmt::UbxGz, 5000);
    let full = std::fs::read(&p).unwrap();
    std::fs::write(&p, &full[..full.len() / 2]).unwrap();
    let s = check_same(d, &Fmt::UbxGz.gnss_section(""));
    assert!(
        matches!(s.error, Some(IoError::Read { .. })),
        "{:?}",
        s.error
    );
    // the fixes decoded before the cut are the first ones of the whole file
    assert!(s.fixes.len() > 1000, "{}", s.fixes.len());
    let clean = gnss_gen::write_file(d, Fmt::Ubx, 5000);
    let all = nav_io::read_ubx_log(&clean, &GnssLogOptions::default(), 6).unwrap();
    assert!(s.fixes.len() < all.fixes.len());
    let want: Vec<GnssFix> = all.fixes[..s.fixes.len()]
        .iter()
        .map(|f| GnssFix {
            t_s: f.t_s + 0.25,
            ..*f
        })
        .collect();
    assert_same_fixes(&s.fixes, &want, "gzip prefix");
}

// ------------------------------------------------------------- UBX week look-ahead

/// A UBX log of `n` NAV-PVT packets of which the first `no_utc` do not flag their UTC date
/// valid.
fn ubx_without_utc_at_start(n: usize, no_utc: usize) -> Vec<u8> {
    let mut b = Vec::new();
    for k in 0..n {
        let mut p = gnss_gen::record_bytes(Fmt::Ubx, k);
        if k < no_utc {
            // clear validDate/validTime (payload byte 11), recompute the checksum
            let mut payload = p[6..p.len() - 2].to_vec();
            payload[11] = 0;
            p = ubx_frame(0x01, 0x07, &payload);
        }
        b.extend(p);
    }
    b
}

#[test]
fn the_ubx_week_is_known_with_the_first_fix_when_a_valid_utc_date_comes_within_the_look_ahead() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let opts = GnssLogOptions::default();
    let la = nav_io::gnsslog::UBX_WEEK_LOOKAHEAD;
    // the first valid UTC date on the 40th kept fix: known with the first fix
    let p = write(d, "a.ubx", &ubx_without_utc_at_start(500, 40));
    let mut rd = UbxLogReader::open(&p, &opts, 6).unwrap();
    rd.next().unwrap().unwrap();
    assert_eq!(rd.week(), Some(WEEK));
    // beyond the look-ahead: the first fixes go out without it, the week comes later
    let p = write(d, "a.ubx", &ubx_without_utc_at_start(500, la + 20));
    let mut rd = UbxLogReader::open(&p, &opts, 6).unwrap();
    rd.next().unwrap().unwrap();
    assert_eq!(rd.week(), None);
    let rest = rd.by_ref().filter(|r| r.is_ok()).count();
    assert_eq!(rd.week(), Some(WEEK));
    assert_eq!(1 + rest, gnss_gen::kept(Fmt::Ubx, 500));
    let w = nav_io::read_ubx_log(&p, &opts, 6).unwrap();
    assert_eq!(w.week, Some(WEEK));
    assert!(w.warnings.is_empty(), "{:?}", w.warnings);
    // never: unknown, and said so at the end
    let p = write(d, "a.ubx", &ubx_without_utc_at_start(100, 100));
    let s = check_same(d, "[gnss]\npath = \"a.ubx\"\nformat = \"ubx\"\n");
    assert_eq!(s.summary.week, None);
    assert!(s.summary.warnings[0].contains("GPS week is unknown"));
    let _ = p;
}

// -------------------------------------------------------------- UBX in random chunks

/// Hands out its bytes in chunks of the given sizes (cycled).
struct Chunked {
    bytes: Vec<u8>,
    at: usize,
    sizes: Vec<usize>,
    k: usize,
}

impl std::io::Read for Chunked {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let want = self.sizes[self.k % self.sizes.len()].max(1);
        self.k += 1;
        let n = want
            .min(buf.len())
            .min(self.bytes.len().saturating_sub(self.at));
        buf[..n].copy_from_slice(&self.bytes[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

/// Everything a UBX read gives, as text (fixes as bits, places, week, counts, warnings, error).
fn ubx_outcome(rd: UbxLogReader) -> String {
    let mut rd = rd;
    let mut out = String::new();
    for r in &mut rd {
        match r {
            Ok((f, off)) => out += &format!("{:?} @{off}\n", bits(&f)),
            Err(e) => out += &format!("error {e:?}\n"),
        }
    }
    out += &format!(
        "week {:?} dropped {} bad {} warnings {:?}",
        rd.week(),
        rd.dropped_by_quality(),
        rd.bad_skipped(),
        rd.warnings()
    );
    out
}

fn gz(b: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn ubx_bytes_in_any_chunks_read_as_the_file_does(
        n in 1usize..150,
        nmea_every in 2usize..20,
        damage in proptest::collection::vec((0usize..20_000, any::<u8>()), 0..4),
        sizes in proptest::collection::vec(1usize..300, 1..8),
        strict in any::<bool>(),
        compress in any::<bool>(),
    ) {
        let mut bytes = Vec::new();
        for k in 0..n {
            bytes.extend(gnss_gen::record_bytes(Fmt::Ubx, k));
            if k % nmea_every == 0 {
                for l in nmea_epoch(&gnss_gen::fix(k), WEEK, 18) {
                    bytes.extend(l.as_bytes());
                    bytes.extend(b"\r\n");
                }
            }
        }
        let len = bytes.len();
        for (at, v) in &damage {
            bytes[at % len] ^= v;
        }
        if compress {
            bytes = gz(&bytes);
        }
        let dir = tempfile::tempdir().unwrap();
        let p = write(dir.path(), "c.ubx", &bytes);
        let opts = GnssLogOptions { strict, ..GnssLogOptions::default() };
        let from_file = ubx_outcome(UbxLogReader::open(&p, &opts, 6).unwrap());
        let src = Chunked { bytes, at: 0, sizes, k: 0 };
        let chunked = ubx_outcome(UbxLogReader::from_reader(&p, src, &opts, 6).unwrap());
        prop_assert_eq!(&from_file, &chunked);
        // and the whole-file reader agrees with the stream
        match nav_io::read_ubx_log(&p, &opts, 6) {
            Ok(w) => {
                let mut want: String = w
                    .fixes
                    .iter()
                    .zip(&w.places)
                    .map(|(f, off)| format!("{:?} @{off}\n", bits(f)))
                    .collect();
                want += &format!(
                    "week {:?} dropped {} bad {} warnings {:?}",
                    w.week, w.dropped_by_quality, w.bad_skipped, w.warnings
                );
                prop_assert_eq!(&from_file, &want);
            }
            Err(e) => {
                let err = format!("error {e:?}");
                prop_assert!(from_file.contains(&err), "{} not in {}", err, from_file);
            }
        }
    }
}
