//! Fit of the source document's noise model to an Allan variance curve, and the simple
//! slope/minimum method for comparison.
//!
//! Model (corrected formula of `docs/DESIGN.md`, two-sided PSDs, IEEE 952):
//!
//! ```text
//! AVAR(tau) = 3 Q^2 / tau^2 + S_N / tau
//!           + (S_B T_B^2 / tau) [1 - (T_B / (2 tau)) (3 - 4 e^(-tau/T_B) + e^(-2 tau/T_B))]
//!           + S_K tau / 3  [+ (2 ln 2 / pi) B^2 for an optional flicker floor]
//! ```
//!
//! `Q^2` plays the role of the source's `S_A` (quantization; `Q = step / sqrt(12)` in
//! increment units, m/s or rad).
//!
//! Method: weighted least squares on the Allan variance with weights `EDF / (2 AVAR^2)` (the
//! variance of a chi-square AVAR estimate is `2 AVAR^2 / EDF`), where AVAR in the weight is the
//! current *model* value (iteratively reweighted, so points that happen to fall low are not
//! favoured). For a fixed `T_B` the model is linear and non-negative in `[Q^2, S_N, S_B, S_K,
//! B^2]`: solved exactly by non-negative least squares (all active sets enumerated, at most 32
//! small solves). `T_B` is found by a 1-D search: a log-spaced grid over the fitted tau range
//! followed by golden-section refinement in log T_B. No initial guess is needed.
//!
//! Uncertainties: the Gauss-Newton covariance `(J^T W J)^-1` of the free (non-zero) parameters
//! including `T_B`, at the solution (first-order, from the weighted LS; the AVAR estimates at
//! neighbouring octave taus are treated as independent). Datasheet coefficients and their
//! uncertainties follow by the delta method.
use super::DevPoint;
use crate::gauss_markov_avar;
use nalgebra::{DMatrix, DVector};
use nav_core::config::units;
use serde::{Deserialize, Serialize};

mod check;
mod select;
mod slope;
pub use check::{check_model, Alternative, Miss, ModelCheck, MIN_RUN, Z95};
pub use select::{fit_select, Candidate, Selection};
pub use slope::{slope_method, SlopeResult};

/// Which terms the model has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Terms {
    /// Quantization `3 Q^2 / tau^2`.
    pub quant: bool,
    /// White noise `S_N / tau`.
    pub white: bool,
    /// First-order Gauss-Markov `S_B`, `T_B`.
    pub gm: bool,
    /// Random walk `S_K tau / 3`.
    pub rw: bool,
    /// Flicker floor `(2 ln 2 / pi) B^2`.
    pub flicker: bool,
}

impl Terms {
    /// The source's accelerometer model: quantization + white + Gauss-Markov + random walk.
    pub const NBK_Q: Terms = Terms {
        quant: true,
        white: true,
        gm: true,
        rw: true,
        flicker: false,
    };
    /// The source's accelerometer model without quantization (white + GM + RW).
    pub const NBK: Terms = Terms {
        quant: false,
        white: true,
        gm: true,
        rw: true,
        flicker: false,
    };
}

/// Index of the linear coefficients.
const IQ: usize = 0;
const IN: usize = 1;
const IB: usize = 2;
const IK: usize = 3;
const IF: usize = 4;
const FLICKER_K: f64 = 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI;

/// A value with its 1-sigma uncertainty.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Est {
    /// Value.
    pub value: f64,
    /// 1-sigma uncertainty (NaN if unknown).
    pub sigma: f64,
}

/// Which physical sensor, for the datasheet units.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SensorKind {
    /// Accelerometer: rate unit m/s^2.
    Accel,
    /// Gyro: rate unit rad/s.
    Gyro,
    /// Unknown: datasheet units equal SI.
    Other,
}

