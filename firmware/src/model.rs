//! The compile-time filter model of the `nav` application: the model type (its layout),
//! configuration and dimension (cargo features `model-n` 15 states, `model-nbk` 18, `model-kf-gins` 21).

use nav_core::config::FilterConfig;
use nav_core::model::StateModel;

#[cfg(any(
    all(feature = "model-n", feature = "model-nbk"),
    all(feature = "model-n", feature = "model-kf-gins"),
    all(feature = "model-nbk", feature = "model-kf-gins"),
))]
compile_error!("choose exactly one of the features model-n, model-nbk, model-kf-gins");

/// The filter model: its type carries the state layout (`nav_core::model::StateModel`).
#[cfg(feature = "model-n")]
pub type Model = nav_core::model::ModelN;
/// The filter model: its type carries the state layout (`nav_core::model::StateModel`).
#[cfg(feature = "model-nbk")]
pub type Model = nav_core::model::ModelNbk;
/// The filter model: its type carries the state layout (`nav_core::model::StateModel`).
#[cfg(feature = "model-kf-gins")]
pub type Model = nav_core::model::ModelKfGins;
#[cfg(not(any(feature = "model-n", feature = "model-nbk", feature = "model-kf-gins")))]
compile_error!("choose one of the features model-n, model-nbk, model-kf-gins");

/// Number of error states (the model's dimension).
pub const N: usize = Model::DIM;

/// The noise configuration of the model.
pub fn config() -> FilterConfig {
    #[cfg(feature = "model-n")]
    return FilterConfig::source_n_model();
    #[cfg(not(feature = "model-n"))]
    return FilterConfig::source_nbk_model();
}
