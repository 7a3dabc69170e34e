//! The truth (reference trajectory) of a streaming run, read as the solution advances instead
//! of loaded whole: a 4-hour case simulated at 200 Hz has 2.9 million truth records.
//!
//! - [`TruthFile`]: which file (nav text, or an RTKLIB `.pos` whose positions are the
//!   reference with NaN velocity and attitude, [`truth_from_fix`]) and its records as a stream
//!   ([`TruthFile::records`], parsed on a thread of their own and handed over in chunks).
//! - [`start_records`]: the initialisation from the truth needs only the first record at or
//!   after the start time: a separate short read.
//! - [`TruthFeed`]: the stream the sink's [`crate::metrics::TruthMatcher`] consumes, which
//!   also keeps the truth inside each imposed outage until that outage's coasting tracks have
//!   been compared with it (outage windows are known in advance): memory is bounded by the
//!   longest outage, not by the record.

use super::outage::Outage;
use super::{InitSpec, RunError, RunOptions};
use nav_core::types::{GnssFix, NavSolution};
use nav_io::{IoError, NavTextReader, PosOptions, TruthFileKind};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// Truth records as a stream (time order; a read error ends it).
pub type TruthSource<'a> = Box<dyn Iterator<Item = Result<NavSolution, IoError>> + 'a>;

/// A truth file a streaming run reads as the solution advances.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthFile {
    /// The file (plain or gzip).
    pub path: PathBuf,
    /// Its format.
    pub format: TruthFileKind,
}

/// A reference position (RTKLIB `.pos` record) as a truth record: position and time, the
/// velocity when the record has one, NaN velocity otherwise and NaN attitude.
pub fn truth_from_fix(f: &GnssFix) -> NavSolution {
    NavSolution {
        t_s: f.t_s,
        lat_rad: f.lat_rad,
        lon_rad: f.lon_rad,
        h_m: f.h_m,
        vel_ned_mps: if f.has_velocity {
            f.vel_ned_mps
        } else {
            [f64::NAN; 3]
        },
        rpy_rad: [f64::NAN; 3],
        ..NavSolution::default()
    }
}

/// Truth records per message from the reader thread ([`TruthFile::records`]).
pub const READ_CHUNK: usize = 1024;
/// Messages in flight between the reader thread and the run.
pub const READ_QUEUE: usize = 4;

impl TruthFile {
    /// A navigation text file.
    pub fn nav_text(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            format: TruthFileKind::NavText,
        }
    }

    /// The records on the calling thread, read line by line (an RTKLIB `.pos` file with all
    /// qualities kept). A nav text line that does not parse (or whose time is not after the
    /// previous record's) is skipped with a warning on stderr ([`SkipBadLines`]): the truth
    /// only scores the run, one bad epoch must not stop it.
    pub fn open(&self) -> Result<TruthSource<'static>, IoError> {
        self.open_with(true)
    }

    /// [`TruthFile::open`]; `warn`: print the warnings about skipped lines (false for the
    /// short reads before the run, which would repeat them).
    fn open_with(&self, warn: bool) -> Result<TruthSource<'static>, IoError> {
        Ok(match self.format {
            TruthFileKind::NavText => Box::new(SkipBadLines {
                rd: NavTextReader::open(&self.path)?,
                warn,
                skipped: 0,
            }),
            TruthFileKind::RtklibPos => Box::new(
                nav_io::PosReader::open(&self.path, &PosOptions { max_q: 6 })?
                    .map(|r| r.map(|(f, _line)| truth_from_fix(&f))),
            ),
        })
    }

    /// Checks that the file opens and its first record parses (the rest is checked as the
    /// run reads it).
    pub fn check(&self) -> Result<(), IoError> {
        self.open_with(false)?.next().transpose().map(|_| ())
    }

    /// The records read and parsed by a thread of their own and handed over in chunks of
    /// [`READ_CHUNK`] through a bounded channel of [`READ_QUEUE`] chunks: parsing overlaps
    /// the filter. The thread stops at the first error (passed on) or when the
    /// stream is dropped.
    pub fn records(&self) -> TruthSource<'static> {
        let file = self.clone();
        let path = self.path.clone();
        Box::new(super::reader_thread::read_in_chunks(
            "truth-reader",
            READ_CHUNK,
            READ_QUEUE,
            move || file.open(),
            |source| IoError::Open { path, source },
        ))
    }
}

