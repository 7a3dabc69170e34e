//! Motion scenarios, truth and ideal IMU increments by inverse mechanization, sensor and GNSS
//! error generation, and `host-sim simulate`.
//!
//! The split is explicit so Monte Carlo studies pay for the trajectory once:
//! [`Trajectory::generate`] integrates a [`Scenario`] (error-free truth and increments), then
//! [`ErrorModel::apply`] adds one seeded error realisation. [`simulate`] does both and returns
//! a [`Case`] in memory; [`Case::write`] writes it in the project's file formats.
pub mod case;
pub mod cli;
pub mod errors;
pub mod odometer;
pub mod plot;
pub mod scenario;
pub mod trajectory;
pub mod undeclared;

pub use case::{simulate, Case, CaseFile, SimError};
pub use errors::{ErrorModel, Measurements};
pub use scenario::Scenario;
pub use trajectory::Trajectory;
