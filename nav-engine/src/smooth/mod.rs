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
//!   [`Node`] per prediction epoch, f64, written as the run goes to a temporary file (a
//!   [`History`], laid out as the derivation's section 3 says): P prior (packed upper
//!   triangle), P posterior only where an update changed it, the correction only where
//!   non-zero, Phi as its dense 9 core rows plus the diagonal below (the filter's
//!   [`Transition`] structure). The recorder holds one node.
//! * **Backward** ([`smooth`]): with `dx_s+(k)` the smoothed error relative to the stored
//!   (post-feedback) nominal at node k and `c(k)` the correction fed back there,
//!   `dx_s-(k+1) = dx_s+(k+1) + c(k+1)` (relative to the pre-feedback nominal that the
//!   prediction from k reaches), `A_k = P+(k) Phi_k^T P-(k+1)^-1`,
//!   `dx_s+(k) = A_k dx_s-(k+1)` (the filtered error after feedback is zero, so is its
//!   prediction) and `P_s(k) = P+(k) + A_k (P_s(k+1) - P-(k+1)) A_k^T`.
//! * **Between nodes** ([`SmoothedCursor::at`]): the nav records at IMU rate between two nodes get
//!   the error interpolated linearly in time between `dx_s+(k)` and `dx_s-(k+1)` (and the
//!   covariance between `P_s(k)` and `P_s(k+1)`); at a node the record (written after the
//!   updates there) gets `dx_s+(k)`. The smoothed state is the nominal corrected as the
//!   filter's own feedback does ([`apply::correct`]).
//!
//! Nothing here depends on N at compile time: the layout's dimension is a runtime value, so
//! every model, layout and effect block works.

pub mod apply;
pub mod run;
mod store;

use nalgebra::{DMatrix, DVector};
use nav_core::filter::observe::{CovObserver, PredictionRecord};
use nav_core::model::discrete::{Cov, Transition};
use nav_core::model::CORE_DIM;
use nav_core::scalar::Scalar;
use std::fs::File;
use std::sync::Arc;
use store::{NodeWriter, RevNodes, SmoothedBlocks, SmoothedWriter};

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

/// The forward pass's record for the smoother: the nodes in a temporary file (removed when
/// the last clone of the history is dropped), read back from the end by [`smooth`].
#[derive(Debug, Clone, Default)]
pub struct History {
    /// Error-state dimension of the layout.
    pub n: usize,
    /// Covariance predictions the filter made that the recorder did not see (a prediction
    /// through a call without the observer): the smoother refuses such a history.
    pub unobserved_predictions: u64,
    nodes: usize,
    update_nodes: usize,
    file: Option<Arc<File>>,
    file_bytes: u64,
    /// The first error writing the file (the smoother refuses such a history).
    error: Option<String>,
}

impl History {
    /// A history of dimension `n` holding `nodes` (in time order), written to a temporary
    /// file (for tests and tools that build one by hand).
    pub fn from_nodes(
        n: usize,
        nodes: impl IntoIterator<Item = Node>,
    ) -> Result<Self, SmoothError> {
        let mut rec = Recorder::new(n);
        for node in nodes {
            rec.emit(node);
        }
        Ok(rec.close())
    }

    /// Nodes (covariance-prediction epochs) stored.
    pub fn len(&self) -> usize {
        self.nodes
    }

    /// True when no node was stored.
    pub fn is_empty(&self) -> bool {
        self.nodes == 0
    }

    /// Size of the temporary file, bytes.
    pub fn file_bytes(&self) -> u64 {
        self.file_bytes
    }

    /// Nodes with an update (a posterior different from the prior, or a correction).
    pub fn update_nodes(&self) -> usize {
        self.update_nodes
    }

    /// The nodes read back from the file, in time order (all in memory: for tests and small
    /// histories; the smoother reads them in blocks).
    pub fn read_nodes(&self) -> Result<Vec<Node>, SmoothError> {
        let mut v = self.rev_nodes()?.collect::<Result<Vec<_>, _>>()?;
        v.reverse();
        Ok(v.into_iter().map(|(_, node)| node).collect())
    }

