//! Input of the noise identification (`host-sim allan`): rate channels from an IMU file.
//!
//! - The project's IMU text format (`t dtheta_xyz dv_xyz [temp]`, increments): rates are the
//!   increments divided by the sample interval (read with `nav_io::read_imu_text`).
//! - A generic CSV / white-space column file with a column mapping (`gx gy gz ax ay az`, `x` for
//!   one generic channel, `t` for a time column in seconds, `_` to ignore a column), units and
//!   either a fixed rate or the time column. When all six IMU columns are mapped, the project's
//!   IMU CSV reader (`nav_io::read_imu_csv_raw`) does the reading; other mappings (e.g. a
//!   single column) are read by the small column reader here, on the same line reader (gzip
//!   detected by magic bytes, `#`/`%` comment lines skipped, errors with file, line, column).
use super::fit::SensorKind;
use nav_io::{
    self as io, AccelUnit, Column, CsvTime, ImuCsvColumns, ImuCsvFormat, RateUnit, SampleConvention,
};
use std::path::Path;

/// Unit of gyro columns on the command line.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, strum::Display, strum::EnumString, strum::VariantNames,
)]
#[strum(serialize_all = "kebab-case")]
pub enum GyroUnit {
    /// deg/s.
    Dps,
    /// rad/s.
    Radps,
    /// deg/h.
    Dph,
}

impl GyroUnit {
    /// Factor to rad/s.
    pub fn to_radps(self) -> f64 {
        let d = std::f64::consts::PI / 180.0;
        match self {
            GyroUnit::Dps => d,
            GyroUnit::Radps => 1.0,
            GyroUnit::Dph => d / 3600.0,
        }
    }
}

/// Unit of accelerometer columns on the command line.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, strum::Display, strum::EnumString, strum::VariantNames,
)]
#[strum(serialize_all = "kebab-case")]
pub enum AccelUnitArg {
    /// Standard gravity, 9.80665 m/s^2.
    G,
    /// m/s^2.
    Mps2,
    /// Micro-g.
    Ug,
}

impl AccelUnitArg {
    /// Factor to m/s^2.
    pub fn to_mps2(self) -> f64 {
        match self {
            AccelUnitArg::G => io::imucsv::G0_MPS2,
            AccelUnitArg::Mps2 => 1.0,
            AccelUnitArg::Ug => io::imucsv::G0_MPS2 * 1e-6,
        }
    }
}

/// Unit of a single generic `x` column on the command line: a gyro or accelerometer unit
/// makes the channel that sensor (datasheet units in the table, a `[noise.gyro]` or
/// `[noise.accel]` section in `allan_params.toml`); `si` keeps it a channel of unknown
/// quantity, reported in SI (its own unit times `--x-scale`).
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Default,
    strum::Display,
    strum::EnumString,
    strum::VariantNames,
)]
#[strum(serialize_all = "kebab-case")]
pub enum XUnit {
    /// Unknown quantity: SI, the column's unit times `--x-scale`.
    #[default]
    Si,
    /// Gyro, rad/s.
    Radps,
    /// Gyro, deg/s.
    Dps,
    /// Gyro, deg/h.
    Dph,
    /// Accelerometer, m/s^2.
    Mps2,
    /// Accelerometer, standard gravity.
    G,
    /// Accelerometer, micro-g.
    Ug,
}

impl XUnit {
    /// The sensor kind and the factor to its SI unit.
    pub fn kind_and_scale(self) -> (SensorKind, f64) {
        match self {
            XUnit::Si => (SensorKind::Other, 1.0),
            XUnit::Radps => (SensorKind::Gyro, GyroUnit::Radps.to_radps()),
            XUnit::Dps => (SensorKind::Gyro, GyroUnit::Dps.to_radps()),
            XUnit::Dph => (SensorKind::Gyro, GyroUnit::Dph.to_radps()),
            XUnit::Mps2 => (SensorKind::Accel, AccelUnitArg::Mps2.to_mps2()),
            XUnit::G => (SensorKind::Accel, AccelUnitArg::G.to_mps2()),
            XUnit::Ug => (SensorKind::Accel, AccelUnitArg::Ug.to_mps2()),
        }
    }
}

