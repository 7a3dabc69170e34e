//! PNG plots of the study: errors and standard deviations over time (log scale, per
//! component), standard-deviation bands with true-error traces around the outage, the average
//! NEES against its 95 % band, and the error budget as bars.

use nav_study::budget::Budget;
use nav_study::report::percent;
use nav_study::setup::Variant;
use nav_study::{Case, Cell, StudyResult};
use noise_id::stats as chi2;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

fn perr<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plot: {e}")
}

/// Colour of a model in every plot.
pub fn model_color(m: Variant) -> RGBColor {
    match m {
        Variant::N => RGBColor(214, 39, 40),
        Variant::Nbk => RGBColor(31, 119, 180),
        Variant::NbkSingle => RGBColor(44, 160, 44),
        Variant::NIdGyro => RGBColor(148, 103, 189),
    }
}

const OUTAGE_FILL: RGBColor = RGBColor(225, 225, 225);

/// Unit conversion of the 9 components for display: attitude in deg, velocity m/s, position m.
fn display_scale(i: usize) -> f64 {
    if i < 3 {
        180.0 / std::f64::consts::PI
    } else {
        1.0
    }
}

/// Draws `pts` as a line of separate 2-point segments: a `LineSeries` wider than 1 px joins
/// its segments with mitres that overshoot far beyond the chart (out of the picture) at a
/// sharp spike such as the fall of the error when the fixes come back after an outage
/// (<https://github.com/plotters-rs/plotters/issues/549>); segments without joins stay where the data are.
fn segments<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate<From = (f64, f64)>>(
    ch: &mut ChartContext<'a, DB, CT>,
    pts: &[(f64, f64)],
    style: ShapeStyle,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    ch.draw_series(
        pts.windows(2)
            .map(|w| PathElement::new(vec![w[0], w[1]], style)),
    )
    .map_err(perr)?;
    Ok(())
}

/// Draws `pts` as a dashed line: runs of 16 points on, 9 off (1 Hz data: 16 s dashes).
fn dashed<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate<From = (f64, f64)>>(
    ch: &mut ChartContext<'a, DB, CT>,
    pts: &[(f64, f64)],
    style: ShapeStyle,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    for chunk in pts.chunks(25) {
        let on: Vec<(f64, f64)> = chunk.iter().take(17).copied().collect();
        segments(ch, &on, style)?;
    }
    Ok(())
}

fn component_title(i: usize) -> String {
    let q = ["attitude error phi", "velocity error", "position error"][i / 3];
    let ax = ["north", "east", "down"][i % 3];
    format!("{q} {ax}")
}

/// The y-axis label of component `i` (as [`component_title`]) on a log scale, with its unit.
fn component_axis(i: usize) -> String {
    let q = ["attitude error", "velocity error", "position error"][i / 3];
    let unit = ["deg", "m/s", "m"][i / 3];
    format!("{q} [{unit}], log scale")
}

/// The font of the axis labels (plotters' default is hard to read at these sizes).
const AXIS_DESC_FONT: (&str, u32) = ("sans-serif", 16);

fn log_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (1e-3, 1.0);
    }
    (lo / 1.5, hi * 1.5)
}

fn outage_span(res: &StudyResult, case: Case) -> Option<(f64, f64)> {
    (case == Case::Outage).then(|| {
        (
            res.config.outage_start_rel_s / 60.0,
            res.config.outage_end_rel_s() / 60.0,
        )
    })
}

