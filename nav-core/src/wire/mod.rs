//! The wire protocol shared by the firmware and the host tools (`hw-bridge`).
//!
//! A frame on the wire is `COBS(header | payload | crc32c) 0x00`:
//!
//! * header (5 bytes): protocol [`VERSION`], message type ([`MsgType`]), flags
//!   ([`FLAG_RESTART`]), per-stream sequence number (u16 little-endian);
//! * payload: a fixed little-endian layout per message type (see [`Payload`] and
//!   `docs/wire-protocol.md`);
//! * CRC-32C ([`crc32c`]) of header and payload, u32 little-endian;
//! * the whole is COBS-encoded ([`cobs`]) so it contains no 0x00, and terminated by one 0x00.
//!
//! Everything the filter consumes (IMU increments, times, GNSS positions, velocities and their
//! standard deviations, the lever arm) is sent as `f64`, so a frame decodes to bit-identical
//! values. The navigation solution's standard deviations are `f32` (they come from the
//! covariance, which is `f32` on the MCU). [`encode`] writes a frame into a caller buffer;
//! [`Encoder`] also numbers the frames; [`Decoder`] takes bytes in any chunking and yields
//! frames or typed errors, resynchronising on the next 0x00 and counting everything in
//! [`DecoderStats`].
//!
//! No allocation, no panics: every size is a constant ([`MAX_FRAME_LEN`]).

pub mod cobs;
pub mod crc;

mod bytes;
mod decoder;

pub use crc::crc32c;
pub use decoder::{Decoder, DecoderStats, Frames};

use crate::types::{FixQuality, GnssFix, ImuSample, NavSolution};
use bytes::{Reader, Writer};

/// Protocol version carried in every frame's first byte.
pub const VERSION: u8 = 1;

/// Header flag: the sender (re)started this stream; its sequence number starts afresh and the
/// receiver must not count a gap.
pub const FLAG_RESTART: u8 = 0x01;

/// Header length in bytes (version, type, flags, sequence u16).
pub const HEADER_LEN: usize = 5;
/// CRC length in bytes.
pub const CRC_LEN: usize = 4;

/// Payload length of an IMU frame, bytes.
pub const IMU_PAYLOAD_LEN: usize = 8 + 24 + 24 + 8 + 2;
/// Payload length of a GNSS frame, bytes.
pub const GNSS_PAYLOAD_LEN: usize = 8 * 4 + 24 * 3 + 3;
/// Payload length of a navigation-solution frame, bytes.
pub const NAV_PAYLOAD_LEN: usize = 2 + 8 * 4 + 24 * 2 + 12 * 3 + 4;
/// Payload length of a configuration frame, bytes.
pub const CONFIG_PAYLOAD_LEN: usize = 1 + 1 + 2 + 4 + 4 + 24;
/// Payload length of a health frame, bytes.
pub const HEALTH_PAYLOAD_LEN: usize = 4 * 16;

/// Longest payload of any message type, bytes.
pub const MAX_PAYLOAD_LEN: usize = max5(
    IMU_PAYLOAD_LEN,
    GNSS_PAYLOAD_LEN,
    NAV_PAYLOAD_LEN,
    CONFIG_PAYLOAD_LEN,
    HEALTH_PAYLOAD_LEN,
);
/// Longest un-stuffed frame (header + payload + CRC), bytes.
pub const MAX_RAW_LEN: usize = HEADER_LEN + MAX_PAYLOAD_LEN + CRC_LEN;
/// Longest frame on the wire (COBS-encoded, without the 0x00 delimiter), bytes: the capacity a
/// [`Decoder`] needs.
pub const MAX_ENCODED_LEN: usize = cobs::max_encoded_len(MAX_RAW_LEN);
/// Longest frame on the wire including its 0x00 delimiter, bytes: the buffer [`encode`] needs.
pub const MAX_FRAME_LEN: usize = MAX_ENCODED_LEN + 1;

const fn max5(a: usize, b: usize, c: usize, d: usize, e: usize) -> usize {
    let mut m = a;
    if b > m {
        m = b;
    }
    if c > m {
        m = c;
    }
    if d > m {
        m = d;
    }
    if e > m {
        m = e;
    }
    m
}

/// A decoder sized for every frame of this protocol version.
pub type FrameDecoder = Decoder<MAX_ENCODED_LEN>;

