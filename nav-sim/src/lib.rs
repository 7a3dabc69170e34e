#![doc = include_str!("../README.md")]

pub mod builder;
pub mod motion;
pub mod scenario;
pub mod trajectory;

pub use builder::ScenarioBuilder;
pub use motion::{BodyKinematics, Integrator, Motion};
pub use scenario::{Scenario, ScenarioError};
pub use trajectory::Trajectory;
