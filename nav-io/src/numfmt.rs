//! Fast float formatting that writes exactly what Rust's `core::fmt` writes, byte for byte.
//!
//! * Shortest form, `format!("{x}")` ([`LineBuf::push_f64`]): the shortest digits that read
//!   back to the same bits, in positional notation, no exponent. The digits come from `zmij`
//!   (shortest round-trip, closest to the value, like `Display`; about twice as fast as
//!   `ryu`). The two pick different digits in one case only: an exact tie, when the value lies
//!   exactly halfway between the two closest shortest candidates (e.g. -1514017065704403.25:
//!   `Display` writes `.2`, the shortest-digit crates `.3`). A tie needs an exact decimal
//!   expansion of at most 18 significant digits; such values (and integers from 2^53 up) are
//!   sent to `Display` itself, so the text is always `Display`'s.
//! * Fixed precision, `format!("{x:.P}")` ([`LineBuf::push_fixed`]), and exponent form with
//!   precision, `format!("{x:.Pe}")` ([`LineBuf::push_exp`]): `core::fmt` rounds the EXACT
//!   binary value to P decimals (P + 1 significant digits). Here `|x| 10^k` is computed with
//!   ONE correctly rounded multiplication or division by an exactly representable power of
//!   ten (10^0..10^22), so the computed `y` is within half an ulp of the exact product; when
//!   `y`'s fraction is farther than one ulp from one half, the exact product rounds to the same
//!   integer as `y`, which gives the digits. Otherwise (a possible tie, a magnitude beyond the
//!   exact powers, more than 2^52, zero in exponent form, non-finite) the number is written by
//!   `core::fmt` itself. So the text is always `core::fmt`'s.
//!
//! All three are checked against `format!` over random bit patterns, tie-prone values and the
//! value ranges of the run outputs in the tests (`tests/it/numfmt.rs`).

use std::io::Write;

/// Longest text written through the fast path (longer numbers go through `Display`).
const FAST_MAX: usize = 48;

/// Text assembled in a buffer of `CAP` bytes (default 512, one line on the stack) and written
/// with one `write_all` when it is flushed or full (a longer text is written in pieces). A
/// large buffer (e.g. [`BlockBuf`]) holds many lines and writes them in blocks.
pub struct LineBuf<const CAP: usize = 512> {
    buf: [u8; CAP],
    len: usize,
}

/// A [`LineBuf`] of 128 KiB, kept on the heap: many lines written in blocks (no write per
/// line; a block larger than a 64 KiB `BufWriter` goes past its buffer, no second copy).
pub type BlockBuf = LineBuf<{ 128 << 10 }>;

impl Default for LineBuf {
    fn default() -> Self {
        Self::new()
    }
}

impl LineBuf {
    /// An empty line.
    pub fn new() -> Self {
        Self {
            buf: [0; 512],
            len: 0,
        }
    }
}

impl BlockBuf {
    /// An empty block buffer on the heap.
    pub fn boxed() -> Box<Self> {
        Box::new(Self {
            buf: [0; 128 << 10],
            len: 0,
        })
    }
}

impl<const CAP: usize> LineBuf<CAP> {
    /// An empty buffer of `CAP` bytes (by value: on the stack for a small `CAP`; see
    /// [`BlockBuf::boxed`] for the large one).
    pub fn new_block() -> Self {
        Self {
            buf: [0; CAP],
            len: 0,
        }
    }

    /// Bytes held, not yet written.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Appends one byte (flushing to `w` first when the buffer is full).
    pub fn push_byte<W: Write + ?Sized>(&mut self, w: &mut W, b: u8) -> std::io::Result<()> {
        if self.len >= CAP {
            self.flush(w)?;
        }
        if let Some(d) = self.buf.get_mut(self.len) {
            *d = b;
            self.len += 1;
        }
        Ok(())
    }

