//! Rauch-Tung-Striebel fixed-interval smoothing of a closed-loop error-state filter run
//! (`host-sim run --smooth`).
//!
//! The forward filter ([`nav_core::filter::Filter`]) feeds every error estimate back into its
//! nominal state and resets the error state to zero. The smoother therefore works on the error
//! relative to the stored forward nominal trajectory. Derivation, storage and numerics:
//! `docs/derivations/rts_smoother.md` (sections 1-2: equations (3) and (4) below; section 3:
//! what is stored and the interpolation between nodes; section 4: the solve).
//!
//! * **Forward** ([`Recorder`], a [`CovObserver`]): at every covariance prediction the filter
//!   hands over Phi, the covariance before (the posterior at the interval start) and after
//!   (the prior at its end), and the correction fed back at the interval start. One
//!   [`Node`] per prediction epoch, f64, in a [`History`]: P prior (packed upper triangle),
//!   P posterior only where an update changed it, the correction only where non-zero, Phi as
//!   its dense 9 core rows plus the diagonal below (the filter's [`Transition`] structure).
//! * **Backward** ([`smooth`]): with `dx_s+(k)` the smoothed error relative to the stored
//!   (post-feedback) nominal at node k and `c(k)` the correction fed back there,
//!   `dx_s-(k+1) = dx_s+(k+1) + c(k+1)` (relative to the pre-feedback nominal that the
//!   prediction from k reaches), `A_k = P+(k) Phi_k^T P-(k+1)^-1`,
//!   `dx_s+(k) = A_k dx_s-(k+1)` (the filtered error after feedback is zero, so is its
//!   prediction) and `P_s(k) = P+(k) + A_k (P_s(k+1) - P-(k+1)) A_k^T`.
//! * **Between nodes** ([`Smoothed::at`]): the nav records at IMU rate between two nodes get
//!   the error interpolated linearly in time between `dx_s+(k)` and `dx_s-(k+1)` (and the
//!   covariance between `P_s(k)` and `P_s(k+1)`); at a node the record (written after the
//!   updates there) gets `dx_s+(k)`. The smoothed state is the nominal corrected as the
//!   filter's own feedback does ([`apply::correct`]).
//!
//! Nothing here depends on N at compile time: the layout's dimension is a runtime value, so
//! every model, layout and effect block works.

pub mod apply;

use nalgebra::{DMatrix, DVector};
use nav_core::filter::observe::{CovObserver, PredictionRecord};
use nav_core::model::discrete::{Cov, Transition};
use nav_core::model::CORE_DIM;
use nav_core::scalar::Scalar;

/// Largest difference between a prediction's start and the previous prediction's end for the
/// two to be linked, s.
pub const LINK_TOL_S: f64 = 1e-6;

/// What the filter stored at one covariance-prediction epoch (all f64).
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Time, GPS seconds of week.
    pub t_s: f64,
    /// Prior covariance at `t_s` (before the updates there), packed upper triangle, row-major
    /// (`n (n + 1) / 2` values; for the first node of a segment the posterior).
    pub p_prior: Vec<f64>,
    /// Posterior covariance after the updates at `t_s`, packed; `None`: equal to the prior.
    pub p_post: Option<Vec<f64>>,
    /// Error-state correction fed back at `t_s` (estimate minus truth); `None`: zero.
    pub correction: Option<Vec<f64>>,
    /// Transition to the next node: the 9 core rows (`9 n`) then the diagonal of the rows
    /// below (`n - 9`); `None`: the last node of a segment.
    pub phi: Option<Vec<f64>>,
}

impl Node {
    /// The posterior covariance (packed).
    pub fn post(&self) -> &[f64] {
        self.p_post.as_deref().unwrap_or(&self.p_prior)
    }

