//! Why a diagnosis could not run, or its files could not be written.
use std::path::PathBuf;

/// The error of [`crate::diagnose`] and of writing its files: the cause keeps its own error
/// (file and line of an input, sample of the record file, the run engine's error) as the
/// source.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// The temporary folder of the diagnosis's record files could not be created.
    #[error("creating a temporary folder for the diagnosis")]
    TempFolder(#[source] std::io::Error),
    /// An input, or a record file of the diagnosis, could not be read (or a navigation file
    /// written): the file and the line or record are in the error.
    #[error(transparent)]
    Io(#[from] nav_io::IoError),
    /// A filter run the diagnosis needs failed.
    #[error(transparent)]
    Run(#[from] nav_engine::run::RunError),
    /// The output folder could not be created.
    #[error("creating {}", path.display())]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// An output file could not be written.
    #[error("writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// The run configuration could not be read again (for `augmented.toml`).
    #[error("reading {}", path.display())]
    ReadConfig {
        /// The configuration file.
        path: PathBuf,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// The diagnosis could not be written as JSON (`diagnosis.json`).
    #[error("diagnosis.json")]
    Json(#[from] serde_json::Error),
    /// SIGINT or SIGTERM stopped the diagnosis (its runs ended at their next IMU read).
    #[error("diagnosis: interrupted by {signal}")]
    Interrupted {
        /// The signal's name.
        signal: String,
    },
    /// A tuned `[gnss]` key (`sigma_scale`, `error_state`) could not be written as TOML
    /// (`augmented.toml`).
    #[error("gnss.{key} of augmented.toml")]
    GnssKey {
        /// The key of `[gnss]`.
        key: &'static str,
        /// The serialiser's error.
        #[source]
        source: toml::ser::Error,
    },
}

/// `error: its source: ...`: an error with its chain of sources, each once (what
/// `diagnosis.json`'s warnings quote of a failed run).
pub(crate) fn chain(e: &dyn std::error::Error) -> String {
    let mut out = e.to_string();
    let mut src = e.source();
    while let Some(s) = src {
        out.push_str(": ");
        out.push_str(&s.to_string());
        src = s.source();
    }
    out
}
