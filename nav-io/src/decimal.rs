//! Plain decimal numbers (`[-]digits[.digits][(e|E)[+-]digits]`, at most 19 significant
//! digits) read to the correctly rounded `f64`, the common spelling of the IMU text's numbers.
//!
//! The digits are read eight at a time into a `u64` (SWAR), the value is then exact in one of
//! two ways: Clinger's fast path (a mantissa of at most 2^53 and a power of ten within 10^±22,
//! both exact in `f64`, so one correctly rounded multiplication or division), or Eisel and
//! Lemire's 128-bit product with a truncated power of five (decimal exponents -27..=27, the
//! same algorithm and table entries as `fast-float2`). What is not read here (other spellings,
//! more digits, other exponents, an undecided product) is left to `fast-float2`: every value
//! given is the one `str::parse::<f64>` gives, bit for bit.

/// Exact powers of ten in `f64`: 10^0 ..= 10^22.
const F64_POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Powers of ten in `u64`: 10^0 ..= 10^8.
const U64_POW10: [u64; 9] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
];

/// Eight ASCII zeros as a little-endian word.
const ASCII_ZEROS: u64 = 0x3030_3030_3030_3030;

/// Largest mantissa of Clinger's fast path (2^53: every integer up to it is exact in `f64`).
const MAX_FAST_MANTISSA: u64 = 1 << 53;

/// Decimal exponents of the power-of-five table.
const Q_MIN: i64 = -27;
/// See [`Q_MIN`].
const Q_MAX: i64 = 27;

/// 5^q for q in [`Q_MIN`]..=[`Q_MAX`], normalised to 128 bits (top bit set) and truncated, as
/// (high word, low word); for q < 0 the truncated reciprocal plus one unit, as in the
/// Eisel-Lemire table of `fast-float2`.
static POW5_128: [(u64, u64); (Q_MAX - Q_MIN + 1) as usize] = pow5_table();

/// Builds [`POW5_128`] at compile time.
const fn pow5_table() -> [(u64, u64); (Q_MAX - Q_MIN + 1) as usize] {
    let mut t = [(0u64, 0u64); (Q_MAX - Q_MIN + 1) as usize];
    let mut k = 0usize;
    while k < t.len() {
        t[k] = pow5_128(Q_MIN + k as i64);
        k += 1;
    }
    t
}

/// One entry of [`POW5_128`]: for q >= 0, 5^q shifted up to bit 127; for q < 0,
/// floor(2^(z + 127) / 5^-q) + 1 with 2^z the smallest power of two not below 5^-q.
const fn pow5_128(q: i64) -> (u64, u64) {
    let mut c: u128;
    if q >= 0 {
        c = 5u128.pow(q as u32);
    } else {
        let d = 5u128.pow((-q) as u32);
        let mut z = 0u32;
        while (1u128 << z) < d {
            z += 1;
        }
        // floor(2^b / d), one quotient bit at a time (the quotient is below 2^128)
        let b = (z + 127) as i64;
        let mut r = 0u128;
        let mut quo = 0u128;
        let mut bit = b;
        while bit >= 0 {
            r = (r << 1) | (bit == b) as u128;
            quo <<= 1;
            if r >= d {
                r -= d;
                quo |= 1;
            }
            bit -= 1;
        }
        c = quo + 1;
    }
    while c < (1u128 << 127) {
        c <<= 1;
    }
    ((c >> 64) as u64, c as u64)
}

/// Flags (bit 7 of a byte) the bytes of a little-endian word that are not ASCII digits; the
/// lowest flag is the first non-digit (carries and borrows only move upwards from it).
#[inline(always)]
fn non_digits(v: u64) -> u64 {
    (v.wrapping_add(0x4646_4646_4646_4646) | v.wrapping_sub(ASCII_ZEROS)) & 0x8080_8080_8080_8080
}

/// The value of eight ASCII digits in a little-endian word (the first digit lowest).
#[inline(always)]
fn eight_digits(v: u64) -> u64 {
    const MASK: u64 = 0x0000_00FF_0000_00FF;
    const MUL1: u64 = 0x000F_4240_0000_0064;
    const MUL2: u64 = 0x0000_2710_0000_0001;
    let v = v.wrapping_sub(ASCII_ZEROS);
    let v = v.wrapping_mul(10).wrapping_add(v >> 8);
    let v1 = (v & MASK).wrapping_mul(MUL1);
    let v2 = ((v >> 16) & MASK).wrapping_mul(MUL2);
    u64::from((v1.wrapping_add(v2) >> 32) as u32)
}