    /// Bytes of this node (struct and heap).
    pub fn bytes(&self) -> usize {
        let v = |x: &Option<Vec<f64>>| x.as_ref().map_or(0, |v| v.capacity() * 8);
        std::mem::size_of::<Self>()
            + self.p_prior.capacity() * 8
            + v(&self.p_post)
            + v(&self.correction)
            + v(&self.phi)
    }
}

/// The forward pass's record for the smoother.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct History {
    /// Error-state dimension of the layout.
    pub n: usize,
    /// One node per covariance-prediction epoch, in time order.
    pub nodes: Vec<Node>,
    /// Covariance predictions the filter made that the recorder did not see (a prediction
    /// through a call without the observer): the smoother refuses such a history.
    pub unobserved_predictions: u64,
}

impl History {
    /// Memory of the history, bytes (nodes and their heap data).
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.nodes.iter().map(Node::bytes).sum::<usize>()
            + (self.nodes.capacity() - self.nodes.len()) * std::mem::size_of::<Node>()
    }

    /// Nodes with an update (a posterior different from the prior, or a correction).
    pub fn update_nodes(&self) -> usize {
        self.nodes
            .iter()
            .filter(|n| n.p_post.is_some() || n.correction.is_some())
            .count()
    }
}

/// Index of (i, j), i <= j, in a packed upper triangle of dimension n.
fn packed_index(n: usize, i: usize, j: usize) -> usize {
    let (i, j) = if i <= j { (i, j) } else { (j, i) };
    i * (2 * n - i + 1) / 2 + (j - i)
}

fn pack<T: Scalar, const N: usize>(p: &Cov<T, N>) -> Vec<f64> {
    let mut v = Vec::with_capacity(N * (N + 1) / 2);
    for (i, row) in p.iter().enumerate() {
        v.extend(row.iter().skip(i).map(|x| x.to_f64()));
    }
    v
}

fn unpack(n: usize, p: &[f64]) -> DMatrix<f64> {
    DMatrix::from_fn(n, n, |i, j| {
        p.get(packed_index(n, i, j)).copied().unwrap_or(0.0)
    })
}

fn pack_phi<T: Scalar, const N: usize>(phi: &Transition<T, N>) -> Vec<f64> {
    let mut v = Vec::with_capacity(CORE_DIM * N + N.saturating_sub(CORE_DIM));
    for row in &phi.top {
        v.extend(row.iter().map(|x| x.to_f64()));
    }
    v.extend(phi.diag.iter().skip(CORE_DIM).map(|x| x.to_f64()));
    v
}

fn phi_dense(n: usize, phi: &[f64]) -> DMatrix<f64> {
    let top = CORE_DIM * n;
    DMatrix::from_fn(n, n, |i, j| {
        if i < CORE_DIM {
            phi.get(i * n + j).copied().unwrap_or(0.0)
        } else if i == j {
            phi.get(top + i - CORE_DIM).copied().unwrap_or(0.0)
        } else {
            0.0
        }
    })
}

/// Records a filter run for the smoother: give it to `Filter::propagate_observed` and
/// `Filter::predict_covariance_observed` (call the latter before every measurement update so
/// that the update's own prediction is seen), then [`Recorder::finish`].
#[derive(Debug, Clone, Default)]
pub struct Recorder {
    enabled: bool,
    hist: History,
    seen: u64,
}

impl Recorder {
    /// A recorder for a layout of `n` states.
    pub fn new(n: usize) -> Self {
        Self {
            enabled: true,
            hist: History {
                n,
                ..History::default()
            },
            seen: 0,
        }
    }

    /// A recorder that records nothing (a run without smoothing).
    pub fn disabled() -> Self {
        Self::default()
    }

    /// Whether it records.
    pub fn is_enabled(&self) -> bool {
        self.enabled
    }

