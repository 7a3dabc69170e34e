//! The slope/minimum method (datasheet-style reading of an ADEV curve), for comparison with
//! the fit.
use super::*;

/// Result of the slope/minimum method (datasheet-style reading of the ADEV curve).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SlopeResult {
    /// N = sigma(1 s) on the -1/2 line through the point whose local slope is closest to -1/2
    /// (U sqrt(s)); `S_N = N^2`.
    pub n: f64,
    /// tau of that point (s).
    pub n_tau_s: f64,
    /// B = sigma_min / 0.664 (U).
    pub b: f64,
    /// tau of the minimum (s).
    pub b_tau_s: f64,
    /// K = sigma(3 s) on the +1/2 line through the point whose slope is closest to +1/2
    /// (U / sqrt(s)), NaN if no rising part.
    pub k: f64,
    /// tau of that point (s).
    pub k_tau_s: f64,
}

/// The slope/minimum method on an ADEV curve.
pub fn slope_method(points: &[DevPoint]) -> Option<SlopeResult> {
    let p: Vec<&DevPoint> = points.iter().filter(|p| p.dev > 0.0).collect();
    if p.len() < 3 {
        return None;
    }
    let (imin, pmin) = p
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.dev.total_cmp(&b.1.dev))?;
    // Local log-log slope at interior points (central difference).
    let slope = |i: usize| {
        let a = p[i.saturating_sub(1)];
        let b = p[(i + 1).min(p.len() - 1)];
        (b.dev.ln() - a.dev.ln()) / (b.tau_s.ln() - a.tau_s.ln())
    };
    let pick = |range: std::ops::Range<usize>, target: f64| {
        range
            .map(|i| (i, (slope(i) - target).abs()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    };
    let in_ = pick(0..imin.max(1), -0.5)?;
    let n = p[in_].dev * p[in_].tau_s.sqrt();
    let (k, k_tau) = match pick(imin + 1..p.len(), 0.5) {
        Some(ik) => (p[ik].dev * (3.0 / p[ik].tau_s).sqrt(), p[ik].tau_s),
        None => (f64::NAN, f64::NAN),
    };
    Some(SlopeResult {
        n,
        n_tau_s: p[in_].tau_s,
        b: pmin.dev / units::FLICKER_FLOOR_ADEV,
        b_tau_s: pmin.tau_s,
        k,
        k_tau_s: k_tau,
    })
}
