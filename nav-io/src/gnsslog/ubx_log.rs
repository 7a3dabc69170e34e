//! The u-blox UBX log read one packet at a time ([`UbxLogReader`]); the rules are those of
//! the parent module's notes.

use super::{fmt_err, keep, GnssLogOptions, Unwrap};
use crate::gnss::ubx::UtcTime;
use crate::gnss::{GnssError, GnssEvent, GnssStream, NmeaOptions};
use crate::gpstime::{gpst_minus_utc_s, gpst_week_sow, SECONDS_PER_WEEK};
use crate::IoError;
use nav_core::types::GnssFix;
use std::collections::VecDeque;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// Bytes read from the file (or the gzip decoder) at a time.
const CHUNK_BYTES: usize = 1 << 16;

/// Sync, class, id, length and checksum bytes around a UBX payload.
const UBX_FRAME_OVERHEAD: usize = 8;

/// Longest UBX frame fed to the parser in one piece, bytes (well inside its 4 KiB buffer).
const FAST_FRAME_MAX: usize = 2048;

/// Kept fixes held back at the start of a log until a NAV-PVT with a valid UTC date gives the
/// GPS week (so that the week is known when the first fix is returned); a log whose first
/// this many kept fixes have no valid UTC date releases them and gets its week later (or
/// never). 64 fixes of about 100 bytes each: 6.4 KiB at most.
pub const UBX_WEEK_LOOKAHEAD: usize = 64;

/// The GPS week of the first fix of a UBX log from a NAV-PVT's UTC date and time: the GPST
/// of the UTC time (leap seconds from the table at that date, or `leap`) gives the week of
/// that packet's iTOW (the nearest week boundary decides, so a UTC/iTOW pair straddling a
/// week boundary lands right), and the unwrapped time `t_u` of that fix counts the weeks
/// back to the first fix.
fn ubx_week(t_u: f64, itow: f64, utc: UtcTime, leap: Option<i64>) -> i64 {
    let (y, mo, d, h, mi, sec) = utc;
    let leap = leap.unwrap_or_else(|| i64::from(gpst_minus_utc_s(i64::from(y), mo, d)));
    let (w, sow) = gpst_week_sow(i64::from(y), mo, d, h, mi, sec + leap as f64);
    let w_pkt = w + ((sow - itow) / SECONDS_PER_WEEK).round() as i64;
    w_pkt - ((t_u - itow) / SECONDS_PER_WEEK).round() as i64
}

/// A u-blox UBX log (plain or gzip) read one packet at a time: the one parser of the format
/// ([`super::read_ubx_log`] collects it). The bytes are read in chunks of 64 KiB and fed to
/// the `ublox` crate's streaming parser ([`GnssStream`], a fixed 4 KiB packet buffer) so that
/// each packet ends a feed: each fix and each bad packet is named by the 0-based byte offset
/// of the packet's last byte (in the decompressed stream). Yields the kept fixes with that
/// offset.
///
/// The GPS week ([`Self::week`]) comes from the first kept NAV-PVT with a valid UTC date: up
/// to [`UBX_WEEK_LOOKAHEAD`] kept fixes are held back at the start until it is found (bounded
/// look-ahead), after that the week is set whenever it is found. The counts cover what was
/// read so far and the warnings are said once the file is exhausted. A log without a kept
/// fix ends with an error; after an error the reader ends. Constant memory.
pub struct UbxLogReader {
    path: PathBuf,
    src: Box<dyn Read + Send>,
    buf: Vec<u8>,
    /// `buf[pos..len]` is not yet fed.
    pos: usize,
    len: usize,
    /// Offset of `buf[pos]` in the (decompressed) stream.
    offset: usize,
    /// Offset of the last byte of the UBX frame being fed whole, when it goes on in the next
    /// chunk.
    frame_end: Option<usize>,
    stream: GnssStream,
    opts: GnssLogOptions,
    max_q: u8,
    queue: VecDeque<(GnssFix, usize)>,
    pending_err: Option<IoError>,
    eof: bool,
    done: bool,
    /// Fixes returned so far.
    released: usize,
    kept: usize,
    week: Option<i64>,
    dropped_by_quality: usize,
    bad_skipped: usize,
    first_bad: Option<(usize, String)>,
    nmea_fixes: usize,
    unwrap: Unwrap,
    warnings: Vec<String>,
}

