//! Capture files: the raw bytes received from a port, chunk by chunk, with the host receive
//! time of each chunk, so a replay reproduces the original chunking and timing.
//!
//! Format (all integers little-endian):
//!
//! ```text
//! magic        8 bytes  "HWBCAP1\n"
//! header_len   u32      length of the header text
//! header       UTF-8    "key=value\n" lines: port, baud, start_unix_ns, tool
//! records      repeated until end of file:
//!   t_ns       u64      receive time, ns since the capture started (monotonic clock)
//!   len_flags  u32      bit 31: link-reset event (no data follows; the port was lost and
//!                       reopened); bits 0-30: number of data bytes
//!   data       len bytes
//! ```
//!
//! A recorder killed mid-write leaves a truncated last record: the reader reports it as
//! [`CaptureError::TruncatedRecord`] after returning every complete record. A corrupt record
//! header (an impossible length) is skipped: the reader resynchronises on the next valid
//! record header and counts the bytes it skipped ([`CaptureReader::resync_stats`]).
//!
//! Records carry no sequence number: two records with the same time and the same bytes are
//! two reads that returned the same bytes (a sender repeating a 16-byte pattern, 1-byte reads
//! of a constant stream), not a duplicate. Duplicated frames are recognised by the wire
//! protocol's sequence numbers (`docs/wire-protocol.md`), not here. Bytes before the
//! magic (a capture glued after other data, a damaged start) are skipped: the reader scans up
//! to [`MAX_RESYNC_SCAN`] bytes for the magic and reports how many it skipped.

use std::io::{self, Cursor, Read, Write};

/// File magic.
pub const MAGIC: &[u8; 8] = b"HWBCAP1\n";
/// `len_flags` bit marking a link-reset event.
pub const LINK_RESET: u32 = 1 << 31;
/// Largest data length accepted in one record (a larger one means a corrupt file).
pub const MAX_RECORD_LEN: u32 = 16 << 20;
/// Largest header text accepted, bytes.
pub const MAX_HEADER_LEN: u32 = 1 << 20;
/// How far the reader scans for the magic when a file does not start with it, bytes (64 MiB).
pub const MAX_RESYNC_SCAN: u64 = 64 << 20;

/// Errors reading a capture.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// I/O error.
    #[error("capture I/O: {0}")]
    Io(#[from] io::Error),
    /// Not a capture file: no magic at the start nor within [`MAX_RESYNC_SCAN`] bytes. Holds
    /// the file's first bytes (zero-padded when shorter than 8).
    #[error("not a hw-bridge capture (starts with {0:?}, no capture magic found)")]
    BadMagic([u8; 8]),
    /// The file is empty (0 bytes).
    #[error("empty file")]
    Empty,
    /// The file ends inside the magic or header.
    #[error("capture header truncated: the file ends in the header field at byte {offset}")]
    TruncatedHeader {
        /// File offset of the field (magic, header length or header text) the file ends in.
        offset: u64,
    },
    /// Header not UTF-8 or malformed.
    #[error("capture header: {0}")]
    BadHeader(String),
    /// The file ends inside a record.
    #[error("capture truncated in record {record} at byte {offset} (recorder stopped mid-write?)")]
    TruncatedRecord {
        /// 0-based record index.
        record: u64,
        /// File offset of the record.
        offset: u64,
    },
    /// A record claims an absurd length.
    #[error("capture record {record} at byte {offset} claims {len} bytes: corrupt file")]
    BadRecord {
        /// 0-based record index.
        record: u64,
        /// File offset of the record.
        offset: u64,
        /// Claimed length.
        len: u32,
    },
}

/// Capture header fields.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CaptureHeader {
    /// Port the bytes came from.
    pub port: String,
    /// Baud rate set on the port.
    pub baud: u32,
    /// Wall-clock start time, ns since the Unix epoch.
    pub start_unix_ns: u64,
    /// Tool and version that wrote it.
    pub tool: String,
    /// The recording started before the sender (`record --streams-from-start`): every stream
    /// begins at sequence number 0 in it, so frames lost before a stream's first delivered
    /// frame are counted (`Decoder::expect_stream_starts`). Header key
    /// `streams_from_start=1`; absent in older captures (false).
    pub streams_from_start: bool,
}

