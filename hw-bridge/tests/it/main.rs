//! The integration tests of `hw-bridge` in one test binary: one build and one link instead of one
//! per file. Tests with a counting global allocator (memory bounds) stay separate binaries
//! in `tests/`.

mod capture_format;
mod capture_gaps;
mod e2e_pty;
mod faults;
mod fuzz_corpus;
mod link;
mod outputs_safety;
mod record_safety;
mod simcase;
mod status_line;
