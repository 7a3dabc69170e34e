//! The diagnosis report (`report.md` with PNG plots) and the augmented configuration.
//!
//! Plots: `innovations.png` (position innovations N/E/D of the used fixes, before and after),
//! `nis.png` (NIS per fix divided by its dimension, 60-fix running mean, before/after, with the
//! chi-square 95 % band of that mean), `evidence.png` (first round's evidence per candidate,
//! signed log scale), `errors.png` (the error of every held-out window before and after, the
//! windows shaded by kind: imposed outage grey, gap of the GNSS file orange, withheld by the
//! diagnosis green; below it the 3D error over time vs truth when there is one).
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;
use plotters::prelude::*;

use super::spill::NavFile;
use super::{DiagnoseOutput, Diagnosis};
use nav_engine::metrics;
use nav_engine::run::prepare::Prepared;
use nav_engine::run::{FixUse, RunOutput};

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
    let root = BitMapBackend::new(path, (1500, 1000)).into_drawing_area();
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
}

/// NIS / dim of every used fix as a 60-fix running mean, before and after, with the 95 %
/// band of that mean.
fn plot_nis(path: &Path, before: &RunOutput, after: &RunOutput, t0: f64) -> anyhow::Result<()> {
    const W: usize = 60;
    let root = BitMapBackend::new(path, (1500, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(perr)?;
    let series = |run: &RunOutput| -> (Vec<(f64, f64)>, f64) {
        let recs: Vec<(f64, f64, f64)> = run
            .innovations
            .iter()
            .filter(|r| super::stats::in_stats(r))
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
            "NIS / dim, 60-fix running mean (log10): before (red), after (blue); grey: 95 % band",
            ("sans-serif", 22),
        )
        .margin(10)
        .x_label_area_size(34)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..x1, y0..y1)
        .map_err(perr)?;
    ch.configure_mesh()
        .x_desc("time [min]")
        .y_desc("log10(NIS/dim)")
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
}

/// Signed log: sign(x) log10(1 + |x|).
fn slog(x: f64) -> f64 {
    x.signum() * x.abs().ln_1p() / std::f64::consts::LN_10
}

/// Evidence (log-likelihood gain minus BIC penalty) of every candidate in the first round.
fn plot_evidence(path: &Path, d: &Diagnosis) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1300, 650)).into_drawing_area();
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
    let root = BitMapBackend::new(path, (1500, 900)).into_drawing_area();
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
            super::WindowKind::Imposed => OUTAGE_FILL,
            super::WindowKind::GnssGap => GAP_FILL,
            super::WindowKind::Withheld => WITHHELD_FILL,
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
                "3D position error vs truth [m] (final run, every fix used): before (red), \
                 after (blue); imposed outages shaded",
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
}

/// `+12.3 % [+4.0, +20.1]`.
fn gain_ci(h: &super::HeldoutComparison) -> String {
    let pc = |x: f64| {
        if x.is_finite() {
            format!("{:+.1}", 100.0 * x)
        } else {
            "-inf".into()
        }
    };
    format!(
        "{} % [{}, {}]",
        pc(h.gain),
        pc(h.gain_ci90[0]),
        pc(h.gain_ci90[1])
    )
}

fn fmt_vec(v: &[f64]) -> String {
    let s: Vec<String> = v.iter().map(|x| format!("{x:.4e}")).collect();
    format!("[{}]", s.join(", "))
}

