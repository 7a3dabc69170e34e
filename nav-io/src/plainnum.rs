//! Reading a plain decimal number (`[-]digits[.digits][(e|E)[-]digits]`, at most 19
//! significant digits before the exponent) in one pass over its bytes, correctly rounded to the nearest `f64`
//! (ties to even): the same bits as `str::parse::<f64>` and `fast-float2`, without their
//! general machinery. The IMU text reader's common line is made of such numbers
//! ([`parse_plain_f64`]); anything else (other spellings, more digits, a value this module
//! cannot round exactly by its two methods) is declined and left to the general parser.
//!
//! The two methods, both exact: with a mantissa `m <= 2^53` and a decimal exponent within
//! `-22..=22`, `m` and `10^|e|` are exact doubles and one IEEE multiplication or division
//! rounds the exact result (Clinger's fast path); otherwise, for a negative exponent
//! `-31..=-1`, `m / 10^k = (m 2^s / 5^k) 2^(-s-k)` is computed in 128-bit integers: the
//! quotient carries at least three bits beyond the 53 kept and the remainder tells whether
//! anything non-zero follows, which is all round-to-nearest-even needs.

/// `10^0 ..= 10^22`, exact in `f64`.
const POW10: [f64; 23] = {
    let mut t = [1.0f64; 23];
    let mut i = 1;
    while i < 23 {
        t[i] = t[i - 1] * 10.0;
        i += 1;
    }
    t
};

/// Largest `k` of the integer method: `5^31 < 2^72`, so `m 2^s` stays below `2^128`.
const POW5_MAX: usize = 31;

/// `5^0 ..= 5^31` as 128-bit integers.
const POW5: [u128; POW5_MAX + 1] = {
    let mut t = [1u128; POW5_MAX + 1];
    let mut i = 1;
    while i <= POW5_MAX {
        t[i] = t[i - 1] * 5;
        i += 1;
    }
    t
};

/// Most digits of the mantissa (`10^19 - 1 < 2^64`).
const MAX_DIGITS: usize = 19;

/// Most digits of the exponent.
const MAX_EXP_DIGITS: usize = 3;

/// Reads the digits at `b[i..]` into `m` (`m = 10 m + d` per digit, wrapping: the caller
/// bounds the count) and counts in `sig` those from the first non-zero one of `m` on (the
/// significant digits); returns the index after the last digit.
#[inline]
fn digits(b: &[u8], mut i: usize, m: &mut u64, sig: &mut usize) -> usize {
    while let Some(&c) = b.get(i) {
        let d = c.wrapping_sub(b'0');
        if d > 9 {
            break;
        }
        *m = m.wrapping_mul(10).wrapping_add(u64::from(d));
        *sig += usize::from(*m != 0);
        i += 1;
    }
    i
}

/// The plain number at the start of `b` and the bytes it takes, when it is followed by ASCII
/// white space or the end of `b`, has a non-zero mantissa of at most 19 significant digits
/// (leading zeros not counted; exponent of at most 3 digits) and one of
/// the two exact methods applies (see the module notes); else `None` (the caller parses the
/// field some other way). The value is the correctly rounded `f64` of the decimal text.
pub(crate) fn parse_plain_f64(b: &[u8]) -> Option<(f64, usize)> {
    let neg = b.first() == Some(&b'-');
    let start = usize::from(neg);
    let mut m = 0u64;
    let mut sig = 0usize;
    let mut i = digits(b, start, &mut m, &mut sig);
    let int_digits = i - start;
    if int_digits == 0 {
        return None;
    }
    let mut e10 = 0i32;
    if b.get(i) == Some(&b'.') {
        let f0 = i + 1;
        i = digits(b, f0, &mut m, &mut sig);
        let frac_digits = i - f0;
        if frac_digits == 0 {
            return None;
        }
        e10 = -(frac_digits as i32);
    }
    if sig > MAX_DIGITS {
        return None;
    }
    if matches!(b.get(i), Some(b'e' | b'E')) {
        let eneg = b.get(i + 1) == Some(&b'-');
        let e0 = i + 1 + usize::from(eneg);
        let mut x = 0u64;
        let mut ex_sig = 0usize;
        i = digits(b, e0, &mut x, &mut ex_sig);
        let n = i - e0;
        if n == 0 || n > MAX_EXP_DIGITS {
            return None;
        }
        let x = x as i32;
        e10 += if eneg { -x } else { x };
    }
    if b.get(i).is_some_and(|c| !c.is_ascii_whitespace()) {
        return None;
    }
    let v = decimal_to_f64(m, e10)?;
    Some((if neg { -v } else { v }, i))
}

/// `m 10^e10` correctly rounded (`m > 0`), by one of the two exact methods; `None` when
/// neither applies.
fn decimal_to_f64(m: u64, e10: i32) -> Option<f64> {
    if m == 0 {
        return None;
    }
    let k = e10.unsigned_abs() as usize;
    if m <= 1 << 53 {
        if let Some(&p) = POW10.get(k) {
            let f = m as f64;
            return Some(if e10 >= 0 { f * p } else { f / p });
        }
    }
    if e10 >= 0 {
        return None;
    }
    div_pow10(m, k)
}

