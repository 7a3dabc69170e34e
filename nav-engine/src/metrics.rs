//! Error metrics of a run, in the field's terms.
//!
//! - Against the **truth** (simulated cases): at every epoch where the solution and the truth
//!   share a time stamp (within 0.1 ms), position error (solution minus truth) in N, E, D,
//!   horizontal and 3D, velocity error N, E, D and attitude error roll, pitch, yaw (wrapped to
//!   +-180 deg).
//! - Against the **withheld GNSS fixes** (real data, no truth): at every fix inside an imposed
//!   outage, the predicted antenna position (lever arm applied) minus the fix: position only.
//!   Outside outages the same comparison with the fixes the filter used (prior residuals: the
//!   solution propagated from the previous update) is reported as `gnss_residuals`.
//!
//! Per outage: the error at its END (the last comparison epoch before the outage ends) and the
//! MAXIMUM error inside it (horizontal, height, 3D, heading), and over all outages the RMS and
//! the maximum of those end errors and maxima: "RMS of the maximum drift per outage", the way
//! the KF-GINS paper reports its 60 s-every-180 s protocol.

use crate::run::{CoastTrack, FixUse, InnovationRecord, Outage, RunOutput};
use nav_core::types::NavSolution;
use serde::Serialize;

mod truth;
pub use truth::{error_vs_truth, errors_vs_truth, interpolate, TruthMatcher};

/// RMS and maximum of |x| over `n` samples (NaN when n = 0).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stat {
    /// Root mean square.
    pub rms: f64,
    /// Maximum absolute value.
    pub max: f64,
    /// Number of samples.
    pub n: usize,
}

impl Stat {
    /// Statistics of the values (non-finite values are skipped).
    pub fn of(values: impl IntoIterator<Item = f64>) -> Self {
        let (mut ss, mut mx, mut n) = (0.0, 0.0f64, 0usize);
        for v in values.into_iter().filter(|v| v.is_finite()) {
            ss += v * v;
            mx = mx.max(v.abs());
            n += 1;
        }
        if n == 0 {
            return Self {
                rms: f64::NAN,
                max: f64::NAN,
                n: 0,
            };
        }
        Self {
            rms: (ss / n as f64).sqrt(),
            max: mx,
            n,
        }
    }
}

/// One error sample: solution minus reference.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrSample {
    /// Time, GPS seconds of week.
    pub t_s: f64,
    /// Position error N, E, D, m.
    pub pos_ned_m: [f64; 3],
    /// Velocity error N, E, D, m/s (NaN without truth).
    pub vel_ned_mps: [f64; 3],
    /// Attitude error roll, pitch, yaw, deg (NaN without truth).
    pub att_deg: [f64; 3],
}

impl ErrSample {
    /// Horizontal position error, m.
    pub fn horizontal_m(&self) -> f64 {
        self.pos_ned_m[0].hypot(self.pos_ned_m[1])
    }
    /// Height error (up), m.
    pub fn height_m(&self) -> f64 {
        -self.pos_ned_m[2]
    }
    /// 3D position error, m.
    pub fn d3_m(&self) -> f64 {
        let [a, b, c] = self.pos_ned_m;
        (a * a + b * b + c * c).sqrt()
    }
}

/// Statistics of every error component.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    /// North position, m.
    pub pos_n_m: Stat,
    /// East position, m.
    pub pos_e_m: Stat,
    /// Down position, m.
    pub pos_d_m: Stat,
    /// Horizontal position, m.
    pub pos_horizontal_m: Stat,
    /// 3D position, m.
    pub pos_3d_m: Stat,
    /// North velocity, m/s.
    pub vel_n_mps: Stat,
    /// East velocity, m/s.
    pub vel_e_mps: Stat,
    /// Down velocity, m/s.
    pub vel_d_mps: Stat,
    /// Roll, deg.
    pub roll_deg: Stat,
    /// Pitch, deg.
    pub pitch_deg: Stat,
    /// Yaw (heading), deg.
    pub yaw_deg: Stat,
}

