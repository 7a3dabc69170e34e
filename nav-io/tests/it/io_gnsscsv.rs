//! The generic GNSS CSV/text reader (`[gnss.csv]`): golden files written by the tests for every
//! time format, two users' files (rover text lines with a date-time stamp and a fix
//! name; u-blox CSV with speed and bearing and no accuracy), missing sigmas, the quality
//! filter, and malformed input named by file, line and column.

use nav_core::types::FixQuality;
use nav_io::gpstime::gpst_week_sow;
use nav_io::{parse_run_config, read_gnss_csv, GnssCsvFormat, GnssFileKind, IoError, RunConfig};
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn fmt(toml_text: &str) -> GnssCsvFormat {
    toml::from_str(toml_text).unwrap()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// Story 1: a rover's RTK lines `2015_11_26_15_00_02_617 RTK_FIXED lat lon h sN sE sD`.
const ROVER: &str = "\
2015_11_26_15_00_02_617 RTK_FIXED 40.0123456789 -105.2345678901 1650.123 0.012 0.013 0.030
2015_11_26_15_00_05_617 RTK_FLOAT 40.0123466789 -105.2345668901 1650.223 0.112 0.113 0.230
2015_11_26_15_00_08_617 RTK_FIXED 40.0123476789 -105.2345658901 1650.323 0.014 0.015 0.031
2015_11_26_15_00_11_617 SINGLE 40.0123486789 -105.2345648901 1652.000 1.5 1.5 3.0
";

const ROVER_FMT: &str = r#"
[columns]
time = 1
lat = 3
lon = 4
h = 5
sigma_ned = [6, 7, 8]
[time]
kind = "text"
format = "%Y_%m_%d_%H_%M_%S_%3f"
scale = "gps"
[quality]
column = 2
accept = ["RTK_FIXED", "rtk_float"]
"#;

#[test]
fn rover_text_lines_with_date_time_and_fix_names() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "rover.txt", ROVER);
    let r = read_gnss_csv(&p, &fmt(ROVER_FMT)).unwrap();
    assert_eq!(r.fixes.len(), 3, "SINGLE is not accepted");
    assert_eq!(r.dropped_by_quality, 1);
    assert_eq!(r.lines, vec![1, 2, 3]);
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    // 2015-11-26 is the Thursday of GPS week 1872 (Sunday 2015-11-22): 4 d 15 h 0 min 2.617 s
    assert_eq!(r.week, Some(1872));
    let sow = 4.0 * 86_400.0 + 15.0 * 3600.0 + 2.617;
    assert!(close(r.fixes[0].t_s, sow, 1e-6), "{}", r.fixes[0].t_s);
    assert_eq!(gpst_week_sow(2015, 11, 26, 15, 0, 2.617).0, 1872);
    assert!(close(r.fixes[2].t_s - r.fixes[0].t_s, 6.0, 1e-6));
    let f = &r.fixes[0];
    assert_eq!(f.quality, FixQuality::RtkFixed);
    assert_eq!(r.fixes[1].quality, FixQuality::RtkFloat);
    assert!(close(f.lat_rad.to_degrees(), 40.0123456789, 1e-12));
    assert!(close(f.lon_rad.to_degrees(), -105.2345678901, 1e-12));
    assert_eq!(f.h_m, 1650.123);
    assert_eq!(f.pos_std_ned_m, [0.012, 0.013, 0.030]);
    assert!(!f.has_velocity);
    assert!(r.fixes.iter().all(|f| f.is_valid()));

    // the same stamps read as UTC are 17 leap seconds later in GPS time (2015-07-01 .. 2017)
    let utc = fmt(&ROVER_FMT.replace("scale = \"gps\"", "scale = \"utc\""));
    let r2 = read_gnss_csv(&p, &utc).unwrap();
    assert!(close(r2.fixes[0].t_s - r.fixes[0].t_s, 17.0, 1e-9));
}

/// Story 2: u-blox fixes as CSV with a header, lat, lon, alt, speed, bearing, Unix ms, no
/// accuracy column.
const UBLOX: &str = "\
time_ms,lat,lon,alt,speed,bearing
1700000000000,48.1000000,11.5000000,520.5,15.0,90.0
1700000000100,48.1000000,11.5000203,520.5,15.0,90.0
1700000000200,48.1000000,11.5000406,520.6,15.2,45.0
";

