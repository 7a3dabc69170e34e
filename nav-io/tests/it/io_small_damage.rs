//! Small damage in input files, the way a broken logger or a careless edit leaves it: a UTF-8
//! byte-order mark, a half-written last line, an exact duplicate IMU line, a bad truth line,
//! and configuration errors that must name the file and line (never "line 0").

use nav_io::text::{is_line_error, same_sample};
use nav_io::{
    incomplete_last_line, read_gnss_text, read_imu_csv, read_imu_text, read_nav_text,
    read_run_config, GnssTextReader, ImuCsvIncrements, ImuTextReader, IoError, NavTextReader,
};
use std::path::{Path, PathBuf};

const IMU: &str = "100.00 1e-5 2e-5 3e-5 0.001 0.002 -0.098\n\
                   100.01 1e-5 2e-5 3e-5 0.001 0.002 -0.098\n\
                   100.02 1e-5 2e-5 3e-5 0.001 0.002 -0.097\n";
const GNSS: &str = "100 30.5 114.3 20 0.1 0.1 0.2\n101 30.5 114.3 20 0.1 0.1 0.2\n";
const NAV: &str = "2300 100 30.5 114.3 20 0 0 0 0 0 30\n2300 101 30.5 114.3 20 0 0 0 0 0 30\n\
                   2300 102 30.5 114.3 20 0 0 0 0 0 30\n";

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_utf8_byte_order_mark_is_accepted() {
    let d = tempfile::tempdir().unwrap();
    let bom = "\u{feff}";
    let imu = read_imu_text(write(d.path(), "imu.txt", &format!("{bom}{IMU}"))).unwrap();
    assert_eq!(imu.samples.len(), 3);
    assert_eq!(imu.samples[0].t_s, 100.0);
    let g = read_gnss_text(write(d.path(), "g.txt", &format!("{bom}{GNSS}"))).unwrap();
    assert_eq!(g.len(), 2);
    let n = read_nav_text(write(d.path(), "t.nav", &format!("{bom}{NAV}"))).unwrap();
    assert_eq!(n.len(), 3);
    // a BOM before a comment line, and in a CSV with a header
    let imu = read_imu_text(write(d.path(), "c.txt", &format!("{bom}# t ...\n{IMU}"))).unwrap();
    assert_eq!(imu.samples.len(), 3);
    let fmt = nav_io::ImuCsvFormat {
        skip_lines: 1,
        ..csv_format()
    };
    let csv = format!("{bom}t,gx,gy,gz,ax,ay,az\n100,0,0,0,0,0,-9.8\n100.01,0,0,0,0,0,-9.8\n");
    let r = read_imu_csv(write(d.path(), "i.csv", &csv), &fmt).unwrap();
    assert_eq!(r.samples.len(), 1);
    // only at the start: elsewhere it is not a number
    let e = read_imu_text(write(
        d.path(),
        "m.txt",
        &format!("{IMU}{bom}100.03 0 0 0 0 0 0\n"),
    ))
    .unwrap_err();
    assert_eq!(e.line(), Some(4), "{e}");
}

fn csv_format() -> nav_io::ImuCsvFormat {
    let text = "[imu]\npath = \"i.csv\"\nformat = \"csv\"\n[imu.csv]\nskip_lines = 0\n\
                gyro_unit = \"rad/s\"\naccel_unit = \"m/s^2\"\nconvention = \"interval_mean\"\n\
                [imu.csv.columns]\ntime = 1\ngyro = [2, 3, 4]\naccel = [5, 6, 7]\n\
                [imu.csv.time]\nkind = \"seconds\"\n";
    let cfg = format!(
        "name = \"c\"\n{text}[gnss]\npath = \"g.txt\"\nformat = \"text\"\n[init]\n\
         pos_std_m = [1.0, 1.0, 1.0]\nvel_std_mps = [0.1, 0.1, 0.1]\n\
         att_std_deg = [1.0, 1.0, 1.0]\n[init.align]\nstatic_s = 10.0\n[noise]\nmodel = \"n\"\n\
         [noise.accel]\nn_ug_per_sqrt_hz = 100.0\n[noise.gyro]\nn_deg_per_s_per_sqrt_hz = 0.005\n"
    );
    nav_io::parse_run_config(Path::new("run.toml"), &cfg)
        .unwrap()
        .imu
        .csv
        .unwrap()
}