impl UbxLogReader {
    /// Opens `path` (gzip detected from its magic bytes).
    pub fn open(path: impl AsRef<Path>, opts: &GnssLogOptions, max_q: u8) -> Result<Self, IoError> {
        let path = path.as_ref();
        let f = crate::lines::open_data_file(path)?;
        Self::from_reader(path, f, opts, max_q)
    }

    /// Reads from any byte source (gzip detected from its magic bytes); `name` is the file
    /// name used in errors and warnings.
    pub fn from_reader<R: Read + Send + 'static>(
        name: &Path,
        src: R,
        opts: &GnssLogOptions,
        max_q: u8,
    ) -> Result<Self, IoError> {
        let path = name;
        // the first two bytes (however the source splits them) tell gzip
        let mut src = src;
        let mut head = [0u8; 2];
        let mut n = 0;
        while n < head.len() {
            match src.read(head.get_mut(n..).unwrap_or(&mut [])) {
                Ok(0) => break,
                Ok(k) => n += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(source) => {
                    return Err(IoError::Read {
                        path: path.to_path_buf(),
                        line: 0,
                        source,
                    })
                }
            }
        }
        let gz = n == 2 && head == [0x1f, 0x8b];
        let src = std::io::Cursor::new(head).take(n as u64).chain(src);
        let src: Box<dyn Read + Send> = if gz {
            Box::new(flate2::read::MultiGzDecoder::new(BufReader::new(src)))
        } else {
            Box::new(src)
        };
        Ok(Self {
            path: path.to_path_buf(),
            src,
            buf: vec![0; CHUNK_BYTES],
            pos: 0,
            len: 0,
            offset: 0,
            frame_end: None,
            stream: GnssStream::new(NmeaOptions::default()),
            opts: opts.clone(),
            max_q,
            queue: VecDeque::new(),
            pending_err: None,
            eof: false,
            done: false,
            released: 0,
            kept: 0,
            week: None,
            dropped_by_quality: 0,
            bad_skipped: 0,
            first_bad: None,
            nmea_fixes: 0,
            unwrap: Unwrap::new(),
            warnings: Vec::new(),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// GPS week of the first fix, once a kept NAV-PVT with a valid UTC date was read.
    pub fn week(&self) -> Option<i64> {
        self.week
    }

    /// Fixes dropped so far as no fix or by `max_q`.
    pub fn dropped_by_quality(&self) -> usize {
        self.dropped_by_quality
    }

    /// Bad packets skipped so far.
    pub fn bad_skipped(&self) -> usize {
        self.bad_skipped
    }

    /// Things the user should know (each said once), complete once the reader is exhausted.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Takes in the events completed by the byte at `off` (or the end of the stream).
    fn handle(&mut self, ev: Vec<GnssEvent>, off: usize, from_ubx: bool, utc: Option<UtcTime>) {
        for e in ev {
            match e {
                GnssEvent::Fix(mut f) => {
                    if !from_ubx {
                        self.nmea_fixes += 1;
                        continue;
                    }
                    if !keep(&f, self.max_q, &mut self.dropped_by_quality) {
                        continue;
                    }
                    let itow = f.t_s;
                    f.t_s = self.unwrap.apply(f.t_s);
                    if let (None, Some(u)) = (self.week, utc) {
                        self.week = Some(ubx_week(f.t_s, itow, u, self.opts.leap_seconds));
                    }
                    self.kept += 1;
                    self.queue.push_back((f, off));
                }
                GnssEvent::Error(GnssError::Ubx { reason, .. }) => {
                    self.bad_skipped += 1;
                    if self.opts.strict {
                        self.pending_err = Some(fmt_err(
                            &self.path,
                            0,
                            format!("bad UBX packet ending at byte offset {off}: {reason}"),
                        ));
                        return;
                    }
                    self.first_bad.get_or_insert((off, reason));
                }
                // NMEA sentences in a UBX log are not used
                GnssEvent::Error(_) => {}
            }
        }
    }

    /// Feeds bytes until a fix or an error is queued or the buffered chunk is used up; reads
    /// the next chunk when it is.
    fn pump(&mut self) {
        if self.pos == self.len {
            loop {
                match self.src.read(&mut self.buf) {
                    Ok(0) => {
                        self.eof = true;
                        let ev = self.stream.finish();
                        self.handle(ev, self.offset, false, None);
                        if self.pending_err.is_none() {
                            self.finish();
                        }
                        return;
                    }
                    Ok(n) => {
                        self.pos = 0;
                        self.len = n;
                        break;
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(source) => {
                        self.eof = true;
                        self.pending_err = Some(IoError::Read {
                            path: self.path.clone(),
                            line: 0,
                            source,
                        });
                        return;
                    }
                }
            }
        }
        // A packet's events come out with its last byte, which names the byte offset of every
        // fix and error: the bytes are fed one at a time, except a whole UBX frame met by an
        // idle parser (see `span`).
        while self.pos < self.len {
            let n = self.span();
            let Some(bytes) = self.buf.get(self.pos..self.pos + n) else {
                break;
            };
            let last = self.offset + n - 1;
            self.pos += n;
            self.offset += n;
            let before = self.stream.stats().ubx_packets;
            let ev = self.stream.feed(bytes);
            if !ev.is_empty() {
                let from_ubx = self.stream.stats().ubx_packets > before;
                let utc = if from_ubx {
                    self.stream.take_nav_pvt_utc()
                } else {
                    None
                };
                self.handle(ev, last, from_ubx, utc);
                if self.pending_err.is_some() || !self.queue.is_empty() {
                    return;
                }
            }
        }
    }

    /// How many of the buffered bytes to feed at once (at least one): the rest of a UBX frame
    /// (up to the chunk's end) when the parser met its header idle, else one. Fed whole, a
    /// frame gives the events the parser gives fed byte by byte, at the same (last) byte: an
    /// idle parser that sees a UBX header with an acceptable length waits for the whole frame
    /// before it parses anything (a checksum error, and any packet found in a bad frame's
    /// bytes, come out with its last byte either way). About 40 times faster than one byte
    /// at a time; bytes that are not UBX frames (NMEA, RTCM, garbage) go one at a time.
    fn span(&mut self) -> usize {
        let rest = self.buf.get(self.pos..self.len).unwrap_or(&[]);
        if let Some(end) = self.frame_end {
            // the frame's rest (its end included) in this chunk
            let n = (end + 1 - self.offset).min(rest.len()).max(1);
            if self.offset + n > end {
                self.frame_end = None;
            }
            return n;
        }
        if let [0xB5, 0x62, _, _, l0, l1, ..] = *rest {
            if self.stream.is_idle() {
                let payload = usize::from(u16::from_le_bytes([l0, l1]));
                let total = UBX_FRAME_OVERHEAD + payload;
                if payload <= self.stream.max_ubx_payload() && total <= FAST_FRAME_MAX {
                    if rest.len() < total {
                        self.frame_end = Some(self.offset + total - 1);
                    }
                    return total.min(rest.len());
                }
            }
        }
        1
    }

    /// The end of the file: the warnings, or the error of a log without a kept fix.
    fn finish(&mut self) {
        let p = self.path.display();
        if self.week.is_none() && self.kept > 0 {
            self.warnings.push(format!(
                "{p}: no NAV-PVT with a valid UTC date: the GPS week is unknown (times are GPS seconds of week)"
            ));
        }
        if let Some((off, reason)) = &self.first_bad {
            self.warnings.push(format!(
                "{p}: {} bad UBX packets skipped (first ending at byte offset {off}: {reason})",
                self.bad_skipped
            ));
        }
        if self.nmea_fixes > 0 {
            self.warnings.push(format!(
                "{p}: {} NMEA epochs in the UBX log ignored (only NAV-PVT is used)",
                self.nmea_fixes
            ));
        }
        if self.kept == 0 {
            self.pending_err = Some(fmt_err(
                &self.path,
                0,
                format!(
                    "no NAV-PVT fixes kept ({} UBX packets, {} dropped as no fix or by max_q, {} bad packets)",
                    self.stream.stats().ubx_packets,
                    self.dropped_by_quality,
                    self.bad_skipped
                ),
            ));
        }
    }
}

impl Iterator for UbxLogReader {
    type Item = Result<(GnssFix, usize), IoError>;

    /// The next kept fix and the byte offset of its packet's last byte; after an error,
    /// `None`.
    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        loop {
            // at the start, hold the fixes back until the week is known (bounded)
            let holding = self.released == 0
                && self.week.is_none()
                && !self.eof
                && self.pending_err.is_none()
                && self.queue.len() < UBX_WEEK_LOOKAHEAD;
            if !holding {
                if let Some(x) = self.queue.pop_front() {
                    self.released += 1;
                    return Some(Ok(x));
                }
                if let Some(e) = self.pending_err.take() {
                    self.done = true;
                    return Some(Err(e));
                }
                if self.done || self.eof {
                    return None;
                }
            }
            self.pump();
        }
    }
}