const UBLOX_FMT: &str = r#"
skip_lines = 1
speed_unit = "m/s"
default_sigma_ned_m = [2.0, 2.0, 4.0]
default_vel_sigma_ned_mps = [0.3, 0.3, 0.6]
[columns]
time = "time_ms"
lat = "lat"
lon = "lon"
h = "alt"
speed = "speed"
course = "bearing"
[time]
kind = "unix_ms"
"#;

#[test]
fn ublox_csv_with_speed_bearing_and_no_accuracy() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "fixes.csv", UBLOX);
    let r = read_gnss_csv(&p, &fmt(UBLOX_FMT)).unwrap();
    assert_eq!(r.fixes.len(), 3);
    // 1700000000 s Unix = 2023-11-14 22:13:20 UTC, a Tuesday; GPS week 2288 began Sunday
    // 2023-11-12; GPS = UTC + 18 s
    assert_eq!(r.week, Some(2288));
    let sow = 2.0 * 86_400.0 + 22.0 * 3600.0 + 13.0 * 60.0 + 20.0 + 18.0;
    assert!(close(r.fixes[0].t_s, sow, 1e-9), "{}", r.fixes[0].t_s);
    assert!(close(r.fixes[1].t_s - r.fixes[0].t_s, 0.1, 1e-9));
    // default sigmas, each warned once
    assert_eq!(r.fixes[2].pos_std_ned_m, [2.0, 2.0, 4.0]);
    assert_eq!(r.fixes[2].vel_std_ned_mps, [0.3, 0.3, 0.6]);
    assert_eq!(
        r.warnings
            .iter()
            .filter(|w| w.contains("default_sigma_ned_m"))
            .count(),
        1
    );
    assert_eq!(
        r.warnings
            .iter()
            .filter(|w| w.contains("default_vel_sigma_ned_mps"))
            .count(),
        1
    );
    assert!(r.warnings.iter().any(|w| w.contains("vertical speed")));
    // speed + course -> NED
    let v = r.fixes[0].vel_ned_mps;
    assert!(close(v[0], 0.0, 1e-12) && close(v[1], 15.0, 1e-12) && v[2] == 0.0);
    let v = r.fixes[2].vel_ned_mps;
    let c = 15.2 / 2f64.sqrt();
    assert!(close(v[0], c, 1e-12) && close(v[1], c, 1e-12));
    assert!(r.fixes.iter().all(|f| f.is_valid() && f.has_velocity));
    assert_eq!(r.fixes[0].quality, FixQuality::Single);
}

#[test]
fn every_time_format_gives_the_same_gps_time() {
    // one epoch: 2023-11-14 22:13:38 GPST = 22:13:20 UTC = Unix 1700000000 (UTC)
    // = week 2288, sow 252818
    let sow = 252_818.25;
    let cases: [(&str, &str, &str); 6] = [
        ("gps_sow", "252818.25", "kind = \"gps_sow\""),
        ("week_sow", "2288 252818.25", "kind = \"week_sow\""),
        ("unix_s", "1700000000.25", "kind = \"unix_s\""),
        ("unix_ms", "1700000000250", "kind = \"unix_ms\""),
        (
            "unix_s_gps",
            "1700000018.25",
            "kind = \"unix_s\"\nscale = \"gps\"",
        ),
        (
            "text",
            "2023-11-14T22:13:20.250",
            "kind = \"text\"\nformat = \"%Y-%m-%dT%H:%M:%S%.f\"",
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (name, stamp, time) in cases {
        let week = name == "week_sow";
        let (tcol, first) = if week {
            ("time = 2\nweek = 1", 3)
        } else {
            ("time = 1", 2)
        };
        let text = format!("{stamp} 48.1 11.5 520.0 0.5 0.6 1.2\n");
        let p = write(dir.path(), &format!("{name}.txt"), &text);
        let f = fmt(&format!(
            "[columns]\n{tcol}\nlat = {}\nlon = {}\nh = {}\nsigma_ned = [{}, {}, {}]\n[time]\n{time}\n",
            first,
            first + 1,
            first + 2,
            first + 3,
            first + 4,
            first + 5
        ));
        let r = read_gnss_csv(&p, &f).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            close(r.fixes[0].t_s, sow, 1e-6),
            "{name}: {} vs {sow}",
            r.fixes[0].t_s
        );
        assert_eq!(
            r.week,
            if name == "gps_sow" { None } else { Some(2288) },
            "{name}"
        );
        assert_eq!(r.fixes[0].pos_std_ned_m, [0.5, 0.6, 1.2], "{name}");
    }
}

#[test]
fn week_rollover_keeps_time_increasing() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "roll.txt",
        "2287 604799.5 48.1 11.5 520 1 1 2\n2288 0.5 48.1 11.5 520 1 1 2\n",
    );
    let f = fmt("[columns]\nweek = 1\ntime = 2\nlat = 3\nlon = 4\nh = 5\nsigma_ned = [6, 7, 8]\n[time]\nkind = \"week_sow\"\n");
    let r = read_gnss_csv(&p, &f).unwrap();
    assert_eq!(r.week, Some(2287));
    assert!(close(r.fixes[1].t_s - r.fixes[0].t_s, 1.0, 1e-9));
}