    /// Closes the history with the filter's state at the end of the run: its covariance, the
    /// correction fed back since the last prediction, and its prediction count (to detect
    /// predictions the recorder did not see). `None` when disabled.
    pub fn finish<T: Scalar, const N: usize>(
        mut self,
        p: &Cov<T, N>,
        pending_correction: &[T; N],
        cov_predictions: u64,
    ) -> Option<History> {
        if !self.enabled {
            return None;
        }
        if let Some(last) = self.hist.nodes.last_mut() {
            let post = pack(p);
            if post != last.p_prior {
                last.p_post = Some(post);
            }
            last.correction = nonzero(pending_correction);
        }
        self.hist.unobserved_predictions = cov_predictions.saturating_sub(self.seen);
        self.hist.nodes.shrink_to_fit();
        Some(self.hist)
    }
}

fn nonzero<T: Scalar, const N: usize>(c: &[T; N]) -> Option<Vec<f64>> {
    c.iter()
        .any(|v| *v != T::ZERO)
        .then(|| c.iter().map(|v| v.to_f64()).collect())
}

impl<T: Scalar, const N: usize> CovObserver<T, N> for Recorder {
    fn predicted(&mut self, rec: &PredictionRecord<'_, T, N>) {
        if !self.enabled {
            return;
        }
        self.seen += 1;
        let before = pack(rec.p_before);
        let correction = nonzero(rec.correction);
        let linked = self
            .hist
            .nodes
            .last()
            .is_some_and(|l| (l.t_s - rec.t_start_s).abs() <= LINK_TOL_S);
        if !linked {
            self.hist.nodes.push(Node {
                t_s: rec.t_start_s,
                p_prior: before,
                p_post: None,
                correction,
                phi: None,
            });
        } else if let Some(last) = self.hist.nodes.last_mut() {
            if before != last.p_prior {
                last.p_post = Some(before);
            }
            last.correction = correction;
        }
        if let Some(last) = self.hist.nodes.last_mut() {
            last.phi = Some(pack_phi(rec.phi));
        }
        self.hist.nodes.push(Node {
            t_s: rec.t_end_s,
            p_prior: pack(rec.p_after),
            p_post: None,
            correction: None,
            phi: None,
        });
    }
}

/// Errors of the backward pass.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SmoothError {
    /// Nothing was recorded.
    #[error("smoother: the history is empty (no covariance prediction was recorded)")]
    Empty,
    /// The filter predicted the covariance without the recorder.
    #[error(
        "smoother: {0} covariance prediction(s) were not recorded (a measurement update was \
         called without Filter::predict_covariance_observed before it)"
    )]
    Unobserved(u64),
    /// A stored matrix has the wrong size.
    #[error("smoother: node {0} has data of the wrong size")]
    Size(usize),
    /// The backward pass produced NaN/Inf.
    #[error("smoother: non-finite smoothed state at node {0} (t = {1:.3} s)")]
    NonFinite(usize, f64),
}

/// The smoothed errors and covariances at the nodes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Smoothed {
    /// Error-state dimension.
    pub n: usize,
    /// Node times, GPS seconds of week.
    pub t_s: Vec<f64>,
    /// Smoothed error relative to the stored (post-feedback) nominal, `n` per node, state
    /// units (estimate minus truth: subtract it as the filter's feedback does).
    pub dx_post: Vec<f64>,
    /// Smoothed error relative to the pre-feedback nominal (`dx_post + correction`).
    pub dx_prior: Vec<f64>,
    /// Smoothed covariance of the 9 core states, 81 per node (row-major).
    pub cov_core: Vec<f64>,
    /// Smoothed variance of every state, `n` per node.
    pub var: Vec<f64>,
    /// Whether node k is linked to node k + 1 (same segment).
    pub linked: Vec<bool>,
    /// Solves of `P-(k+1)` that fell back to the pseudo-inverse (not positive definite).
    pub pinv_fallbacks: usize,
}

/// The smoothed error and covariance at one time.
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothedPoint {
    /// Smoothed error relative to the stored nominal at that time (`n`).
    pub dx: Vec<f64>,
    /// Covariance of the 9 core states (row-major).
    pub cov_core: [f64; 81],
    /// Variance of every state (`n`).
    pub var: Vec<f64>,
}

