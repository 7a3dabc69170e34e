//! Seeded generators of the IMU noise processes: quantization, white, first-order Gauss-Markov
//! (exact discretisation), random walk, flicker (1/f, Kasdin's method) and random constant.
//!
//! All generators work in the **rate domain**: each call of `next` returns the value of the
//! process for one sample of length `dt_s`, in the sensor's rate units (m/s^2 for an
//! accelerometer, rad/s for a gyro). A rate-type sensor output is `true_rate + sum of processes`;
//! the increment over the sample is that value times `dt_s`.
//!
//! PSD convention (IEEE 952, as in `docs/DESIGN.md`): every `S_*` is a **two-sided** continuous
//! PSD, so that the Allan variance is `sigma^2(tau) = 4 int_0^inf S(f) sin^4(pi f tau) /
//! (pi f tau)^2 df`:
//!
//! | process | PSD of the rate | Allan variance |
//! |---|---|---|
//! | white, `S_N` (`N = sqrt(S_N)`) | `S_N` | `S_N / tau` |
//! | random walk, `S_K` (`K = sqrt(S_K)`) | `S_K / (2 pi f)^2` | `S_K tau / 3` |
//! | Gauss-Markov, `S_B`, `T_B` | `S_B T_B^2 / (1 + (2 pi f T_B)^2)` | see `noise_id::gauss_markov_avar` |
//! | flicker, `B` | `B^2 / (2 pi f)` | `2 ln 2 B^2 / pi` (floor `0.6643 B`) |
//! | quantization, `Q = step / sqrt(12)` | (increments) | `3 Q^2 / tau^2` |
//!
//! The randomness comes from the caller's `Rng` (seed a `rand_chacha::ChaCha8Rng` for
//! reproducible runs); the generators only hold their state, so they are `Clone + Debug`.
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use rustfft::{num_complex::Complex, FftPlanner};

fn gauss<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    StandardNormal.sample(rng)
}

/// Band-limited white noise of two-sided PSD `S_N` (units^2/Hz, e.g. (m/s^2)^2/Hz = m^2/s^3).
///
/// Per-sample standard deviation `sqrt(S_N / dt)`, so the increment error over one sample
/// (`value * dt`) has variance `S_N dt`, and the Allan variance is exactly `S_N / tau` at every
/// `tau = m dt`.
#[derive(Clone, Debug)]
pub struct White {
    sigma: f64,
}

impl White {
    /// White noise from its two-sided PSD `s_n` and the sample time `dt_s` (s).
    pub fn from_psd(s_n: f64, dt_s: f64) -> Self {
        Self {
            sigma: (s_n.max(0.0) / dt_s).sqrt(),
        }
    }
    /// Per-sample standard deviation (rate units).
    pub fn sigma(&self) -> f64 {
        self.sigma
    }
    /// The value for the next sample.
    #[allow(clippy::should_implement_trait)]
    pub fn next<R: Rng + ?Sized>(&mut self, rng: &mut R) -> f64 {
        self.sigma * gauss(rng)
    }
}

/// First-order Gauss-Markov process `db/dt = -b / T_B + w`, `w` white with two-sided PSD `S_B`
/// (units^2/s^2/Hz, m^2/s^5 for an accelerometer). Stationary variance `S_B T_B / 2`.
///
/// Exact discretisation: `b_k = Phi b_{k-1} + u_k`, `Phi = exp(-dt / T_B)`, `var u =
/// (S_B T_B / 2)(1 - Phi^2)`. The first value is drawn from the stationary distribution. The
/// process is returned as its point value at each sample (not its mean over the sample); the
/// difference to the interval mean is of order `dt / T_B`.
#[derive(Clone, Debug)]
pub struct GaussMarkov {
    phi: f64,
    q_std: f64,
    stat_std: f64,
    state: Option<f64>,
}

impl GaussMarkov {
    /// Gauss-Markov process with driving PSD `s_b`, correlation time `t_b_s` (s), sample time
    /// `dt_s` (s).
    pub fn new(s_b: f64, t_b_s: f64, dt_s: f64) -> Self {
        let var = 0.5 * s_b.max(0.0) * t_b_s;
        let phi = (-dt_s / t_b_s).exp();
        Self {
            phi,
            q_std: (var * (1.0 - phi * phi)).sqrt(),
            stat_std: var.sqrt(),
            state: None,
        }
    }
    /// `Phi = exp(-dt / T_B)`.
    pub fn phi(&self) -> f64 {
        self.phi
    }
    /// Stationary standard deviation `sqrt(S_B T_B / 2)` (rate units).
    pub fn stationary_sigma(&self) -> f64 {
        self.stat_std
    }
    /// The value for the next sample.
    #[allow(clippy::should_implement_trait)]
    pub fn next<R: Rng + ?Sized>(&mut self, rng: &mut R) -> f64 {
        let x = match self.state {
            None => self.stat_std * gauss(rng),
            Some(b) => self.phi * b + self.q_std * gauss(rng),
        };
        self.state = Some(x);
        x
    }
}

