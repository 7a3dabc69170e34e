//! Dual-antenna GNSS heading input (`[aiding.heading] file`): one sample a line,
//!
//! ```text
//! # time [s, GPS seconds of week]  heading [deg, azimuth of the baseline from north, clockwise]  sigma [deg, optional]
//! 200000.0 45.12 0.30
//! 200000.2 45.15 0.30
//! ```
//!
//! The common text rules apply (gzip, `#`/`%` comments, comma or white-space separated); the
//! times must increase. Without the third column the configured sigma applies. Any heading
//! value is accepted (it is wrapped); a sigma must be positive. [`HeadingStream`] hands the
//! samples out at the IMU epoch nearest each one, reading the file as the run goes.
//!
//! NMEA 0183 logs ([`HeadingFormat::Nmea`], [`NmeaHeadingReader`]): `HDT` (heading true,
//! parsed and checksum-checked by the `nmea` crate) and `THS` (true heading and status; the
//! crate has no parser for it: parsed here, checksum checked, status `V` = invalid skipped).
//! Neither carries a time: a heading takes the time of the receiver's latest `RMC` (date and
//! time) or `GGA` (time, with the last RMC date), i.e. of its epoch; a second heading in the
//! same epoch is skipped. No sigma: the configured one applies.

use super::gnss::nmea_epoch::gps_seconds_of_week;
use super::lines::{is_skippable, open_text, LineReader, MonotonicTime};
use super::IoError;
use chrono::{NaiveDate, NaiveTime};
use std::path::Path;

/// The kind of a heading file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HeadingFormat {
    /// `time heading_deg [sigma_deg]` text (the module's format).
    #[default]
    Text,
    /// An NMEA 0183 log with `HDT` or `THS` sentences and `RMC`/`GGA` for the time.
    Nmea {
        /// GPS - UTC, s (18 since 2017).
        leap_seconds: i64,
    },
}

/// Heading samples of an NMEA 0183 log (see the module documentation), one at a time.
pub struct NmeaHeadingReader {
    rd: LineReader,
    path: std::path::PathBuf,
    leap_seconds: i64,
    date: Option<NaiveDate>,
    time: Option<NaiveTime>,
    last_t_s: Option<f64>,
}

impl NmeaHeadingReader {
    /// Opens an NMEA log (plain or gzip).
    pub fn open(path: impl AsRef<Path>, leap_seconds: i64) -> Result<Self, IoError> {
        Ok(Self {
            rd: open_text(path.as_ref())?,
            path: path.as_ref().to_path_buf(),
            leap_seconds,
            date: None,
            time: None,
            last_t_s: None,
        })
    }

    /// The next heading sample; `None` at the end of the file. Errors: a `HDT`/`THS`
    /// sentence with a bad checksum or field (other sentences that do not parse are
    /// ignored, as the receiver's other output).
    pub fn next_sample(&mut self) -> Result<Option<HeadingSample>, IoError> {
        loop {
            let leap = self.leap_seconds;
            let Some((line, text)) = self.rd.next_raw()? else {
                return Ok(None);
            };
            if is_skippable(text) {
                continue;
            }
            let t = text.trim();
            let kind = t.get(3..6).unwrap_or("");
            let bad = |message: String| IoError::Format {
                path: self.path.clone(),
                line,
                message,
            };
            let heading = match kind {
                "THS" => parse_ths(t).map_err(|m| bad(format!("{t}: {m}")))?,
                "HDT" => match nmea::parse_str(t) {
                    Ok(nmea::ParseResult::HDT(h)) => h.heading.map(f64::from),
                    Ok(_) => None,
                    Err(e) => return Err(bad(format!("{t}: {e}"))),
                },
                _ => {
                    match nmea::parse_str(t) {
                        Ok(nmea::ParseResult::RMC(r)) => {
                            if r.fix_date.is_some() {
                                self.date = r.fix_date;
                            }
                            if r.fix_time.is_some() {
                                self.time = r.fix_time;
                            }
                        }
                        Ok(nmea::ParseResult::GGA(g)) if g.fix_time.is_some() => {
                            self.time = g.fix_time;
                        }
                        _ => {}
                    }
                    None
                }
            };
            let (Some(h), Some(date), Some(time)) = (heading, self.date, self.time) else {
                continue;
            };
            let t_s = gps_seconds_of_week(date, time, leap);
            if self.last_t_s.is_some_and(|p| t_s <= p) {
                continue;
            }
            self.last_t_s = Some(t_s);
            return Ok(Some(HeadingSample {
                t_s,
                heading_deg: h,
                sigma_deg: None,
            }));
        }
    }
}