impl ErrorStats {
    /// Statistics of a set of samples.
    pub fn of<'a>(s: impl Iterator<Item = &'a ErrSample> + Clone) -> Self {
        let c = |f: &dyn Fn(&ErrSample) -> f64| Stat::of(s.clone().map(f));
        Self {
            pos_n_m: c(&|e| e.pos_ned_m[0]),
            pos_e_m: c(&|e| e.pos_ned_m[1]),
            pos_d_m: c(&|e| e.pos_ned_m[2]),
            pos_horizontal_m: c(&|e| e.horizontal_m()),
            pos_3d_m: c(&|e| e.d3_m()),
            vel_n_mps: c(&|e| e.vel_ned_mps[0]),
            vel_e_mps: c(&|e| e.vel_ned_mps[1]),
            vel_d_mps: c(&|e| e.vel_ned_mps[2]),
            roll_deg: c(&|e| e.att_deg[0]),
            pitch_deg: c(&|e| e.att_deg[1]),
            yaw_deg: c(&|e| e.att_deg[2]),
        }
    }
}

/// Horizontal, height, 3D and heading error at one instant (absolute values, heading NaN
/// without truth).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Drift {
    /// Horizontal, m.
    pub horizontal_m: f64,
    /// |Height|, m.
    pub height_m: f64,
    /// 3D, m.
    pub d3_m: f64,
    /// |Heading|, deg.
    pub heading_deg: f64,
}

impl Drift {
    fn of(e: &ErrSample) -> Self {
        Self {
            horizontal_m: e.horizontal_m(),
            height_m: e.height_m().abs(),
            d3_m: e.d3_m(),
            heading_deg: e.att_deg[2].abs(),
        }
    }
}

/// Metrics of one outage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutageMetrics {
    /// Index of the outage.
    pub index: usize,
    /// Start, GPS seconds of week.
    pub start_s: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// Time of the last comparison in the outage, s.
    pub end_t_s: f64,
    /// Error at the end of the outage.
    pub end: Drift,
    /// Maximum of each error inside the outage.
    pub max: Drift,
    /// All statistics inside the outage.
    pub stats: ErrorStats,
}

/// Over all outages: RMS and max of the end errors and of the per-outage maxima.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OutageSummary {
    /// Outages with at least one comparison.
    pub count: usize,
    /// Horizontal error at the end.
    pub end_horizontal_m: Stat,
    /// |Height| error at the end.
    pub end_height_m: Stat,
    /// 3D error at the end.
    pub end_3d_m: Stat,
    /// |Heading| error at the end.
    pub end_heading_deg: Stat,
    /// Maximum horizontal drift per outage (RMS over outages = the field's figure).
    pub max_horizontal_m: Stat,
    /// Maximum |height| drift per outage.
    pub max_height_m: Stat,
    /// Maximum 3D drift per outage.
    pub max_3d_m: Stat,
    /// Maximum |heading| drift per outage.
    pub max_heading_deg: Stat,
}

impl OutageSummary {
    /// Summary of per-outage metrics.
    pub fn of(v: &[OutageMetrics]) -> Self {
        let s = |f: &dyn Fn(&OutageMetrics) -> f64| Stat::of(v.iter().map(f));
        Self {
            count: v.len(),
            end_horizontal_m: s(&|o| o.end.horizontal_m),
            end_height_m: s(&|o| o.end.height_m),
            end_3d_m: s(&|o| o.end.d3_m),
            end_heading_deg: s(&|o| o.end.heading_deg),
            max_horizontal_m: s(&|o| o.max.horizontal_m),
            max_height_m: s(&|o| o.max.height_m),
            max_3d_m: s(&|o| o.max.d3_m),
            max_heading_deg: s(&|o| o.max.heading_deg),
        }
    }
}

/// GNSS prior residuals of the fixes the filter used (outside outages), m.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ResidualStats {
    /// Horizontal.
    pub horizontal_m: Stat,
    /// Vertical.
    pub vertical_m: Stat,
    /// Fixes rejected by the gate.
    pub rejected: usize,
}

/// Metrics of a coasting baseline.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoastingMetrics {
    /// Which correction the coasting applied.
    pub mode: String,
    /// Per outage.
    pub outages: Vec<OutageMetrics>,
    /// Over outages.
    pub summary: OutageSummary,
}

/// Everything in `metrics.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    /// `truth` or `withheld_gnss`.
    pub reference: String,
    /// Model run.
    pub model: String,
    /// All comparison epochs.
    pub overall: ErrorStats,
    /// Comparison epochs outside outages (truth only; with GNSS see `gnss_residuals`).
    pub outside_outages: Option<ErrorStats>,
    /// The outages.
    pub outages: Vec<Outage>,
    /// Per outage.
    pub per_outage: Vec<OutageMetrics>,
    /// Over outages.
    pub outage_summary: OutageSummary,
    /// Prior residuals of the used fixes.
    pub gnss_residuals: ResidualStats,
    /// Free-inertial coasting baselines from the same points.
    pub coasting: Vec<CoastingMetrics>,
    /// What the innovation gate and its model-mismatch monitor did (in numbers and words).
    pub gating: crate::run::gating_report::GatingReport,
    /// Land-vehicle aiding updates used/rejected per source.
    pub aiding: crate::run::aiding::AidingReport,
}