/// Message types. Each type is its own sequence-numbered stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum MsgType {
    /// IMU sample (increments), usually 100-1000 Hz.
    Imu = 0x01,
    /// GNSS fix.
    Gnss = 0x02,
    /// Navigation solution.
    Nav = 0x03,
    /// Configuration.
    Config = 0x10,
    /// Health and counters.
    Health = 0x11,
}

/// Number of message types, i.e. of sequence-numbered streams.
pub const NUM_STREAMS: usize = 5;

impl MsgType {
    /// Every message type, in stream-index order.
    pub const ALL: [MsgType; NUM_STREAMS] = [
        MsgType::Imu,
        MsgType::Gnss,
        MsgType::Nav,
        MsgType::Config,
        MsgType::Health,
    ];

    /// The type for a type byte, `None` when unknown.
    pub fn from_byte(b: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|t| *t as u8 == b)
    }

    /// Index of this type's stream in per-stream counters (0..[`NUM_STREAMS`]).
    pub fn stream_index(self) -> usize {
        match self {
            Self::Imu => 0,
            Self::Gnss => 1,
            Self::Nav => 2,
            Self::Config => 3,
            Self::Health => 4,
        }
    }

    /// Payload length of this type, bytes.
    pub fn payload_len(self) -> usize {
        match self {
            Self::Imu => IMU_PAYLOAD_LEN,
            Self::Gnss => GNSS_PAYLOAD_LEN,
            Self::Nav => NAV_PAYLOAD_LEN,
            Self::Config => CONFIG_PAYLOAD_LEN,
            Self::Health => HEALTH_PAYLOAD_LEN,
        }
    }

    /// Encoded frame length of this type on the wire, including the 0x00 delimiter, bytes.
    pub fn frame_len(self) -> usize {
        let raw = HEADER_LEN + self.payload_len() + CRC_LEN;
        // All raw frames are shorter than 254 bytes: COBS adds exactly one byte.
        raw + 1 + 1
    }

    /// Lower-case name (`imu`, `gnss`, `nav`, `config`, `health`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Imu => "imu",
            Self::Gnss => "gnss",
            Self::Nav => "nav",
            Self::Config => "config",
            Self::Health => "health",
        }
    }
}

/// An IMU frame: the sample as the filter consumes it plus the sensor's status word.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuFrame {
    /// The sample (time, increments, temperature; all `f64` on the wire).
    pub sample: ImuSample,
    /// Sensor status bits as reported by the IMU (0 = nominal); passed through unchanged.
    pub status: u16,
}

/// Filter model ids used in [`Config::model`].
pub mod model {
    /// Classical model N: white noise + constant biases (15 states).
    pub const N: u8 = 0;
    /// The source document's NBK model with Gauss-Markov and random walk in one bias state
    /// per accelerometer axis (18 states).
    pub const NBK_SEED: u8 = 1;
    /// NBK with separate Gauss-Markov and random-walk accelerometer bias states (21 states).
    pub const NBK: u8 = 2;
}

/// Configuration sent to the board (or echoed by it). Fixed layout, 36 bytes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Filter model id (see [`model`]).
    pub model: u8,
    /// Option bits: bit 0 = use GNSS velocity when a fix carries one ([`CONFIG_USE_GNSS_VELOCITY`]);
    /// bit 1 = land-vehicle aiding ([`CONFIG_LAND_AIDING`]); other bits 0.
    pub flags: u8,
    /// Send one navigation solution every `nav_divider` IMU epochs (0 = none).
    pub nav_divider: u16,
    /// Nominal IMU sample rate, Hz.
    pub imu_rate_hz: f32,
    /// Nominal GNSS fix rate, Hz.
    pub gnss_rate_hz: f32,
    /// GNSS antenna lever arm from the IMU reference point in body axes (FRD), m.
    pub lever_arm_frd_m: [f64; 3],
}

/// Config flag: use GNSS velocity measurements when present.
pub const CONFIG_USE_GNSS_VELOCITY: u8 = 0x01;

/// Config flag: land-vehicle aiding on the board: the non-holonomic constraint and the
/// zero-velocity / zero-rate updates at stops, with `nav_core::aiding`'s default settings.
pub const CONFIG_LAND_AIDING: u8 = 0x02;