/// `m / 10^k` correctly rounded, for `m > 0` and `1 <= k <= 31`, in integers:
/// `q = floor(m 2^s / 5^k)` has at least 56 bits, its bits below the top 53 and the remainder
/// round it to nearest, ties to even; the value is `q' 2^(-s-k)`.
fn div_pow10(m: u64, k: usize) -> Option<f64> {
    let d = *POW5.get(k)?;
    if m == 0 || k == 0 {
        return None;
    }
    let lm = 64 - m.leading_zeros();
    let ld = 128 - d.leading_zeros();
    // m 2^s >= 2^(55 + ld) > 2^55 d, and m 2^s < 2^(56 + ld) <= 2^128 (ld <= 72); a large
    // m over a small 5^k needs no shift (s = 0: q has more bits, the rounding is the same)
    let s = (56 + ld).saturating_sub(lm);
    let n = u128::from(m) << s;
    let q = n / d;
    let r = n - q * d;
    let bits = 128 - q.leading_zeros();
    let extra = bits.checked_sub(53)?;
    if extra == 0 {
        return None;
    }
    let mut mant = (q >> extra) as u64;
    let half = 1u128 << (extra - 1);
    let low = q & ((1u128 << extra) - 1);
    if low > half || (low == half && (r != 0 || mant & 1 == 1)) {
        mant += 1;
    }
    let mut exp2 = extra as i32 - s as i32 - k as i32;
    if mant == 1 << 53 {
        mant >>= 1;
        exp2 += 1;
    }
    // mant in [2^52, 2^53): the value is mant 2^exp2, biased exponent exp2 + 52 + 1023
    let biased = exp2 + 52 + 1023;
    if !(1..=2046).contains(&biased) {
        return None;
    }
    Some(f64::from_bits(
        ((biased as u64) << 52) | (mant & ((1u64 << 52) - 1)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The parse of `s` when it is taken, checked against `str::parse` (bits) and its length.
    fn check(s: &str) -> Option<f64> {
        let (v, n) = parse_plain_f64(s.as_bytes())?;
        let head = &s[..n];
        let want: f64 = head.parse().unwrap();
        assert_eq!(v.to_bits(), want.to_bits(), "{s:?}: {v:e} != {want:e}");
        Some(v)
    }

    #[test]
    fn awkward_spellings_agree_with_the_standard_parser_or_are_declined() {
        let taken = [
            "0.5",
            "-0.5",
            "200000.005",
            "-4.514718900277834e-7",
            "3.4308508043685698e-6",
            "-3.4308508043685698E-6",
            "1e5",
            "1e22",
            "9007199254740993",
            "9007199254740993e-3",
            "1234567890123456789e-31",
            "1234567890123456789",
            "0.0000000000000000001",
            "5e-31",
            "17976931348623157e-31",
            "2.2250738585072014e-308",
            "1.5 ",
            "7\t",
            "00012.50",
            "4.9406564584124654e-324",
        ];
        for s in taken {
            // some may be declined (beyond the two methods): never a different value
            let _ = check(s);
        }
        for s in [
            "0.5",
            "-4.514718900277834e-7",
            "3.4308508043685698e-6",
            "1e22",
        ] {
            assert!(check(s).is_some(), "{s} should be taken");
        }
        let declined = [
            "",
            "-",
            "+1",
            ".5",
            "1.",
            "1e",
            "1e-",
            "1e+5",
            "1e1234",
            "1.5x",
            "1,5",
            "0",
            "-0.0",
            "0e5",
            "inf",
            "nan",
            "NaN",
            "1_0",
            "12345678901234567890",
            "1e23x",
            "--1",
            "1..2",
        ];
        for s in declined {
            assert_eq!(parse_plain_f64(s.as_bytes()), None, "{s:?}");
        }
    }

    #[test]
    fn ties_round_to_even() {
        // 2^53 + 1 lies halfway between 2^53 and 2^53 + 2: to even (2^53)
        for (s, want) in [
            ("9007199254740993", 9007199254740992.0),
            ("9007199254740995", 9007199254740996.0),
            ("90071992547409930e-1", 9007199254740992.0),
            ("9007199254740993000e-3", 9007199254740992.0),
        ] {
            let (v, _) = parse_plain_f64(s.as_bytes()).unwrap_or((f64::NAN, 0));
            if !v.is_nan() {
                assert_eq!(v, want, "{s}");
            }
        }
        let (v, _) = parse_plain_f64(b"9007199254740993000e-3").unwrap();
        assert_eq!(
            v.to_bits(),
            "9007199254740993000e-3".parse::<f64>().unwrap().to_bits()
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 20_000, ..ProptestConfig::default() })]

        /// Any finite double written as the IMU file writes it (`{:e}`, `{}`), and with a few
        /// digits cut: the same bits as the standard parser whenever taken.
        #[test]
        fn written_doubles_read_back_like_the_standard_parser(
            bits in any::<u64>(), keep in 1usize..20
        ) {
            let x = f64::from_bits(bits);
            prop_assume!(x.is_finite());
            for s in [format!("{x:e}"), format!("{x}"), format!("{x:.*e}", keep - 1)] {
                let _ = check(&s);
            }
        }

        /// Random mantissas of up to 19 digits with random decimal points and exponents.
        #[test]
        fn random_decimals_agree(
            m in 1u64..10_000_000_000_000_000_000,
            point in 0usize..20,
            e in -40i32..30,
            neg in any::<bool>()
        ) {
            let ds = m.to_string();
            let p = point.min(ds.len() - 1);
            let text = if p == 0 { ds.clone() } else {
                format!("{}.{}", &ds[..ds.len() - p], &ds[ds.len() - p..])
            };
            let s = format!("{}{text}e{e}", if neg { "-" } else { "" });
            let _ = check(&s);
        }

        /// The magnitudes of IMU increments and times (17 significant digits, exponents
        /// -12..=6): always taken, always the standard parser's bits.
        #[test]
        fn imu_magnitudes_are_taken(mant in 1.0f64..10.0, e in -12i32..7, neg in any::<bool>()) {
            let x = mant * 10f64.powi(e) * if neg { -1.0 } else { 1.0 };
            for s in [format!("{x:e}"), format!("{x}")] {
                prop_assert!(check(&s).is_some(), "{}", s);
            }
        }
    }
}
