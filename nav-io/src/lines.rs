//! Line-oriented text input shared by the readers: gzip detection, comment skipping, field
//! splitting and number parsing with errors that name file, line and column.
//!
//! Nothing is allocated per line: the reader keeps one line buffer, a line's fields are
//! `&str` slices of it held in a fixed array ([`Fields`], a heap vector only for lines of more
//! than [`Fields::INLINE`] fields), and numbers are parsed with `fast-float2` (correctly
//! rounded: bit-identical to `str::parse::<f64>`, checked by a property test), falling back to
//! the standard library for the spellings it leaves out (`nan`, `inf`, ...).

use super::IoError;
use flate2::read::MultiGzDecoder;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// The UTF-8 byte-order mark, skipped at the start of a text file.
const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// Longest accepted line, bytes; longer lines are reported as a format error (binary input).
const MAX_LINE_BYTES: usize = 1 << 20;

/// Bytes asked of the source per read (the buffer grows beyond it only for longer lines).
const CHUNK_BYTES: usize = 1 << 17;

/// A text file read line by line (gzip or plain), counting 1-based line numbers. `Send`: a
/// reader can be moved to another thread.
///
/// The bytes are read in chunks of 128 KiB into one buffer and the lines are found
/// in it with `memchr` (no per-line read call, no copy of a line); a line's text is a slice
/// of the buffer.
pub struct LineReader {
    path: PathBuf,
    inner: Box<dyn Read + Send>,
    line: usize,
    /// Read buffer: `buf[start..end]` is not yet consumed (its length is the allocation,
    /// zeroed once).
    buf: Vec<u8>,
    start: usize,
    end: usize,
    /// The current line (terminators removed): `buf[cur.0..cur.1]`.
    cur: (usize, usize),
    eof: bool,
    /// The current line is the last one and has no line end (a file still being written, or
    /// cut short).
    unterminated: bool,
}

/// Opens the data file `path` for reading; a folder under that name is
/// [`IoError::Folder`] (checked before and after opening: a folder can be opened on some
/// systems and fails only at the first read).
pub fn open_data_file(path: &Path) -> Result<File, IoError> {
    let folder = || IoError::Folder {
        path: path.to_path_buf(),
        given_as: None,
    };
    if std::fs::metadata(path).is_ok_and(|m| m.is_dir()) {
        return Err(folder());
    }
    let f = File::open(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    if f.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(folder());
    }
    Ok(f)
}

/// Opens `path` for line reading; gzip is detected from the magic bytes `1f 8b`.
pub fn open_text(path: &Path) -> Result<LineReader, IoError> {
    let f = open_data_file(path)?;
    LineReader::from_reader(path, f)
}

