//! The streaming frame decoder: bytes in any chunking in, frames or typed errors out.

use super::{cobs, decode_raw, DecodeError, Frame, FLAG_RESTART, NUM_STREAMS};

/// Counters of a [`Decoder`]. Every non-empty chunk between two delimiters ends up in exactly
/// one of `frames_ok` or the rejection counters, so
/// `chunks = frames_ok + rejected()`; and, per stream, once a stream's latest frame has arrived,
/// `frames sent = frames delivered + lost` (counted from the first frame seen or the last
/// restart).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Bytes fed to the decoder.
    pub bytes: u64,
    /// Frames delivered intact.
    pub frames_ok: u32,
    /// Frames delivered intact, per stream ([`super::MsgType::stream_index`]).
    pub frames_ok_by_stream: [u32; NUM_STREAMS],
    /// Chunks rejected as invalid COBS.
    pub cobs_errors: u32,
    /// Chunks longer than the decoder's buffer.
    pub overflows: u32,
    /// Frames too short for header + CRC, or with a payload length wrong for their type.
    pub length_errors: u32,
    /// Frames whose CRC did not match.
    pub crc_errors: u32,
    /// Frames of another protocol version.
    pub version_mismatches: u32,
    /// Frames of an unknown message type.
    pub unknown_types: u32,
    /// Frames with an out-of-range field value.
    pub invalid_fields: u32,
    /// Partial chunks discarded by [`Decoder::reset_link`] (link lost mid-frame).
    pub truncated: u32,
    /// Frames missing according to sequence-number gaps, per stream.
    pub lost_by_stream: [u32; NUM_STREAMS],
    /// Frames whose sequence number went backwards without the restart flag (duplicate or
    /// unannounced sender restart), per stream; they are delivered and not counted as lost.
    pub backwards_by_stream: [u32; NUM_STREAMS],
    /// Frames carrying the restart flag, per stream.
    pub restarts_by_stream: [u32; NUM_STREAMS],
}

impl DecoderStats {
    /// Chunks rejected for any reason.
    pub fn rejected(&self) -> u32 {
        self.cobs_errors
            .saturating_add(self.overflows)
            .saturating_add(self.length_errors)
            .saturating_add(self.crc_errors)
            .saturating_add(self.version_mismatches)
            .saturating_add(self.unknown_types)
            .saturating_add(self.invalid_fields)
            .saturating_add(self.truncated)
    }

    /// Frames missing by sequence numbers, all streams.
    pub fn lost(&self) -> u32 {
        self.lost_by_stream
            .iter()
            .fold(0u32, |a, &b| a.saturating_add(b))
    }

    fn count_error(&mut self, e: &DecodeError) {
        let c = match e {
            DecodeError::Cobs(_) => &mut self.cobs_errors,
            DecodeError::Overflow { .. } => &mut self.overflows,
            DecodeError::TooShort { .. } | DecodeError::BadLength { .. } => &mut self.length_errors,
            DecodeError::BadCrc { .. } => &mut self.crc_errors,
            DecodeError::VersionMismatch { .. } => &mut self.version_mismatches,
            DecodeError::UnknownType { .. } => &mut self.unknown_types,
            DecodeError::InvalidField { .. } => &mut self.invalid_fields,
        };
        *c = c.saturating_add(1);
    }
}

fn bump(counters: &mut [u32; NUM_STREAMS], stream: usize, n: u32) {
    if let Some(c) = counters.get_mut(stream) {
        *c = c.saturating_add(n);
    }
}

/// Streaming decoder over its own `CAP`-byte buffer ([`super::FrameDecoder`] is sized for
/// every frame). Feed it bytes with [`Decoder::feed`] (any chunking) and drain the iterator;
/// chunks are processed at each 0x00 delimiter, so a damaged frame costs only itself and the
/// decoder resynchronises on the next delimiter.
#[derive(Debug, Clone)]
pub struct Decoder<const CAP: usize> {
    buf: [u8; CAP],
    len: usize,
    overflow: bool,
    expected_seq: [Option<u16>; NUM_STREAMS],
    stats: DecoderStats,
    chunk_start: u64,
    last_chunk_start: u64,
}

impl<const CAP: usize> Default for Decoder<CAP> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const CAP: usize> Decoder<CAP> {
    /// An empty decoder with zeroed counters.
    pub const fn new() -> Self {
        Self {
            buf: [0; CAP],
            len: 0,
            overflow: false,
            expected_seq: [None; NUM_STREAMS],
            stats: DecoderStats {
                bytes: 0,
                frames_ok: 0,
                frames_ok_by_stream: [0; NUM_STREAMS],
                cobs_errors: 0,
                overflows: 0,
                length_errors: 0,
                crc_errors: 0,
                version_mismatches: 0,
                unknown_types: 0,
                invalid_fields: 0,
                truncated: 0,
                lost_by_stream: [0; NUM_STREAMS],
                backwards_by_stream: [0; NUM_STREAMS],
                restarts_by_stream: [0; NUM_STREAMS],
            },
            chunk_start: 0,
            last_chunk_start: 0,
        }
    }

