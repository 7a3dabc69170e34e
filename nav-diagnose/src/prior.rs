//! Which effect blocks a base model lacks, and how a candidate is put into the model.
//!
//! A block is a candidate when the model does not carry it, or carries it FROZEN: every state
//! with zero initial variance and zero driving noise. A KF-GINS YAML with `gsstd`, `asstd`,
//! `initsgstd`, `initsastd` = 0 declares "no scale factor" this way: the 21-state layout keeps
//! the states, but they can never move. The diagnosis treats such a block as absent and, as a
//! candidate, frees it ([`free`]): scale factors get the project's default prior (1000 ppm,
//! Gauss-Markov with the configured correlation time, at least 1 h), other effect blocks the
//! default priors of [`nav_core::config::EffectsConfig`].
//!
//! `imu_clock_drift` (a time offset with a rate) and `time_offset` are the same kind of state:
//! a model that carries one does not get the other as a candidate; `gnss_position_gm` is
//! frozen when its sigmas are all zero.
use nav_core::config::{EffectsConfig, FilterConfig, ScaleFactorNoise};
use nav_core::model::{Block, EFFECT_BLOCKS};

use nav_engine::run::{CaseData, RunOptions};

/// Prior 1-sigma of a freed scale-factor block, ppm.
pub const FREED_SCALE_SIGMA_PPM: f64 = 1000.0;
/// Smallest correlation time of a freed scale-factor block, s.
pub const FREED_SCALE_MIN_T_S: f64 = 3600.0;

fn zero(v: &[f64]) -> bool {
    v.iter().all(|x| *x == 0.0)
}

fn effect_noise_mut(e: &mut EffectsConfig, b: Block) -> Option<&mut nav_core::config::EffectNoise> {
    Some(match b {
        Block::AccelMisalignment => &mut e.accel_misalignment,
        Block::GyroMisalignment => &mut e.gyro_misalignment,
        Block::LeverArm => &mut e.lever_arm,
        Block::TimeOffset => &mut e.time_offset,
        Block::ImuClockDrift => &mut e.imu_clock_drift,
        Block::AccelTemperatureBias => &mut e.accel_temperature,
        Block::GyroTemperatureBias => &mut e.gyro_temperature,
        Block::GyroGSensitivity => &mut e.gyro_g_sensitivity,
        _ => return None,
    })
}

/// Whether the filter configuration freezes block `b`: zero initial sigma and zero driving
/// noise on every state (scale factors: a zero stationary sigma on every axis).
pub fn frozen_in(cfg: &FilterConfig, b: Block) -> bool {
    match b {
        Block::GyroScaleFactor => zero(&cfg.gyro_scale.sigma),
        Block::AccelScaleFactor => zero(&cfg.accel_scale.sigma),
        Block::GnssPositionGm => zero(&cfg.effects.gnss_position_gm.sigma_m),
        other => {
            let mut e = cfg.effects;
            effect_noise_mut(&mut e, other).is_some_and(|n| n.init_sigma == 0.0 && n.rw_psd == 0.0)
        }
    }
}

/// Whether the run's model carries block `b` or one of its kind (in its layout or as an
/// extra block: `imu_clock_drift` carries the time offset).
pub fn carried(opts: &RunOptions, b: Block) -> bool {
    opts.model.layout().contains(b.kind()) || opts.extra_blocks.iter().any(|e| e.kind() == b.kind())
}

/// Whether the run's model carries block `b` frozen ([`frozen_in`]): declared absent.
pub fn is_frozen(opts: &RunOptions, b: Block) -> bool {
    carried(opts, b) && frozen_in(&opts.filter, b)
}

