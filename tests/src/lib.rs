//! The cross-crate integration tests live in `tests/tests/`; their shared helpers are
//! `test-support`'s (the real data beside the repository: `test_support::real_data`).
