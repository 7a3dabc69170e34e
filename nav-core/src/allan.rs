//! Streaming Allan variance for on-board sensor health monitoring during static periods.
//!
//! Fixed memory, no allocation, O(1) amortised work per sample: an **octave pyramid** of `L`
//! levels. Level `k` sees the means of consecutive, non-overlapping blocks of `2^k` samples;
//! each new block mean is differenced with the previous one and the squared difference is
//! accumulated, and every second block mean is paired with the previous one to make the next
//! level's block mean.
//!
//! Estimator: the **non-overlapping** Allan variance at the octave averaging times
//! `tau_k = 2^k tau0`, `AVAR_k = sum_j (z_{j+1} - z_j)^2 / (2 (M_k - 1))` over the `M_k =
//! floor(n / 2^k)` complete blocks seen so far (NIST SP1065 eq. 8 in frequency form). It equals
//! the host's non-overlapping ADEV (`noise_id::Deviation::Adev`) on the same samples up to
//! rounding. The first sample is kept as an offset and subtracted from all later ones, so a
//! constant 9.81 m/s^2 does not cost precision.
//!
//! State: `24 L + 16` bytes (e.g. 400 bytes for `L = 16`, `2^15` tau0 = 327 s at 100 Hz).

/// Per-level state.
#[derive(Clone, Copy, Debug, Default)]
struct Level {
    /// Most recent block mean at this level (input units, offset removed).
    last: f64,
    /// Sum of squared differences of consecutive block means.
    sum_sq: f64,
    /// Number of block means seen at this level.
    blocks: u64,
}

/// Streaming non-overlapping Allan variance at `L` octave averaging times
/// `2^0 .. 2^(L-1)` sample times. Input samples are rates (m/s^2, rad/s, ...).
#[derive(Clone, Debug)]
pub struct StreamingAllan<const L: usize> {
    levels: [Level; L],
    offset: f64,
    n: u64,
}

impl<const L: usize> Default for StreamingAllan<L> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const L: usize> StreamingAllan<L> {
    /// An empty accumulator.
    pub const fn new() -> Self {
        Self {
            levels: [Level {
                last: 0.0,
                sum_sq: 0.0,
                blocks: 0,
            }; L],
            offset: 0.0,
            n: 0,
        }
    }

    /// Forgets all samples.
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Adds one rate sample (units of the sensor, e.g. m/s^2). Non-finite samples are ignored
    /// (returns `false`).
    pub fn push(&mut self, x: f64) -> bool {
        if !x.is_finite() {
            return false;
        }
        if self.n == 0 {
            self.offset = x;
        }
        self.n = self.n.saturating_add(1);
        let mut v = x - self.offset;
        for lvl in self.levels.iter_mut() {
            if lvl.blocks > 0 {
                let d = v - lvl.last;
                lvl.sum_sq += d * d;
            }
            let odd = lvl.blocks % 2 == 1;
            let prev = lvl.last;
            lvl.last = v;
            lvl.blocks = lvl.blocks.saturating_add(1);
            if !odd {
                break;
            }
            v = 0.5 * (prev + v);
        }
        true
    }

    /// Number of samples pushed.
    pub fn n_samples(&self) -> u64 {
        self.n
    }

    /// Number of levels `L`.
    pub const fn levels(&self) -> usize {
        L
    }

    /// Averaging factor `2^level` (samples).
    pub fn factor(level: usize) -> u64 {
        1u64.checked_shl(level as u32).unwrap_or(0)
    }

    /// Number of difference terms at `level` (complete blocks - 1), 0 if none.
    pub fn n_terms(&self, level: usize) -> u64 {
        self.levels
            .get(level)
            .map_or(0, |l| l.blocks.saturating_sub(1))
    }

    /// Non-overlapping Allan variance at `tau = 2^level tau0` (input units squared), `None`
    /// while fewer than two blocks have been seen.
    pub fn avar(&self, level: usize) -> Option<f64> {
        let l = self.levels.get(level)?;
        if l.blocks < 2 {
            return None;
        }
        Some(l.sum_sq / (2.0 * (l.blocks - 1) as f64))
    }

    /// Allan deviation at `tau = 2^level tau0` (input units).
    pub fn adev(&self, level: usize) -> Option<f64> {
        self.avar(level).map(libm::sqrt)
    }

    /// `tau = 2^level tau0` in seconds for sample time `tau0_s`.
    pub fn tau_s(level: usize, tau0_s: f64) -> f64 {
        Self::factor(level) as f64 * tau0_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alternating_series_has_known_avar() {
        // y = +1, -1, +1, ...: level 0 differences are 2 -> AVAR = 4/2 = 2; level 1 block
        // means are all 0 -> AVAR 0.
        let mut a = StreamingAllan::<4>::new();
        for i in 0..64 {
            a.push(if i % 2 == 0 { 1.0 } else { -1.0 });
        }
        assert_eq!(a.avar(0), Some(2.0));
        assert_eq!(a.avar(1), Some(0.0));
        assert_eq!(a.n_terms(0), 63);
        assert_eq!(a.n_terms(3), 7);
        assert_eq!(a.avar(4), None);
    }
}
