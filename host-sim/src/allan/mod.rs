//! Allan statistics (overlapping/modified/Hadamard deviations with confidence intervals) and
//! the noise-model fit of the source document.
pub mod cli;
