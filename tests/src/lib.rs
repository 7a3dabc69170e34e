//! Shared helpers for the cross-crate integration tests in `tests/tests/`.

use std::path::PathBuf;

/// The `../shared/data` folder beside the repository, if present. Tests that need it call
/// [`shared_data_or_skip`].
pub fn shared_data() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    p.is_dir().then_some(p)
}

/// The shared data folder; in CI (`CI=true`) its absence is a failure, elsewhere the test is
/// skipped with a visible message (returns `None`).
pub fn shared_data_or_skip(test: &str) -> Option<PathBuf> {
    match shared_data() {
        Some(p) => Some(p),
        None if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("{test}: ../shared/data is missing, and CI=true requires it")
        }
        None => {
            eprintln!("SKIPPED {test}: ../shared/data not found beside the repository");
            None
        }
    }
}
