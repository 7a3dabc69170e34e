//! Line-oriented text input shared by the readers: gzip detection, comment skipping, field
//! splitting and number parsing with errors that name file, line and column.

use super::IoError;
use flate2::read::MultiGzDecoder;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// Longest accepted line, bytes; longer lines are reported as a format error (binary input).
const MAX_LINE_BYTES: usize = 1 << 20;

/// A text file read line by line (gzip or plain), counting 1-based line numbers.
pub struct LineReader {
    path: PathBuf,
    inner: Box<dyn BufRead>,
    line: usize,
    buf: Vec<u8>,
    text: String,
}

/// Opens `path` for line reading; gzip is detected from the magic bytes `1f 8b`.
pub fn open_text(path: &Path) -> Result<LineReader, IoError> {
    let f = File::open(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    LineReader::from_reader(path, f)
}

impl LineReader {
    /// Wraps any byte source; `name` is used in error messages. Gzip is detected from the
    /// magic bytes.
    pub fn from_reader<R: Read + 'static>(name: &Path, src: R) -> Result<Self, IoError> {
        let mut br = BufReader::with_capacity(1 << 16, src);
        let head = br.fill_buf().map_err(|source| IoError::Read {
            path: name.to_path_buf(),
            line: 1,
            source,
        })?;
        let gz = head.len() >= 2 && head[0] == 0x1f && head[1] == 0x8b;
        let inner: Box<dyn BufRead> = if gz {
            Box::new(BufReader::with_capacity(1 << 16, MultiGzDecoder::new(br)))
        } else {
            Box::new(br)
        };
        Ok(Self {
            path: name.to_path_buf(),
            inner,
            line: 0,
            buf: Vec::new(),
            text: String::new(),
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

    /// The next line, whatever it holds (line terminator removed), with its 1-based number;
    /// `None` at the end of the file.
    pub fn next_raw(&mut self) -> Result<Option<(usize, &str)>, IoError> {
        self.buf.clear();
        self.line += 1;
        let n = (&mut self.inner)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut self.buf)
            .map_err(|source| IoError::Read {
                path: self.path.clone(),
                line: self.line,
                source,
            })?;
        if n == 0 {
            self.line -= 1;
            return Ok(None);
        }
        if self.buf.len() > MAX_LINE_BYTES {
            return Err(IoError::Format {
                path: self.path.clone(),
                line: self.line,
                message: format!("line longer than {MAX_LINE_BYTES} bytes (not a text file?)"),
            });
        }
        while matches!(self.buf.last(), Some(b'\n' | b'\r')) {
            self.buf.pop();
        }
        self.text.clear();
        match std::str::from_utf8(&self.buf) {
            Ok(s) => self.text.push_str(s),
            Err(_) => {
                return Err(IoError::NotText {
                    path: self.path.clone(),
                    line: self.line,
                })
            }
        }
        Ok(Some((self.line, self.text.as_str())))
    }

    /// The next data line: blank lines and comment lines (first non-blank character `#` or
    /// `%`) are skipped. `None` at the end of the file.
    pub fn next_data(&mut self) -> Result<Option<DataLine<'_>>, IoError> {
        loop {
            match self.next_raw()? {
                None => return Ok(None),
                Some((_, t)) if is_skippable(t) => continue,
                Some(_) => break,
            }
        }
        Ok(Some(DataLine::new(&self.path, self.line, &self.text)))
    }
}

/// Whether a line is blank or a comment (`#` or `%` first).
pub(crate) fn is_skippable(line: &str) -> bool {
    let t = line.trim_start();
    t.is_empty() || t.starts_with('#') || t.starts_with('%')
}

/// Splits a line into fields: on commas when it holds one (fields trimmed, one trailing empty
/// field dropped), otherwise on white space.
pub(crate) fn split_fields(line: &str) -> Vec<&str> {
    if line.contains(',') {
        let mut v: Vec<&str> = line.split(',').map(str::trim).collect();
        if v.len() > 1 && v.last().is_some_and(|s| s.is_empty()) {
            v.pop();
        }
        v
    } else {
        line.split_whitespace().collect()
    }
}

/// One data line split into fields, with helpers that parse a field and report errors with
/// file, line and column.
pub struct DataLine<'a> {
    /// The file.
    pub path: &'a Path,
    /// 1-based line number.
    pub line: usize,
    /// The fields (see [`split_fields`]).
    pub fields: Vec<&'a str>,
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
        let expected = if min == max {
            format!("{min}")
        } else if max == usize::MAX {
            format!("at least {min}")
        } else {
            format!("{min} to {max}")
        };
        if self.fields.len() < min {
            let col = self.fields.len();
            return Err(IoError::TooFewFields {
                path: self.path.to_path_buf(),
                line: self.line,
                column: col + 1,
                name: names.get(col).copied().unwrap_or("?").to_string(),
                found: self.fields.len(),
                expected,
            });
        }
        if self.fields.len() > max {
            return Err(IoError::TooManyFields {
                path: self.path.to_path_buf(),
                line: self.line,
                column: max + 1,
                found: self.fields.len(),
                expected,
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
        let v: f64 = s.parse().map_err(|_| IoError::NotANumber {
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
