//! nav-study's integration tests, one module per topic (one test binary for the crate).

mod errors;
mod study_reduced;
