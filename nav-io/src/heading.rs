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

use super::lines::{open_text, LineReader, MonotonicTime};
use super::IoError;
use std::path::Path;

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

/// Heading samples handed out at the IMU epochs nearest them, read from the file as the run
/// advances (one sample held): [`HeadingStream::due`] at each IMU epoch `t` with the IMU
/// interval `dt` gives the samples with `t - dt/2 < t_s <= t + dt/2`; samples before the
/// first query's window are skipped (counted).
#[derive(Debug)]
pub struct HeadingStream {
    rd: HeadingReader,
    next: Option<HeadingSample>,
    started: bool,
    skipped: usize,
}

impl HeadingStream {
    /// Opens `path`.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, IoError> {
        Ok(Self {
            rd: HeadingReader::open(path)?,
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
}