/// Random walk (rate random walk) `dk/dt = w`, `w` white with two-sided PSD `S_K`
/// (units^2/s^2/Hz). Starts at 0; each sample adds an independent `N(0, S_K dt)` step and
/// returns the new value. Allan variance of the sampled walk: `S_K dt (2 m^2 + 1) / (6 m)` at
/// `tau = m dt`, i.e. `S_K tau / 3 + S_K dt^2 / (6 tau)`.
#[derive(Clone, Debug)]
pub struct RandomWalk {
    step_std: f64,
    value: f64,
}

impl RandomWalk {
    /// Random walk with driving PSD `s_k` and sample time `dt_s` (s).
    pub fn new(s_k: f64, dt_s: f64) -> Self {
        Self {
            step_std: (s_k.max(0.0) * dt_s).sqrt(),
            value: 0.0,
        }
    }
    /// The value for the next sample.
    #[allow(clippy::should_implement_trait)]
    pub fn next<R: Rng + ?Sized>(&mut self, rng: &mut R) -> f64 {
        self.value += self.step_std * gauss(rng);
        self.value
    }
}

/// Random constant (turn-on bias): `N(0, sigma^2)` drawn on the first call, then returned
/// unchanged.
#[derive(Clone, Debug)]
pub struct RandomConstant {
    sigma: f64,
    value: Option<f64>,
}

impl RandomConstant {
    /// Random constant of standard deviation `sigma` (rate units).
    pub fn new(sigma: f64) -> Self {
        Self { sigma, value: None }
    }
    /// The value (drawn once).
    #[allow(clippy::should_implement_trait)]
    pub fn next<R: Rng + ?Sized>(&mut self, rng: &mut R) -> f64 {
        let s = self.sigma;
        *self.value.get_or_insert_with(|| s * gauss(rng))
    }
}

/// True flicker (1/f) noise by Kasdin's method (N. J. Kasdin, "Discrete simulation of colored
/// noise and stochastic processes and 1/f^alpha power law noise generation", Proc. IEEE 83(5),
/// 1995): white noise of variance `B^2` filtered by `(1 - z^-1)^(-1/2)`, i.e. the impulse
/// response `h_0 = 1`, `h_k = h_{k-1} (k - 1/2) / k`, applied by FFT convolution.
///
/// Convention (IEEE 952): two-sided PSD `B^2 / (2 pi f)` at `f << 1/dt` (the discrete PSD is
/// `B^2 dt / (2 sin(pi f dt))`), Allan floor `sigma(tau) = B sqrt(2 ln 2 / pi) = 0.6643 B` for
/// `dt << tau`; [`flicker_avar_discrete`] gives the exact value at every `tau = m dt`.
///
/// A 1/f process has no stationary form, so it is made in blocks of `block_len` samples: each
/// block is filtered from `warmup` = `block_len` earlier samples of the same white sequence, so
/// every output sample has at least `block_len` samples of past (the Allan variance is within
/// a few percent of the floor for `tau <= block_len dt / 10`). Successive blocks are independent;
/// choose `block_len` >= the record length for one continuous realisation. Memory: `block_len`
/// f64 plus the FFT work space while a block is made.
#[derive(Clone, Debug)]
pub struct Flicker {
    b: f64,
    block_len: usize,
    buf: Vec<f64>,
    pos: usize,
}

impl Flicker {
    /// Flicker noise with IEEE 952 coefficient `b` (rate units: the floor is `0.6643 b`), sample
    /// time `dt_s` (s; it only enters through the `tau = m dt` scaling, the per-sample process
    /// does not depend on it), blocks of `block_len` samples (at least 16).
    pub fn new(b: f64, dt_s: f64, block_len: usize) -> Self {
        let _ = dt_s;
        Self {
            b,
            block_len: block_len.max(16),
            buf: Vec::new(),
            pos: 0,
        }
    }

    /// Kasdin impulse response `h_k` for `1/f^alpha` noise, `k = 0..n`.
    pub fn kasdin_response(alpha: f64, n: usize) -> Vec<f64> {
        let mut h = Vec::with_capacity(n);
        let mut hk = 1.0;
        for k in 0..n {
            if k > 0 {
                hk *= (k as f64 - 1.0 + 0.5 * alpha) / k as f64;
            }
            h.push(hk);
        }
        h
    }

