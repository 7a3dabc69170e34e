//! The study's simulated world: the truth error model (the source's identified IMU), the two
//! filter models, the initial errors, and the error sources of the budget (each switchable on
//! its own, with the same random streams).

use nav_core::config::FilterConfig;
use nav_core::filter::InitialUncertainty;
use nav_engine::run::{InitSpec, Model};
use nav_sim::errors::{Axes3, ErrorModel, DEG_PER_H_RADPS, UG_MPS2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

/// Accelerometer turn-on bias of the simulated IMU (1-sigma per axis), ug. The source gives
/// none; 25 ug is a typical run-to-run value of a tactical servo accelerometer whose bias
/// instability is 2.2 ug (the `seed-nbk` preset's value).
pub const ACCEL_TURN_ON_UG: f64 = 25.0;
/// Gyro turn-on bias of the simulated IMU (1-sigma per axis), deg/h: the manufacturer's gyro
/// bias specification (< 0.1 deg/h, Appendix V).
pub const GYRO_TURN_ON_DEG_PER_H: f64 = 0.1;

/// GNSS position error (white, 1-sigma N, E, D), m: RTK level, also reported with each fix.
pub const GNSS_SIGMA_NED_M: [f64; 3] = [0.01, 0.01, 0.02];

/// Initial uncertainty told to the filter, and the 1-sigma of the initial errors drawn per run
/// (the filter starts from the truth plus these errors, 3 minutes into a static period's
/// start): roll/pitch 0.02 deg, heading 0.5 deg, velocity 0.01 m/s, position 0.02 m.
pub fn initial_uncertainty() -> InitialUncertainty {
    let d = std::f64::consts::PI / 180.0;
    InitialUncertainty {
        att_sigma_rad: [0.02 * d, 0.02 * d, 0.5 * d],
        vel_sigma_mps: [0.01; 3],
        pos_sigma_m: [0.02, 0.02, 0.02],
    }
}

/// One independent error source of the simulation (the budget switches them one at a time).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Gyro white noise (angle random walk), S_N = 5.3079e-10 rad^2/s.
    GyroWhite,
    /// Gyro turn-on bias (random constant).
    GyroBias,
    /// Accelerometer white noise (velocity random walk), S_N = 6.2865e-9 m^2/s^3.
    AccelWhite,
    /// Accelerometer first-order Gauss-Markov bias, S_B = 2.4360e-11 m^2/s^5, T_B = 45 s.
    AccelFogm,
    /// Accelerometer random-walk bias, S_K = 2.6731e-12 m^2/s^5.
    AccelRw,
    /// Accelerometer turn-on bias (random constant).
    AccelBias,
    /// GNSS position errors (white, RTK level).
    Gnss,
    /// Errors of the initial state (drawn with the filter's initial uncertainty).
    Init,
}

impl Source {
    /// All sources, gyro first.
    pub const ALL: [Source; 8] = [
        Source::GyroWhite,
        Source::GyroBias,
        Source::AccelWhite,
        Source::AccelFogm,
        Source::AccelRw,
        Source::AccelBias,
        Source::Gnss,
        Source::Init,
    ];

    /// Short label for tables and plots.
    pub fn label(self) -> &'static str {
        match self {
            Self::GyroWhite => "gyro white noise",
            Self::GyroBias => "gyro turn-on bias",
            Self::AccelWhite => "accel white noise",
            Self::AccelFogm => "accel FOGM bias",
            Self::AccelRw => "accel random-walk bias",
            Self::AccelBias => "accel turn-on bias",
            Self::Gnss => "GNSS errors",
            Self::Init => "initial-state errors",
        }
    }

    /// Whether the source is a gyro error.
    pub fn is_gyro(self) -> bool {
        matches!(self, Self::GyroWhite | Self::GyroBias)
    }

    /// Whether the source is an accelerometer error.
    pub fn is_accel(self) -> bool {
        matches!(
            self,
            Self::AccelWhite | Self::AccelFogm | Self::AccelRw | Self::AccelBias
        )
    }
}

/// Which sources a run has switched on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sources {
    /// Every source.
    All,
    /// Only this one.
    Only(Source),
}

impl Sources {
    /// Whether `s` is on.
    pub fn has(self, s: Source) -> bool {
        match self {
            Self::All => true,
            Self::Only(o) => o == s,
        }
    }
}

/// The simulated sensor errors: the `seed-nbk` preset (the source's Appendix V parameters,
/// no quantization) with the turn-on biases stated above and white RTK GNSS errors
/// ([`GNSS_SIGMA_NED_M`]).
pub fn truth_errors() -> ErrorModel {
    let mut m = ErrorModel::preset("seed-nbk").unwrap_or_else(|_| unreachable_preset());
    m.name = "study: seed-nbk (Appendix V)".into();
    m.accel.turn_on_bias_sigma = Axes3::splat(ACCEL_TURN_ON_UG * UG_MPS2);
    m.gyro.turn_on_bias_sigma = Axes3::splat(GYRO_TURN_ON_DEG_PER_H * DEG_PER_H_RADPS);
    m.accel.quantization_step = Axes3::splat(0.0);
    m.gyro.quantization_step = Axes3::splat(0.0);
    // RTK-level GNSS as the source has it: white errors of the sigma the fixes report (the
    // filter models GNSS errors as white; the preset's time-correlated part would add an
    // unmodelled error unrelated to the bias models under study)
    m.gnss.white_sigma_ned_m = Axes3(GNSS_SIGMA_NED_M);
    m.gnss.gm_sigma_ned_m = Axes3::splat(0.0);
    m.gnss.reported_std_ned_m = Some(Axes3(GNSS_SIGMA_NED_M));
    m
}

