//! Odometer / wheel-speed input (`[aiding.odometer] file`): one sample a line,
//!
//! ```text
//! # time [s, the IMU's time scale (GPS seconds of week)]  speed [m/s, forward, >= 0 or signed]
//! 200000.00 12.314
//! 200000.10 12.320
//! ```
//!
//! The common text rules apply (gzip, `#`/`%` comments, comma or white-space separated); the
//! times must increase. Extra columns are an error (a wrong file). [`OdometerTrack`] gives the
//! speed at any time by linear interpolation between neighbouring samples, none across a gap.

use super::lines::{open_text, LineReader, MonotonicTime};
use super::IoError;
use std::path::Path;

/// One wheel-speed sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometerSample {
    /// Time, s (the IMU's time scale).
    pub t_s: f64,
    /// Forward speed, m/s.
    pub speed_mps: f64,
}

const NAMES: [&str; 2] = ["time", "speed"];

/// Reads an odometer file (see the module documentation); errors name the file, line and
/// column.
pub fn read_odometer(path: impl AsRef<Path>) -> Result<Vec<OdometerSample>, IoError> {
    OdometerReader::open(path)?.collect()
}

/// An odometer file read one sample at a time (nothing kept but the current line): an
/// iterator of samples; errors name the file, line and column.
pub struct OdometerReader {
    rd: LineReader,
    mono: MonotonicTime,
}

impl OdometerReader {
    /// Opens an odometer file (plain or gzip).
    pub fn open(path: impl AsRef<Path>) -> Result<Self, IoError> {
        Ok(Self {
            rd: open_text(path.as_ref())?,
            mono: MonotonicTime::new(),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        self.rd.path()
    }

    /// The next sample; `None` at the end of the file.
    pub fn next_sample(&mut self) -> Result<Option<OdometerSample>, IoError> {
        let Some(dl) = self.rd.next_data()? else {
            return Ok(None);
        };
        dl.require(2, 2, &NAMES)?;
        let t_s = dl.num(0, NAMES[0])?;
        let speed_mps = dl.num(1, NAMES[1])?;
        self.mono.check(&dl, 0, NAMES[0], t_s)?;
        Ok(Some(OdometerSample { t_s, speed_mps }))
    }
}

impl Iterator for OdometerReader {
    type Item = Result<OdometerSample, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_sample().transpose()
    }
}

impl std::fmt::Debug for OdometerReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OdometerReader")
            .field("path", &self.rd.path())
            .field("line", &self.rd.line_number())
            .finish()
    }
}

/// The speed at increasing times, read from the file as the times advance (two samples in
/// memory): linear interpolation between the two samples around `t` when they are at most
/// `max_gap_s` apart, none outside the data or across a longer gap (the rule of
/// [`OdometerTrack`]). For a run that streams its IMU.
#[derive(Debug)]
pub struct OdometerStream {
    rd: OdometerReader,
    max_gap_s: f64,
    /// The last sample at or before the last query time, and the one after it.
    a: Option<OdometerSample>,
    b: Option<OdometerSample>,
    started: bool,
}

impl OdometerStream {
    /// Opens `path`; interpolates across at most `max_gap_s`.
    pub fn open(path: impl AsRef<Path>, max_gap_s: f64) -> Result<Self, IoError> {
        Ok(Self {
            rd: OdometerReader::open(path)?,
            max_gap_s,
            a: None,
            b: None,
            started: false,
        })
    }

    /// The speed at `t_s`, m/s; queries must not go back in time (an earlier query than the
    /// last sample read is answered from the two samples held, or none). Errors: a bad line
    /// met while reading ahead.
    pub fn speed_at(&mut self, t_s: f64) -> Result<Option<f64>, IoError> {
        if !self.started {
            self.started = true;
            self.b = self.rd.next_sample()?;
        }
        while let Some(b) = self.b.filter(|b| b.t_s <= t_s) {
            self.a = Some(b);
            self.b = self.rd.next_sample()?;
        }
        let Some(a) = self.a else {
            return Ok(None);
        };
        if a.t_s == t_s {
            return Ok(Some(a.speed_mps));
        }
        let Some(b) = self.b else {
            return Ok(None);
        };
        if !(a.t_s <= t_s && t_s < b.t_s) || b.t_s - a.t_s > self.max_gap_s {
            return Ok(None);
        }
        let w = (t_s - a.t_s) / (b.t_s - a.t_s);
        Ok(Some(a.speed_mps + w * (b.speed_mps - a.speed_mps)))
    }
}