/// Writes `report.md` and its PNG plots into `dir`.
pub fn write_report(dir: &Path, p: &Prepared, d: &DiagnoseOutput) -> anyhow::Result<()> {
    let t0 = t0_of(&d.before_nav);
    plot_innovations(&dir.join("innovations.png"), &d.before, &d.after, t0)?;
    plot_nis(&dir.join("nis.png"), &d.before, &d.after, t0)?;
    plot_evidence(&dir.join("evidence.png"), &d.diagnosis)?;
    plot_errors(&dir.join("errors.png"), p, d)?;
    let dg = &d.diagnosis;
    let mut s = String::new();
    let _ = writeln!(s, "# Diagnosis\n\n{}\n", p.description);
    let _ = writeln!(s, "Verdict: **{}**\n", dg.verdict);
    if let Some(t) = &dg.noise_tuning {
        let _ = writeln!(
            s,
            "Noise tuning (default; `--no-tune-noise` keeps the configuration's): stage 1 factor \
             on both white-noise PSDs **{}** (evidence {:.1} nats); all stages: **{}** (evidence \
             {:.1} nats); NIS mean {:.2} -> {:.2} (expected {:.2}); {}\n",
            t.chosen_scale,
            t.evidence,
            t.chosen.describe(),
            t.total_evidence,
            t.nis_before,
            t.nis_after,
            t.nis_expected,
            if t.adopted {
                "adopted"
            } else if t.chosen.is_one() {
                "nothing to change"
            } else {
                "NOT adopted (held-out check, see the steps)"
            }
        );
        let _ = writeln!(
            s,
            "| factor on the white-noise PSDs | log-likelihood [nats] | NIS mean |"
        );
        let _ = writeln!(s, "|---|---|---|");
        for ((k, ll), nis) in t.scales.iter().zip(&t.log_likelihood).zip(&t.nis_mean) {
            let _ = writeln!(s, "| {k} | {ll:.1} | {nis:.2} |");
        }
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "GNSS noise scale (factor on the declared sigmas, 1 when they are right): \
             horizontal **{:.3}**, vertical **{:.3}** (stage 0 evidence {:.1} nats).\n",
            t.chosen.gnss_horizontal, t.chosen.gnss_vertical, t.gnss_evidence
        );
        let _ = writeln!(
            s,
            "| factor on the GNSS sigmas | log-likelihood [nats] | NIS mean |"
        );
        let _ = writeln!(s, "|---|---|---|");
        for ((k, ll), nis) in t
            .gnss_scales
            .iter()
            .zip(&t.gnss_log_likelihood)
            .zip(&t.gnss_nis_mean)
        {
            let _ = writeln!(s, "| {k:.3} | {ll:.1} | {nis:.2} |");
        }
        let _ = writeln!(s);
        if let Some(t2) = &t.with_effects {
            let _ = writeln!(
                s,
                "Re-tuned with the added effects in the model: **{}** (evidence {:.1} nats, NIS \
                 {:.2} -> {:.2}); {}.\n",
                t2.chosen.describe(),
                t2.total_evidence,
                t2.nis_before,
                t2.nis_after,
                if t2.adopted { "adopted" } else { "not adopted" }
            );
        }
    }
    let _ = writeln!(s, "## Held-out windows\n\n{}.\n", dg.heldout_windows.how);
    let _ = writeln!(
        s,
        "| window | kind | start [min] | end [min] | error before [m] | error after [m] |\n|---|---|---|---|---|---|"
    );
    let om = |x: Option<&f64>| {
        x.filter(|v| v.is_finite())
            .map_or("-".to_string(), |v| format!("{v:.3}"))
    };
    for (i, w) in dg.heldout_windows.windows.iter().enumerate() {
        let _ = writeln!(
            s,
            "| {} | {:?} | {:.2} | {:.2} | {} | {} |",
            i + 1,
            w.kind,
            (w.start_s - t0) / 60.0,
            (w.end_s - t0) / 60.0,
            om(dg.window_errors_before_m.get(i)),
            om(dg.window_errors_after_m.get(i))
        );
    }
    if let Some(h) = &dg.heldout_change {
        let _ = writeln!(
            s,
            "\nFinal model against the configuration: {}.",
            h.describe()
        );
    }
    s.push('\n');
    if let Some(u) = &dg.unexplained {
        let _ = writeln!(s, "## Unexplained\n\n{}\n", u.summary);
    }
    let _ = writeln!(
        s,
        "## Steps (every model change; a change whose held-out errors are significantly higher is not made)\n"
    );
    let _ = writeln!(
        s,
        "| step | kept | held-out windows RMS [m] | held-out gain vs the step before | GNSS prior residual, horizontal RMS [m] | outage error vs truth [m] | 3D RMS with GNSS vs truth [m] | NIS mean | why |\n|---|---|---|---|---|---|---|---|---|"
    );
    let o = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.3}"));
    for st in &dg.steps {
        let e = &st.errors;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.3} | {} | {} | {:.2} | {} |",
            st.label,
            if st.accepted { "yes" } else { "no" },
            o(e.heldout_windows_rms_m),
            st.heldout.as_ref().map_or("-".into(), gain_ci),
            e.gnss_prior_horizontal_rms_m,
            o(e.truth_outage_m),
            o(e.truth_with_gnss_3d_rms_m),
            e.nis_mean,
            st.reason.as_deref().unwrap_or("")
        );
    }
    s.push('\n');
    if dg.output_clock_shift_s != 0.0 {
        let _ = writeln!(
            s,
            "nav_after.txt is on the GNSS clock: its times are the IMU times {:+.4} s (minus the \
             time offset estimate).\n",
            dg.output_clock_shift_s
        );
    }
    if !dg.undetected.is_empty() {
        let _ = writeln!(
            s,
            "Not added, with the detectability bound on this drive (the smallest magnitude that \
             would have been found):\n\n| effect | bound (smallest state) | bound per state | unit | last estimate | why not |\n|---|---|---|---|---|---|"
        );
        for u in &dg.undetected {
            let _ = writeln!(
                s,
                "| {} | {:.3e} | {} | {} | {} | {} |",
                u.name,
                u.min_bound,
                fmt_vec(&u.bound),
                u.unit,
                fmt_vec(&u.estimate),
                u.reason
            );
        }
        s.push('\n');
    }
    for w in &dg.warnings {
        let _ = writeln!(s, "Warning: {w}\n");
    }
    let _ = writeln!(
        s,
        "Candidates considered: {}\n",
        dg.candidates_considered.join(", ")
    );
    if !dg.added_effects.is_empty() {
        let _ = writeln!(
            s,
            "| effect | estimate | 1-sigma | unit | likelihood gain [nats] | evidence (gain - BIC) [nats] | held-out gain [90 % CI] | p (lower errors) | runner-up (nats behind) | held-out windows RMS before -> after [m] | GNSS prior residual before -> after [m] |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
        for e in &dg.added_effects {
            let ru = e
                .runner_up
                .as_ref()
                .map_or(String::from("-"), |(n, m)| format!("{n} ({m:.1})"));
            let _ = writeln!(
                s,
                "| {}{} | {} | {} | {} | {:.1} | {:.1} | {} | {:.4} | {} | {} -> {} | {:.3} -> {:.3} |",
                e.name,
                if e.freed { " (freed)" } else { "" },
                fmt_vec(&e.estimate),
                fmt_vec(&e.sigma),
                e.unit,
                e.delta_log_likelihood,
                e.evidence,
                gain_ci(&e.heldout),
                e.heldout.p_better,
                ru,
                o(e.before.heldout_windows_rms_m),
                o(e.after.heldout_windows_rms_m),
                e.before.gnss_prior_horizontal_rms_m,
                e.after.gnss_prior_horizontal_rms_m
            );
        }
        s.push('\n');
    }
    let _ = writeln!(s, "## Errors ({})\n", dg.error_before.reference);
    let _ = writeln!(s, "| | before | after |\n|---|---|---|");
    let (b, a) = (&dg.error_before, &dg.error_after);
    let _ = writeln!(
        s,
        "| outages compared | {} | {} |\n| RMS over outages of the max 3D error [m] | {:.3} | {:.3} |\n| RMS over outages of the end horizontal error [m] | {:.3} | {:.3} |\n| 3D RMS, all epochs [m] | {:.3} | {:.3} |\n| prior GNSS residual, horizontal RMS [m] | {:.3} | {:.3} |\n| written solution vs the USED GNSS fixes outside outages, horizontal RMS [m] (posterior: favours no time offset, see docs/diagnose.md) | {:.3} | {:.3} |\n",
        b.outages,
        a.outages,
        b.outage_max_3d_rms_m,
        a.outage_max_3d_rms_m,
        b.outage_end_horizontal_rms_m,
        a.outage_end_horizontal_rms_m,
        b.overall_3d_rms_m,
        a.overall_3d_rms_m,
        b.gnss_residual_horizontal_rms_m,
        a.gnss_residual_horizontal_rms_m,
        b.output_vs_fixes_horizontal_rms_m,
        a.output_vs_fixes_horizontal_rms_m
    );
    let _ = writeln!(s, "![errors](errors.png)\n");
    let _ = writeln!(s, "## Residuals\n");
    let _ = writeln!(s, "| | before | after |\n|---|---|---|");
    let (rb, ra) = (&dg.residuals_before, &dg.residuals_after);
    let _ = writeln!(
        s,
        "| fixes | {} | {} |\n| NIS mean (expected {:.2}, 95 % band {:.2}..{:.2}) | {:.2} | {:.2} |\n| log-likelihood [nats] | {:.1} | {:.1} |",
        rb.updates,
        ra.updates,
        rb.nis_expected,
        rb.nis_band[0],
        rb.nis_band[1],
        rb.nis_mean,
        ra.nis_mean,
        rb.log_likelihood,
        ra.log_likelihood
    );
    for (wb, wa) in rb.whiteness.iter().zip(&ra.whiteness) {
        let _ = writeln!(
            s,
            "| Ljung-Box Q, component {} (white: < {:.1}) | {:.1} | {:.1} |",
            wb.component, wb.ljung_box_q95, wb.ljung_box_q, wa.ljung_box_q
        );
    }
    for (wb, wa) in rb.whiteness.iter().zip(&ra.whiteness) {
        let last = |w: &super::Whiteness| w.allan_ratio.last().copied().unwrap_or([0.0; 2]);
        let (lb, la) = (last(wb), last(wa));
        let _ = writeln!(
            s,
            "| m AVAR(m) of component {} at m = {:.0} fixes (white: about 1) | {:.1} | {:.1} |",
            wb.component, lb[0], lb[1], la[1]
        );
    }
    let _ = writeln!(s, "\n![innovations](innovations.png)\n\n![nis](nis.png)\n");
    let _ = writeln!(s, "## Evidence\n");
    for (i, r) in dg.rounds.iter().enumerate() {
        let _ = writeln!(
            s,
            "Round {} (model effects: [{}]; added: {}):\n",
            i + 1,
            r.model_effects.join(", "),
            r.added.as_deref().unwrap_or("none")
        );
        for note in r.ambiguous.iter().chain(&r.unexplained) {
            let _ = writeln!(s, "{note}\n");
        }
        let _ = writeln!(
            s,
            "| candidate | estimate +- sigma | evidence [nats] | LL gain | BIC penalty | max z | regressor corr z | held-out gain [90 % CI] | p lower / p higher | decision | reason |\n|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for c in &r.candidates {
            let _ = writeln!(
                s,
                "| {}{} | {} +- {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} | {:?} | {} |",
                c.name,
                if c.freed { " (freed)" } else { "" },
                fmt_vec(&c.estimate),
                fmt_vec(&c.sigma),
                c.evidence.unwrap_or(f64::NAN),
                c.delta_log_likelihood.unwrap_or(f64::NAN),
                c.bic_penalty,
                c.max_z,
                c.correlation_z,
                c.heldout.as_ref().map_or("-".into(), gain_ci),
                c.heldout.as_ref().map_or("-".into(), |h| format!(
                    "{:.3} / {:.3}",
                    h.p_better, h.p_worse
                )),
                c.decision,
                c.reason
            );
        }
        s.push('\n');
    }
    let _ = writeln!(s, "![evidence](evidence.png)");
    let path = dir.join("report.md");
    std::fs::write(&path, s).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Writes `augmented.toml` into `dir`: the input configuration (a project TOML) with the
/// added lever-arm correction folded into `gnss.lever_arm_m`, the time offset into
/// `imu.time_offset_s` (the IMU on the GNSS clock, so the run's output is on the GNSS clock),
/// the tuned noise as SI PSDs in `[noise.accel]`/`[noise.gyro]`, the tuned GNSS noise scale as
/// `gnss.sigma_scale` (times the configuration's), and its relative paths made
/// absolute; a comment header lists every
/// added effect with its estimate; the other added effects (IMU effect blocks) are listed in
/// the top-level `effects` key, so `host-sim run --config augmented.toml` runs the augmented
/// model. KF-GINS YAML inputs are not rewritten.
pub fn write_augmented_config(dir: &Path, config: &Path, d: &Diagnosis) -> anyhow::Result<()> {
    let text =
        std::fs::read_to_string(config).with_context(|| format!("reading {}", config.display()))?;
    let Ok(mut doc) = text.parse::<toml::Table>() else {
        return Ok(());
    };
    let cfg_dir = config.parent().map(Path::to_path_buf).unwrap_or_default();
    let cfg_dir = std::fs::canonicalize(&cfg_dir).unwrap_or(cfg_dir);
    for sec in ["imu", "gnss", "truth"] {
        if let Some(toml::Value::Table(t)) = doc.get_mut(sec) {
            if let Some(toml::Value::String(p)) = t.get_mut("path") {
                let abs = cfg_dir.join(&*p);
                *p = abs.display().to_string();
            }
        }
    }
    let gnss = doc
        .entry("gnss")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    if let toml::Value::Table(g) = gnss {
        for e in &d.added_effects {
            {
                if e.name == "lever_arm" {
                    let old: Vec<f64> = g
                        .get("lever_arm_m")
                        .and_then(|v| v.as_array())
                        .map(|a| a.iter().filter_map(|x| x.as_float()).collect())
                        .unwrap_or_else(|| vec![0.0; 3]);
                    let new: Vec<toml::Value> = (0..3)
                        .map(|i| {
                            let o = old.get(i).copied().unwrap_or(0.0);
                            toml::Value::Float(o + e.estimate.get(i).copied().unwrap_or(0.0))
                        })
                        .collect();
                    g.insert("lever_arm_m".into(), toml::Value::Array(new));
                }
            }
        }
        if let Some(s) = d.final_gnss_sigma_scale {
            // the configuration's scale times the tuned GNSS noise scale: one number when
            // horizontal and vertical agree, else the table form
            let v = toml::Value::try_from(s).context("GNSS sigma_scale")?;
            g.insert("sigma_scale".into(), v);
        }
    }
    if let Some(dt) = d
        .added_effects
        .iter()
        .find(|e| e.name == "time_offset")
        .and_then(|e| e.estimate.first())
    {
        // a fix tagged t is the antenna at IMU time t + dt: the IMU tags move by -dt onto the
        // GNSS clock (the run configuration's imu.time_offset_s is added to the IMU tags), so
        // the run's output is on the GNSS clock as nav_after.txt is
        let imu = doc
            .entry("imu")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let toml::Value::Table(t) = imu {
            let old = t
                .get("time_offset_s")
                .and_then(|v| v.as_float())
                .unwrap_or(0.0);
            t.insert("time_offset_s".into(), toml::Value::Float(old - dt));
        }
    }
    if let Some(psd) = d.final_noise_psd {
        // the tuned PSDs in SI (they include any white_noise_scale of the input)
        let noise = doc
            .entry("noise")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let toml::Value::Table(n) = noise {
            n.remove("white_noise_scale");
            type Keys<'a> = &'a [&'a str];
            let sensors: [(&str, [f64; 3], Keys, Keys, Keys); 2] = [
                (
                    "accel",
                    [psd[0], psd[1], psd[2]],
                    &["s_n", "n_ug_per_sqrt_hz", "vrw_mps_per_sqrt_h"],
                    &["s_b", "gm_sigma_ug"],
                    &["s_k", "k_ug_per_sqrt_h", "k_ug_per_sqrt_hz"],
                ),
                (
                    "gyro",
                    [psd[3], psd[4], psd[5]],
                    &["s_n", "arw_deg_per_sqrt_h", "n_deg_per_s_per_sqrt_hz"],
                    &["s_b", "gm_sigma_deg_per_h"],
                    &["s_k", "k_deg_per_h_per_sqrt_h", "k_deg_per_s_per_sqrt_hz"],
                ),
            ];
            for (name, v, white, gm, rw) in sensors {
                let t = n
                    .entry(name)
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()));
                if let toml::Value::Table(t) = t {
                    for (keys, val) in [(white, v[0]), (gm, v[1]), (rw, v[2])] {
                        for k in keys {
                            t.remove(*k);
                        }
                        if val > 0.0 {
                            t.insert(keys[0].into(), toml::Value::Float(val));
                        }
                    }
                }
            }
        }
    }
    let imu_effects: Vec<&str> = d
        .added_effects
        .iter()
        .map(|e| e.name.as_str())
        .filter(|n| !matches!(*n, "lever_arm" | "time_offset"))
        .collect();
    if !imu_effects.is_empty() {
        let mut list: Vec<toml::Value> = doc
            .get("effects")
            .and_then(|v| v.as_array())
            .cloned()
            .unwrap_or_default();
        for n in &imu_effects {
            if !list.iter().any(|v| v.as_str() == Some(n)) {
                list.push(toml::Value::String((*n).to_string()));
            }
        }
        doc.insert("effects".into(), toml::Value::Array(list));
    }
    let mut head = format!(
        "# Written by host-sim diagnose from {} (paths made absolute).\n\
         # Verdict: {}. lever_arm is folded into [gnss], time_offset into [imu] (output on the GNSS clock), the other\n\
         # added effects are appended to the model by the `effects` key;\n",
        config.display(),
        d.verdict
    );
    for e in &d.added_effects {
        head.push_str(&format!(
            "# {}: estimate {:?} sigma {:?} [{}]\n",
            e.name, e.estimate, e.sigma, e.unit
        ));
    }
    head.push_str(&closing_comments(d));
    let out = format!("{head}{}", toml::to_string_pretty(&doc).unwrap_or_default());
    let path = dir.join("augmented.toml");
    std::fs::write(&path, out).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// The last comment lines of `augmented.toml`: a named clock drift's rate as a recommendation
/// (the run configuration has no clock-rate key: only the constant `imu.time_offset_s`), then
/// how to run it.
fn closing_comments(d: &Diagnosis) -> String {
    let mut out = String::new();
    if let Some(e) = d.added_effects.iter().find(|e| e.name == "imu_clock_drift") {
        // the run configuration has no key for a clock rate (nav_io::RunConfig: only the
        // constant imu.time_offset_s), so the rate is a recommendation, not a setting
        let (dt0, rate) = (
            e.estimate.first().copied().unwrap_or(f64::NAN),
            e.estimate.get(1).copied().unwrap_or(f64::NAN),
        );
        let sr = e.sigma.get(1).copied().unwrap_or(f64::NAN);
        out.push_str(&format!(
            "# imu clock drift (recommendation, not applied: the run configuration has no \
             clock-rate key): imu_clock_rate_ppm = {:.2} (1-sigma {:.2}), offset at the start \
             {dt0:.4} s (IMU time tau is GNSS time tau - dt_0 - rate (tau - t_0)); the `effects` \
             list keeps imu_clock_drift so the run estimates it\n",
            rate * 1e6,
            sr * 1e6
        ));
    }
    out.push_str("# run with: host-sim run --config augmented.toml\n");
    out
}
