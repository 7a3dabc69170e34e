//! The compile-time filter model of the `nav` application: layout, configuration and
//! dimension (cargo features `model-n` 15 states, `model-nbk` 18, `model-kf-gins` 21).

use nav_core::config::FilterConfig;
use nav_core::model::Layout;

#[cfg(any(
    all(feature = "model-n", feature = "model-nbk"),
    all(feature = "model-n", feature = "model-kf-gins"),
    all(feature = "model-nbk", feature = "model-kf-gins"),
))]
compile_error!("choose exactly one of the features model-n, model-nbk, model-kf-gins");

/// The state layout.
#[cfg(feature = "model-n")]
pub const LAYOUT: Layout = nav_core::model::LAYOUT_N;
/// The state layout.
#[cfg(feature = "model-nbk")]
pub const LAYOUT: Layout = nav_core::model::LAYOUT_NBK;
/// The state layout.
#[cfg(feature = "model-kf-gins")]
pub const LAYOUT: Layout = nav_core::model::LAYOUT_KF_GINS;
#[cfg(not(any(feature = "model-n", feature = "model-nbk", feature = "model-kf-gins")))]
compile_error!("choose one of the features model-n, model-nbk, model-kf-gins");

/// Number of error states.
pub const N: usize = LAYOUT.dim();

/// The noise configuration of the model.
pub fn config() -> FilterConfig {
    #[cfg(feature = "model-n")]
    return FilterConfig::source_n_model();
    #[cfg(not(feature = "model-n"))]
    return FilterConfig::source_nbk_model();
}