/// Warnings printed about skipped truth lines (the rest are counted at the end).
pub const MAX_TRUTH_WARNINGS: usize = 10;

/// A nav text truth file whose bad lines are skipped: each is a warning on stderr (the first
/// [`MAX_TRUTH_WARNINGS`], then a count at the end of the file); errors about the file as a
/// whole (opening, reading, not text) still end the stream.
pub struct SkipBadLines {
    rd: NavTextReader,
    warn: bool,
    skipped: usize,
}

impl Iterator for SkipBadLines {
    type Item = Result<NavSolution, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            match self.rd.next() {
                Some(Err(e)) if nav_io::text::is_line_error(&e) => {
                    self.skipped += 1;
                    if self.warn && self.skipped <= MAX_TRUTH_WARNINGS {
                        eprintln!("warning: truth {e}: that truth epoch is skipped");
                    }
                }
                None => {
                    if self.warn && self.skipped > MAX_TRUTH_WARNINGS {
                        eprintln!(
                            "warning: truth {}: {} bad line(s) skipped in all",
                            self.rd.path().display(),
                            self.skipped
                        );
                    }
                    self.warn = false;
                    return None;
                }
                r => return r,
            }
        }
    }
}

/// The truth file of a run as [`super::prepare::load`] would load it, checked
/// ([`TruthFile::check`]): `--truth` (`arg`, nav text), else the case directory's truth file
/// when it exists (`case_dir_truth`, nav text), else, without a case directory, the run
/// configuration's `[truth]` (`config`, relative to `config_dir`).
pub fn run_truth_file(
    arg: Option<&Path>,
    case_dir_truth: Option<&Path>,
    config: Option<&nav_io::TruthSource>,
    config_dir: &Path,
) -> Result<Option<TruthFile>, IoError> {
    let f = match (arg, case_dir_truth) {
        (Some(p), _) => Some(TruthFile::nav_text(p)),
        (None, Some(p)) => p.exists().then(|| TruthFile::nav_text(p)),
        (None, None) => config.map(|t| TruthFile {
            path: nav_io::RunConfig::resolve(config_dir, &t.path),
            format: t.format,
        }),
    };
    if let Some(f) = &f {
        f.check()?;
    }
    Ok(f)
}

/// What the initialisation of a streaming run needs of the truth file: for an
/// initialisation from the truth, its first record at or after the start time (a short read
/// from the file's beginning, stopped there; none when the file has no such record), else
/// nothing. `None` without a truth file.
pub fn start_records(
    opts: &RunOptions,
    file: Option<&TruthFile>,
) -> Result<Option<Vec<NavSolution>>, RunError> {
    let Some(file) = file else {
        return Ok(None);
    };
    if !matches!(opts.init, InitSpec::FromTruth { .. }) {
        return Ok(Some(Vec::new()));
    }
    let start_s = opts.start_s.unwrap_or(f64::NEG_INFINITY);
    for r in file.open_with(false).map_err(RunError::Input)? {
        let s = r.map_err(RunError::Input)?;
        // the initialisation's own rule (see `init::initialise`)
        if s.t_s >= start_s && s.t_s.is_finite() {
            return Ok(Some(vec![s]));
        }
    }
    Ok(Some(Vec::new()))
}

/// The truth a streaming run's metrics read (see the module notes): an iterator of records
/// for the [`crate::metrics::TruthMatcher`] that keeps, for each imposed outage, the records
/// inside it (`[start, end)`, the only ones its coasting metrics use) until the outage's
/// coasting tracks are in. A read error ends the stream and is kept ([`Self::take_err`]).
pub struct TruthFeed<'a> {
    src: TruthSource<'a>,
    ended: bool,
    err: Option<IoError>,
    /// Read from the source ahead of the matcher (for a coasting track).
    ahead: VecDeque<NavSolution>,
    /// Time of the last record read from the source, s.
    last_t: f64,
    /// The run's outages, sorted by start ([`super::outage::normalise`]).
    outages: Vec<Outage>,
    /// Per outage: the records inside it while they may still be needed.
    kept: Vec<Option<Vec<NavSolution>>>,
    /// Per outage: coasting tracks compared so far.
    tracks: Vec<usize>,
    /// Per outage: reached by the run (a snapshot was taken).
    reached: Vec<bool>,
    /// Coasting tracks per outage the run makes (one per coasting mode).
    modes: usize,
    /// First outage that may still end after the last record read.
    first_open: usize,
    /// Records are kept for the outages (off while the rest is only checked).
    keeping: bool,
}

