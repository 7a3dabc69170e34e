//! Overview plot of a trajectory: ground track, speed and height, attitude, specific force and
//! angular rate (from the ideal increments).

use nav_core::earth::{ned_offset_m, Llh};
use nav_sim::trajectory::Trajectory;
use plotters::prelude::*;
use std::path::Path;

fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    (lo - pad, hi + pad)
}

type Series<'a> = (&'a str, RGBColor, Vec<(f64, f64)>);

fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    xlabel: &str,
    ylabel: &str,
    series: &[Series<'_>],
    equal_aspect: bool,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let (mut x0, mut x1) = range(series.iter().flat_map(|s| s.2.iter().map(|p| p.0)));
    let (mut y0, mut y1) = range(series.iter().flat_map(|s| s.2.iter().map(|p| p.1)));
    if equal_aspect {
        let (w, h) = area.dim_in_pixel();
        let (sx, sy) = ((x1 - x0) / w as f64, (y1 - y0) / h as f64);
        let s = sx.max(sy);
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        (x0, x1) = (cx - 0.5 * s * w as f64, cx + 0.5 * s * w as f64);
        (y0, y1) = (cy - 0.5 * s * h as f64, cy + 0.5 * s * h as f64);
    }
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(8)
        .x_label_area_size(32)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    chart
        .configure_mesh()
        .x_desc(xlabel)
        .y_desc(ylabel)
        .draw()
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    for (name, color, pts) in series {
        let c = *color;
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2)));
    }
    if series.len() > 1 {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    }
    Ok(())
}

/// Writes a 2x3 overview PNG of the trajectory to `path`.
pub fn plot_trajectory(tr: &Trajectory, path: &Path) -> anyhow::Result<()> {
    crate::png::draw_png(path, (1800, 1100), |root| {
        let root = root.clone();
        root.fill(&WHITE)
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        let areas = root.split_evenly((2, 3));
        // Decimate to about 5 points per second of data.
        let step = ((0.2 / tr.dt_s).round() as usize).max(1);
        let s0 = tr.truth.first().copied().unwrap_or_default();
        let p0 = Llh {
            lat_rad: s0.lat_rad,
            lon_rad: s0.lon_rad,
            h_m: s0.h_m,
        };
        let pts: Vec<_> = tr.truth.iter().step_by(step).collect();
        let t = |s: &nav_core::types::NavSolution| (s.t_s - tr.t0_s) / 60.0;
        let ned: Vec<(f64, f64)> = pts
            .iter()
            .map(|s| {
                let d = ned_offset_m(
                    &p0,
                    &Llh {
                        lat_rad: s.lat_rad,
                        lon_rad: s.lon_rad,
                        h_m: s.h_m,
                    },
                );
                (d.y, d.x)
            })
            .collect();
        let title = format!("`{}`: ground track (start at 0,0)", tr.scenario.name);
        let a = areas
            .first()
            .ok_or_else(|| anyhow::anyhow!("plot layout"))?;
        panel(
            a,
            &title,
            "east [m]",
            "north [m]",
            &[("track", BLUE, ned)],
            true,
        )?;
        let speed: Vec<_> = pts
            .iter()
            .map(|s| {
                let v = s.vel_ned_mps;
                (t(s), (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            })
            .collect();
        let height: Vec<_> = pts.iter().map(|s| (t(s), s.h_m - s0.h_m)).collect();
        if let Some(a) = areas.get(1) {
            panel(
                a,
                "speed [m/s] and height change [m]",
                "time [min]",
                "",
                &[("speed m/s", BLUE, speed), ("height m", RED, height)],
                false,
            )?;
        }
        let yaw = unwrapped_yaw_deg(&pts, t);
        if let Some(a) = areas.get(2) {
            panel(
                a,
                "yaw, unwrapped [deg]",
                "time [min]",
                "deg",
                &[("yaw", BLUE, yaw)],
                false,
            )?;
        }
        let roll: Vec<_> = pts
            .iter()
            .map(|s| (t(s), s.rpy_rad[0].to_degrees()))
            .collect();
        let pitch: Vec<_> = pts
            .iter()
            .map(|s| (t(s), s.rpy_rad[1].to_degrees()))
            .collect();
        if let Some(a) = areas.get(3) {
            panel(
                a,
                "roll and pitch [deg]",
                "time [min]",
                "deg",
                &[("roll", BLUE, roll), ("pitch", RED, pitch)],
                false,
            )?;
        }
        imu_panels(&areas, tr, step)?;
        root.present().map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        Ok(())
    })
}

/// Yaw in degrees against time, unwrapped (continuous through +-180 deg).
fn unwrapped_yaw_deg(
    pts: &[&nav_core::types::NavSolution],
    t: impl Fn(&nav_core::types::NavSolution) -> f64,
) -> Vec<(f64, f64)> {
    let mut yaw = Vec::with_capacity(pts.len());
    let mut prev = f64::NAN;
    let mut offset = 0.0;
    for s in pts {
        let y = s.rpy_rad[2].to_degrees();
        if prev.is_finite() {
            if y - prev > 180.0 {
                offset -= 360.0;
            } else if y - prev < -180.0 {
                offset += 360.0;
            }
        }
        prev = y;
        yaw.push((t(s), y + offset));
    }
    yaw
}

/// The IMU panels (the fifth and sixth areas): specific force and angular rate against time,
/// every `step`-th sample.
fn imu_panels<DB: DrawingBackend>(
    areas: &[DrawingArea<DB, plotters::coord::Shift>],
    tr: &Trajectory,
    step: usize,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let imu: Vec<_> = tr.imu.iter().step_by(step).collect();
    let ti = |s: &nav_core::types::ImuSample| (s.t_s - tr.t0_s) / 60.0;
    let f = |i: usize| -> Vec<(f64, f64)> {
        imu.iter().map(|s| (ti(s), s.dv_mps[i] / tr.dt_s)).collect()
    };
    if let Some(a) = areas.get(4) {
        panel(
            a,
            "specific force f_b [m/s^2] (z + 9.8 shown)",
            "time [min]",
            "m/s^2",
            &[
                ("f_x", BLUE, f(0)),
                ("f_y", RED, f(1)),
                (
                    "f_z + 9.8",
                    GREEN,
                    f(2).into_iter().map(|(a, b)| (a, b + 9.8)).collect(),
                ),
            ],
            false,
        )?;
    }
    let w = |i: usize| -> Vec<(f64, f64)> {
        imu.iter()
            .map(|s| (ti(s), s.dtheta_rad[i].to_degrees() / tr.dt_s))
            .collect()
    };
    if let Some(a) = areas.get(5) {
        panel(
            a,
            "angular rate w_ib_b [deg/s]",
            "time [min]",
            "deg/s",
            &[
                ("w_x", BLUE, w(0)),
                ("w_y", RED, w(1)),
                ("w_z", GREEN, w(2)),
            ],
            false,
        )?;
    }
    Ok(())
}
