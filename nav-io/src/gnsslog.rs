//! GNSS receiver log files as run inputs: NMEA 0183 logs (`[gnss] format = "nmea"`: GGA,
//! RMC, GST, VTG) and u-blox UBX logs (`format = "ubx"`: NAV-PVT), read with the parsers the
//! bridge uses ([`super::gnss::NmeaAssembler`], [`super::gnss::GnssStream`]); options in
//! `[gnss.log]` ([`GnssLogOptions`]).
//!
//! # NMEA
//! One sentence per line (gzip accepted; blank lines and lines not starting with `$` or `!`
//! are skipped). Time: UTC time of day of each epoch with the RMC date (carried over between
//! epochs) converted to GPS time with the leap seconds of [`super::gpstime`] at each epoch's
//! UTC date (a log crossing a leap second stays on GPS time; the 23:59:60 epoch itself is
//! skipped as a bad sentence), or with `leap_seconds` throughout; returned as GPS seconds of
//! the week of the first fix, with that week. Epochs before the first RMC date cannot be timed and are skipped (counted, warned).
//! Position sigmas: GST latitude/longitude/altitude sigmas; an epoch without GST gets
//! `hdop_uere_m` x HDOP when stated, else `default_sigma_ned_m` (warned once), else the read
//! fails naming the line. Velocity: RMC (or VTG) speed over ground and course, down velocity 0,
//! with sigmas `vel_sigma_mps = [horizontal, vertical]`; without them the velocity is not used
//! (warned once).
//!
//! # UBX
//! The file's bytes go through the bridge's stream splitter (UBX, NMEA and RTCM interleaved);
//! NAV-PVT packets become fixes (`iTOW`, lat/lon/height above the ellipsoid, `hAcc`/`vAcc`,
//! `velN/E/D`, `sAcc`); NMEA sentences in a UBX log are ignored (counted, warned). Times are
//! GPS seconds of week (`iTOW`), continued past 604800 across a week rollover. NAV-PVT has no
//! GPS week: it comes from the first packet whose UTC date and time are flagged valid,
//! converted to GPS time with the leap seconds (table or `leap_seconds`); without one the week
//! is unknown (warned).
//!
//! # Both
//! Fixes without a position fix (`NoFix`) and with an RTKLIB-numbered quality above
//! `[gnss] max_q` are dropped and counted. Bad sentences (checksum, malformed field) and bad
//! packets are skipped and counted, with a warning naming the first one's line (NMEA) or byte
//! offset (UBX); with `strict = true` the first one is an error instead.

use super::gnss::{GnssEvent, GnssStream, NmeaAssembler, NmeaOptions};
use super::gpstime::{
    gpst_minus_utc_at_utc_week_sow, gpst_minus_utc_s, gpst_week_sow, SECONDS_PER_WEEK,
};
use super::lines::open_text;
use super::IoError;
use chrono::{Datelike, Timelike};
use nav_core::types::{FixQuality, GnssFix};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Options of NMEA and UBX log files (`[gnss.log]`, all optional).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssLogOptions {
    /// NMEA: position sigmas north, east, down (m) for epochs without GST (and without
    /// `hdop_uere_m`); warned once when used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_sigma_ned_m: Option<[f64; 3]>,
    /// NMEA: without GST, sigma north = east = HDOP x this, down = 1.5 x HDOP x this, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hdop_uere_m: Option<f64>,
    /// NMEA: sigmas of the speed/course velocity, `[horizontal, vertical]` m/s (NMEA has no
    /// vertical velocity: the down velocity is 0 with the vertical sigma); absent: the NMEA
    /// velocity is not used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vel_sigma_mps: Option<[f64; 2]>,
    /// NMEA: GPS - UTC in s for the whole log (default: from the leap-second table at each
    /// epoch's UTC date).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leap_seconds: Option<i64>,
    /// Stop at the first bad sentence or packet instead of skipping it.
    #[serde(default)]
    pub strict: bool,
}

/// Fixes of an NMEA or UBX log file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GnssLogRecord {
    /// Fixes kept, time order (GPS seconds of [`Self::week`], or of the first fix's week).
    pub fixes: Vec<GnssFix>,
    /// Where each fix ended: 1-based line (NMEA) or 0-based byte offset of the packet's last
    /// byte (UBX).
    pub places: Vec<usize>,
    /// GPS week of the first fix (NMEA: from the RMC date; UBX: from the first NAV-PVT with
    /// a valid UTC date and time; `None` when there is none).
    pub week: Option<i64>,
    /// Fixes dropped as no fix or by `max_q`.
    pub dropped_by_quality: usize,
    /// Bad sentences or packets skipped.
    pub bad_skipped: usize,
    /// Things the user should know (each said once).
    pub warnings: Vec<String>,
    /// The file read.
    pub path: PathBuf,
}