/// Result of the weighted least-squares fit, SI units (rate unit `U`: m/s^2 or rad/s).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FitResult {
    /// Quantization `Q^2` (U^2 s^2, i.e. m^2/s^2 for accelerometers; the source's S_A).
    pub q2: Est,
    /// White-noise PSD S_N (U^2 s).
    pub s_n: Est,
    /// Gauss-Markov driving PSD S_B (U^2 / s).
    pub s_b: Est,
    /// Gauss-Markov correlation time T_B (s); NaN when S_B = 0.
    pub t_b_s: Est,
    /// Random-walk PSD S_K (U^2 / s).
    pub s_k: Est,
    /// Flicker coefficient squared B^2 (U^2), 0 unless the flicker term is fitted.
    pub flicker_b2: Est,
    /// Weighted sum of squared residuals (chi-square).
    pub chi2: f64,
    /// Number of points used.
    pub n_points: usize,
    /// Number of free parameters at the solution.
    pub n_free: usize,
    /// Correlation of the S_B and T_B estimates (for the uncertainty of B).
    pub corr_sb_tb: f64,
    /// Per fitted tau: (tau_s, measured AVAR, model AVAR, normalized residual
    /// (meas - model) / (model sqrt(2 / EDF + model_error_rel^2))).
    pub residuals: Vec<(f64, f64, f64, f64)>,
    /// The terms the model had.
    pub terms: Terms,
    /// The range (s) T_B was searched in.
    pub t_b_range_s: (f64, f64),
    /// Relative model-error floor that was added to the statistical scatter of each AVAR
    /// estimate (0: purely statistical weights; see [`FitOptions::model_error_rel`]).
    pub model_error_rel: f64,
}

/// Datasheet coefficients derived from a [`FitResult`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Datasheet {
    /// Unit of `n`.
    pub n_unit: String,
    /// White noise N = sqrt(S_N): ug/sqrt(Hz) (accel) or deg/sqrt(h) (gyro).
    pub n: Est,
    /// Unit of `b` and `b_flicker`.
    pub b_unit: String,
    /// Bias instability B = 0.6572 sqrt(S_B T_B) (flicker floor matched to the Gauss-Markov
    /// peak): ug (accel) or deg/h (gyro).
    pub b: Est,
    /// Unit of `k`.
    pub k_unit: String,
    /// Random walk K = sqrt(S_K): ug/sqrt(h) (accel) or deg/h/sqrt(h) (gyro).
    pub k: Est,
    /// K in SI (U / sqrt(s)): m/s^2.5 for accelerometers.
    pub k_si: Est,
    /// Quantization Q in increment units (m/s or rad).
    pub q: Est,
    /// Bias instability of the flicker-floor term, B = sqrt(B^2) (AVAR floor (2 ln 2 / pi)
    /// B^2): ug (accel) or deg/h (gyro); 0 without a flicker term.
    pub b_flicker: Est,
}

impl FitResult {
    /// Model Allan variance at `tau_s`.
    pub fn avar(&self, tau_s: f64) -> f64 {
        let c = self.components(tau_s);
        c.iter().sum()
    }
    /// Model components at `tau_s`: [quantization, white, Gauss-Markov, random walk, flicker].
    pub fn components(&self, tau_s: f64) -> [f64; 5] {
        let gm = if self.s_b.value > 0.0 && self.t_b_s.value.is_finite() {
            gauss_markov_avar(self.s_b.value, self.t_b_s.value, tau_s)
        } else {
            0.0
        };
        [
            3.0 * self.q2.value / (tau_s * tau_s),
            self.s_n.value / tau_s,
            gm,
            self.s_k.value * tau_s / 3.0,
            FLICKER_K * self.flicker_b2.value,
        ]
    }

