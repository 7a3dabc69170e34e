//! The fast float writers of `nav_io::numfmt` against `core::fmt`, byte for byte: the shortest
//! form (`{}`), fixed precision (`{:.P}`) and the exponent form with precision (`{:.Pe}`), over
//! random bit patterns, tie-prone values (exact binary fractions, exact decimal halves), values
//! next to powers of ten and the value ranges of `std.txt` / `bias.txt`.

use nav_io::LineBuf;
use proptest::prelude::*;

#[derive(Clone, Copy, Debug)]
enum Form {
    Shortest,
    Fixed(usize),
    Exp(usize),
}

fn fast(x: f64, f: Form) -> String {
    let mut v = Vec::new();
    let mut lb = LineBuf::new();
    match f {
        Form::Shortest => lb.push_f64(&mut v, x),
        Form::Fixed(p) => lb.push_fixed(&mut v, x, p),
        Form::Exp(p) => lb.push_exp(&mut v, x, p),
    }
    .unwrap();
    lb.flush(&mut v).unwrap();
    String::from_utf8(v).unwrap()
}

fn reference(x: f64, f: Form) -> String {
    match f {
        Form::Shortest => format!("{x}"),
        Form::Fixed(p) => format!("{x:.p$}"),
        Form::Exp(p) => format!("{x:.p$e}"),
    }
}

/// The forms the run outputs use, and a few more precisions.
const FORMS: [Form; 9] = [
    Form::Shortest,
    Form::Fixed(4),
    Form::Fixed(6),
    Form::Fixed(0),
    Form::Fixed(1),
    Form::Fixed(9),
    Form::Exp(6),
    Form::Exp(0),
    Form::Exp(3),
];

/// `xs` through the spaced runs with a constant precision (`{:.4}`, `{:.6}`, `{:.6e}`, each
/// run ended by `|`), in a buffer of `CAP` bytes.
fn spaced_fixed_exp<const CAP: usize>(xs: &[f64]) -> String {
    let mut v = Vec::new();
    let mut lb = LineBuf::<CAP>::new_block();
    lb.push_spaced_fixed::<4, _>(&mut v, xs).unwrap();
    lb.push_byte(&mut v, b'|').unwrap();
    lb.push_spaced_fixed::<6, _>(&mut v, xs).unwrap();
    lb.push_byte(&mut v, b'|').unwrap();
    lb.push_spaced_exp::<6, _>(&mut v, xs).unwrap();
    lb.push_byte(&mut v, b'|').unwrap();
    lb.flush(&mut v).unwrap();
    String::from_utf8(v).unwrap()
}

/// What [`spaced_fixed_exp`] must write, by `core::fmt`.
fn spaced_fixed_exp_reference(xs: &[f64]) -> String {
    let mut s = String::new();
    for x in xs {
        s.push_str(&format!(" {x:.4}"));
    }
    s.push('|');
    for x in xs {
        s.push_str(&format!(" {x:.6}"));
    }
    s.push('|');
    for x in xs {
        s.push_str(&format!(" {x:.6e}"));
    }
    s.push('|');
    s
}

fn check(x: f64) -> Result<(), TestCaseError> {
    prop_assert_eq!(
        spaced_fixed_exp::<512>(&[x]),
        spaced_fixed_exp_reference(&[x]),
        "spaced runs of {:e} ({:#x})",
        x,
        x.to_bits()
    );
    for f in FORMS {
        prop_assert_eq!(
            fast(x, f),
            reference(x, f),
            "{:?} of {:e} ({:#x})",
            f,
            x,
            x.to_bits()
        );
    }
    Ok(())
}