impl std::fmt::Debug for NmeaHeadingReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NmeaHeadingReader")
            .field("path", &self.rd.path())
            .field("line", &self.rd.line_number())
            .finish()
    }
}

/// `$--THS,x.x,a*hh`: the heading, deg, or `None` for status `V` (invalid) or an empty
/// heading; the checksum must match.
fn parse_ths(s: &str) -> Result<Option<f64>, String> {
    let body = s.strip_prefix('$').ok_or("no leading $")?;
    let (data, cs) = body.split_once('*').ok_or("no checksum")?;
    let want = u8::from_str_radix(cs.trim(), 16).map_err(|_| "bad checksum field")?;
    let got = data.bytes().fold(0u8, |a, b| a ^ b);
    if want != got {
        return Err(format!("checksum {want:02X}, computed {got:02X}"));
    }
    let mut f = data.split(',').skip(1);
    let (h, status) = (f.next().unwrap_or(""), f.next().unwrap_or(""));
    if status == "V" || h.is_empty() {
        return Ok(None);
    }
    h.parse::<f64>()
        .map(Some)
        .map_err(|_| format!("heading `{h}` is not a number"))
}

/// One heading sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingSample {
    /// Time, s (GPS seconds of week, the run's time scale).
    pub t_s: f64,
    /// Azimuth of the antenna baseline from north, clockwise, deg.
    pub heading_deg: f64,
    /// Its 1-sigma, deg (`None`: the configured one).
    pub sigma_deg: Option<f64>,
}

const NAMES: [&str; 3] = ["time", "heading_deg", "sigma_deg"];

/// A heading file read one sample at a time (an iterator of samples); errors name the file,
/// line and column.
pub struct HeadingReader {
    rd: LineReader,
    mono: MonotonicTime,
}

impl HeadingReader {
    /// Opens a heading file (plain or gzip).
    pub fn open(path: impl AsRef<Path>) -> Result<Self, IoError> {
        Ok(Self {
            rd: open_text(path.as_ref())?,
            mono: MonotonicTime::new(),
        })
    }

    /// The next sample; `None` at the end of the file.
    pub fn next_sample(&mut self) -> Result<Option<HeadingSample>, IoError> {
        let Some(dl) = self.rd.next_data()? else {
            return Ok(None);
        };
        dl.require(2, 3, &NAMES)?;
        let t_s = dl.num(0, NAMES[0])?;
        let heading_deg = dl.num(1, NAMES[1])?;
        let sigma_deg = if dl.len() > 2 {
            let s = dl.num(2, NAMES[2])?;
            if s <= 0.0 {
                return Err(dl.invalid(2, NAMES[2], "must be positive"));
            }
            Some(s)
        } else {
            None
        };
        self.mono.check(&dl, 0, NAMES[0], t_s)?;
        Ok(Some(HeadingSample {
            t_s,
            heading_deg,
            sigma_deg,
        }))
    }
}

impl Iterator for HeadingReader {
    type Item = Result<HeadingSample, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_sample().transpose()
    }
}

impl std::fmt::Debug for HeadingReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HeadingReader")
            .field("path", &self.rd.path())
            .field("line", &self.rd.line_number())
            .finish()
    }
}