    /// Datasheet coefficients (with delta-method uncertainties).
    pub fn datasheet(&self, kind: SensorKind) -> Datasheet {
        let sqrt_est = |e: Est| {
            let v = e.value.max(0.0).sqrt();
            Est {
                value: v,
                sigma: if v > 0.0 {
                    e.sigma / (2.0 * v)
                } else {
                    e.sigma.sqrt()
                },
            }
        };
        let scale = |e: Est, f: f64| Est {
            value: e.value * f,
            sigma: e.sigma * f,
        };
        let n = sqrt_est(self.s_n);
        let k = sqrt_est(self.s_k);
        let ratio = units::GM_PEAK_ADEV / units::FLICKER_FLOOR_ADEV;
        // B = ratio sqrt(S_B T_B); its sigma uses the S_B-T_B correlation of the fit.
        let sbt = self.s_b.value * self.t_b_s.value;
        let b_val = if sbt > 0.0 { ratio * sbt.sqrt() } else { 0.0 };
        let b_sig = b_val * self.b_rel_sigma();
        let b = Est {
            value: b_val,
            sigma: b_sig,
        };
        let q = sqrt_est(self.q2);
        let bf = sqrt_est(self.flicker_b2);
        match kind {
            SensorKind::Accel => Datasheet {
                n_unit: "ug/sqrt(Hz)".into(),
                n: scale(n, 1.0 / units::UG_MPS2),
                b_unit: "ug".into(),
                b: scale(b, 1.0 / units::UG_MPS2),
                k_unit: "ug/sqrt(h)".into(),
                k: scale(k, units::SQRT_HOUR_S / units::UG_MPS2),
                k_si: k,
                q,
                b_flicker: scale(bf, 1.0 / units::UG_MPS2),
            },
            SensorKind::Gyro => Datasheet {
                n_unit: "deg/sqrt(h)".into(),
                n: scale(n, units::SQRT_HOUR_S / units::DEG),
                b_unit: "deg/h".into(),
                b: scale(b, units::HOUR_S / units::DEG),
                k_unit: "deg/h/sqrt(h)".into(),
                k: scale(k, units::HOUR_S * units::SQRT_HOUR_S / units::DEG),
                k_si: k,
                q,
                b_flicker: scale(bf, units::HOUR_S / units::DEG),
            },
            SensorKind::Other => Datasheet {
                n_unit: "U*sqrt(s)".into(),
                n,
                b_unit: "U".into(),
                b,
                k_unit: "U/sqrt(s)".into(),
                k,
                k_si: k,
                q,
                b_flicker: bf,
            },
        }
    }

    /// The first local minimum of the model's Allan deviation over the fitted tau range,
    /// scanning from the shortest tau: `(tau_s, adev)` in rate units. This is the floor a
    /// datasheet quotes as "in-run bias stability" (the flicker floor 0.664 B for white +
    /// flicker; the dip before the Gauss-Markov bump when there is one; the bottom of the
    /// white/random-walk bowl). Log grid of 400 points.
    pub fn model_adev_minimum(&self) -> (f64, f64) {
        let t0 = self.residuals.first().map_or(1.0, |r| r.0);
        let t1 = self.residuals.last().map_or(1.0, |r| r.0);
        let grid: Vec<(f64, f64)> = (0..400)
            .map(|i| {
                let t = (t0.ln() + (t1.ln() - t0.ln()) * i as f64 / 399.0).exp();
                (t, self.avar(t).max(0.0).sqrt())
            })
            .collect();
        grid.windows(2)
            .find(|w| w[1].1 > w[0].1)
            .map(|w| w[0])
            .or_else(|| grid.last().copied())
            .unwrap_or((f64::NAN, f64::NAN))
    }

    /// Relative 1-sigma of sqrt(S_B T_B) (uses the S_B-T_B correlation stored by the fit).
    pub fn b_rel_sigma(&self) -> f64 {
        if self.s_b.value.is_nan() || self.s_b.value <= 0.0 {
            return f64::NAN;
        }
        let rb = self.s_b.sigma / self.s_b.value;
        let rt = self.t_b_s.sigma / self.t_b_s.value;
        let var = 0.25 * (rb * rb + rt * rt + 2.0 * self.corr_sb_tb * rb * rt);
        var.max(0.0).sqrt()
    }
}

/// Options of the fit.
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Model terms.
    pub terms: Terms,
    /// Number of IRLS iterations (weights from the model).
    pub irls_iterations: usize,
    /// Only points with tau in this range (s) are used.
    pub tau_range_s: (f64, f64),
    /// Only points with at least this EDF are used.
    pub min_edf: f64,
    /// Weighting of the Allan variance estimates.
    pub weighting: Weighting,
    /// Relative model error `eps`: each AVAR estimate is given the variance
    /// `AVAR^2 (2 / EDF + eps^2)` instead of the statistical `2 AVAR^2 / EDF`. 0 for simulated
    /// data that follow the model; [`fit_select`] estimates it for real data, where the
    /// model's few power laws cannot follow every feature of a real sensor's curve to the
    /// 0.1 % precision of the short-tau estimates (internal filters, vibration lines, drifts).
    pub model_error_rel: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            terms: Terms::NBK_Q,
            irls_iterations: 4,
            tau_range_s: (0.0, f64::INFINITY),
            min_edf: 3.0,
            weighting: Weighting::EdfSandwich,
            model_error_rel: 0.0,
        }
    }
}

