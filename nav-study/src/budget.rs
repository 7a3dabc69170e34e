//! The error budget: the position error at the end of the outage with each error source alone
//! (same seeds, same random streams as the all-sources runs), its mean square over the runs,
//! and the check that the contributions add up in variance to the all-sources total.
//!
//! For a linear(ised) filter the error is a sum of the sources' contributions run by run
//! (superposition), and independent sources add in variance. The difference between the total
//! mean square and the sum of the contributions is then only the sampling noise of the cross
//! terms (zero in expectation) plus any nonlinearity; both are reported.

use super::setup::Source;
use super::setup::Variant;
use serde::Serialize;

/// One source's contribution.
#[derive(Debug, Clone, Serialize)]
pub struct BudgetEntry {
    /// The source.
    pub source: Source,
    /// Human-readable name.
    pub label: String,
    /// Mean square position error over the runs, N, E, D, m^2.
    pub mse_ned_m2: [f64; 3],
    /// RMS horizontal position error, m.
    pub rms_horizontal_m: f64,
    /// Share of the sum of the horizontal mean squares (0..1).
    pub share_horizontal: f64,
}

/// The budget of one model.
#[derive(Debug, Clone, Serialize)]
pub struct Budget {
    /// The filter model.
    pub model: Variant,
    /// Evaluation epoch, s after the first IMU epoch.
    pub t_eval_rel_s: f64,
    /// Runs per source.
    pub runs: usize,
    /// Contributions, in [`Source::ALL`] order.
    pub entries: Vec<BudgetEntry>,
    /// Mean square position error with all sources on, N, E, D, m^2.
    pub total_mse_ned_m2: [f64; 3],
    /// RMS horizontal error with all sources on, m.
    pub total_rms_horizontal_m: f64,
    /// Sum of the contributions' horizontal mean squares, m^2.
    pub sum_mse_horizontal_m2: f64,
    /// Sum of the contributions' 3-D mean squares over the total 3-D mean square.
    pub ratio_sum_to_total_3d: f64,
    /// Sum of the contributions' horizontal mean squares over the total's.
    pub ratio_sum_to_total_horizontal: f64,
    /// Standard error of `ratio_sum_to_total_horizontal` from the run-to-run spread of
    /// (total minus sum of contributions) (sampling noise of the cross terms).
    pub ratio_std_error: f64,
    /// Superposition check: `sum_r |e_total - sum_s e_s|^2 / sum_r |e_total|^2` (3-D).
    pub superposition_residual: f64,
    /// Share of the gyro sources in the sum (horizontal).
    pub gyro_share: f64,
    /// Share of the accelerometer sources in the sum (horizontal).
    pub accel_share: f64,
    /// The largest contributor.
    pub largest: Source,
    /// Average position NEES of the all-sources runs at the evaluation epoch (from the
    /// filter's position standard deviation there), when that std is known.
    pub total_pos_nees: Option<f64>,
    /// Two-sided 95 % band of that average (runs x 3 degrees of freedom).
    pub total_pos_nees_band: (f64, f64),
}

fn h2(e: &[f64; 3]) -> f64 {
    e[0] * e[0] + e[1] * e[1]
}

fn d3(e: &[f64; 3]) -> f64 {
    e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
}