impl LineReader {
    /// Wraps any byte source; `name` is used in error messages. Gzip is detected from the
    /// magic bytes.
    pub fn from_reader<R: Read + Send + 'static>(name: &Path, src: R) -> Result<Self, IoError> {
        let mut br = BufReader::with_capacity(1 << 16, src);
        let head = br.fill_buf().map_err(|source| IoError::Read {
            path: name.to_path_buf(),
            line: 1,
            source,
        })?;
        let gz = head.len() >= 2 && head[0] == 0x1f && head[1] == 0x8b;
        let inner: Box<dyn Read + Send> = if gz {
            Box::new(MultiGzDecoder::new(br))
        } else {
            Box::new(br)
        };
        Ok(Self {
            path: name.to_path_buf(),
            inner,
            line: 0,
            buf: vec![0; CHUNK_BYTES],
            start: 0,
            end: 0,
            cur: (0, 0),
            eof: false,
            unterminated: false,
        })
    }

    /// The file name used in errors.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// 1-based number of the line returned last (0 before the first).
    pub fn line_number(&self) -> usize {
        self.line
    }

    /// Reads more bytes after `end` (the unconsumed part moved to the front first; the buffer
    /// doubled when that part fills it). Sets `eof` when the source is exhausted.
    fn fill(&mut self) -> Result<(), IoError> {
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        if self.end == self.buf.len() {
            let n = self.buf.len().max(CHUNK_BYTES);
            self.buf.resize(2 * n, 0);
        }
        let dst = self.buf.get_mut(self.end..).unwrap_or(&mut []);
        loop {
            match self.inner.read(dst) {
                Ok(0) => {
                    self.eof = true;
                    return Ok(());
                }
                Ok(n) => {
                    self.end += n;
                    return Ok(());
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(source) => {
                    return Err(IoError::Read {
                        path: self.path.clone(),
                        line: self.line,
                        source,
                    })
                }
            }
        }
    }

    /// Moves to the next line (its bytes in `cur`, terminators `\n` and trailing `\r`
    /// removed); false at the end of the file. A line of more than [`MAX_LINE_BYTES`] bytes
    /// (with its `\n`) is a format error.
    pub(crate) fn advance(&mut self) -> Result<bool, IoError> {
        self.line += 1;
        let too_long = |s: &Self| IoError::Format {
            path: s.path.clone(),
            line: s.line,
            message: format!("line longer than {MAX_LINE_BYTES} bytes (not a text file?)"),
        };
        let (a, mut b) = loop {
            let avail = self.buf.get(self.start..self.end).unwrap_or(&[]);
            if let Some(i) = memchr::memchr(b'\n', avail) {
                if i + 1 > MAX_LINE_BYTES {
                    return Err(too_long(self));
                }
                let a = self.start;
                self.start = a + i + 1;
                self.unterminated = false;
                break (a, a + i);
            }
            if avail.len() > MAX_LINE_BYTES {
                return Err(too_long(self));
            }
            if self.eof {
                if avail.is_empty() {
                    self.line -= 1;
                    return Ok(false);
                }
                let a = self.start;
                self.start = self.end;
                self.unterminated = true;
                break (a, self.end);
            }
            self.fill()?;
        };
        // a UTF-8 byte-order mark (written by some Windows tools) before the first line
        let a = if self.line == 1 && self.buf.get(a..b).is_some_and(|l| l.starts_with(UTF8_BOM)) {
            a + UTF8_BOM.len()
        } else {
            a
        };
        while b > a && matches!(self.buf.get(b - 1), Some(b'\r' | b'\n')) {
            b -= 1;
        }
        self.cur = (a, b);
        Ok(true)
    }

    /// Whether the current line is the last one of the file and has no line end: a line that
    /// may have been cut short (a log still being written). The readers drop such a line when
    /// it does not parse instead of failing (see [`incomplete_last_line`]).
    pub fn at_unterminated_end(&self) -> bool {
        self.unterminated
    }

    /// The bytes of the current line (terminators removed).
    pub(crate) fn current_bytes(&self) -> &[u8] {
        self.buf.get(self.cur.0..self.cur.1).unwrap_or(&[])
    }

    /// The current line as text (an error when it is not UTF-8).
    fn current_str(&self) -> Result<&str, IoError> {
        std::str::from_utf8(self.current_bytes()).map_err(|_| IoError::NotText {
            path: self.path.clone(),
            line: self.line,
        })
    }

    /// The current line split into fields, or `None` when it is blank or a comment (see
    /// [`LineReader::next_data`]); an error when it is not UTF-8.
    pub(crate) fn current_data(&self) -> Result<Option<DataLine<'_>>, IoError> {
        let text = self.current_str()?;
        if is_skippable(text) {
            return Ok(None);
        }
        Ok(Some(DataLine::new(&self.path, self.line, text)))
    }

    /// The next line, whatever it holds (line terminator removed), with its 1-based number;
    /// `None` at the end of the file.
    pub fn next_raw(&mut self) -> Result<Option<(usize, &str)>, IoError> {
        if !self.advance()? {
            return Ok(None);
        }
        Ok(Some((self.line, self.current_str()?)))
    }

    /// The next data line: blank lines and comment lines (first non-blank character `#` or
    /// `%`) are skipped. `None` at the end of the file.
    pub fn next_data(&mut self) -> Result<Option<DataLine<'_>>, IoError> {
        loop {
            if !self.advance()? {
                return Ok(None);
            }
            if !is_skippable(self.current_str()?) {
                break;
            }
        }
        // The line was validated as UTF-8 above; validate again rather than keep an
        // unsafe unchecked conversion (a few ns per line).
        self.current_data()
    }
}