    /// Appends raw bytes (flushing to `w` first when they would not fit).
    pub fn push_bytes<W: Write + ?Sized>(&mut self, w: &mut W, b: &[u8]) -> std::io::Result<()> {
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

    /// Appends what `fast` writes, formatted in place (the line is flushed to `w` first when
    /// fewer than [`FAST_MAX`] bytes are free); when `fast` declines (`None`), the line is
    /// flushed and `slow` writes to `w`.
    fn push_with<W: Write + ?Sized>(
        &mut self,
        w: &mut W,
        fast: impl FnOnce(&mut [u8; FAST_MAX]) -> Option<usize>,
        slow: impl FnOnce(&mut W) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        if self.len + FAST_MAX > self.buf.len() {
            self.flush(w)?;
        }
        let dst = self
            .buf
            .get_mut(self.len..self.len + FAST_MAX)
            .and_then(|d| <&mut [u8; FAST_MAX]>::try_from(d).ok());
        if let Some(n) = dst.and_then(fast) {
            self.len += n;
            return Ok(());
        }
        self.flush(w)?;
        slow(w)
    }

    /// Appends `x` as `Display` writes it.
    pub fn push_f64<W: Write + ?Sized>(&mut self, w: &mut W, x: f64) -> std::io::Result<()> {
        self.push_with(w, |d| display_f64(x, d), |w| write!(w, "{x}"))
    }

    /// Appends each of `xs` after a space, as `Display` writes it (`" {x}"` per number), with
    /// one check of the free room for all of them (the buffer is flushed to `w` first when
    /// fewer than `xs.len() * (1 + FAST_MAX)` bytes are free): the separators and the digits
    /// go straight into the buffer. A number the fast path declines is written by `Display`
    /// after a flush, as [`LineBuf::push_f64`] does.
    pub fn push_spaced_f64s<W: Write + ?Sized>(
        &mut self,
        w: &mut W,
        xs: &[f64],
    ) -> std::io::Result<()> {
        self.push_spaced_with(w, xs, display_f64, |w, x| write!(w, "{x}"))
    }

    /// Appends each of `xs` after a space as `format!(" {x:.P$}")` writes it (`P` decimals,
    /// rounded from the exact value), with one check of the free room for all of them, as
    /// [`LineBuf::push_spaced_f64s`] does. The precision is a constant: the divisions by
    /// `10^P` become multiplications and the formatting is inlined.
    #[inline(always)]
    pub fn push_spaced_fixed<const P: usize, W: Write + ?Sized>(
        &mut self,
        w: &mut W,
        xs: &[f64],
    ) -> std::io::Result<()> {
        self.push_spaced_with(w, xs, fixed_const::<P>, |w, x| write!(w, "{x:.P$}"))
    }

    /// Appends each of `xs` after a space as `format!(" {x:.P$e}")` writes it (`P + 1`
    /// significant digits, rounded from the exact value), with one check of the free room for
    /// all of them, as [`LineBuf::push_spaced_f64s`] does. The precision is a constant: the
    /// divisions by `10^P` become multiplications and the formatting is inlined.
    #[inline(always)]
    pub fn push_spaced_exp<const P: usize, W: Write + ?Sized>(
        &mut self,
        w: &mut W,
        xs: &[f64],
    ) -> std::io::Result<()> {
        self.push_spaced_with(w, xs, exp_const::<P>, |w, x| write!(w, "{x:.P$e}"))
    }

    /// Appends each of `xs` after a space, written by `fast` into the buffer (one check of the
    /// free room for all of them), or by `slow` to `w` after a flush when `fast` declines.
    #[inline(always)]
    fn push_spaced_with<W: Write + ?Sized>(
        &mut self,
        w: &mut W,
        xs: &[f64],
        fast: impl Fn(f64, &mut [u8; FAST_MAX]) -> Option<usize>,
        slow: impl Fn(&mut W, f64) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        const SLOT: usize = 1 + FAST_MAX;
        if self.len + xs.len() * SLOT > CAP {
            self.flush(w)?;
        }
        for &x in xs {
            let at = self.len;
            let slot = self
                .buf
                .get_mut(at..at + SLOT)
                .and_then(|d| d.split_first_mut())
                .and_then(|(sp, d)| Some((sp, <&mut [u8; FAST_MAX]>::try_from(d).ok()?)));
            let Some((sp, dst)) = slot else {
                // a buffer too small for the whole line: number by number
                self.push_byte(w, b' ')?;
                self.push_with(w, |d| fast(x, d), |w| slow(w, x))?;
                continue;
            };
            *sp = b' ';
            match fast(x, dst) {
                Some(n) => self.len = at + 1 + n,
                None => {
                    self.len = at + 1;
                    self.flush(w)?;
                    slow(w, x)?;
                }
            }
        }
        Ok(())
    }

    /// Appends an unsigned integer.
    pub fn push_u64<W: Write + ?Sized>(&mut self, w: &mut W, v: u64) -> std::io::Result<()> {
        // the digits, two at a time from the last, at the start of a scratch of fixed size,
        // which goes to the buffer in one fixed-size move when the buffer has room for it
        let n = 1 + POW10_U64.iter().skip(1).take_while(|&&p| v >= p).count();
        let mut tmp = [b'0'; 20];
        let mut len = 0usize;
        put_width_digits(&mut tmp, &mut len, v, n).unwrap_or(());
        if self.len + tmp.len() <= CAP {
            if let Some(dst) = self.buf.get_mut(self.len..self.len + tmp.len()) {
                dst.copy_from_slice(&tmp);
                self.len += len;
                return Ok(());
            }
        }
        self.push_bytes(w, tmp.get(..len).unwrap_or(&[]))
    }

    /// Appends `x` as `format!("{x:.prec$}")` writes it (`prec` decimals, rounded from the
    /// exact value).
    pub fn push_fixed<W: Write + ?Sized>(
        &mut self,
        w: &mut W,
        x: f64,
        prec: usize,
    ) -> std::io::Result<()> {
        self.push_with(w, |d| fixed_f64(x, prec, d), |w| write!(w, "{x:.prec$}"))
    }

    /// Appends `x` as `format!("{x:.prec$e}")` writes it (`prec + 1` significant digits,
    /// rounded from the exact value; exponent without sign for >= 0, e.g. `1.745329e-4`).
    pub fn push_exp<W: Write + ?Sized>(
        &mut self,
        w: &mut W,
        x: f64,
        prec: usize,
    ) -> std::io::Result<()> {
        self.push_with(w, |d| exp_f64(x, prec, d), |w| write!(w, "{x:.prec$e}"))
    }

    /// Drops the bytes not yet written (a line left over by a failed write).
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Writes the buffered bytes to `w`.
    pub fn flush<W: Write + ?Sized>(&mut self, w: &mut W) -> std::io::Result<()> {
        let r = w.write_all(self.buf.get(..self.len).unwrap_or(&[]));
        self.len = 0;
        r
    }
}

/// Whether `x` (finite, non-zero) may be an exact tie between two shortest candidates, where
/// the shortest-digit crates and `Display` may pick different digits: its exact decimal
/// expansion has at most 18 significant digits, or it is an integer of 2^53 or more.
#[inline(always)]
fn maybe_tie(x: f64) -> bool {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    // The common case first, in a few instructions: a normal x = m 2^e whose significand m
    // (bit 52 set, so at most 52 trailing zeros) reduced by its trailing zeros leaves
    // k = 1075 - biased - tz >= 27 binary places after the point, more than 18 digits.
    let tz = (bits | (1u64 << 52)).trailing_zeros() as i32;
    if biased != 0 && 1075 - biased - tz >= 27 {
        return false;
    }
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
static POW5: [u64; 27] = {
    let mut t = [1u64; 27];
    let mut i = 1;
    while i < 27 {
        t[i] = t[i - 1] * 5;
        i += 1;
    }
    t
};

/// Writes `x` as `format!("{x}")` would into `out`; `None` when the fast path does not apply
/// (non-finite, possible tie, or longer than `out`): the caller uses `Display` then. Inlined
/// into the callers' loops (no call, no register saves per number); the rare text with an
/// exponent is rewritten out of line (`positional_from_exp`).
#[inline(always)]
pub(crate) fn display_f64(x: f64, out: &mut [u8; FAST_MAX]) -> Option<usize> {
    // The common case in two comparisons: a normal x = m 2^e with 2^-13 <= |x| (biased
    // exponent 1010 or more) whose significand m reduced by its trailing zeros leaves 27 or
    // more binary places after the point (`maybe_tie`'s first test: not a tie; and |x| < 2^26).
    // Then |x| is within zmij's positional range [1e-4, 1e15) and not an integer, so zmij's
    // text is `Display`'s as it is: no ".0" to strip, no exponent to look for.
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let tz = (bits | (1u64 << 52)).trailing_zeros() as i32;
    if biased >= 1010 && biased + tz <= 1075 - 27 {
        let mut rb = zmij::Buffer::new();
        let s = rb.format_finite(x).as_bytes();
        copy_short(out, s)?;
        return Some(s.len());
    }
    display_f64_other(x, out)
}

/// [`display_f64`] for the values outside its common case: zero, non-finite, possible ties,
/// integers, |x| below 2^-13 or from 2^26 up.
#[inline(never)]
fn display_f64_other(x: f64, out: &mut [u8; FAST_MAX]) -> Option<usize> {
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
    let mut rb = zmij::Buffer::new();
    let s = rb.format_finite(x).as_bytes();
    // Within its positional range zmij writes what `Display` does, except that an integer
    // gets ".0" ("12.0" where `Display` writes "12"); outside it, an exponent.
    // zmij writes positionally when the decimal exponent of the shortest digits is in
    // -5..=15, so for 1e-4 <= |x| < 1e15 (exponent -4..=15 whatever the digits) there is no
    // exponent to look for; otherwise an exponent ("e-7", "e16", "e-308") is within the last
    // 5 bytes: no memchr call
    let ax = x.abs();
    if (1e-4..1e15).contains(&ax) || !s.iter().rev().take(5).any(|&c| c == b'e') {
        let s = s.strip_suffix(b".0").unwrap_or(s);
        copy_short(out, s)?;
        return Some(s.len());
    }
    positional_from_exp(s, out)
}

/// zmij's text of a number with an exponent (`s`, e.g. `-1.5e-7`, `1e16`) written positionally
/// into `out` as `Display` writes it; `None` when it does not fit or is not such a text.
#[inline(never)]
fn positional_from_exp(s: &[u8], out: &mut [u8; FAST_MAX]) -> Option<usize> {
    // Split zmij's text into sign, significant digits and the decimal exponent `p` such that
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

/// Copies `src` (at most [`FAST_MAX`] bytes) to the start of `out` with two overlapping
/// fixed-size moves (no call to `memcpy` for a number's few bytes); `None` when it is longer.
/// Inlined into the number's formatting (no call per number).
#[inline(always)]
fn copy_short(out: &mut [u8; FAST_MAX], src: &[u8]) -> Option<()> {
    /// One fixed-size move of `K` bytes from `src[at..]` to `out[at..]`.
    fn mv<const K: usize>(out: &mut [u8], src: &[u8], at: usize) -> Option<()> {
        let s: [u8; K] = src.get(at..at + K)?.try_into().ok()?;
        out.get_mut(at..at + K)?.copy_from_slice(&s);
        Some(())
    }
    let n = src.len();
    match n {
        0 => Some(()),
        1..=3 => {
            for (d, s) in out.iter_mut().zip(src) {
                *d = *s;
            }
            Some(())
        }
        4..=7 => {
            mv::<4>(out, src, 0)?;
            mv::<4>(out, src, n - 4)
        }
        8..=15 => {
            mv::<8>(out, src, 0)?;
            mv::<8>(out, src, n - 8)
        }
        16..=31 => {
            mv::<16>(out, src, 0)?;
            mv::<16>(out, src, n - 16)
        }
        32..=FAST_MAX => {
            mv::<32>(out, src, 0)?;
            mv::<32>(out, src, n - 32)
        }
        _ => None,
    }
}

/// Exact powers of ten representable in f64: 10^0 ..= 10^22.
static POW10: [f64; 23] = {
    let mut t = [1.0f64; 23];
    let mut i = 1;
    while i < 23 {
        t[i] = t[i - 1] * 10.0;
        i += 1;
    }
    t
};

/// 10^0 ..= 10^19 as integers.
static POW10_U64: [u64; 20] = {
    let mut t = [1u64; 20];
    let mut i = 1;
    while i < 20 {
        t[i] = t[i - 1] * 10;
        i += 1;
    }
    t
};

/// Largest precision handled by the fast paths (`10^(prec + 1)` stays far below 2^52).
const PREC_MAX: usize = 15;

/// The integer nearest to the exact value that `y` (>= 0) approximates within half an ulp
/// (`y` is the correctly rounded result of one operation), or `None` when that value may lie
/// too close to a half-integer to tell from `y` (or `y >= 2^52`).
#[inline(always)]
fn round_exact(y: f64) -> Option<u64> {
    if !(0.0..4_503_599_627_370_496.0).contains(&y) {
        return None;
    }
    // the integer part (y >= 0 and below 2^52: truncation is the floor, and exact; no
    // call to a software `floor`). Through i64, which x86-64 converts to and from f64 in
    // one instruction each (u64 takes a sequence of them); the value fits either way.
    let n = y as i64;
    let f = n as f64;
    // exact: f and y share the binade or f is smaller with coarser-or-equal spacing
    let r = y - f;
    let ulp = f64::from_bits(y.to_bits() + 1) - y;
    if (r - 0.5).abs() <= ulp {
        return None;
    }
    let n = n.unsigned_abs();
    Some(if r > 0.5 { n + 1 } else { n })
}

/// The two-digit groups `00` ..= `99`, back to back.
static DIGIT_PAIRS: [u8; 200] = {
    let mut t = [0u8; 200];
    let mut i = 0;
    while i < 100 {
        t[2 * i] = b'0' + (i / 10) as u8;
        t[2 * i + 1] = b'0' + (i % 10) as u8;
        i += 1;
    }
    t
};

/// Writes `v` in decimal, left-padded with zeros to `width` digits (at most 20), at
/// `out[*len..]`; `v = 0` writes at least one `0`.
fn put_digits(out: &mut [u8], len: &mut usize, v: u64, width: usize) -> Option<()> {
    // two digits per division, last first, into a zero-filled scratch
    let mut tmp = [b'0'; 20];
    let mut i = tmp.len();
    let mut v = v;
    while v >= 100 {
        let r = (v % 100) as usize;
        v /= 100;
        i -= 2;
        tmp.get_mut(i..i + 2)?
            .copy_from_slice(DIGIT_PAIRS.get(2 * r..2 * r + 2)?);
    }
    if v >= 10 {
        let r = v as usize;
        i -= 2;
        tmp.get_mut(i..i + 2)?
            .copy_from_slice(DIGIT_PAIRS.get(2 * r..2 * r + 2)?);
    } else {
        i -= 1;
        *tmp.get_mut(i)? = b'0' + v as u8;
    }
    let n = (tmp.len() - i).max(width);
    let src = tmp.get(tmp.len().checked_sub(n)?..)?;
    out.get_mut(*len..*len + n)?.copy_from_slice(src);
    *len += n;
    Some(())
}

/// `|x| * 10^k` with one correctly rounded operation (`k` in -22..=22), else `None`.
#[inline(always)]
fn scale10(a: f64, k: i32) -> Option<f64> {
    let p = *POW10.get(k.unsigned_abs() as usize)?;
    Some(if k >= 0 { a * p } else { a / p })
}

/// Writes `-` when `negative`, then `n / p10`, and for `prec > 0` a `.` and the `prec` digits of
/// `n % p10` (the mantissa of both the fixed and the exponent form).
#[inline(always)]
fn put_sign_and_digits(
    out: &mut [u8; FAST_MAX],
    len: &mut usize,
    negative: bool,
    n: u64,
    p10: u64,
    prec: usize,
) -> Option<()> {
    if negative {
        *out.get_mut(*len)? = b'-';
        *len += 1;
    }
    let int = n / p10;
    if int < 10 {
        // one digit (always so in exponent form): no scratch
        *out.get_mut(*len)? = b'0' + int as u8;
        *len += 1;
    } else {
        put_digits(out, len, int, 1)?;
    }
    if prec > 0 {
        *out.get_mut(*len)? = b'.';
        *len += 1;
        put_width_digits(out, len, n % p10, prec)?;
    }
    Some(())
}

/// Writes `v` (below 10^`width`) as exactly `width` digits, zeros in front, straight into
/// `out` (two digits at a time from the last; no scratch, no copy of a variable length).
#[inline(always)]
fn put_width_digits(out: &mut [u8], len: &mut usize, v: u64, width: usize) -> Option<()> {
    let dst = out.get_mut(*len..*len + width)?;
    let mut v = v;
    let mut i = width;
    while i >= 2 {
        let r = (v % 100) as usize;
        v /= 100;
        i -= 2;
        let pair = DIGIT_PAIRS.get(2 * r..2 * r + 2)?;
        dst.get_mut(i..i + 2)?.copy_from_slice(pair);
    }
    if i == 1 {
        *dst.first_mut()? = b'0' + (v % 10) as u8;
    }
    *len += width;
    Some(())
}

/// Writes `x` as `format!("{x:.prec$}")` would into `out`; `None` when the fast path does not
/// apply (see the module docs): the caller uses `core::fmt` then.
#[inline(always)]
pub(crate) fn fixed_f64(x: f64, prec: usize, out: &mut [u8; FAST_MAX]) -> Option<usize> {
    if !x.is_finite() || prec > PREC_MAX {
        return None;
    }
    let n = round_exact(scale10(x.abs(), prec as i32)?)?;
    let p10 = *POW10_U64.get(prec)?;
    let mut len = 0usize;
    put_sign_and_digits(out, &mut len, x.is_sign_negative(), n, p10, prec)?;
    Some(len)
}

/// [`fixed_f64`] with the precision `P` a constant (inlined where it is used).
#[inline(always)]
fn fixed_const<const P: usize>(x: f64, out: &mut [u8; FAST_MAX]) -> Option<usize> {
    fixed_f64(x, P, out)
}

/// [`exp_f64`] with the precision `P` a constant (inlined where it is used).
#[inline(always)]
fn exp_const<const P: usize>(x: f64, out: &mut [u8; FAST_MAX]) -> Option<usize> {
    exp_f64(x, P, out)
}

/// Writes `x` as `format!("{x:.prec$e}")` would into `out`; `None` when the fast path does
/// not apply (see the module docs): the caller uses `core::fmt` then.
#[inline(always)]
pub(crate) fn exp_f64(x: f64, prec: usize, out: &mut [u8; FAST_MAX]) -> Option<usize> {
    if !x.is_finite() || x == 0.0 || prec > PREC_MAX {
        return None;
    }
    let a = x.abs();
    let lo = *POW10.get(prec)?;
    let hi = *POW10.get(prec + 1)?;
    // decimal exponent: the estimate from the binary exponent E (floor(E log10 2), a normal
    // |x| = m 2^E with m in [1, 2)) or, for a subnormal, from log10, is off by at most one
    let biased = ((a.to_bits() >> 52) & 0x7ff) as i32;
    let mut e = if biased == 0 {
        a.log10().floor() as i32
    } else {
        // floor(E log10 2) in integers, exact for |E| <= 1650 (78913 / 2^18 ~ log10 2)
        ((biased - 1023) * 78_913) >> 18
    };
    let mut y = scale10(a, prec as i32 - e)?;
    if y < lo {
        e -= 1;
        y = scale10(a, prec as i32 - e)?;
    } else if y >= hi {
        e += 1;
        y = scale10(a, prec as i32 - e)?;
    }
    if !(lo * 0.5..hi * 2.0).contains(&y) {
        return None;
    }
    let mut n = round_exact(y)?;
    let p10 = *POW10_U64.get(prec)?;
    let p10_next = *POW10_U64.get(prec + 1)?;
    // y within an ulp of a power of ten: carry (9.9999995 -> 10.00000) or borrow
    if n >= p10_next {
        if n != p10_next {
            return None;
        }
        n = p10;
        e += 1;
    } else if n < p10 {
        return None;
    }
    let mut len = 0usize;
    put_sign_and_digits(out, &mut len, x.is_sign_negative(), n, p10, prec)?;
    *out.get_mut(len)? = b'e';
    len += 1;
    if e < 0 {
        *out.get_mut(len)? = b'-';
        len += 1;
    }
    let e = e.unsigned_abs();
    if e < 10 {
        *out.get_mut(len)? = b'0' + e as u8;
        len += 1;
    } else {
        put_digits(out, &mut len, u64::from(e), 1)?;
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

    /// The fast paths are taken for the values of the run outputs (a fallback to `core::fmt`
    /// is rare: only near-ties), and agree with `core::fmt` there.
    #[test]
    fn fixed_and_exp_take_the_fast_path_on_typical_values() {
        let mut buf = [0u8; FAST_MAX];
        let (mut fast_fixed, mut fast_exp, mut n) = (0, 0, 0);
        let mut x = 1.234_567_890_123e-9_f64;
        while x < 1e4 {
            for v in [x, -x * 1.000_123] {
                n += 1;
                if let Some(k) = fixed_f64(v, 6, &mut buf) {
                    fast_fixed += 1;
                    assert_eq!(&buf[..k], format!("{v:.6}").as_bytes());
                }
                if let Some(k) = exp_f64(v, 6, &mut buf) {
                    fast_exp += 1;
                    assert_eq!(&buf[..k], format!("{v:.6e}").as_bytes());
                }
            }
            x *= 1.001_713;
        }
        assert!(n > 20_000, "{n}");
        assert_eq!(fast_fixed, n, "fixed: {fast_fixed} of {n} on the fast path");
        assert!(
            fast_exp * 1000 >= n * 999,
            "exp: {fast_exp} of {n} on the fast path"
        );
        // exact decimal halves go to core::fmt (its tie rule)
        assert_eq!(fixed_f64(0.5, 0, &mut buf), None);
        assert_eq!(fixed_f64(2.5, 0, &mut buf), None);
        assert_eq!(exp_f64(0.125, 1, &mut buf), None);
    }

    #[test]
    fn short_copies_are_exact_at_every_length() {
        let src: Vec<u8> = (0..=FAST_MAX as u8).map(|i| b'0' + i % 10).collect();
        for n in 0..=FAST_MAX {
            let mut out = [b'#'; FAST_MAX];
            assert_eq!(copy_short(&mut out, &src[..n]), Some(()), "{n}");
            assert_eq!(&out[..n], &src[..n], "{n}");
            assert!(
                out[n..].iter().all(|&c| c == b'#'),
                "{n}: wrote past the end"
            );
        }
        let mut out = [0u8; FAST_MAX];
        assert_eq!(copy_short(&mut out, &src), None);
    }

    /// Integers are `Display`'s at every digit count, in a buffer with room and in one that
    /// has to be flushed first.
    #[test]
    fn integers_match_display() {
        let mut vals = vec![0u64, 1, 9, 10, 99, 100, 2227, u64::MAX, u64::MAX - 1];
        for k in 1..20 {
            let p = 10u64.pow(k);
            vals.extend([p - 1, p, p + 1]);
        }
        for v in vals {
            let mut out = Vec::new();
            let mut lb = LineBuf::new();
            lb.push_u64(&mut out, v).unwrap();
            lb.flush(&mut out).unwrap();
            assert_eq!(String::from_utf8(out).unwrap(), v.to_string());
            let mut out = Vec::new();
            let mut small = LineBuf::<24>::new_block();
            small.push_bytes(&mut out, b"0123456789").unwrap();
            small.push_u64(&mut out, v).unwrap();
            small.flush(&mut out).unwrap();
            assert_eq!(String::from_utf8(out).unwrap(), format!("0123456789{v}"));
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
