//! `cargo xtask hostile`: the careless and hostile inputs of `host-sim run` and `hw-bridge
//! replay` / `record`, re-run as a family table. Each try runs a release binary with a time
//! limit (killed past it) and is judged:
//!
//! - **panic**: exit 101 or a panic message;
//! - **hang**: killed at the time limit;
//! - **silent wrong result**: exit 0 where an error or a warning naming the cause was due
//!   (nothing on stderr), or a solution that differs from the undamaged input's where the
//!   damage must change nothing;
//! - **lost or clobbered file**: an input, a previous output or a file a link points at whose
//!   content hash changed;
//! - **message without file and line**: an error about a file's content that does not name
//!   the file and the line (or the byte offset of a capture);
//! - **other**: an unexpected exit code or a cause not named.
//!
//! The families: outputs (the output folder at the inputs, links at output names, two runs
//! at once, an interrupted run), unbounded option values, all GNSS unusable (sigmas 0, fixes
//! out of the IMU span, an empty file), careless data (g read as m/s^2, 100 Hz increments
//! stamped at 200 Hz, GNSS 0.5 s late, a half-written last IMU line, a duplicated IMU line, a
//! bad truth line, UTF-8 byte-order marks), bad configuration values, damaged captures
//! (chunked, corrupt, truncated), and `record --out` at an existing capture, a link or the
//! port. The case is `scenarios/land_stops.toml` simulated with a tactical IMU (8 minutes).
//! Exits non-zero when any count but `tried` is not 0.

mod captures;
mod families;

use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::hash::{Hash, Hasher};
use std::path::Path;
use std::process::Command;
use std::time::Duration;
use test_support::cli::{run_bounded, Bounded};

/// Longest run of one try.
const LIMIT: Duration = Duration::from_secs(120);

/// The binaries under test: the ones the host test suite (`cargo test --workspace --profile
/// ci`) builds.
pub(crate) use crate::hil::HostBins as Bins;

/// What a try must do.
pub(crate) struct Expect {
    /// Accepted exit codes.
    pub(crate) codes: &'static [i32],
    /// Texts the output (stdout and stderr) must hold: the cause named.
    pub(crate) says: Vec<String>,
    /// Texts naming the file and the line (or byte) stderr must hold; empty: no file concerned.
    pub(crate) at: Vec<String>,
}

impl Expect {
    /// Exit with one of `codes`, the output holding each of `says`.
    pub(crate) fn new(codes: &'static [i32], says: &[&str]) -> Self {
        Self {
            codes,
            says: says.iter().map(|s| s.to_string()).collect(),
            at: Vec::new(),
        }
    }

    /// And stderr naming each of `at` (the file, the line).
    pub(crate) fn at(mut self, at: &[&str]) -> Self {
        self.at = at.iter().map(|s| s.to_string()).collect();
        self
    }
}

/// The counts of the table and what was found.
#[derive(Default)]
pub(crate) struct Tally {
    rows: BTreeMap<&'static str, [u64; 7]>,
    findings: Vec<String>,
}

/// Columns of a row.
const TRIED: usize = 0;
const PANICS: usize = 1;
const HANGS: usize = 2;
const SILENT: usize = 3;
const CLOBBERED: usize = 4;
const NO_LOCATION: usize = 5;
const OTHER: usize = 6;

impl Tally {
    fn count(&mut self, family: &'static str, col: usize, finding: Option<String>) {
        self.rows.entry(family).or_default()[col] += 1;
        if let Some(f) = finding {
            self.findings.push(format!("{family}: {f}"));
        }
    }

    /// Judges one try `name` of `family`.
    pub(crate) fn judge(&mut self, family: &'static str, name: &str, r: &Bounded, e: &Expect) {
        self.count(family, TRIED, None);
        let short = |s: &str| s.chars().take(600).collect::<String>();
        if r.timed_out() {
            return self.count(
                family,
                HANGS,
                Some(format!("{name}: killed after {LIMIT:?}")),
            );
        }
        if r.panicked() {
            let f = format!("{name}: panic: {}", short(&r.stderr));
            return self.count(family, PANICS, Some(f));
        }
        let code = r.code().unwrap_or(-1);
        let all = format!("{}{}", r.stdout, r.stderr);
        let missing: Vec<&String> = e
            .says
            .iter()
            .filter(|s| !all.contains(s.as_str()))
            .collect();
        if !e.codes.contains(&code) || !missing.is_empty() {
            let col = if code == 0 { SILENT } else { OTHER };
            let f = format!(
                "{name}: exit {code} (expected {:?}), missing {missing:?}: {}",
                e.codes,
                short(&r.stderr)
            );
            self.count(family, col, Some(f));
        }
        let unnamed: Vec<&String> =
            e.at.iter()
                .filter(|s| !r.stderr.contains(s.as_str()))
                .collect();
        if !unnamed.is_empty() {
            let f = format!("{name}: message lacks {unnamed:?}: {}", short(&r.stderr));
            self.count(family, NO_LOCATION, Some(f));
        }
    }

