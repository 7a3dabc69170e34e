//! The diagnosis report (Markdown with PNG plots) and the augmented configuration.
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;

use super::{DiagnoseOutput, Diagnosis};
use crate::run::cli::Prepared;

/// Writes `report.md` into `dir`.
pub fn write_report(dir: &Path, _p: &Prepared, d: &DiagnoseOutput) -> anyhow::Result<()> {
    let dg = &d.diagnosis;
    let mut s = String::new();
    let _ = writeln!(s, "# Diagnosis\n\nVerdict: **{}**\n", dg.verdict);
    let path = dir.join("report.md");
    std::fs::write(&path, s).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Writes the augmented configuration into `dir` (not yet).
pub fn write_augmented_config(_dir: &Path, _config: &Path, _d: &Diagnosis) -> anyhow::Result<()> {
    Ok(())
}