/// Health and counters of a board. Fixed layout, 64 bytes, all u32.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Health {
    /// Time since boot, ms.
    pub uptime_ms: u32,
    /// Frames received intact.
    pub rx_frames_ok: u32,
    /// Received chunks rejected (any decode error).
    pub rx_rejected: u32,
    /// Of those, rejected for a bad CRC.
    pub rx_crc_errors: u32,
    /// Frames missing by sequence numbers.
    pub rx_lost: u32,
    /// IMU epochs processed.
    pub imu_epochs: u32,
    /// GNSS updates applied.
    pub gnss_updates: u32,
    /// GNSS fixes rejected by the filter (invalid or gated).
    pub gnss_rejected: u32,
    /// Longest IMU epoch processing time, time-base ticks.
    pub epoch_ticks_max: u32,
    /// Peak stack use, bytes.
    pub stack_peak_bytes: u32,
    /// Filter status bits (0 = nominal).
    pub filter_status: u32,
    /// IMU samples the IMU guard rejected as implausible (not integrated).
    pub imu_implausible: u32,
    /// Time gaps in the IMU stream the IMU guard bridged.
    pub imu_gaps: u32,
    /// Non-holonomic-constraint updates used by the land-vehicle aiding.
    pub nhc_updates: u32,
    /// Zero-velocity updates used by the land-vehicle aiding.
    pub zupt_updates: u32,
    /// Zero-angular-rate updates used by the land-vehicle aiding.
    pub zaru_updates: u32,
}

/// The content of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Payload {
    /// IMU sample.
    Imu(ImuFrame),
    /// GNSS fix.
    Gnss(GnssFix),
    /// Navigation solution (standard deviations travel as `f32`).
    Nav(NavSolution),
    /// Configuration.
    Config(Config),
    /// Health and counters.
    Health(Health),
}

impl Payload {
    /// The message type of this payload.
    pub fn msg_type(&self) -> MsgType {
        match self {
            Self::Imu(_) => MsgType::Imu,
            Self::Gnss(_) => MsgType::Gnss,
            Self::Nav(_) => MsgType::Nav,
            Self::Config(_) => MsgType::Config,
            Self::Health(_) => MsgType::Health,
        }
    }
}

/// One frame: header fields and payload.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame {
    /// Sequence number within the payload type's stream (wraps at 65536).
    pub seq: u16,
    /// Header flags ([`FLAG_RESTART`]; other bits are sent as 0 and ignored).
    pub flags: u8,
    /// The content.
    pub payload: Payload,
}

/// Errors of [`encode`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The output buffer is shorter than the frame (needs at most [`MAX_FRAME_LEN`] bytes).
    BufferTooSmall {
        /// Bytes the frame needs.
        needed: usize,
        /// Bytes available.
        available: usize,
    },
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BufferTooSmall { needed, available } => write!(
                f,
                "wire encode: frame needs {needed} bytes, buffer has {available}"
            ),
        }
    }
}

/// Why a received chunk (the bytes between two 0x00 delimiters) was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DecodeError {
    /// The chunk is not valid COBS.
    Cobs(cobs::CobsError),
    /// The chunk was longer than the decoder's buffer; it was discarded up to the delimiter.
    Overflow {
        /// Decoder capacity, bytes.
        capacity: usize,
    },
    /// The frame is shorter than header + CRC.
    TooShort {
        /// Decoded length, bytes.
        len: usize,
    },
    /// The CRC does not match.
    BadCrc {
        /// CRC carried by the frame.
        received: u32,
        /// CRC computed over the frame.
        computed: u32,
    },
    /// The frame's protocol version is not [`VERSION`].
    VersionMismatch {
        /// Version byte received.
        received: u8,
    },
    /// The message type byte is unknown.
    UnknownType {
        /// Type byte received.
        msg_type: u8,
    },
    /// The payload length does not match the message type.
    BadLength {
        /// Message type.
        msg_type: MsgType,
        /// Payload length received, bytes.
        len: usize,
        /// Payload length of this type, bytes.
        expected: usize,
    },
    /// A payload field has a value outside its range (e.g. an unknown fix quality).
    InvalidField {
        /// Message type.
        msg_type: MsgType,
        /// Field name.
        field: &'static str,
        /// The offending raw value.
        value: u32,
    },
}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Cobs(e) => write!(f, "{e}"),
            Self::Overflow { capacity } => {
                write!(f, "chunk longer than the decoder buffer ({capacity} bytes)")
            }
            Self::TooShort { len } => write!(
                f,
                "frame of {len} bytes is shorter than header + CRC ({} bytes)",
                HEADER_LEN + CRC_LEN
            ),
            Self::BadCrc { received, computed } => write!(
                f,
                "bad CRC: frame carries {received:#010x}, computed {computed:#010x}"
            ),
            Self::VersionMismatch { received } => write!(
                f,
                "protocol version {received}, this decoder speaks version {VERSION}"
            ),
            Self::UnknownType { msg_type } => write!(f, "unknown message type {msg_type:#04x}"),
            Self::BadLength {
                msg_type,
                len,
                expected,
            } => write!(
                f,
                "{} payload of {len} bytes, expected {expected}",
                msg_type.name()
            ),
            Self::InvalidField {
                msg_type,
                field,
                value,
            } => write!(
                f,
                "{} field {field} has invalid value {value}",
                msg_type.name()
            ),
        }
    }
}

