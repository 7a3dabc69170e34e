//! noise-id's integration tests, one binary: one module per topic.

mod allan_covariance;
mod allan_fit_recovery;
mod allan_reference;
mod allan_stream_agrees;
mod common;
mod model_check;
mod noise_allan_mc;
mod outliers;
