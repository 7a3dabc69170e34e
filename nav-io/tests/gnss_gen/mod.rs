//! GNSS files of any length in every format a run configuration accepts, written by the tests
//! (text, RTKLIB .pos, CSV, NMEA, UBX, UBX gzip), and the run configuration naming one.

#![allow(dead_code)]

use nav_core::types::{FixQuality, GnssFix};
use nav_io::gnss::encode::{nmea_epoch, ubx_nav_pvt};
use nav_io::{parse_run_config, RunConfig};
use std::io::Write;
use std::path::{Path, PathBuf};

/// GPS week of the generated fixes.
pub const WEEK: i64 = 2305;
/// GPS seconds of week of the first fix (Tuesday 11:20 GPST).
pub const T0: f64 = 2.0 * 86_400.0 + 40_800.0;
/// Interval of the fixes, s (10 Hz).
pub const DT: f64 = 0.1;
/// Every fix `k` with `k % NOFIX_EVERY == NOFIX_AT` has no fix (dropped by every format that
/// states a quality).
pub const NOFIX_EVERY: usize = 50;
const NOFIX_AT: usize = 7;

/// The formats of `[gnss] format`, UBX also gzip-compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fmt {
    Text,
    Pos,
    Csv,
    Nmea,
    Ubx,
    UbxGz,
}

impl Fmt {
    pub const ALL: [Fmt; 6] = [
        Fmt::Text,
        Fmt::Pos,
        Fmt::Csv,
        Fmt::Nmea,
        Fmt::Ubx,
        Fmt::UbxGz,
    ];

    /// Whether the format has a quality (no-fix records dropped).
    pub fn drops(self) -> bool {
        self != Fmt::Text
    }

    /// Whether the format states the GPS week.
    pub fn has_week(self) -> bool {
        self != Fmt::Text
    }

    fn file_name(self) -> &'static str {
        match self {
            Fmt::Text => "gnss.txt",
            Fmt::Pos => "gnss.pos",
            Fmt::Csv => "gnss.csv",
            Fmt::Nmea => "gnss.nmea",
            Fmt::Ubx => "gnss.ubx",
            Fmt::UbxGz => "gnss.ubx.gz",
        }
    }

    /// The `[gnss]` section naming the file, with the keys `extra` (lines `key = value` of
    /// the `[gnss]` table, e.g. `time_offset_s = 0.25\n`).
    pub fn gnss_section(self, extra: &str) -> String {
        let p = self.file_name();
        let head = |kind: &str| format!("[gnss]\npath = \"{p}\"\nformat = \"{kind}\"\n{extra}");
        match self {
            Fmt::Text => head("text"),
            Fmt::Pos => head("rtklib_pos"),
            Fmt::Csv => {
                head("csv")
                    + "[gnss.csv]\nskip_lines = 1\ndefault_vel_sigma_ned_mps = [0.1, 0.1, 0.2]\n\
                   [gnss.csv.columns]\nweek = \"week\"\ntime = \"sow\"\nlat = \"lat\"\n\
                   lon = \"lon\"\nh = \"h\"\nsigma_ned = [\"sn\", \"se\", \"sd\"]\n\
                   vel_ned = [\"vn\", \"ve\", \"vd\"]\nnum_sats = \"ns\"\n\
                   [gnss.csv.time]\nkind = \"week_sow\"\n[gnss.csv.quality]\ncolumn = \"fix\"\n"
            }
            Fmt::Nmea => head("nmea") + "[gnss.log]\nvel_sigma_mps = [0.1, 0.2]\n",
            Fmt::Ubx | Fmt::UbxGz => head("ubx"),
        }
    }
}

/// Fix `k` of the generated drive: 10 Hz, a slow drift north-east, every
/// [`NOFIX_EVERY`]th without a fix.
pub fn fix(k: usize) -> GnssFix {
    let x = k as f64;
    let quality = if k % NOFIX_EVERY == NOFIX_AT {
        FixQuality::NoFix
    } else if k.is_multiple_of(3) {
        FixQuality::RtkFloat
    } else {
        FixQuality::RtkFixed
    };
    GnssFix {
        t_s: T0 + x * DT,
        lat_rad: (30.5 + x * 1e-7).to_radians(),
        lon_rad: (114.3 + x * 2e-7).to_radians(),
        h_m: 20.0 + (x * 0.01).sin(),
        pos_std_ned_m: [0.02, 0.03, 0.05],
        vel_ned_mps: [1.1, 2.2, -0.1],
        vel_std_ned_mps: [0.05, 0.05, 0.1],
        has_velocity: true,
        quality,
        num_sats: (8 + k % 10) as u8,
    }
}

/// Fixes kept of the first `n` (those with a fix; all of them for the text format).
pub fn kept(fmt: Fmt, n: usize) -> usize {
    if fmt.drops() {
        (0..n).filter(|k| k % NOFIX_EVERY != NOFIX_AT).count()
    } else {
        n
    }
}

