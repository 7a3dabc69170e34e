//! The one gated Kalman update of the filter: every measurement (GNSS position, GNSS
//! position + velocity, GNSS velocity alone, the aiding sources of [`crate::aiding`]) goes
//! through [`Filter::gated_update`].
//!
//! Measurement `z = H dx + v` with `z` = predicted minus measured, `dx` = estimate - truth,
//! diagonal `R`. The normalised innovation squared `NIS = z^T S^-1 z`, `S = H P H^T + R`, is
//! tested against a [`Gate`]: at or below `downweight` the measurement is used as it is;
//! between `downweight` and `reject` `R` is divided by the IGG-III weight
//! ([`super::robust::igg3_weight`]); beyond `reject` (or with a weight below
//! [`super::robust::MIN_WEIGHT`]) it is not used and nothing changes. The update is done in
//! Joseph form and fed back into the nominal state (closed loop).
//!
//! No allocation (const generic sizes), no panics, no unchecked indexing. The arithmetic is in
//! two functions generic over the measurement dimension M alone, the state dimension a runtime
//! value over row-major slices ([`innovation`], [`gain_and_joseph`]): a binary with several
//! filter sizes carries them once per M (flash), in the same operation order as a
//! const-generic version (bit-identical results).

use super::linalg::{cholesky_in_place, cholesky_solve, dot, forward_solve};
use super::reacq::FixCheck;
use super::robust::{igg3_weight, MIN_WEIGHT};
use super::{get2, Filter, FilterError};
use crate::scalar::Scalar;

/// The chi-square thresholds of one gated update (dimensionless NIS values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Gate {
    /// At or below: full weight. Equal to `reject`: a hard gate (no down-weighting).
    pub downweight: f64,
    /// Above: not used (infinite: no gate).
    pub reject: f64,
}

impl Gate {
    /// A hard gate at `threshold` (infinite: every measurement is used).
    pub(crate) const fn hard(threshold: f64) -> Self {
        Self {
            downweight: threshold,
            reject: threshold,
        }
    }
}

/// What a gated update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Gated<const M: usize> {
    /// NIS `z^T S^-1 z` with the given R.
    pub nis: f64,
    /// Diagonal of `S = H P H^T + R` with the given R (units^2 of the measurement).
    pub s_diag: [f64; M],
    /// The weight used (1 full, in (0, 1) R / weight; 0 when not used).
    pub weight: f64,
    /// Whether the measurement was used.
    pub accepted: bool,
}

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// The gated Joseph-form update (see the module documentation) for the current
    /// covariance (the caller predicts it first). `z64` = predicted minus measured, `h` the
    /// Jacobian rows, `r64` the diagonal variances of the measurement. `fix`: a GNSS position
    /// fix's bookkeeping, done as soon as the NIS is known (before the decision, also when a
    /// later numerical failure returns an error): whether it is within the normal gate, the
    /// probation of the previous fix it decides (undone: the caller processes the fix again
    /// and this update stops there), and, for a first fix after an outage, its own probation
    /// with the covariance before it when it is accepted beyond the normal gate
    /// ([`super::reacq`]).
    ///
    /// Errors: [`FilterError::Numerical`] (counted) when `S` is not positive definite, the
    /// NIS or the result is not finite; the state and covariance are then unchanged.
    // one instance per (N, M) whatever the caller, its N x N temporaries in its own frame (MCU
    // stack); the arithmetic in the N-independent `innovation` and `gain_and_joseph` (flash:
    // the bench carries three filter sizes)
    #[inline(never)]
    pub(super) fn gated_update<const M: usize>(
        &mut self,
        z64: &[f64; M],
        h: &[[T; N]; M],
        r64: &[f64; M],
        gate: Gate,
        fix: Option<&FixCheck<T, N>>,
    ) -> Result<Gated<M>, FilterError> {
        let z = z64.map(T::of_f64);
        let r = r64.map(T::of_f64);
        let mut pht = [[T::ZERO; M]; N];
        let inn = innovation(self.p.as_flattened(), h.as_flattened(), N, &r, &z, &mut pht);
        let mut out = Gated {
            nis: f64::NAN,
            s_diag: [0.0; M],
            weight: 0.0,
            accepted: false,
        };
        for (i, o) in out.s_diag.iter_mut().enumerate() {
            *o = get2(&inn.s, i, i).to_f64();
        }
        let Some(l) = inn.l else {
            return Err(self.numerical_failure());
        };
        let nis = inn.nis;
        out.nis = nis;
        if !nis.is_finite() {
            return Err(self.numerical_failure());
        }
        if let Some(c) = fix {
            self.gate.last_within_normal_gate = nis <= c.normal_reject;
            self.redo = self.settle_tentative(nis, c);
        }
        if self.redo {
            // the fix's probation check undid the previous fix: the caller processes it again
            return Ok(out);
        }
        let weight = if nis <= gate.downweight {
            1.0
        } else {
            igg3_weight(nis, gate.downweight, gate.reject)
        };
        if !(nis <= gate.reject && weight >= MIN_WEIGHT) {
            return Ok(out);
        }
        let mut k = [[T::ZERO; M]; N];
        let mut y_mat = [[T::ZERO; M]; N];
        let mut dx = [T::ZERO; N];
        let mut p = self.p;
        let ok = gain_and_joseph(Joseph {
            n: N,
            p: p.as_flattened_mut(),
            h: h.as_flattened(),
            pht: &pht,
            s: &inn.s,
            l,
            z: &z,
            r,
            weight,
            k: &mut k,
            y: &mut y_mat,
            dx: &mut dx,
        });
        if !ok {
            return Err(self.numerical_failure());
        }
        match fix.filter(|c| c.fed_back_before.is_some()) {
            Some(c) => {
                // the covariance before the update stays in `p` for the probation
                core::mem::swap(&mut self.p, &mut p);
                self.feedback(&dx);
                self.put_on_probation(c, &p, nis);
            }
            None => {
                self.p = p;
                self.feedback(&dx);
            }
        }
        out.accepted = true;
        out.weight = weight;
        Ok(out)
    }
}

