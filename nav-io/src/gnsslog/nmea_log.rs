//! The NMEA 0183 log read one epoch at a time ([`NmeaLogReader`]); the rules are those of the
//! parent module's notes.

use super::{cfg_err, fmt_err, keep, sig_ok, GnssLogOptions, Unwrap};
use crate::gnss::{GnssError, GnssEvent, NmeaAssembler, NmeaOptions};
use crate::gpstime::{
    gpst_minus_utc_at_utc_week_sow, gpst_minus_utc_s, gpst_week_sow, SECONDS_PER_WEEK,
};
use crate::lines::{open_text, LineReader};
use crate::IoError;
use chrono::{Datelike, Timelike};
use nav_core::types::GnssFix;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// The first RMC date and time of day in an NMEA log (a pass that stops there).
fn first_rmc_date(path: &Path) -> Result<Option<(chrono::NaiveDate, chrono::NaiveTime)>, IoError> {
    let mut rd = open_text(path)?;
    while let Some((_, text)) = rd.next_raw()? {
        let t = text.trim();
        if t.len() > 6 && t.get(3..6) == Some("RMC") {
            if let Ok(nmea::ParseResult::RMC(r)) = nmea::parse_str(t) {
                if let (Some(d), Some(tm)) = (r.fix_date, r.fix_time) {
                    return Ok(Some((d, tm)));
                }
            }
        }
    }
    Ok(None)
}

/// An NMEA 0183 log read one epoch at a time: the one parser of the format
/// ([`super::read_nmea_log`] collects it). Yields the kept fixes (GPS seconds of
/// [`Self::week`]) with the 1-based line of the sentence that completed each epoch.
///
/// Bounded look-ahead: the first RMC date (it sets GPS - UTC and the week of the GPS times)
/// is found by a first pass over the file that stops at it (usually the first lines); the
/// epochs are assembled by [`NmeaAssembler`], which holds one epoch; the fixes completed by
/// one sentence (at most two) wait in a queue. The week is known once the first fix is read.
/// The counts (`dropped_by_quality`, bad sentences) cover what was read so far and the
/// warnings are said once the file is exhausted. A log without a kept fix ends with an error;
/// errors name the file and the line; after an error the reader ends. Constant memory.
pub struct NmeaLogReader {
    rd: LineReader,
    path: PathBuf,
    asm: NmeaAssembler,
    opts: GnssLogOptions,
    max_q: u8,
    /// GPS week and seconds of week of the first RMC date and time; GPS - UTC there.
    week0: i64,
    sow0: f64,
    leap: i64,
    /// The week of the first kept fix (set with it).
    week: Option<i64>,
    line: usize,
    queue: VecDeque<(GnssFix, usize)>,
    pending_err: Option<IoError>,
    /// The file was read to its end (or failed): nothing more is read.
    eof: bool,
    done: bool,
    kept: usize,
    dropped_by_quality: usize,
    bad_skipped: usize,
    first_bad: Option<(usize, String)>,
    untimed: usize,
    first_untimed: Option<usize>,
    defaulted: usize,
    has_vel_data: bool,
    unwrap: Unwrap,
    /// The first fix whose GPS - UTC differs from the first RMC date's: (its time, the offset).
    leap_change: Option<(f64, i64)>,
    warnings: Vec<String>,
}

