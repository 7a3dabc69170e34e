//! KF-GINS YAML configuration: keys and units as KF-GINS reads them, SI conversions, defaults
//! of the optional initial-std keys, errors with file and position, round trip.

use nav_core::config::FilterConfig;
use nav_io::{parse_kf_gins_yaml, read_kf_gins_yaml, write_kf_gins_yaml, IoError};
use std::path::Path;

/// A configuration in KF-GINS's layout (same keys, comments and flow-style vectors as its
/// dataset/kf-gins.yaml; values of a tactical IMU).
const CFG: &str = r#"
# KF-GINS configuration file
imupath: "./dataset/IMU.txt"
gnsspath: "./dataset/GNSS-RTK.txt"
outputpath: "./dataset"
imudatalen: 7
imudatarate: 200
starttime: 456300
endtime: -1
initpos: [ 30.4447873701, 114.4718632047, 20.899 ]   # [deg, deg, m]
initvel: [ 0.0, 0.0, 0.0 ]
initatt: [ 0.85421502, -2.03480295, 185.70235133 ]
initgyrbias: [ 0, 0, 0 ]    # [deg/h]
initaccbias: [ 0, 0, 0 ]    # [mGal]
initgyrscale: [ 0, 0, 0 ]   # [ppm]
initaccscale: [ 0, 0, 0 ]   # [ppm]
initposstd: [ 0.005, 0.004, 0.008 ]
initvelstd: [ 0.003, 0.004, 0.004 ]
initattstd: [ 0.003, 0.003, 0.023 ]
#initbgstd: [ 1, 1, 1 ]
imunoise:
  arw: [0.003, 0.003, 0.003]          # [deg/sqrt(hr)]
  vrw: [0.03, 0.03, 0.03]             # [m/s/sqrt(hr)]
  gbstd: [0.027, 0.027, 0.027]        # [deg/hr]
  abstd: [15.0, 15.0, 15.0]           # [mGal]
  gsstd: [300.0, 300.0, 300.0]        # [ppm]
  asstd: [300.0, 300.0, 300.0]        # [ppm]
  corrtime: 4.0                       # [hr]
antlever:  [ 0.136, -0.301, -0.184 ]
"#;

fn name() -> &'static Path {
    Path::new("cases/kf-gins.yaml")
}

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

#[test]
fn kf_gins_yaml_is_read_field_for_field_with_si_conversions() {
    let c = parse_kf_gins_yaml(name(), CFG).unwrap();
    assert_eq!(c.imupath, "./dataset/IMU.txt");
    assert_eq!(c.imudatalen, 7);
    assert_eq!(c.imudatarate, 200);
    assert_eq!(c.starttime, 456300.0);
    assert_eq!(c.end_time_s(), None);
    assert_eq!(c.imu_dt_s(), 0.005);
    assert_eq!(c.initpos, [30.4447873701, 114.4718632047, 20.899]);
    let llh = c.init_llh();
    assert!((llh.lat_rad - 30.4447873701f64.to_radians()).abs() < 1e-15);
    assert_eq!(llh.h_m, 20.899);
    assert!((c.init_rpy_rad()[2] - 185.70235133f64.to_radians()).abs() < 1e-15);
    assert!((c.init_att_std_rad()[2] - 0.023f64.to_radians()).abs() < 1e-18);
    assert_eq!(c.antlever, [0.136, -0.301, -0.184]);
    assert!(c.unknown_keys.is_empty(), "{:?}", c.unknown_keys);
    // imunoise in SI, against hand-computed values
    let n = &c.imunoise;
    // 0.003 deg/sqrt(h) = 0.003 * (pi/180) / 60 rad/sqrt(s) = 8.7266e-7
    assert!(rel(n.arw_rad_per_sqrt_s()[0], 8.726_646_259_971_648e-7) < 1e-12);
    // 0.03 m/s/sqrt(h) = 5e-4 m/s/sqrt(s)
    assert!(rel(n.vrw_mps_per_sqrt_s()[1], 5.0e-4) < 1e-12);
    // 0.027 deg/h = 1.309e-7 rad/s
    assert!(
        rel(
            n.gbstd_radps()[2],
            0.027 * std::f64::consts::PI / 180.0 / 3600.0
        ) < 1e-12
    );
    // 15 mGal = 1.5e-4 m/s^2
    assert!(rel(n.abstd_mps2()[0], 1.5e-4) < 1e-12);
    assert!(rel(n.gsstd()[0], 3.0e-4) < 1e-12);
    assert!(rel(n.asstd()[0], 3.0e-4) < 1e-12);
    assert_eq!(n.corrtime_s(), 14_400.0);
    // optional initial bias/scale std default to the noise sigmas (as KF-GINS does)
    assert_eq!(c.init_bg_std_radps(), n.gbstd_radps());
    assert_eq!(c.init_ba_std_mps2(), n.abstd_mps2());
    assert_eq!(c.init_sg_std(), n.gsstd());
    assert_eq!(c.init_sa_std(), n.asstd());
    assert_eq!(c.init_gyr_bias_radps(), [0.0; 3]);
    // mapped onto the nav-core filter: S_N = arw^2 (rad^2/s), S_B = 2 sigma^2 / T
    let f = FilterConfig::from_kf_gins(&c.imu_noise());
    assert!(rel(f.gyro.s_n[0], 8.726_646_259_971_648e-7f64.powi(2)) < 1e-10);
    assert!(rel(f.accel.s_b[0], 2.0 * 1.5e-4f64.powi(2) / 14_400.0) < 1e-10);
    assert_eq!(f.accel.t_b_s, 14_400.0);
}