/// 3x3 grid (rows position, velocity, attitude; columns N, E, D), log scale: the filter's
/// standard deviation (dashed) and the Monte Carlo RMS true error (solid) of every model.
pub fn plot_errors(res: &StudyResult, case: Case, path: &Path) -> anyhow::Result<()> {
    crate::png::draw_png(path, (1800, 1350), |root| {
        let root = root.clone();
        root.fill(&WHITE).map_err(perr)?;
        let (title, body) = root.split_vertically(50);
        title
        .draw_text(
            &format!(
                "{}: filter std (dashed) and RMS true error over {} runs (solid); N red, NBK blue, NBK-single green, N+id.gyro purple",
                case.label(),
                res.config.runs
            ),
            &("sans-serif", 26).into_font().color(&BLACK),
            (20, 12),
        )
        .map_err(perr)?;
        let areas = body.split_evenly((3, 3));
        let cells: Vec<&Cell> = res.cells.iter().filter(|c| c.case == case).collect();
        let order = [6, 7, 8, 3, 4, 5, 0, 1, 2];
        for (a, &i) in areas.iter().zip(order.iter()) {
            let sc = display_scale(i);
            let skip = |t: f64| t >= 1.0;
            let (y0, y1) = log_range(cells.iter().flat_map(|c| {
                c.stats
                    .t_rel_s
                    .iter()
                    .zip(c.stats.rms_err.iter().zip(&c.stats.std))
                    .filter(|(t, _)| skip(**t))
                    .flat_map(move |(_, (e, s))| [e[i] * sc, s[i] * sc])
            }));
            let (y0, y1) = (y0.log10(), y1.log10());
            let x1 = res.duration_s / 60.0;
            let mut ch = ChartBuilder::on(a)
                .caption(component_title(i), ("sans-serif", 20))
                .margin(8)
                .x_label_area_size(34)
                .y_label_area_size(70)
                .build_cartesian_2d(0.0..x1, y0..y1)
                .map_err(perr)?;
            ch.configure_mesh()
                .x_desc("time [min]")
                .y_desc(component_axis(i))
                .axis_desc_style(AXIS_DESC_FONT)
                .y_label_formatter(&crate::png::pow10_label)
                .draw()
                .map_err(perr)?;
            if let Some((s0, s1)) = outage_span(res, case) {
                ch.draw_series(std::iter::once(Rectangle::new(
                    [(s0, y0), (s1, y1)],
                    OUTAGE_FILL.filled(),
                )))
                .map_err(perr)?;
            }
            for c in &cells {
                let col = model_color(c.model);
                let pts = |v: &Vec<[f64; 9]>| -> Vec<(f64, f64)> {
                    c.stats
                        .t_rel_s
                        .iter()
                        .zip(v)
                        .filter(|(t, x)| skip(**t) && x[i] > 0.0)
                        .map(|(t, x)| (t / 60.0, (x[i] * sc).log10().clamp(y0, y1)))
                        .collect()
                };
                segments(&mut ch, &pts(&c.stats.rms_err), col.stroke_width(2))?;
                dashed(&mut ch, &pts(&c.stats.std), col.stroke_width(2))?;
            }
        }
        root.present().map_err(perr)?;
        Ok(())
    })
}

/// Position N, E, D in linear scale around the outage (case 2) or over the drive (case 1):
/// the +-1 sigma bands of N (red lines) and NBK (blue fill) and the true errors of the first
/// runs of each (thin lines).
pub fn plot_bands(res: &StudyResult, case: Case, path: &Path) -> anyhow::Result<()> {
    crate::png::draw_png(path, (1800, 1200), |root| {
        let root = root.clone();
        root.fill(&WHITE).map_err(perr)?;
        let (title, body) = root.split_vertically(50);
        let (t0, t1) = match case {
            Case::Outage => (
                res.config.outage_start_rel_s - 60.0,
                res.config.outage_end_rel_s() + 60.0,
            ),
            Case::Continuous => (180.0, res.duration_s),
        };
        title
        .draw_text(
            &format!(
                "{}: position +-1 sigma of N (red lines) and NBK (blue band); true errors of {} runs each (thin)",
                case.label(),
                res.cells.first().map_or(0, |c| c.sample_traces.len())
            ),
            &("sans-serif", 26).into_font().color(&BLACK),
            (20, 12),
        )
        .map_err(perr)?;
        let areas = body.split_evenly((3, 1));
        let n = res.cell(Variant::N, case);
        let k = res.cell(Variant::Nbk, case);
        let unit = if case == Case::Continuous { 100.0 } else { 1.0 };
        let uname = if case == Case::Continuous { "cm" } else { "m" };
        for (a, i) in areas.iter().zip(6..9) {
            band_panel(a, res, case, [n, k], i, (t0, t1), (unit, uname))?;
        }
        root.present().map_err(perr)?;
        Ok(())
    })
}