#[test]
fn a_half_written_last_line_ends_the_file_and_is_named() {
    let d = tempfile::tempdir().unwrap();
    for cut in [
        "100.03 1e-5 2e-",
        "100.03 1e-5 2e-5 3e-5 0.001",
        "100.0",
        "1",
    ] {
        let p = write(d.path(), "imu.txt", &format!("{IMU}{cut}"));
        let r = read_imu_text(&p).unwrap_or_else(|e| panic!("{cut:?}: {e}"));
        assert_eq!(r.samples.len(), 3, "{cut:?}");
        let inc = incomplete_last_line(&p).unwrap().expect("named");
        assert_eq!(inc.offset as usize, IMU.len());
        assert_eq!(inc.line, 4);
        let at = format!("imu.txt: line 4, the last line (byte offset {})", IMU.len());
        assert!(inc.to_string().contains(&at), "{inc}");
        assert!(inc.to_string().contains("still being written"), "{inc}");
    }
    // a complete last line without a line end is read and not named
    let p = write(d.path(), "imu.txt", IMU.trim_end());
    assert_eq!(read_imu_text(&p).unwrap().samples.len(), 3);
    assert_eq!(incomplete_last_line(&p).unwrap(), None);
    // a bad line that ends with a line end is still an error, naming file, line and column
    let p = write(d.path(), "imu.txt", &format!("{IMU}100.03 1e-5 2e-\n"));
    let e = read_imu_text(&p).unwrap_err().to_string();
    assert!(e.contains("imu.txt") && e.contains("line 4"), "{e}");
    // and so is one in the middle of the file, whatever follows it
    let p = write(
        d.path(),
        "imu.txt",
        &format!(
            "{IMU}100.03 1e-5 2x-5 3e-5 0.001 0.002 -0.098\n{}",
            &IMU[..20]
        ),
    );
    let e = read_imu_text(&p).unwrap_err().to_string();
    assert!(
        e.contains("imu.txt") && e.contains("line 4") && e.contains("column 3"),
        "{e}"
    );
    // the line named in a file longer than the 64 KiB read from its end
    let mut long = String::new();
    for k in 0..3000 {
        long.push_str(&format!(
            "{:.2} 1e-5 2e-5 3e-5 0.001 0.002 -0.098\n",
            100.0 + 0.01 * k as f64
        ));
    }
    let p = write(d.path(), "imu.txt", &format!("{long}130.00 1e-5"));
    let inc = incomplete_last_line(&p).unwrap().expect("named");
    assert_eq!((inc.line, inc.offset as usize), (3001, long.len()));
    assert_eq!(read_imu_text(&p).unwrap().samples.len(), 3000);
    // GNSS text, nav text, IMU CSV
    let p = write(d.path(), "g.txt", &format!("{GNSS}102 30.5 114."));
    assert_eq!(read_gnss_text(&p).unwrap().len(), 2);
    assert!(incomplete_last_line(&p).unwrap().is_some());
    let p = write(d.path(), "t.nav", &format!("{NAV}2300 103 30.5"));
    assert_eq!(read_nav_text(&p).unwrap().len(), 3);
    let csv = "100,0,0,0,0,0,-9.8\n100.01,0,0,0,0,0,-9.8\n100.02,0,0,0,0,0,-9.8\n100.03,0,0";
    let p = write(d.path(), "i.csv", csv);
    assert_eq!(read_imu_csv(&p, &csv_format()).unwrap().samples.len(), 2);
    assert_eq!(incomplete_last_line(&p).unwrap().unwrap().fields, 3);
}