    /// Declares that the bytes fed from now on start at the very beginning of every stream (a
    /// recording started before the sender, e.g. `hw-bridge record --streams-from-start`):
    /// each stream not seen yet is expected to begin at sequence number 0, so frames lost
    /// before the first one delivered are counted in `lost_by_stream` too (without this, a
    /// stream's first delivered frame sets the expectation and earlier losses are invisible).
    /// A frame carrying the restart flag still starts its stream afresh without a gap.
    pub fn expect_stream_starts(&mut self) {
        for e in &mut self.expected_seq {
            if e.is_none() {
                *e = Some(0);
            }
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Stream offset (bytes fed before it) of the first byte of the chunk last completed: where
    /// the frame or error most recently returned came from.
    pub fn last_chunk_offset(&self) -> u64 {
        self.last_chunk_start
    }

    /// Bytes of an incomplete chunk waiting for their delimiter.
    pub fn pending_len(&self) -> usize {
        self.len
    }

    /// The link was lost (port closed, cable pulled): discards a partial chunk, counting it in
    /// [`DecoderStats::truncated`]. Sequence expectations are kept, so frames the sender sent
    /// meanwhile are counted as lost when its next frame arrives.
    pub fn reset_link(&mut self) {
        if self.len > 0 || self.overflow {
            self.stats.truncated = self.stats.truncated.saturating_add(1);
        }
        self.len = 0;
        self.overflow = false;
        self.chunk_start = self.stats.bytes;
    }

    /// Feeds `input`; the returned iterator yields one item per completed chunk. Drain it:
    /// input not yet consumed when the iterator is dropped is discarded.
    pub fn feed<'a>(&'a mut self, input: &'a [u8]) -> Frames<'a, CAP> {
        Frames {
            dec: self,
            rest: input,
        }
    }

    /// Feeds one byte; returns the frame or error when it completed a chunk.
    pub fn push_byte(&mut self, byte: u8) -> Option<Result<Frame, DecodeError>> {
        self.stats.bytes = self.stats.bytes.saturating_add(1);
        if byte == 0 {
            self.finish_chunk()
        } else {
            self.append(&[byte]);
            None
        }
    }

    fn append(&mut self, bytes: &[u8]) {
        if self.overflow || bytes.is_empty() {
            return;
        }
        let end = self.len.saturating_add(bytes.len());
        match self.buf.get_mut(self.len..end) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                self.len = end;
            }
            None => self.overflow = true,
        }
    }

    fn finish_chunk(&mut self) -> Option<Result<Frame, DecodeError>> {
        let len = core::mem::take(&mut self.len);
        let overflow = core::mem::take(&mut self.overflow);
        self.last_chunk_start = self.chunk_start;
        self.chunk_start = self.stats.bytes;
        let result = if overflow {
            Err(DecodeError::Overflow { capacity: CAP })
        } else if len == 0 {
            return None;
        } else {
            self.decode_chunk(len)
        };
        match &result {
            Ok(frame) => self.account(frame),
            Err(e) => self.stats.count_error(e),
        }
        Some(result)
    }

    fn decode_chunk(&mut self, len: usize) -> Result<Frame, DecodeError> {
        let chunk = self
            .buf
            .get_mut(..len)
            .ok_or(DecodeError::Overflow { capacity: CAP })?;
        let n = cobs::decode_in_place(chunk).map_err(DecodeError::Cobs)?;
        let raw = chunk.get(..n).ok_or(DecodeError::TooShort { len: n })?;
        decode_raw(raw)
    }

    fn account(&mut self, frame: &Frame) {
        let s = frame.payload.msg_type().stream_index();
        self.stats.frames_ok = self.stats.frames_ok.saturating_add(1);
        bump(&mut self.stats.frames_ok_by_stream, s, 1);
        let expected = self.expected_seq.get(s).copied().flatten();
        if frame.flags & FLAG_RESTART != 0 {
            bump(&mut self.stats.restarts_by_stream, s, 1);
        } else if let Some(e) = expected {
            let gap = frame.seq.wrapping_sub(e);
            if gap < 0x8000 {
                bump(&mut self.stats.lost_by_stream, s, u32::from(gap));
            } else {
                bump(&mut self.stats.backwards_by_stream, s, 1);
            }
        }
        if let Some(slot) = self.expected_seq.get_mut(s) {
            *slot = Some(frame.seq.wrapping_add(1));
        }
    }
}

/// Iterator over the chunks completed by one [`Decoder::feed`] call.
#[derive(Debug)]
pub struct Frames<'a, const CAP: usize> {
    dec: &'a mut Decoder<CAP>,
    rest: &'a [u8],
}

impl<const CAP: usize> Iterator for Frames<'_, CAP> {
    type Item = Result<Frame, DecodeError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.rest.is_empty() {
            let rest = self.rest;
            match cobs::find_zero(rest) {
                Some(i) => {
                    let (head, tail) = rest.split_at_checked(i).unwrap_or((rest, &[]));
                    self.dec.append(head);
                    self.dec.stats.bytes = self.dec.stats.bytes.saturating_add(i as u64 + 1);
                    self.rest = tail.get(1..).unwrap_or(&[]);
                    if let Some(r) = self.dec.finish_chunk() {
                        return Some(r);
                    }
                }
                None => {
                    self.dec.append(rest);
                    self.dec.stats.bytes = self.dec.stats.bytes.saturating_add(rest.len() as u64);
                    self.rest = &[];
                }
            }
        }
        None
    }
}