#[test]
fn optional_keys_are_honoured_and_unknown_keys_reported() {
    let text = CFG
        .replace(
            "#initbgstd: [ 1, 1, 1 ]",
            "initbgstd: [ 1, 2, 3 ]\ninitsastd: [ 100, 100, 100 ]\nodometer: true",
        )
        .replace("initgyrbias: [ 0, 0, 0 ]    # [deg/h]\n", "")
        .replace("initaccbias: [ 0, 0, 0 ]", "initaccbias: [ 10, -20, 30 ]")
        .replace("endtime: -1", "endtime: 457000.5");
    let c = parse_kf_gins_yaml(name(), &text).unwrap();
    assert!((c.init_bg_std_radps()[1] - 2.0f64.to_radians() / 3600.0).abs() < 1e-18);
    assert!((c.init_sa_std()[0] - 1e-4).abs() < 1e-18);
    assert_eq!(
        c.init_gyr_bias_radps(),
        [0.0; 3],
        "absent initgyrbias defaults to zero"
    );
    assert!((c.init_acc_bias_mps2()[1] + 2.0e-4).abs() < 1e-18);
    assert_eq!(c.end_time_s(), Some(457000.5));
    assert!(c.unknown_keys.contains_key("odometer"));
}

fn cfg_err(text: &str) -> String {
    let e = parse_kf_gins_yaml(name(), text).unwrap_err();
    assert!(matches!(e, IoError::Config { .. }));
    let m = e.to_string();
    assert!(m.contains("cases/kf-gins.yaml"), "{m}");
    m
}

#[test]
fn malformed_kf_gins_yaml_gives_errors_naming_the_key_and_position() {
    // missing required key
    let m = cfg_err(&CFG.replace("antlever:  [ 0.136, -0.301, -0.184 ]", ""));
    assert!(m.contains("antlever"), "{m}");
    // a vector with two elements: the YAML parser names the line and column
    let m = cfg_err(&CFG.replace("initvel: [ 0.0, 0.0, 0.0 ]", "initvel: [ 0.0, 0.0 ]"));
    assert!(
        m.contains("initvel") && m.contains("line 11 column 10"),
        "{m}"
    );
    // text in a number
    let m = cfg_err(&CFG.replace("corrtime: 4.0", "corrtime: four"));
    assert!(m.contains("corrtime") && m.contains("line "), "{m}");
    // negative std, NaN, bad rate
    let m = cfg_err(&CFG.replace(
        "initposstd: [ 0.005, 0.004, 0.008 ]",
        "initposstd: [ 0.005, -0.004, 0.008 ]",
    ));
    assert!(m.contains("initposstd") && m.contains("negative"), "{m}");
    let m = cfg_err(&CFG.replace("arw: [0.003, 0.003, 0.003]", "arw: [.nan, 0.003, 0.003]"));
    assert!(m.contains("imunoise.arw") && m.contains("finite"), "{m}");
    let m = cfg_err(&CFG.replace("imudatarate: 200", "imudatarate: 0"));
    assert!(m.contains("imudatarate"), "{m}");
    let m = cfg_err(&CFG.replace("endtime: -1", "endtime: 100"));
    assert!(m.contains("endtime"), "{m}");
    // not YAML at all
    cfg_err("imupath: [unclosed\n");
    // missing file
    let e = read_kf_gins_yaml("/nonexistent/kf-gins.yaml").unwrap_err();
    assert!(matches!(e, IoError::Open { .. }));
}

