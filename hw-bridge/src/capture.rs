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
//! [`CaptureError::TruncatedRecord`] after returning every complete record.

use std::io::{self, Read, Write};

/// File magic.
pub const MAGIC: &[u8; 8] = b"HWBCAP1\n";
/// `len_flags` bit marking a link-reset event.
pub const LINK_RESET: u32 = 1 << 31;
/// Largest data length accepted in one record (a larger one means a corrupt file).
pub const MAX_RECORD_LEN: u32 = 16 << 20;

/// Errors reading a capture.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// I/O error.
    #[error("capture I/O: {0}")]
    Io(#[from] io::Error),
    /// Not a capture file.
    #[error("not a hw-bridge capture (bad magic {0:?})")]
    BadMagic([u8; 8]),
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
}

impl CaptureHeader {
    fn to_text(&self) -> String {
        format!(
            "port={}\nbaud={}\nstart_unix_ns={}\ntool={}\n",
            self.port.replace('\n', " "),
            self.baud,
            self.start_unix_ns,
            self.tool.replace('\n', " ")
        )
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
                "baud" => h.baud = num(v)? as u32,
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
    r: R,
    header: CaptureHeader,
    offset: u64,
    record: u64,
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

impl<R: Read> CaptureReader<R> {
    /// Reads magic and header.
    pub fn new(mut r: R) -> Result<Self, CaptureError> {
        let mut magic = [0u8; 8];
        if !read_full(&mut r, &mut magic)? || &magic != MAGIC {
            return Err(CaptureError::BadMagic(magic));
        }
        let mut len = [0u8; 4];
        read_full(&mut r, &mut len)?;
        let len = u32::from_le_bytes(len);
        if len > 1 << 20 {
            return Err(CaptureError::BadHeader(format!("header length {len}")));
        }
        let mut text = vec![0u8; len as usize];
        read_full(&mut r, &mut text)?;
        let text = String::from_utf8(text).map_err(|e| CaptureError::BadHeader(e.to_string()))?;
        let header = CaptureHeader::parse(&text)?;
        Ok(Self {
            r,
            header,
            offset: 12 + u64::from(len),
            record: 0,
        })
    }

    /// The header.
    pub fn header(&self) -> &CaptureHeader {
        &self.header
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
