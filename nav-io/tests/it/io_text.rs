//! The project's IMU/GNSS/nav text formats: round trips (plain and gzip) and malformed input
//! (truncated line, text in a number column, NaN, non-monotonic time, IMU time gaps).

use nav_core::types::{FixQuality, GnssFix, ImuSample, NavSolution};
use nav_io::{
    read_gnss_text, read_imu_bin, read_imu_text, read_nav_text, write_gnss_text, write_imu_bin,
    write_imu_text, write_nav_text, IoError, NavTextReader,
};
use std::io::Write;
use std::path::{Path, PathBuf};

fn tmp(dir: &tempfile::TempDir, name: &str) -> PathBuf {
    dir.path().join(name)
}

fn write_str(p: &Path, s: &str) {
    std::fs::write(p, s).unwrap();
}

fn imu_samples(n: usize, with_temp: bool) -> Vec<ImuSample> {
    (0..n)
        .map(|k| {
            let t = 456300.0 + 0.005 * (k as f64 + 1.0);
            let x = k as f64;
            ImuSample {
                t_s: t,
                dtheta_rad: [
                    1.234567e-5 * (x * 0.1).sin(),
                    -3.0e-9 * x,
                    7.7e-4 / (x + 1.0),
                ],
                dv_mps: [0.049 * (x * 0.3).cos(), -1.0e-7, -0.0490332 + 1e-12 * x],
                temperature_c: if with_temp && k % 3 != 0 {
                    25.0 + 0.01 * x
                } else {
                    f64::NAN
                },
            }
        })
        .collect()
}

#[test]
fn imu_text_round_trip_is_bit_exact_plain_and_gzip_with_optional_temperature() {
    let dir = tempfile::tempdir().unwrap();
    for (name, with_temp) in [("a.txt", false), ("b.txt.gz", true), ("c.txt", true)] {
        let s = imu_samples(500, with_temp);
        let p = tmp(&dir, name);
        write_imu_text(&p, &s).unwrap();
        let r = read_imu_text(&p).unwrap();
        assert_eq!(r.samples.len(), s.len());
        for (a, b) in s.iter().zip(&r.samples) {
            assert_eq!(a.t_s.to_bits(), b.t_s.to_bits());
            assert_eq!(a.dtheta_rad, b.dtheta_rad);
            assert_eq!(a.dv_mps, b.dv_mps);
            assert_eq!(a.temperature_c.is_nan(), b.temperature_c.is_nan());
            if a.temperature_c.is_finite() {
                assert_eq!(a.temperature_c, b.temperature_c);
            }
        }
        assert_eq!(r.gaps.count(), 0);
        assert!((r.gaps.median_dt_s - 0.005).abs() < 1e-9);
        assert!((r.mean_rate_hz() - 200.0).abs() < 1e-6);
        // 7 columns without temperature, 8 with.
        if !name.ends_with(".gz") {
            let text = std::fs::read_to_string(&p).unwrap();
            let nf = text.lines().next().unwrap().split_whitespace().count();
            assert_eq!(nf, if with_temp { 8 } else { 7 });
        }
    }
    // The gzip file is really compressed (magic bytes).
    let raw = std::fs::read(tmp(&dir, "b.txt.gz")).unwrap();
    assert_eq!(&raw[..2], &[0x1f, 0x8b]);
}

#[test]
fn imu_text_reader_accepts_commas_comments_blank_lines_and_gzip_under_any_name() {
    let dir = tempfile::tempdir().unwrap();
    let p = tmp(&dir, "imu.csv");
    write_str(
        &p,
        "# header comment\n% another\n\n1.0, 0.1, 0.2, 0.3, 1, 2, 3\r\n  \n2.0,0.1,0.2,0.3,1,2,3,21.5,\n",
    );
    let r = read_imu_text(&p).unwrap();
    assert_eq!(r.samples.len(), 2);
    assert_eq!(r.samples[0].dtheta_rad, [0.1, 0.2, 0.3]);
    assert!(r.samples[0].temperature_c.is_nan());
    assert_eq!(r.samples[1].temperature_c, 21.5);
    // gzip detected by magic bytes, not by name
    let pz = tmp(&dir, "imu_noext");
    let mut e = flate2::write::GzEncoder::new(
        std::fs::File::create(&pz).unwrap(),
        flate2::Compression::fast(),
    );
    e.write_all(b"1 0 0 0 0 0 9.8\n2 0 0 0 0 0 9.8\n").unwrap();
    e.finish().unwrap();
    let r = read_imu_text(&pz).unwrap();
    assert_eq!(r.samples.len(), 2);
    assert_eq!(r.samples[1].dv_mps[2], 9.8);
}

