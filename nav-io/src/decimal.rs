//! Correctly rounded conversion of the plain decimal numbers of the IMU text (`-1.2e-7`,
//! `200000.005`) to `f64`, in one pass over their bytes: the digits read eight at a time, the
//! value by the Eisel-Lemire algorithm (one or two 64x64-bit products with a 128-bit
//! approximation of the power of five) over a small table of decimal exponents.
//!
//! It takes only the common spelling: an optional `-`, at least one integer digit, an
//! optional `.` followed by at least one digit, an optional exponent (`e`/`E`, optional sign,
//! one to four digits), at most 19 significant digits, a decimal exponent within the table,
//! and a result that is normal and finite. For anything else it answers `None` and the caller
//! uses its general parser. What it answers, it answers with the bits `str::parse::<f64>`
//! gives (the property tests below check it on random 17-digit and short decimals).

/// Smallest decimal exponent of the power table (`w * 10^q`, `w` the significant digits as an
/// integer). Down to -27 the 128-bit approximation decides every rounding it does not flag.
const Q_MIN: i32 = -27;

/// Largest decimal exponent of the power table.
const Q_MAX: i32 = 27;

/// Entries of the power table.
const N_POW: usize = (Q_MAX - Q_MIN + 1) as usize;

/// 5^q for q in [`Q_MIN`]..=[`Q_MAX`] as 128 bits with the top bit set, as (high word, low
/// word): for q >= 0 the exact power shifted left; for q < 0, `floor(2^b / 5^-q) + 1` with
/// `b = bitlen(5^-q) + 127` (the table of the Eisel-Lemire algorithm over this range).
static POW5_128: [(u64, u64); N_POW] = pow5_table();

/// Builds [`POW5_128`] at compile time (a long division bit by bit for the negative powers;
/// the remainder stays below 5^27 < 2^63).
const fn pow5_table() -> [(u64, u64); N_POW] {
    let mut t = [(0u64, 0u64); N_POW];
    let mut i = 0;
    while i < N_POW {
        let q = Q_MIN + i as i32;
        let mut p: u128 = 1;
        let mut k = 0;
        while k < q.unsigned_abs() {
            p *= 5;
            k += 1;
        }
        let c: u128 = if q >= 0 {
            p << p.leading_zeros()
        } else {
            // floor(2^b / p) + 1, b = z + 127, z = bitlen(p): in (2^127, 2^128)
            let b = (128 - p.leading_zeros()) + 127;
            let mut r: u128 = 0;
            let mut quot: u128 = 0;
            let mut bit = b as i32;
            while bit >= 0 {
                r = (r << 1) | (bit == b as i32) as u128;
                if r >= p {
                    r -= p;
                    if bit < 128 {
                        quot |= 1u128 << bit;
                    }
                }
                bit -= 1;
            }
            quot.wrapping_add(1)
        };
        t[i] = ((c >> 64) as u64, c as u64);
        i += 1;
    }
    t
}

/// `w * 10^q` (w != 0) correctly rounded to the bits of a positive `f64`; `None` when `q` is
/// outside the table, when the result would be subnormal or infinite.
fn eisel_lemire(w: u64, q: i32) -> Option<u64> {
    let &(hi5, lo5) = POW5_128.get(usize::try_from(q - Q_MIN).ok()?)?;
    let lz = w.leading_zeros();
    let w = w << lz;
    let first = u128::from(w) * u128::from(hi5);
    let (mut lo, mut hi) = (first as u64, (first >> 64) as u64);
    // the 55 bits kept (52 + 3) are decided unless the 9 below them are all ones: then the
    // low word of the power is added in
    if hi & 0x1FF == 0x1FF {
        let second_hi = ((u128::from(w) * u128::from(lo5)) >> 64) as u64;
        let (s, carry) = lo.overflowing_add(second_hi);
        lo = s;
        hi = hi.wrapping_add(u64::from(carry));
    }
    // (a product still all ones below the kept bits is exact enough for -27 <= q <= 55: no
    // further check within the table)
    let upper = (hi >> 63) as i32;
    let shift = upper + 9;
    let mut m = hi >> shift;
    // binary exponent of the result, biased: floor(q log2 10) + 63 + upper - lz + 1023
    let mut p2 = ((q.wrapping_mul(152_170 + 65_536)) >> 16) + 63 + upper - lz as i32 + 1023;
    if p2 <= 0 {
        return None;
    }
    // an exact halfway case (possible only for -4 <= q <= 23): round to even
    if lo <= 1 && (-4..=23).contains(&q) && m & 3 == 1 && (m << shift) == hi {
        m &= !1;
    }
    m += m & 1;
    m >>= 1;
    if m >= 2u64 << 52 {
        m = 1u64 << 52;
        p2 += 1;
    }
    m &= !(1u64 << 52);
    if p2 >= 0x7FF {
        return None;
    }
    Some(m | (p2 as u64) << 52)
}