/// Whether `e`, met on the current line of `rd`, is about a last line cut short: the line has
/// no line end and does not parse (a log still being written). The readers end there instead
/// of failing; [`incomplete_last_line`] names it for the user.
pub(crate) fn cut_short(rd: &LineReader, e: &IoError) -> bool {
    rd.at_unterminated_end()
        && matches!(
            e,
            IoError::TooFewFields { .. }
                | IoError::NotANumber { .. }
                | IoError::NonFinite { .. }
                | IoError::InvalidValue { .. }
                | IoError::NotText { .. }
                | IoError::NonMonotonicTime { .. }
        )
}

/// Whether a line is blank or a comment (`#` or `%` first).
pub(crate) fn is_skippable(line: &str) -> bool {
    let t = line.trim_start();
    t.is_empty() || t.starts_with('#') || t.starts_with('%')
}

/// Splits a line into fields: on commas when it holds one (fields trimmed, one trailing empty
/// field dropped), otherwise on white space.
pub(crate) fn split_fields(line: &str) -> Fields<'_> {
    let mut f = Fields::new();
    if line.as_bytes().contains(&b',') {
        for x in line.split(',') {
            f.push(x.trim());
        }
        if f.len() > 1 && f.last().is_some_and(|s| s.is_empty()) {
            f.pop();
        }
    } else if line.is_ascii() {
        for x in line.split_ascii_whitespace() {
            f.push(x);
        }
    } else {
        for x in line.split_whitespace() {
            f.push(x);
        }
    }
    f
}

/// The fields of one line, as `&str` slices of it: up to [`Fields::INLINE`] in a fixed array
/// (no allocation), more in a vector. Dereferences to `[&str]`.
#[derive(Debug, Clone)]
pub struct Fields<'a> {
    inline: [&'a str; Fields::INLINE],
    len: usize,
    spill: Vec<&'a str>,
}

impl Fields<'_> {
    /// Fields held without allocation.
    pub const INLINE: usize = 24;
}

impl<'a> Fields<'a> {
    /// No fields.
    pub fn new() -> Self {
        Self {
            inline: [""; Fields::INLINE],
            len: 0,
            spill: Vec::new(),
        }
    }

    /// Appends a field.
    pub fn push(&mut self, f: &'a str) {
        if !self.spill.is_empty() {
            self.spill.push(f);
        } else if let Some(slot) = self.inline.get_mut(self.len) {
            *slot = f;
            self.len += 1;
        } else {
            self.spill.reserve(2 * Fields::INLINE);
            self.spill.extend_from_slice(&self.inline);
            self.spill.push(f);
        }
    }

    /// Removes the last field.
    pub fn pop(&mut self) -> Option<&'a str> {
        if self.spill.is_empty() {
            let last = self.len.checked_sub(1)?;
            self.len = last;
            self.inline.get(last).copied()
        } else {
            self.spill.pop()
        }
    }
}

impl Default for Fields<'_> {
    fn default() -> Self {
        Self::new()
    }
}

impl<'a> std::ops::Deref for Fields<'a> {
    type Target = [&'a str];

    fn deref(&self) -> &[&'a str] {
        if self.spill.is_empty() {
            self.inline.get(..self.len).unwrap_or(&[])
        } else {
            &self.spill
        }
    }
}

impl<'a> FromIterator<&'a str> for Fields<'a> {
    fn from_iter<I: IntoIterator<Item = &'a str>>(iter: I) -> Self {
        let mut f = Fields::new();
        for x in iter {
            f.push(x);
        }
        f
    }
}

