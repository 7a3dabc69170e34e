//! The command line's value parsers (`cli_enum::parser`, the simulator's `START:DURATION`
//! outage, `host-sim study --budget-models`), the HTML report's base64 encoder and the plots'
//! log-axis tick labels, through the library's public API.
use clap::Parser;
use host_sim::cli_enum::parser;
use host_sim::sim::cli::parse_outage;
use host_sim::study::{base64, StudyArgs};
use nav_engine::run::Model;
use nav_study::setup::Variant;

#[derive(Parser, Debug)]
struct ModelArgs {
    #[arg(long, value_parser = parser::<Model>(), default_value = "nbk")]
    model: Model,
}

#[test]
fn names_parse_to_their_variant_and_others_are_refused_with_the_list() {
    let a = ModelArgs::try_parse_from(["x", "--model", "kf-gins-feedback"]).unwrap();
    assert_eq!(a.model, Model::KfGinsFeedback);
    assert_eq!(ModelArgs::try_parse_from(["x"]).unwrap().model, Model::Nbk);
    let e = ModelArgs::try_parse_from(["x", "--model", "kf"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("kf-gins, kf-gins-feedback"), "{e}");
    for name in <Model as strum::VariantNames>::VARIANTS {
        let m: Model = name.parse().unwrap();
        assert_eq!(m.name(), *name);
        assert_eq!(m.to_string(), *name);
    }
}

#[test]
fn outage_argument_parses_and_rejects_garbage() {
    let o = parse_outage("600:300").unwrap();
    assert_eq!((o.start_s, o.duration_s), (600.0, 300.0));
    assert!(parse_outage("600").is_err());
    assert!(parse_outage("a:3").is_err());
    assert!(parse_outage("10:-3").is_err());
}

#[test]
fn base64_matches_rfc4648_vectors() {
    for (a, b) in [
        ("", ""),
        ("f", "Zg=="),
        ("fo", "Zm8="),
        ("foo", "Zm9v"),
        ("foob", "Zm9vYg=="),
        ("fooba", "Zm9vYmE="),
        ("foobar", "Zm9vYmFy"),
    ] {
        assert_eq!(base64(a.as_bytes()), b);
    }
}

#[derive(Parser)]
struct StudyCli {
    #[command(flatten)]
    study: StudyArgs,
}

fn budget(args: &[&str]) -> Vec<Variant> {
    let argv = std::iter::once("study").chain(args.iter().copied());
    StudyCli::try_parse_from(argv).unwrap().study.budget_models
}

#[test]
fn budget_models_default_list_and_none() {
    assert_eq!(budget(&[]), [Variant::Nbk, Variant::N]);
    assert_eq!(
        budget(&["--budget-models", "nbk-single,n-id-gyro"]),
        [Variant::NbkSingle, Variant::NIdGyro]
    );
    assert!(budget(&["--budget-models"]).is_empty());
    assert!(StudyCli::try_parse_from(["study", "--budget-models", "kbn"]).is_err());
}

/// The tick labels of a log axis drawn on log10 of the values: whole powers of ten as `1eN`
/// (a zero computed as -0.0 is `1e0`, not `1e-0`), two decimals between 0.01 and 1000, two
/// significant digits outside.
#[test]
fn log_axis_tick_labels_name_the_value() {
    use host_sim::png::pow10_label;
    for (v, want) in [
        (0.0, "1e0"),
        (-0.0, "1e0"),
        (-1e-12, "1e0"),
        (2.0, "1e2"),
        (-3.0, "1e-3"),
        (0.2, "1.58"),
        (-0.5, "0.32"),
        (-2.5, "3.2e-3"),
        (3.5, "3.2e3"),
    ] {
        assert_eq!(pow10_label(&v), want, "log10 value {v}");
    }
}