/// Gives a frozen block its default prior (see the module notes).
pub fn free(opts: &mut RunOptions, b: Block) {
    let sf = |s: &ScaleFactorNoise| ScaleFactorNoise {
        sigma: [FREED_SCALE_SIGMA_PPM * 1e-6; 3],
        t_s: s.t_s.max(FREED_SCALE_MIN_T_S),
    };
    match b {
        Block::GyroScaleFactor => opts.filter.gyro_scale = sf(&opts.filter.gyro_scale),
        Block::AccelScaleFactor => opts.filter.accel_scale = sf(&opts.filter.accel_scale),
        Block::GnssPositionGm => {
            opts.filter.effects.gnss_position_gm = EffectsConfig::default().gnss_position_gm;
        }
        other => {
            let d = EffectsConfig::default();
            let mut dd = d;
            if let (Some(dst), Some(src)) = (
                effect_noise_mut(&mut opts.filter.effects, other),
                effect_noise_mut(&mut dd, other),
            ) {
                *dst = *src;
            }
            if matches!(other, Block::TimeOffset | Block::ImuClockDrift) {
                // the acceptance window of add_effect_block
                opts.add_effect_block(other);
            }
        }
    }
}

/// Puts candidate `b` into the model: frees it when it is carried frozen, else appends it
/// ([`RunOptions::add_effect_block`]).
pub fn apply(opts: &mut RunOptions, b: Block) {
    if is_frozen(opts, b) {
        free(opts, b);
    } else if !carried(opts, b) {
        opts.add_effect_block(b);
    }
}

/// Options of a run with `blocks` put into the model ([`apply`]).
pub fn options_with(base: &RunOptions, blocks: &[Block]) -> RunOptions {
    let mut o = base.clone();
    for &b in blocks {
        apply(&mut o, b);
    }
    o
}

/// The block an added block is upgraded from when candidate `b` joins the model of the
/// effect blocks `added`: the IMU clock drift (an offset with a rate) takes the place of an
/// added time offset, the one-parameter model nested in it (the two are one state of the
/// filter, [`carried`]: appended beside the offset the drift would change nothing). None: `b`
/// is appended.
pub fn upgrades(added: &[Block], b: Block) -> Option<Block> {
    (b == Block::ImuClockDrift && added.contains(&Block::TimeOffset)).then_some(Block::TimeOffset)
}

/// Whether candidate `b` is nested in a block of `added` (a time offset beside an added clock
/// drift, which carries the offset): not a candidate.
pub fn nested_in(added: &[Block], b: Block) -> bool {
    b == Block::TimeOffset && added.contains(&Block::ImuClockDrift)
}

/// The effect blocks of the model `added` with candidate `b`: appended, or in the place of the
/// block it upgrades ([`upgrades`]).
pub fn with_candidate(added: &[Block], b: Block) -> Vec<Block> {
    match upgrades(added, b) {
        Some(old) => added
            .iter()
            .map(|&x| if x == old { b } else { x })
            .collect(),
        None => {
            let mut v = added.to_vec();
            v.push(b);
            v
        }
    }
}

/// The parameters candidate `b` adds to the model `added` (its BIC penalty's count): its
/// dimension, less the dimension of the block it upgrades ([`upgrades`]).
pub fn added_params(added: &[Block], b: Block) -> usize {
    b.dim()
        .saturating_sub(upgrades(added, b).map_or(0, |o| o.dim()))
}

/// The candidates for a case and base model: every effect block the model does not carry or
/// carries frozen; the temperature blocks only when some IMU sample carries a temperature.
pub fn candidates(case: &CaseData, opts: &RunOptions) -> Vec<Block> {
    let has_temp = case.imu.iter().any(|s| s.temperature_c.is_finite());
    candidates_with(has_temp, opts)
}

/// [`candidates`] for IMU data that carry a temperature (`has_temp`) or not.
pub fn candidates_with(has_temp: bool, opts: &RunOptions) -> Vec<Block> {
    EFFECT_BLOCKS
        .iter()
        .copied()
        .filter(|&b| !carried(opts, b) || is_frozen(opts, b))
        .filter(|b| {
            has_temp || !matches!(b, Block::AccelTemperatureBias | Block::GyroTemperatureBias)
        })
        .collect()
}

