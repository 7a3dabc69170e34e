//! The integration tests of `integration-tests` in one test binary: one build and one link instead of one
//! per file. Tests with a counting global allocator (memory bounds) stay separate binaries
//! in `tests/`.

mod bridge_replay;
mod earth_consistency;
mod real_drive;
mod sim_mechanization;