/// Errors of the fit.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// Too few usable points.
    #[error("allan fit: {0} usable points (tau in range, EDF >= min, AVAR > 0); need >= 3")]
    TooFewPoints(usize),
}

struct Pt {
    tau: f64,
    avar: f64,
    edf: f64,
    m: usize,
    n_terms: usize,
}

/// How the Allan variance estimates are weighted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Weighting {
    /// Diagonal weights `EDF / (2 AVAR_model^2)`; uncertainties `(J^T W J)^-1` as if the
    /// estimates at different taus were independent.
    Edf,
    /// Diagonal EDF weights for the estimate (as `Edf`), uncertainties from the sandwich
    /// `(J^T W J)^-1 J^T W V W J (J^T W J)^-1` with `V` the full model covariance of the
    /// overlapping AVAR estimates ([`oavar_covariance`]), which accounts for the strong
    /// correlation of neighbouring octave estimates (0.5 - 0.85). The default.
    EdfSandwich,
    /// Generalized least squares with the full covariance matrix of the overlapping AVAR
    /// estimates predicted by the current model ([`oavar_covariance`]); the first iteration
    /// uses the EDF weights. Needs OADEV points (`m`, `n_terms`).
    Gls,
}

/// Generalized covariance `K(t)` of the integrated rate ("phase" `x(t) = int y`) of the model:
/// `Cov(sum w_p x(t_p), sum v_q x(s_q)) = sum w_p v_q K(t_p - s_q)` for weights that cancel
/// constants and lines (second differences). White: `-S_N |t| / 2`; random walk:
/// `S_K |t|^3 / 12`; Gauss-Markov: `-sigma^2 T^2 (|t|/T - 1 + e^(-|t|/T))` with `sigma^2 =
/// S_B T / 2`; quantization: `Q^2` at `t = 0`; flicker: `(B^2 / 2 pi) t^2 ln|t|`. Each gives
/// its Allan variance term through `(6K(0) - 8K(tau) + 2K(2tau)) / (2 tau^2)`.
fn gen_cov(c: &[f64; 5], t_b: f64, t: f64) -> f64 {
    let a = t.abs();
    let mut k = -0.5 * c[IN] * a + c[IK] * a * a * a / 12.0;
    if c[IB] > 0.0 && t_b > 0.0 {
        let sig2 = 0.5 * c[IB] * t_b;
        let r = a / t_b;
        // r - 1 + e^-r, with a series for small r (cancellation).
        let g = if r < 1e-4 {
            r * r / 2.0 - r * r * r / 6.0
        } else {
            r - 1.0 + (-r).exp()
        };
        k -= sig2 * t_b * t_b * g;
    }
    if a == 0.0 {
        k += c[IQ];
    } else if c[IF] > 0.0 {
        k += c[IF] / (2.0 * std::f64::consts::PI) * a * a * a.ln();
    }
    k
}