/// Whether the 8 bytes of `v` (little-endian) are all ASCII digits.
fn all_digits(v: u64) -> bool {
    (v & 0xF0F0_F0F0_F0F0_F0F0) | (((v.wrapping_add(0x0606_0606_0606_0606)) & 0xF0F0_F0F0_F0F0_F0F0) >> 4)
        == 0x3333_3333_3333_3333
}

/// The value of 8 ASCII digits (little-endian in `v`, first digit in the low byte).
fn eight_digits(v: u64) -> u64 {
    const MASK: u64 = 0x0000_00FF_0000_00FF;
    const MUL1: u64 = 0x000F_4240_0000_0064;
    const MUL2: u64 = 0x0000_2710_0000_0001;
    let v = v.wrapping_sub(0x3030_3030_3030_3030);
    let v = v.wrapping_mul(10).wrapping_add(v >> 8);
    let v1 = (v & MASK).wrapping_mul(MUL1);
    let v2 = ((v >> 16) & MASK).wrapping_mul(MUL2);
    u64::from((v1.wrapping_add(v2) >> 32) as u32)
}

/// Digits of `b` from `i` on, appended to `w` (each counted in `nd`); returns the index after
/// them.
fn take_digits(b: &[u8], mut i: usize, w: &mut u64, nd: &mut u32) -> usize {
    while let Some(v) = b
        .get(i..i + 8)
        .and_then(|s| <[u8; 8]>::try_from(s).ok())
        .map(u64::from_le_bytes)
        .filter(|&v| all_digits(v))
    {
        *w = w.wrapping_mul(100_000_000).wrapping_add(eight_digits(v));
        *nd += 8;
        i += 8;
    }
    while let Some(d) = b.get(i).map(|c| c.wrapping_sub(b'0')).filter(|d| *d <= 9) {
        *w = w.wrapping_mul(10).wrapping_add(u64::from(d));
        *nd += 1;
        i += 1;
    }
    i
}

/// The plain decimal number at the start of `b` (see the module's text for the spelling
/// taken), which must end there or at ASCII white space: its value, bit for bit what
/// `str::parse::<f64>` gives, and the bytes it spans. `None` for any other text, for more
/// than 19 significant digits or a value this conversion does not take (the caller's general
/// parser decides those).
pub(crate) fn parse_plain(b: &[u8]) -> Option<(f64, usize)> {
    let neg = b.first() == Some(&b'-');
    let mut i = usize::from(neg);
    let mut w = 0u64;
    let mut nd = 0u32;
    // leading zeros of the integer part are not significant
    let int_start = i;
    while b.get(i) == Some(&b'0') {
        i += 1;
    }
    i = take_digits(b, i, &mut w, &mut nd);
    if i == int_start {
        return None;
    }
    let mut frac = 0usize;
    if b.get(i) == Some(&b'.') {
        i += 1;
        let fs = i;
        if w == 0 {
            while b.get(i) == Some(&b'0') {
                i += 1;
            }
        }
        i = take_digits(b, i, &mut w, &mut nd);
        frac = i - fs;
        if frac == 0 {
            return None;
        }
    }
    if nd > 19 {
        return None;
    }
    let mut e10 = 0i32;
    if matches!(b.get(i), Some(b'e' | b'E')) {
        i += 1;
        let eneg = b.get(i) == Some(&b'-');
        if matches!(b.get(i), Some(b'-' | b'+')) {
            i += 1;
        }
        let es = i;
        while let Some(d) = b.get(i).map(|c| c.wrapping_sub(b'0')).filter(|d| *d <= 9) {
            e10 = e10 * 10 + i32::from(d);
            i += 1;
            if i - es > 4 {
                return None;
            }
        }
        if i == es {
            return None;
        }
        if eneg {
            e10 = -e10;
        }
    }
    if b.get(i).is_some_and(|c| !c.is_ascii_whitespace()) {
        return None;
    }
    let sign = u64::from(neg) << 63;
    if w == 0 {
        return Some((f64::from_bits(sign), i));
    }
    let q = e10 - i32::try_from(frac).ok()?;
    let bits = eisel_lemire(w, q)?;
    Some((f64::from_bits(bits | sign), i))
}

