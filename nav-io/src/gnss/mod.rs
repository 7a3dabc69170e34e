//! GNSS receiver input: NMEA 0183 (GGA + GST + RMC/VTG of one epoch) and u-blox UBX NAV-PVT,
//! mapped to [`nav_core::types::GnssFix`]. [`GnssStream`] splits a receiver's mixed byte stream
//! (UBX, NMEA, RTCM interleaved, any chunking) with the `ublox` crate's parser, parses NMEA
//! sentences with the `nmea` crate and NAV-PVT with `ublox`.

pub mod encode;
pub mod nmea_epoch;
pub mod ubx;

pub use nmea_epoch::{NmeaAssembler, NmeaOptions};

use nav_core::types::GnssFix;

/// Seconds in a GPS week.
pub const WEEK_S: f64 = 604_800.0;

/// Errors of GNSS input, naming where the bad input was.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GnssError {
    /// An NMEA sentence failed to parse (bad checksum, malformed field, ...).
    #[error("NMEA sentence {index} ({sentence:?}): {reason}")]
    Nmea {
        /// 1-based index of the sentence in the input.
        index: u64,
        /// The sentence text (trimmed, at most 100 characters).
        sentence: String,
        /// What was wrong.
        reason: String,
    },
    /// An NMEA epoch could not be turned into a fix.
    #[error("NMEA epoch at {utc_time}: {reason}")]
    Epoch {
        /// UTC time of the epoch as sent.
        utc_time: String,
        /// What was missing.
        reason: String,
    },
    /// A UBX packet failed (checksum, length, field).
    #[error("UBX packet {index}: {reason}")]
    Ubx {
        /// 1-based index of the UBX packet in the input.
        index: u64,
        /// What was wrong.
        reason: String,
    },
}

/// What [`GnssStream`] yields besides fixes.
#[derive(Debug, Clone, PartialEq)]
pub enum GnssEvent {
    /// A fix (possibly `quality == NoFix`: check `GnssFix::is_valid`).
    Fix(GnssFix),
    /// Bad input, with where it was.
    Error(GnssError),
}

/// Counters of a [`GnssStream`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GnssStats {
    /// Bytes fed.
    pub bytes: u64,
    /// NMEA sentences seen (parsed or not).
    pub nmea_sentences: u64,
    /// NMEA sentences rejected (checksum or format).
    pub nmea_errors: u64,
    /// NMEA sentences of types not used here (GSA, GSV, ...).
    pub nmea_ignored: u64,
    /// UBX packets seen (valid checksum).
    pub ubx_packets: u64,
    /// UBX packets rejected.
    pub ubx_errors: u64,
    /// RTCM packets skipped.
    pub rtcm_packets: u64,
    /// Fixes produced.
    pub fixes: u64,
}

/// Parses a GNSS receiver's byte stream (NMEA and/or UBX, any chunking) into fixes.
pub struct GnssStream {
    parser: ublox::Parser<ublox::FixedBuffer<4096>>,
    nmea: NmeaAssembler,
    stats: GnssStats,
    last_utc: Option<ubx::UtcTime>,
}

impl GnssStream {
    /// A stream parser with the given NMEA options.
    pub fn new(opts: NmeaOptions) -> Self {
        Self {
            parser: ublox::ParserBuilder::new().with_fixed_buffer::<4096>(),
            nmea: NmeaAssembler::new(opts),
            stats: GnssStats::default(),
            last_utc: None,
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> GnssStats {
        let mut s = self.stats;
        s.nmea_sentences = self.nmea.sentences();
        s.nmea_errors = self.nmea.errors();
        s.nmea_ignored = self.nmea.ignored();
        s
    }

    /// Whether the parser holds no partial packet: the next byte starts afresh.
    pub fn is_idle(&self) -> bool {
        self.parser.is_buffer_empty()
    }

    /// The largest UBX payload the parser's protocol accepts, bytes (a header announcing
    /// more is skipped as garbage).
    pub fn max_ubx_payload(&self) -> usize {
        fn max<T: ublox::UnderlyingBuffer, P: ublox::UbxProtocol>(_: &ublox::Parser<T, P>) -> u16 {
            P::MAX_PAYLOAD_LEN
        }
        usize::from(max(&self.parser))
    }

    /// The UTC date and time of the last NAV-PVT packet (when flagged valid), taken: a
    /// NAV-PVT's iTOW has no GPS week, its UTC date gives it.
    pub fn take_nav_pvt_utc(&mut self) -> Option<ubx::UtcTime> {
        self.last_utc.take()
    }

    /// Feeds bytes; returns the fixes and errors they completed.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<GnssEvent> {
        self.stats.bytes += bytes.len() as u64;
        let mut out = Vec::new();
        let mut it = self.parser.consume_ubx_rtcm_nmea(bytes);
        while let Some(item) = it.next() {
            match item {
                Ok(ublox::AnyPacketRef::Nmea(p)) => {
                    let text = String::from_utf8_lossy(p.data).into_owned();
                    out.extend(self.nmea.push_sentence(&text));
                }
                Ok(ublox::AnyPacketRef::Ubx(p)) => {
                    self.stats.ubx_packets += 1;
                    if let ublox::UbxPacket::Proto23(ublox::proto23::PacketRef::NavPvt(pvt)) = &p {
                        self.last_utc = ubx::utc_of_nav_pvt(pvt);
                    }
                    if let Some(fix) = ubx::fix_from_packet(&p) {
                        out.push(GnssEvent::Fix(fix));
                    }
                }
                Ok(ublox::AnyPacketRef::Rtcm(_)) => self.stats.rtcm_packets += 1,
                Err(e) => {
                    self.stats.ubx_errors += 1;
                    out.push(GnssEvent::Error(GnssError::Ubx {
                        index: self.stats.ubx_packets + self.stats.ubx_errors,
                        reason: e.to_string(),
                    }));
                }
            }
        }
        self.stats.fixes += out
            .iter()
            .filter(|e| matches!(e, GnssEvent::Fix(_)))
            .count() as u64;
        out
    }

    /// End of input: emits an NMEA epoch still being assembled.
    pub fn finish(&mut self) -> Vec<GnssEvent> {
        let out: Vec<GnssEvent> = self.nmea.flush().into_iter().collect();
        self.stats.fixes += out
            .iter()
            .filter(|e| matches!(e, GnssEvent::Fix(_)))
            .count() as u64;
        out
    }
}