/// Covariance matrix of overlapping Allan variance estimates at averaging factors `m_i` with
/// `n_i` terms each (sample time `dt_s`), for Gaussian noise with the model `c` (linear
/// coefficients `[Q^2, S_N, S_B, S_K, B^2]`) and `T_B`:
/// `Cov(A_a, A_b) = 2 sum_k C_ab(k)^2 #(k) / (4 m_a^2 m_b^2 n_a n_b dt^4)` with `C_ab(k)` the
/// covariance of the second differences `d_a(i)` and `d_b(i + k)` (from `gen_cov`) and `#(k)`
/// the number of term pairs at lag k. The lag sum is exact for short supports and sampled
/// (step h, weight h) when the support exceeds 4096 lags. Its diagonal is the exact variance of
/// each estimate (what the EDF approximates).
pub fn oavar_covariance(ms: &[(usize, usize)], dt_s: f64, c: &[f64; 5], t_b: f64) -> DMatrix<f64> {
    let n = ms.len();
    let mut v = DMatrix::zeros(n, n);
    for a in 0..n {
        for b in a..n {
            let (ma, na) = ms[a];
            let (mb, nb) = ms[b];
            let wa = [(1.0, 0i64), (-2.0, ma as i64), (1.0, 2 * ma as i64)];
            let wb = [(1.0, 0i64), (-2.0, mb as i64), (1.0, 2 * mb as i64)];
            let cab = |k: i64| {
                let mut s = 0.0;
                for (wp, op) in wa {
                    for (wq, oq) in wb {
                        s += wp * wq * gen_cov(c, t_b, (k + oq - op) as f64 * dt_s);
                    }
                }
                s
            };
            let mut ext = 0i64;
            if c[IB] > 0.0 && t_b.is_finite() {
                ext += (12.0 * t_b / dt_s).ceil() as i64;
            }
            if c[IF] > 0.0 {
                ext += 2 * (ma + mb) as i64;
            }
            let pairs = |k: i64| {
                let i0 = 0i64.max(-k);
                let i1 = (na as i64).min(nb as i64 - k);
                (i1 - i0).max(0) as f64
            };
            // Sum of C(k)^2 #(k) over [lo, hi] with at most ~4096 samples (step h, weight h).
            let range_sum = |lo: i64, hi: i64, max_pts: f64| {
                if hi < lo {
                    return 0.0;
                }
                let span = (hi - lo + 1) as f64;
                let step = ((span / max_pts).ceil() as i64).max(1);
                let mut sum = 0.0;
                let mut k = lo;
                while k <= hi {
                    let ck = cab(k);
                    sum += ck * ck * pairs(k) * step as f64;
                    k += step;
                }
                sum
            };
            // Core support of the difference filters (where white / random walk /
            // quantization live), then the tails where only the smooth Gauss-Markov and
            // flicker parts remain.
            let (lo_c, hi_c) = (-(2 * mb as i64), 2 * ma as i64);
            let sum = range_sum(lo_c, hi_c, 2048.0)
                + range_sum(lo_c - ext, lo_c - 1, 512.0)
                + range_sum(hi_c + 1, hi_c + ext, 512.0);
            let den = 4.0
                * (ma as f64).powi(2)
                * (mb as f64).powi(2)
                * na as f64
                * nb as f64
                * dt_s.powi(4);
            let val = 2.0 * sum / den;
            v[(a, b)] = val;
            v[(b, a)] = val;
        }
    }
    v
}

fn basis(terms: &Terms, tau: f64, t_b: f64) -> [f64; 5] {
    [
        if terms.quant { 3.0 / (tau * tau) } else { 0.0 },
        if terms.white { 1.0 / tau } else { 0.0 },
        if terms.gm {
            gauss_markov_avar(1.0, t_b, tau)
        } else {
            0.0
        },
        if terms.rw { tau / 3.0 } else { 0.0 },
        if terms.flicker { FLICKER_K } else { 0.0 },
    ]
}

/// Exact NNLS of `min || A c - b ||^2, c >= 0` for <= 5 columns by enumerating active sets.
/// Columns that are all zero stay 0. Returns (c, cost).
fn nnls_small(a: &DMatrix<f64>, b: &DVector<f64>) -> ([f64; 5], f64) {
    let ncol = a.ncols();
    let norms: Vec<f64> = (0..ncol).map(|j| a.column(j).norm()).collect();
    let usable: Vec<usize> = (0..ncol).filter(|&j| norms[j] > 0.0).collect();
    let mut best = ([0.0; 5], b.norm_squared());
    for mask in 1u32..(1 << usable.len()) {
        let cols: Vec<usize> = usable
            .iter()
            .enumerate()
            .filter(|(i, _)| mask & (1 << i) != 0)
            .map(|(_, &j)| j)
            .collect();
        let sub = DMatrix::from_fn(a.nrows(), cols.len(), |r, c| {
            a[(r, cols[c])] / norms[cols[c]]
        });
        let svd = sub.clone().svd(true, true);
        let Ok(sol) = svd.solve(b, 1e-13) else {
            continue;
        };
        if sol.iter().any(|&v| v < 0.0) {
            continue;
        }
        let cost = (&sub * &sol - b).norm_squared();
        if cost < best.1 {
            let mut c = [0.0; 5];
            for (k, &j) in cols.iter().enumerate() {
                c[j] = sol[k] / norms[j];
            }
            best = (c, cost);
        }
    }
    best
}

/// Solves the linear NNLS for a fixed T_B with weights from `wmodel` (model AVAR per point).
fn solve_fixed_tb(pts: &[Pt], terms: &Terms, t_b: f64, w: &DMatrix<f64>) -> ([f64; 5], f64) {
    let n = pts.len();
    let mut a = DMatrix::zeros(n, 5);
    let mut b = DVector::zeros(n);
    for (i, p) in pts.iter().enumerate() {
        let row = basis(terms, p.tau, t_b);
        for j in 0..5 {
            a[(i, j)] = row[j];
        }
        b[i] = p.avar;
    }
    nnls_small(&(w * a), &(w * b))
}

