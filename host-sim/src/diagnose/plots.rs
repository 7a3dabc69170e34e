//! The diagnosis's plots, drawn next to `report.md` (which links them): `innovations.png`
//! (position innovations N/E/D of the used fixes, before and after), `nis.png` (NIS per fix
//! divided by its dimension, 60-fix running mean, before/after, with the chi-square 95 % band
//! of that mean), `evidence.png` (first round's evidence per candidate, signed log scale),
//! `errors.png` (the error of every held-out window before and after, the windows shaded by
//! kind: imposed outage grey, gap of the GNSS file orange, withheld by the diagnosis green;
//! below it the 3D error over time vs truth when there is one).
use std::path::Path;

use nav_diagnose::spill::NavFile;
use nav_diagnose::{DiagnoseOutput, Diagnosis};
use nav_engine::metrics;
use nav_engine::run::prepare::Prepared;
use nav_engine::run::{FixUse, RunOutput};
use plotters::prelude::*;

/// Draws the four plots of the diagnosis `d` of `p` into `dir`.
pub fn write_plots(dir: &Path, p: &Prepared, d: &DiagnoseOutput) -> anyhow::Result<()> {
    let t0 = t0_of(&d.before_nav);
    plot_innovations(&dir.join("innovations.png"), &d.before, &d.after, t0)?;
    plot_nis(&dir.join("nis.png"), &d.before, &d.after, t0)?;
    plot_evidence(&dir.join("evidence.png"), &d.diagnosis)?;
    plot_errors(&dir.join("errors.png"), p, d)
}

fn perr<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plot: {e}")
}

const BEFORE: RGBColor = RGBColor(214, 39, 40);
const AFTER: RGBColor = RGBColor(31, 119, 180);
const OUTAGE_FILL: RGBColor = RGBColor(225, 225, 225);
const GAP_FILL: RGBColor = RGBColor(253, 215, 170);
const WITHHELD_FILL: RGBColor = RGBColor(200, 235, 200);

fn range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi <= lo {
        return (lo - 1.0, hi + 1.0);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// The 0.5 % to 99.5 % range (padded), so a few post-outage innovations do not flatten the
/// rest; points outside are drawn at the edge.
fn robust_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let mut v: Vec<f64> = vals.filter(|x| x.is_finite()).collect();
    if v.len() < 20 {
        return range(v.into_iter());
    }
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    range([q(0.005), q(0.995)].into_iter())
}

fn t0_of(nav: &NavFile) -> f64 {
    nav.first_t_s().unwrap_or(0.0)
}

/// Position innovations (N, E, D) of the used fixes, before and after.
/// `t0`: time of the first record, s (the plots' origin).
fn plot_innovations(
    path: &Path,
    before: &RunOutput,
    after: &RunOutput,
    t0: f64,
) -> anyhow::Result<()> {
    crate::png::draw_png(path, (1500, 1000), |root| {
        let root = root.clone();
        root.fill(&WHITE).map_err(perr)?;
        let areas = root.split_evenly((3, 1));
        let used = |r: &&nav_engine::run::InnovationRecord| {
            matches!(r.used, FixUse::Accepted | FixUse::Forced)
        };
        for (c, a) in areas.iter().enumerate() {
            let pts = |run: &RunOutput| -> Vec<(f64, f64)> {
                run.innovations
                    .iter()
                    .filter(used)
                    .map(|r| ((r.t_s - t0) / 60.0, r.innovation[c]))
                    .collect()
            };
            let (pb, pa) = (pts(before), pts(after));
            let (y0, y1) = robust_range(pb.iter().chain(&pa).map(|p| p.1));
            let clip = |v: Vec<(f64, f64)>| -> Vec<(f64, f64)> {
                v.into_iter().map(|(t, x)| (t, x.clamp(y0, y1))).collect()
            };
            let (pb, pa) = (clip(pb), clip(pa));
            let x1 = pb.iter().chain(&pa).map(|p| p.0).fold(1e-3, f64::max);
            let mut ch = ChartBuilder::on(a)
            .caption(
                format!(
                    "GNSS position innovation {} [m] (0.5-99.5 % range, outliers at the edge): before (red), after (blue)",
                    ["north", "east", "down"][c]
                ),
                ("sans-serif", 20),
            )
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..x1, y0..y1)
            .map_err(perr)?;
            ch.configure_mesh()
                .x_desc("time [min]")
                .draw()
                .map_err(perr)?;
            ch.draw_series(pb.iter().map(|p| Circle::new(*p, 2, BEFORE.filled())))
                .map_err(perr)?;
            ch.draw_series(pa.iter().map(|p| Circle::new(*p, 2, AFTER.filled())))
                .map_err(perr)?;
        }
        root.present().map_err(perr)?;
        Ok(())
    })
}