/// Column mapping of a generic file.
#[derive(Clone, Debug)]
pub struct ColumnSpec {
    /// Meaning of each column in order: `gx gy gz ax ay az x t _`.
    pub columns: Vec<String>,
    /// Gyro unit.
    pub gyro_unit: GyroUnit,
    /// Accelerometer unit.
    pub accel_unit: AccelUnitArg,
    /// Fixed sample rate (Hz); `None` takes the sample time from the `t` column.
    pub rate_hz: Option<f64>,
    /// Physical lines skipped at the start (headers).
    pub skip_lines: usize,
    /// Scale applied to an `x` column (default 1), on top of `x_unit`.
    pub x_scale: f64,
    /// Unit (and so sensor kind) of an `x` column.
    pub x_unit: XUnit,
}

/// Rate channels read from a file (SI: rad/s, m/s^2; `x` in its own unit times `x_scale`).
#[derive(Clone, Debug, Default)]
pub struct Channels {
    /// Channel keys (`gx gy gz ax ay az` or `x`).
    pub names: Vec<String>,
    /// Kind of each channel.
    pub kinds: Vec<SensorKind>,
    /// Samples of each channel.
    pub data: Vec<Vec<f64>>,
    /// Sample time (s).
    pub tau0_s: f64,
    /// Notes on the reading (gaps, conversions) for the report.
    pub notes: Vec<String>,
}

/// Errors of the reader.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// From the project's readers.
    #[error(transparent)]
    Io(#[from] io::IoError),
    /// Bad column specification.
    #[error("column mapping: {0}")]
    Spec(String),
    /// Bad file content.
    #[error("{path}: {message}")]
    Content {
        /// File.
        path: String,
        /// What is wrong.
        message: String,
    },
}

const IMU_KEYS: [&str; 6] = ["gx", "gy", "gz", "ax", "ay", "az"];

fn kind_of(key: &str) -> SensorKind {
    match key {
        "gx" | "gy" | "gz" => SensorKind::Gyro,
        "ax" | "ay" | "az" => SensorKind::Accel,
        _ => SensorKind::Other,
    }
}

fn median_dt(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|v| *v > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    Some(*m)
}

/// Reads the project's IMU text format (increments) as rates.
pub fn read_imu_text_rates(path: &Path) -> Result<Channels, ReadError> {
    let rec = io::read_imu_text(path)?;
    let t: Vec<f64> = rec.samples.iter().map(|s| s.t_s).collect();
    let dt = median_dt(&t).ok_or_else(|| ReadError::Content {
        path: path.display().to_string(),
        message: "fewer than two samples with increasing time".into(),
    })?;
    let mut data: Vec<Vec<f64>> = (0..6)
        .map(|_| Vec::with_capacity(rec.samples.len()))
        .collect();
    for s in &rec.samples {
        for k in 0..3 {
            data[k].push(s.dtheta_rad[k] / dt);
            data[3 + k].push(s.dv_mps[k] / dt);
        }
    }
    let mut notes = vec![format!(
        "{}: {} samples of increments, dt = {dt:.6} s (median), rates = increment / dt",
        path.display(),
        rec.samples.len()
    )];
    if !rec.gaps.gaps.is_empty() {
        notes.push(format!(
            "{} time gaps in the record (the Allan statistics assume a gap-free record)",
            rec.gaps.gaps.len()
        ));
    }
    let ch = Channels {
        names: IMU_KEYS.iter().map(|s| s.to_string()).collect(),
        kinds: IMU_KEYS.iter().map(|k| kind_of(k)).collect(),
        data,
        tau0_s: dt,
        notes,
    };
    check_sensor_channels_vary(path, &ch)?;
    Ok(ch)
}

/// Reads a generic column file.
pub fn read_columns(path: &Path, spec: &ColumnSpec) -> Result<Channels, ReadError> {
    let ch = read_columns_unchecked(path, spec)?;
    check_sensor_channels_vary(path, &ch)?;
    Ok(ch)
}

