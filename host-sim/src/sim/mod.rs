//! `host-sim simulate`: motion scenarios and their truth and ideal IMU increments (the crate
//! `nav-sim`, re-exported here as `scenario` and `trajectory`), sensor and GNSS error
//! generation, case files.
//!
//! The split is explicit so Monte Carlo studies pay for the trajectory once:
//! [`Trajectory::generate`] integrates a [`Scenario`] (error-free truth and increments), then
//! [`ErrorModel::apply`] adds one seeded error realisation. [`simulate`] does both and returns
//! a [`Case`] in memory; [`Case::write`] writes it in the project's file formats.
pub mod case;
pub mod cli;
pub mod errors;
pub mod heading;
pub mod odometer;
pub mod plot;
/// The scenario format and its kinematic profiles (in `nav-sim`).
pub use nav_sim::scenario;
/// The truth generator (in `nav-sim`).
pub use nav_sim::trajectory;
pub mod undeclared;

pub use case::{simulate, Case, CaseFile, SimError};
pub use errors::{ErrorModel, Measurements};
pub use scenario::Scenario;
pub use trajectory::Trajectory;
