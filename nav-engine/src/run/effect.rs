//! The names of the effect vocabulary ([`nav_core::model::EFFECT_BLOCKS`]) as an option type:
//! [`Effect`] parses with `FromStr` (an unknown name is an [`UnknownEffect`] listing the valid
//! ones) and prints with `Display`, as the other option enums do; the command lines turn it
//! into clap values.

use nav_core::model::Block;
use std::fmt;
use std::str::FromStr;

/// One effect block of the vocabulary appended to a model (`--effects`, `effects = [...]`,
/// what `host-sim diagnose` adds), named as [`Block::name`] names it.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Hash,
    strum::Display,
    strum::IntoStaticStr,
    strum::VariantNames,
    strum::VariantArray,
)]
#[strum(serialize_all = "snake_case")]
pub enum Effect {
    /// Accelerometer scale factors (3 states, dimensionless).
    AccelScaleFactor,
    /// Gyro scale factors (3 states, dimensionless).
    GyroScaleFactor,
    /// Accelerometer axis misalignment (6 states, rad).
    AccelMisalignment,
    /// Gyro axis misalignment (6 states, rad).
    GyroMisalignment,
    /// GNSS antenna lever arm (3 states, m).
    LeverArm,
    /// IMU-to-GNSS time offset (1 state, s).
    TimeOffset,
    /// Accelerometer bias temperature coefficients (3 states, m/s^2/degC).
    AccelTemperatureBias,
    /// Gyro bias temperature coefficients (3 states, rad/s/degC).
    GyroTemperatureBias,
    /// Gyro g-sensitivity (3 states, rad/s/(m/s^2)).
    GyroGSensitivity,
    /// IMU clock offset and drift (2 states: s, s/s).
    ImuClockDrift,
    /// Time-correlated GNSS position error (3 states, m).
    GnssPositionGm,
}

impl Effect {
    /// The model block this effect appends.
    pub const fn block(self) -> Block {
        match self {
            Self::AccelScaleFactor => Block::AccelScaleFactor,
            Self::GyroScaleFactor => Block::GyroScaleFactor,
            Self::AccelMisalignment => Block::AccelMisalignment,
            Self::GyroMisalignment => Block::GyroMisalignment,
            Self::LeverArm => Block::LeverArm,
            Self::TimeOffset => Block::TimeOffset,
            Self::AccelTemperatureBias => Block::AccelTemperatureBias,
            Self::GyroTemperatureBias => Block::GyroTemperatureBias,
            Self::GyroGSensitivity => Block::GyroGSensitivity,
            Self::ImuClockDrift => Block::ImuClockDrift,
            Self::GnssPositionGm => Block::GnssPositionGm,
        }
    }

    /// The effect of an effect block ([`nav_core::model::EFFECT_BLOCKS`]); `None` for the
    /// other blocks.
    pub fn from_block(b: Block) -> Option<Self> {
        <Self as strum::VariantArray>::VARIANTS
            .iter()
            .copied()
            .find(|e| e.block() == b)
    }

    /// The effect names joined with `,` (as `--effects` takes them).
    pub fn join(effects: &[Self]) -> String {
        effects
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join(",")
    }
}

impl From<Effect> for Block {
    fn from(e: Effect) -> Self {
        e.block()
    }
}

/// A name that is not one of the effect vocabulary's.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownEffect {
    /// The name given.
    pub name: String,
}

impl fmt::Display for UnknownEffect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names = <Effect as strum::VariantNames>::VARIANTS;
        write!(
            f,
            "`{}` is not an effect name; the effects are {}",
            self.name,
            names.join(", ")
        )?;
        if let Some(hint) = nav_io::did_you_mean(&self.name, names.iter().copied()) {
            write!(f, "; {hint}")?;
        }
        Ok(())
    }
}

impl std::error::Error for UnknownEffect {}

impl FromStr for Effect {
    type Err = UnknownEffect;

    /// Parses an effect name ([`Block::name`] of one of [`nav_core::model::EFFECT_BLOCKS`]);
    /// surrounding blanks are ignored.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let name = s.trim();
        <Self as strum::VariantArray>::VARIANTS
            .iter()
            .copied()
            .find(|e| <&'static str>::from(*e) == name)
            .ok_or_else(|| UnknownEffect {
                name: name.to_string(),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nav_core::model::EFFECT_BLOCKS;
    use strum::VariantArray;

    #[test]
    fn the_effects_are_the_effect_blocks_in_order_with_their_names() {
        assert_eq!(Effect::VARIANTS.len(), EFFECT_BLOCKS.len());
        for (e, b) in Effect::VARIANTS.iter().zip(EFFECT_BLOCKS) {
            assert_eq!(e.block(), b);
            assert_eq!(e.to_string(), b.name());
            assert_eq!(b.name().parse::<Effect>(), Ok(*e));
            assert_eq!(Effect::from_block(b), Some(*e));
        }
        assert_eq!(" lever_arm ".parse::<Effect>(), Ok(Effect::LeverArm));
        assert_eq!(Effect::from_block(Block::Core), None);
    }

    #[test]
    fn an_unknown_name_lists_the_valid_ones_and_suggests_the_nearest() {
        let e = "lever_arms".parse::<Effect>().unwrap_err().to_string();
        assert!(e.contains("`lever_arms` is not an effect name"), "{e}");
        assert!(e.contains("accel_scale_factor, gyro_scale_factor"), "{e}");
        assert!(e.contains("did you mean `lever_arm`?"), "{e}");
        let e = "wind".parse::<Effect>().unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
    }
}