#[test]
fn an_exact_duplicate_imu_line_is_passed_on_for_the_run_to_skip() {
    let d = tempfile::tempdir().unwrap();
    let lines: Vec<&str> = IMU.lines().collect();
    let text = format!("{}\n{}\n{}\n{}\n", lines[0], lines[1], lines[1], lines[2]);
    let p = write(d.path(), "imu.txt", &text);
    let got: Vec<_> = ImuTextReader::open(&p)
        .unwrap()
        .map(|r| r.unwrap())
        .collect();
    assert_eq!(got.len(), 4);
    assert!(same_sample(&got[1].0, &got[2].0));
    assert_eq!((got[1].1, got[2].1), (2, 3));
    // the same time with other values is an error naming both lines
    let text = format!(
        "{}\n{}\n{}\n",
        lines[0],
        lines[1],
        lines[1].replace("0.001", "0.002")
    );
    let e = read_imu_text(write(d.path(), "imu2.txt", &text)).unwrap_err();
    assert!(
        e.to_string().contains("line 3") && e.to_string().contains("(line 2)"),
        "{e}"
    );
    // an IMU CSV row written twice gives the previous increment again
    let csv = "100,0,0,0,0,0,-9.8\n100.01,0,0,0.1,0,0,-9.8\n100.01,0,0,0.1,0,0,-9.8\n\
               100.02,0,0,0,0,0,-9.8\n";
    let p = write(d.path(), "i.csv", csv);
    let inc: Vec<_> = ImuCsvIncrements::open(&p, &csv_format())
        .unwrap()
        .map(|r| r.unwrap())
        .collect();
    assert_eq!(inc.len(), 3);
    assert!(same_sample(&inc[0].0, &inc[1].0));
    assert_eq!((inc[0].1, inc[1].1), (2, 3));
    let whole = read_imu_csv(&p, &csv_format()).unwrap();
    assert_eq!(whole.samples.len(), inc.len());
    assert!(whole
        .samples
        .iter()
        .zip(&inc)
        .all(|(a, b)| same_sample(a, &b.0)));
}

#[test]
fn a_bad_truth_line_is_an_error_the_reader_reads_on_from() {
    let d = tempfile::tempdir().unwrap();
    let bad = NAV.replacen("2300 101 30.5", "2300 101 x30.5", 1);
    let p = write(d.path(), "t.nav", &bad);
    let got: Vec<_> = NavTextReader::open(&p).unwrap().collect();
    assert_eq!(got.len(), 3);
    let e = got[1].as_ref().unwrap_err();
    assert!(is_line_error(e));
    assert_eq!((e.line(), e.column()), (Some(2), Some(3)));
    assert_eq!(got[2].as_ref().unwrap().t_s, 102.0);
    // the whole-file reader still stops there
    assert!(read_nav_text(&p).is_err());
    // a GNSS reader still stops at the first error
    let p = write(d.path(), "g.txt", &GNSS.replacen("101 30.5", "101 x", 1));
    assert_eq!(GnssTextReader::open(&p).unwrap().count(), 2);
}

#[test]
fn no_error_says_line_0() {
    let e = IoError::Format {
        path: "log.nmea".into(),
        line: 0,
        message: "no RMC sentence with a date".into(),
    };
    assert_eq!(e.to_string(), "log.nmea: no RMC sentence with a date");
    assert_eq!(e.line(), None);
    let e = IoError::Read {
        path: "log.ubx".into(),
        line: 0,
        source: std::io::Error::other("boom"),
    };
    assert_eq!(e.to_string(), "log.ubx: read error: boom");
    let e = IoError::Format {
        path: "a.txt".into(),
        line: 7,
        message: "m".into(),
    };
    assert_eq!(e.to_string(), "a.txt: line 7: m");
    // NMEA and UBX logs without a fix
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "log.nmea", "$GPGGA,bad*00\n");
    let e = nav_io::read_nmea_log(&p, &nav_io::GnssLogOptions::default(), 6).unwrap_err();
    assert!(!e.to_string().contains("line 0"), "{e}");
    assert!(e.to_string().contains("log.nmea"), "{e}");
    let p = write(d.path(), "log.ubx", "not ubx");
    let e = nav_io::read_ubx_log(&p, &nav_io::GnssLogOptions::default(), 6).unwrap_err();
    assert!(!e.to_string().contains("line 0"), "{e}");
    assert!(e.to_string().contains("log.ubx"), "{e}");
}

