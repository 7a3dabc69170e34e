//! Log-log Allan deviation plot with the confidence band and each fitted component.
use noise_id::fit::FitResult;
use noise_id::DevPoint;
use plotters::coord::combinators::{IntoLogRange, LogCoord};
use plotters::prelude::*;
use std::path::Path;

/// What to draw for one channel.
pub struct PlotInput<'a> {
    /// Title (e.g. "gx: overlapping Allan deviation").
    pub title: String,
    /// Unit label of the deviation (e.g. "deg/s", "m/s^2").
    pub unit: String,
    /// Factor from SI to the plotted unit.
    pub scale: f64,
    /// The curve.
    pub points: &'a [DevPoint],
    /// The fit, if any.
    pub fit: Option<&'a FitResult>,
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    p: &PlotInput<'_>,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("plot: {e}");
    root.fill(&WHITE).map_err(e)?;
    let pts: Vec<&DevPoint> = p.points.iter().filter(|q| q.dev > 0.0).collect();
    if pts.is_empty() {
        anyhow::bail!("plot: no positive deviations");
    }
    let s = p.scale;
    let x0 = pts.iter().map(|q| q.tau_s).fold(f64::INFINITY, f64::min) / 1.5;
    let x1 = pts.iter().map(|q| q.tau_s).fold(0.0, f64::max) * 1.5;
    let mut y0 = pts
        .iter()
        .map(|q| if q.lo > 0.0 { q.lo } else { q.dev })
        .fold(f64::INFINITY, f64::min)
        * s;
    let y1 = pts
        .iter()
        .map(|q| if q.hi.is_finite() { q.hi } else { q.dev })
        .fold(0.0, f64::max)
        * s
        * 1.5;
    y0 = (y0 / 3.0).max(y1 * 1e-6);
    let mut chart = ChartBuilder::on(&root)
        .caption(&p.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(80)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("tau [s]")
        .y_desc(format!("Allan deviation [{}]", p.unit))
        .y_labels(8)
        .x_labels(12)
        .y_label_formatter(&|v| format!("{v:.1e}"))
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(e)?;
    // Confidence band.
    let band_color = RGBColor(120, 160, 230);
    let mut poly: Vec<(f64, f64)> = pts.iter().map(|q| (q.tau_s, q.hi.max(q.dev) * s)).collect();
    poly.extend(
        pts.iter()
            .rev()
            .map(|q| (q.tau_s, q.lo.clamp(y0 / s, q.dev) * s)),
    );
    chart
        .draw_series(std::iter::once(Polygon::new(
            poly,
            band_color.mix(0.35).filled(),
        )))
        .map_err(e)?
        .label("68% confidence")
        .legend(move |(x, y)| {
            Rectangle::new([(x, y - 5), (x + 16, y + 5)], band_color.mix(0.35).filled())
        });
    chart
        .draw_series(LineSeries::new(
            pts.iter().map(|q| (q.tau_s, q.dev * s)),
            BLUE.stroke_width(2),
        ))
        .map_err(e)?
        .label("measured")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLUE.stroke_width(2)));
    chart
        .draw_series(
            pts.iter()
                .map(|q| Circle::new((q.tau_s, q.dev * s), 3, BLUE.filled())),
        )
        .map_err(e)?;
    if let Some(f) = p.fit {
        draw_fit(&mut chart, f, (x0, x1), (y0, y1), s)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

/// Writes the plot as PNG (`<stem>.png`) and SVG (`<stem>.svg`).
pub fn plot_allan(p: &PlotInput<'_>, stem: &Path) -> anyhow::Result<()> {
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    crate::png::draw_png(&png, (1000, 720), |root| draw(root.clone(), p))?;
    draw(SVGBackend::new(&svg, (1000, 720)).into_drawing_area(), p)?;
    Ok(())
}

/// The fitted model on the chart: each noise term dashed, their sum solid, over `x` (tau, s)
/// and kept inside `y` (deviation in the plot's unit, `s` the scale to it).
fn draw_fit<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>,
    f: &FitResult,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    s: f64,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("plot: {e}");
    let ngrid = 200;
    let taus: Vec<f64> = (0..ngrid)
        .map(|i| (x0.ln() + (x1.ln() - x0.ln()) * i as f64 / (ngrid - 1) as f64).exp())
        .collect();
    let names = [
        "quantization",
        "white",
        "Gauss-Markov",
        "random walk",
        "flicker",
    ];
    let colors = [
        RGBColor(150, 150, 150),
        RGBColor(0, 150, 0),
        RGBColor(200, 120, 0),
        RGBColor(160, 0, 160),
        RGBColor(0, 160, 160),
    ];
    for (k, name) in names.iter().enumerate() {
        let v: Vec<(f64, f64)> = taus
            .iter()
            .map(|&t| (t, f.components(t)[k].max(0.0).sqrt() * s))
            .filter(|&(_, d)| d >= y0 && d <= y1)
            .collect();
        if v.len() < 2 {
            continue;
        }
        let c = colors[k];
        chart
            .draw_series(DashedLineSeries::new(v, 6, 4, c.stroke_width(2)))
            .map_err(e)?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2)));
    }
    chart
        .draw_series(LineSeries::new(
            taus.iter()
                .map(|&t| (t, f.avar(t).max(0.0).sqrt() * s))
                .filter(|&(_, d)| d >= y0 && d <= y1),
            RED.stroke_width(2),
        ))
        .map_err(e)?
        .label("fit")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], RED.stroke_width(2)));
    Ok(())
}