    fn refill<R: Rng + ?Sized>(&mut self, rng: &mut R) {
        let l = self.block_len;
        let total = 2 * l; // warm-up + block
        let nfft = (2 * total).next_power_of_two();
        let h = Self::kasdin_response(1.0, total);
        let mut hf: Vec<Complex<f64>> = (0..nfft)
            .map(|i| Complex::new(h.get(i).copied().unwrap_or(0.0), 0.0))
            .collect();
        let mut wf: Vec<Complex<f64>> = (0..nfft)
            .map(|i| {
                let v = if i < total { self.b * gauss(rng) } else { 0.0 };
                Complex::new(v, 0.0)
            })
            .collect();
        let mut planner = FftPlanner::<f64>::new();
        let fwd = planner.plan_fft_forward(nfft);
        let inv = planner.plan_fft_inverse(nfft);
        fwd.process(&mut hf);
        fwd.process(&mut wf);
        for (w, h) in wf.iter_mut().zip(hf.iter()) {
            *w *= *h;
        }
        drop(hf);
        inv.process(&mut wf);
        let scale = 1.0 / nfft as f64;
        self.buf.clear();
        self.buf.extend(wf[l..total].iter().map(|c| c.re * scale));
        self.pos = 0;
    }

    /// The value for the next sample.
    #[allow(clippy::should_implement_trait)]
    pub fn next<R: Rng + ?Sized>(&mut self, rng: &mut R) -> f64 {
        if self.pos >= self.buf.len() {
            self.refill(rng);
        }
        let v = self.buf[self.pos];
        self.pos += 1;
        v
    }
}

