#![doc = include_str!("../README.md")]

pub mod alloc;
pub mod cli;
pub mod csvcase;
pub mod filter_sim;
pub mod realdata;
pub mod runcase;
pub mod scenario;
pub mod standing;
pub mod trajectory;
pub mod transition;
pub mod truth_start;

/// Chi-square statistics for consistency bands: the workspace's one definition.
pub use noise_id::stats;

pub use realdata::{real_data, real_data_in};