impl Smoothed {
    /// Memory of the result, bytes.
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + 8 * (self.t_s.capacity()
                + self.dx_post.capacity()
                + self.dx_prior.capacity()
                + self.cov_core.capacity()
                + self.var.capacity())
            + self.linked.capacity()
    }

    fn slice(v: &[f64], k: usize, len: usize) -> &[f64] {
        v.get(k * len..(k + 1) * len).unwrap_or(&[])
    }

    /// The smoothed error and covariance at `t_s` for a record of the stored forward nominal
    /// at that time (see the module notes); `None` before the first node.
    pub fn at(&self, t_s: f64) -> Option<SmoothedPoint> {
        let n = self.n;
        let k = self
            .t_s
            .partition_point(|t| *t <= t_s + 1e-9)
            .checked_sub(1)?;
        let tk = *self.t_s.get(k)?;
        let point = |dx: Vec<f64>, cov: &[f64], var: &[f64]| {
            let mut c = [0.0; 81];
            for (d, s) in c.iter_mut().zip(cov) {
                *d = *s;
            }
            SmoothedPoint {
                dx,
                cov_core: c,
                var: var.to_vec(),
            }
        };
        let here = || {
            point(
                Self::slice(&self.dx_post, k, n).to_vec(),
                Self::slice(&self.cov_core, k, 81),
                Self::slice(&self.var, k, n),
            )
        };
        let linked = self.linked.get(k).copied().unwrap_or(false);
        let next_t = self.t_s.get(k + 1).copied();
        match next_t {
            Some(t1) if linked && (t_s - tk).abs() > 1e-9 && t1 > tk => {
                let f = ((t_s - tk) / (t1 - tk)).clamp(0.0, 1.0);
                let lerp = |a: &[f64], b: &[f64]| -> Vec<f64> {
                    a.iter().zip(b).map(|(x, y)| x + f * (y - x)).collect()
                };
                let dx = lerp(
                    Self::slice(&self.dx_post, k, n),
                    Self::slice(&self.dx_prior, k + 1, n),
                );
                let cov = lerp(
                    Self::slice(&self.cov_core, k, 81),
                    Self::slice(&self.cov_core, k + 1, 81),
                );
                let var = lerp(
                    Self::slice(&self.var, k, n),
                    Self::slice(&self.var, k + 1, n),
                );
                Some(point(dx, &cov, &var))
            }
            _ => Some(here()),
        }
    }
}

/// `X = P^+ B` for a symmetric positive semi-definite P. States with zero variance (a block
/// configured with a zero sigma and no noise, e.g. the Gauss-Markov part of an NBK bias when
/// the configuration has only a random walk) are left out (their rows of X are zero, as the
/// pseudo-inverse gives); the rest is solved by Cholesky of the Jacobi-scaled matrix
/// (`D^-1/2 P D^-1/2`: the states' units differ by 10 orders of magnitude), or by its
/// pseudo-inverse when that fails (`fallback` counts those).
fn solve_spd(p: &DMatrix<f64>, b: &DMatrix<f64>, fallback: &mut usize) -> DMatrix<f64> {
    let active: Vec<usize> = (0..p.nrows())
        .filter(|&i| p[(i, i)] > 0.0 && p[(i, i)].is_finite())
        .collect();
    let m = active.len();
    let s: Vec<f64> = active.iter().map(|&i| 1.0 / p[(i, i)].sqrt()).collect();
    let ps = DMatrix::from_fn(m, m, |a, c| s[a] * p[(active[a], active[c])] * s[c]);
    let bs = DMatrix::from_fn(m, b.ncols(), |a, j| s[a] * b[(active[a], j)]);
    let y = match ps.clone().cholesky() {
        Some(c) => c.solve(&bs),
        None => {
            *fallback += 1;
            let pinv = ps
                .pseudo_inverse(1e-12)
                .unwrap_or_else(|_| DMatrix::zeros(m, m));
            pinv * bs
        }
    };
    let mut x = DMatrix::zeros(p.nrows(), b.ncols());
    for (a, &i) in active.iter().enumerate() {
        for j in 0..b.ncols() {
            x[(i, j)] = s[a] * y[(a, j)];
        }
    }
    x
}