impl CaptureHeader {
    fn to_text(&self) -> String {
        let mut t = format!(
            "port={}\nbaud={}\nstart_unix_ns={}\ntool={}\n",
            self.port.replace('\n', " "),
            self.baud,
            self.start_unix_ns,
            self.tool.replace('\n', " ")
        );
        if self.streams_from_start {
            t.push_str("streams_from_start=1\n");
        }
        t
    }

    fn parse(text: &str) -> Result<Self, CaptureError> {
        let mut h = Self::default();
        for line in text.lines().filter(|l| !l.is_empty()) {
            let (k, v) = line
                .split_once('=')
                .ok_or_else(|| CaptureError::BadHeader(format!("line {line:?} has no '='")))?;
            let num = |v: &str| {
                v.parse::<u64>()
                    .map_err(|e| CaptureError::BadHeader(format!("{k}={v}: {e}")))
            };
            match k {
                "port" => h.port = v.to_string(),
                "baud" => {
                    h.baud = u32::try_from(num(v)?)
                        .map_err(|e| CaptureError::BadHeader(format!("{k}={v}: {e}")))?
                }
                "streams_from_start" => h.streams_from_start = num(v)? != 0,
                "start_unix_ns" => h.start_unix_ns = num(v)?,
                "tool" => h.tool = v.to_string(),
                _ => {} // later versions may add keys
            }
        }
        Ok(h)
    }
}

/// One record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Record {
    /// Bytes received at `t_ns`.
    Data {
        /// Receive time, ns since the capture started.
        t_ns: u64,
        /// The bytes, as one read returned them.
        bytes: Vec<u8>,
    },
    /// The link was lost and reopened at `t_ns`.
    LinkReset {
        /// Time of the event, ns since the capture started.
        t_ns: u64,
    },
}

impl Record {
    /// Time of the record, ns since the capture started.
    pub fn t_ns(&self) -> u64 {
        match self {
            Self::Data { t_ns, .. } | Self::LinkReset { t_ns } => *t_ns,
        }
    }
}

/// Writes a capture.
pub struct CaptureWriter<W: Write> {
    w: W,
}

impl<W: Write> CaptureWriter<W> {
    /// Writes magic and header.
    pub fn new(mut w: W, header: &CaptureHeader) -> io::Result<Self> {
        let text = header.to_text();
        w.write_all(MAGIC)?;
        w.write_all(&(text.len() as u32).to_le_bytes())?;
        w.write_all(text.as_bytes())?;
        Ok(Self { w })
    }

    /// Appends one record (data longer than [`MAX_RECORD_LEN`] is split).
    pub fn write(&mut self, rec: &Record) -> io::Result<()> {
        match rec {
            Record::Data { t_ns, bytes } => {
                for part in bytes.chunks(MAX_RECORD_LEN as usize) {
                    self.w.write_all(&t_ns.to_le_bytes())?;
                    self.w.write_all(&(part.len() as u32).to_le_bytes())?;
                    self.w.write_all(part)?;
                }
                Ok(())
            }
            Record::LinkReset { t_ns } => {
                self.w.write_all(&t_ns.to_le_bytes())?;
                self.w.write_all(&LINK_RESET.to_le_bytes())
            }
        }
    }

    /// Flushes the underlying writer.
    pub fn flush(&mut self) -> io::Result<()> {
        self.w.flush()
    }

    /// The underlying writer.
    pub fn into_inner(self) -> W {
        self.w
    }
}

/// Latest time a record found by resynchronisation may have, ns after the last good record's
/// (one day): a candidate header with a later time is taken for data bytes.
pub const MAX_RESYNC_TIME_STEP_NS: u64 = 86_400_000_000_000;