/// Position errors at GNSS fixes (predicted minus measured) of the records `keep` selects.
pub fn errors_vs_fixes<'a>(
    recs: impl Iterator<Item = &'a InnovationRecord>,
    keep: impl Fn(&InnovationRecord) -> bool,
) -> Vec<ErrSample> {
    recs.filter(|r| keep(r) && r.innovation.iter().take(3).all(|v| v.is_finite()))
        .map(|r| ErrSample {
            t_s: r.t_s,
            pos_ned_m: r.pos_error_ned_m(),
            vel_ned_mps: [f64::NAN; 3],
            att_deg: [f64::NAN; 3],
        })
        .collect()
}

/// Per-outage metrics of error samples (samples with time in `[start, end)` belong to it).
pub fn outage_metrics(samples: &[ErrSample], outages: &[Outage]) -> Vec<OutageMetrics> {
    let mut v = Vec::new();
    for (i, o) in outages.iter().enumerate() {
        let inside: Vec<&ErrSample> = samples
            .iter()
            .filter(|e| e.t_s >= o.start_s && e.t_s < o.end_s())
            .collect();
        let Some(last) = inside.last() else {
            continue;
        };
        let mx = |f: &dyn Fn(&ErrSample) -> f64| {
            inside
                .iter()
                .map(|e| f(e))
                .filter(|x| x.is_finite())
                .fold(f64::NAN, f64::max)
        };
        v.push(OutageMetrics {
            index: i,
            start_s: o.start_s,
            duration_s: o.duration_s,
            end_t_s: last.t_s,
            end: Drift::of(last),
            max: Drift {
                horizontal_m: mx(&|e| e.horizontal_m()),
                height_m: mx(&|e| e.height_m().abs()),
                d3_m: mx(&|e| e.d3_m()),
                heading_deg: mx(&|e| e.att_deg[2].abs()),
            },
            stats: ErrorStats::of(inside.iter().copied()),
        });
    }
    v
}

/// Metrics of a run, against the truth when given, else against the withheld fixes.
pub fn compute(run: &RunOutput, truth: Option<&[NavSolution]>) -> Metrics {
    let residuals = {
        let used = errors_vs_fixes(run.innovations.iter(), |r| {
            matches!(r.used, FixUse::Accepted | FixUse::Forced)
        });
        ResidualStats {
            horizontal_m: Stat::of(used.iter().map(|e| e.horizontal_m())),
            vertical_m: Stat::of(used.iter().map(|e| e.height_m())),
            rejected: run
                .innovations
                .iter()
                .filter(|r| r.used == FixUse::Rejected)
                .count(),
        }
    };
    let in_outage = |t: f64| run.outages.iter().any(|o| o.contains(t));
    let (reference, samples, outside) = match truth {
        Some(tr) => {
            let s = errors_vs_truth(&run.nav, tr);
            let out = ErrorStats::of(s.iter().filter(|e| !in_outage(e.t_s)));
            ("truth", s, Some(out))
        }
        None => (
            "withheld_gnss",
            errors_vs_fixes(run.innovations.iter(), |r| r.used == FixUse::Withheld),
            None,
        ),
    };
    let per_outage = outage_metrics(&samples, &run.outages);
    Metrics {
        reference: reference.into(),
        model: run.model.name().into(),
        overall: ErrorStats::of(samples.iter()),
        outside_outages: outside,
        outages: run.outages.clone(),
        outage_summary: OutageSummary::of(&per_outage),
        per_outage,
        gnss_residuals: residuals,
        coasting: Vec::new(),
        gating: run.gating.clone(),
        aiding: run.aiding.clone(),
    }
}