/// One panel of [`plot_bands`]: the position error's component `i` (6, 7, 8: north, east,
/// down) of the N and NBK cells `[n, k]` over `t0..t1` (s from the start), in the unit
/// `(factor from m, name)`.
fn band_panel<DB: DrawingBackend>(
    a: &DrawingArea<DB, Shift>,
    res: &StudyResult,
    case: Case,
    [n, k]: [Option<&Cell>; 2],
    i: usize,
    (t0, t1): (f64, f64),
    (unit, uname): (f64, &str),
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let within = |t: f64| t >= t0 && t <= t1;
    let mut ymax = 0.0f64;
    for c in [n, k].into_iter().flatten() {
        for (t, s) in c.stats.t_rel_s.iter().zip(&c.stats.std) {
            if within(*t) {
                ymax = ymax.max(s[i] * unit);
            }
        }
        for tr in &c.sample_traces {
            for (t, e) in tr.t_rel_s.iter().zip(&tr.err) {
                if within(*t) {
                    ymax = ymax.max(e[i].abs() * unit);
                }
            }
        }
    }
    let ymax = if ymax > 0.0 { ymax * 1.1 } else { 1.0 };
    let mut ch = ChartBuilder::on(a)
        .caption(
            format!("position error {}", ["north", "east", "down"][i - 6]),
            ("sans-serif", 20),
        )
        .margin(8)
        .x_label_area_size(34)
        .y_label_area_size(70)
        .build_cartesian_2d(t0 / 60.0..t1 / 60.0, -ymax..ymax)
        .map_err(perr)?;
    ch.configure_mesh()
        .x_desc("time [min]")
        .y_desc(format!("position error [{uname}]"))
        .axis_desc_style(AXIS_DESC_FONT)
        .draw()
        .map_err(perr)?;
    if let Some((s0, s1)) = outage_span(res, case) {
        ch.draw_series(std::iter::once(Rectangle::new(
            [(s0, -ymax), (s1, ymax)],
            OUTAGE_FILL.filled(),
        )))
        .map_err(perr)?;
    }
    if let Some(c) = k {
        let col = model_color(Variant::Nbk);
        let up: Vec<(f64, f64)> = c
            .stats
            .t_rel_s
            .iter()
            .zip(&c.stats.std)
            .filter(|(t, _)| within(**t))
            .map(|(t, s)| (t / 60.0, s[i] * unit))
            .collect();
        let mut poly = up.clone();
        poly.extend(up.iter().rev().map(|(t, s)| (*t, -*s)));
        ch.draw_series(std::iter::once(Polygon::new(poly, col.mix(0.2).filled())))
            .map_err(perr)?;
    }
    for (c, m) in [(n, Variant::N), (k, Variant::Nbk)] {
        let Some(c) = c else { continue };
        let col = model_color(m);
        for tr in &c.sample_traces {
            let pts: Vec<(f64, f64)> = tr
                .t_rel_s
                .iter()
                .zip(&tr.err)
                .filter(|(t, _)| within(**t))
                .map(|(t, e)| (t / 60.0, e[i] * unit))
                .collect();
            ch.draw_series(LineSeries::new(pts, col.mix(0.7).stroke_width(1)))
                .map_err(perr)?;
        }
    }
    for (c, m) in [(n, Variant::N), (k, Variant::Nbk)] {
        let Some(c) = c else { continue };
        let col = model_color(m);
        for sign in [1.0, -1.0] {
            let pts: Vec<(f64, f64)> = c
                .stats
                .t_rel_s
                .iter()
                .zip(&c.stats.std)
                .filter(|(t, _)| within(**t))
                .map(|(t, s)| (t / 60.0, sign * s[i] * unit))
                .collect();
            let a = ch
                .draw_series(LineSeries::new(pts, col.stroke_width(3)))
                .map_err(perr)?;
            if sign > 0.0 {
                a.label(format!("{} +-1 sigma", m.label()))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(3))
                    });
            }
        }
    }
    ch.configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(perr)?;
    Ok(())
}