/// Whitening matrix for diagonal EDF weights with model values `wmodel` and the relative
/// model error `eps`.
fn diag_whitening(pts: &[Pt], wmodel: &[f64], eps: f64) -> DMatrix<f64> {
    DMatrix::from_fn(pts.len(), pts.len(), |i, j| {
        if i == j {
            1.0 / (wmodel[i] * (2.0 / pts[i].edf + eps * eps).sqrt())
        } else {
            0.0
        }
    })
}

/// Adds the model-error floor `(eps m_i)^2` to the diagonal of a covariance of the estimates.
fn add_model_error(mut v: DMatrix<f64>, wmodel: &[f64], eps: f64) -> DMatrix<f64> {
    for (i, m) in wmodel.iter().enumerate() {
        v[(i, i)] += (eps * m).powi(2);
    }
    v
}

/// Whitening matrix `L^-1` for the covariance `V = L L^T`; `None` if V is not positive
/// definite.
fn full_whitening(v: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    // Scale to unit diagonal for conditioning.
    let d: Vec<f64> = (0..v.nrows()).map(|i| v[(i, i)].sqrt()).collect();
    if d.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
        return None;
    }
    let r = DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[(i, j)] / (d[i] * d[j]));
    let ch = r.cholesky()?;
    let linv = ch.l().try_inverse()?;
    Some(DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| {
        linv[(i, j)] / d[j]
    }))
}

fn model_at(c: &[f64; 5], terms: &Terms, tau: f64, t_b: f64) -> f64 {
    basis(terms, tau, t_b)
        .iter()
        .zip(c.iter())
        .map(|(x, y)| x * y)
        .sum()
}

/// The T_B search range (s): within the fitted tau range, because a Gauss-Markov process with
/// T_B well below the smallest tau is indistinguishable from white noise (AVAR -> S_B T_B^2 /
/// tau), and one with T_B far above the largest tau from a random walk (AVAR -> S_B tau / 3).
/// It is also kept below a tenth of the record length: over the record, a slower Gauss-Markov
/// process is a random walk plus a constant, and letting it absorb the random walk biases S_K
/// low.
fn tb_range(pts: &[Pt]) -> (f64, f64) {
    let tmin = pts.iter().map(|p| p.tau).fold(f64::INFINITY, f64::min);
    let record_s = pts
        .iter()
        .map(|p| (p.n_terms + 2 * p.m) as f64 * p.tau / p.m.max(1) as f64)
        .fold(0.0, f64::max);
    let tmax = pts
        .iter()
        .map(|p| p.tau)
        .fold(0.0, f64::max)
        .min(record_s / 10.0)
        .max(tmin * 2.0);
    (tmin, tmax)
}

/// Best T_B (log grid + golden section) for the given weights; returns (t_b, c, cost).
fn search_tb(pts: &[Pt], terms: &Terms, wmodel: &DMatrix<f64>) -> (f64, [f64; 5], f64) {
    if !terms.gm {
        let (c, cost) = solve_fixed_tb(pts, terms, 1.0, wmodel);
        return (f64::NAN, c, cost);
    }
    let (tmin, tmax) = tb_range(pts);
    let (lmin, lmax) = (tmin.ln(), tmax.ln());
    let ngrid = 60;
    let eval = |lt: f64| {
        let (c, cost) = solve_fixed_tb(pts, terms, lt.exp(), wmodel);
        (cost, c)
    };
    let mut best = (f64::INFINITY, 0usize);
    let grid: Vec<f64> = (0..ngrid)
        .map(|i| lmin + (lmax - lmin) * i as f64 / (ngrid - 1) as f64)
        .collect();
    let costs: Vec<f64> = grid.iter().map(|&l| eval(l).0).collect();
    for (i, &c) in costs.iter().enumerate() {
        if c < best.0 {
            best = (c, i);
        }
    }
    let i = best.1;
    let mut lo = grid[i.saturating_sub(1)];
    let mut hi = grid[(i + 1).min(ngrid - 1)];
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = hi - g * (hi - lo);
    let mut x2 = lo + g * (hi - lo);
    let mut f1 = eval(x1).0;
    let mut f2 = eval(x2).0;
    for _ in 0..60 {
        if f1 < f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = eval(x1).0;
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = eval(x2).0;
        }
        if hi - lo < 1e-7 {
            break;
        }
    }
    let lt = 0.5 * (lo + hi);
    let (cost, c) = eval(lt);
    if cost <= best.0 {
        (lt.exp(), c, cost)
    } else {
        let (c0, c) = eval(grid[i]);
        (grid[i].exp(), c, c0)
    }
}