/// NIS / dim of every used fix as a 60-fix running mean, before and after, with the 95 %
/// band of that mean.
fn plot_nis(path: &Path, before: &RunOutput, after: &RunOutput, t0: f64) -> anyhow::Result<()> {
    const W: usize = 60;
    crate::png::draw_png(path, (1500, 600), |root| {
        let root = root.clone();
        root.fill(&WHITE).map_err(perr)?;
        let series = |run: &RunOutput| -> (Vec<(f64, f64)>, f64) {
            let recs: Vec<(f64, f64, f64)> = run
                .innovations
                .iter()
                .filter(|r| nav_diagnose::stats::in_stats(r))
                .map(|r| ((r.t_s - t0) / 60.0, r.nis / r.dim as f64, r.dim as f64))
                .collect();
            let dim = recs.iter().map(|r| r.2).sum::<f64>() / recs.len().max(1) as f64;
            let mut out = Vec::new();
            for w in recs.windows(W) {
                let m = w.iter().map(|r| r.1).sum::<f64>() / W as f64;
                if let Some(last) = w.last() {
                    out.push((last.0, m.max(1e-3).log10()));
                }
            }
            (out, dim)
        };
        let (sb, dim) = series(before);
        let (sa, _) = series(after);
        // mean of W NIS/dim values: variance 2 / (dim W)
        let half = 1.96 * (2.0 / (dim.max(1.0) * W as f64)).sqrt();
        let band = ((1.0 - half).max(1e-3).log10(), (1.0 + half).log10());
        let (y0, y1) = range(sb.iter().chain(&sa).map(|p| p.1).chain([band.0, band.1]));
        let x1 = sb.iter().chain(&sa).map(|p| p.0).fold(1e-3, f64::max);
        let mut ch = ChartBuilder::on(&root)
            .caption(
                "NIS / dim, 60-fix running mean: before (red), after (blue); grey: 95 % band",
                ("sans-serif", 22),
            )
            .margin(10)
            .x_label_area_size(34)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..x1, y0..y1)
            .map_err(perr)?;
        ch.configure_mesh()
            .x_desc("time [min]")
            .y_desc("NIS / dim (log scale)")
            .y_label_formatter(&crate::png::pow10_label)
            .draw()
            .map_err(perr)?;
        ch.draw_series(std::iter::once(Rectangle::new(
            [(0.0, band.0), (x1, band.1)],
            OUTAGE_FILL.filled(),
        )))
        .map_err(perr)?;
        ch.draw_series(LineSeries::new(sb, BEFORE.stroke_width(2)))
            .map_err(perr)?;
        ch.draw_series(LineSeries::new(sa, AFTER.stroke_width(2)))
            .map_err(perr)?;
        root.present().map_err(perr)?;
        Ok(())
    })
}

/// Signed log: sign(x) log10(1 + |x|).
fn slog(x: f64) -> f64 {
    x.signum() * x.abs().ln_1p() / std::f64::consts::LN_10
}