/// What [`innovation`] found.
struct Innovation<T, const M: usize> {
    /// `S = H P H^T + R`, symmetrised.
    s: [[T; M]; M],
    /// Its Cholesky factor (None: S not positive definite).
    l: Option<[[T; M]; M]>,
    /// NIS `z^T S^-1 z` (NaN without a factor).
    nis: f64,
}

/// `P H^T` (into `pht`, n rows), `S = H P H^T + R` (symmetrised), its Cholesky factor and the
/// NIS of `z`, for the covariance `p` (n x n, row-major) and the Jacobian `h` (M rows of n).
/// Generic over M only (flash).
#[inline(never)]
fn innovation<T: Scalar, const M: usize>(
    p: &[T],
    h: &[T],
    n: usize,
    r: &[T; M],
    z: &[T; M],
    pht: &mut [[T; M]],
) -> Innovation<T, M> {
    let mut s = [[T::ZERO; M]; M];
    if n == 0 {
        return Innovation {
            s,
            l: None,
            nis: f64::NAN,
        };
    }
    for (prow, out) in p.chunks_exact(n).zip(pht.iter_mut()) {
        for (o, hrow) in out.iter_mut().zip(h.chunks_exact(n)) {
            *o = dot(prow, hrow);
        }
    }
    for (a, (srow, hrow)) in s.iter_mut().zip(h.chunks_exact(n)).enumerate() {
        for (b, sab) in srow.iter_mut().enumerate() {
            let mut acc = T::ZERO;
            for (hai, phti) in hrow.iter().zip(pht.iter()) {
                acc += *hai * phti.get(b).copied().unwrap_or(T::ZERO);
            }
            if a == b {
                acc += r.get(a).copied().unwrap_or(T::ZERO);
            }
            *sab = acc;
        }
    }
    for a in 0..M {
        for b in 0..a {
            let v = (get2(&s, a, b) + get2(&s, b, a)) * T::HALF;
            super::set2(&mut s, a, b, v);
            super::set2(&mut s, b, a, v);
        }
    }
    let mut l = s;
    if !cholesky_in_place(&mut l) {
        return Innovation {
            s,
            l: None,
            nis: f64::NAN,
        };
    }
    let y = forward_solve(&l, z);
    let nis = dot(&y, &y).to_f64();
    Innovation { s, l: Some(l), nis }
}

/// The inputs and outputs of [`gain_and_joseph`] (n the state dimension; `p` n x n and `h`
/// M rows of n, row-major; `pht`, `k`, `y` n rows).
struct Joseph<'a, T, const M: usize> {
    n: usize,
    /// The covariance, updated in place.
    p: &'a mut [T],
    h: &'a [T],
    pht: &'a [[T; M]],
    s: &'a [[T; M]; M],
    /// The Cholesky factor of `s`.
    l: [[T; M]; M],
    z: &'a [T; M],
    r: [T; M],
    /// The IGG-III weight (1: full).
    weight: f64,
    /// The gain (output).
    k: &'a mut [[T; M]],
    /// Scratch.
    y: &'a mut [[T; M]],
    /// The correction `K z` (output).
    dx: &'a mut [T],
}