impl<'a> From<Vec<&'a str>> for Fields<'a> {
    fn from(v: Vec<&'a str>) -> Self {
        v.into_iter().collect()
    }
}

/// Parses a decimal number exactly as `str::parse::<f64>` does (same accepted texts, same
/// bits): `fast-float2` for texts made of digits, signs, `.` and `e`/`E` (correctly rounded,
/// as the standard library), the standard library for everything else (`nan`, `inf`, errors).
pub fn parse_f64(s: &str) -> Option<f64> {
    let b = s.as_bytes();
    let plain = b
        .iter()
        .all(|c| matches!(c, b'0'..=b'9' | b'.' | b'-' | b'+' | b'e' | b'E'));
    if plain {
        if let Ok(v) = fast_float2::parse::<f64, _>(b) {
            return Some(v);
        }
    }
    s.parse().ok()
}

/// One data line split into fields, with helpers that parse a field and report errors with
/// file, line and column.
pub struct DataLine<'a> {
    /// The file.
    pub path: &'a Path,
    /// 1-based line number.
    pub line: usize,
    /// The fields (see `split_fields`): `&str` slices of the line, no allocation for up to
    /// [`Fields::INLINE`] fields.
    pub fields: Fields<'a>,
}

fn clip(s: &str) -> String {
    s.chars().take(40).collect()
}

impl<'a> DataLine<'a> {
    /// Splits `text` (line `line` of `path`) into fields.
    pub fn new(path: &'a Path, line: usize, text: &'a str) -> Self {
        Self {
            path,
            line,
            fields: split_fields(text),
        }
    }

    /// Number of fields.
    pub fn len(&self) -> usize {
        self.fields.len()
    }

    /// Whether the line has no fields.
    pub fn is_empty(&self) -> bool {
        self.fields.is_empty()
    }

    /// Checks the field count is in `min..=max`; `names[i]` is the meaning of column i+1 (used
    /// to name the first missing column).
    pub fn require(&self, min: usize, max: usize, names: &[&str]) -> Result<(), IoError> {
        // built only for an error: nothing is allocated for a good line
        let expected = || {
            if min == max {
                format!("{min}")
            } else if max == usize::MAX {
                format!("at least {min}")
            } else {
                format!("{min} to {max}")
            }
        };
        if self.fields.len() < min {
            let col = self.fields.len();
            return Err(IoError::TooFewFields {
                path: self.path.to_path_buf(),
                line: self.line,
                column: col + 1,
                name: names.get(col).copied().unwrap_or("?").to_string(),
                found: self.fields.len(),
                expected: expected(),
            });
        }
        if self.fields.len() > max {
            return Err(IoError::TooManyFields {
                path: self.path.to_path_buf(),
                line: self.line,
                column: max + 1,
                found: self.fields.len(),
                expected: expected(),
            });
        }
        Ok(())
    }

    /// The error for a field `idx` (0-based) that is present but wrong.
    pub fn invalid(&self, idx: usize, name: &str, reason: impl Into<String>) -> IoError {
        IoError::InvalidValue {
            path: self.path.to_path_buf(),
            line: self.line,
            column: idx + 1,
            name: name.to_string(),
            text: clip(self.fields.get(idx).copied().unwrap_or("")),
            reason: reason.into(),
        }
    }

    fn missing(&self, idx: usize, name: &str) -> IoError {
        IoError::TooFewFields {
            path: self.path.to_path_buf(),
            line: self.line,
            column: idx + 1,
            name: name.to_string(),
            found: self.fields.len(),
            expected: format!("at least {}", idx + 1),
        }
    }

    /// Parses field `idx` (0-based) as a number that may be NaN (written "nan"/"NaN") but not
    /// infinite.
    pub fn num_allow_nan(&self, idx: usize, name: &str) -> Result<f64, IoError> {
        let s = *self
            .fields
            .get(idx)
            .ok_or_else(|| self.missing(idx, name))?;
        let v: f64 = parse_f64(s).ok_or_else(|| IoError::NotANumber {
            path: self.path.to_path_buf(),
            line: self.line,
            column: idx + 1,
            name: name.to_string(),
            text: clip(s),
        })?;
        if v.is_infinite() {
            return Err(IoError::NonFinite {
                path: self.path.to_path_buf(),
                line: self.line,
                column: idx + 1,
                name: name.to_string(),
                text: clip(s),
            });
        }
        Ok(v)
    }