#[cfg(test)]
mod tests {
    use super::parse_plain;
    use proptest::prelude::*;

    /// `parse_plain` on `s` against `str::parse::<f64>`: the same bits when it answers; the
    /// answer itself when `taken` (the spelling and range it is made for).
    fn check(s: &str, taken: bool) {
        let want: f64 = s.parse().unwrap_or(f64::NAN);
        match parse_plain(s.as_bytes()) {
            Some((x, n)) => {
                assert_eq!(n, s.len(), "{s}: length");
                assert_eq!(x.to_bits(), want.to_bits(), "{s}: {x} vs {want}");
            }
            None => assert!(!taken, "{s}: not taken"),
        }
    }

    #[test]
    fn edge_spellings() {
        for s in [
            "0", "-0", "0.0", "-0.0", "1", "-1", "1.5", "2.5", "0.1", "0.3", "200000.005",
            "200000.01", "9007199254740993", "9007199254740992.5", "1e22", "1e23", "1e-27",
            "4.9406564584124654e-324", "1.7976931348623157e308", "123456789012345678",
            "1234567890123456789", "0.000001234567890123456", "007.5", "1E5", "1e+5",
        ] {
            check(s, false);
        }
        for s in ["", "-", ".5", "1.", "1e", "1e+", "+1", "1x", "1.5e12345", "nan", "inf"] {
            assert!(parse_plain(s.as_bytes()).is_none(), "{s}");
        }
        // more than 19 significant digits: left to the general parser
        assert!(parse_plain(b"12345678901234567890").is_none());
        // a number ending at white space
        assert_eq!(parse_plain(b"1.25 7").map(|(x, n)| (x, n)), Some((1.25, 4)));
    }

    /// Halfway cases between two doubles (exact ties, rounded to even) near 2^53.
    #[test]
    fn exact_ties_round_to_even() {
        for k in 0..2000u64 {
            let s = format!("{}.5", 4_503_599_627_370_496u64 + k);
            check(&s, true);
            let s = format!("{}", 9_007_199_254_740_992u64 + 2 * k + 1);
            check(&s, true);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        /// 17 significant digits in exponent form, as the IMU text writes them.
        #[test]
        fn seventeen_digits(m in 10_000_000_000_000_000u64..100_000_000_000_000_000u64,
                            e in -10i32..6, neg in any::<bool>()) {
            let d = m.to_string();
            let s = format!("{}{}.{}e{}", if neg { "-" } else { "" }, &d[..1], &d[1..], e);
            check(&s, true);
        }

        /// Short decimals in positional form (times, configuration values).
        #[test]
        fn short_decimals(int in 0u64..10_000_000, frac in 0u64..1_000_000, w in 1usize..7,
                          neg in any::<bool>()) {
            let s = format!("{}{}.{:0w$}", if neg { "-" } else { "" }, int, frac % 10u64.pow(w as u32));
            check(&s, true);
        }

        /// Any double as `Display` and `{:e}` write it (shortest round trip).
        #[test]
        fn shortest_texts(bits in any::<u64>()) {
            let x = f64::from_bits(bits);
            if x.is_finite() {
                check(&format!("{x}"), false);
                check(&format!("{x:e}"), false);
                if (1e-10..1e10).contains(&x.abs()) {
                    check(&format!("{x:e}"), true);
                }
            }
        }

        /// Random digit strings of 1 to 19 digits with a point anywhere and an exponent.
        #[test]
        fn random_digits(m in 1u64..10_000_000_000_000_000_000u64, point in 0usize..20,
                         e in -8i32..8) {
            let d = m.to_string();
            let p = point.min(d.len() - 1) + 1;
            let s = format!("{}.{}0e{}", &d[..p], &d[p..], e);
            check(&s, false);
        }
    }
}
