//! The error type of every reader and writer in this crate.

use std::path::PathBuf;

/// What went wrong reading or writing a data or configuration file. Every variant names the
/// file; the ones about a place in the file name the 1-based line and, where it applies, the
/// 1-based column (field index on the line) and the column's meaning.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened or created.
    #[error("{}: cannot open: {source}", path.display())]
    Open {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A folder was given where a data file is read (the system would open it and fail at the
    /// first read with "Is a directory").
    #[error(
        "{} is a folder, not a data file{}",
        path.display(),
        given_as.as_deref().map(|g| format!(" (given as {g})")).unwrap_or_default()
    )]
    Folder {
        /// The folder.
        path: PathBuf,
        /// Where the path came from (a configuration key and file, a command-line flag), when
        /// known.
        given_as: Option<String>,
    },
    /// Reading failed part-way (I/O error, corrupt gzip stream); `line` 0 (not named) before
    /// the first line or in a binary file.
    #[error("{}{}: read error: {source}", path.display(), at_line(*line))]
    Read {
        /// The file.
        path: PathBuf,
        /// 1-based line being read.
        line: usize,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Writing failed.
    #[error("{}: write error: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A line is not valid UTF-8 text.
    #[error("{}: line {line}: not UTF-8 text", path.display())]
    NotText {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
    },
    /// A line has fewer fields than the format needs (a truncated line).
    #[error("{}: line {line}, column {column} ({name}): truncated line: {found} fields, expected {expected}", path.display())]
    TooFewFields {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column of the first missing field.
        column: usize,
        /// Meaning of the first missing column.
        name: String,
        /// Fields found on the line.
        found: usize,
        /// Fields expected (a description such as "7 or 8").
        expected: String,
    },
    /// A line has more fields than the format allows.
    #[error("{}: line {line}, column {column}: too many fields: {found}, expected {expected}", path.display())]
    TooManyFields {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column of the first unexpected field.
        column: usize,
        /// Fields found on the line.
        found: usize,
        /// Fields expected (a description such as "7 or 8").
        expected: String,
    },
    /// A numeric column holds something that is not a number.
    #[error("{}: line {line}, column {column} ({name}): not a number: {text:?}", path.display())]
    NotANumber {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Meaning of the column.
        name: String,
        /// The offending text (truncated to 40 characters).
        text: String,
    },
    /// A numeric column holds NaN or an infinity where a finite value is required.
    #[error("{}: line {line}, column {column} ({name}): value is not finite: {text:?}", path.display())]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Meaning of the column.
        name: String,
        /// The offending text.
        text: String,
    },
    /// A value is a number but outside what the column allows (negative sigma, |lat| > 90 deg,
    /// non-integer week, unknown quality flag, ...).
    #[error("{}: line {line}, column {column} ({name}): invalid value {text:?}: {reason}", path.display())]
    InvalidValue {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Meaning of the column.
        name: String,
        /// The offending text.
        text: String,
        /// Why it is invalid.
        reason: String,
    },
    /// Time does not increase strictly from one record to the next.
    #[error("{}: line {line}, column {column} ({name}): non-monotonic time: {t_s} s is not after the previous record's {prev_t_s} s (line {prev_line})", path.display())]
    NonMonotonicTime {
        /// The file.
        path: PathBuf,
        /// 1-based line of the offending record.
        line: usize,
        /// 1-based column of the time field.
        column: usize,
        /// Meaning of the time column.
        name: String,
        /// The offending time, s.
        t_s: f64,
        /// The previous record's time, s.
        prev_t_s: f64,
        /// 1-based line of the previous record.
        prev_line: usize,
    },
    /// The file's layout is not what the reader supports (header, time system, binary tag file
    /// structure, ...). `line` is 0 when the problem is not tied to a line.
    #[error("{}{}: {message}", path.display(), at_line(*line))]
    Format {
        /// The file.
        path: PathBuf,
        /// 1-based line (0: the file as a whole).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A configuration file (YAML/TOML) could not be parsed or holds inconsistent settings.
    #[error("{}: configuration error: {message}", path.display())]
    Config {
        /// The file.
        path: PathBuf,
        /// What is wrong (with the parser's line/column where it gives them).
        message: String,
        /// The parser's or serializer's own error, when it is the cause (TOML, YAML).
        #[source]
        source: Option<Box<dyn std::error::Error + Send + Sync + 'static>>,
    },
}

/// `": line N"` for a 1-based line, nothing for 0 (the file as a whole: never "line 0").
fn at_line(line: usize) -> String {
    if line == 0 {
        String::new()
    } else {
        format!(": line {line}")
    }
}

impl IoError {
    /// The error with where its path came from (`given_as`, e.g. "`[imu] path` in run.toml"),
    /// for an error about a folder given as a data file; any other error unchanged.
    pub fn given_as(self, origin: impl FnOnce() -> String) -> Self {
        match self {
            IoError::Folder {
                path,
                given_as: None,
            } => IoError::Folder {
                path,
                given_as: Some(origin()),
            },
            e => e,
        }
    }

    /// The file the error is about.
    pub fn path(&self) -> &std::path::Path {
        match self {
            IoError::Open { path, .. }
            | IoError::Folder { path, .. }
            | IoError::Read { path, .. }
            | IoError::Write { path, .. }
            | IoError::NotText { path, .. }
            | IoError::TooFewFields { path, .. }
            | IoError::TooManyFields { path, .. }
            | IoError::NotANumber { path, .. }
            | IoError::NonFinite { path, .. }
            | IoError::InvalidValue { path, .. }
            | IoError::NonMonotonicTime { path, .. }
            | IoError::Format { path, .. }
            | IoError::Config { path, .. } => path,
        }
    }

    /// The 1-based line the error is about, when it is about one.
    pub fn line(&self) -> Option<usize> {
        match self {
            IoError::NotText { line, .. }
            | IoError::TooFewFields { line, .. }
            | IoError::TooManyFields { line, .. }
            | IoError::NotANumber { line, .. }
            | IoError::NonFinite { line, .. }
            | IoError::InvalidValue { line, .. }
            | IoError::NonMonotonicTime { line, .. } => Some(*line),
            IoError::Format { line, .. } | IoError::Read { line, .. } if *line > 0 => Some(*line),
            _ => None,
        }
    }

    /// The 1-based column (field index) the error is about, when it is about one.
    pub fn column(&self) -> Option<usize> {
        match self {
            IoError::TooFewFields { column, .. }
            | IoError::TooManyFields { column, .. }
            | IoError::NotANumber { column, .. }
            | IoError::NonFinite { column, .. }
            | IoError::InvalidValue { column, .. }
            | IoError::NonMonotonicTime { column, .. } => Some(*column),
            _ => None,
        }
    }
}