const CFG: &str = "name = \"v\"\n\
[imu]\n\
path = \"imu.txt\"\n\
format = \"text\"\n\
[gnss]\n\
path = \"gnss.txt\"\n\
format = \"text\"\n\
max_q = 2\n\
sigma_scale = 1.0\n\
[init]\n\
pos_std_m = [1.0, 1.0, 2.0]\n\
vel_std_mps = [0.1, 0.1, 0.1]\n\
att_std_deg = [1.0, 1.0, 5.0]\n\
[init.align]\n\
static_s = 10.0\n\
[noise]\n\
model = \"n\"\n\
[noise.accel]\n\
n_ug_per_sqrt_hz = 100.0\n\
[noise.gyro]\n\
n_deg_per_s_per_sqrt_hz = 0.005\n";

#[test]
fn every_configuration_error_names_the_file_and_line() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "run.toml", CFG);
    read_run_config(&p).unwrap();
    // (replacement, the line the error must name)
    let cases = [
        ("max_q = 2", "max_q = 9", 8),
        ("sigma_scale = 1.0", "sigma_scale = -1.0", 9),
        ("sigma_scale = 1.0", "sigma_scale = nan", 9),
        ("format = \"text\"\n[gnss]", "format = \"csv\"\n[gnss]", 4),
        ("max_q = 2", "max_q = 2\ntime_offset_s = inf", 9),
        (
            "pos_std_m = [1.0, 1.0, 2.0]",
            "pos_std_m = [1.0, -1.0, 2.0]",
            11,
        ),
        (
            "att_std_deg = [1.0, 1.0, 5.0]",
            "att_std_deg = [1.0, nan, 5.0]",
            13,
        ),
        ("static_s = 10.0", "static_s = 0.0", 15),
        (
            "static_s = 10.0",
            "static_s = 10.0\nmax_gravity_mismatch_mps2 = -1.0",
            14,
        ),
        (
            "name = \"v\"",
            "name = \"v\"\nstart_s = 5.0\nend_s = 1.0",
            3,
        ),
        (
            "sigma_scale = 1.0",
            "sigma_scale = 1.0\n[gnss.log]\nleap_seconds = 18",
            10,
        ),
        (
            "[gnss]\npath",
            "[imu.mounting]\nrpy_deg = [0.0, nan, 0.0]\n[gnss]\npath",
            5,
        ),
        // syntax and type errors: the TOML reader's line and column
        ("max_q = 2", "max_q = \"two\"", 8),
        ("static_s = 10.0", "static_s = 10.0.0", 15),
        ("model = \"n\"", "model = \"n\"\nbogus = 1", 18),
    ];
    let mut named = 0;
    for (from, to, line) in cases {
        assert!(CFG.contains(from), "{from}");
        let p = write(d.path(), "run.toml", &CFG.replacen(from, to, 1));
        let e = read_run_config(&p).unwrap_err();
        let m = e.to_string();
        assert!(m.starts_with(&p.display().to_string()), "{to:?}: {m}");
        assert!(
            m.contains(&format!("line {line}")),
            "{to:?}: line {line} not named: {m}"
        );
        assert!(!m.contains("line 0"), "{m}");
        named += 1;
    }
    assert_eq!(named, cases.len());
}