/// How the reader got past corrupt record headers ([`CaptureReader::resync_stats`]).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ResyncStats {
    /// Corrupt stretches skipped (each one starting at a record header that was not valid,
    /// or whose record ran past the end of the file, and ending at a valid record header).
    pub resyncs: u64,
    /// Bytes skipped in them.
    pub skipped_bytes: u64,
    /// The first corrupt stretch: (0-based record index, file offset of its header, bytes
    /// skipped).
    pub first: Option<(u64, u64, u64)>,
}

/// Reads a capture record by record.
///
/// A record header that cannot be valid (a data length of 0 or over [`MAX_RECORD_LEN`], a
/// link-reset flag with length bits set), whose record runs past the end of the file, or whose time is
/// more than [`MAX_RESYNC_TIME_STEP_NS`] from the last record's while the header after its
/// record is not valid (the previous record's length was too short) is not the end:
/// the reader scans on (up to [`MAX_RESYNC_SCAN`] bytes) for the next valid record header and
/// goes on from there, counting what it skipped ([`CaptureReader::resync_stats`]). The capture
/// format has no record marker, so a position is taken as a record header when its time is at
/// or after the last good record's and at most [`MAX_RESYNC_TIME_STEP_NS`] later, its length
/// field is valid, and the record it announces ends exactly at the end of the file or at
/// another such header. Only when no such position exists does the reader return
/// [`CaptureError::BadRecord`] or [`CaptureError::TruncatedRecord`].
pub struct CaptureReader<R: Read> {
    inner: R,
    /// Bytes read from `inner` and not consumed yet start at `buf[pos]`.
    buf: Vec<u8>,
    pos: usize,
    eof: bool,
    header: CaptureHeader,
    offset: u64,
    record: u64,
    skipped: u64,
    last_t_ns: u64,
    resync: ResyncStats,
    /// An error ended the reading: later calls return `Ok(None)`.
    failed: bool,
}

/// Reads exactly `buf.len()` bytes; `Ok(false)` at a clean end of file before any byte,
/// `Err(UnexpectedEof)` when the file ends part-way.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> io::Result<bool> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) if got == 0 => return Ok(false),
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

/// Finds the magic: `(bytes before it, bytes read after it)`. Scans at most
/// [`MAX_RESYNC_SCAN`] bytes.
fn find_magic(r: &mut impl Read) -> Result<(u64, Vec<u8>), CaptureError> {
    let mut first = [0u8; 8];
    let mut win: Vec<u8> = Vec::with_capacity(1 << 16);
    // bytes dropped from the front of `win` so far
    let mut dropped = 0u64;
    let mut block = vec![0u8; 1 << 16];
    loop {
        if let Some(p) = win.windows(MAGIC.len()).position(|w| w == MAGIC) {
            let rest = win.split_off(p + MAGIC.len());
            return Ok((dropped + p as u64, rest));
        }
        if dropped + win.len() as u64 >= MAX_RESYNC_SCAN + MAGIC.len() as u64 {
            return Err(CaptureError::BadMagic(first));
        }
        let n = loop {
            match r.read(&mut block) {
                Ok(n) => break n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(CaptureError::Io(e)),
            }
        };
        if n == 0 {
            return Err(if dropped == 0 && win.is_empty() {
                CaptureError::Empty
            } else if dropped == 0 && MAGIC.starts_with(&win) {
                CaptureError::TruncatedHeader { offset: 0 }
            } else {
                CaptureError::BadMagic(first)
            });
        }
        let data = block.get(..n).unwrap_or_default();
        if dropped == 0 && win.len() < first.len() {
            for (d, s) in first.iter_mut().skip(win.len()).zip(data) {
                *d = *s;
            }
        }
        win.extend_from_slice(data);
        // keep the last 7 bytes: the magic may straddle two blocks
        let keep = MAGIC.len() - 1;
        if win.len() > (1 << 20) {
            let cut = win.len() - keep;
            if win.windows(MAGIC.len()).any(|w| w == MAGIC) {
                continue;
            }
            win.drain(..cut);
            dropped += cut as u64;
        }
    }
}