/// The extra state count a candidate adds (0 when it is freed in place).
pub fn added_dim(opts: &RunOptions, b: Block) -> usize {
    if carried(opts, b) {
        0
    } else {
        b.dim()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nav_core::filter::InitialUncertainty;
    use nav_engine::run::{InitSpec, Model};

    fn init() -> InitSpec {
        InitSpec::FromTruth {
            pos_err_m: [0.0; 3],
            vel_err_mps: [0.0; 3],
            att_err_rad: [0.0; 3],
            unc: InitialUncertainty {
                att_sigma_rad: [1e-3; 3],
                vel_sigma_mps: [0.1; 3],
                pos_sigma_m: [0.1; 3],
            },
        }
    }

    #[test]
    fn a_clock_drift_takes_the_place_of_an_added_time_offset() {
        let o = RunOptions::new(Model::Nbk, FilterConfig::source_nbk_model(), init());
        let added = [Block::LeverArm, Block::TimeOffset];
        let cur = options_with(&o, &added);
        // appended beside the offset the drift is the same state: the model unchanged
        assert_eq!(
            options_with(&cur, &[Block::ImuClockDrift]).extra_blocks,
            cur.extra_blocks
        );
        let with = with_candidate(&added, Block::ImuClockDrift);
        assert_eq!(with, vec![Block::LeverArm, Block::ImuClockDrift]);
        assert_eq!(
            options_with(&o, &with).extra_blocks,
            vec![Block::LeverArm, Block::ImuClockDrift]
        );
        assert_eq!(
            upgrades(&added, Block::ImuClockDrift),
            Some(Block::TimeOffset)
        );
        // one parameter more than the offset: the rate
        assert_eq!(added_params(&added, Block::ImuClockDrift), 1);
        assert_eq!(added_params(&[Block::LeverArm], Block::ImuClockDrift), 2);
        // other candidates are appended; an offset beside an added drift is no candidate
        assert_eq!(
            with_candidate(&added, Block::GyroScaleFactor),
            vec![Block::LeverArm, Block::TimeOffset, Block::GyroScaleFactor]
        );
        assert!(nested_in(&[Block::ImuClockDrift], Block::TimeOffset));
        assert!(!nested_in(&added, Block::ImuClockDrift));
    }

    #[test]
    fn frozen_kf_gins_scale_factors_are_candidates_and_freed_in_place() {
        let mut f = FilterConfig::source_nbk_model();
        f.gyro_scale.sigma = [0.0; 3];
        f.accel_scale.sigma = [0.0; 3];
        let o = RunOptions::new(Model::KfGins21, f, init());
        let c = candidates(&CaseData::default(), &o);
        assert!(c.contains(&Block::GyroScaleFactor) && c.contains(&Block::AccelScaleFactor));
        assert_eq!(added_dim(&o, Block::GyroScaleFactor), 0);
        let o2 = options_with(&o, &[Block::GyroScaleFactor]);
        assert!(o2.extra_blocks.is_empty());
        assert_eq!(o2.filter.gyro_scale.sigma, [1e-3; 3]);
        assert!(o2.filter.gyro_scale.t_s >= FREED_SCALE_MIN_T_S);
        assert!(frozen_in(&o2.filter, Block::AccelScaleFactor));
        // a declared (non-zero) scale factor is not a candidate
        let o3 = RunOptions::new(Model::KfGins21, FilterConfig::source_nbk_model(), init());
        assert!(!candidates(&CaseData::default(), &o3).contains(&Block::GyroScaleFactor));
        // an NBK model lacks them: appended
        let o4 = RunOptions::new(Model::Nbk, FilterConfig::source_nbk_model(), init());
        assert_eq!(added_dim(&o4, Block::GyroScaleFactor), 3);
        assert_eq!(
            options_with(&o4, &[Block::GyroScaleFactor]).extra_blocks,
            vec![Block::GyroScaleFactor]
        );
    }
}
