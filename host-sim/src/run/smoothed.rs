//! `run --smooth`'s outputs: the smoothed solution of a run ([`nav_engine::smooth`], in
//! bounded memory: [`nav_engine::smooth::run`]) written beside the forward one, and both
//! summaries printed.

use super::cli::{imu_summary, Loaded};
use nav_engine::metrics::{self, Metrics};
use nav_engine::run::{ImuReport, RunOutput};
use nav_engine::smooth::apply::SmootherReport;
use nav_engine::smooth::run::{execute_smoothed, SmoothedRun};
use serde::Serialize;

/// The text of `run --smooth`'s `metrics.json`: the forward metrics at the top level, the
/// smoothed ones under `smoothed`, the smoother's sizes and times under `smoother`.
fn metrics_json(
    forward: &Metrics,
    smoothed: &Metrics,
    smoother: &SmootherReport,
    fwd: &RunOutput,
) -> anyhow::Result<String> {
    #[derive(Serialize)]
    struct File<'a> {
        #[serde(flatten)]
        forward: &'a Metrics,
        smoothed: &'a Metrics,
        smoother: &'a SmootherReport,
        imu: &'a ImuReport,
        complete: bool,
    }
    Ok(serde_json::to_string_pretty(&File {
        forward,
        smoothed,
        smoother,
        imu: &fwd.imu_report,
        complete: true,
    })?)
}

/// `run --smooth`: runs the loaded case smoothed, writes the smoothed `nav.txt`, `std.txt`
/// (and the other outputs), the forward solution as `nav_forward.txt`, and `metrics.json`
/// with the forward metrics at the top level and the smoothed ones under `smoothed` (with
/// `smoother`: sizes and times) in `dir` (the stage folder of the output folder `out`, named
/// in the summary), `nav.txt` at the loaded (checked) rate [`Loaded::nav_rate_hz`]; prints
/// both summaries. `t0`: start of the command.
pub fn finish(
    l: &Loaded,
    out: &std::path::Path,
    dir: &std::path::Path,
    t0: std::time::Instant,
) -> anyhow::Result<nav_engine::run::RunCounters> {
    let SmoothedRun {
        forward: fwd,
        forward_metrics: m,
        smoothed_metrics: ms,
        report: rep,
    } = execute_smoothed(
        &l.prepared,
        l.imu_stream.as_ref(),
        l.truth_stream.as_ref(),
        dir,
        l.nav_rate_hz,
        &metrics_json,
        &mut |_, _| {},
    )?;
    let t_run_s = t0.elapsed().as_secs_f64();
    let c = &fwd.counters;
    println!(
        "model {} ({} states): {} IMU epochs, GNSS {} used, {} withheld in {} outage(s); \
         {:.2} s",
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
        "smoother: {} nodes ({} with updates), history {:.1} MB ({:.0} B/node) and smoothed \
         {:.1} MB in temporary files, backward pass {:.2} s, smoothed outputs in {:.2} s{}",
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
        out.display()
    );
    Ok(fwd.counters)
}