impl<R: Read> CaptureReader<R> {
    /// Reads magic and header. A file not starting with the magic is scanned for it (up to
    /// [`MAX_RESYNC_SCAN`] bytes); [`CaptureReader::skipped_bytes`] says how many bytes came
    /// before it.
    pub fn new(mut r: R) -> Result<Self, CaptureError> {
        let (skipped, rest) = find_magic(&mut r)?;
        let mut c = Cursor::new(rest).chain(r);
        let base = skipped + 8;
        let eof = |e: io::Error, at: u64| {
            if e.kind() == io::ErrorKind::UnexpectedEof {
                CaptureError::TruncatedHeader { offset: at }
            } else {
                CaptureError::Io(e)
            }
        };
        let mut len = [0u8; 4];
        if !read_full(&mut c, &mut len).map_err(|e| eof(e, base))? {
            return Err(CaptureError::TruncatedHeader { offset: base });
        }
        let len = u32::from_le_bytes(len);
        if len > MAX_HEADER_LEN {
            return Err(CaptureError::BadHeader(format!(
                "header length {len} (at most {MAX_HEADER_LEN})"
            )));
        }
        let mut text = Vec::new();
        (&mut c)
            .take(u64::from(len))
            .read_to_end(&mut text)
            .map_err(CaptureError::Io)?;
        if text.len() != len as usize {
            return Err(CaptureError::TruncatedHeader { offset: base + 4 });
        }
        let text = String::from_utf8(text).map_err(|e| CaptureError::BadHeader(e.to_string()))?;
        let header = CaptureHeader::parse(&text)?;
        let (cur, inner) = c.into_inner();
        let at = usize::try_from(cur.position()).unwrap_or(usize::MAX);
        let buf = cur.into_inner().get(at..).unwrap_or_default().to_vec();
        Ok(Self {
            inner,
            buf,
            pos: 0,
            eof: false,
            header,
            offset: base + 4 + u64::from(len),
            record: 0,
            skipped,
            last_t_ns: 0,
            resync: ResyncStats::default(),
            failed: false,
        })
    }

    /// The header.
    pub fn header(&self) -> &CaptureHeader {
        &self.header
    }

    /// Bytes before the magic that were skipped to find it (0 for an intact file).
    pub fn skipped_bytes(&self) -> u64 {
        self.skipped
    }

    /// Corrupt stretches between records skipped so far, and their bytes.
    pub fn resync_stats(&self) -> ResyncStats {
        self.resync
    }

    /// File offset of the next record.
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// Unconsumed bytes buffered.
    fn avail(&self) -> usize {
        self.buf.len() - self.pos
    }

