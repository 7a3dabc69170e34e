//! The properties the fuzz targets (`fuzz/`) check, as plain functions so the saved corpus and
//! any crasher also run as ordinary regression tests (`tests/it/fuzz_corpus.rs`). Each function
//! panics when a property is violated; bad input itself must only ever produce errors.

use crate::capture::CaptureReader;
use nav_core::wire::{encode, FrameDecoder, MAX_FRAME_LEN};
use nav_io::gnss::{GnssStream, NmeaAssembler, NmeaOptions};

/// Splits off the first byte as a chunk size (so fuzzers explore chunking too).
fn chunking(data: &[u8]) -> Option<(usize, &[u8])> {
    data.split_first()
        .map(|(c, rest)| (usize::from(*c).max(1), rest))
}

/// Wire decoder: no panic; every non-empty 0x00-terminated chunk is delivered or rejected
/// exactly once; every delivered frame re-encodes to bytes that decode to the same frame.
pub fn wire_decoder(data: &[u8]) {
    let Some((chunk, bytes)) = chunking(data) else {
        return;
    };
    let mut d = FrameDecoder::new();
    let mut results = 0usize;
    for piece in bytes.chunks(chunk) {
        for r in d.feed(piece) {
            results += 1;
            if let Ok(f) = r {
                let mut buf = [0u8; MAX_FRAME_LEN];
                let n = encode(&f, &mut buf).expect("a decoded frame must re-encode");
                let mut d2 = FrameDecoder::new();
                let again: Vec<_> = d2.feed(&buf[..n]).collect();
                assert_eq!(again.len(), 1, "re-encoded frame is one chunk");
                let g = again[0].as_ref().expect("re-encoded frame must decode");
                let mut b2 = [0u8; MAX_FRAME_LEN];
                let n2 = encode(g, &mut b2).expect("re-encode");
                assert_eq!(&buf[..n], &b2[..n2], "decode/encode is a fixed point");
            }
        }
    }
    let mut chunks = 0usize;
    let mut len = 0usize;
    for &b in bytes {
        if b == 0 {
            chunks += usize::from(len > 0);
            len = 0;
        } else {
            len += 1;
        }
    }
    let s = d.stats();
    assert_eq!(results, chunks, "one result per chunk");
    assert_eq!(s.frames_ok as usize + s.rejected() as usize, chunks);
    assert_eq!(s.bytes, bytes.len() as u64);
}

/// NMEA assembler on arbitrary text lines: no panic.
pub fn nmea(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let mut a = NmeaAssembler::new(NmeaOptions {
        leap_seconds: 18,
        hdop_uere_m: Some(2.0),
        velocity_std_mps: Some((0.1, 0.2)),
    });
    for line in text.split('\n') {
        let _ = a.push_sentence(line);
    }
    let _ = a.flush();
}

/// Mixed UBX/NMEA/RTCM stream on arbitrary bytes and chunking: no panic, every byte counted.
pub fn gnss_stream(data: &[u8]) {
    let Some((chunk, bytes)) = chunking(data) else {
        return;
    };
    let mut s = GnssStream::new(NmeaOptions::default());
    for piece in bytes.chunks(chunk) {
        let _ = s.feed(piece);
    }
    let _ = s.finish();
    assert_eq!(s.stats().bytes, bytes.len() as u64);
}

/// Capture reader on arbitrary bytes: no panic.
pub fn capture(data: &[u8]) {
    if let Ok(rd) = CaptureReader::new(data) {
        for r in rd {
            if r.is_err() {
                break;
            }
        }
    }
}