/// Metrics of coasting tracks (same reference rule as [`compute`]).
pub fn coasting_metrics(
    mode: &str,
    tracks: &[CoastTrack],
    outages: &[Outage],
    truth: Option<&[NavSolution]>,
) -> CoastingMetrics {
    let mut per = Vec::new();
    for t in tracks {
        let samples = match truth {
            Some(tr) => errors_vs_truth(&t.nav, tr),
            None => errors_vs_fixes(t.fixes.iter(), |_| true),
        };
        let Some(o) = outages.get(t.outage) else {
            continue;
        };
        // evaluate against this outage only, keeping its index
        let mut m = outage_metrics(&samples, std::slice::from_ref(o));
        for x in &mut m {
            x.index = t.outage;
        }
        per.extend(m);
    }
    CoastingMetrics {
        mode: mode.into(),
        summary: OutageSummary::of(&per),
        outages: per,
    }
}

fn f(x: f64, p: usize) -> String {
    if x.is_finite() {
        format!("{x:.p$}")
    } else {
        "-".into()
    }
}

/// A short printable summary table.
pub fn summary_table(m: &Metrics) -> String {
    let mut s = String::new();
    let o = &m.overall;
    s.push_str(&format!(
        "reference: {} | model: {}\n",
        m.reference, m.model
    ));
    s.push_str("                      RMS        max\n");
    let rows: [(&str, &Stat, usize); 10] = [
        ("position N [m]", &o.pos_n_m, 3),
        ("position E [m]", &o.pos_e_m, 3),
        ("position D [m]", &o.pos_d_m, 3),
        ("horizontal [m]", &o.pos_horizontal_m, 3),
        ("velocity N [m/s]", &o.vel_n_mps, 4),
        ("velocity E [m/s]", &o.vel_e_mps, 4),
        ("velocity D [m/s]", &o.vel_d_mps, 4),
        ("roll [deg]", &o.roll_deg, 4),
        ("pitch [deg]", &o.pitch_deg, 4),
        ("yaw [deg]", &o.yaw_deg, 4),
    ];
    if rows.iter().all(|r| r.1.n == 0) {
        s.push_str(
            "  (no reference epochs: give a [truth] file, or impose outages (--outage) to compare \
             with the withheld fixes)\n",
        );
    }
    for (name, st, p) in rows {
        if st.n > 0 {
            s.push_str(&format!(
                "  {name:<18} {:>10} {:>10}\n",
                f(st.rms, p),
                f(st.max, p)
            ));
        }
    }
    let r = &m.gnss_residuals;
    s.push_str(&format!(
        "GNSS prior residuals (used fixes): horizontal RMS {} m, vertical RMS {} m, {} rejected\n",
        f(r.horizontal_m.rms, 3),
        f(r.vertical_m.rms, 3),
        r.rejected
    ));
    if !m.per_outage.is_empty() {
        s.push_str(&outage_table("filter", &m.per_outage, &m.outage_summary));
        for c in &m.coasting {
            s.push_str(&outage_table(
                &format!("coasting ({})", c.mode),
                &c.outages,
                &c.summary,
            ));
        }
    }
    s
}

