//! The common plain decimal number of a text data line read without a general parser:
//! `[+-] digits [. digits] [(e|E) [+-] digits]` with at most 19 significant-or-not digits whose
//! integer `m` is at most 2^53 and whose decimal exponent `q` (value `m 10^q`) is in -22..=22.
//! Then `m` and `10^|q|` are exact doubles and the value is ONE correctly rounded
//! multiplication or division of the two (Clinger's fast path), which is the correctly rounded
//! value of the text: the bits every exact parser (`str::parse`, `fast-float2`) gives.
//! Anything else gives `None`, and the caller parses the number with its exact parser.
//!
//! The digits are read eight at a time as one little-endian word: the count of leading digit
//! bytes from the carries of two word additions, their value with three multiplications.

/// Exact powers of ten as doubles, 10^0 ..= 10^22 (10^22 < 2^53 5^22: every one is exact).
static POW10: [f64; 23] = {
    let mut t = [1.0f64; 23];
    let mut i = 1;
    while i < 23 {
        t[i] = t[i - 1] * 10.0;
        i += 1;
    }
    t
};

/// 10^k as an integer, k = 0..=8.
const POW10_U64: [u64; 9] = [
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

/// The leading decimal digits of `s[at..]`, at most eight: their value and their count (0
/// when `s[at]` is not a digit or `at` is at or past the end).
pub(crate) fn digits8(s: &[u8], at: usize) -> (u64, usize) {
    let w = match s.get(at..at + 8) {
        Some(b) => {
            let mut a = [0u8; 8];
            a.copy_from_slice(b);
            u64::from_le_bytes(a)
        }
        None => {
            // the end of the slice: padded with NUL bytes (not digits)
            let mut a = [0u8; 8];
            let rest = s.get(at..).unwrap_or(&[]);
            for (d, c) in a.iter_mut().zip(rest) {
                *d = *c;
            }
            u64::from_le_bytes(a)
        }
    };
    const ONES: u64 = 0x0101_0101_0101_0101;
    // per byte b: b - '0' sets the top bit for b < '0' (and b >= 0xb0), b + 0x46 for
    // b > '9'; a borrow or carry only leaves a non-digit byte, so it reaches only bytes after
    // the first non-digit one, and the lowest flagged byte is the first non-digit
    let x = w.wrapping_sub(ONES * u64::from(b'0'));
    let y = w.wrapping_add(ONES * 0x46);
    let flag = (x | y) & (ONES * 0x80);
    let k = (flag.trailing_zeros() / 8) as usize;
    if k == 0 {
        return (0, 0);
    }
    // the k digit values to the top bytes, zeros (digit value 0) before them: the number
    // "0..0 d1..dk" of eight digits, the first digit in the lowest byte
    let v = x << (8 * (8 - k));
    // pairs, then quadruples, then the eight digits
    let v = v.wrapping_mul(10).wrapping_add(v >> 8);
    const MASK: u64 = 0x0000_00FF_0000_00FF;
    const MUL1: u64 = 0x000F_4240_0000_0064;
    const MUL2: u64 = 0x0000_2710_0000_0001;
    let v1 = (v & MASK).wrapping_mul(MUL1);
    let v2 = ((v >> 16) & MASK).wrapping_mul(MUL2);
    (u64::from((v1.wrapping_add(v2) >> 32) as u32), k)
}

/// The number at the start of `s` and the bytes it takes, when it is a plain decimal number
/// of the fast-path kind (module docs); `None` otherwise (nothing is said about `s` then).
pub(crate) fn parse_plain(s: &[u8]) -> Option<(f64, usize)> {
    let (neg, mut i) = match s.first() {
        Some(b'-') => (true, 1),
        Some(b'+') => (false, 1),
        _ => (false, 0),
    };
    let (mut m, n_int) = digits8(s, i);
    if n_int == 8 {
        // eight or more integer digits: rare in data lines, left to the exact parser
        return None;
    }
    i += n_int;
    let mut n_frac = 0usize;
    if s.get(i) == Some(&b'.') {
        i += 1;
        for _ in 0..3 {
            let (v, k) = digits8(s, i);
            m = m.wrapping_mul(*POW10_U64.get(k)?).wrapping_add(v);
            i += k;
            n_frac += k;
            if k < 8 {
                break;
            }
        }
    }
    let n = n_int + n_frac;
    // no digit, more than 19 (m may have wrapped), or more digits than read
    if n == 0 || n > 19 || s.get(i).is_some_and(u8::is_ascii_digit) {
        return None;
    }
    let mut q = -(n_frac as i64);
    if let Some(&c) = s.get(i) {
        if c == b'e' || c == b'E' {
            let (eneg, j) = match s.get(i + 1) {
                Some(b'-') => (true, i + 2),
                Some(b'+') => (false, i + 2),
                _ => (false, i + 1),
            };
            let (e, k) = digits8(s, j);
            // no exponent digits, or more than four: the exact parser decides
            if k == 0 || k > 4 {
                return None;
            }
            q += if eneg { -(e as i64) } else { e as i64 };
            i = j + k;
        }
    }
    if m > (1u64 << 53) || !(-22..=22).contains(&q) {
        return None;
    }
    let p = *POW10.get(q.unsigned_abs() as usize)?;
    let a = m as f64;
    let v = if q < 0 { a / p } else { a * p };
    Some((if neg { -v } else { v }, i))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The naive count and value of the leading digits (at most eight).
    fn naive_digits8(s: &[u8], at: usize) -> (u64, usize) {
        let mut v = 0u64;
        let mut k = 0usize;
        while k < 8 {
            match s.get(at + k) {
                Some(c) if c.is_ascii_digit() => {
                    v = v * 10 + u64::from(c - b'0');
                    k += 1;
                }
                _ => break,
            }
        }
        (v, k)
    }

    #[test]
    fn digits8_counts_and_reads_every_byte_after_every_digit_run() {
        // every byte value after 0..=8 digits, with every byte value after it too (borrows and
        // carries from a non-digit byte must not matter), at the end of the slice or not
        for run in 0..=8usize {
            let digits: Vec<u8> = (0..run).map(|i| b"9081726354"[i % 10]).collect();
            for b in 0..=255u8 {
                for after in [0u8, b'0', b'9', 0x2f, 0x3a, 0x80, 0xb0, 0xba, 0xff] {
                    let mut s = digits.clone();
                    s.push(b);
                    s.push(after);
                    s.extend_from_slice(b"12345678");
                    assert_eq!(digits8(&s, 0), naive_digits8(&s, 0), "{s:?}");
                    let cut = &s[..run + 1];
                    assert_eq!(digits8(cut, 0), naive_digits8(cut, 0), "{cut:?}");
                }
            }
            let s = digits.clone();
            assert_eq!(digits8(&s, 0), naive_digits8(&s, 0), "{s:?}");
            assert_eq!(digits8(&s, run + 3), (0, 0));
        }
    }

    /// `parse_plain` where it answers: the bits of `str::parse` and the whole token.
    fn agrees(t: &str) -> Result<bool, TestCaseError> {
        let mut line = t.as_bytes().to_vec();
        line.extend_from_slice(b" 1.5");
        match parse_plain(&line) {
            Some((v, used)) => {
                prop_assert_eq!(used, t.len(), "{}", t);
                let r: f64 = t.parse().map_err(|_| TestCaseError::fail(t.to_string()))?;
                prop_assert_eq!(v.to_bits(), r.to_bits(), "{}", t);
                Ok(true)
            }
            None => Ok(false),
        }
    }

    #[test]
    fn plain_numbers_of_the_data_files_take_the_fast_path_and_parse_exactly() {
        for t in [
            "200000.005",
            "-4.514718900277834e-7",
            "-4.907465952629882e-2",
            "0",
            "-0",
            "5.",
            ".5",
            "+7",
            "1e22",
            "1e-22",
            "9007199.254740992",
            "0.1",
            "3.0E+2",
            "1234567.12345678",
            "0.000123456789012345",
        ] {
            assert!(agrees(t).unwrap(), "{t}");
        }
        for t in [
            "1e23",
            "9007199.254740993",
            "9007199254740992",
            "12345678",
            "1e",
            "1e+",
            "-",
            ".",
            "e5",
            "1e12345",
        ] {
            let mut line = t.as_bytes().to_vec();
            line.push(b' ');
            assert_eq!(parse_plain(&line), None, "{t}");
        }
    }

    proptest! {
        #[test]
        fn shortest_and_exponent_forms_parse_to_the_same_bits(bits in any::<u64>(), scale in -30i32..10) {
            let x = f64::from_bits(bits);
            prop_assume!(x.is_finite());
            // values of the data files' magnitudes, and raw bit patterns
            let y = (x.abs().fract() + 0.5) * 10f64.powi(scale) * x.signum();
            for v in [x, y] {
                for t in [format!("{v}"), format!("{v:e}"), format!("{v:.3}"), format!("{v:.9e}")] {
                    agrees(&t)?;
                }
            }
        }

        #[test]
        fn any_short_token_parses_exactly_or_is_left(t in "[+-]?[0-9]{0,9}(\\.[0-9]{0,20})?([eE][+-]?[0-9]{0,3})?") {
            if agrees(&t)? {
                prop_assert!(t.parse::<f64>().is_ok());
            }
        }
    }
}