fn err_of(content: &str, f: impl Fn(&Path) -> Result<(), IoError>) -> (IoError, String) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad_input.txt");
    write_str(&p, content);
    let e = f(&p).expect_err("malformed input must be an error");
    let msg = e.to_string();
    assert!(
        msg.contains("bad_input.txt"),
        "message must name the file: {msg}"
    );
    (e, msg)
}

fn imu(p: &Path) -> Result<(), IoError> {
    read_imu_text(p).map(|_| ())
}
fn gnss(p: &Path) -> Result<(), IoError> {
    read_gnss_text(p).map(|_| ())
}
fn nav(p: &Path) -> Result<(), IoError> {
    read_nav_text(p).map(|_| ())
}

#[test]
fn imu_text_truncated_line_names_file_line_and_missing_column() {
    let (e, msg) = err_of("1 0 0 0 0 0 0\n# c\n2 0 0 0 0\n", imu);
    assert!(
        matches!(
            e,
            IoError::TooFewFields {
                line: 3,
                column: 6,
                found: 5,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        msg.contains("line 3") && msg.contains("column 6") && msg.contains("dv_y_mps"),
        "{msg}"
    );
    assert!(msg.contains("truncated"), "{msg}");
}

#[test]
fn imu_text_text_in_number_column_names_line_and_column() {
    let (e, msg) = err_of("1 0 0 0 0 0 0\n2 0 0 abc 0 0 0\n", imu);
    assert!(
        matches!(
            e,
            IoError::NotANumber {
                line: 2,
                column: 4,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        msg.contains("line 2, column 4 (dtheta_z_rad)") && msg.contains("abc"),
        "{msg}"
    );
}

#[test]
fn imu_text_nan_and_inf_are_errors_but_nan_temperature_means_absent() {
    let (e, msg) = err_of("1 0 0 0 0 0 0\n2 0 NaN 0 0 0 0\n", imu);
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: 2,
                column: 3,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(msg.contains("not finite"), "{msg}");
    let (e, _) = err_of("1 0 0 0 0 0 inf\n", imu);
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: 1,
                column: 7,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, _) = err_of("1 0 0 0 0 0 0 -inf\n", imu);
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: 1,
                column: 8,
                ..
            }
        ),
        "{e:?}"
    );
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.txt");
    write_str(&p, "1 0 0 0 0 0 0 nan\n2 0 0 0 0 0 0 20\n");
    let r = read_imu_text(&p).unwrap();
    assert!(r.samples[0].temperature_c.is_nan());
    assert_eq!(r.samples[1].temperature_c, 20.0);
}