fn unreachable_preset() -> ErrorModel {
    // `seed-nbk` is a built-in preset; this is never reached.
    ErrorModel {
        name: String::new(),
        accel: Default::default(),
        gyro: Default::default(),
        temperature: None,
        gnss: Default::default(),
        imu_clock_drift_ppm: 0.0,
    }
}

/// The truth error model with only the sources in `on` (same random streams for each source
/// whatever else is on: `sim::errors::stream`).
pub fn errors_with(on: Sources) -> ErrorModel {
    let mut m = truth_errors();
    let zero = Axes3::splat(0.0);
    if !on.has(Source::GyroWhite) {
        m.gyro.white_psd = zero;
    }
    if !on.has(Source::GyroBias) {
        m.gyro.turn_on_bias_sigma = zero;
    }
    if !on.has(Source::AccelWhite) {
        m.accel.white_psd = zero;
    }
    if !on.has(Source::AccelFogm) {
        m.accel.gm_psd = zero;
    }
    if !on.has(Source::AccelRw) {
        m.accel.rw_psd = zero;
    }
    if !on.has(Source::AccelBias) {
        m.accel.turn_on_bias_sigma = zero;
    }
    if !on.has(Source::Gnss) {
        m.gnss.white_sigma_ned_m = zero;
    }
    m
}

/// A filter variant of the study: a state layout ([`Model`]) with its noise configuration.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Hash,
    Serialize,
    strum::EnumString,
    strum::Display,
    strum::VariantNames,
)]
#[serde(rename_all = "kebab-case")]
#[strum(serialize_all = "kebab-case")]
pub enum Variant {
    /// The source's N model: manufacturer white noise (accelerometer 50 ug/sqrt(Hz), gyro
    /// 0.15 deg/sqrt(h)), constant biases (15 states).
    N,
    /// The source's NBK model with the identified parameters, separate Gauss-Markov and
    /// random-walk accelerometer bias states (18 states).
    Nbk,
    /// The source's NBK model as printed: one accelerometer bias state decaying with 1/T_B,
    /// driven by S_B + S_K (15 states).
    NbkSingle,
    /// A diagnostic: the N model's accelerometer (50 ug/sqrt(Hz), constant bias) with the
    /// identified gyro white noise (0.079 deg/sqrt(h)), to separate the gyro specification
    /// from the accelerometer bias model in the N-NBK difference.
    NIdGyro,
}

impl Variant {
    /// Every variant.
    pub const ALL: [Variant; 4] = [
        Variant::N,
        Variant::Nbk,
        Variant::NbkSingle,
        Variant::NIdGyro,
    ];

    /// The state layout.
    pub fn model(self) -> Model {
        match self {
            Self::N | Self::NIdGyro => Model::N,
            Self::Nbk => Model::Nbk,
            Self::NbkSingle => Model::NbkSingle,
        }
    }

    /// Display name.
    pub fn label(self) -> &'static str {
        match self {
            Self::N => "N",
            Self::Nbk => "NBK",
            Self::NbkSingle => "NBK-single",
            Self::NIdGyro => "N+id.gyro",
        }
    }

    /// The filter configuration: the source's N model (manufacturer white noise
    /// 50 ug/sqrt(Hz), 0.15 deg/sqrt(h); constant biases) or NBK model (identified
    /// parameters), with the initial bias sigmas equal to the simulated turn-on biases (so every
    /// model is told the truth about the turn-on; they differ only in the noise model, as in
    /// the source).
    pub fn config(self) -> FilterConfig {
        let mut c = match self {
            Self::N => FilterConfig::source_n_model(),
            Self::NIdGyro => {
                let mut c = FilterConfig::source_n_model();
                c.gyro.s_n = FilterConfig::source_nbk_model().gyro.s_n;
                c
            }
            Self::Nbk | Self::NbkSingle => FilterConfig::source_nbk_model(),
        };
        c.accel.bias_init_sigma = [ACCEL_TURN_ON_UG * UG_MPS2; 3];
        c.gyro.bias_init_sigma = [GYRO_TURN_ON_DEG_PER_H * DEG_PER_H_RADPS; 3];
        c
    }
}

/// The initial state of run `seed`: the truth plus errors drawn from [`initial_uncertainty`]
/// (own random stream; zero when the `Init` source is off).
pub fn init_spec(seed: u64, on: Sources) -> InitSpec {
    let unc = initial_uncertainty();
    let mut e = [[0.0f64; 3]; 3];
    if on.has(Source::Init) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(0x5354_5544_5900_0001); // "STUDY" init stream
        for (row, sig) in e
            .iter_mut()
            .zip([unc.att_sigma_rad, unc.vel_sigma_mps, unc.pos_sigma_m])
        {
            for (x, s) in row.iter_mut().zip(sig) {
                let z: f64 = StandardNormal.sample(&mut rng);
                *x = s * z;
            }
        }
    }
    InitSpec::FromTruth {
        pos_err_m: e[2],
        vel_err_mps: e[1],
        att_err_rad: e[0],
        unc,
    }
}
