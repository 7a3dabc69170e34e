//! noise-id's integration tests, one binary: one module per topic.

mod allan_covariance;
mod allan_reference;
mod common;
mod model_check;
mod outliers;