impl NmeaLogReader {
    /// Opens `path`: checks the options and finds the first RMC date (an error when there is
    /// none: GPS time needs the date).
    pub fn open(path: impl AsRef<Path>, opts: &GnssLogOptions, max_q: u8) -> Result<Self, IoError> {
        let path = path.as_ref();
        if let Some(d) = opts.default_sigma_ned_m {
            if !sig_ok(&d) {
                return Err(cfg_err(
                    path,
                    format!("gnss.log.default_sigma_ned_m must be finite and > 0, got {d:?}"),
                ));
            }
        }
        if let Some(u) = opts.hdop_uere_m {
            if !sig_ok(&[u]) {
                return Err(cfg_err(
                    path,
                    format!("gnss.log.hdop_uere_m must be finite and > 0, got {u}"),
                ));
            }
        }
        if let Some(v) = opts.vel_sigma_mps {
            if !sig_ok(&v) {
                return Err(cfg_err(
                    path,
                    format!("gnss.log.vel_sigma_mps must be finite and > 0, got {v:?}"),
                ));
            }
        }
        let Some((date0, time0)) = first_rmc_date(path)? else {
            return Err(fmt_err(
                path,
                0,
                "no RMC sentence with a date: GPS time needs the date (RMC)",
            ));
        };
        let leap = opts.leap_seconds.unwrap_or_else(|| {
            i64::from(gpst_minus_utc_s(
                i64::from(date0.year()),
                date0.month(),
                date0.day(),
            ))
        });
        let sec0 =
            f64::from(time0.second()) + f64::from(time0.nanosecond().min(999_999_999)) * 1e-9;
        let (week0, sow0) = gpst_week_sow(
            i64::from(date0.year()),
            date0.month(),
            date0.day(),
            time0.hour(),
            time0.minute(),
            sec0 + leap as f64,
        );
        let week0 = week0 + (sow0 / SECONDS_PER_WEEK).floor() as i64;
        let sow0 = sow0.rem_euclid(SECONDS_PER_WEEK);
        let asm = NmeaAssembler::new(NmeaOptions {
            leap_seconds: leap,
            hdop_uere_m: opts.hdop_uere_m,
            velocity_std_mps: opts.vel_sigma_mps.map(|[h, v]| (h, v)),
        });
        Ok(Self {
            rd: open_text(path)?,
            path: path.to_path_buf(),
            asm,
            opts: opts.clone(),
            max_q,
            week0,
            sow0,
            leap,
            week: None,
            line: 0,
            queue: VecDeque::new(),
            pending_err: None,
            eof: false,
            done: false,
            kept: 0,
            dropped_by_quality: 0,
            bad_skipped: 0,
            first_bad: None,
            untimed: 0,
            first_untimed: None,
            defaulted: 0,
            has_vel_data: false,
            unwrap: Unwrap::new(),
            leap_change: None,
            warnings: Vec::new(),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// GPS week of the first kept fix (the first RMC date's, one more when the first fix is
    /// past a week rollover); `None` before the first fix is read.
    pub fn week(&self) -> Option<i64> {
        self.week
    }

    /// Fixes dropped so far as no fix or by `max_q`.
    pub fn dropped_by_quality(&self) -> usize {
        self.dropped_by_quality
    }

    /// Bad sentences skipped so far.
    pub fn bad_skipped(&self) -> usize {
        self.bad_skipped
    }

    /// Things the user should know (each said once), complete once the reader is exhausted.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Takes in the events completed by the sentence of line `line` (or the end of the file).
    fn handle(&mut self, ev: Vec<GnssEvent>, line: usize) {
        for e in ev {
            match e {
                GnssEvent::Fix(mut f) => {
                    if f.vel_ned_mps[0] != 0.0 || f.vel_ned_mps[1] != 0.0 || f.has_velocity {
                        self.has_vel_data = true;
                    }
                    if !keep(&f, self.max_q, &mut self.dropped_by_quality) {
                        continue;
                    }
                    if f.pos_std_ned_m.iter().any(|s| !s.is_finite()) {
                        match self.opts.default_sigma_ned_m {
                            Some(d) => {
                                f.pos_std_ned_m = d;
                                self.defaulted += 1;
                            }
                            None => {
                                self.pending_err = Some(fmt_err(
                                    &self.path,
                                    line,
                                    format!("NMEA epoch at GPS {:.3} s of week (ended here) has no GST (position sigmas): state default_sigma_ned_m = [n, e, d] (m) or hdop_uere_m in [gnss.log]", f.t_s),
                                ));
                                return;
                            }
                        }
                    }
                    f.t_s = self.unwrap.apply(f.t_s);
                    let week = match self.week {
                        Some(w) => w,
                        // the week of the first kept fix (one later than the first RMC's
                        // after a rollover)
                        None => *self
                            .week
                            .insert(if f.t_s < self.sow0 - SECONDS_PER_WEEK / 2.0 {
                                self.week0 + 1
                            } else {
                                self.week0
                            }),
                    };
                    if self.opts.leap_seconds.is_none() {
                        self.leap_seconds_at_fix(&mut f, week);
                    }
                    self.kept += 1;
                    self.queue.push_back((f, line));
                }
                GnssEvent::Error(e @ GnssError::Epoch { .. }) => {
                    // no date yet (before the first RMC) or no GGA in the epoch
                    self.untimed += 1;
                    self.first_untimed.get_or_insert(line);
                    if self.opts.strict {
                        self.pending_err = Some(fmt_err(&self.path, line, e.to_string()));
                        return;
                    }
                }
                GnssEvent::Error(e) => {
                    self.bad_skipped += 1;
                    let reason = match &e {
                        GnssError::Nmea { reason, .. } => reason.clone(),
                        other => other.to_string(),
                    };
                    if self.opts.strict {
                        self.pending_err = Some(fmt_err(
                            &self.path,
                            line,
                            format!("bad NMEA sentence: {reason}"),
                        ));
                        return;
                    }
                    self.first_bad.get_or_insert((line, reason));
                }
            }
        }
    }

    /// A time converted with GPST - UTC = `leap` (the first RMC date's) moved by the leap
    /// seconds inserted since: the fix's UTC time gets the table's offset at its own date, so
    /// a log crossing a leap second (2016-12-31 23:59:60) stays on GPS time after it. The
    /// 23:59:60 epoch itself has no valid NMEA time (the parser refuses second 60) and is
    /// skipped as a bad sentence.
    fn leap_seconds_at_fix(&mut self, f: &mut GnssFix, week: i64) {
        let leap = self.leap;
        let utc = f.t_s - leap as f64;
        let w = (utc / SECONDS_PER_WEEK).floor();
        let here = i64::from(gpst_minus_utc_at_utc_week_sow(
            week + w as i64,
            utc - w * SECONDS_PER_WEEK,
        ));
        if here != leap {
            f.t_s += (here - leap) as f64;
            self.leap_change.get_or_insert((f.t_s, here));
        }
    }

    /// Reads lines until a fix or an error is queued or the file ends.
    fn pump(&mut self) {
        loop {
            match self.rd.next_raw() {
                Err(e) => {
                    self.pending_err = Some(e);
                    self.eof = true;
                    return;
                }
                Ok(Some((n, text))) => {
                    self.line = n;
                    let t = text.trim();
                    if !(t.starts_with('$') || t.starts_with('!')) {
                        continue;
                    }
                    let ev = self.asm.push_sentence(t);
                    self.handle(ev, n);
                }
                Ok(None) => {
                    self.eof = true;
                    let ev: Vec<GnssEvent> = self.asm.flush().into_iter().collect();
                    self.handle(ev, self.line);
                    if self.pending_err.is_none() {
                        self.finish();
                    }
                    return;
                }
            }
            if self.pending_err.is_some() || !self.queue.is_empty() {
                return;
            }
        }
    }

    /// The end of the file: the warnings, or the error of a log without a kept fix.
    fn finish(&mut self) {
        let p = self.path.display();
        if self.defaulted > 0 {
            self.warnings.push(format!(
                "{p}: {} NMEA epochs without GST: they get the configured default_sigma_ned_m = {:?} m",
                self.defaulted,
                self.opts.default_sigma_ned_m.unwrap_or([f64::NAN; 3])
            ));
        }
        if self.has_vel_data && self.opts.vel_sigma_mps.is_none() {
            self.warnings.push(format!(
                "{p}: NMEA speed/course not used as velocity: state vel_sigma_mps = [horizontal, vertical] (m/s) in [gnss.log] to use it"
            ));
        }
        if let Some((l, reason)) = &self.first_bad {
            self.warnings.push(format!(
                "{p}: {} bad NMEA sentences skipped (first at line {l}: {reason})",
                self.bad_skipped
            ));
        }
        if self.untimed > 0 {
            self.warnings.push(format!(
                "{p}: {} NMEA epochs skipped without a date or a GGA position (first ending at line {})",
                self.untimed,
                self.first_untimed.unwrap_or(0)
            ));
        }
        if self.kept == 0 {
            self.pending_err = Some(fmt_err(
                &self.path,
                0,
                format!(
                    "no GNSS fixes kept ({} dropped as no fix or by max_q, {} bad sentences)",
                    self.dropped_by_quality, self.bad_skipped
                ),
            ));
            return;
        }
        if let Some((t, here)) = self.leap_change {
            self.warnings.push(format!(
                "{p}: a leap second inside the log: GPS - UTC is {} s at the first RMC date \
                 and {here} s from the fix at GPS {t:.3} s on (times follow it; set \
                 [gnss.log] leap_seconds to use one value throughout)",
                self.leap
            ));
        }
    }
}

impl Iterator for NmeaLogReader {
    type Item = Result<(GnssFix, usize), IoError>;

    /// The next kept fix and the line that completed its epoch; after an error, `None`.
    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(x) = self.queue.pop_front() {
                return Some(Ok(x));
            }
            if let Some(e) = self.pending_err.take() {
                self.done = true;
                return Some(Err(e));
            }
            if self.done || self.eof {
                return None;
            }
            self.pump();
        }
    }
}