fn cfg_err(path: &Path, message: impl Into<String>) -> IoError {
    IoError::Config {
        path: path.to_path_buf(),
        message: message.into(),
        source: None,
    }
}

fn fmt_err(path: &Path, line: usize, message: impl Into<String>) -> IoError {
    IoError::Format {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

fn sig_ok(v: &[f64]) -> bool {
    v.iter().all(|s| s.is_finite() && *s > 0.0)
}

/// Continues seconds of week past 604800 (and keeps order) across week rollovers.
struct Unwrap {
    weeks: f64,
    last: Option<f64>,
}

impl Unwrap {
    fn new() -> Self {
        Self {
            weeks: 0.0,
            last: None,
        }
    }
    fn apply(&mut self, sow: f64) -> f64 {
        if let Some(l) = self.last {
            if sow + self.weeks < l - SECONDS_PER_WEEK / 2.0 {
                self.weeks += SECONDS_PER_WEEK;
            }
        }
        let t = sow + self.weeks;
        self.last = Some(t);
        t
    }
}

/// Keeps a fix when it is a fix of quality within `max_q`; counts the others.
fn keep(f: &GnssFix, max_q: u8, dropped: &mut usize) -> bool {
    let ok = f.quality != FixQuality::NoFix && (f.quality as u8) <= max_q;
    if !ok {
        *dropped += 1;
    }
    ok
}

/// The first RMC date and time of day in an NMEA log.
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

/// Reads an NMEA 0183 log (see the module notes); `max_q` as `[gnss] max_q`.
pub fn read_nmea_log(
    path: impl AsRef<Path>,
    opts: &GnssLogOptions,
    max_q: u8,
) -> Result<GnssLogRecord, IoError> {
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
    let sec0 = f64::from(time0.second()) + f64::from(time0.nanosecond().min(999_999_999)) * 1e-9;
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
    let mut asm = NmeaAssembler::new(NmeaOptions {
        leap_seconds: leap,
        hdop_uere_m: opts.hdop_uere_m,
        velocity_std_mps: opts.vel_sigma_mps.map(|[h, v]| (h, v)),
    });
    let mut out = GnssLogRecord {
        path: path.to_path_buf(),
        week: Some(week0),
        ..GnssLogRecord::default()
    };
    let mut first_bad: Option<(usize, String)> = None;
    let mut untimed = 0usize;
    let mut first_untimed: Option<usize> = None;
    let mut defaulted = 0usize;
    let mut has_vel_data = false;
    let mut unwrap = Unwrap::new();
    let mut rd = open_text(path)?;
    let mut line = 0usize;
    let mut handle = |ev: Vec<GnssEvent>, line: usize, out: &mut GnssLogRecord| {
        for e in ev {
            match e {
                GnssEvent::Fix(mut f) => {
                    if f.vel_ned_mps[0] != 0.0 || f.vel_ned_mps[1] != 0.0 || f.has_velocity {
                        has_vel_data = true;
                    }
                    if !keep(&f, max_q, &mut out.dropped_by_quality) {
                        continue;
                    }
                    if f.pos_std_ned_m.iter().any(|s| !s.is_finite()) {
                        match opts.default_sigma_ned_m {
                            Some(d) => {
                                f.pos_std_ned_m = d;
                                defaulted += 1;
                            }
                            None => {
                                return Err(fmt_err(
                                    path,
                                    line,
                                    format!("NMEA epoch at GPS {:.3} s of week (ended here) has no GST (position sigmas): state default_sigma_ned_m = [n, e, d] (m) or hdop_uere_m in [gnss.log]", f.t_s),
                                ))
                            }
                        }
                    }
                    f.t_s = unwrap.apply(f.t_s);
                    out.fixes.push(f);
                    out.places.push(line);
                }
                GnssEvent::Error(e @ super::gnss::GnssError::Epoch { .. }) => {
                    // no date yet (before the first RMC) or no GGA in the epoch
                    untimed += 1;
                    first_untimed.get_or_insert(line);
                    if opts.strict {
                        return Err(fmt_err(path, line, e.to_string()));
                    }
                }
                GnssEvent::Error(e) => {
                    out.bad_skipped += 1;
                    let reason = match &e {
                        super::gnss::GnssError::Nmea { reason, .. } => reason.clone(),
                        other => other.to_string(),
                    };
                    if opts.strict {
                        return Err(fmt_err(path, line, format!("bad NMEA sentence: {reason}")));
                    }
                    first_bad.get_or_insert((line, reason));
                }
            }
        }
        Ok(())
    };
    while let Some((n, text)) = rd.next_raw()? {
        line = n;
        let t = text.trim();
        if !(t.starts_with('$') || t.starts_with('!')) {
            continue;
        }
        handle(asm.push_sentence(t), n, &mut out)?;
    }
    handle(asm.flush().into_iter().collect(), line, &mut out)?;
    if defaulted > 0 {
        out.warnings.push(format!(
            "{}: {defaulted} NMEA epochs without GST: they get the configured default_sigma_ned_m = {:?} m",
            path.display(),
            opts.default_sigma_ned_m.unwrap_or([f64::NAN; 3])
        ));
    }
    if has_vel_data && opts.vel_sigma_mps.is_none() {
        out.warnings.push(format!(
            "{}: NMEA speed/course not used as velocity: state vel_sigma_mps = [horizontal, vertical] (m/s) in [gnss.log] to use it",
            path.display()
        ));
    }
    if let Some((l, reason)) = first_bad {
        out.warnings.push(format!(
            "{}: {} bad NMEA sentences skipped (first at line {l}: {reason})",
            path.display(),
            out.bad_skipped
        ));
    }
    if untimed > 0 {
        out.warnings.push(format!(
            "{}: {untimed} NMEA epochs skipped without a date or a GGA position (first ending at line {})",
            path.display(),
            first_untimed.unwrap_or(0)
        ));
    }
    if out.fixes.is_empty() {
        return Err(fmt_err(
            path,
            0,
            format!(
                "no GNSS fixes kept ({} dropped as no fix or by max_q, {} bad sentences)",
                out.dropped_by_quality, out.bad_skipped
            ),
        ));
    }
    // the week of the first kept fix (one later than the first RMC's after a rollover)
    if out.fixes[0].t_s < sow0 - SECONDS_PER_WEEK / 2.0 {
        out.week = Some(week0 + 1);
    }
    if opts.leap_seconds.is_none() {
        leap_seconds_per_fix(&mut out, week0, leap);
    }
    Ok(out)
}

/// Times converted with GPST - UTC = `leap` (the first RMC date's) moved by the leap seconds
/// inserted since: each fix's UTC time gets the table's offset at its own date, so a log
/// crossing a leap second (2016-12-31 23:59:60) stays on GPS time after it. The
/// 23:59:60 epoch itself has no valid NMEA time (the parser refuses second 60) and is skipped
/// as a bad sentence.
fn leap_seconds_per_fix(out: &mut GnssLogRecord, week0: i64, leap: i64) {
    let week = out.week.unwrap_or(week0);
    let mut first_change: Option<(f64, i64)> = None;
    for f in &mut out.fixes {
        let utc = f.t_s - leap as f64;
        let w = (utc / SECONDS_PER_WEEK).floor();
        let here = i64::from(gpst_minus_utc_at_utc_week_sow(
            week + w as i64,
            utc - w * SECONDS_PER_WEEK,
        ));
        if here != leap {
            f.t_s += (here - leap) as f64;
            first_change.get_or_insert((f.t_s, here));
        }
    }
    if let Some((t, here)) = first_change {
        out.warnings.push(format!(
            "{}: a leap second inside the log: GPS - UTC is {leap} s at the first RMC date \
             and {here} s from the fix at GPS {t:.3} s on (times follow it; set \
             [gnss.log] leap_seconds to use one value throughout)",
            out.path.display()
        ));
    }
}

/// The GPS week of the first fix of a UBX log from a NAV-PVT's UTC date and time: the GPST
/// of the UTC time (leap seconds from the table at that date, or `leap`) gives the week of
/// that packet's iTOW (the nearest week boundary decides, so a UTC/iTOW pair straddling a
/// week boundary lands right), and the unwrapped time `t_u` of that fix counts the weeks
/// back to the first fix.
fn ubx_week(t_u: f64, itow: f64, utc: super::gnss::ubx::UtcTime, leap: Option<i64>) -> i64 {
    let (y, mo, d, h, mi, sec) = utc;
    let leap = leap.unwrap_or_else(|| i64::from(gpst_minus_utc_s(i64::from(y), mo, d)));
    let (w, sow) = gpst_week_sow(i64::from(y), mo, d, h, mi, sec + leap as f64);
    let w_pkt = w + ((sow - itow) / SECONDS_PER_WEEK).round() as i64;
    w_pkt - ((t_u - itow) / SECONDS_PER_WEEK).round() as i64
}

/// Reads a u-blox UBX log (see the module notes); `max_q` as `[gnss] max_q`.
pub fn read_ubx_log(
    path: impl AsRef<Path>,
    opts: &GnssLogOptions,
    max_q: u8,
) -> Result<GnssLogRecord, IoError> {
    let path = path.as_ref();
    let mut raw = Vec::new();
    std::fs::File::open(path)
        .map_err(|source| IoError::Open {
            path: path.to_path_buf(),
            source,
        })?
        .read_to_end(&mut raw)
        .map_err(|source| IoError::Read {
            path: path.to_path_buf(),
            line: 0,
            source,
        })?;
    if raw.starts_with(&[0x1f, 0x8b]) {
        let mut dec = Vec::new();
        flate2::read::MultiGzDecoder::new(&raw[..])
            .read_to_end(&mut dec)
            .map_err(|source| IoError::Read {
                path: path.to_path_buf(),
                line: 0,
                source,
            })?;
        raw = dec;
    }
    let mut s = GnssStream::new(NmeaOptions::default());
    let mut out = GnssLogRecord {
        path: path.to_path_buf(),
        ..GnssLogRecord::default()
    };
    let mut unwrap = Unwrap::new();
    let mut first_bad: Option<(usize, String)> = None;
    let mut nmea_fixes = 0usize;
    // (unwrapped time, iTOW, UTC) of the first kept fix with a valid UTC date and time
    let mut anchor: Option<(f64, f64, super::gnss::ubx::UtcTime)> = None;
    let mut push = |ev: Vec<GnssEvent>,
                    off: usize,
                    from_ubx: bool,
                    utc: Option<super::gnss::ubx::UtcTime>,
                    out: &mut GnssLogRecord| {
        for e in ev {
            match e {
                GnssEvent::Fix(mut f) => {
                    if !from_ubx {
                        nmea_fixes += 1;
                        continue;
                    }
                    if !keep(&f, max_q, &mut out.dropped_by_quality) {
                        continue;
                    }
                    let itow = f.t_s;
                    f.t_s = unwrap.apply(f.t_s);
                    if let (None, Some(u)) = (anchor, utc) {
                        anchor = Some((f.t_s, itow, u));
                    }
                    out.fixes.push(f);
                    out.places.push(off);
                }
                GnssEvent::Error(super::gnss::GnssError::Ubx { reason, .. }) => {
                    out.bad_skipped += 1;
                    if opts.strict {
                        return Err(fmt_err(
                            path,
                            0,
                            format!("bad UBX packet ending at byte offset {off}: {reason}"),
                        ));
                    }
                    first_bad.get_or_insert((off, reason));
                }
                // NMEA sentences in a UBX log are not used
                GnssEvent::Error(_) => {}
            }
        }
        Ok(())
    };
    // One byte at a time: a packet's events come out with its last byte, which names the
    // byte offset of every fix and error.
    for (off, b) in raw.iter().enumerate() {
        let before = s.stats().ubx_packets;
        let ev = s.feed(std::slice::from_ref(b));
        if !ev.is_empty() {
            let from_ubx = s.stats().ubx_packets > before;
            let utc = if from_ubx { s.take_nav_pvt_utc() } else { None };
            push(ev, off, from_ubx, utc, &mut out)?;
        }
    }
    push(s.finish(), raw.len(), false, None, &mut out)?;
    if let Some((t_u, itow, (y, mo, d, h, mi, sec))) = anchor {
        out.week = Some(ubx_week(
            t_u,
            itow,
            (y, mo, d, h, mi, sec),
            opts.leap_seconds,
        ));
    } else if !out.fixes.is_empty() {
        out.warnings.push(format!(
            "{}: no NAV-PVT with a valid UTC date: the GPS week is unknown (times are GPS seconds of week)",
            path.display()
        ));
    }
    if let Some((off, reason)) = first_bad {
        out.warnings.push(format!(
            "{}: {} bad UBX packets skipped (first ending at byte offset {off}: {reason})",
            path.display(),
            out.bad_skipped
        ));
    }
    if nmea_fixes > 0 {
        out.warnings.push(format!(
            "{}: {nmea_fixes} NMEA epochs in the UBX log ignored (only NAV-PVT is used)",
            path.display()
        ));
    }
    if out.fixes.is_empty() {
        return Err(fmt_err(
            path,
            0,
            format!(
                "no NAV-PVT fixes kept ({} UBX packets, {} dropped as no fix or by max_q, {} bad packets)",
                s.stats().ubx_packets,
                out.dropped_by_quality,
                out.bad_skipped
            ),
        ));
    }
    Ok(out)
}