/// Block means per tau below which the noise type identified at that tau is not trusted
/// for the fit's weights: the lag-1 autocorrelation of `n` block means has a standard error
/// of about `1 / sqrt(n)`, 0.03 at 1,000, enough to move the identified exponent by one.
pub const RELIABLE_ID_BLOCKS: usize = 1000;

/// The equivalent degrees of freedom the fit and its checks give an OADEV point: the
/// curve's EDF (for the noise type identified at that tau), but where fewer than
/// [`RELIABLE_ID_BLOCKS`] block means identified it (or it was carried over from a shorter
/// tau, below 30 block means), the smaller of that and the EDF of the next lower noise
/// exponent. A chance white- or flicker-phase identification at a long tau otherwise gives
/// EDFs tens of times too large there (one Gauss-Markov record of 30 min: 711 instead of
/// 66 at tau 41 s), which makes a correct model look like it misses the curve and inflates
/// the model-error floor of every candidate.
pub fn fit_edf(p: &DevPoint) -> f64 {
    let n_phase = p.n_terms + 2 * p.m;
    let blocks = n_phase.saturating_sub(1) / p.m.max(1);
    if blocks >= RELIABLE_ID_BLOCKS || !p.edf.is_finite() {
        return p.edf;
    }
    let lower = crate::edf::edf_for(crate::Deviation::Oadev, p.alpha - 1, p.m, n_phase);
    if lower.is_finite() {
        p.edf.min(lower)
    } else {
        p.edf
    }
}