/// Average NEES over the runs per group (attitude, velocity, position) and model, log scale,
/// with the two-sided 95 % band (dashed).
pub fn plot_nees(res: &StudyResult, case: Case, path: &Path) -> anyhow::Result<()> {
    crate::png::draw_png(path, (1800, 1200), |root| {
        let root = root.clone();
        root.fill(&WHITE).map_err(perr)?;
        let (title, body) = root.split_vertically(50);
        let (lo, hi) = chi2::nees_band_95(res.config.runs, 3);
        title
        .draw_text(
            &format!(
                "{}: average NEES of {} runs (3 dof each); 95 % band [{lo:.2}, {hi:.2}] dashed; N red, NBK blue, NBK-single green, N+id.gyro purple",
                case.label(),
                res.config.runs
            ),
            &("sans-serif", 26).into_font().color(&BLACK),
            (20, 12),
        )
        .map_err(perr)?;
        let areas = body.split_evenly((3, 1));
        let cells: Vec<&Cell> = res.cells.iter().filter(|c| c.case == case).collect();
        for (a, g) in areas.iter().zip([2usize, 1, 0]) {
            let (mut y0, mut y1) = log_range(
                cells
                    .iter()
                    .flat_map(|c| c.stats.nees.iter().map(move |n| n[g])),
            );
            y0 = y0.min(lo / 2.0).max(1e-3).log10();
            y1 = y1.max(hi * 2.0).log10();
            let x1 = res.duration_s / 60.0;
            let mut ch = ChartBuilder::on(a)
                .caption(
                    format!("{} NEES (average over runs)", nav_study::stats::GROUPS[g]),
                    ("sans-serif", 20),
                )
                .margin(8)
                .x_label_area_size(34)
                .y_label_area_size(70)
                .build_cartesian_2d(0.0..x1, y0..y1)
                .map_err(perr)?;
            ch.configure_mesh()
                .x_desc("time [min]")
                .y_desc("NEES (dimensionless), log scale")
                .axis_desc_style(AXIS_DESC_FONT)
                .y_label_formatter(&crate::png::pow10_label)
                .draw()
                .map_err(perr)?;
            if let Some((s0, s1)) = outage_span(res, case) {
                ch.draw_series(std::iter::once(Rectangle::new(
                    [(s0, y0), (s1, y1)],
                    OUTAGE_FILL.filled(),
                )))
                .map_err(perr)?;
            }
            for b in [lo, 3.0, hi] {
                let style = if b == 3.0 {
                    BLACK.mix(0.4).stroke_width(1)
                } else {
                    BLACK.stroke_width(2)
                };
                let b = b.log10();
                ch.draw_series(DashedLineSeries::new(vec![(0.0, b), (x1, b)], 10, 6, style))
                    .map_err(perr)?;
            }
            for c in &cells {
                let col = model_color(c.model);
                let pts: Vec<(f64, f64)> = c
                    .stats
                    .t_rel_s
                    .iter()
                    .zip(&c.stats.nees)
                    .filter(|(_, n)| n[g] > 0.0)
                    .map(|(t, n)| (t / 60.0, n[g].log10().clamp(y0, y1)))
                    .collect();
                ch.draw_series(LineSeries::new(pts, col.stroke_width(2)))
                    .map_err(perr)?
                    .label(c.model.label())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], col.stroke_width(3))
                    });
            }
            ch.configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(perr)?;
        }
        root.present().map_err(perr)?;
        Ok(())
    })
}