impl Budget {
    /// The budget from the all-sources errors `total` (one per run, N/E/D m) and each source's
    /// errors alone (runs in the same seed order).
    pub fn compute(
        model: Variant,
        t_eval_rel_s: f64,
        total: &[[f64; 3]],
        per_source: &[(Source, Vec<[f64; 3]>)],
        pos_std_at_eval: Option<[f64; 3]>,
    ) -> Self {
        let r = total.len();
        let rf = r.max(1) as f64;
        let mse = |v: &[[f64; 3]]| {
            let mut m = [0.0; 3];
            for e in v {
                for i in 0..3 {
                    m[i] += e[i] * e[i] / v.len().max(1) as f64;
                }
            }
            m
        };
        let total_mse = mse(total);
        let tot_h = total_mse[0] + total_mse[1];
        let tot_3 = tot_h + total_mse[2];
        let mut entries = Vec::new();
        let (mut sum_h, mut sum_3) = (0.0, 0.0);
        for (s, v) in per_source {
            let m = mse(v);
            sum_h += m[0] + m[1];
            sum_3 += m[0] + m[1] + m[2];
            entries.push(BudgetEntry {
                source: *s,
                label: s.label().to_string(),
                mse_ned_m2: m,
                rms_horizontal_m: (m[0] + m[1]).sqrt(),
                share_horizontal: 0.0,
            });
        }
        for e in &mut entries {
            e.share_horizontal = (e.mse_ned_m2[0] + e.mse_ned_m2[1]) / sum_h.max(f64::MIN_POSITIVE);
        }
        // per-run difference total - sum of contributions (horizontal), and superposition
        let mut d = Vec::with_capacity(r);
        let (mut res, mut den) = (0.0, 0.0);
        for (k, t) in total.iter().enumerate() {
            let mut s_h = 0.0;
            let mut s_vec = [0.0; 3];
            for (_, v) in per_source {
                if let Some(e) = v.get(k) {
                    s_h += h2(e);
                    for i in 0..3 {
                        s_vec[i] += e[i];
                    }
                }
            }
            d.push(h2(t) - s_h);
            res += d3(&[t[0] - s_vec[0], t[1] - s_vec[1], t[2] - s_vec[2]]);
            den += d3(t);
        }
        let dm = d.iter().sum::<f64>() / rf;
        let dv = d.iter().map(|x| (x - dm) * (x - dm)).sum::<f64>() / (rf - 1.0).max(1.0);
        // ratio = sum / total = 1 - mean(d) / tot_h; its standard error from d's spread
        let ratio_std_error = (dv / rf).sqrt() / tot_h.max(f64::MIN_POSITIVE);
        let share = |f: fn(Source) -> bool| {
            entries
                .iter()
                .filter(|e| f(e.source))
                .map(|e| e.share_horizontal)
                .sum::<f64>()
        };
        let largest = entries
            .iter()
            .max_by(|a, b| a.share_horizontal.total_cmp(&b.share_horizontal))
            .map_or(Source::GyroWhite, |e| e.source);
        let total_pos_nees = pos_std_at_eval.map(|s| {
            total
                .iter()
                .map(|e| (0..3).map(|i| (e[i] / s[i]).powi(2)).sum::<f64>())
                .sum::<f64>()
                / rf
        });
        Self {
            model,
            t_eval_rel_s,
            total_pos_nees,
            total_pos_nees_band: noise_id::stats::nees_band_95(r, 3),
            runs: r,
            gyro_share: share(Source::is_gyro),
            accel_share: share(Source::is_accel),
            entries,
            total_mse_ned_m2: total_mse,
            total_rms_horizontal_m: tot_h.sqrt(),
            sum_mse_horizontal_m2: sum_h,
            ratio_sum_to_total_3d: sum_3 / tot_3.max(f64::MIN_POSITIVE),
            ratio_sum_to_total_horizontal: sum_h / tot_h.max(f64::MIN_POSITIVE),
            ratio_std_error,
            superposition_residual: res / den.max(f64::MIN_POSITIVE),
            largest,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_superposition_of_orthogonal_sources_adds_up() {
        // two sources whose per-run errors are orthogonal across runs: the cross terms vanish
        let a = vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]];
        let b = vec![[0.0, 2.0, 1.0], [0.0, 2.0, -1.0]];
        let total: Vec<[f64; 3]> = a
            .iter()
            .zip(&b)
            .map(|(x, y)| [x[0] + y[0], x[1] + y[1], x[2] + y[2]])
            .collect();
        let bud = Budget::compute(
            Variant::Nbk,
            10.0,
            &total,
            &[(Source::GyroWhite, a), (Source::AccelRw, b)],
            Some([1.0, 2.0, 1.0]),
        );
        // run 1 e = (1, 2, 1): 1 + 1 + 1 = 3; run 2 e = (-1, 2, -1): 3  =>  3
        assert!((bud.total_pos_nees.unwrap_or(0.0) - 3.0).abs() < 1e-12);
        assert!((bud.ratio_sum_to_total_horizontal - 1.0).abs() < 1e-12);
        assert!(bud.superposition_residual < 1e-15);
        assert!((bud.entries[1].share_horizontal - 0.8).abs() < 1e-12);
        assert_eq!(bud.largest, Source::AccelRw);
        assert!((bud.gyro_share - 0.2).abs() < 1e-12);
        assert!((bud.total_rms_horizontal_m - 5f64.sqrt()).abs() < 1e-12);
    }
}