/// A gyro or accelerometer channel that holds one value in every sample is not a sensor's
/// output (a real sensor has at least its quantization noise): a dead channel, or columns of
/// another file (a GNSS file's constant sigma columns read as IMU increments). Its Allan
/// deviation is zero and nothing can be fitted, so the reading fails instead of writing
/// parameters without that sensor.
fn check_sensor_channels_vary(path: &Path, ch: &Channels) -> Result<(), ReadError> {
    let constant: Vec<String> = ch
        .names
        .iter()
        .zip(&ch.kinds)
        .zip(&ch.data)
        .filter(|((_, k), y)| {
            matches!(k, SensorKind::Gyro | SensorKind::Accel)
                && y.len() >= 2
                && y.iter().all(|v| v.to_bits() == y[0].to_bits())
        })
        .map(|((n, _), y)| format!("{n} = {}", y[0]))
        .collect();
    if constant.is_empty() {
        return Ok(());
    }
    Err(ReadError::Content {
        path: path.display().to_string(),
        message: format!(
            "the same value in every one of the {} samples on {}: a dead channel or not IMU \
             data (the IMU text format is `t dtheta_x dtheta_y dtheta_z dv_x dv_y dv_z`, \
             increments in rad and m/s); the Allan deviation of a constant is zero",
            ch.data.first().map_or(0, Vec::len),
            constant.join(", ")
        ),
    })
}

fn read_columns_unchecked(path: &Path, spec: &ColumnSpec) -> Result<Channels, ReadError> {
    let cols: Vec<String> = spec
        .columns
        .iter()
        .map(|c| c.trim().to_lowercase())
        .collect();
    for c in &cols {
        if !matches!(
            c.as_str(),
            "gx" | "gy" | "gz" | "ax" | "ay" | "az" | "x" | "t" | "_" | "-"
        ) {
            return Err(ReadError::Spec(format!(
                "unknown column name {c:?} (use gx gy gz ax ay az x t _)"
            )));
        }
    }
    let pos = |k: &str| cols.iter().position(|c| c == k);
    for k in ["gx", "gy", "gz", "ax", "ay", "az", "x", "t"] {
        if cols.iter().filter(|c| c.as_str() == k).count() > 1 {
            return Err(ReadError::Spec(format!("column {k} given twice")));
        }
    }
    if spec.rate_hz.is_none() && pos("t").is_none() {
        return Err(ReadError::Spec(
            "give --rate-hz or a time column `t` (seconds)".into(),
        ));
    }
    if let Some(r) = spec.rate_hz {
        if !(r.is_finite() && r > 0.0) {
            return Err(ReadError::Spec(format!("--rate-hz must be > 0 (got {r})")));
        }
    }
    let all_imu = IMU_KEYS.iter().all(|k| pos(k).is_some());
    if all_imu && pos("x").is_none() {
        return read_with_io(path, spec, &cols);
    }
    let keys: Vec<(String, usize)> = cols
        .iter()
        .enumerate()
        .filter(|(_, c)| !matches!(c.as_str(), "t" | "_" | "-"))
        .map(|(i, c)| (c.clone(), i))
        .collect();
    if keys.is_empty() {
        return Err(ReadError::Spec("no data column mapped".into()));
    }
    let tcol = pos("t");
    let mut rd = io::open_text(path)?;
    for _ in 0..spec.skip_lines {
        if rd.next_raw()?.is_none() {
            break;
        }
    }
    let mut data: Vec<Vec<f64>> = vec![Vec::new(); keys.len()];
    let mut t = Vec::new();
    let scale: Vec<f64> = keys
        .iter()
        .map(|(k, _)| match kind_of(k) {
            SensorKind::Gyro => spec.gyro_unit.to_radps(),
            SensorKind::Accel => spec.accel_unit.to_mps2(),
            SensorKind::Other => spec.x_unit.kind_and_scale().1 * spec.x_scale,
        })
        .collect();
    let need = cols.len();
    while let Some(dl) = rd.next_data()? {
        if dl.len() < need {
            return Err(io::IoError::TooFewFields {
                path: path.to_path_buf(),
                line: dl.line,
                column: dl.len() + 1,
                name: cols.get(dl.len()).cloned().unwrap_or_default(),
                found: dl.len(),
                expected: format!("at least {need}"),
            }
            .into());
        }
        for (j, (k, i)) in keys.iter().enumerate() {
            let v: f64 = dl.fields[*i]
                .parse()
                .map_err(|_| dl.invalid(*i, k, "not a number"))?;
            if !v.is_finite() {
                return Err(dl.invalid(*i, k, "not finite").into());
            }
            data[j].push(v * scale[j]);
        }
        if let Some(ti) = tcol {
            let v: f64 = dl.fields[ti]
                .parse()
                .map_err(|_| dl.invalid(ti, "t", "not a number"))?;
            t.push(v);
        }
    }
    let tau0 = match spec.rate_hz {
        Some(r) => 1.0 / r,
        None => median_dt(&t).ok_or_else(|| ReadError::Content {
            path: path.display().to_string(),
            message: "time column: fewer than two increasing time stamps".into(),
        })?,
    };
    let n = data.first().map_or(0, Vec::len);
    Ok(Channels {
        names: keys.iter().map(|(k, _)| k.clone()).collect(),
        kinds: keys
            .iter()
            .map(|(k, _)| match kind_of(k) {
                SensorKind::Other => spec.x_unit.kind_and_scale().0,
                kd => kd,
            })
            .collect(),
        data,
        tau0_s: tau0,
        notes: vec![format!(
            "{}: {n} rows, tau0 = {tau0:.6} s (column reader of noise_id::reader)",
            path.display()
        )],
    })
}