    fn rev_nodes(&self) -> Result<RevNodes<'_>, SmoothError> {
        if let Some(e) = &self.error {
            return Err(SmoothError::Io(e.clone()));
        }
        match &self.file {
            Some(f) => Ok(RevNodes::new(f, self.n, self.file_bytes, self.nodes)),
            None if self.nodes == 0 => Err(SmoothError::Empty),
            None => Err(SmoothError::Io("the history has no file".into())),
        }
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
/// that the update's own prediction is seen), then [`Recorder::finish`]. Every node is written
/// to the history's temporary file once no later prediction can change it (the recorder holds
/// the last one).
#[derive(Debug, Default)]
pub struct Recorder {
    enabled: bool,
    n: usize,
    /// The node file (opened at the first node; None after a write error).
    out: Option<NodeWriter>,
    /// The last node (its posterior, correction and transition are known later).
    last: Option<Node>,
    nodes: usize,
    update_nodes: usize,
    error: Option<String>,
    seen: u64,
}

impl Recorder {
    /// A recorder for a layout of `n` states.
    pub fn new(n: usize) -> Self {
        Self {
            enabled: true,
            n,
            ..Self::default()
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

    /// Writes a complete node to the file.
    fn emit(&mut self, node: Node) {
        self.nodes += 1;
        if node.p_post.is_some() || node.correction.is_some() {
            self.update_nodes += 1;
        }
        if self.error.is_some() {
            return;
        }
        if self.out.is_none() {
            match NodeWriter::new() {
                Ok(w) => self.out = Some(w),
                Err(e) => {
                    self.error = Some(format!("creating the temporary history file: {e}"));
                    return;
                }
            }
        }
        if let Some(w) = &mut self.out {
            if let Err(e) = w.write(&node) {
                self.error = Some(format!("writing the temporary history file: {e}"));
                self.out = None;
            }
        }
    }

    /// The history of the nodes emitted.
    fn close(mut self) -> History {
        let mut h = History {
            n: self.n,
            nodes: self.nodes,
            update_nodes: self.update_nodes,
            error: self.error.take(),
            ..History::default()
        };
        if let Some(w) = self.out.take() {
            match w.finish() {
                Ok((f, bytes)) => {
                    h.file = Some(Arc::new(f));
                    h.file_bytes = bytes;
                }
                Err(e) => {
                    h.error
                        .get_or_insert(format!("writing the temporary history file: {e}"));
                }
            }
        }
        h
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
        if let Some(mut last) = self.last.take() {
            let post = pack(p);
            if post != last.p_prior {
                last.p_post = Some(post);
            }
            last.correction = nonzero(pending_correction);
            self.emit(last);
        }
        let unobserved = cov_predictions.saturating_sub(self.seen);
        let mut h = self.close();
        h.unobserved_predictions = unobserved;
        Some(h)
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
            .last
            .as_ref()
            .is_some_and(|l| (l.t_s - rec.t_start_s).abs() <= LINK_TOL_S);
        let start = match self.last.take() {
            Some(mut last) if linked => {
                if before != last.p_prior {
                    last.p_post = Some(before);
                }
                last.correction = correction;
                last
            }
            other => {
                // a new segment: the previous one ends at its last node
                if let Some(last) = other {
                    self.emit(last);
                }
                Node {
                    t_s: rec.t_start_s,
                    p_prior: before,
                    p_post: None,
                    correction,
                    phi: None,
                }
            }
        };
        self.emit(Node {
            phi: Some(pack_phi(rec.phi)),
            ..start
        });
        self.last = Some(Node {
            t_s: rec.t_end_s,
            p_prior: pack(rec.p_after),
            p_post: None,
            correction: None,
            phi: None,
        });
    }
}

/// Errors of the backward pass.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
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
    /// Writing or reading a temporary file failed (the message names the file and the cause).
    #[error("smoother: {0}")]
    Io(String),
    /// A record asked for a node the cursor had passed (records out of time order).
    #[error("smoother: a record at t = {0:.6} s came after one at t = {1:.6} s")]
    OutOfOrder(f64, f64),
}

/// The smoothed errors and covariances at the nodes, in a temporary file (removed when the
/// last clone is dropped); read them with [`Smoothed::cursor`].
#[derive(Debug, Clone, Default)]
pub struct Smoothed {
    /// Error-state dimension.
    pub n: usize,
    /// Nodes.
    pub nodes: usize,
    /// Solves of `P-(k+1)` that fell back to the pseudo-inverse (not positive definite).
    pub pinv_fallbacks: usize,
    file: Option<Arc<File>>,
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

/// The smoothed node data read back in memory (for tests and small runs; the run reads them
/// through a [`SmoothedCursor`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SmoothedNodes {
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
}

/// The parts of a smoothed record (see [`store`]).
struct Rec<'a> {
    t_s: f64,
    linked: bool,
    dx_post: &'a [f64],
    dx_prior: &'a [f64],
    cov_core: &'a [f64],
    var: &'a [f64],
}

impl<'a> Rec<'a> {
    fn of(n: usize, r: &'a [f64]) -> Self {
        let part = |a: usize, len: usize| r.get(a..a + len).unwrap_or(&[]);
        Self {
            t_s: r.first().copied().unwrap_or(f64::NAN),
            linked: r.get(1).is_some_and(|v| *v != 0.0),
            dx_post: part(2, n),
            dx_prior: part(2 + n, n),
            cov_core: part(2 + 2 * n, 81),
            var: part(83 + 2 * n, n),
        }
    }
}

impl Smoothed {
    /// Size of the temporary file, bytes.
    pub fn file_bytes(&self) -> u64 {
        (self.nodes * store::smoothed_len(self.n) * 8) as u64
    }

    /// A reader of the smoothed solution at times in increasing order.
    pub fn cursor(&self) -> SmoothedCursor<'_> {
        SmoothedCursor {
            n: self.n,
            count: self.nodes,
            blocks: SmoothedBlocks::new(self.file.as_deref(), self.n, self.nodes),
            k: None,
            last_t: f64::NEG_INFINITY,
        }
    }