    /// Parses field `idx` (0-based) as a finite number.
    pub fn num(&self, idx: usize, name: &str) -> Result<f64, IoError> {
        let v = self.num_allow_nan(idx, name)?;
        if v.is_nan() {
            return Err(IoError::NonFinite {
                path: self.path.to_path_buf(),
                line: self.line,
                column: idx + 1,
                name: name.to_string(),
                text: clip(self.fields.get(idx).copied().unwrap_or("")),
            });
        }
        Ok(v)
    }

    /// Parses field `idx` as a finite, non-negative number (a standard deviation).
    pub fn sigma(&self, idx: usize, name: &str) -> Result<f64, IoError> {
        let v = self.num(idx, name)?;
        if v < 0.0 {
            return Err(self.invalid(idx, name, "a standard deviation cannot be negative"));
        }
        Ok(v)
    }

    /// Parses field `idx` as a latitude in degrees (finite, |lat| <= 90).
    pub fn lat_deg(&self, idx: usize, name: &str) -> Result<f64, IoError> {
        let v = self.num(idx, name)?;
        if v.abs() > 90.0 {
            return Err(self.invalid(idx, name, "latitude outside [-90, 90] deg"));
        }
        Ok(v)
    }

    /// Parses field `idx` as a longitude in degrees (finite, |lon| <= 360).
    pub fn lon_deg(&self, idx: usize, name: &str) -> Result<f64, IoError> {
        let v = self.num(idx, name)?;
        if v.abs() > 360.0 {
            return Err(self.invalid(idx, name, "longitude outside [-360, 360] deg"));
        }
        Ok(v)
    }

    /// Parses field `idx` as an integer in `min..=max` (written as an integer or an integral
    /// decimal such as `1.0000000`, as RTKLIB writes its Q flag).
    pub fn integer(&self, idx: usize, name: &str, min: i64, max: i64) -> Result<i64, IoError> {
        let v = self.num(idx, name)?;
        if v.fract() != 0.0 || v < min as f64 || v > max as f64 {
            return Err(self.invalid(idx, name, format!("expected an integer in {min}..={max}")));
        }
        Ok(v as i64)
    }
}

/// Tracks strictly increasing time across records and reports the first violation.
pub(crate) struct MonotonicTime {
    prev: Option<(f64, usize)>,
}

impl MonotonicTime {
    pub(crate) fn new() -> Self {
        Self { prev: None }
    }

    /// Whether `t_s` (of line `line`) is after the previous time; if so it becomes the
    /// previous time (as [`MonotonicTime::check`] does), otherwise nothing changes (the
    /// caller reports the error with `check`).
    pub(crate) fn accept(&mut self, line: usize, t_s: f64) -> bool {
        if let Some((p, _)) = self.prev {
            if t_s <= p {
                return false;
            }
        }
        self.prev = Some((t_s, line));
        true
    }

    /// Checks `t_s` (on `dl`'s line, column `idx` 0-based) is after the previous time.
    pub(crate) fn check(
        &mut self,
        dl: &DataLine<'_>,
        idx: usize,
        name: &str,
        t_s: f64,
    ) -> Result<(), IoError> {
        if let Some((p, pl)) = self.prev {
            if t_s <= p {
                return Err(IoError::NonMonotonicTime {
                    path: dl.path.to_path_buf(),
                    line: dl.line,
                    column: idx + 1,
                    name: name.to_string(),
                    t_s,
                    prev_t_s: p,
                    prev_line: pl,
                });
            }
        }
        self.prev = Some((t_s, dl.line));
        Ok(())
    }
}

