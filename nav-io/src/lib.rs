#![doc = include_str!("../README.md")]
//!
//! ## Common rules
//!
//! Common rules for every text reader here:
//! - gzip-compressed input is detected by its magic bytes (`1f 8b`), whatever the file name;
//! - blank lines and lines whose first non-blank character is `#` or `%` are skipped;
//! - fields are separated by commas when the line contains a comma, otherwise by white space;
//! - lines and columns in errors are 1-based (column = field index on the line);
//! - no input makes a reader panic: every problem is an [`IoError`];
//! - IMU inputs have streaming readers ([`ImuTextReader`], [`ImuBinReader`], [`ImuCsvReader`],
//!   [`ImuCsvIncrements`]) that allocate nothing per line; the whole-file readers collect them;
//! - GNSS inputs too, one reader per format ([`GnssTextReader`], [`PosReader`],
//!   [`GnssCsvReader`], [`NmeaLogReader`], [`UbxLogReader`]; `runcfg::GnssFixReader` holds
//!   the one a run configuration names): constant memory, the whole-file readers collect them.
//!
//! Writers write gzip when the path ends in `.gz`.
#![deny(missing_docs)]

pub mod aidingcfg;
mod decimal;
mod error;
pub mod gnss;
pub mod gnsscsv;
pub mod gnsslog;
pub mod gpstime;
pub mod heading;
pub mod imucsv;
pub mod kfgins;
mod lines;
pub mod mount;
pub mod noisecfg;
pub mod numfmt;
pub mod odometer;
pub mod pos;
pub mod restcheck;
pub mod runcfg;
pub mod tag;
pub mod text;

pub use aidingcfg::AidingSection;
pub use error::IoError;
pub use gnsscsv::{
    read_gnss_csv, GnssCsvColumns, GnssCsvFormat, GnssCsvReader, GnssCsvRecord, GnssCsvTime,
    QualityCodes, QualityMap, SpeedUnit, TimeScale,
};
pub use gnsslog::{
    read_nmea_log, read_ubx_log, GnssLogOptions, GnssLogRecord, NmeaLogReader, UbxLogReader,
};
pub use heading::{read_heading, write_heading, HeadingReader, HeadingSample, HeadingStream};
pub use imucsv::{
    rates_to_increments, read_imu_csv, read_imu_csv_raw, AccelUnit, Column, CsvTime, ImuCsvColumns,
    ImuCsvFormat, ImuCsvIncrements, ImuCsvReader, RateUnit, RawImuRecord, RawImuSample,
    SampleConvention,
};
pub use kfgins::{
    parse_kf_gins_yaml, read_kf_gins_yaml, write_kf_gins_yaml, KfGinsConfig, KfGinsImuNoiseYaml,
};
pub use lines::{
    incomplete_last_line, open_data_file, open_text, parse_f64, DataLine, Fields, IncompleteLine,
    LineReader,
};
pub use mount::Mounting;
pub use noisecfg::AxisValue;
pub use numfmt::{BlockBuf, LineBuf};
pub use odometer::{
    read_odometer, write_odometer, OdometerReader, OdometerSample, OdometerStream, OdometerTrack,
};
pub use pos::{
    read_rtklib_pos, PosOptions, PosPositionFormat, PosReader, PosRecord, PosTimeSystem,
};
pub use runcfg::{
    check_leap_seconds, did_you_mean, parse_run_config, read_run_config, write_run_config,
    AccelNoiseConfig, AlignSpec, BiasModel, GivenState, GnssErrorPrior, GnssFileKind, GnssSource,
    GyroNoiseConfig, ImuChecksConfig, ImuClassName, ImuFileKind, ImuSource, InitConfig, InitMode,
    NoiseConfig, RunConfig, RunInputs, ScaleNoiseConfig, SigmaScale, TruthData, TruthFileKind,
    TruthSource, MAX_LEVER_ARM_M, MAX_TIME_OFFSET_S,
};
pub use tag::{read_time_tag, tick_clock_fit, TickClockFit, TimeTag};
pub use text::{
    read_gnss_text, read_imu_bin, read_imu_text, read_nav_text, write_gnss_line, write_gnss_text,
    write_imu_bin, write_imu_line, write_imu_text, write_nav_line, write_nav_line_display,
    write_nav_text, GnssTextReader, ImuBinReader, ImuGap, ImuOrigin, ImuRecord, ImuTextReader,
    NavTextReader, TimeGapReport,
};