/// Reads the ASCII digits of `b` from `i` on into `w` (`w * 10 + digit` for each, wrapping:
/// the caller bounds the count); returns the index after them.
#[inline(always)]
fn digits(b: &[u8], mut i: usize, w: &mut u64) -> usize {
    while let Some(chunk) = b.get(i..i.wrapping_add(8)) {
        let Ok(bytes) = <[u8; 8]>::try_from(chunk) else {
            break;
        };
        let v = u64::from_le_bytes(bytes);
        let nd = non_digits(v);
        if nd == 0 {
            *w = w.wrapping_mul(100_000_000).wrapping_add(eight_digits(v));
            i += 8;
            continue;
        }
        // k < 8 digits, then a non-digit: the digits moved to the top of the word, zeros
        // below them
        let k = (nd.trailing_zeros() / 8) as usize;
        if k > 0 {
            let v = (v << (64 - 8 * k)) | (ASCII_ZEROS >> (8 * k));
            let scale = U64_POW10.get(k).copied().unwrap_or(0);
            *w = w.wrapping_mul(scale).wrapping_add(eight_digits(v));
        }
        return i + k;
    }
    // fewer than eight bytes left
    while let Some(d) = b.get(i).map(|c| c.wrapping_sub(b'0')).filter(|d| *d < 10) {
        *w = w.wrapping_mul(10).wrapping_add(u64::from(d));
        i += 1;
    }
    i
}

/// Reads a plain decimal at the start of `b` and returns its correctly rounded value and the
/// number of bytes it spans, or `None` when the text is anything else or its value is not
/// decided here (see the module): `[-]digits[.digits][(e|E)[+-]digits]` with at least one
/// digit on each side of a point, at most 19 digits before the exponent and at most 4 in it.
#[inline]
pub(crate) fn parse_plain(b: &[u8]) -> Option<(f64, usize)> {
    let neg = b.first() == Some(&b'-');
    let start = usize::from(neg);
    let mut w = 0u64;
    // the common integer part, one digit and the point, without the eight-byte read
    let mut i = match (b.get(start).map(|c| c.wrapping_sub(b'0')), b.get(start + 1)) {
        (Some(d), Some(b'.')) if d < 10 => {
            w = u64::from(d);
            start + 1
        }
        _ => digits(b, start, &mut w),
    };
    let n_int = i - start;
    if n_int == 0 {
        return None;
    }
    let mut n_frac = 0usize;
    if b.get(i) == Some(&b'.') {
        let s = i + 1;
        i = digits(b, s, &mut w);
        n_frac = i - s;
        if n_frac == 0 {
            return None;
        }
    }
    if n_int + n_frac > 19 {
        return None;
    }
    let mut q = -(n_frac as i64);
    if let Some(b'e' | b'E') = b.get(i) {
        let (e, used) = exponent(b.get(i + 1..)?)?;
        q += e;
        i += 1 + used;
    }
    let x = if w <= MAX_FAST_MANTISSA && (-22..=22).contains(&q) {
        let m = w as f64;
        let p = *F64_POW10.get(q.unsigned_abs() as usize)?;
        if q < 0 {
            m / p
        } else {
            m * p
        }
    } else {
        f64::from_bits(eisel_lemire(w, q)?)
    };
    Some((if neg { -x } else { x }, i))
}

/// An exponent's `[+-]digits` (at most 4 digits) at the start of `b`: its value and length.
#[inline(always)]
fn exponent(b: &[u8]) -> Option<(i64, usize)> {
    let digit = |i: usize| {
        b.get(i)
            .map(|c| c.wrapping_sub(b'0'))
            .filter(|d| *d < 10)
            .map(i64::from)
    };
    let (neg, s) = match b.first() {
        Some(b'-') => (true, 1),
        Some(b'+') => (false, 1),
        _ => (false, 0),
    };
    let mut e = digit(s)?;
    let mut i = s + 1;
    while let Some(d) = digit(i) {
        e = e * 10 + d;
        i += 1;
        if i - s > 4 {
            return None;
        }
    }
    Some((if neg { -e } else { e }, i))
}