#[test]
fn ecef_horizontal_vertical_accuracy_and_nmea_quality_codes() {
    // ECEF of lat 48.1, lon 11.5, h 520 (WGS-84)
    let (lat, lon, h) = (48.1f64.to_radians(), 11.5f64.to_radians(), 520.0);
    let a = 6_378_137.0;
    let e2 = 6.694_379_990_14e-3;
    let n = a / (1.0 - e2 * lat.sin().powi(2)).sqrt();
    let x = (n + h) * lat.cos() * lon.cos();
    let y = (n + h) * lat.cos() * lon.sin();
    let z = (n * (1.0 - e2) + h) * lat.sin();
    let text = format!(
        "# t, x, y, z, q, hacc, vacc, nsat\n100.0, {x:.4}, {y:.4}, {z:.4}, 4, 0.02, 0.05, 17\n101.0, {x:.4}, {y:.4}, {z:.4}, 0, 0.02, 0.05, 0\n102.0, {x:.4}, {y:.4}, {z:.4}, 1, 2.5, 4.0, 9\n"
    );
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "ecef.csv", &text);
    let f = fmt("[columns]\ntime = 1\necef = [2, 3, 4]\nsigma_h = 6\nsigma_v = 7\nnum_sats = 8\n[time]\nkind = \"gps_sow\"\n[quality]\ncolumn = 5\ncodes = \"nmea\"\n");
    let r = read_gnss_csv(&p, &f).unwrap();
    assert_eq!(r.fixes.len(), 2, "quality 0 (invalid) dropped");
    assert_eq!(r.dropped_by_quality, 1);
    assert_eq!(r.fixes[0].quality, FixQuality::RtkFixed);
    assert_eq!(r.fixes[1].quality, FixQuality::Single);
    assert!(close(r.fixes[0].lat_rad, lat, 1e-9) && close(r.fixes[0].lon_rad, lon, 1e-9));
    assert!(close(r.fixes[0].h_m, h, 1e-3));
    assert_eq!(r.fixes[0].pos_std_ned_m, [0.02, 0.02, 0.05]);
    assert_eq!(r.fixes[1].pos_std_ned_m, [2.5, 2.5, 4.0]);
    assert_eq!((r.fixes[0].num_sats, r.fixes[1].num_sats), (17, 9));
}

#[test]
fn missing_sigmas_without_a_default_is_a_config_error_that_says_what_to_state() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "fixes.csv", UBLOX);
    let no_default = UBLOX_FMT.replace("default_sigma_ned_m = [2.0, 2.0, 4.0]\n", "");
    let e = read_gnss_csv(&p, &fmt(&no_default)).unwrap_err();
    assert!(matches!(e, IoError::Config { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("fixes.csv") && msg.contains("default_sigma_ned_m"),
        "{msg}"
    );
    let no_vel_default = UBLOX_FMT.replace("default_vel_sigma_ned_mps = [0.3, 0.3, 0.6]\n", "");
    let e = read_gnss_csv(&p, &fmt(&no_vel_default)).unwrap_err();
    assert!(e.to_string().contains("default_vel_sigma_ned_mps"), "{e}");
    let zero = UBLOX_FMT.replace("[2.0, 2.0, 4.0]", "[2.0, 0.0, 4.0]");
    let e = read_gnss_csv(&p, &fmt(&zero)).unwrap_err();
    assert!(e.to_string().contains("> 0"), "{e}");
}

fn malformed(text: &str, f: &str) -> IoError {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "bad.txt", text);
    read_gnss_csv(&p, &fmt(f)).unwrap_err()
}