impl<'a> TruthFeed<'a> {
    /// Over `src`, for the run's (normalised) outages.
    pub fn new(src: TruthSource<'a>, outages: &[Outage]) -> Self {
        Self {
            src,
            ended: false,
            err: None,
            ahead: VecDeque::new(),
            last_t: f64::NEG_INFINITY,
            outages: outages.to_vec(),
            kept: vec![None; outages.len()],
            tracks: vec![0; outages.len()],
            reached: vec![false; outages.len()],
            modes: 0,
            first_open: 0,
            keeping: true,
        }
    }

    /// The number of coasting tracks the run makes per outage (its coasting modes).
    pub fn set_coast_modes(&mut self, n: usize) {
        self.modes = n;
    }

    /// The read error that ended the stream, once.
    pub fn take_err(&mut self) -> Option<IoError> {
        self.err.take()
    }

    fn read(&mut self) -> Option<NavSolution> {
        if self.ended {
            return None;
        }
        match self.src.next() {
            Some(Ok(s)) => {
                self.last_t = s.t_s;
                if self.keeping {
                    self.keep(&s);
                }
                Some(s)
            }
            Some(Err(e)) => {
                self.ended = true;
                self.err = Some(e);
                None
            }
            None => {
                self.ended = true;
                None
            }
        }
    }

    /// Keeps `s` for every outage containing it.
    fn keep(&mut self, s: &NavSolution) {
        if self.modes == 0 {
            return;
        }
        while self
            .outages
            .get(self.first_open)
            .is_some_and(|o| o.end_s() <= s.t_s)
        {
            self.first_open += 1;
        }
        for (o, k) in self
            .outages
            .iter()
            .zip(self.kept.iter_mut())
            .skip(self.first_open)
        {
            if o.start_s > s.t_s {
                break;
            }
            if o.contains(s.t_s) {
                k.get_or_insert_with(Vec::new).push(*s);
            }
        }
    }

    /// Reads ahead (for the matcher to take later) until a record at or after `t_s` has
    /// been read, or the end.
    fn read_until(&mut self, t_s: f64) {
        while self.last_t < t_s {
            match self.read() {
                Some(s) => self.ahead.push_back(s),
                None => break,
            }
        }
    }

    /// The truth inside outage `k` (read as far as its end), for a coasting track of it.
    pub fn outage_window(&mut self, k: usize) -> &[NavSolution] {
        if let Some(o) = self.outages.get(k) {
            self.read_until(o.end_s());
        }
        self.kept.get(k).and_then(|v| v.as_deref()).unwrap_or(&[])
    }

    /// A coasting track of outage `k` has been compared: the outage's records are dropped
    /// when all its tracks are.
    pub fn track_done(&mut self, k: usize) {
        if let (Some(n), Some(v)) = (self.tracks.get_mut(k), self.kept.get_mut(k)) {
            *n += 1;
            if *n >= self.modes {
                *v = None;
            }
        }
    }

    /// The run has reached outage `k` (its snapshot, which starts its coasting tracks):
    /// earlier outages it never reached (no snapshot, so no tracks) drop their records.
    pub fn outage_reached(&mut self, k: usize) {
        if let Some(r) = self.reached.get_mut(k) {
            *r = true;
        }
        for (v, r) in self.kept.iter_mut().zip(&self.reached).take(k) {
            if !r {
                *v = None;
            }
        }
    }

    /// Reads the rest of the source (nothing kept) and returns its read error: a truth file
    /// is checked to its end, as when it was loaded whole.
    pub fn check_rest(&mut self) -> Result<(), IoError> {
        self.keeping = false;
        self.ahead.clear();
        self.kept.iter_mut().for_each(|v| *v = None);
        while self.read().is_some() {}
        self.take_err().map_or(Ok(()), Err)
    }

    /// Records kept for outages and read ahead (for the memory tests), count.
    pub fn held(&self) -> usize {
        self.ahead.len() + self.kept.iter().flatten().map(Vec::len).sum::<usize>()
    }
}

impl Iterator for TruthFeed<'_> {
    type Item = NavSolution;

    fn next(&mut self) -> Option<NavSolution> {
        match self.ahead.pop_front() {
            Some(s) => Some(s),
            None => self.read(),
        }
    }
}
