#![doc = include_str!("../README.md")]

pub mod builder;
pub mod case;
pub mod errors;
pub mod heading;
pub mod motion;
pub mod noise;
pub mod odometer;
pub mod scenario;
pub mod trajectory;
pub mod undeclared;

pub use builder::ScenarioBuilder;
pub use case::{simulate, Case, CaseFile, SimError};
pub use errors::{ErrorModel, Measurements};
pub use motion::{BodyKinematics, Integrator, Motion};
pub use scenario::{Scenario, ScenarioError};
pub use trajectory::Trajectory;