/// Numbers written as quoted strings, which KF-GINS (yaml-cpp's `as<double>()` /
/// `as<int>()`) reads as the numbers they spell: the same configuration as written plain. A
/// quoted string that is not a number is refused with the key, line and column.
#[test]
fn quoted_numbers_read_as_kf_gins_reads_them() {
    let plain = parse_kf_gins_yaml(name(), CFG).unwrap();
    let quoted = CFG
        .replace("imudatalen: 7", "imudatalen: '7'")
        .replace("imudatarate: 200", "imudatarate: \"200\"")
        .replace("starttime: 456300", "starttime: \"456300\"")
        .replace("endtime: -1", "endtime: \"-1\"")
        .replace(
            "initpos: [ 30.4447873701, 114.4718632047, 20.899 ]",
            "initpos: [ \"30.4447873701\", \"114.4718632047\", \" 20.899 \" ]",
        )
        .replace(
            "initgyrbias: [ 0, 0, 0 ]",
            "initgyrbias: [ \"0\", 0, '0.0' ]",
        )
        .replace(
            "#initbgstd: [ 1, 1, 1 ]",
            "initbgstd: [ \"0.027\", \"0.027\", \"0.027\" ]",
        )
        .replace("corrtime: 4.0", "corrtime: \"4.0\"")
        .replace(
            "antlever:  [ 0.136, -0.301, -0.184 ]",
            "antlever: [ \"0.136\", \"-0.301\", \"-0.184\" ]",
        );
    let q = parse_kf_gins_yaml(name(), &quoted).unwrap();
    let mut want = plain.clone();
    want.initbgstd = Some([0.027; 3]);
    assert_eq!(q, want);
    // not a number, quoted or not: refused, naming the key and where
    let m = cfg_err(&CFG.replace("imudatarate: 200", "imudatarate: \"200 Hz\""));
    assert!(
        m.contains("imudatarate") && m.contains("\"200 Hz\"") && m.contains("line 7 column 14"),
        "{m}"
    );
    let m = cfg_err(&CFG.replace(
        "initpos: [ 30.4447873701, 114.4718632047, 20.899 ]",
        "initpos: [ \"30.4447873701\", \"north\", 20.899 ]",
    ));
    assert!(
        m.contains("initpos") && m.contains("\"north\"") && m.contains("line 10 column "),
        "{m}"
    );
    let m = cfg_err(&CFG.replace("imudatarate: 200", "imudatarate: \"200.5\""));
    assert!(m.contains("imudatarate") && m.contains("200.5"), "{m}");
}

#[test]
fn kf_gins_yaml_round_trips_through_the_writer() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = parse_kf_gins_yaml(name(), CFG).unwrap();
    c.initbgstd = Some([0.5, 0.6, 0.7]);
    let p = dir.path().join("kf-gins.yaml");
    write_kf_gins_yaml(&p, &c).unwrap();
    let back = read_kf_gins_yaml(&p).unwrap();
    assert_eq!(back, c);
    // relative data paths resolve beside the config when the file is there
    std::fs::create_dir_all(dir.path().join("dataset")).unwrap();
    std::fs::write(dir.path().join("dataset/IMU.txt"), "").unwrap();
    assert_eq!(
        back.resolve_path(&back.imupath, dir.path()),
        dir.path().join("./dataset/IMU.txt")
    );
    // ... and relative to the working directory (KF-GINS's rule) otherwise
    assert_eq!(
        back.resolve_path(&back.gnsspath, dir.path()),
        Path::new("./dataset/GNSS-RTK.txt")
    );
}