/// Evidence (log-likelihood gain minus BIC penalty) of every candidate in the first round.
fn plot_evidence(path: &Path, d: &Diagnosis) -> anyhow::Result<()> {
    crate::png::draw_png(path, (1300, 650), |root| {
        let root = root.clone();
        root.fill(&WHITE).map_err(perr)?;
        let Some(r) = d.rounds.first() else {
            root.present().map_err(perr)?;
            return Ok(());
        };
        let vals: Vec<(String, f64)> = r
            .candidates
            .iter()
            .map(|c| (c.name.clone(), slog(c.evidence.unwrap_or(0.0))))
            .collect();
        let n = vals.len().max(1);
        let (y0, y1) = range(vals.iter().map(|v| v.1).chain([0.0, 1.0]));
        let names: Vec<String> = vals.iter().map(|v| v.0.clone()).collect();
        let mut ch = ChartBuilder::on(&root)
        .caption(
            "first round: evidence = log-likelihood gain - BIC penalty [nats], signed log10(1+|x|); > 0 pays",
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(60)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.5..(n as f64 - 0.5), y0..y1)
        .map_err(perr)?;
        ch.configure_mesh()
            .disable_x_mesh()
            .x_labels(n)
            .x_label_formatter(&|x| {
                let i = x.round();
                if (x - i).abs() < 0.01 && i >= 0.0 {
                    names.get(i as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .x_label_style(("sans-serif", 13))
            .y_desc("signed log10(1+|evidence|)")
            .draw()
            .map_err(perr)?;
        ch.draw_series(vals.iter().enumerate().map(|(i, (_, v))| {
            let col = if *v > 0.0 { AFTER } else { BEFORE };
            Rectangle::new(
                [(i as f64 - 0.35, 0.0), (i as f64 + 0.35, *v)],
                col.filled(),
            )
        }))
        .map_err(perr)?;
        ch.draw_series(LineSeries::new([(-0.5, 0.0), (n as f64 - 0.5, 0.0)], BLACK))
            .map_err(perr)?;
        root.present().map_err(perr)?;
        Ok(())
    })
}

/// 3D position error over time against the truth (IMU point), the run's navigation read
/// from its file: about 4000 points (min since its first record, m).
fn error_series(
    nav: &NavFile,
    truth: &[nav_core::types::NavSolution],
) -> anyhow::Result<Vec<(f64, f64)>> {
    let t0 = t0_of(nav);
    let step = (nav.len() / 4000).max(1);
    let mut m = metrics::TruthMatcher::new(truth.iter().copied());
    let (mut k, mut v) = (0usize, Vec::new());
    for s in nav.records()? {
        m.push(&s?, |e| {
            if k % step == 0 {
                v.push(((e.t_s - t0) / 60.0, e.d3_m()));
            }
            k += 1;
        });
    }
    Ok(v)
}

/// Two panels: the error of each held-out window (whatever its kind) for the configuration
/// and the final model, at the window's end, windows shaded; below, the 3D error over time
/// against the truth when there is one.
fn plot_errors(path: &Path, p: &Prepared, d: &DiagnoseOutput) -> anyhow::Result<()> {
    crate::png::draw_png(path, (1500, 900), |root| {
        let root = root.clone();
        root.fill(&WHITE).map_err(perr)?;
        let truth = p.case.truth.as_deref();
        let (top, bottom) = if truth.is_some() {
            root.split_vertically(480)
        } else {
            (root.clone(), root.split_vertically(900).1)
        };
        let dg = &d.diagnosis;
        let t0 = t0_of(&d.before_nav);
        let wins = &dg.heldout_windows.windows;
        let x1 = wins
            .iter()
            .map(|w| (w.end_s - t0) / 60.0)
            .chain(d.before_nav.last_t_s().map(|t| (t - t0) / 60.0))
            .fold(1e-3, f64::max);
        let pts = |v: &[f64]| -> Vec<(f64, f64)> {
            wins.iter()
                .zip(v)
                .filter(|(_, e)| e.is_finite())
                .map(|(w, e)| ((w.end_s - t0) / 60.0, *e))
                .collect()
        };
        let (pb, pa) = (
            pts(&dg.window_errors_before_m),
            pts(&dg.window_errors_after_m),
        );
        let (_, y1) = range(pb.iter().chain(&pa).map(|p| p.1).chain([0.0]));
        let mut ch = ChartBuilder::on(&top)
            .caption(
                format!(
                "error of each held-out window (withheld fixes and the first fix after it) [m]: \
                 before (red), after (blue); {} windows shaded",
                wins.len()
            ),
                ("sans-serif", 20),
            )
            .margin(10)
            .x_label_area_size(34)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..x1, 0.0..y1)
            .map_err(perr)?;
        ch.configure_mesh()
            .x_desc("time [min]")
            .y_desc("m")
            .draw()
            .map_err(perr)?;
        ch.draw_series(wins.iter().map(|w| {
            let fill = match w.kind {
                nav_diagnose::WindowKind::Imposed => OUTAGE_FILL,
                nav_diagnose::WindowKind::GnssGap => GAP_FILL,
                nav_diagnose::WindowKind::Withheld => WITHHELD_FILL,
            };
            Rectangle::new(
                [((w.start_s - t0) / 60.0, 0.0), ((w.end_s - t0) / 60.0, y1)],
                fill.filled(),
            )
        }))
        .map_err(perr)?;
        for (a, b) in pb.iter().zip(&pa) {
            ch.draw_series(LineSeries::new([*a, *b], BLACK.mix(0.3)))
                .map_err(perr)?;
        }
        ch.draw_series(pb.iter().map(|p| Circle::new(*p, 5, BEFORE.filled())))
            .map_err(perr)?;
        ch.draw_series(pa.iter().map(|p| Circle::new(*p, 5, AFTER.filled())))
            .map_err(perr)?;
        if let Some(tr) = truth {
            let sb = error_series(&d.before_nav, tr)?;
            let sa = error_series(&d.after_nav, tr)?;
            let (_, y1) = range(sb.iter().chain(&sa).map(|p| p.1).chain([0.0]));
            let mut ch = ChartBuilder::on(&bottom)
                .caption(
                    format!(
                        "3D position error vs truth [m] (final run, every fix used): before \
                         (red), after (blue){}",
                        if d.before.outages.is_empty() {
                            ""
                        } else {
                            "; imposed outages shaded"
                        }
                    ),
                    ("sans-serif", 20),
                )
                .margin(10)
                .x_label_area_size(34)
                .y_label_area_size(70)
                .build_cartesian_2d(0.0..x1, 0.0..y1)
                .map_err(perr)?;
            ch.configure_mesh()
                .x_desc("time [min]")
                .y_desc("m")
                .draw()
                .map_err(perr)?;
            ch.draw_series(d.before.outages.iter().map(|o| {
                Rectangle::new(
                    [
                        ((o.start_s - t0) / 60.0, 0.0),
                        ((o.end_s() - t0) / 60.0, y1),
                    ],
                    OUTAGE_FILL.filled(),
                )
            }))
            .map_err(perr)?;
            ch.draw_series(LineSeries::new(sb, BEFORE.stroke_width(2)))
                .map_err(perr)?;
            ch.draw_series(LineSeries::new(sa, AFTER.stroke_width(2)))
                .map_err(perr)?;
        }
        root.present().map_err(perr)?;
        Ok(())
    })
}