/// Per-outage table with the summary rows.
pub fn outage_table(title: &str, per: &[OutageMetrics], sum: &OutageSummary) -> String {
    let mut s = format!(
        "{title}: {} outage(s)\n  #   start[s]  dur[s] | end: hor[m] hgt[m] hdg[deg] | max: hor[m] hgt[m] 3D[m] hdg[deg]\n",
        per.len()
    );
    for o in per {
        s.push_str(&format!(
            "  {:<3} {:>9.1} {:>6.1} | {:>11} {:>6} {:>8} | {:>11} {:>6} {:>5} {:>8}\n",
            o.index,
            o.start_s,
            o.duration_s,
            f(o.end.horizontal_m, 3),
            f(o.end.height_m, 3),
            f(o.end.heading_deg, 3),
            f(o.max.horizontal_m, 3),
            f(o.max.height_m, 3),
            f(o.max.d3_m, 3),
            f(o.max.heading_deg, 3),
        ));
    }
    // the summary rows: RMS and max over the outages of each column
    for (label, pick) in [
        ("RMS", (|st: &Stat| st.rms) as fn(&Stat) -> f64),
        ("max", |st: &Stat| st.max),
    ] {
        s.push_str(&format!(
            "  {label:<22} | {:>11} {:>6} {:>8} | {:>11} {:>6} {:>5} {:>8}\n",
            f(pick(&sum.end_horizontal_m), 3),
            f(pick(&sum.end_height_m), 3),
            f(pick(&sum.end_heading_deg), 3),
            f(pick(&sum.max_horizontal_m), 3),
            f(pick(&sum.max_height_m), 3),
            f(pick(&sum.max_3d_m), 3),
            f(pick(&sum.max_heading_deg), 3),
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stat_and_wrap() {
        let s = Stat::of([3.0, -4.0, f64::NAN]);
        assert_eq!(s.n, 2);
        assert!((s.rms - 12.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(s.max, 4.0);
        assert!(Stat::of([]).rms.is_nan());
    }
}

/// [`Stat`] accumulated one value at a time (same sums in the same order: identical result).
#[derive(Debug, Clone, Copy, Default)]
struct StatAcc {
    ss: f64,
    mx: f64,
    n: usize,
}

impl StatAcc {
    fn push(&mut self, v: f64) {
        if v.is_finite() {
            self.ss += v * v;
            self.mx = self.mx.max(v.abs());
            self.n += 1;
        }
    }

    fn stat(&self) -> Stat {
        if self.n == 0 {
            return Stat {
                rms: f64::NAN,
                max: f64::NAN,
                n: 0,
            };
        }
        Stat {
            rms: (self.ss / self.n as f64).sqrt(),
            max: self.mx,
            n: self.n,
        }
    }
}

/// [`ErrorStats`] accumulated sample by sample.
#[derive(Debug, Clone, Copy, Default)]
pub struct ErrorStatsAcc {
    c: [StatAcc; 11],
}

impl ErrorStatsAcc {
    /// Adds one sample.
    pub fn push(&mut self, e: &ErrSample) {
        let v = [
            e.pos_ned_m[0],
            e.pos_ned_m[1],
            e.pos_ned_m[2],
            e.horizontal_m(),
            e.d3_m(),
            e.vel_ned_mps[0],
            e.vel_ned_mps[1],
            e.vel_ned_mps[2],
            e.att_deg[0],
            e.att_deg[1],
            e.att_deg[2],
        ];
        for (c, x) in self.c.iter_mut().zip(v) {
            c.push(x);
        }
    }

    /// The statistics so far.
    pub fn stats(&self) -> ErrorStats {
        let [a, b, c, d, e, f, g, h, i, j, k] = self.c.map(|s| s.stat());
        ErrorStats {
            pos_n_m: a,
            pos_e_m: b,
            pos_d_m: c,
            pos_horizontal_m: d,
            pos_3d_m: e,
            vel_n_mps: f,
            vel_e_mps: g,
            vel_d_mps: h,
            roll_deg: i,
            pitch_deg: j,
            yaw_deg: k,
        }
    }
}

/// [`OutageMetrics`] of one outage accumulated sample by sample.
#[derive(Debug, Clone, Copy)]
struct OutageAcc {
    last: Option<ErrSample>,
    max: [f64; 4],
    stats: ErrorStatsAcc,
}

impl OutageAcc {
    fn new() -> Self {
        Self {
            last: None,
            max: [f64::NAN; 4],
            stats: ErrorStatsAcc::default(),
        }
    }

    fn push(&mut self, e: &ErrSample) {
        let v = [
            e.horizontal_m(),
            e.height_m().abs(),
            e.d3_m(),
            e.att_deg[2].abs(),
        ];
        for (m, x) in self.max.iter_mut().zip(v) {
            if x.is_finite() {
                *m = m.max(x);
            }
        }
        self.stats.push(e);
        self.last = Some(*e);
    }

    fn metrics(&self, index: usize, o: &Outage) -> Option<OutageMetrics> {
        let last = self.last?;
        let [h, v, d, y] = self.max;
        Some(OutageMetrics {
            index,
            start_s: o.start_s,
            duration_s: o.duration_s,
            end_t_s: last.t_s,
            end: Drift::of(&last),
            max: Drift {
                horizontal_m: h,
                height_m: v,
                d3_m: d,
                heading_deg: y,
            },
            stats: self.stats.stats(),
        })
    }
}

/// Error samples accumulated into the overall, outside-outage and per-outage statistics as
/// they come (the online form of [`compute`]'s statistics; identical numbers).
#[derive(Debug, Clone)]
pub struct SampleAcc {
    outages: Vec<Outage>,
    overall: ErrorStatsAcc,
    outside: ErrorStatsAcc,
    per: Vec<OutageAcc>,
}

impl SampleAcc {
    /// For the (sorted) outages of a run.
    pub fn new(outages: &[Outage]) -> Self {
        Self {
            outages: outages.to_vec(),
            overall: ErrorStatsAcc::default(),
            outside: ErrorStatsAcc::default(),
            per: vec![OutageAcc::new(); outages.len()],
        }
    }

    /// Adds one sample (in time order).
    pub fn push(&mut self, e: &ErrSample) {
        self.overall.push(e);
        let mut inside = false;
        for (o, acc) in self.outages.iter().zip(self.per.iter_mut()) {
            if o.contains(e.t_s) {
                inside = true;
            }
            if e.t_s >= o.start_s && e.t_s < o.end_s() {
                acc.push(e);
            }
        }
        if !inside {
            self.outside.push(e);
        }
    }

    /// Overall statistics.
    pub fn overall(&self) -> ErrorStats {
        self.overall.stats()
    }

    /// Statistics outside the outages.
    pub fn outside(&self) -> ErrorStats {
        self.outside.stats()
    }

    /// Per-outage metrics (outages with at least one sample).
    pub fn per_outage(&self) -> Vec<OutageMetrics> {
        self.outages
            .iter()
            .zip(&self.per)
            .enumerate()
            .filter_map(|(i, (o, a))| a.metrics(i, o))
            .collect()
    }
}

/// Metrics of one coasting track against its outage (as [`coasting_metrics`] does per
/// track), for online use: the track can be dropped afterwards. `truth`: the whole truth, or
/// only its records inside the track's outage (`[start, end)`: the only epochs the outage's
/// metrics count, each compared by itself, so the result is the same).
pub fn coasting_track_metrics(
    t: &CoastTrack,
    outages: &[Outage],
    truth: Option<&[NavSolution]>,
) -> Vec<OutageMetrics> {
    let samples = match truth {
        Some(tr) => {
            // only the truth around the track matters
            let (a, b) = match (t.nav.first(), t.nav.last()) {
                (Some(f), Some(l)) => (
                    tr.partition_point(|s| s.t_s < f.t_s - 1e-3),
                    tr.partition_point(|s| s.t_s <= l.t_s + 1e-3),
                ),
                _ => (0, 0),
            };
            errors_vs_truth(&t.nav, tr.get(a..b).unwrap_or(&[]))
        }
        None => errors_vs_fixes(t.fixes.iter(), |_| true),
    };
    let Some(o) = outages.get(t.outage) else {
        return Vec::new();
    };
    let mut m = outage_metrics(&samples, std::slice::from_ref(o));
    for x in &mut m {
        x.index = t.outage;
    }
    m
}

/// [`ResidualStats`] accumulated fix by fix (identical to [`compute`]'s).
#[derive(Debug, Clone, Copy, Default)]
pub struct ResidualAcc {
    h: StatAcc,
    v: StatAcc,
    rejected: usize,
}

impl ResidualAcc {
    /// Adds one innovation record (time order).
    pub fn push(&mut self, r: &InnovationRecord) {
        if r.used == FixUse::Rejected {
            self.rejected += 1;
        }
        let used = matches!(r.used, FixUse::Accepted | FixUse::Forced);
        for e in errors_vs_fixes(std::iter::once(r), |_| used) {
            self.h.push(e.horizontal_m());
            self.v.push(e.height_m());
        }
    }

    /// The statistics so far.
    pub fn stats(&self) -> ResidualStats {
        ResidualStats {
            horizontal_m: self.h.stat(),
            vertical_m: self.v.stat(),
            rejected: self.rejected,
        }
    }
}

/// Metrics from their online parts: `samples` (against the truth, or the withheld fixes when
/// `truth_reference` is false), the GNSS residuals and the coasting metrics per mode (name,
/// per-outage metrics in any order).
pub fn assemble(
    run: &RunOutput,
    residuals: &ResidualAcc,
    samples: &SampleAcc,
    truth_reference: bool,
    coasting: Vec<(String, Vec<OutageMetrics>)>,
) -> Metrics {
    let residuals = residuals.stats();
    let per_outage = samples.per_outage();
    Metrics {
        reference: if truth_reference {
            "truth"
        } else {
            "withheld_gnss"
        }
        .into(),
        model: run.model.name().into(),
        overall: samples.overall(),
        outside_outages: truth_reference.then(|| samples.outside()),
        outages: run.outages.clone(),
        outage_summary: OutageSummary::of(&per_outage),
        per_outage,
        gnss_residuals: residuals,
        coasting: coasting
            .into_iter()
            .map(|(mode, mut per)| {
                per.sort_by_key(|m| m.index);
                CoastingMetrics {
                    mode,
                    summary: OutageSummary::of(&per),
                    outages: per,
                }
            })
            .collect(),
        gating: run.gating.clone(),
        aiding: run.aiding.clone(),
    }
}