    /// A solution that must equal the undamaged input's and does not: a silent wrong result.
    pub(crate) fn differs(&mut self, family: &'static str, name: &str, what: &str) {
        self.count(family, SILENT, Some(format!("{name}: {what}")));
    }

    /// Compares the hashes of a protected folder before and after a try.
    pub(crate) fn protect(
        &mut self,
        family: &'static str,
        name: &str,
        before: &Hashes,
        after: &Hashes,
    ) {
        for (k, v) in before {
            if after.get(k) != Some(v) {
                let f = format!("{name}: {k} changed or vanished");
                self.count(family, CLOBBERED, Some(f));
            }
        }
    }

    fn print(&self) -> bool {
        let head = [
            "tried",
            "panics",
            "hangs",
            "silent wrong",
            "lost/clobbered",
            "no file+line",
            "other",
        ];
        println!(
            "{:<22} {}",
            "family",
            head.map(|h| format!("{h:>16}")).join("")
        );
        let mut total = [0u64; 7];
        for (fam, row) in &self.rows {
            for (t, v) in total.iter_mut().zip(row) {
                *t += v;
            }
            println!("{fam:<22} {}", row.map(|v| format!("{v:>16}")).join(""));
        }
        println!(
            "{:<22} {}",
            "total",
            total.map(|v| format!("{v:>16}")).join("")
        );
        for f in &self.findings {
            println!("- {f}");
        }
        total.iter().skip(1).all(|&v| v == 0)
    }
}

/// Name -> content hash of the files of `d` (links: their target path; the lock file and
/// stage folders of an output folder left out).
pub(crate) type Hashes = BTreeMap<String, u64>;

/// The content hashes of the entries of `d` (see [`Hashes`]).
pub(crate) fn hashes(d: &Path) -> Hashes {
    let mut m = BTreeMap::new();
    let Ok(rd) = std::fs::read_dir(d) else {
        return m;
    };
    for e in rd.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with(".nav-out") {
            continue;
        }
        let mut h = std::collections::hash_map::DefaultHasher::new();
        match e.file_type() {
            Ok(t) if t.is_symlink() => std::fs::read_link(e.path()).ok().hash(&mut h),
            Ok(t) if t.is_dir() => continue,
            _ => std::fs::read(e.path()).ok().hash(&mut h),
        }
        m.insert(name, h.finish());
    }
    m
}

/// Runs `cmd` under the time limit.
pub(crate) fn bounded(cmd: &mut Command) -> Bounded {
    run_bounded(cmd, LIMIT)
}

/// Builds the binaries (the CI's test build), runs every family in a temporary folder (kept
/// with `keep`), prints the table.
pub fn run(keep: bool) -> Result<()> {
    // the test build's binaries: `cargo build -p ...` would resolve the dependencies' features
    // differently and compile most of them a second time
    let bins = crate::hil::host_bins()?;
    let dir = std::env::temp_dir().join(format!("navcore-hostile-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)?;
    let mut t = Tally::default();
    let r = families::all(&bins, &dir, &mut t);
    if keep {
        eprintln!("  kept {}", dir.display());
    } else {
        let _ = std::fs::remove_dir_all(&dir);
    }
    r?;
    if !t.print() {
        bail!("hostile inputs: findings above");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    /// Every count of the table but `tried` is 0. Not a step of `cargo xtask ci`: it costs
    /// about 120 CPU-s (4 minutes wall on the 2-core machine, the case simulated and run some
    /// 48 times), over the ~25 s a CI step may add; run it with `cargo xtask hostile` or
    /// `cargo test --profile ci -p xtask -- --ignored hostile`.
    #[test]
    #[ignore = "about 2 CPU-minutes: run with cargo xtask hostile"]
    fn hostile_inputs_find_nothing() {
        if let Err(e) = super::run(false) {
            panic!("{e:#}");
        }
    }
}