fn write_payload(w: &mut Writer<'_>, p: &Payload) -> Option<()> {
    match p {
        Payload::Imu(m) => {
            w.f64(m.sample.t_s)?;
            w.f64x3(&m.sample.dtheta_rad)?;
            w.f64x3(&m.sample.dv_mps)?;
            w.f64(m.sample.temperature_c)?;
            w.u16(m.status)
        }
        Payload::Gnss(g) => {
            w.f64(g.t_s)?;
            w.f64(g.lat_rad)?;
            w.f64(g.lon_rad)?;
            w.f64(g.h_m)?;
            w.f64x3(&g.pos_std_ned_m)?;
            w.f64x3(&g.vel_ned_mps)?;
            w.f64x3(&g.vel_std_ned_mps)?;
            w.u8(g.quality.rtklib_q())?;
            w.u8(g.num_sats)?;
            w.u8(u8::from(g.has_velocity))
        }
        Payload::Nav(n) => {
            w.u16(n.week)?;
            w.f64(n.t_s)?;
            w.f64(n.lat_rad)?;
            w.f64(n.lon_rad)?;
            w.f64(n.h_m)?;
            w.f64x3(&n.vel_ned_mps)?;
            w.f64x3(&n.rpy_rad)?;
            w.f32x3(&n.pos_std_ned_m)?;
            w.f32x3(&n.vel_std_ned_mps)?;
            w.f32x3(&n.att_std_rad)?;
            w.u32(n.status)
        }
        Payload::Config(c) => {
            w.u8(c.model)?;
            w.u8(c.flags)?;
            w.u16(c.nav_divider)?;
            w.f32(c.imu_rate_hz)?;
            w.f32(c.gnss_rate_hz)?;
            w.f64x3(&c.lever_arm_frd_m)
        }
        Payload::Health(h) => {
            for v in [
                h.uptime_ms,
                h.rx_frames_ok,
                h.rx_rejected,
                h.rx_crc_errors,
                h.rx_lost,
                h.imu_epochs,
                h.gnss_updates,
                h.gnss_rejected,
                h.epoch_ticks_max,
                h.stack_peak_bytes,
                h.filter_status,
                h.imu_implausible,
                h.imu_gaps,
                h.nhc_updates,
                h.zupt_updates,
                h.zaru_updates,
            ] {
                w.u32(v)?;
            }
            Some(())
        }
    }
}

fn read_imu(r: &mut Reader<'_>) -> Option<Payload> {
    Some(Payload::Imu(ImuFrame {
        sample: ImuSample {
            t_s: r.f64()?,
            dtheta_rad: r.f64x3()?,
            dv_mps: r.f64x3()?,
            temperature_c: r.f64()?,
        },
        status: r.u16()?,
    }))
}

/// GNSS fields as read, before the range checks of the quality and velocity-flag bytes.
type GnssRaw = (GnssFix, u8, u8);

fn read_gnss(r: &mut Reader<'_>) -> Option<GnssRaw> {
    let fix = GnssFix {
        t_s: r.f64()?,
        lat_rad: r.f64()?,
        lon_rad: r.f64()?,
        h_m: r.f64()?,
        pos_std_ned_m: r.f64x3()?,
        vel_ned_mps: r.f64x3()?,
        vel_std_ned_mps: r.f64x3()?,
        has_velocity: false,
        quality: FixQuality::NoFix,
        num_sats: 0,
    };
    let q = r.u8()?;
    let sats = r.u8()?;
    let vflag = r.u8()?;
    Some((
        GnssFix {
            num_sats: sats,
            ..fix
        },
        q,
        vflag,
    ))
}

