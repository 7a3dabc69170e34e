//! The `[noise]` section of the run configuration ([`NoiseConfig`]): the IMU noise model in
//! the source document's terms (S_N, S_B, T_B, S_K, initial sigmas), in SI or datasheet units.
//!
//! Noise values are given either in SI (the `s_n`, `s_b`, `s_k`, `bias_init_sigma` keys, units
//! below) or in datasheet units (keys named after their unit), never both for one quantity:
//!
//! | quantity | SI key (accel / gyro unit) | datasheet alternatives |
//! |---|---|---|
//! | white noise | `s_n` (m^2/s^3 / rad^2/s) | accel `n_ug_per_sqrt_hz`, `vrw_mps_per_sqrt_h`; gyro `arw_deg_per_sqrt_h`, `n_deg_per_s_per_sqrt_hz` |
//! | Gauss-Markov bias | `s_b` (m^2/s^5 / rad^2/s^3) with `t_b_s` | accel `gm_sigma_ug`; gyro `gm_sigma_deg_per_h` (stationary sigma; S_B = 2 sigma^2 / T_B) |
//! | bias random walk | `s_k` (m^2/s^5 / rad^2/s^3) | accel `k_ug_per_sqrt_h`, `k_ug_per_sqrt_hz`; gyro `k_deg_per_h_per_sqrt_h`, `k_deg_per_s_per_sqrt_hz` |
//! | initial bias sigma | `bias_init_sigma` (m/s^2 / rad/s) | accel `bias_init_ug`; gyro `bias_init_deg_per_h`, `bias_init_deg_per_s` |
//!
//! Every value except `t_b_s` is either one number (all three axes) or an array of three
//! (`[x, y, z]`, IMU axes), e.g. `s_n = [4.1e-7, 3.9e-7, 5.2e-7]` as `host-sim allan` writes
//! it; the filter has one correlation time per sensor.
//!
//! (`k_..._per_sqrt_hz` is the bias random walk written as a rate PSD per sqrt(Hz), the way
//! rtklibexplorer's GNSS_IMU states `accel_bias_PSD` / `gyro_bias_PSD`: S_K = K^2.)
use nav_core::config::units;
use nav_core::config::SensorNoise;

/// A noise value: one number for the three axes, or one per axis `[x, y, z]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AxisValue {
    /// The same value on x, y and z.
    One(f64),
    /// One value per IMU axis.
    PerAxis([f64; 3]),
}

impl AxisValue {
    /// The three axis values.
    pub fn axes(self) -> [f64; 3] {
        match self {
            AxisValue::One(v) => [v; 3],
            AxisValue::PerAxis(a) => a,
        }
    }
    /// The three axis values, each converted by `f`.
    pub fn map(self, f: impl Fn(f64) -> f64) -> [f64; 3] {
        self.axes().map(f)
    }
}

impl serde::Serialize for AxisValue {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            AxisValue::One(v) => s.serialize_f64(*v),
            AxisValue::PerAxis(a) => a.serialize(s),
        }
    }
}