    /// All node data in memory.
    pub fn load(&self) -> Result<SmoothedNodes, SmoothError> {
        let mut b = SmoothedBlocks::new(self.file.as_deref(), self.n, self.nodes);
        let mut out = SmoothedNodes::default();
        for k in 0..self.nodes {
            let r = Rec::of(self.n, b.pair(k)?.0);
            out.t_s.push(r.t_s);
            out.linked.push(r.linked);
            out.dx_post.extend_from_slice(r.dx_post);
            out.dx_prior.extend_from_slice(r.dx_prior);
            out.cov_core.extend_from_slice(r.cov_core);
            out.var.extend_from_slice(r.var);
        }
        Ok(out)
    }
}

/// The smoothed error and covariance at times in increasing order, read from the smoothed
/// file in blocks ([`Smoothed::cursor`]).
#[derive(Debug)]
pub struct SmoothedCursor<'a> {
    n: usize,
    count: usize,
    blocks: SmoothedBlocks<'a>,
    /// The last node at or before the last time asked.
    k: Option<usize>,
    last_t: f64,
}

impl SmoothedCursor<'_> {
    /// The smoothed error and covariance at `t_s` for a record of the stored forward nominal
    /// at that time (see the module notes); `None` before the first node. Times must not
    /// decrease from one call to the next ([`SmoothError::OutOfOrder`]).
    pub fn at(&mut self, t_s: f64) -> Result<Option<SmoothedPoint>, SmoothError> {
        if t_s < self.last_t {
            return Err(SmoothError::OutOfOrder(t_s, self.last_t));
        }
        self.last_t = t_s;
        // the last node with t <= t_s + 1e-9
        loop {
            let next = self.k.map_or(0, |k| k + 1);
            if next >= self.count || self.blocks.time(next)? > t_s + 1e-9 {
                break;
            }
            self.k = Some(next);
        }
        let Some(k) = self.k else {
            return Ok(None);
        };
        let n = self.n;
        let (here, next) = self.blocks.pair(k)?;
        let here = Rec::of(n, here);
        let next = next.map(|r| Rec::of(n, r));
        let tk = here.t_s;
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
        Ok(Some(match next {
            Some(nx) if here.linked && (t_s - tk).abs() > 1e-9 && nx.t_s > tk => {
                let t1 = nx.t_s;
                let f = ((t_s - tk) / (t1 - tk)).clamp(0.0, 1.0);
                let lerp = |a: &[f64], b: &[f64]| -> Vec<f64> {
                    a.iter().zip(b).map(|(x, y)| x + f * (y - x)).collect()
                };
                let dx = lerp(here.dx_post, nx.dx_prior);
                let cov = lerp(here.cov_core, nx.cov_core);
                let var = lerp(here.var, nx.var);
                point(dx, &cov, &var)
            }
            _ => point(here.dx_post.to_vec(), here.cov_core, here.var),
        }))
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

/// The Rauch-Tung-Striebel backward pass over a recorded history (see the module notes): the
/// history read from its end in blocks, the smoothed node data written to a temporary file.
pub fn smooth(h: &History) -> Result<Smoothed, SmoothError> {
    if h.unobserved_predictions > 0 {
        return Err(SmoothError::Unobserved(h.unobserved_predictions));
    }
    let n = h.n;
    let m = h.nodes;
    if m == 0 {
        return Err(SmoothError::Empty);
    }
    if n < CORE_DIM {
        return Err(SmoothError::Size(0));
    }
    let mut nodes = h.rev_nodes()?;
    let mut w = SmoothedWriter::new(n)?;
    let store =
        |w: &mut SmoothedWriter, k: usize, node: &Node, dxs: &DVector<f64>, ps: &DMatrix<f64>| {
            let corr = |i: usize| {
                node.correction
                    .as_ref()
                    .and_then(|c| c.get(i))
                    .copied()
                    .unwrap_or(0.0)
            };
            let vals = [node.t_s, if node.phi.is_some() { 1.0 } else { 0.0 }]
                .into_iter()
                .chain(dxs.iter().copied())
                .chain((0..n).map(|i| dxs[i] + corr(i)))
                .chain((0..CORE_DIM * CORE_DIM).map(|a| ps[(a / CORE_DIM, a % CORE_DIM)]))
                .chain((0..n).map(|i| ps[(i, i)]));
            w.push(k, vals)
        };
    let (last, mut next) = nodes.next().ok_or(SmoothError::Empty)??;
    let mut ps = unpack(n, next.post());
    let mut dxs = DVector::<f64>::zeros(n);
    store(&mut w, last, &next, &dxs, &ps)?;
    let mut fallbacks = 0usize;
    for item in nodes {
        let (k, node) = item?;
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
        store(&mut w, k, &node, &dxs, &ps)?;
        next = node;
    }
    Ok(Smoothed {
        n,
        nodes: m,
        pinv_fallbacks: fallbacks,
        file: Some(w.finish()?),
    })
}