#[test]
fn imu_text_non_monotonic_time_names_both_lines() {
    // a time going back (an exact repeat of a line is skipped and counted instead)
    let (e, msg) = err_of("1 0 0 0 0 0 0\n2 0 0 0 0 0 0\n\n1.5 0 0 0 0 0 0\n", imu);
    assert!(
        matches!(
            e,
            IoError::NonMonotonicTime {
                line: 4,
                column: 1,
                prev_line: 2,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        msg.contains("non-monotonic") && msg.contains("line 4, column 1"),
        "{msg}"
    );
    let (e, _) = err_of("1 0 0 0 0 0 0\n0.5 0 0 0 0 0 0\n", imu);
    assert!(
        matches!(e, IoError::NonMonotonicTime { line: 2, .. }),
        "{e:?}"
    );
}

#[test]
fn imu_text_too_many_fields_is_an_error() {
    let (e, msg) = err_of("1 0 0 0 0 0 0 20 99\n", imu);
    assert!(
        matches!(
            e,
            IoError::TooManyFields {
                line: 1,
                column: 9,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(msg.contains("column 9"), "{msg}");
}

#[test]
fn imu_text_time_gaps_are_counted_located_and_not_filled() {
    // 100 Hz with a 0.5 s hole after t = 1.00 and a 0.03 s hole after t = 2.00
    let mut s = String::new();
    let mut times = Vec::new();
    let mut t: f64 = 0.0;
    while t < 3.0 - 1e-9 {
        let tt = (t * 100.0).round() / 100.0;
        let skip = (tt > 1.0 + 1e-9 && tt < 1.5 - 1e-9) || (tt > 2.0 + 1e-9 && tt < 2.03 - 1e-9);
        if !skip {
            times.push(tt);
            s.push_str(&format!("{tt} 0 0 0 0 0 -0.0981\n"));
        }
        t += 0.01;
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("gappy.txt");
    write_str(&p, &s);
    let r = read_imu_text(&p).unwrap();
    assert_eq!(r.samples.len(), times.len(), "no samples invented");
    assert_eq!(r.gaps.count(), 2);
    assert!((r.gaps.median_dt_s - 0.01).abs() < 1e-12);
    let g0 = &r.gaps.gaps[0];
    assert!((g0.t_before_s - 1.0).abs() < 1e-12 && (g0.t_after_s - 1.5).abs() < 1e-12);
    assert!((g0.missing_s - 0.49).abs() < 1e-9);
    assert_eq!(
        g0.line,
        g0.index + 1,
        "line of the sample after the gap (no comments here)"
    );
    let g1 = &r.gaps.gaps[1];
    assert!((g1.interval_s() - 0.03).abs() < 1e-9);
    assert!((r.gaps.total_missing_s - (0.49 + 0.02)).abs() < 1e-9);
    let shown = r.gaps.to_string();
    assert!(shown.contains("2 time gap(s)"), "{shown}");
}

fn fixes(n: usize) -> Vec<GnssFix> {
    (0..n)
        .map(|k| {
            let x = k as f64;
            GnssFix {
                t_s: 243258.5 + 0.25 * x,
                lat_rad: (40.0966268 + 1e-7 * x).to_radians(),
                lon_rad: (-105.1474483 - 3e-8 * x).to_radians(),
                h_m: 1601.474 + 0.001 * x,
                pos_std_ned_m: [0.0098995, 0.0098995, 0.01],
                vel_ned_mps: [0.01 * x, -0.002, 0.009],
                vel_std_ned_mps: [0.0586899, 0.0586899, 0.0586899],
                has_velocity: k % 2 == 0,
                quality: FixQuality::Single,
                num_sats: 0,
            }
        })
        .collect()
}

#[test]
fn gnss_text_round_trip_with_and_without_velocity_within_1e_15_rad() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["g.txt", "g.txt.gz"] {
        let f = fixes(200);
        let p = dir.path().join(name);
        write_gnss_text(&p, &f).unwrap();
        let r = read_gnss_text(&p).unwrap();
        assert_eq!(r.len(), f.len());
        for (a, b) in f.iter().zip(&r) {
            assert_eq!(a.t_s, b.t_s);
            assert!((a.lat_rad - b.lat_rad).abs() < 1e-15);
            assert!((a.lon_rad - b.lon_rad).abs() < 1e-15);
            assert_eq!(a.h_m, b.h_m);
            assert_eq!(a.pos_std_ned_m, b.pos_std_ned_m);
            assert_eq!(a.has_velocity, b.has_velocity);
            if a.has_velocity {
                assert_eq!(a.vel_ned_mps, b.vel_ned_mps);
                assert_eq!(a.vel_std_ned_mps, b.vel_std_ned_mps);
            }
            assert!(b.is_valid());
        }
    }
}

#[test]
fn gnss_text_malformed_lines_give_located_errors() {
    let good = "1 40 -105 1600 0.01 0.01 0.02\n";
    let (e, _) = err_of(&format!("{good}2 40 -105 1600 0.01 0.01\n"), gnss);
    assert!(
        matches!(
            e,
            IoError::TooFewFields {
                line: 2,
                column: 7,
                ..
            }
        ),
        "{e:?}"
    );
    // 10 fields: an incomplete velocity block
    let (e, msg) = err_of(
        &format!("{good}2 40 -105 1600 0.01 0.01 0.02 1 2 3\n"),
        gnss,
    );
    assert!(
        matches!(
            e,
            IoError::TooFewFields {
                line: 2,
                column: 11,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(msg.contains("std_vn_mps"), "{msg}");
    let (e, _) = err_of(&format!("{good}2 40 x -105 0.01 0.01 0.02\n"), gnss);
    assert!(
        matches!(
            e,
            IoError::NotANumber {
                line: 2,
                column: 3,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, _) = err_of(&format!("{good}2 40 -105 nan 0.01 0.01 0.02\n"), gnss);
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: 2,
                column: 4,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, _) = err_of(&format!("{good}1 40 -105 1600 0.01 0.01 0.02\n"), gnss);
    assert!(
        matches!(e, IoError::NonMonotonicTime { line: 2, .. }),
        "{e:?}"
    );
    let (e, msg) = err_of("1 95 -105 1600 0.01 0.01 0.02\n", gnss);
    assert!(
        matches!(
            e,
            IoError::InvalidValue {
                line: 1,
                column: 2,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(msg.contains("latitude"), "{msg}");
    let (e, _) = err_of("1 45 -105 1600 0.01 -0.01 0.02\n", gnss);
    assert!(
        matches!(
            e,
            IoError::InvalidValue {
                line: 1,
                column: 6,
                ..
            }
        ),
        "{e:?}"
    );
}

fn navs(n: usize) -> Vec<NavSolution> {
    (0..n)
        .map(|k| {
            let x = k as f64;
            NavSolution {
                week: 2374,
                t_s: 604799.0 + 0.005 * x - if k > 100 { 604800.0 } else { 0.0 },
                lat_rad: (30.4447873701 + 1e-9 * x).to_radians(),
                lon_rad: (114.4718632047 + 2e-9 * x).to_radians(),
                h_m: 20.899 + 1e-4 * x,
                vel_ned_mps: [1.0 + x, -0.5, 0.01],
                rpy_rad: [
                    0.0149,
                    -0.0355,
                    (185.70235133f64 - 360.0).to_radians() + 1e-6 * x,
                ],
                pos_std_ned_m: [f64::NAN; 3],
                vel_std_ned_mps: [f64::NAN; 3],
                att_std_rad: [f64::NAN; 3],
                status: 0,
            }
        })
        .map(|mut s| {
            if s.t_s < 604000.0 {
                s.week += 1;
            }
            s
        })
        .collect()
}

#[test]
fn nav_text_round_trip_across_a_week_rollover_within_a_micrometre() {
    let dir = tempfile::tempdir().unwrap();
    let f = navs(300);
    let p = dir.path().join("nav.txt");
    write_nav_text(&p, &f).unwrap();
    let r = read_nav_text(&p).unwrap();
    assert_eq!(r.len(), f.len());
    let r_e = 6.4e6;
    for (a, b) in f.iter().zip(&r) {
        assert_eq!(a.week, b.week);
        assert_eq!(a.t_s, b.t_s);
        assert!((a.lat_rad - b.lat_rad).abs() * r_e < 1e-6);
        assert!((a.lon_rad - b.lon_rad).abs() * r_e < 1e-6);
        assert!((a.lat_rad - b.lat_rad).abs() < 1e-15);
        assert_eq!(a.h_m, b.h_m);
        assert_eq!(a.vel_ned_mps, b.vel_ned_mps);
        for k in 0..3 {
            assert!((a.rpy_rad[k] - b.rpy_rad[k]).abs() < 1e-15);
        }
    }
    // lat/lon to 1e-10 deg or better: the file holds at least 10 decimals for them
    let line = std::fs::read_to_string(&p)
        .unwrap()
        .lines()
        .nth(7)
        .unwrap()
        .to_string();
    let lat = line.split_whitespace().nth(2).unwrap();
    assert!(lat.split('.').nth(1).unwrap().len() >= 10, "{line}");
}

#[test]
fn nav_text_reader_streams_what_read_nav_text_loads_and_reads_on_after_a_bad_line() {
    let dir = tempfile::tempdir().unwrap();
    let f = navs(300);
    let p = dir.path().join("nav.txt.gz");
    write_nav_text(&p, &f).unwrap();
    let whole = read_nav_text(&p).unwrap();
    let streamed: Vec<NavSolution> = NavTextReader::open(&p)
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(whole.len(), 300);
    // the same records (the standard deviations are NaN: compared by their debug text)
    assert_eq!(streamed.len(), whole.len());
    assert!(
        format!("{streamed:?}") == format!("{whole:?}"),
        "the streamed records differ from the loaded ones"
    );
    // the records before a bad line, its located error, then the records after it (a caller
    // may skip the bad record); loading the whole file stops at the error
    let bad = dir.path().join("bad.txt");
    write_str(
        &bad,
        "2374 100 30 114 20 0 0 0 1 2 3\n2374 100.5 30 114 20 0 0 0 1 2 3\n\
         2374 100.2 30 114 20 0 0 0 1 2 3\n2374 101 30 114 20 0 0 0 1 2 3\n",
    );
    let mut rd = NavTextReader::open(&bad).unwrap();
    assert_eq!(rd.path(), bad.as_path());
    assert_eq!(rd.next().unwrap().unwrap().t_s, 100.0);
    assert_eq!(rd.next().unwrap().unwrap().t_s, 100.5);
    let e = rd.next().unwrap().unwrap_err();
    assert!(
        matches!(e, IoError::NonMonotonicTime { line: 3, .. }),
        "{e:?}"
    );
    assert_eq!(rd.next().unwrap().unwrap().t_s, 101.0);
    assert!(rd.next().is_none());
    assert!(matches!(
        read_nav_text(&bad),
        Err(IoError::NonMonotonicTime { line: 3, .. })
    ));
}

#[test]
fn nav_text_malformed_lines_give_located_errors() {
    let good = "2374 100 30 114 20 0 0 0 1 2 3\n";
    let (e, _) = err_of(&format!("{good}2374 101 30 114 20 0 0 0 1 2\n"), nav);
    assert!(
        matches!(
            e,
            IoError::TooFewFields {
                line: 2,
                column: 11,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, msg) = err_of(&format!("{good}2374.5 101 30 114 20 0 0 0 1 2 3\n"), nav);
    assert!(
        matches!(
            e,
            IoError::InvalidValue {
                line: 2,
                column: 1,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(msg.contains("week"), "{msg}");
    let (e, _) = err_of(&format!("{good}2374 101 30 114 20 0 0 0 1 2 yaw\n"), nav);
    assert!(
        matches!(
            e,
            IoError::NotANumber {
                line: 2,
                column: 11,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, _) = err_of(&format!("{good}2374 101 30 114 20 0 NaN 0 1 2 3\n"), nav);
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: 2,
                column: 7,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, _) = err_of(&format!("{good}2374 99 30 114 20 0 0 0 1 2 3\n"), nav);
    assert!(
        matches!(
            e,
            IoError::NonMonotonicTime {
                line: 2,
                column: 2,
                ..
            }
        ),
        "{e:?}"
    );
    // a new week with a small sow is later, not earlier
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("n.txt");
    write_str(&p, &format!("{good}2375 1 30 114 20 0 0 0 1 2 3\n"));
    assert_eq!(read_nav_text(&p).unwrap().len(), 2);
}

#[test]
fn missing_file_is_an_open_error_naming_the_file() {
    let e = read_imu_text("/nonexistent/dir/imu.txt").unwrap_err();
    assert!(matches!(e, IoError::Open { .. }));
    assert!(e.to_string().contains("/nonexistent/dir/imu.txt"));
}

#[test]
fn binary_and_non_utf8_input_is_an_error_not_a_panic() {
    let (e, _) = err_of("1 0 0 0 0 0 0\n", |p| {
        std::fs::write(p, b"1 0 0 0 0 0 0\n\xff\xfe\x00\x01 0 0\n").unwrap();
        imu(p)
    });
    assert!(matches!(e, IoError::NotText { line: 2, .. }), "{e:?}");
    // a truncated gzip stream
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("cut.gz");
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    for k in 0..2000 {
        writeln!(enc, "{} 0 0 0 0 0 9.8", k + 1).unwrap();
    }
    let bytes = enc.finish().unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let e = read_imu_text(&p).unwrap_err();
    assert!(matches!(e, IoError::Read { .. }), "{e:?}");
}

#[test]
fn imu_binary_format_round_trips_and_reports_truncation_nan_and_time_order() {
    let dir = tempfile::tempdir().unwrap();
    let s = imu_samples(300, false);
    for name in ["imu.bin", "imu.bin.gz"] {
        let p = dir.path().join(name);
        write_imu_bin(&p, &s).unwrap();
        let r = read_imu_bin(&p).unwrap();
        assert_eq!(r.samples.len(), 300);
        for (a, b) in s.iter().zip(&r.samples) {
            assert_eq!(
                (a.t_s, a.dtheta_rad, a.dv_mps),
                (b.t_s, b.dtheta_rad, b.dv_mps)
            );
        }
        assert_eq!(r.gaps.count(), 0);
    }
    let p = dir.path().join("bad.bin");
    write_imu_bin(&p, &s[..3]).unwrap();
    let mut bytes = std::fs::read(&p).unwrap();
    // truncated third record
    std::fs::write(&p, &bytes[..2 * 56 + 20]).unwrap();
    let e = read_imu_bin(&p).unwrap_err();
    assert!(matches!(e, IoError::Format { line: 3, .. }), "{e:?}");
    assert!(e.to_string().contains("truncated"), "{e}");
    // NaN in record 2, field 5
    bytes[56 + 4 * 8..56 + 5 * 8].copy_from_slice(&f64::NAN.to_le_bytes());
    std::fs::write(&p, &bytes).unwrap();
    let e = read_imu_bin(&p).unwrap_err();
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: 2,
                column: 5,
                ..
            }
        ),
        "{e:?}"
    );
    // time going backwards in record 3
    write_imu_bin(&p, &[s[0], s[2], s[1]]).unwrap();
    let e = read_imu_bin(&p).unwrap_err();
    assert!(
        matches!(
            e,
            IoError::NonMonotonicTime {
                line: 3,
                prev_line: 2,
                ..
            }
        ),
        "{e:?}"
    );
}

/// `ImuSample::to_values` / `from_values` give the sample back bit for bit (a NaN temperature
/// too), and `same_sample` compares those 8 values: bit for bit, any two NaN temperatures equal.
#[test]
fn imu_sample_values_round_trip_and_same_sample_compares_them() {
    use nav_io::text::same_sample;
    for s in imu_samples(50, true)
        .into_iter()
        .chain(imu_samples(50, false))
    {
        let v = s.to_values();
        assert_eq!(v[0].to_bits(), s.t_s.to_bits());
        assert_eq!(v[7].to_bits(), s.temperature_c.to_bits());
        let back = ImuSample::from_values(v);
        assert_eq!(back.to_values().map(f64::to_bits), v.map(f64::to_bits));
        assert!(same_sample(&s, &back));
    }
    // a sample with a temperature (every third has none)
    let a = imu_samples(2, true)[1];
    assert!(a.has_temperature());
    for i in 0..8 {
        let mut v = a.to_values();
        v[i] = f64::from_bits(v[i].to_bits() ^ 1);
        assert!(!same_sample(&a, &ImuSample::from_values(v)), "value {i}");
    }
    // -0.0 and 0.0 differ in bits: not the same record
    let mut v = a.to_values();
    v[4] = 0.0;
    let z = ImuSample::from_values(v);
    v[4] = -0.0;
    assert!(!same_sample(&z, &ImuSample::from_values(v)));
    // two absent temperatures (NaNs of different bits) are equal
    let mut v = a.to_values();
    v[7] = f64::NAN;
    let n1 = ImuSample::from_values(v);
    v[7] = f64::from_bits(f64::NAN.to_bits() | 1);
    assert!(same_sample(&n1, &ImuSample::from_values(v)));
}