#[test]
fn malformed_input_names_file_line_and_column() {
    // a word where the latitude should be, on line 3
    let bad_lat = ROVER.replacen("40.0123476789", "forty", 1);
    let e = malformed(&bad_lat, ROVER_FMT);
    assert_eq!((e.line(), e.column()), (Some(3), Some(3)), "{e}");
    assert!(
        e.to_string().contains("bad.txt") && e.to_string().contains("lat"),
        "{e}"
    );
    // a time stamp that does not match the format, line 2
    let bad_time = ROVER.replacen("2015_11_26_15_00_05_617", "2015-11-26T15:00:05", 1);
    let e = malformed(&bad_time, ROVER_FMT);
    assert_eq!((e.line(), e.column()), (Some(2), Some(1)), "{e}");
    assert!(e.to_string().contains("format"), "{e}");
    // a truncated line: the sigma_d column is missing on line 4
    let truncated = ROVER
        .replacen(" 1.5 1.5 3.0", " 1.5 1.5", 1)
        .replace("SINGLE", "RTK_FIXED");
    let e = malformed(&truncated, ROVER_FMT);
    assert_eq!((e.line(), e.column()), (Some(4), Some(8)), "{e}");
    // an unknown quality name not in accept
    let unknown = ROVER.replacen("SINGLE", "WEIRD_MODE", 1);
    let e = malformed(&unknown, ROVER_FMT);
    assert_eq!((e.line(), e.column()), (Some(4), Some(2)), "{e}");
    assert!(e.to_string().contains("accept"), "{e}");
    // a negative sigma
    let neg = ROVER.replacen("0.013", "-0.013", 1);
    let e = malformed(&neg, ROVER_FMT);
    assert_eq!((e.line(), e.column()), (Some(1), Some(7)), "{e}");
    // time going backwards
    let back = "100 48.1 11.5 520 1 1 2\n99 48.1 11.5 520 1 1 2\n";
    let e = malformed(
        back,
        "[columns]\ntime = 1\nlat = 2\nlon = 3\nh = 4\nsigma_ned = [5, 6, 7]\n[time]\nkind = \"gps_sow\"\n",
    );
    assert!(
        matches!(e, IoError::NonMonotonicTime { line: 2, .. }),
        "{e}"
    );
    // a column name that is not in the header
    let e = malformed(UBLOX, &UBLOX_FMT.replace("\"bearing\"", "\"heading\""));
    assert!(
        e.to_string().contains("heading") && e.to_string().contains("bearing"),
        "{e}"
    );
}

#[test]
fn run_configuration_reads_a_gnss_csv() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "fixes.csv", UBLOX);
    let imu: String = (0..=300)
        .map(|k| {
            let t = 252_818.0 + k as f64 * 0.01;
            format!("{t:.3} 0 0 0 0 0 -0.0980665\n")
        })
        .collect();
    write(dir.path(), "imu.txt", &imu);
    let mut gnss_section =
        String::from("[gnss]\npath = \"fixes.csv\"\nformat = \"csv\"\n[gnss.csv]\n");
    for l in UBLOX_FMT.lines() {
        let l = l
            .replace("[columns]", "[gnss.csv.columns]")
            .replace("[time]", "[gnss.csv.time]");
        gnss_section.push_str(&l);
        gnss_section.push('\n');
    }
    let cfg_text = format!(
        "[imu]\npath = \"imu.txt\"\nformat = \"text\"\n{gnss_section}\n[init]\npos_std_m = [1, 1, 1]\nvel_std_mps = [1, 1, 1]\natt_std_deg = [1, 1, 5]\n[init.align]\nstatic_s = 1.0\n[noise.accel]\nvrw_mps_per_sqrt_h = 0.1\n[noise.gyro]\narw_deg_per_sqrt_h = 0.3\n"
    );
    let cfg_path = write(dir.path(), "run.toml", &cfg_text);
    let cfg = parse_run_config(&cfg_path, &cfg_text).unwrap();
    assert_eq!(cfg.gnss.format, GnssFileKind::Csv);
    let inp = cfg.load_inputs(dir.path()).unwrap();
    assert_eq!(inp.gnss.len(), 3);
    assert_eq!(inp.gnss_week, Some(2288));
    assert!(inp
        .warnings
        .iter()
        .any(|w| w.contains("default_sigma_ned_m")));
    // round trip through the writer keeps the mapping
    let back: RunConfig = toml::from_str(&toml::to_string_pretty(&cfg).unwrap()).unwrap();
    assert_eq!(back.gnss.csv, cfg.gnss.csv);
    // format = "csv" without the mapping is refused, naming the file
    let no_map = cfg_text.replace(
        &gnss_section,
        "[gnss]\npath = \"fixes.csv\"\nformat = \"csv\"\n",
    );
    let e = parse_run_config(&cfg_path, &no_map).unwrap_err();
    assert!(
        e.to_string().contains("run.toml") && e.to_string().contains("[gnss.csv] mapping"),
        "{e}"
    );
}
