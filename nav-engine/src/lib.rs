#![doc = include_str!("../README.md")]
#![deny(missing_docs)]

pub mod metrics;
pub mod mounting;
pub mod run;
pub mod smooth;

pub use metrics::Metrics;
pub use run::execute::{execute, execute_case, execute_streaming};
pub use run::live::LiveRun;
pub use run::prepare::{load, load_checking_in_run, Loaded, Prepared, RunSpec};
pub use run::{run_engine, run_filter, CaseData, RunError, RunOptions, RunOutput, Streams};