fn read_with_io(path: &Path, spec: &ColumnSpec, cols: &[String]) -> Result<Channels, ReadError> {
    let idx = |k: &str| Column::Index(cols.iter().position(|c| c == k).map_or(0, |p| p + 1));
    let fmt = ImuCsvFormat {
        skip_lines: spec.skip_lines,
        skip_last_rows: 0,
        names_line: None,
        columns: ImuCsvColumns {
            time: cols
                .iter()
                .position(|c| c == "t")
                .map(|p| Column::Index(p + 1)),
            gyro: [idx("gx"), idx("gy"), idx("gz")],
            accel: [idx("ax"), idx("ay"), idx("az")],
            temperature: None,
            week: None,
        },
        // Units are applied here (the io reader knows deg/s, rad/s, g, m/s^2 only).
        gyro_unit: RateUnit::RadPerS,
        accel_unit: AccelUnit::Mps2,
        time: match spec.rate_hz {
            Some(r) => CsvTime::FixedRate {
                rate_hz: r,
                start_s: 0.0,
            },
            None => CsvTime::Seconds,
        },
        time_offset_s: 0.0,
        convention: SampleConvention::IntervalMean,
    };
    let rec = io::read_imu_csv_raw(path, &fmt)?;
    let gs = spec.gyro_unit.to_radps();
    let as_ = spec.accel_unit.to_mps2();
    let mut data: Vec<Vec<f64>> = (0..6)
        .map(|_| Vec::with_capacity(rec.samples.len()))
        .collect();
    for s in &rec.samples {
        for k in 0..3 {
            data[k].push(s.gyro_radps[k] * gs);
            data[3 + k].push(s.accel_mps2[k] * as_);
        }
    }
    let tau0 = match spec.rate_hz {
        Some(r) => 1.0 / r,
        None => {
            let t: Vec<f64> = rec.samples.iter().map(|s| s.t_s).collect();
            median_dt(&t).ok_or_else(|| ReadError::Content {
                path: path.display().to_string(),
                message: "time column: fewer than two increasing time stamps".into(),
            })?
        }
    };
    let mut notes = vec![format!(
        "{}: {} rows, tau0 = {tau0:.6} s (nav_io::read_imu_csv_raw)",
        path.display(),
        rec.samples.len()
    )];
    if !rec.gaps.gaps.is_empty() {
        notes.push(format!("{} time gaps in the record", rec.gaps.gaps.len()));
    }
    Ok(Channels {
        names: IMU_KEYS.iter().map(|s| s.to_string()).collect(),
        kinds: IMU_KEYS.iter().map(|k| kind_of(k)).collect(),
        data,
        tau0_s: tau0,
        notes,
    })
}