#[test]
fn edge_values_match_core_fmt() {
    let mut vals = vec![
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.5,
        1.5,
        2.5,
        -2.5,
        0.125,
        0.00005,
        0.000_000_5,
        0.000_001_5,
        1.745_329_251_994_33e-4,
        9.999_999_5e-5,
        9.999_999_4e-5,
        9.999_999_6e-5,
        0.999_999_95,
        9_999_999.5,
        99_999.999_995,
        1e-7,
        1e22,
        1e23,
        4_503_599_627_370_495.5,
        4_503_599_627_370_496.0,
        9_007_199_254_740_993.0,
        f64::MAX,
        f64::MIN_POSITIVE,
        5e-324,
        f64::EPSILON,
        std::f64::consts::PI,
        200_000.000_05,
        200_000.000_15,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for k in -30..=30 {
        let p = 10f64.powi(k);
        for x in [
            p,
            f64::from_bits(p.to_bits() + 1),
            f64::from_bits(p.to_bits() - 1),
        ] {
            vals.push(x);
            vals.push(-x);
        }
    }
    for x in vals {
        check(x).unwrap();
    }
}

/// Random bits, exact binary fractions (where decimal halves live), decimal halves at the
/// precisions used, and the magnitudes of std.txt (1e-9..1e2) and bias.txt (1e-3..1e4).
fn values() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<u64>().prop_map(f64::from_bits),
        (any::<i64>(), 0i32..40).prop_map(|(m, s)| (m >> 11) as f64 / 2f64.powi(s)),
        (any::<i32>(), 0u32..10).prop_map(|(m, p)| (f64::from(m) + 0.5) / 10f64.powi(p as i32)),
        (0u32..1_000_000, 0i32..30).prop_map(|(m, s)| 200000.0 + m as f64 / 2f64.powi(s)),
        (-1e6f64..1e6),
        (-9.0f64..3.0, any::<bool>()).prop_map(|(e, neg)| {
            let x = 10f64.powf(e);
            if neg {
                -x
            } else {
                x
            }
        }),
        (-1.0f64..1.0).prop_map(|x| x * 1e-9),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 50_000, ..ProptestConfig::default() })]

    /// Every form is `core::fmt`'s, byte for byte.
    #[test]
    fn fast_forms_are_byte_identical_to_core_fmt(x in values()) {
        check(x)?;
    }
}

/// The exponent form around every binary exponent (its decimal exponent is estimated from the
/// binary one, off by at most one and corrected), subnormals included, and its neighbours.
#[test]
fn exp_form_matches_core_fmt_at_every_binary_exponent() {
    for k in -1074..=1023 {
        let p = 2f64.powi(k);
        for x in [
            p,
            f64::from_bits(p.to_bits() + 1),
            f64::from_bits(p.to_bits().saturating_sub(1)),
            p * 1.999_999_999,
            p * 1.5,
        ] {
            for f in [Form::Exp(6), Form::Exp(0), Form::Exp(3), Form::Exp(15)] {
                for v in [x, -x] {
                    assert_eq!(fast(v, f), reference(v, f), "{f:?} of {v:e}");
                }
            }
        }
    }
}

/// One `LineBuf` kept for many nav lines (as the run's writer does), even one left holding
/// bytes, writes what `write!` and `Display` write.
#[test]
fn nav_lines_through_a_kept_line_buffer_match_display() {
    use nav_core::types::NavSolution;
    let mut lb = LineBuf::new();
    let mut junk = Vec::new();
    lb.push_bytes(&mut junk, b"left over").unwrap();
    let (mut fast_text, mut reference_text) = (Vec::new(), Vec::new());
    for k in 0..2000u32 {
        let x = f64::from(k);
        let n = NavSolution {
            week: 2227,
            t_s: 118_800.0 + x * 0.005,
            lat_rad: (48.199 + x * 1e-7).to_radians(),
            lon_rad: (16.37 - x * 3e-8).to_radians(),
            h_m: 220.0 + (x * 0.01).sin(),
            vel_ned_mps: [x * 1e-3, -(x * 1e-6), (x * 0.3).cos() * 1e-5],
            rpy_rad: [
                1e-9 * x,
                -0.01,
                (x * 0.001).rem_euclid(std::f64::consts::TAU),
            ],
            ..NavSolution::default()
        };
        nav_io::text::write_nav_line_with(&mut lb, &mut fast_text, &n).unwrap();
        nav_io::text::write_nav_line_display(&mut reference_text, &n).unwrap();
    }
    assert!(junk.is_empty());
    assert_eq!(
        String::from_utf8(fast_text).unwrap(),
        String::from_utf8(reference_text).unwrap()
    );
}