fn read_nav(r: &mut Reader<'_>) -> Option<Payload> {
    Some(Payload::Nav(NavSolution {
        week: r.u16()?,
        t_s: r.f64()?,
        lat_rad: r.f64()?,
        lon_rad: r.f64()?,
        h_m: r.f64()?,
        vel_ned_mps: r.f64x3()?,
        rpy_rad: r.f64x3()?,
        pos_std_ned_m: r.f32x3()?,
        vel_std_ned_mps: r.f32x3()?,
        att_std_rad: r.f32x3()?,
        status: r.u32()?,
    }))
}

fn read_config(r: &mut Reader<'_>) -> Option<Payload> {
    Some(Payload::Config(Config {
        model: r.u8()?,
        flags: r.u8()?,
        nav_divider: r.u16()?,
        imu_rate_hz: r.f32()?,
        gnss_rate_hz: r.f32()?,
        lever_arm_frd_m: r.f64x3()?,
    }))
}

fn read_health(r: &mut Reader<'_>) -> Option<Payload> {
    Some(Payload::Health(Health {
        uptime_ms: r.u32()?,
        rx_frames_ok: r.u32()?,
        rx_rejected: r.u32()?,
        rx_crc_errors: r.u32()?,
        rx_lost: r.u32()?,
        imu_epochs: r.u32()?,
        gnss_updates: r.u32()?,
        gnss_rejected: r.u32()?,
        epoch_ticks_max: r.u32()?,
        stack_peak_bytes: r.u32()?,
        filter_status: r.u32()?,
        imu_implausible: r.u32()?,
        imu_gaps: r.u32()?,
        nhc_updates: r.u32()?,
        zupt_updates: r.u32()?,
        zaru_updates: r.u32()?,
    }))
}

/// Reads a payload of type `t`. The caller has checked the length, so running out of bytes
/// cannot happen for well-sized input (it would map to a length error).
fn read_payload(t: MsgType, r: &mut Reader<'_>) -> Result<Payload, DecodeError> {
    let short = DecodeError::BadLength {
        msg_type: t,
        len: 0,
        expected: t.payload_len(),
    };
    match t {
        MsgType::Imu => read_imu(r).ok_or(short),
        MsgType::Nav => read_nav(r).ok_or(short),
        MsgType::Config => read_config(r).ok_or(short),
        MsgType::Health => read_health(r).ok_or(short),
        MsgType::Gnss => {
            let (fix, q, vflag) = read_gnss(r).ok_or(short)?;
            if q > 6 {
                return Err(DecodeError::InvalidField {
                    msg_type: t,
                    field: "quality",
                    value: u32::from(q),
                });
            }
            if vflag > 1 {
                return Err(DecodeError::InvalidField {
                    msg_type: t,
                    field: "has_velocity",
                    value: u32::from(vflag),
                });
            }
            Ok(Payload::Gnss(GnssFix {
                quality: FixQuality::from_rtklib_q(q),
                has_velocity: vflag == 1,
                ..fix
            }))
        }
    }
}

fn write_frame(w: &mut Writer<'_>, frame: &Frame) -> Option<()> {
    w.u8(VERSION)?;
    w.u8(frame.payload.msg_type() as u8)?;
    w.u8(frame.flags)?;
    w.u16(frame.seq)?;
    write_payload(w, &frame.payload)
}

fn read_header(r: &mut Reader<'_>) -> Option<(u8, u8, u8, u16)> {
    Some((r.u8()?, r.u8()?, r.u8()?, r.u16()?))
}

/// Writes the un-stuffed frame (header, payload, CRC) into `out`; returns its length.
pub fn encode_raw(frame: &Frame, out: &mut [u8]) -> Result<usize, EncodeError> {
    let t = frame.payload.msg_type();
    let needed = HEADER_LEN + t.payload_len() + CRC_LEN;
    let available = out.len();
    let too_small = EncodeError::BufferTooSmall { needed, available };
    let body_len = {
        let mut w = Writer::new(out);
        write_frame(&mut w, frame).ok_or(too_small)?;
        w.pos()
    };
    let crc = crc32c(out.get(..body_len).ok_or(too_small)?);
    out.get_mut(body_len..needed)
        .ok_or(too_small)?
        .copy_from_slice(&crc.to_le_bytes());
    Ok(needed)
}

