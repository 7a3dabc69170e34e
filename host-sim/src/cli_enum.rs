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

#[cfg(test)]
mod tests {
    use super::parser;
    use clap::Parser;
    use nav_engine::run::Model;

    #[derive(Parser, Debug)]
    struct Args {
        #[arg(long, value_parser = parser::<Model>(), default_value = "nbk")]
        model: Model,
    }

    #[test]
    fn names_parse_to_their_variant_and_others_are_refused_with_the_list() {
        let a = Args::try_parse_from(["x", "--model", "kf-gins-feedback"]).unwrap();
        assert_eq!(a.model, Model::KfGinsFeedback);
        assert_eq!(Args::try_parse_from(["x"]).unwrap().model, Model::Nbk);
        let e = Args::try_parse_from(["x", "--model", "kf"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("kf-gins, kf-gins-feedback"), "{e}");
        for name in <Model as strum::VariantNames>::VARIANTS {
            let m: Model = name.parse().unwrap();
            assert_eq!(m.name(), *name);
            assert_eq!(m.to_string(), *name);
        }
    }
}