impl<'de> serde::Deserialize<'de> for AxisValue {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = AxisValue;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number, or an array of three numbers [x, y, z]")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<AxisValue, E> {
                Ok(AxisValue::One(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<AxisValue, E> {
                Ok(AxisValue::One(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<AxisValue, E> {
                Ok(AxisValue::One(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<AxisValue, A::Error> {
                let mut out = [0.0f64; 3];
                for (i, o) in out.iter_mut().enumerate() {
                    *o = seq
                        .next_element::<f64>()?
                        .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<f64>()?.is_some() {
                    return Err(serde::de::Error::invalid_length(4, &self));
                }
                Ok(AxisValue::PerAxis(out))
            }
        }
        d.deserialize_any(V)
    }
}

/// Accelerometer noise (see the module table; exactly one key per quantity, absent = 0).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccelNoiseConfig {
    /// White-noise PSD, m^2/s^3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub s_n: Option<AxisValue>,
    /// White noise as a density, ug/sqrt(Hz).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub n_ug_per_sqrt_hz: Option<AxisValue>,
    /// White noise as a velocity random walk, m/s/sqrt(h).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vrw_mps_per_sqrt_h: Option<AxisValue>,
    /// Gauss-Markov driving PSD, m^2/s^5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub s_b: Option<AxisValue>,
    /// Gauss-Markov stationary sigma, ug.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gm_sigma_ug: Option<AxisValue>,
    /// Gauss-Markov correlation time, s (required with a Gauss-Markov term; one for all axes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t_b_s: Option<f64>,
    /// Bias random-walk PSD, m^2/s^5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub s_k: Option<AxisValue>,
    /// Bias random walk, ug/sqrt(h).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k_ug_per_sqrt_h: Option<AxisValue>,
    /// Bias random walk as a rate PSD, ug/sqrt(Hz) (= ug/s/sqrt(1/s)).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k_ug_per_sqrt_hz: Option<AxisValue>,
    /// Initial bias sigma, m/s^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_init_sigma: Option<AxisValue>,
    /// Initial bias sigma, ug.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_init_ug: Option<AxisValue>,
}

/// Gyro noise (see the module table; exactly one key per quantity, absent = 0).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GyroNoiseConfig {
    /// White-noise PSD, rad^2/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub s_n: Option<AxisValue>,
    /// White noise as an angle random walk, deg/sqrt(h).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arw_deg_per_sqrt_h: Option<AxisValue>,
    /// White noise as a density, deg/s/sqrt(Hz).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub n_deg_per_s_per_sqrt_hz: Option<AxisValue>,
    /// Gauss-Markov driving PSD, rad^2/s^3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub s_b: Option<AxisValue>,
    /// Gauss-Markov stationary sigma, deg/h.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gm_sigma_deg_per_h: Option<AxisValue>,
    /// Gauss-Markov correlation time, s (required with a Gauss-Markov term; one for all axes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t_b_s: Option<f64>,
    /// Bias random-walk PSD, rad^2/s^3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub s_k: Option<AxisValue>,
    /// Bias random walk, deg/h/sqrt(h).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k_deg_per_h_per_sqrt_h: Option<AxisValue>,
    /// Bias random walk as a rate PSD, deg/s/sqrt(Hz).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k_deg_per_s_per_sqrt_hz: Option<AxisValue>,
    /// Initial bias sigma, rad/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_init_sigma: Option<AxisValue>,
    /// Initial bias sigma, deg/h.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_init_deg_per_h: Option<AxisValue>,
    /// Initial bias sigma, deg/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_init_deg_per_s: Option<AxisValue>,
}

/// A scale-factor error as a first-order Gauss-Markov process.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleNoiseConfig {
    /// Stationary (and initial) sigma, ppm.
    pub sigma_ppm: f64,
    /// Correlation time, s.
    pub t_s: f64,
}

/// Which bias model the filter uses (the source document's two, plus its single-state
/// approximation of the detailed one; DESIGN.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BiasModel {
    /// N: white noise + constant (random-constant) biases.
    N,
    /// NBK: white noise + Gauss-Markov + random walk, separate states.
    #[default]
    Nbk,
    /// NBK with the seed's single bias state (GM and RW noise in one decaying state).
    NbkSingleState,
}

/// The IMU noise model.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseConfig {
    /// Bias model.
    #[serde(default)]
    pub model: BiasModel,
    /// Accelerometer noise.
    #[serde(default)]
    pub accel: AccelNoiseConfig,
    /// Gyro noise.
    #[serde(default)]
    pub gyro: GyroNoiseConfig,
    /// Accelerometer scale-factor states (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accel_scale: Option<ScaleNoiseConfig>,
    /// Gyro scale-factor states (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gyro_scale: Option<ScaleNoiseConfig>,
    /// Factor on the accelerometer and gyro white-noise PSDs (absent: 1), e.g. the
    /// maximum-likelihood factor found by `host-sim diagnose --tune-noise` (vibration in a
    /// vehicle raises the in-run noise above the datasheet's static figure).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub white_noise_scale: Option<f64>,
}

/// Picks the one given alternative (each already converted to SI); 0 when none.
fn one_of(what: &str, alts: &[(&str, Option<[f64; 3]>)]) -> Result<[f64; 3], String> {
    let given: Vec<&(&str, Option<[f64; 3]>)> = alts.iter().filter(|(_, v)| v.is_some()).collect();
    match given.as_slice() {
        [] => Ok([0.0; 3]),
        [(k, Some(v))] => {
            if v.iter().all(|x| x.is_finite() && *x >= 0.0) {
                Ok(*v)
            } else {
                Err(format!("{what}: {k} must be finite and >= 0, got {v:?}"))
            }
        }
        many => Err(format!(
            "{what}: give only one of {:?}",
            many.iter().map(|(k, _)| *k).collect::<Vec<_>>()
        )),
    }
}

fn t_b(what: &str, s_b: [f64; 3], t_b_s: Option<f64>) -> Result<f64, String> {
    match t_b_s {
        Some(t) if t.is_finite() && t > 0.0 => Ok(t),
        Some(t) => Err(format!("{what}.t_b_s must be > 0 s, got {t}")),
        None if s_b.iter().any(|v| *v > 0.0) => {
            Err(format!("{what}: a Gauss-Markov term needs t_b_s"))
        }
        // no Gauss-Markov term: any positive placeholder (unused)
        None => Ok(3600.0),
    }
}

/// The Gauss-Markov PSD from `s_b` or from a stationary sigma (both already in SI).
fn gm_psd(
    w: &str,
    s_b: Option<[f64; 3]>,
    sigma_key: &str,
    sigma: Option<[f64; 3]>,
    t_raw: Option<f64>,
) -> Result<[f64; 3], String> {
    match (s_b, sigma) {
        (Some(_), Some(_)) => Err(format!("{w}: give only one of s_b, {sigma_key}")),
        (Some(v), None) => one_of(w, &[("s_b", Some(v))]),
        (None, Some(sg)) => {
            let t = t_b(w, [1.0; 3], t_raw)?;
            one_of(
                w,
                &[(sigma_key, Some(sg.map(|s| units::gm_psd_from_sigma(s, t))))],
            )
        }
        (None, None) => Ok([0.0; 3]),
    }
}

/// What a key of `[noise.accel]` / `[noise.gyro]` gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Quantity {
    /// White-noise PSD.
    White,
    /// Gauss-Markov driving PSD `s_b`.
    GmPsd,
    /// Gauss-Markov stationary sigma (converted with `t_b_s`).
    GmSigma,
    /// Gauss-Markov correlation time `t_b_s`.
    Tb,
    /// Bias random-walk PSD.
    RandomWalk,
    /// Initial (turn-on) bias sigma.
    BiasInit,
}

/// One key of a sensor's noise table: its name, what it gives, its value as written and the
/// conversion of one value to SI.
type NoiseKey = (&'static str, Quantity, Option<[f64; 3]>, fn(f64) -> f64);

fn si(x: f64) -> f64 {
    x
}

/// The SI parameters from a sensor's keys (one definition for accelerometers and gyros):
/// one alternative per quantity, a Gauss-Markov term by PSD or by stationary sigma, `t_b_s`
/// where a Gauss-Markov term needs it.
fn sensor_noise(w: &str, keys: &[NoiseKey]) -> Result<SensorNoise, String> {
    let alts = |q: Quantity| -> Vec<(&str, Option<[f64; 3]>)> {
        keys.iter()
            .filter(|k| k.1 == q)
            .map(|(name, _, v, to_si)| (*name, v.map(|a| a.map(to_si))))
            .collect()
    };
    let first = |q: Quantity| alts(q).into_iter().next();
    let t_raw = first(Quantity::Tb).and_then(|(_, v)| v).map(|v| v[0]);
    let s_n = one_of(w, &alts(Quantity::White))?;
    let (sigma_key, sigma) = first(Quantity::GmSigma).unwrap_or(("gm_sigma", None));
    let s_b_given = first(Quantity::GmPsd).and_then(|(_, v)| v);
    let s_b = gm_psd(w, s_b_given, sigma_key, sigma, t_raw)?;
    let t_b_s = t_b(w, s_b, t_raw)?;
    let s_k = one_of(w, &alts(Quantity::RandomWalk))?;
    let bias_init_sigma = one_of(w, &alts(Quantity::BiasInit))?;
    Ok(SensorNoise {
        s_n,
        s_b,
        t_b_s,
        s_k,
        bias_init_sigma,
    })
}

fn raw(v: Option<AxisValue>) -> Option<[f64; 3]> {
    v.map(AxisValue::axes)
}

impl AccelNoiseConfig {
    /// The keys of `[noise.accel]`: name, quantity, value, conversion to SI.
    fn keys(&self) -> [NoiseKey; 11] {
        use Quantity::*;
        [
            ("s_n", White, raw(self.s_n), si),
            (
                "n_ug_per_sqrt_hz",
                White,
                raw(self.n_ug_per_sqrt_hz),
                units::accel_psd_from_ug_per_sqrt_hz,
            ),
            (
                "vrw_mps_per_sqrt_h",
                White,
                raw(self.vrw_mps_per_sqrt_h),
                units::accel_psd_from_mps_per_sqrt_h,
            ),
            ("s_b", GmPsd, raw(self.s_b), si),
            (
                "gm_sigma_ug",
                GmSigma,
                raw(self.gm_sigma_ug),
                units::mps2_from_ug,
            ),
            ("t_b_s", Tb, self.t_b_s.map(|t| [t; 3]), si),
            ("s_k", RandomWalk, raw(self.s_k), si),
            (
                "k_ug_per_sqrt_h",
                RandomWalk,
                raw(self.k_ug_per_sqrt_h),
                units::accel_rw_psd_from_ug_per_sqrt_h,
            ),
            (
                "k_ug_per_sqrt_hz",
                RandomWalk,
                raw(self.k_ug_per_sqrt_hz),
                |k| units::mps2_from_ug(k).powi(2),
            ),
            ("bias_init_sigma", BiasInit, raw(self.bias_init_sigma), si),
            (
                "bias_init_ug",
                BiasInit,
                raw(self.bias_init_ug),
                units::mps2_from_ug,
            ),
        ]
    }

    /// The SI parameters (nav-core's [`SensorNoise`]).
    pub fn to_sensor_noise(&self) -> Result<SensorNoise, String> {
        sensor_noise("noise.accel", &self.keys())
    }

    /// Every key with its values (absent: None).
    pub(crate) fn entries(&self) -> [(&'static str, Option<[f64; 3]>); 11] {
        self.keys().map(|(name, _, v, _)| (name, v))
    }
}

impl GyroNoiseConfig {
    /// The keys of `[noise.gyro]`: name, quantity, value, conversion to SI.
    fn keys(&self) -> [NoiseKey; 12] {
        use Quantity::*;
        [
            ("s_n", White, raw(self.s_n), si),
            (
                "arw_deg_per_sqrt_h",
                White,
                raw(self.arw_deg_per_sqrt_h),
                units::gyro_psd_from_deg_per_sqrt_h,
            ),
            (
                "n_deg_per_s_per_sqrt_hz",
                White,
                raw(self.n_deg_per_s_per_sqrt_hz),
                |n| (n * units::DEG).powi(2),
            ),
            ("s_b", GmPsd, raw(self.s_b), si),
            (
                "gm_sigma_deg_per_h",
                GmSigma,
                raw(self.gm_sigma_deg_per_h),
                units::radps_from_deg_per_h,
            ),
            ("t_b_s", Tb, self.t_b_s.map(|t| [t; 3]), si),
            ("s_k", RandomWalk, raw(self.s_k), si),
            (
                "k_deg_per_h_per_sqrt_h",
                RandomWalk,
                raw(self.k_deg_per_h_per_sqrt_h),
                units::gyro_rw_psd_from_deg_per_h_per_sqrt_h,
            ),
            (
                "k_deg_per_s_per_sqrt_hz",
                RandomWalk,
                raw(self.k_deg_per_s_per_sqrt_hz),
                |k| (k * units::DEG).powi(2),
            ),
            ("bias_init_sigma", BiasInit, raw(self.bias_init_sigma), si),
            (
                "bias_init_deg_per_h",
                BiasInit,
                raw(self.bias_init_deg_per_h),
                units::radps_from_deg_per_h,
            ),
            (
                "bias_init_deg_per_s",
                BiasInit,
                raw(self.bias_init_deg_per_s),
                |x| x * units::DEG,
            ),
        ]
    }

    /// The SI parameters (nav-core's [`SensorNoise`]).
    pub fn to_sensor_noise(&self) -> Result<SensorNoise, String> {
        sensor_noise("noise.gyro", &self.keys())
    }

    /// Every key with its values (absent: None).
    pub(crate) fn entries(&self) -> [(&'static str, Option<[f64; 3]>); 12] {
        self.keys().map(|(name, _, v, _)| (name, v))
    }
}

/// White-noise keys: a density of zero there is a sensor trusted absolutely.
const WHITE_KEYS: [&str; 6] = [
    "s_n",
    "n_ug_per_sqrt_hz",
    "vrw_mps_per_sqrt_h",
    "arw_deg_per_sqrt_h",
    "n_deg_per_s_per_sqrt_hz",
    "t_b_s",
];

impl NoiseConfig {
    /// Problems tied to one key, as (table, key, message): values that are not finite,
    /// negative (the TOML keys are densities or sigmas that are squared: a sign would vanish
    /// silently), or zero where zero is meaningless (white noise, correlation time).
    pub fn located_problems(&self) -> Vec<(&'static str, String, String)> {
        let mut out = Vec::new();
        let noise = self
            .accel
            .entries()
            .into_iter()
            .map(|e| ("noise.accel", e))
            .chain(self.gyro.entries().into_iter().map(|e| ("noise.gyro", e)));
        for (table, (key, v)) in noise {
            let Some(v) = v else { continue };
            if let Some(x) = v.iter().find(|x| !x.is_finite() || **x < 0.0) {
                out.push((
                    table,
                    key.to_string(),
                    format!(
                        "{x} is not allowed: noise values are densities or sigmas and must be \
                         finite and >= 0 (the sign would be squared away)"
                    ),
                ));
            } else if v.contains(&0.0) && WHITE_KEYS.contains(&key) {
                out.push((
                    table,
                    key.to_string(),
                    if key == "t_b_s" {
                        "0 is not a correlation time: give t_b_s > 0 or drop the Gauss-Markov term"
                            .to_string()
                    } else {
                        "a white-noise density of 0 makes the filter trust the sensor absolutely: \
                         give the datasheet or `host-sim allan` value"
                            .to_string()
                    },
                ));
            }
        }
        out
    }

    /// Checks the keys together: one key per quantity, a white-noise term on each sensor
    /// (an absent key means 0, but a sensor without white noise is a filter that trusts the
    /// IMU absolutely: an empty `[noise]` section ran silently with zero noise, 26 m
    /// residuals on a rover), valid scale-factor processes. Every problem, in order.
    pub fn problems(&self) -> Vec<String> {
        let mut bad = Vec::new();
        match self.accel.to_sensor_noise() {
            Err(e) => bad.push(e),
            Ok(n) if n.s_n.iter().any(|v| *v <= 0.0) => bad.push(
                "noise.accel: no white noise given (one of s_n, n_ug_per_sqrt_hz, \
                 vrw_mps_per_sqrt_h is required; `host-sim allan` identifies it)"
                    .into(),
            ),
            Ok(_) => {}
        }
        match self.gyro.to_sensor_noise() {
            Err(e) => bad.push(e),
            Ok(n) if n.s_n.iter().any(|v| *v <= 0.0) => bad.push(
                "noise.gyro: no white noise given (one of s_n, arw_deg_per_sqrt_h, \
                 n_deg_per_s_per_sqrt_hz is required; `host-sim allan` identifies it)"
                    .into(),
            ),
            Ok(_) => {}
        }
        for (n, s) in [
            ("accel_scale", &self.accel_scale),
            ("gyro_scale", &self.gyro_scale),
        ] {
            if let Some(s) = s {
                if !(s.sigma_ppm.is_finite()
                    && s.sigma_ppm >= 0.0
                    && s.t_s.is_finite()
                    && s.t_s > 0.0)
                {
                    bad.push(format!("noise.{n}: sigma_ppm >= 0 and t_s > 0 required"));
                }
            }
        }
        bad
    }
}