/// Many nav lines appended to a block buffer (written only when it is full, so lines are cut
/// across writes) give the bytes of `write!` and `Display`, with a small buffer (a write every
/// few lines, numbers through `Display` after a flush) and with the run's [`nav_io::BlockBuf`].
#[test]
fn nav_lines_through_a_block_buffer_match_display() {
    use nav_core::types::NavSolution;
    fn lines(k: u32) -> NavSolution {
        let x = f64::from(k);
        NavSolution {
            week: 2227,
            t_s: 118_800.0 + x * 0.005,
            lat_rad: (48.199 + x * 1e-7).to_radians(),
            lon_rad: (16.37 - x * 3e-8).to_radians(),
            // every 97th a non-finite height (the `Display` path) and a tie-prone value
            h_m: if k.is_multiple_of(97) {
                f64::NAN
            } else {
                220.0 + (x * 0.01).sin()
            },
            vel_ned_mps: [x * 1e-3, -(x * 1e-6), (x * 0.3).cos() * 1e-5],
            rpy_rad: [
                1e-9 * x,
                if k.is_multiple_of(89) { 0.25 } else { -0.01 },
                3.0,
            ],
            ..NavSolution::default()
        }
    }
    let mut reference_text = Vec::new();
    for k in 0..3000u32 {
        nav_io::text::write_nav_line_display(&mut reference_text, &lines(k)).unwrap();
    }
    let mut small = LineBuf::<200>::new_block();
    let mut big = nav_io::BlockBuf::boxed();
    let (mut small_text, mut big_text) = (Vec::new(), Vec::new());
    for k in 0..3000u32 {
        nav_io::text::push_nav_line(&mut small, &mut small_text, &lines(k)).unwrap();
        nav_io::text::push_nav_line(&mut *big, &mut big_text, &lines(k)).unwrap();
    }
    assert!(big.pending() > 0 && big_text.len() > 128 << 10);
    assert_eq!(small_text.len() + small.pending(), reference_text.len());
    small.flush(&mut small_text).unwrap();
    big.flush(&mut big_text).unwrap();
    assert_eq!(big.pending(), 0);
    let r = String::from_utf8(reference_text).unwrap();
    assert_eq!(String::from_utf8(small_text).unwrap(), r);
    assert_eq!(String::from_utf8(big_text).unwrap(), r);
}

/// A run of numbers appended with one room check (`LineBuf::push_spaced_f64s`) gives
/// `" {x}"` per number as `Display` writes it, for awkward values (signed zeros, ties,
/// non-finite, subnormal, huge, tiny) and buffers that hold the run, hold it only after a
/// flush, or cannot hold it at all.
#[test]
fn spaced_runs_match_display_in_every_buffer() {
    let awkward = [
        0.0,
        -0.0,
        1.0,
        -1.5e-7,
        200_000.005,
        200_000.0 + 2f64.powi(-12),
        -1_514_017_065_704_403.2,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        5e-324,
        f64::MAX,
        1e16,
        -123_456_789.123_456_78,
        0.25,
        48.199_000_010_687_65,
    ];
    let runs: Vec<&[f64]> = awkward.chunks(10).chain(awkward.chunks(3)).collect();
    let mut reference = String::new();
    for _ in 0..40 {
        for r in &runs {
            for x in *r {
                reference.push_str(&format!(" {x}"));
            }
            reference.push('\n');
        }
    }
    fn through<const CAP: usize>(mut lb: LineBuf<CAP>, runs: &[&[f64]]) -> String {
        let mut out = Vec::new();
        for _ in 0..40 {
            for r in runs {
                lb.push_spaced_f64s(&mut out, r).unwrap();
                lb.push_byte(&mut out, b'\n').unwrap();
            }
        }
        lb.flush(&mut out).unwrap();
        String::from_utf8(out).unwrap()
    }
    assert_eq!(through(LineBuf::<512>::new_block(), &runs), reference);
    assert_eq!(through(LineBuf::<600>::new_block(), &runs), reference);
    assert_eq!(through(LineBuf::<100>::new_block(), &runs), reference);
    assert_eq!(
        through(LineBuf::<{ 64 << 10 }>::new_block(), &runs),
        reference
    );
    // the spaced runs with a constant precision, in the same kinds of buffer
    let fixed_exp = spaced_fixed_exp_reference(&awkward);
    assert_eq!(spaced_fixed_exp::<2048>(&awkward), fixed_exp);
    assert_eq!(spaced_fixed_exp::<600>(&awkward), fixed_exp);
    assert_eq!(spaced_fixed_exp::<100>(&awkward), fixed_exp);
    assert_eq!(spaced_fixed_exp::<{ 64 << 10 }>(&awkward), fixed_exp);
}
