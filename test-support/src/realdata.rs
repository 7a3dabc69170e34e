//! The real measured data beside the repository (`../shared/data`, read in place, never
//! copied): the one preamble of the tests that need it.

use std::path::PathBuf;

/// The `../shared/data` folder beside the repository, if it is there (no message).
pub fn shared_data_dir() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    p.is_dir().then_some(p)
}

/// The `../shared/data` folder for the test `test`: `Some(folder)` when present; when missing,
/// prints `SKIPPED {test}: ../shared/data not found` and returns `None`, except under
/// `CI=true`, where the data are required and their absence panics (the test fails).
pub fn real_data(test: &str) -> Option<PathBuf> {
    real_data_in(test, "")
}

/// [`real_data`] for a sub-folder of `../shared/data` (e.g. `"kfgins-parity"`): the path of
/// that sub-folder, or `None` after the SKIPPED line (a panic under `CI=true`).
pub fn real_data_in(test: &str, sub: &str) -> Option<PathBuf> {
    let found = shared_data_dir()
        .map(|d| if sub.is_empty() { d } else { d.join(sub) })
        .filter(|d| d.is_dir());
    let shown = if sub.is_empty() {
        "../shared/data".to_string()
    } else {
        format!("../shared/data/{sub}")
    };
    match found {
        Some(d) => Some(d),
        None if std::env::var("CI").as_deref() == Ok("true") => {
            panic!("{test}: {shown} not found, and CI=true requires it")
        }
        None => {
            println!("SKIPPED {test}: {shown} not found");
            None
        }
    }
}
