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
//! [`CaptureError::TruncatedRecord`] after returning every complete record. Bytes before the
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

/// Reads a capture record by record.
pub struct CaptureReader<R: Read> {
    r: io::Chain<Cursor<Vec<u8>>, R>,
    header: CaptureHeader,
    offset: u64,
    record: u64,
    skipped: u64,
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
        let mut r = Cursor::new(rest).chain(r);
        let base = skipped + 8;
        let eof = |e: io::Error, at: u64| {
            if e.kind() == io::ErrorKind::UnexpectedEof {
                CaptureError::TruncatedHeader { offset: at }
            } else {
                CaptureError::Io(e)
            }
        };
        let mut len = [0u8; 4];
        if !read_full(&mut r, &mut len).map_err(|e| eof(e, base))? {
            return Err(CaptureError::TruncatedHeader { offset: base });
        }
        let len = u32::from_le_bytes(len);
        if len > MAX_HEADER_LEN {
            return Err(CaptureError::BadHeader(format!(
                "header length {len} (at most {MAX_HEADER_LEN})"
            )));
        }
        let mut text = Vec::new();
        (&mut r)
            .take(u64::from(len))
            .read_to_end(&mut text)
            .map_err(CaptureError::Io)?;
        if text.len() != len as usize {
            return Err(CaptureError::TruncatedHeader { offset: base + 4 });
        }
        let text = String::from_utf8(text).map_err(|e| CaptureError::BadHeader(e.to_string()))?;
        let header = CaptureHeader::parse(&text)?;
        Ok(Self {
            r,
            header,
            offset: base + 4 + u64::from(len),
            record: 0,
            skipped,
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

    /// File offset of the next record.
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// The next record, `Ok(None)` at the end of the file.
    pub fn next_record(&mut self) -> Result<Option<Record>, CaptureError> {
        let (record, offset) = (self.record, self.offset);
        let truncated = |e: io::Error| {
            if e.kind() == io::ErrorKind::UnexpectedEof {
                CaptureError::TruncatedRecord { record, offset }
            } else {
                CaptureError::Io(e)
            }
        };
        let mut head = [0u8; 12];
        if !read_full(&mut self.r, &mut head).map_err(truncated)? {
            return Ok(None);
        }
        let t_ns = u64::from_le_bytes(head[..8].try_into().unwrap_or_default());
        let len_flags = u32::from_le_bytes(head[8..].try_into().unwrap_or_default());
        self.record += 1;
        if len_flags & LINK_RESET != 0 {
            self.offset += 12;
            return Ok(Some(Record::LinkReset { t_ns }));
        }
        if len_flags > MAX_RECORD_LEN {
            return Err(CaptureError::BadRecord {
                record,
                offset,
                len: len_flags,
            });
        }
        // Read through `take` so a corrupt length cannot make us allocate before data arrives.
        let mut bytes = Vec::new();
        (&mut self.r)
            .take(u64::from(len_flags))
            .read_to_end(&mut bytes)
            .map_err(truncated)?;
        if bytes.len() != len_flags as usize {
            return Err(CaptureError::TruncatedRecord { record, offset });
        }
        self.offset += 12 + u64::from(len_flags);
        Ok(Some(Record::Data { t_ns, bytes }))
    }
}

impl<R: Read> Iterator for CaptureReader<R> {
    type Item = Result<Record, CaptureError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_record().transpose()
    }
}