/// With `R / weight`: the gain `K = P H^T S^-1`, the correction `K z` and the Joseph-form
/// covariance in place ([`joseph`]). False (numerical failure; `p` partly overwritten) when the reweighted
/// S is not positive definite, or K, the correction or the covariance is not finite or has a
/// negative diagonal. Generic over M only (flash).
#[inline(never)]
fn gain_and_joseph<T: Scalar, const M: usize>(j: Joseph<'_, T, M>) -> bool {
    let Joseph {
        n,
        p,
        h,
        pht,
        s,
        mut l,
        z,
        mut r,
        weight,
        k,
        y,
        dx,
    } = j;
    if n == 0 {
        return false;
    }
    if weight < 1.0 {
        // R / w: only the diagonal of S changes (P H^T does not)
        let kw = T::of_f64(1.0 / weight);
        let mut s2 = *s;
        for (i, rv) in r.iter_mut().enumerate() {
            let extra = *rv * kw - *rv;
            *rv *= kw;
            if let Some(x) = s2.get_mut(i).and_then(|row| row.get_mut(i)) {
                *x += extra;
            }
        }
        if !cholesky_in_place(&mut s2) {
            return false;
        }
        l = s2;
    }
    // K = P H^T S^-1 (row i solves S k_i = (P H^T)_i)
    for (krow, phtrow) in k.iter_mut().zip(pht.iter()) {
        *krow = cholesky_solve(&l, phtrow);
    }
    for (d, krow) in dx.iter_mut().zip(k.iter()) {
        *d = dot(krow, z);
    }
    if !(k.iter().all(|r| r.iter().all(|v| v.finite())) && dx.iter().all(|v| v.finite())) {
        return false;
    }
    joseph(
        p,
        n,
        h,
        pht.as_flattened(),
        k.as_flattened(),
        &r,
        y.as_flattened_mut(),
    )
}

/// The Joseph-form covariance update in place, `P = (I - K H) P (I - K H)^T + K R K^T`, for
/// `p` (n x n), `h` (m rows of n), `pht` = P H^T and the gain `k` (n rows of m each), the
/// diagonal `r` (m) and the scratch `y` (n rows of m), all row-major; then mirrored from the
/// upper triangle. False when the result is not finite or has a negative diagonal. Both
/// dimensions are runtime values: one instance per scalar type (flash).
#[inline(never)]
fn joseph<T: Scalar>(
    p: &mut [T],
    n: usize,
    h: &[T],
    pht: &[T],
    k: &[T],
    r: &[T],
    y: &mut [T],
) -> bool {
    let m = r.len();
    if n == 0 || m == 0 {
        return false;
    }
    // AP = P - K (P H^T)^T;  P = AP - (AP H^T - K R) K^T  (upper triangle, mirrored)
    for (prow, krow) in p.chunks_exact_mut(n).zip(k.chunks_exact(m)) {
        for (pij, phtj) in prow.iter_mut().zip(pht.chunks_exact(m)) {
            *pij -= dot(krow, phtj);
        }
    }
    for ((yrow, prow), krow) in y
        .chunks_exact_mut(m)
        .zip(p.chunks_exact(n))
        .zip(k.chunks_exact(m))
    {
        for (((yv, hrow), kv), rv) in yrow
            .iter_mut()
            .zip(h.chunks_exact(n))
            .zip(krow)
            .zip(r.iter())
        {
            *yv = dot(prow, hrow) - *kv * *rv;
        }
    }
    for (i, (prow, yrow)) in p.chunks_exact_mut(n).zip(y.chunks_exact(m)).enumerate() {
        for (pij, kj) in prow.iter_mut().zip(k.chunks_exact(m)).skip(i) {
            *pij -= dot(yrow, kj);
        }
    }
    // mirror the upper triangle
    for i in 1..n {
        let Some((upper, lower)) = p.split_at_mut_checked(i * n) else {
            break;
        };
        let Some(row_i) = lower.get_mut(..n) else {
            break;
        };
        for (x, urow) in row_i.iter_mut().zip(upper.chunks_exact(n)) {
            if let Some(v) = urow.get(i) {
                *x = *v;
            }
        }
    }
    p.iter().all(|v| v.finite())
        && p.chunks_exact(n)
            .enumerate()
            .all(|(i, row)| row.get(i).is_some_and(|v| *v >= T::ZERO))
}