/// Exact Allan variance at `tau = m dt` of the discrete flicker process made by [`Flicker`]
/// (infinite past): `AVAR(m) = (2 B^2 / m^2) int_0^(1/2) sin^4(pi m u) / sin^3(pi u) du`, the
/// discrete PSD `B^2 dt / (2 sin(pi f dt))` through the Allan filter. Tends to
/// `2 ln 2 B^2 / pi` for large `m`.
pub fn flicker_avar_discrete(b: f64, m: usize) -> f64 {
    let m = m.max(1) as f64;
    // Integrate in x = pi u on (0, pi/2]; split into panels of the oscillation period.
    let f = |x: f64| {
        let s = x.sin();
        if s < 1e-300 {
            0.0
        } else {
            let sm = (m * x).sin();
            let sm2 = sm * sm;
            sm2 * sm2 / (s * s * s)
        }
    };
    let half_pi = std::f64::consts::FRAC_PI_2;
    let panels = ((m * 8.0).ceil() as usize).clamp(64, 1 << 16);
    // Gauss-Legendre 8 points per panel, panels geometric near 0 is not needed: integrand ~ x.
    let gl_x = [
        -0.960_289_856_497_536_2,
        -0.796_666_477_413_626_7,
        -0.525_532_409_916_329,
        -0.183_434_642_495_649_8,
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_2,
    ];
    let gl_w = [
        0.101_228_536_290_376_3,
        0.222_381_034_453_374_5,
        0.313_706_645_877_887_3,
        0.362_683_783_378_362,
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    let hstep = half_pi / panels as f64;
    let mut sum = 0.0;
    for p in 0..panels {
        let a = p as f64 * hstep;
        let c = a + 0.5 * hstep;
        for (xi, wi) in gl_x.iter().zip(gl_w.iter()) {
            sum += wi * f(c + 0.5 * hstep * xi);
        }
    }
    let integral_x = sum * 0.5 * hstep; // integral over x
    2.0 * b * b / (m * m) * integral_x / std::f64::consts::PI
}

/// Quantizer of accumulated increments with residual carry (the way an IMU's velocity or angle
/// counter works): the input is the true increment over one sample (e.g. `dv` in m/s), the
/// output the quantized increment (a multiple of `step`); the part not yet output is carried
/// to the next sample, so no increment is ever lost.
///
/// Error of the output increment: `r_{k-1} - r_k` with `r_k` the residual, uniform on
/// `[-step/2, step/2)` when the signal dithers it. The Allan variance of the rate
/// (`increment / dt`) is then `3 Q^2 / tau^2` with `Q^2 = step^2 / 12` (`Q` in increment units,
/// m/s or rad: the `S_A = Q^2` of `docs/DESIGN.md`), exactly at every `tau = m dt` for
/// independent residuals: the block-mean difference is `(r_0 - 2 r_m + r_2m) / tau`.
#[derive(Clone, Debug)]
pub struct Quantizer {
    step: f64,
    residual: f64,
}

impl Quantizer {
    /// Quantizer with increment quantum `step` (e.g. m/s per LSB). `step <= 0` passes through.
    pub fn new(step: f64) -> Self {
        Self {
            step,
            residual: 0.0,
        }
    }
    /// `Q = step / sqrt(12)` (increment units), the IEEE 952 quantization coefficient.
    pub fn q_coefficient(&self) -> f64 {
        self.step / 12f64.sqrt()
    }
    /// Quantize the next increment `x`; returns a multiple of `step`.
    pub fn quantize(&mut self, x: f64) -> f64 {
        if self.step.is_nan() || self.step <= 0.0 {
            return x;
        }
        let acc = self.residual + x;
        let q = (acc / self.step).round() * self.step;
        self.residual = acc - q;
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn mean_var(x: &[f64]) -> (f64, f64) {
        let n = x.len() as f64;
        let m = x.iter().sum::<f64>() / n;
        (
            m,
            x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0),
        )
    }

    #[test]
    fn white_variance_is_psd_over_dt() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut w = White::from_psd(6.2865e-9, 0.01);
        let x: Vec<f64> = (0..200_000).map(|_| w.next(&mut rng)).collect();
        let (_, v) = mean_var(&x);
        let expect = 6.2865e-9 / 0.01;
        // std of a variance estimate: sqrt(2/n) = 0.32%; allow 4 sigma.
        assert!((v / expect - 1.0).abs() < 4.0 * (2.0f64 / 200_000.0).sqrt());
    }

    #[test]
    fn gauss_markov_is_stationary_with_lag1_correlation_phi() {
        let (s_b, t_b, dt) = (2.4360e-11, 45.0, 0.01 * 450.0); // phi = e^-0.1
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let runs = 4000;
        let mut first = Vec::with_capacity(runs);
        let mut tenth = Vec::with_capacity(runs);
        let mut prod = 0.0;
        for _ in 0..runs {
            let mut g = GaussMarkov::new(s_b, t_b, dt);
            let x0 = g.next(&mut rng);
            let x1 = g.next(&mut rng);
            let mut x = x1;
            for _ in 0..8 {
                x = g.next(&mut rng);
            }
            first.push(x0);
            tenth.push(x);
            prod += x0 * x1;
        }
        let var = s_b * t_b / 2.0;
        let (_, v0) = mean_var(&first);
        let (_, v9) = mean_var(&tenth);
        let tol = 4.0 * (2.0 / runs as f64).sqrt();
        assert!((v0 / var - 1.0).abs() < tol, "{v0} vs {var}");
        assert!((v9 / var - 1.0).abs() < tol, "{v9} vs {var}");
        let rho = prod / runs as f64 / var;
        let phi = (-dt / t_b).exp();
        assert!(
            (rho - phi).abs() < 4.0 / (runs as f64).sqrt(),
            "{rho} vs {phi}"
        );
    }

    #[test]
    fn random_walk_variance_grows_as_s_k_t() {
        let (s_k, dt) = (2.6731e-12, 0.01);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let runs = 4000;
        let steps = 500;
        let end: Vec<f64> = (0..runs)
            .map(|_| {
                let mut r = RandomWalk::new(s_k, dt);
                (0..steps).fold(0.0, |_, _| r.next(&mut rng))
            })
            .collect();
        let (_, v) = mean_var(&end);
        let expect = s_k * dt * steps as f64;
        assert!((v / expect - 1.0).abs() < 4.0 * (2.0 / runs as f64).sqrt());
    }

    #[test]
    fn random_constant_is_constant_with_sigma() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let vals: Vec<f64> = (0..4000)
            .map(|_| {
                let mut c = RandomConstant::new(3.0);
                let a = c.next(&mut rng);
                assert_eq!(a, c.next(&mut rng));
                a
            })
            .collect();
        let (_, v) = mean_var(&vals);
        assert!((v / 9.0 - 1.0).abs() < 4.0 * (2.0f64 / 4000.0).sqrt());
    }

    #[test]
    fn quantizer_keeps_the_sum_and_outputs_multiples_of_step() {
        let mut q = Quantizer::new(0.01);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut sum_in = 0.0;
        let mut sum_out = 0.0;
        for _ in 0..10_000 {
            let x = 0.003 + 0.02 * gauss(&mut rng);
            sum_in += x;
            let y = q.quantize(x);
            let k = y / 0.01;
            assert!((k - k.round()).abs() < 1e-9);
            sum_out += y;
        }
        assert!((sum_in - sum_out).abs() <= 0.005 + 1e-12);
        assert!((q.q_coefficient() - 0.01 / 12f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn kasdin_response_matches_closed_form() {
        // alpha = 1: h_k = (2k)! / (4^k (k!)^2); h_3 = 5/16.
        let h = Flicker::kasdin_response(1.0, 5);
        assert!((h[3] - 5.0 / 16.0).abs() < 1e-15);
        assert!((h[4] - 35.0 / 128.0).abs() < 1e-15);
    }

    #[test]
    fn flicker_discrete_avar_tends_to_ieee_floor() {
        let floor = 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI;
        let a = flicker_avar_discrete(1.0, 4096);
        assert!((a / floor - 1.0).abs() < 1e-3, "{a} vs {floor}");
    }
}