/// Encodes `frame` for the wire (COBS + trailing 0x00) into `out`; returns the number of bytes
/// written. `out` needs [`MsgType::frame_len`] bytes ([`MAX_FRAME_LEN`] fits every frame).
pub fn encode(frame: &Frame, out: &mut [u8]) -> Result<usize, EncodeError> {
    let needed = frame.payload.msg_type().frame_len();
    let available = out.len();
    let too_small = EncodeError::BufferTooSmall { needed, available };
    let mut raw = [0u8; MAX_RAW_LEN];
    let raw_len = encode_raw(frame, &mut raw)?;
    let src = raw.get(..raw_len).ok_or(too_small)?;
    let n = cobs::encode(src, out).ok_or(too_small)?;
    *out.get_mut(n).ok_or(too_small)? = 0;
    Ok(n + 1)
}

/// Decodes an un-stuffed frame (header, payload, CRC) after COBS decoding.
pub fn decode_raw(raw: &[u8]) -> Result<Frame, DecodeError> {
    let len = raw.len();
    let (body, crc_bytes) = len
        .checked_sub(CRC_LEN)
        .filter(|&b| b >= HEADER_LEN)
        .and_then(|b| raw.split_at_checked(b))
        .ok_or(DecodeError::TooShort { len })?;
    let received = Reader::new(crc_bytes)
        .u32()
        .ok_or(DecodeError::TooShort { len })?;
    let computed = crc32c(body);
    if received != computed {
        return Err(DecodeError::BadCrc { received, computed });
    }
    let mut r = Reader::new(body);
    let (version, type_byte, flags, seq) =
        read_header(&mut r).ok_or(DecodeError::TooShort { len })?;
    if version != VERSION {
        return Err(DecodeError::VersionMismatch { received: version });
    }
    let t = MsgType::from_byte(type_byte).ok_or(DecodeError::UnknownType {
        msg_type: type_byte,
    })?;
    let payload_len = body.len() - HEADER_LEN;
    if payload_len != t.payload_len() {
        return Err(DecodeError::BadLength {
            msg_type: t,
            len: payload_len,
            expected: t.payload_len(),
        });
    }
    let payload = read_payload(t, &mut r)?;
    Ok(Frame {
        seq,
        flags,
        payload,
    })
}

/// Numbers outgoing frames: one sequence counter per stream, [`FLAG_RESTART`] on the first
/// frame of each stream after construction.
#[derive(Debug, Clone, Default)]
pub struct Encoder {
    next_seq: [u16; NUM_STREAMS],
    started: [bool; NUM_STREAMS],
}

impl Encoder {
    /// A fresh encoder (all streams start at sequence 0 with the restart flag).
    pub const fn new() -> Self {
        Self {
            next_seq: [0; NUM_STREAMS],
            started: [false; NUM_STREAMS],
        }
    }

    /// The frame the next call of [`Encoder::encode`] would send for `payload`.
    pub fn peek(&self, payload: &Payload) -> Frame {
        let s = payload.msg_type().stream_index();
        let started = self.started.get(s).copied().unwrap_or(false);
        Frame {
            seq: self.next_seq.get(s).copied().unwrap_or(0),
            flags: if started { 0 } else { FLAG_RESTART },
            payload: *payload,
        }
    }

    /// Encodes `payload` as the next frame of its stream into `out` (see [`encode`]); the
    /// sequence advances only when encoding succeeds.
    pub fn encode(&mut self, payload: &Payload, out: &mut [u8]) -> Result<usize, EncodeError> {
        let frame = self.peek(payload);
        let n = encode(&frame, out)?;
        let s = payload.msg_type().stream_index();
        if let Some(seq) = self.next_seq.get_mut(s) {
            *seq = seq.wrapping_add(1);
        }
        if let Some(st) = self.started.get_mut(s) {
            *st = true;
        }
        Ok(n)
    }
}

impl core::error::Error for EncodeError {}
impl core::error::Error for DecodeError {}
