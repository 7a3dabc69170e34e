//! Consistent Overhead Byte Stuffing (Cheshire & Baker, 1999): removes every 0x00 from a
//! packet so 0x00 can delimit packets on a byte stream.
//!
//! An encoded packet is a sequence of blocks `code, data[code - 1]`: the block's data bytes
//! are non-zero and are followed, in the decoded packet, by one 0x00 unless `code == 0xFF`
//! (a full 254-byte run) or the block is the last one. Overhead: at most
//! `ceil(n / 254)` bytes (1 byte for packets up to 254 bytes).

/// Errors of COBS decoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CobsError {
    /// A 0x00 byte inside an encoded packet.
    ZeroByte {
        /// Offset of the zero in the encoded packet.
        at: usize,
    },
    /// A block's code points past the end of the encoded packet.
    Truncated {
        /// Offset of the block's code byte in the encoded packet.
        at: usize,
    },
}

impl core::fmt::Display for CobsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::ZeroByte { at } => write!(f, "COBS: zero byte at offset {at}"),
            Self::Truncated { at } => {
                write!(
                    f,
                    "COBS: block starting at offset {at} runs past the packet end"
                )
            }
        }
    }
}

impl core::error::Error for CobsError {}

/// Index of the first 0x00 in `b`, scanning eight bytes at a time (SWAR: a word has a zero
/// byte when `(x - 0x01..01) & !x & 0x80..80 != 0`).
pub fn find_zero(b: &[u8]) -> Option<usize> {
    const LO: u64 = 0x0101_0101_0101_0101;
    const HI: u64 = 0x8080_8080_8080_8080;
    let mut words = b.chunks_exact(8);
    let mut base = 0usize;
    for w in &mut words {
        let x = u64::from_le_bytes(w.try_into().unwrap_or([1; 8]));
        if x.wrapping_sub(LO) & !x & HI != 0 {
            return w.iter().position(|&v| v == 0).map(|i| base + i);
        }
        base += 8;
    }
    words
        .remainder()
        .iter()
        .position(|&v| v == 0)
        .map(|i| base + i)
}

/// Largest encoded size (without delimiter) of a packet of `n` bytes.
pub const fn max_encoded_len(n: usize) -> usize {
    n + n / 254 + 1
}

/// Encodes `src` into `dst` (no delimiter is written). Returns the encoded length, or `None`
/// when `dst` is too short (`dst` is then partly written).
pub fn encode(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    let mut code_at = 0usize; // where the current block's code byte goes
    let mut write = 1usize; // next data byte position
    let mut code: u8 = 1;
    // Reserve the first code byte.
    if dst.is_empty() {
        return None;
    }
    for &b in src {
        if b == 0 {
            *dst.get_mut(code_at)? = code;
            code_at = write;
            write += 1;
            code = 1;
        } else {
            *dst.get_mut(write)? = b;
            write += 1;
            code += 1;
            if code == 0xFF {
                *dst.get_mut(code_at)? = code;
                code_at = write;
                write += 1;
                code = 1;
            }
        }
    }
    *dst.get_mut(code_at)? = code;
    Some(write)
}

/// Decodes the encoded packet in `buf` in place; returns the decoded length (the decoded
/// packet is `buf[..len]`). The decoded packet is never longer than the encoded one.
pub fn decode_in_place(buf: &mut [u8]) -> Result<usize, CobsError> {
    let len = buf.len();
    if let Some(at) = find_zero(buf) {
        return Err(CobsError::ZeroByte { at });
    }
    let mut read = 0usize;
    let mut write = 0usize;
    while read < len {
        let code_at = read;
        // No zero anywhere (checked above), so the code is 1..=255.
        let code = buf.get(read).copied().unwrap_or(1);
        read += 1;
        let n = usize::from(code).saturating_sub(1);
        let end = read + n;
        if end > len {
            return Err(CobsError::Truncated { at: code_at });
        }
        buf.copy_within(read..end, write);
        write += n;
        read = end;
        if code != 0xFF && read < len {
            if let Some(slot) = buf.get_mut(write) {
                *slot = 0;
            }
            write += 1;
        }
    }
    Ok(write)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip(src: &[u8]) -> ([u8; 600], usize) {
        let mut enc = [0u8; 600];
        let n = encode(src, &mut enc).unwrap();
        assert!(n <= max_encoded_len(src.len()));
        assert!(enc[..n].iter().all(|&b| b != 0));
        let encoded = enc;
        let m = decode_in_place(&mut enc[..n]).unwrap();
        assert_eq!(&enc[..m], src);
        (encoded, n)
    }

    #[test]
    fn cobs_paper_examples_encode_as_published() {
        // Examples from the COBS literature (Wikipedia "Consistent Overhead Byte Stuffing").
        let (e, n) = roundtrip(&[0x00]);
        assert_eq!(&e[..n], &[0x01, 0x01]);
        let (e, n) = roundtrip(&[0x00, 0x00]);
        assert_eq!(&e[..n], &[0x01, 0x01, 0x01]);
        let (e, n) = roundtrip(&[0x11, 0x22, 0x00, 0x33]);
        assert_eq!(&e[..n], &[0x03, 0x11, 0x22, 0x02, 0x33]);
        let (e, n) = roundtrip(&[0x11, 0x00, 0x00, 0x00]);
        assert_eq!(&e[..n], &[0x02, 0x11, 0x01, 0x01, 0x01]);
        let (e, n) = roundtrip(&[]);
        assert_eq!(&e[..n], &[0x01]);
    }

    #[test]
    fn cobs_long_runs_roundtrip() {
        let mut v = [0u8; 520];
        for (i, b) in v.iter_mut().enumerate() {
            *b = (i % 255 + 1) as u8;
        }
        for len in [253, 254, 255, 508, 509, 520] {
            roundtrip(&v[..len]);
        }
        v[254] = 0;
        roundtrip(&v);
    }

    #[test]
    fn find_zero_agrees_with_a_plain_scan() {
        let mut v = [7u8; 40];
        assert_eq!(find_zero(&v), None);
        for z in 0..40 {
            v = [7u8; 40];
            v[z] = 0;
            v[(z + 13) % 40] = 0;
            for start in 0..8 {
                let want = v[start..].iter().position(|&b| b == 0);
                assert_eq!(find_zero(&v[start..]), want, "zero at {z}, start {start}");
            }
        }
        // Bytes >= 0x80 and 0x01 must not look like zeros.
        assert_eq!(
            find_zero(&[0x80, 0x01, 0xFF, 0x81, 0x01, 0x01, 0x80, 0x7F, 0x01]),
            None
        );
    }

    #[test]
    fn cobs_rejects_zero_and_truncation() {
        let mut b = [0x03, 0x11, 0x00];
        assert_eq!(decode_in_place(&mut b), Err(CobsError::ZeroByte { at: 2 }));
        let mut b = [0x05, 0x11, 0x22];
        assert_eq!(decode_in_place(&mut b), Err(CobsError::Truncated { at: 0 }));
        let mut out = [0u8; 2];
        assert_eq!(encode(&[1, 2, 3], &mut out), None);
    }
}