/// Writes samples in the odometer format (`t speed`, one a line).
pub fn write_odometer(path: impl AsRef<Path>, samples: &[OdometerSample]) -> Result<(), IoError> {
    let path = path.as_ref();
    let mut text = String::from("# time_s speed_mps\n");
    for s in samples {
        text.push_str(&format!("{} {}\n", s.t_s, s.speed_mps));
    }
    std::fs::write(path, text).map_err(|source| IoError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// The speed at any time from a sorted sample list: linear interpolation between the two
/// samples around `t` when they are at most `max_gap_s` apart; none outside the data or across
/// a longer gap. Queries at increasing times cost O(1) on average (a cursor).
#[derive(Debug, Clone)]
pub struct OdometerTrack {
    samples: Vec<OdometerSample>,
    max_gap_s: f64,
    cursor: usize,
}

impl OdometerTrack {
    /// A track over `samples` (increasing times) that interpolates across at most `max_gap_s`.
    pub fn new(samples: Vec<OdometerSample>, max_gap_s: f64) -> Self {
        Self {
            samples,
            max_gap_s,
            cursor: 0,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The speed at `t_s`, m/s (see the type's documentation).
    pub fn speed_at(&mut self, t_s: f64) -> Option<f64> {
        if self.cursor > 0 && self.samples.get(self.cursor)?.t_s > t_s {
            // a query back in time: search again from the start
            self.cursor = 0;
        }
        while self
            .samples
            .get(self.cursor + 1)
            .is_some_and(|s| s.t_s <= t_s)
        {
            self.cursor += 1;
        }
        let a = self.samples.get(self.cursor)?;
        if a.t_s == t_s {
            return Some(a.speed_mps);
        }
        let b = self.samples.get(self.cursor + 1)?;
        if !(a.t_s <= t_s && t_s < b.t_s) || b.t_s - a.t_s > self.max_gap_s {
            return None;
        }
        let w = (t_s - a.t_s) / (b.t_s - a.t_s);
        Some(a.speed_mps + w * (b.speed_mps - a.speed_mps))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_interpolates_and_names_bad_lines() {
        let dir = std::env::temp_dir().join(format!("nav-io-odo-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("odo.txt");
        let s = vec![
            OdometerSample {
                t_s: 10.0,
                speed_mps: 1.0,
            },
            OdometerSample {
                t_s: 10.1,
                speed_mps: 2.0,
            },
            OdometerSample {
                t_s: 11.0,
                speed_mps: 3.0,
            },
        ];
        write_odometer(&p, &s).unwrap();
        let back = read_odometer(&p).unwrap();
        assert_eq!(back, s);
        let mut tr = OdometerTrack::new(back, 0.5);
        assert_eq!(tr.speed_at(9.99), None);
        assert_eq!(tr.speed_at(10.0), Some(1.0));
        assert!((tr.speed_at(10.05).unwrap() - 1.5).abs() < 1e-12);
        assert_eq!(tr.speed_at(10.5), None, "0.9 s gap > 0.5 s");
        assert_eq!(tr.speed_at(11.0), Some(3.0));
        assert_eq!(tr.speed_at(11.01), None);
        assert!(
            (tr.speed_at(10.02).unwrap() - 1.2).abs() < 1e-12,
            "back in time"
        );
        // the streaming reader answers the same at increasing times
        let mut st = OdometerStream::open(&p, 0.5).unwrap();
        let mut tr = OdometerTrack::new(read_odometer(&p).unwrap(), 0.5);
        for k in 0..130 {
            let t = 9.95 + 0.01 * k as f64;
            assert_eq!(st.speed_at(t).unwrap(), tr.speed_at(t), "t = {t}");
        }

        std::fs::write(&p, "# t v\n10.0 1.0\n10.1 x\n").unwrap();
        let e = read_odometer(&p).unwrap_err();
        assert_eq!((e.line(), e.column()), (Some(3), Some(2)), "{e}");
        let mut st = OdometerStream::open(&p, 0.5).unwrap();
        assert_eq!(st.speed_at(9.0).unwrap(), None);
        let e = st.speed_at(10.05).unwrap_err();
        assert_eq!((e.line(), e.column()), (Some(3), Some(2)), "streaming: {e}");
        std::fs::write(&p, "10.0 1.0\n9.0 1.0\n").unwrap();
        let e = read_odometer(&p).unwrap_err().to_string();
        assert!(e.contains("line 2"), "{e}");
        std::fs::write(&p, "10.0 1.0 5\n").unwrap();
        assert!(read_odometer(&p).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
