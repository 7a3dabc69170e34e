//! Command-line parsing of the library crates' option enums (`nav_engine::run::Model`,
//! `nav_io::ImuClassName`, the `noise_id` units and deviations). The libraries name their
//! values with `FromStr`, `Display` and `strum::VariantNames` and do not depend on clap; the
//! command line turns those names into clap's possible values here.

use clap::builder::{PossibleValuesParser, TypedValueParser};
use std::str::FromStr;
use strum::VariantNames;

/// A clap value parser for an option enum of a library crate: its names are the possible
/// values (listed in `--help`, and in the error for a value that is not one of them), each
/// parsed with the enum's `FromStr`.
pub fn parser<T>() -> impl TypedValueParser<Value = T>
where
    T: FromStr + VariantNames + Clone + Send + Sync + 'static,
    T::Err: std::error::Error + Send + Sync + 'static,
{
    PossibleValuesParser::new(T::VARIANTS.iter().copied()).try_map(|s| s.parse::<T>())
}
