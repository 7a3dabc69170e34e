//! The integration tests of `nav-diagnose` in one test binary. Tests with a counting global
//! allocator (memory bounds) stay separate binaries in `tests/`.

mod diagmem;
mod diagnose_real;
mod diagnose_spill;
mod errors;
mod gnss_side;
mod heldout_rule;
mod run_memo;
mod vocabulary;