/// Fits the model to a deviation curve (normally OADEV with EDF from [`super::deviation_curve`]).
pub fn fit(points: &[DevPoint], opt: &FitOptions) -> Result<FitResult, FitError> {
    let pts: Vec<Pt> = points
        .iter()
        .filter(|p| {
            p.tau_s >= opt.tau_range_s.0
                && p.tau_s <= opt.tau_range_s.1
                && fit_edf(p).is_finite()
                && fit_edf(p) >= opt.min_edf
                && p.dev > 0.0
        })
        .map(|p| Pt {
            tau: p.tau_s,
            avar: p.dev * p.dev,
            edf: fit_edf(p),
            m: p.m,
            n_terms: p.n_terms,
        })
        .collect();
    if pts.len() < 3 {
        return Err(FitError::TooFewPoints(pts.len()));
    }
    let terms = opt.terms;
    let eps = opt.model_error_rel;
    let dt = pts[0].tau / pts[0].m.max(1) as f64;
    let ms: Vec<(usize, usize)> = pts.iter().map(|p| (p.m, p.n_terms)).collect();
    let (sol, wmodel, w) = reweighted_solution(&pts, opt, dt, &ms);
    let (t_b, c, chi2) = sol;

    // Covariance of the free parameters by Gauss-Newton at the solution.
    // Parameters: the non-zero linear coefficients, and log T_B when S_B > 0.
    let free: Vec<usize> = (0..5).filter(|&j| c[j] > 0.0).collect();
    let has_tb = terms.gm && c[IB] > 0.0 && t_b.is_finite();
    let np = free.len() + usize::from(has_tb);
    let mut jac = DMatrix::zeros(pts.len(), np);
    for (i, p) in pts.iter().enumerate() {
        let row = basis(&terms, p.tau, t_b);
        for (k, &j) in free.iter().enumerate() {
            jac[(i, k)] = row[j];
        }
        if has_tb {
            let h = 1e-5;
            let up = gauss_markov_avar(c[IB], t_b * (1.0 + h), p.tau);
            let dn = gauss_markov_avar(c[IB], t_b * (1.0 - h), p.tau);
            // derivative with respect to T_B itself
            jac[(i, np - 1)] = (up - dn) / (2.0 * h * t_b);
        }
    }
    let jac0 = jac;
    let jac = &w * &jac0;
    let jtj = jac.transpose() * &jac;
    let bread = jtj
        .clone()
        .try_inverse()
        .unwrap_or_else(|| jtj.pseudo_inverse(1e-300).unwrap_or(DMatrix::zeros(np, np)));
    let cov = match opt.weighting {
        Weighting::EdfSandwich => {
            // Cov = B J0^T Om V Om J0 B, Om = W^T W, V the model covariance of the estimates.
            let v = add_model_error(oavar_covariance(&ms, dt, &c, t_b), &wmodel, eps);
            let om_j = w.transpose() * &jac;
            let meat = om_j.transpose() * v * om_j;
            &bread * meat * &bread
        }
        _ => bread,
    };
    let mut sig = [0.0f64; 5];
    for (k, &j) in free.iter().enumerate() {
        sig[j] = cov[(k, k)].max(0.0).sqrt();
    }
    let (tb_sig, corr) = if has_tb {
        let st = cov[(np - 1, np - 1)].max(0.0).sqrt();
        let kb = free.iter().position(|&j| j == IB);
        let corr = kb
            .map(|kb| cov[(kb, np - 1)] / (sig[IB] * st))
            .filter(|v| v.is_finite())
            .unwrap_or(0.0);
        (st, corr)
    } else {
        (f64::NAN, 0.0)
    };
    // Zero (bound) parameters: report the sigma they would have if free, as an upper scale.
    let est = |j: usize| Est {
        value: c[j],
        sigma: sig[j],
    };
    let residuals = pts
        .iter()
        .map(|p| {
            let m = model_at(&c, &terms, p.tau, t_b);
            (
                p.tau,
                p.avar,
                m,
                (p.avar - m) / (m * (2.0 / p.edf + eps * eps).sqrt()),
            )
        })
        .collect();
    Ok(FitResult {
        q2: est(IQ),
        s_n: est(IN),
        s_b: est(IB),
        t_b_s: Est {
            value: if has_tb { t_b } else { f64::NAN },
            sigma: tb_sig,
        },
        s_k: est(IK),
        flicker_b2: est(IF),
        chi2,
        n_points: pts.len(),
        n_free: np,
        residuals,
        corr_sb_tb: corr,
        terms,
        model_error_rel: eps,
        t_b_range_s: tb_range(&pts),
    })
}

/// A solution of the fit: (T_B in s, the five linear coefficients, chi2).
type TbSolution = (f64, [f64; 5], f64);

/// The weighted least-squares fit iterated `opt.irls_iterations` times, each time with the
/// weights of the previous solution's model (diagonal EDF weights, or the full covariance
/// of the overlapping estimates for [`Weighting::Gls`]): the solution `(T_B, coefficients,
/// chi2)`, the model values the last weights came from, and those whitening weights.
/// `dt` is the sample interval (s), `ms` each point's averaging factor and term count.
fn reweighted_solution(
    pts: &[Pt],
    opt: &FitOptions,
    dt: f64,
    ms: &[(usize, usize)],
) -> (TbSolution, Vec<f64>, DMatrix<f64>) {
    let terms = opt.terms;
    let mut wmodel: Vec<f64> = pts.iter().map(|p| p.avar).collect();
    let eps = opt.model_error_rel;
    let mut w = diag_whitening(pts, &wmodel, eps);
    let mut sol = search_tb(pts, &terms, &w);
    for _ in 0..opt.irls_iterations {
        let (t_b, c, _) = sol;
        let new: Vec<f64> = pts
            .iter()
            .zip(wmodel.iter())
            .map(|(p, &old)| {
                let m = model_at(&c, &terms, p.tau, t_b);
                if m > 0.0 {
                    m
                } else {
                    old
                }
            })
            .collect();
        wmodel = new;
        w = match opt.weighting {
            Weighting::Edf | Weighting::EdfSandwich => diag_whitening(pts, &wmodel, eps),
            Weighting::Gls => full_whitening(&add_model_error(
                oavar_covariance(ms, dt, &c, t_b),
                &wmodel,
                eps,
            ))
            .unwrap_or_else(|| diag_whitening(pts, &wmodel, eps)),
        };
        sol = search_tb(pts, &terms, &w);
    }
    (sol, wmodel, w)
}