    /// Buffers at least `n` unconsumed bytes, fewer only at the end of the file.
    fn fill(&mut self, n: usize) -> io::Result<()> {
        if self.avail() >= n || self.eof {
            return Ok(());
        }
        if self.pos > 0 {
            self.buf.drain(..self.pos);
            self.pos = 0;
        }
        let mut block = [0u8; 1 << 14];
        while self.buf.len() < n && !self.eof {
            // never more than asked for plus one block: a corrupt length cannot make the
            // reader allocate ahead of the data
            match self.inner.read(&mut block) {
                Ok(0) => self.eof = true,
                Ok(k) => self
                    .buf
                    .extend_from_slice(block.get(..k).unwrap_or_default()),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// The unconsumed bytes `from..to` (relative to the read position), if buffered.
    fn peek(&self, from: usize, to: usize) -> Option<&[u8]> {
        self.buf
            .get(self.pos.checked_add(from)?..self.pos.checked_add(to)?)
    }

    /// The record header (time, `len_flags`) `at` bytes ahead, if buffered.
    fn header_at(&self, at: usize) -> Option<(u64, u32)> {
        let h = self.peek(at, at + 12)?;
        let t = u64::from_le_bytes(h.get(..8)?.try_into().ok()?);
        let lf = u32::from_le_bytes(h.get(8..12)?.try_into().ok()?);
        Some((t, lf))
    }

    /// Bytes of data a valid `len_flags` announces, `None` when it cannot be valid.
    fn data_len(len_flags: u32) -> Option<usize> {
        match len_flags {
            LINK_RESET => Some(0),
            // the writer never writes an empty data record: zeros are a damaged file's (a
            // zero-filled tail after a crash), not records
            l if l > 0 && l <= MAX_RECORD_LEN => Some(l as usize),
            _ => None,
        }
    }

    /// Whether a record header `at` bytes ahead is plausible after a record at `after_t`.
    fn plausible(&self, at: usize, after_t: u64) -> Option<usize> {
        let (t, lf) = self.header_at(at)?;
        let len = Self::data_len(lf)?;
        (t >= after_t && t - after_t <= MAX_RESYNC_TIME_STEP_NS).then_some(len)
    }

    /// Scans for the next valid record header after a corrupt one at the read position;
    /// consumes the bytes before it and returns how many, or `None` when there is none
    /// within [`MAX_RESYNC_SCAN`] bytes.
    fn resync(&mut self) -> io::Result<Option<u64>> {
        let limit = usize::try_from(MAX_RESYNC_SCAN).unwrap_or(usize::MAX);
        let mut q = 1usize;
        while q <= limit {
            self.fill(q + 12)?;
            if self.avail() < q + 12 {
                return Ok(None);
            }
            if let Some(len) = self.plausible(q, self.last_t_ns) {
                let end = q + 12 + len;
                self.fill(end + 12)?;
                let t = self.header_at(q).map_or(0, |h| h.0);
                let ok = self.avail() == end
                    || (self.avail() >= end + 12 && self.plausible(end, t).is_some());
                if ok {
                    self.pos += q;
                    return Ok(Some(q as u64));
                }
            }
            q += 1;
        }
        Ok(None)
    }

    /// The next record, `Ok(None)` at the end of the file (and after an error).
    pub fn next_record(&mut self) -> Result<Option<Record>, CaptureError> {
        if self.failed {
            return Ok(None);
        }
        let r = self.read_record();
        self.failed = r.is_err();
        r
    }

    fn read_record(&mut self) -> Result<Option<Record>, CaptureError> {
        loop {
            let (record, offset) = (self.record, self.offset);
            self.fill(12)?;
            if self.avail() == 0 {
                return Ok(None);
            }
            let Some((t_ns, len_flags)) = self.header_at(0) else {
                return Err(CaptureError::TruncatedRecord { record, offset });
            };
            let len = Self::data_len(len_flags);
            let mut corrupt = len.is_none();
            if let Some(len) = len {
                self.fill(12 + len + 12)?;
                // a time far from the last record's is allowed (a damaged clock, a long link
                // loss) when the record is followed by a valid header or the end of the file;
                // otherwise the header is a misread (the previous length was wrong)
                let far = t_ns.abs_diff(self.last_t_ns) > MAX_RESYNC_TIME_STEP_NS;
                let broken = far
                    && self.avail() >= 12 + len + 12
                    && self
                        .header_at(12 + len)
                        .is_some_and(|(_, lf)| Self::data_len(lf).is_none());
                if self.avail() >= 12 + len && !broken {
                    let rec = if len_flags == LINK_RESET {
                        Record::LinkReset { t_ns }
                    } else {
                        Record::Data {
                            t_ns,
                            bytes: self.peek(12, 12 + len).unwrap_or_default().to_vec(),
                        }
                    };
                    self.pos += 12 + len;
                    self.offset += 12 + len as u64;
                    self.record += 1;
                    self.last_t_ns = t_ns;
                    return Ok(Some(rec));
                }
                corrupt = broken;
            }
            // an invalid header, or a record running past the end of the file
            match self.resync()? {
                Some(n) => {
                    self.resync.resyncs += 1;
                    self.resync.skipped_bytes += n;
                    self.resync.first.get_or_insert((record, offset, n));
                    self.offset += n;
                    self.record += 1;
                }
                None if corrupt => {
                    return Err(CaptureError::BadRecord {
                        record,
                        offset,
                        len: len_flags,
                    })
                }
                None => return Err(CaptureError::TruncatedRecord { record, offset }),
            }
        }
    }
}

impl<R: Read> Iterator for CaptureReader<R> {
    type Item = Result<Record, CaptureError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_record().transpose()
    }
}