/// Reads a whole heading file.
pub fn read_heading(path: impl AsRef<Path>) -> Result<Vec<HeadingSample>, IoError> {
    HeadingReader::open(path)?.collect()
}

/// Writes samples in the heading format (`t heading_deg sigma_deg`, one a line; a sample
/// without sigma gets two columns).
pub fn write_heading(path: impl AsRef<Path>, samples: &[HeadingSample]) -> Result<(), IoError> {
    let path = path.as_ref();
    let mut text = String::from("# time_s heading_deg sigma_deg\n");
    for s in samples {
        match s.sigma_deg {
            Some(sg) => text.push_str(&format!("{} {} {}\n", s.t_s, s.heading_deg, sg)),
            None => text.push_str(&format!("{} {}\n", s.t_s, s.heading_deg)),
        }
    }
    std::fs::write(path, text).map_err(|source| IoError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[derive(Debug)]
enum Source {
    Text(HeadingReader),
    Nmea(NmeaHeadingReader),
}

impl Source {
    fn next_sample(&mut self) -> Result<Option<HeadingSample>, IoError> {
        match self {
            Self::Text(r) => r.next_sample(),
            Self::Nmea(r) => r.next_sample(),
        }
    }
}

/// Heading samples handed out at the IMU epochs nearest them, read from the file as the run
/// advances (one sample held): [`HeadingStream::due`] at each IMU epoch `t` with the IMU
/// interval `dt` gives the samples with `t - dt/2 < t_s <= t + dt/2`; samples before the
/// first query's window are skipped (counted).
#[derive(Debug)]
pub struct HeadingStream {
    rd: Source,
    next: Option<HeadingSample>,
    started: bool,
    skipped: usize,
}

impl HeadingStream {
    /// Opens a text heading file.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, IoError> {
        Self::open_format(path, HeadingFormat::Text)
    }

    /// Opens a heading file of the given kind.
    pub fn open_format(path: impl AsRef<Path>, format: HeadingFormat) -> Result<Self, IoError> {
        Ok(Self {
            rd: match format {
                HeadingFormat::Text => Source::Text(HeadingReader::open(path)?),
                HeadingFormat::Nmea { leap_seconds } => {
                    Source::Nmea(NmeaHeadingReader::open(path, leap_seconds)?)
                }
            },
            next: None,
            started: false,
            skipped: 0,
        })
    }

    /// The next sample due at the IMU epoch `t_s` (interval `dt_s`), if any; call it again
    /// until `None` (several samples may fall into one interval). Errors: a bad line met
    /// while reading ahead.
    pub fn due(&mut self, t_s: f64, dt_s: f64) -> Result<Option<HeadingSample>, IoError> {
        if !self.started {
            self.started = true;
            self.next = self.rd.next_sample()?;
        }
        let half = 0.5 * dt_s.max(0.0);
        while let Some(s) = self.next {
            if s.t_s > t_s + half {
                return Ok(None);
            }
            self.next = self.rd.next_sample()?;
            if s.t_s > t_s - half {
                return Ok(Some(s));
            }
            self.skipped += 1;
        }
        Ok(None)
    }

    /// Samples skipped because they were older than the IMU epoch they were asked at (before
    /// the run's start, or within an IMU gap).
    pub fn skipped(&self) -> usize {
        self.skipped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_streams_at_nearest_epochs_and_names_bad_lines() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("heading.txt");
        let s = vec![
            HeadingSample {
                t_s: 9.0,
                heading_deg: 10.0,
                sigma_deg: Some(0.3),
            },
            HeadingSample {
                t_s: 10.004,
                heading_deg: 359.5,
                sigma_deg: None,
            },
            HeadingSample {
                t_s: 10.2,
                heading_deg: -12.0,
                sigma_deg: Some(0.5),
            },
        ];
        write_heading(&p, &s).unwrap();
        assert_eq!(read_heading(&p).unwrap(), s);
        let mut st = HeadingStream::open(&p).unwrap();
        // IMU at 100 Hz from 10.0: 9.0 is before the first epoch's window (skipped), 10.004
        // is due at 10.00, 10.2 at 10.20
        let mut got = Vec::new();
        for k in 0..30 {
            let t = 10.0 + 0.01 * k as f64;
            while let Some(h) = st.due(t, 0.01).unwrap() {
                got.push((k, h.t_s));
            }
        }
        assert_eq!(got, vec![(0, 10.004), (20, 10.2)]);
        assert_eq!(st.skipped(), 1);

        std::fs::write(&p, "10.0 1.0 0.5\n10.1 2.0 -1\n").unwrap();
        let e = read_heading(&p).unwrap_err();
        assert_eq!((e.line(), e.column()), (Some(2), Some(3)), "{e}");
        std::fs::write(&p, "10.0 1.0 0.5 7\n").unwrap();
        assert!(read_heading(&p).is_err());
        std::fs::write(&p, "10.0 1.0\n9.0 1.0\n").unwrap();
        assert!(read_heading(&p).unwrap_err().to_string().contains("line 2"));
    }

    fn with_checksum(body: &str) -> String {
        let cs = body.bytes().fold(0u8, |a, b| a ^ b);
        format!("${body}*{cs:02X}")
    }

    /// HDT and THS take the time of their epoch's RMC/GGA (GPS time = UTC + 18 s); THS with
    /// status V and a second heading in one epoch are skipped; a bad checksum is an error
    /// naming the line.
    #[test]
    fn nmea_hdt_and_ths_take_their_epoch_time() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("heading.nmea");
        // 2024-03-06 is a Wednesday: 3 days into the GPS week
        let log = [
            with_checksum("GPHDT,10.0,T"), // before any time: skipped
            with_checksum("GPRMC,120000.00,A,3030.0000,N,11418.0000,E,0.0,0.0,060324,,,A"),
            with_checksum("GPHDT,45.25,T"),
            with_checksum("GPHDT,46.00,T"), // the same epoch: skipped
            with_checksum("GPGGA,120001.00,3030.0000,N,11418.0000,E,4,12,0.8,20.0,M,0.0,M,,"),
            with_checksum("GNTHS,47.50,A"),
            with_checksum("GPGGA,120002.00,3030.0000,N,11418.0000,E,4,12,0.8,20.0,M,0.0,M,,"),
            with_checksum("GNTHS,48.00,V"), // invalid
            with_checksum("GPGGA,120003.00,3030.0000,N,11418.0000,E,4,12,0.8,20.0,M,0.0,M,,"),
            with_checksum("GNTHS,359.90,A"),
        ]
        .join("\r\n");
        std::fs::write(&p, &log).unwrap();
        let mut r = NmeaHeadingReader::open(&p, 18).unwrap();
        let mut got = Vec::new();
        while let Some(s) = r.next_sample().unwrap() {
            got.push((s.t_s, s.heading_deg, s.sigma_deg));
        }
        let t0 = 3.0 * 86_400.0 + 12.0 * 3600.0 + 18.0;
        assert_eq!(
            got,
            vec![
                (t0, 45.25, None),
                (t0 + 1.0, 47.5, None),
                (t0 + 3.0, 359.9, None)
            ]
        );
        let mut st =
            HeadingStream::open_format(&p, HeadingFormat::Nmea { leap_seconds: 18 }).unwrap();
        assert_eq!(
            st.due(t0, 0.01).unwrap().map(|s| s.heading_deg),
            Some(45.25)
        );
        let bad = log.replace("GNTHS,47.50,A*", "GNTHS,47.60,A*");
        std::fs::write(&p, bad).unwrap();
        let mut r = NmeaHeadingReader::open(&p, 18).unwrap();
        let e = loop {
            match r.next_sample() {
                Ok(Some(_)) => continue,
                Ok(None) => panic!("no error"),
                Err(e) => break e,
            }
        };
        assert_eq!(e.line(), Some(6), "{e}");
        assert!(e.to_string().contains("checksum"), "{e}");
    }
}
