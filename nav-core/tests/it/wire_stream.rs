//! Property tests of the streaming decoder: any sequence of valid frames, cut into arbitrary
//! chunks, decodes to the same frames; arbitrary bytes never panic and every chunk is
//! accounted for exactly once.
use crate::wire_common;

use nav_core::wire::{Decoder, Frame, FrameDecoder, MsgType, NUM_STREAMS};
use proptest::prelude::*;
use wire_common::*;

/// Cuts `bytes` at the given (sorted, deduplicated) positions and feeds the pieces.
fn feed_in_pieces<const CAP: usize>(
    d: &mut Decoder<CAP>,
    bytes: &[u8],
    cuts: &[usize],
) -> Vec<Result<Frame, nav_core::wire::DecodeError>> {
    let mut out = Vec::new();
    let mut prev = 0;
    let mut cuts: Vec<usize> = cuts.iter().map(|c| c % (bytes.len() + 1)).collect();
    cuts.sort_unstable();
    cuts.push(bytes.len());
    for c in cuts {
        out.extend(d.feed(&bytes[prev..c]));
        prev = c;
    }
    out
}

/// Number of non-empty 0x00-terminated chunks: an independent count of what the decoder must
/// report (frames + rejections).
fn terminated_chunks(bytes: &[u8]) -> usize {
    let mut n = 0;
    let mut len = 0;
    for &b in bytes {
        if b == 0 {
            if len > 0 {
                n += 1;
            }
            len = 0;
        } else {
            len += 1;
        }
    }
    n
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn valid_frames_in_any_chunking_decode_to_the_same_frames(
        frames in proptest::collection::vec(frame(), 1..40),
        cuts in proptest::collection::vec(any::<usize>(), 0..60),
        leading_zeros in 0usize..3,
    ) {
        let mut bytes = vec![0u8; leading_zeros];
        for f in &frames {
            bytes.extend(wire_bytes(f));
        }
        let mut d = FrameDecoder::new();
        let got = feed_in_pieces(&mut d, &bytes, &cuts);
        prop_assert_eq!(got.len(), frames.len());
        for (g, f) in got.iter().zip(&frames) {
            let g = g.as_ref().map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert!(same_frame(g, f), "decoded {:?}\n  sent {:?}", g, f);
        }
        let s = d.stats();
        prop_assert_eq!(s.frames_ok as usize, frames.len());
        prop_assert_eq!(s.rejected(), 0);
        prop_assert_eq!(s.bytes, bytes.len() as u64);
        prop_assert_eq!(d.pending_len(), 0);
    }

    #[test]
    fn byte_at_a_time_equals_one_slice(frames in proptest::collection::vec(frame(), 1..10)) {
        let bytes: Vec<u8> = frames.iter().flat_map(wire_bytes).collect();
        let mut a = FrameDecoder::new();
        let whole: Vec<_> = a.feed(&bytes).collect();
        let mut b = FrameDecoder::new();
        let single: Vec<_> = bytes.iter().filter_map(|&x| b.push_byte(x)).collect();
        prop_assert_eq!(whole.len(), single.len());
        for (x, y) in whole.iter().zip(&single) {
            prop_assert!(same_frame(x.as_ref().unwrap(), y.as_ref().unwrap()));
        }
        prop_assert_eq!(a.stats(), b.stats());
    }

    #[test]
    fn random_bytes_never_panic_and_every_chunk_is_counted_once(
        bytes in proptest::collection::vec(
            prop_oneof![3 => any::<u8>(), 1 => Just(0u8), 1 => 1u8..4], 0..3000),
        cuts in proptest::collection::vec(any::<usize>(), 0..40),
    ) {
        let mut d = FrameDecoder::new();
        let out = feed_in_pieces(&mut d, &bytes, &cuts);
        let s = *d.stats();
        let chunks = terminated_chunks(&bytes);
        prop_assert_eq!(out.len(), chunks);
        prop_assert_eq!(s.frames_ok as usize + s.rejected() as usize, chunks);
        prop_assert_eq!(out.iter().filter(|r| r.is_ok()).count(), s.frames_ok as usize);
        prop_assert_eq!(s.bytes, bytes.len() as u64);
        // Messages render without panicking.
        for e in out.iter().filter_map(|r| r.as_ref().err()) {
            prop_assert!(!e.to_string().is_empty());
        }
    }

    #[test]
    fn small_decoder_rejects_long_frames_as_overflow_and_recovers(
        frames in proptest::collection::vec(frame(), 1..20),
    ) {
        // A 80-byte decoder holds IMU (76), config (46) and health (54) frames but not GNSS
        // (117) or nav (132) frames.
        let mut d = Decoder::<80>::new();
        let bytes: Vec<u8> = frames.iter().flat_map(wire_bytes).collect();
        let out: Vec<_> = d.feed(&bytes).collect();
        prop_assert_eq!(out.len(), frames.len());
        for (r, f) in out.iter().zip(&frames) {
            let fits = f.payload.msg_type().frame_len() - 1 <= 80;
            prop_assert_eq!(r.is_ok(), fits);
        }
    }
}

#[test]
fn sequence_wrap_at_65536_is_not_a_loss() {
    let mut d = FrameDecoder::new();
    let mut bytes = Vec::new();
    for seq in [65533u16, 65534, 65535, 0, 1, 3] {
        bytes.extend(wire_bytes(&Frame {
            seq,
            flags: 0,
            payload: sample_imu(),
        }));
    }
    assert_eq!(d.feed(&bytes).filter(|r| r.is_ok()).count(), 6);
    assert_eq!(
        d.stats().lost_by_stream,
        [1, 0, 0, 0, 0],
        "only seq 2 is missing"
    );
}

#[test]
fn streams_are_counted_separately() {
    let mut d = FrameDecoder::new();
    let mut bytes = Vec::new();
    let frames = [
        (sample_imu(), 10u16),
        (sample_gnss(), 100),
        (sample_imu(), 11),
        (sample_imu(), 14), // 12, 13 lost
        (sample_gnss(), 101),
        (sample_nav(), 7),
        (sample_gnss(), 105), // 102..104 lost
        (sample_imu(), 12),   // backwards: duplicate or unannounced restart
    ];
    for (p, seq) in frames {
        bytes.extend(wire_bytes(&Frame {
            seq,
            flags: 0,
            payload: p,
        }));
    }
    let n = d.feed(&bytes).count();
    assert_eq!(n, frames.len());
    let s = d.stats();
    assert_eq!(s.lost_by_stream, [2, 3, 0, 0, 0]);
    assert_eq!(s.backwards_by_stream, [1, 0, 0, 0, 0]);
    let mut by_stream = [0u32; NUM_STREAMS];
    by_stream[MsgType::Imu.stream_index()] = 4;
    by_stream[MsgType::Gnss.stream_index()] = 3;
    by_stream[MsgType::Nav.stream_index()] = 1;
    assert_eq!(s.frames_ok_by_stream, by_stream);
}
