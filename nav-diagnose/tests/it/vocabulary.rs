//! The diagnosis's vocabulary against the undeclared-drive generator's effects.

use nav_sim::undeclared::Effect;

/// Every effect the undeclared-drive generator can add has a name the diagnosis knows: a
/// model block of nav-core, one of the diagnosis's bias-step sensors or the GNSS noise scale
/// (a factor of the noise model, written as `[gnss] sigma_scale`).
#[test]
fn block_names_are_the_filter_vocabulary() {
    use nav_core::model::{Block, EFFECT_BLOCKS};
    for e in Effect::ALL {
        if matches!(e, Effect::AccelBiasStep | Effect::GyroBiasStep) {
            let steps = nav_diagnose::changepoint::BiasStepSensor::ALL.map(|s| s.name());
            assert!(steps.contains(&e.block_name()), "{e}");
            continue;
        }
        if e == Effect::GnssWhiteNoise {
            // not a block: the noise model's factor on the fixes' sigmas (`Diagnosis::
            // final_gnss_sigma_scale`), judged by its size in the sweep of diagnose_heldout.rs
            continue;
        }
        let known = EFFECT_BLOCKS
            .iter()
            .chain(&[Block::GyroScaleFactor, Block::AccelScaleFactor])
            .any(|b| b.name() == e.block_name());
        assert!(known, "{e}");
    }
}