/// The last line of a text file when it has no line end and fewer fields than the line
/// before it: a line cut short (a log still being written). The readers drop such a line
/// (it does not parse) instead of failing; this tells the user about it before a run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IncompleteLine {
    /// The file.
    pub path: PathBuf,
    /// The line's number in the file (1-based).
    pub line: usize,
    /// Byte offset of the line's start in the file.
    pub offset: u64,
    /// The line's text (at most 40 characters).
    pub text: String,
    /// Fields on the line.
    pub fields: usize,
    /// Fields on the complete line before it.
    pub expected: usize,
}

impl std::fmt::Display for IncompleteLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: line {}, the last line (byte offset {}), is incomplete, {} field(s) where the \
             line before has {}, and no line end: {:?} dropped (is the file still being written?)",
            self.path.display(),
            self.line,
            self.offset,
            self.fields,
            self.expected,
            self.text
        )
    }
}

/// Bytes read from the end of a file by [`incomplete_last_line`].
const TAIL_BYTES: u64 = 1 << 16;

/// The cut-short last line of the plain text file `path` ([`IncompleteLine`]), when there is
/// one: only the file's last 64 KiB are read. `None` for a gzip file, a file whose last line
/// ends with a line end or is as long (in fields) as the one before it.
pub fn incomplete_last_line(path: &Path) -> Result<Option<IncompleteLine>, IoError> {
    use std::io::{Seek, SeekFrom};
    let mut f = open_data_file(path)?;
    let read_err = |source| IoError::Read {
        path: path.to_path_buf(),
        line: 1,
        source,
    };
    let len = f.seek(SeekFrom::End(0)).map_err(read_err)?;
    let mut head = [0u8; 2];
    f.seek(SeekFrom::Start(0)).map_err(read_err)?;
    if len >= 2 {
        f.read_exact(&mut head).map_err(read_err)?;
        if head == [0x1f, 0x8b] {
            return Ok(None);
        }
    }
    let from = len.saturating_sub(TAIL_BYTES);
    f.seek(SeekFrom::Start(from)).map_err(read_err)?;
    let mut tail = Vec::new();
    (&mut f)
        .take(TAIL_BYTES)
        .read_to_end(&mut tail)
        .map_err(read_err)?;
    if tail.is_empty() || tail.ends_with(b"\n") {
        return Ok(None);
    }
    let Some(nl) = memchr::memrchr(b'\n', &tail) else {
        return Ok(None);
    };
    let (before, last) = tail.split_at(nl + 1);
    let last_text = String::from_utf8_lossy(last);
    let prev = before
        .strip_suffix(b"\n")
        .map(|b| b.strip_suffix(b"\r").unwrap_or(b))
        .unwrap_or(before);
    let prev_start = memchr::memrchr(b'\n', prev).map_or(0, |i| i + 1);
    let prev_text = String::from_utf8_lossy(prev.get(prev_start..).unwrap_or(&[]));
    if is_skippable(&prev_text) || is_skippable(&last_text) {
        return Ok(None);
    }
    let (fields, expected) = (
        split_fields(&last_text).len(),
        split_fields(&prev_text).len(),
    );
    if fields >= expected {
        return Ok(None);
    }
    // the line's number: the line ends before it (the file is read once more, only when it
    // ends with a line cut short)
    f.seek(SeekFrom::Start(0)).map_err(read_err)?;
    let mut ends = memchr::memchr_iter(b'\n', before).count();
    let mut buf = vec![0u8; 1 << 16];
    let mut rest = from;
    while rest > 0 {
        let n = usize::try_from(rest.min(buf.len() as u64)).unwrap_or(buf.len());
        let chunk = buf.get_mut(..n).unwrap_or_default();
        f.read_exact(chunk).map_err(read_err)?;
        ends += memchr::memchr_iter(b'\n', chunk).count();
        rest -= n as u64;
    }
    Ok(Some(IncompleteLine {
        path: path.to_path_buf(),
        line: ends + 1,
        offset: from + (nl as u64) + 1,
        text: clip(&last_text),
        fields,
        expected,
    }))
}