/// The Rauch-Tung-Striebel backward pass over a recorded history (see the module notes).
pub fn smooth(h: &History) -> Result<Smoothed, SmoothError> {
    if h.unobserved_predictions > 0 {
        return Err(SmoothError::Unobserved(h.unobserved_predictions));
    }
    let n = h.n;
    let m = h.nodes.len();
    if m == 0 {
        return Err(SmoothError::Empty);
    }
    let np = n * (n + 1) / 2;
    for (k, node) in h.nodes.iter().enumerate() {
        let ok = node.p_prior.len() == np
            && node.p_post.as_ref().is_none_or(|p| p.len() == np)
            && node.correction.as_ref().is_none_or(|c| c.len() == n)
            && node
                .phi
                .as_ref()
                .is_none_or(|p| p.len() == CORE_DIM * n + n.saturating_sub(CORE_DIM));
        if !ok || n < CORE_DIM {
            return Err(SmoothError::Size(k));
        }
    }
    let mut out = Smoothed {
        n,
        t_s: h.nodes.iter().map(|x| x.t_s).collect(),
        dx_post: vec![0.0; m * n],
        dx_prior: vec![0.0; m * n],
        cov_core: vec![0.0; m * 81],
        var: vec![0.0; m * n],
        linked: h.nodes.iter().map(|x| x.phi.is_some()).collect(),
        pinv_fallbacks: 0,
    };
    let store = |k: usize, dxs: &DVector<f64>, ps: &DMatrix<f64>, out: &mut Smoothed| {
        let corr = h.nodes.get(k).and_then(|x| x.correction.as_ref());
        for i in 0..n {
            let c = corr.and_then(|c| c.get(i)).copied().unwrap_or(0.0);
            out.dx_post[k * n + i] = dxs[i];
            out.dx_prior[k * n + i] = dxs[i] + c;
            out.var[k * n + i] = ps[(i, i)];
        }
        for i in 0..CORE_DIM {
            for j in 0..CORE_DIM {
                out.cov_core[k * 81 + i * 9 + j] = ps[(i, j)];
            }
        }
    };
    let last = m - 1;
    let mut ps = unpack(n, h.nodes[last].post());
    let mut dxs = DVector::<f64>::zeros(n);
    store(last, &dxs, &ps, &mut out);
    let mut fallbacks = 0usize;
    for k in (0..last).rev() {
        let node = &h.nodes[k];
        let next = &h.nodes[k + 1];
        let pp = unpack(n, node.post());
        match &node.phi {
            None => {
                ps = pp;
                dxs = DVector::zeros(n);
            }
            Some(phi) => {
                let phi = phi_dense(n, phi);
                let pr = unpack(n, &next.p_prior);
                // A^T = P-(k+1)^-1 Phi P+(k)
                let at = solve_spd(&pr, &(&phi * &pp), &mut fallbacks);
                let a = at.transpose();
                let mut target = dxs.clone();
                if let Some(c) = &next.correction {
                    for (t, ci) in target.iter_mut().zip(c) {
                        *t += ci;
                    }
                }
                dxs = &a * target;
                let mut p_new = &pp + &a * (&ps - &pr) * &at;
                p_new = (&p_new + p_new.transpose()) * 0.5;
                ps = p_new;
            }
        }
        if !(dxs.iter().all(|v| v.is_finite()) && ps.iter().all(|v| v.is_finite())) {
            return Err(SmoothError::NonFinite(k, node.t_s));
        }
        store(k, &dxs, &ps, &mut out);
    }
    out.pinv_fallbacks = fallbacks;
    Ok(out)
}