fn budget_panel(a: &Area<'_>, b: &Budget) -> anyhow::Result<()> {
    // rows: each source, then the root-sum-square of the sources and the all-sources total
    let mut rows: Vec<(String, f64, RGBColor)> = b
        .entries
        .iter()
        .map(|e| {
            let col = if e.source.is_gyro() {
                RGBColor(214, 39, 40)
            } else if e.source.is_accel() {
                RGBColor(31, 119, 180)
            } else {
                RGBColor(127, 127, 127)
            };
            (
                format!("{} ({})", e.label, percent(e.share_horizontal)),
                e.rms_horizontal_m,
                col,
            )
        })
        .collect();
    rows.push((
        "root-sum-square of the sources".into(),
        b.sum_mse_horizontal_m2.sqrt(),
        BLACK,
    ));
    rows.push((
        "all sources together".into(),
        b.total_rms_horizontal_m,
        BLACK,
    ));
    let (x0, x1) = log_range(rows.iter().map(|r| r.1));
    let n = rows.len();
    let mut ch = ChartBuilder::on(a)
        .caption(
            format!(
                "{} model: RMS horizontal position error at the end of the outage, each source alone ({} runs); sum/total in variance {:.3}",
                b.model.label(),
                b.runs,
                b.ratio_sum_to_total_horizontal
            ),
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(330)
        .build_cartesian_2d((x0..x1).log_scale(), (0..n - 1).into_segmented())
        .map_err(perr)?;
    let labels: Vec<String> = rows.iter().map(|r| r.0.clone()).collect();
    ch.configure_mesh()
        .disable_y_mesh()
        .x_desc("RMS horizontal position error [m] (log scale)")
        .y_label_formatter(&|v| match v {
            SegmentValue::CenterOf(i) => labels.get(n - 1 - *i).cloned().unwrap_or_default(),
            _ => String::new(),
        })
        .y_labels(n)
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(perr)?;
    ch.draw_series(rows.iter().enumerate().map(|(j, (_, v, col))| {
        let y = n - 1 - j;
        let mut r = Rectangle::new(
            [
                (x0, SegmentValue::Exact(y)),
                (*v, SegmentValue::Exact(y + 1)),
            ],
            col.mix(0.75).filled(),
        );
        r.set_margin(4, 4, 0, 0);
        r
    }))
    .map_err(perr)?;
    Ok(())
}

/// The error budgets as horizontal bars (log scale): each source's RMS horizontal position
/// error at the end of the outage, gyro red, accelerometer blue, others grey.
pub fn plot_budget(res: &StudyResult, path: &Path) -> anyhow::Result<()> {
    let nb = res.budgets.len().max(1);
    crate::png::draw_png(path, (1600, 520 * nb as u32), |root| {
        let root = root.clone();
        root.fill(&WHITE).map_err(perr)?;
        let areas = root.split_evenly((nb, 1));
        for (a, b) in areas.iter().zip(&res.budgets) {
            budget_panel(a, b)?;
        }
        root.present().map_err(perr)?;
        Ok(())
    })
}

/// All plots; returns the file names written.
pub fn write_all(res: &StudyResult, out: &Path) -> anyhow::Result<Vec<String>> {
    let mut names = Vec::new();
    for case in Case::ALL {
        let f = format!("errors_{}.png", case.short());
        plot_errors(res, case, &out.join(&f))?;
        names.push(f);
        let f = format!("bands_{}.png", case.short());
        plot_bands(res, case, &out.join(&f))?;
        names.push(f);
        let f = format!("nees_{}.png", case.short());
        plot_nees(res, case, &out.join(&f))?;
        names.push(f);
    }
    if !res.budgets.is_empty() {
        plot_budget(res, &out.join("budget.png"))?;
        names.push("budget.png".into());
    }
    Ok(names)
}
