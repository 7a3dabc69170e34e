//! A run configuration over files in formats other than the project's text (the tests of a
//! configuration's own files streamed by `host-sim run`): an IMU CSV log (time in seconds,
//! gyro rad/s, accelerometer m/s^2, interval means) and an RTKLIB `.pos` GNSS file (GPS week
//! and time of week, latitude/longitude/height), written by the test at any length, with a
//! given initial state. The vehicle stands level and north-facing: the gyros see the earth
//! rate and the accelerometers the reaction to gravity, each with a small deterministic
//! wobble (so the rows are not all alike).

use nav_core::earth::{earth_rate_ned_radps, gravity_mps2};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Latitude, longitude (deg) and height (m) of the standing vehicle.
pub const PLACE: [f64; 3] = [30.5, 114.3, 20.0];
/// GPS week written in the `.pos` file.
pub const WEEK: u16 = 2300;
/// Time of the first IMU row, GPS seconds of week.
pub const T0_S: f64 = 100_000.0;

/// What [`write_csv_pos_case`] wrote.
#[derive(Debug, Clone)]
pub struct CsvPosCase {
    /// The run configuration (`run.toml`).
    pub config: PathBuf,
    /// The IMU CSV (`imu.csv`; a header line, then one row per sample).
    pub imu: PathBuf,
    /// Rows of IMU data (the first opens the first interval: `rows - 1` increments).
    pub rows: usize,
    /// Fixes in the `.pos` file (1 Hz, from `T0_S + 1`).
    pub fixes: usize,
}

/// Writes `imu.csv` (`minutes` of data at `rate_hz`), `gnss.pos` (1 Hz) and `run.toml` into
/// `dir`. `bad_row`: that data row (1-based, after the header) is written as `t,x,...`, a
/// field that does not parse (file line `bad_row + 1`).
pub fn write_csv_pos_case(
    dir: &Path,
    minutes: f64,
    rate_hz: f64,
    bad_row: Option<usize>,
) -> CsvPosCase {
    let [lat, lon, h] = PLACE;
    let w = earth_rate_ned_radps(lat.to_radians());
    let g = gravity_mps2(lat.to_radians(), h);
    let rows = (minutes * 60.0 * rate_hz) as usize + 1;
    let imu = dir.join("imu.csv");
    let mut s = String::with_capacity(rows * 90);
    s.push_str("t,gx,gy,gz,ax,ay,az\n");
    for k in 0..rows {
        let t = T0_S + k as f64 / rate_hz;
        let e = 1e-4 * (k as f64 * 0.731).sin();
        if bad_row == Some(k + 1) {
            let _ = writeln!(s, "{t:.4},x,0,0,0,0,0");
            continue;
        }
        let _ = writeln!(
            s,
            "{t:.4},{:.9},{:.9},{:.9},{:.6},{:.6},{:.6}",
            w.x + e,
            w.y - e,
            w.z + 0.5 * e,
            100.0 * e,
            -100.0 * e,
            -g + 50.0 * e
        );
    }
    std::fs::write(&imu, s).expect("writing imu.csv");
    let fixes = (minutes * 60.0) as usize - 1;
    let mut p = String::from(
        "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   \
         sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n",
    );
    for k in 1..=fixes {
        let e = 1e-9 * (k as f64 * 1.37).sin();
        let _ = writeln!(
            p,
            "{WEEK} {:.3}   {:.9}  {:.9} {:10.4}   1  12   0.0200   0.0200   0.0500   0.0000   \
             0.0000   0.0000   0.00    0.0",
            T0_S + k as f64,
            lat + e,
            lon - e,
            h + 1e6 * e
        );
    }
    std::fs::write(dir.join("gnss.pos"), p).expect("writing gnss.pos");
    let config = dir.join("run.toml");
    std::fs::write(
        &config,
        format!(
            "name = \"csv-pos\"\n\
             [imu]\npath = \"imu.csv\"\nformat = \"csv\"\n\
             [imu.csv]\nskip_lines = 1\ngyro_unit = \"rad/s\"\naccel_unit = \"m/s^2\"\n\
             convention = \"interval_mean\"\n\
             [imu.csv.columns]\ntime = 1\ngyro = [2, 3, 4]\naccel = [5, 6, 7]\n\
             [imu.csv.time]\nkind = \"seconds\"\n\
             [gnss]\npath = \"gnss.pos\"\nformat = \"rtklib_pos\"\n\
             [init]\npos_std_m = [1.0, 1.0, 2.0]\nvel_std_mps = [0.1, 0.1, 0.1]\n\
             att_std_deg = [1.0, 1.0, 5.0]\n\
             [init.given]\npos_deg_deg_m = [{lat}, {lon}, {h}]\nvel_ned_mps = [0.0, 0.0, 0.0]\n\
             rpy_deg = [0.0, 0.0, 0.0]\n\
             [noise]\nmodel = \"n\"\n\
             [noise.accel]\nn_ug_per_sqrt_hz = 100.0\nk_ug_per_sqrt_hz = 10.0\n\
             [noise.gyro]\nn_deg_per_s_per_sqrt_hz = 0.005\nk_deg_per_s_per_sqrt_hz = 1e-4\n"
        ),
    )
    .expect("writing run.toml");
    CsvPosCase {
        config,
        imu,
        rows,
        fixes,
    }
}