/// GPST calendar text `yyyy/mm/dd hh:mm:ss.sss` of seconds `sow` of [`WEEK`] (Tuesday
/// 2024-03-12, the day of every generated fix: 100,000 fixes span 2.8 h from 11:20).
fn calendar(sow: f64) -> String {
    let ms = ((sow - 2.0 * 86_400.0) * 1000.0).round() as i64;
    assert!(
        (0..86_400_000).contains(&ms),
        "generated fixes stay on 2024-03-12"
    );
    let (h, mi, s, f) = (ms / 3_600_000, ms / 60_000 % 60, ms / 1000 % 60, ms % 1000);
    format!("2024/03/12 {h:02}:{mi:02}:{s:02}.{f:03}")
}

/// One record of `fmt` for fix `k`, appended to `w`.
fn write_record(w: &mut impl Write, fmt: Fmt, k: usize) -> std::io::Result<()> {
    let f = fix(k);
    match fmt {
        Fmt::Text => nav_io::write_gnss_line(w, &f),
        Fmt::Pos => {
            let q = match f.quality {
                FixQuality::NoFix => 0,
                FixQuality::RtkFloat => 2,
                _ => 1,
            };
            writeln!(
                w,
                "{}  {:.9} {:.9} {:.4} {q} {} 0.0200 0.0300 0.0500 0.0010 -0.0020 0.0030 0.00 0.0 1.1000 2.2000 0.1000 0.0500 0.0500 0.1000 0.0000 0.0000 0.0000",
                calendar(f.t_s),
                f.lat_rad.to_degrees(),
                f.lon_rad.to_degrees(),
                f.h_m,
                f.num_sats
            )
        }
        Fmt::Csv => {
            let name = match f.quality {
                FixQuality::NoFix => "NONE",
                FixQuality::RtkFloat => "RTK_FLOAT",
                _ => "RTK_FIXED",
            };
            writeln!(
                w,
                "{WEEK},{:.3},{name},{:.9},{:.9},{:.4},0.02,0.03,0.05,1.1,2.2,-0.1,{}",
                f.t_s,
                f.lat_rad.to_degrees(),
                f.lon_rad.to_degrees(),
                f.h_m,
                f.num_sats
            )
        }
        Fmt::Nmea => {
            for s in nmea_epoch(&f, WEEK, 18) {
                w.write_all(s.as_bytes())?;
                w.write_all(b"\r\n")?;
            }
            Ok(())
        }
        Fmt::Ubx | Fmt::UbxGz => w.write_all(&ubx_nav_pvt(&f, WEEK, 18)),
    }
}

fn header(fmt: Fmt) -> &'static str {
    match fmt {
        Fmt::Pos => "% program   : generated by nav-io's tests\n%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio    vn(m/s)    ve(m/s)    vu(m/s)      sdvn     sdve     sdvu    sdvne    sdveu    sdvun\n",
        Fmt::Csv => "week,sow,fix,lat,lon,h,sn,se,sd,vn,ve,vd,ns\n",
        _ => "",
    }
}

/// Writes the first `n` fixes in `fmt` into `dir` (buffered, nothing held); the file's path.
pub fn write_file(dir: &Path, fmt: Fmt, n: usize) -> PathBuf {
    write_file_with(dir, fmt, n, |_| None)
}

/// As [`write_file`], with record `k` replaced by the bytes `replace(k)` returns.
pub fn write_file_with(
    dir: &Path,
    fmt: Fmt,
    n: usize,
    replace: impl Fn(usize) -> Option<Vec<u8>>,
) -> PathBuf {
    let path = dir.join(fmt.file_name());
    let file = std::fs::File::create(&path).unwrap();
    let buf = std::io::BufWriter::with_capacity(1 << 16, file);
    let mut w: Box<dyn Write> = if fmt == Fmt::UbxGz {
        Box::new(flate2::write::GzEncoder::new(
            buf,
            flate2::Compression::fast(),
        ))
    } else {
        Box::new(buf)
    };
    w.write_all(header(fmt).as_bytes()).unwrap();
    for k in 0..n {
        match replace(k) {
            Some(b) => w.write_all(&b).unwrap(),
            None => write_record(&mut w, fmt, k).unwrap(),
        }
    }
    w.flush().unwrap();
    drop(w);
    path
}

/// The bytes of record `k` of `fmt` (as [`write_file`] writes it).
pub fn record_bytes(fmt: Fmt, k: usize) -> Vec<u8> {
    let mut v = Vec::new();
    write_record(&mut v, fmt, k).unwrap();
    v
}

/// A run configuration in `dir` whose GNSS section is `gnss` (the IMU file is named but not
/// read by `open_gnss`).
pub fn config(dir: &Path, gnss: &str) -> RunConfig {
    let text = format!(
        "[imu]\npath = \"imu.txt\"\nformat = \"text\"\n{gnss}\n[init]\npos_std_m = [1, 1, 1]\n\
         vel_std_mps = [1, 1, 1]\natt_std_deg = [1, 1, 5]\n[init.align]\nstatic_s = 1.0\n\
         [noise.accel]\nvrw_mps_per_sqrt_h = 0.1\n[noise.gyro]\narw_deg_per_sqrt_h = 0.3\n"
    );
    parse_run_config(&dir.join("run.toml"), &text).unwrap()
}
