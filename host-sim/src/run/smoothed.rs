//! `run --smooth`'s outputs: the smoothed solution of a run ([`nav_engine::smooth`]) written
//! beside the forward one, and both summaries printed.

use super::cli::{decimate, imu_summary, Prepared, RunArgs};
use super::{output, RunOutput};
use anyhow::Context;
use nav_core::types::NavSolution;
use nav_engine::metrics::{self, Metrics};
use nav_engine::smooth::apply::{smooth_run, SmootherReport};
use serde::Serialize;

/// `run --smooth`: smooths the forward run `fwd` (metrics `m`), writes the smoothed
/// `nav.txt`, `std.txt` (and the other outputs), the forward solution as `nav_forward.txt`,
/// and `metrics.json` with the forward metrics at the top level and the smoothed ones under
/// `smoothed` (with `smoother`: memory and time), all in `dir` (the stage folder of
/// `--out`); prints both summaries.
pub fn finish(
    args: &RunArgs,
    p: &Prepared,
    dir: &std::path::Path,
    fwd: RunOutput,
    m: Metrics,
    t_run_s: f64,
) -> anyhow::Result<()> {
    let (out, _, rep) = smooth_run(&p.case, &fwd)?;
    let ms = metrics::compute(&out, p.case.truth.as_deref());
    let rate = |nav: &[NavSolution]| match args.nav_rate {
        Some(r) if r > 0.0 => decimate(nav, r),
        _ => nav.to_vec(),
    };
    output::write_nav(&dir.join("nav_forward.txt"), &rate(&fwd.nav), p.week)
        .with_context(|| format!("writing {}/nav_forward.txt", dir.display()))?;
    #[derive(Serialize)]
    struct File<'a> {
        #[serde(flatten)]
        forward: &'a Metrics,
        smoothed: &'a Metrics,
        smoother: &'a SmootherReport,
        imu: &'a nav_engine::run::ImuReport,
        complete: bool,
    }
    let json = serde_json::to_string_pretty(&File {
        forward: &m,
        smoothed: &ms,
        smoother: &rep,
        imu: &fwd.imu_report,
        complete: true,
    })?;
    output::write_all(dir, &out, &rate(&out.nav), p.week, &json, true)
        .with_context(|| format!("writing the outputs in {}", dir.display()))?;
    let c = &fwd.counters;
    println!(
        "model {} ({} states): {} IMU epochs, GNSS {} used, {} withheld in {} outage(s); \
         forward {:.2} s",
        fwd.model.name(),
        rep.states,
        c.imu_epochs,
        c.gnss_accepted,
        c.gnss_withheld,
        fwd.outages.len(),
        t_run_s
    );
    print!("{}", imu_summary(&fwd));
    let al = fwd.aiding.summary_line();
    if !al.is_empty() {
        println!("{al}");
    }
    println!(
        "smoother: {} nodes ({} with updates), history {:.1} MB ({:.0} B/node), smoothed {:.1} MB, \
         backward pass {:.2} s, applied in {:.2} s{}",
        rep.nodes,
        rep.update_nodes,
        rep.history_bytes as f64 / 1e6,
        rep.history_bytes_per_node,
        rep.smoothed_bytes as f64 / 1e6,
        rep.backward_s,
        rep.apply_s,
        if rep.pinv_fallbacks > 0 {
            format!(", {} pseudo-inverse fallback(s)", rep.pinv_fallbacks)
        } else {
            String::new()
        }
    );
    println!("forward:");
    print!("{}", metrics::summary_table(&m));
    println!("smoothed:");
    print!("{}", metrics::summary_table(&ms));
    println!(
        "wrote {}/{{nav.txt, std.txt (smoothed), nav_forward.txt, bias.txt (forward), \
         innovations.txt (vs smoothed), metrics.json}}",
        args.out.display()
    );
    Ok(())
}