/// The bits of the `f64` nearest to `w * 10^q` by Eisel and Lemire's algorithm (as
/// `fast-float2`'s `compute_float` for `f64`, restricted to the table's exponents, where the
/// product's truncation is always safe), or `None` outside them, for zero, or when the
/// result would not be a normal number.
#[inline]
fn eisel_lemire(w: u64, q: i64) -> Option<u64> {
    /// Explicit mantissa bits of `f64`.
    const MANT: i32 = 52;
    let &(hi5, lo5) = POW5_128.get(usize::try_from(q - Q_MIN).ok()?)?;
    if w == 0 {
        return None;
    }
    let lz = w.leading_zeros();
    let w = w << lz;
    let p = u128::from(w) * u128::from(hi5);
    let (mut lo, mut hi) = (p as u64, (p >> 64) as u64);
    let mask = u64::MAX >> (MANT + 3);
    if hi & mask == mask {
        let p2hi = ((u128::from(w) * u128::from(lo5)) >> 64) as u64;
        lo = lo.wrapping_add(p2hi);
        if p2hi > lo {
            hi = hi.wrapping_add(1);
        }
    }
    let upperbit = (hi >> 63) as i32;
    let shift = upperbit + 64 - MANT - 3;
    let mut mantissa = hi >> shift;
    // the binary exponent: floor(q * log2(10)) + 63, biased
    let mut power2 =
        ((q as i32).wrapping_mul(152_170 + 65_536) >> 16) + 63 + upperbit - lz as i32 + 1023;
    if power2 <= 0 {
        return None;
    }
    // a product exactly halfway between two floats: round to even
    if lo <= 1 && (-4..=23).contains(&q) && mantissa & 3 == 1 && (mantissa << shift) == hi {
        mantissa &= !1;
    }
    mantissa += mantissa & 1;
    mantissa >>= 1;
    if mantissa >= (2u64 << MANT) {
        mantissa = 1u64 << MANT;
        power2 += 1;
    }
    mantissa &= !(1u64 << MANT);
    if power2 >= 0x7FF {
        return None;
    }
    Some(mantissa | ((power2 as u64) << MANT))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// `parse_plain` against `str::parse::<f64>`: the same bits whenever it gives a value.
    fn check(s: &str) {
        if let Some((x, used)) = parse_plain(s.as_bytes()) {
            let want: f64 = s[..used].parse().unwrap();
            assert_eq!(x.to_bits(), want.to_bits(), "{s}");
        }
    }

    /// `parse_plain` reads the whole of `s` and gives the bits of `str::parse::<f64>`.
    fn check_read(s: &str) {
        let (x, used) = parse_plain(s.as_bytes()).unwrap_or_else(|| panic!("not read: {s}"));
        assert_eq!(used, s.len(), "{s}");
        let want: f64 = s.parse().unwrap();
        assert_eq!(x.to_bits(), want.to_bits(), "{s}");
    }

    #[test]
    fn the_imu_files_spellings_are_read_to_the_bit() {
        for s in [
            "200000.005",
            "-4.514718900277834e-7",
            "2.095063049018687e-6",
            "4.7831483269046746e-5",
            "3.4308508043685698e-6",
            "-4.907465952629882e-2",
            "0",
            "-0",
            "0.0",
            "9007199254740992",
            "9007199254740993",
            "1e22",
            "1e-22",
            "123456789012345678e-27",
            "9999999999999999999e27",
            "1E5",
            "2.5e+3",
        ] {
            check_read(s);
        }
    }

    #[test]
    fn other_spellings_are_left_to_the_general_parser() {
        for s in [
            "", "-", ".5", "5.", "+5", "1e", "1e+", "nan", "inf", "1e12345", "1x",
        ] {
            if let Some((_, used)) = parse_plain(s.as_bytes()) {
                // a number followed by other text: read up to it, as `fast-float2` does
                let want: f64 = s[..used].parse().unwrap();
                let (ff, ff_used) = fast_float2::parse_partial::<f64, _>(s).unwrap();
                assert_eq!((want.to_bits(), used), (ff.to_bits(), ff_used), "{s}");
            }
        }
        assert!(parse_plain(b"12345678901234567890").is_none());
    }

    #[test]
    fn the_power_of_five_table_matches_fast_float() {
        // entries of fast-float2's table (q = -27, -1, 0, 1, 27)
        assert_eq!(POW5_128[0], (0x9e74_d1b7_91e0_7e48, 0x775e_a264_cf55_347e));
        assert_eq!(POW5_128[26], (0xcccc_cccc_cccc_cccc, 0xcccc_cccc_cccc_cccd));
        assert_eq!(POW5_128[27], (0x8000_0000_0000_0000, 0));
        assert_eq!(POW5_128[28], (0xa000_0000_0000_0000, 0));
        assert_eq!(POW5_128[54], (0xcecb_8f27_f420_0f3a, 0));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        #[test]
        fn shortest_spellings_of_random_doubles(bits in any::<u64>(), neg: bool) {
            let x = f64::from_bits(bits);
            prop_assume!(x.is_finite());
            let x = if neg { -x.abs() } else { x.abs() };
            check(&format!("{x}"));
            check(&format!("{x:e}"));
            check(&format!("{x:E}"));
        }

        #[test]
        fn decimals_of_the_imu_files_shapes(
            int in 0u64..1_000_000,
            frac in "[0-9]{1,18}",
            exp in -30i32..30,
            neg: bool,
        ) {
            let sign = if neg { "-" } else { "" };
            check(&format!("{sign}{int}.{frac}"));
            check(&format!("{sign}{}.{frac}e{exp}", int % 10));
            check(&format!("{sign}{int}e{exp}"));
            check(&format!("{sign}{}.{frac}E+{}", int % 10, exp.unsigned_abs()));
        }

        #[test]
        fn mantissas_of_up_to_19_digits(w in any::<u64>(), digits in 1usize..20, q in -40i64..40) {
            let s = format!("{}", w % 10u64.pow(digits as u32));
            check(&format!("{s}e{q}"));
            if s.len() > 1 {
                let (a, b) = s.split_at(1);
                check(&format!("{a}.{b}e{q}"));
            }
        }
    }
}
