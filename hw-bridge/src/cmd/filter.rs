//! `replay --config`: the run engine (`nav_engine`) on a replay's frames, as `host-sim run`
//! runs it on files.

use super::*;
use crate::frames::FrameLog;
use crate::outputs::{partial_name, rename};
use anyhow::{bail, Context};
use std::path::Path;
use std::time::Instant;

/// The host filter run on a replay's frames (`replay --config`).
#[derive(Debug)]
pub struct FilterRun {
    /// Inputs and options as `host-sim run` prepares them (`nav_engine::load`), with the capture's IMU samples and
    /// GNSS fixes in place of the files'.
    pub prepared: nav_engine::Prepared,
    /// The filter's output.
    pub output: nav_engine::RunOutput,
    /// Metrics (against the truth when there is one).
    pub metrics: nav_engine::Metrics,
    /// Wall time of the filter run alone, s.
    pub wall_s: f64,
}

/// Decodes a capture as frames, feeding the recorded chunks in order (no timing, no port).
pub fn decode_capture(path: &Path) -> anyhow::Result<ReplayOutcome> {
    replay(&ReplayArgs::new(path))
}

/// Runs the host filter on decoded frames the way `host-sim run --config CONFIG [--case DIR]`
/// runs it on files: the configuration is loaded by the run engine (`nav_engine::load`), then its IMU samples
/// and GNSS fixes are replaced by the frames' (with the configuration's GNSS sigma scale
/// applied, as `host-sim` applies it to its files). Same samples, same options: the same
/// solution, bit for bit.
pub fn run_filter_on_frames(
    log: &FrameLog,
    config: &Path,
    case: Option<&Path>,
    model: Option<nav_engine::run::Model>,
    f32: bool,
) -> anyhow::Result<FilterRun> {
    let mut spec = nav_engine::RunSpec::new(config);
    spec.case = case.map(Path::to_path_buf);
    spec.model = model;
    spec.f32 = f32;
    let loaded = nav_engine::load(&spec, false)
        .with_context(|| format!("preparing the filter from {}", config.display()))?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    let mut prepared = loaded.prepared;
    if log.imu.is_empty() {
        bail!("the capture holds no IMU frame: nothing to run the filter on");
    }
    // the configuration's `[gnss] sigma_scale` is in `prepared.opts`: the engine applies it
    prepared.case.imu = log.imu.clone();
    // the samples are the capture's now: messages name IMU sample indices, not the
    // configuration's file lines
    prepared.case.imu_origin = None;
    prepared.case.gnss = log.gnss.clone();
    let t = Instant::now();
    let (output, metrics) = nav_engine::execute(&prepared, &mut |_, _| {})?;
    Ok(FilterRun {
        prepared,
        output,
        metrics,
        wall_s: t.elapsed().as_secs_f64(),
    })
}

/// Writes a filter run's outputs under the names `host-sim run` uses.
pub fn write_filter_outputs(dir: &Path, f: &FilterRun) -> anyhow::Result<()> {
    use nav_engine::run::output;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    // each file under its `.partial` name first, renamed when written completely
    let p = |name: &str| partial_name(&dir.join(name));
    output::write_nav(&p("nav.txt"), &f.output.nav, f.prepared.week)?;
    output::write_std(&p("std.txt"), &f.output)?;
    output::write_bias(&p("bias.txt"), &f.output)?;
    output::write_innovations(&p("innovations.txt"), &f.output.innovations)?;
    let mp = p("metrics.json");
    std::fs::write(
        &mp,
        nav_engine::run::execute::metrics_json(&f.metrics, &f.output, None)?,
    )
    .with_context(|| format!("writing {}", mp.display()))?;
    for name in [
        "nav.txt",
        "std.txt",
        "bias.txt",
        "innovations.txt",
        "metrics.json",
    ] {
        rename(&p(name), &dir.join(name))?;
    }
    Ok(())
}
