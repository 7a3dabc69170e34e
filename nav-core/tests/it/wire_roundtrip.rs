//! Round-trip, golden-byte and error tests of the wire codec, one per frame type.
use crate::wire_common;

use nav_core::types::FixQuality;
use nav_core::wire::{
    cobs, crc32c, decode_raw, encode, DecodeError, EncodeError, Encoder, Frame, FrameDecoder,
    MsgType, Payload, FLAG_RESTART, MAX_ENCODED_LEN, MAX_FRAME_LEN, MAX_RAW_LEN, VERSION,
};
use wire_common::*;

/// Golden wire bytes of the sample frames (`wire_common::sample_*`, seq = 42 + index,
/// flags = 0). Any change to the layout, CRC or stuffing breaks these on purpose.
const GOLDEN: [(MsgType, &str); 5] = [
    (
        MsgType::Imu,
        "03 01 01 02 2a 05 52 b8 1e 05 34 bb 17 41 f1 68 e3 88 b5 f8 e4 3e f1 68 e3 88 b5 f8 \
         c4 be 61 32 55 30 2a a9 33 3f 8d 28 ed 0d be 30 89 3f 3b df 4f 8d 97 6e 72 bf 4a 0c \
         02 2b 87 16 a9 bf 01 01 01 01 04 80 39 40 01 05 b0 be 61 91 00",
    ),
    (
        MsgType::Gnss,
        "03 01 02 02 2b 01 01 01 01 15 04 bb 17 41 da bd b6 52 cf 08 e1 3f 97 f1 e5 25 28 eb \
         ff 3f 01 01 01 01 01 03 39 40 01 01 01 01 01 03 e0 3f 01 01 01 01 01 03 e0 3f 01 01 \
         01 01 01 03 f0 3f 01 01 01 01 01 03 f0 3f 01 01 01 01 01 01 29 40 9a 99 99 99 99 99 \
         b9 bf 9a 99 99 99 99 99 a9 3f 9a 99 99 99 99 99 a9 3f 9a 99 99 99 99 99 b9 3f 05 0c \
         01 18 8d ee e5 00",
    ),
    (
        MsgType::Nav,
        "03 01 03 02 2c 03 fc 08 01 01 01 15 04 bb 17 41 da bd b6 52 cf 08 e1 3f 97 f1 e5 25 \
         28 eb ff 3f 01 01 01 01 01 03 39 40 01 01 01 01 01 03 f0 3f 01 01 01 01 01 01 22 40 \
         9a 99 99 99 99 99 b9 bf 39 9d 52 a2 46 df 91 3f 39 9d 52 a2 46 df a1 bf 18 2d 44 54 \
         fb 21 e9 3f 01 01 02 3f 01 01 02 3f 01 03 80 3f 01 03 80 3d 01 03 80 3d 01 01 02 3e \
         01 01 02 3b 01 01 02 3b 01 04 80 3c 03 01 01 05 5d 40 65 07 00",
    ),
    (
        MsgType::Config,
        "03 01 10 02 2d 04 02 01 14 01 01 03 48 43 01 1f 80 3f 9a 99 99 99 99 99 b9 3f 9a 99 \
         99 99 99 99 c9 bf 33 33 33 33 33 33 eb bf 01 0c 9f 90 00",
    ),
    (
        MsgType::Health,
        "03 01 11 02 2e 04 80 ee 36 04 80 fc 0a 02 03 01 01 02 02 01 01 02 04 01 01 04 76 fc \
         0a 03 10 0e 01 02 01 01 01 03 28 a0 01 01 02 18 01 01 01 01 01 02 02 01 01 02 05 01 \
         01 03 30 75 01 03 b0 04 01 03 7e 04 01 05 13 aa f1 99 00",
    ),
];

fn parse_hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|h| u8::from_str_radix(h, 16).unwrap())
        .collect()
}

fn sample_frame(i: usize) -> Frame {
    Frame {
        seq: 42 + i as u16,
        flags: 0,
        payload: all_samples()[i],
    }
}

fn decode_one(bytes: &[u8]) -> Result<Frame, DecodeError> {
    let mut d = FrameDecoder::new();
    let out: Vec<_> = d.feed(bytes).collect();
    assert_eq!(out.len(), 1, "expected exactly one chunk");
    out.into_iter().next().unwrap()
}

#[test]
fn every_frame_type_encodes_to_its_golden_bytes() {
    for (i, (t, golden)) in GOLDEN.iter().enumerate() {
        let f = sample_frame(i);
        assert_eq!(f.payload.msg_type(), *t);
        let bytes = wire_bytes(&f);
        assert_eq!(hex(&bytes), hex(&parse_hex(golden)), "{t:?}");
        assert_eq!(bytes.len(), t.frame_len(), "{t:?} frame length");
    }
}

#[test]
fn every_frame_type_round_trips_exactly() {
    for i in 0..5 {
        let f = sample_frame(i);
        let got = decode_one(&wire_bytes(&f)).unwrap();
        // The samples are chosen exactly representable, so plain equality holds here.
        assert_eq!(got, f);
        assert!(same_frame(&got, &f));
    }
}

#[test]
fn golden_header_and_crc_fields_are_where_the_spec_says() {
    // Independent of the encoder: un-stuff the golden IMU bytes with the COBS decoder and read
    // the fields at the documented offsets.
    let mut b = parse_hex(GOLDEN[0].1);
    assert_eq!(b.pop(), Some(0));
    let n = cobs::decode_in_place(&mut b).unwrap();
    let raw = &b[..n];
    assert_eq!(raw.len(), 5 + 66 + 4);
    assert_eq!(raw[0], VERSION);
    assert_eq!(raw[1], 0x01);
    assert_eq!(raw[2], 0);
    assert_eq!(u16::from_le_bytes([raw[3], raw[4]]), 42);
    assert_eq!(
        f64::from_le_bytes(raw[5..13].try_into().unwrap()),
        388_800.005
    );
    assert_eq!(f64::from_le_bytes(raw[61..69].try_into().unwrap()), 25.5);
    let crc = u32::from_le_bytes(raw[71..75].try_into().unwrap());
    assert_eq!(crc, crc32c(&raw[..71]));
    assert_eq!(crc, 0x9161_beb0);
}

#[test]
fn spec_document_worked_example_matches_the_encoder() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/wire-protocol.md");
    let doc = std::fs::read_to_string(path).expect("docs/wire-protocol.md");
    let start = doc
        .find("<!-- golden-imu-begin -->")
        .expect("golden-imu-begin marker");
    let end = doc
        .find("<!-- golden-imu-end -->")
        .expect("golden-imu-end marker");
    let block = &doc[start..end];
    let hexes: Vec<u8> = block
        .lines()
        .filter(|l| {
            let t = l.trim();
            !t.is_empty()
                && t.split_whitespace()
                    .all(|w| w.len() == 2 && u8::from_str_radix(w, 16).is_ok())
        })
        .flat_map(parse_hex)
        .collect();
    assert_eq!(hex(&hexes), hex(&wire_bytes(&sample_frame(0))));
}

#[test]
fn frame_lengths_are_the_documented_constants() {
    assert_eq!(MsgType::Imu.frame_len(), 77);
    assert_eq!(MsgType::Gnss.frame_len(), 118);
    assert_eq!(MsgType::Nav.frame_len(), 133);
    assert_eq!(MsgType::Config.frame_len(), 47);
    assert_eq!(MsgType::Health.frame_len(), 75);
    assert_eq!(MAX_RAW_LEN, 131);
    assert_eq!(MAX_ENCODED_LEN, 132);
    assert_eq!(MAX_FRAME_LEN, 133);
}

#[test]
fn nav_standard_deviations_travel_as_nearest_f32() {
    let Payload::Nav(mut n) = sample_nav() else {
        unreachable!()
    };
    n.pos_std_ned_m = [0.1, 1.0 / 3.0, 1e-9];
    n.att_std_rad = [f64::NAN, 7.0, 1e40];
    let f = Frame {
        seq: 0,
        flags: 0,
        payload: Payload::Nav(n),
    };
    let Payload::Nav(g) = decode_one(&wire_bytes(&f)).unwrap().payload else {
        panic!("not a nav frame")
    };
    assert_eq!(g.pos_std_ned_m[0], 0.1f32 as f64);
    assert_eq!(g.pos_std_ned_m[1], (1.0f64 / 3.0) as f32 as f64);
    assert_eq!(g.pos_std_ned_m[2], 1e-9f32 as f64);
    assert!(g.att_std_rad[0].is_nan());
    assert_eq!(g.att_std_rad[1], 7.0);
    assert_eq!(
        g.att_std_rad[2],
        f64::INFINITY,
        "out of f32 range saturates to inf"
    );
    // Everything else is f64 and exact.
    assert_eq!(g.lat_rad.to_bits(), n.lat_rad.to_bits());
    assert_eq!(g.rpy_rad, n.rpy_rad);
}

#[test]
fn encode_reports_a_short_buffer() {
    let f = sample_frame(0);
    let mut out = [0u8; 76];
    assert_eq!(
        encode(&f, &mut out),
        Err(EncodeError::BufferTooSmall {
            needed: 77,
            available: 76
        })
    );
    let mut out = [0u8; 77];
    assert_eq!(encode(&f, &mut out), Ok(77));
}

#[test]
fn encoder_numbers_each_stream_and_flags_the_first_frame() {
    let mut e = Encoder::new();
    let mut d = FrameDecoder::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let mut got = Vec::new();
    for p in [
        sample_imu(),
        sample_imu(),
        sample_gnss(),
        sample_imu(),
        sample_gnss(),
    ] {
        let n = e.encode(&p, &mut buf).unwrap();
        got.extend(d.feed(&buf[..n]).map(|r| r.unwrap()));
    }
    let seqs: Vec<(MsgType, u16, u8)> = got
        .iter()
        .map(|f| (f.payload.msg_type(), f.seq, f.flags))
        .collect();
    assert_eq!(
        seqs,
        vec![
            (MsgType::Imu, 0, FLAG_RESTART),
            (MsgType::Imu, 1, 0),
            (MsgType::Gnss, 0, FLAG_RESTART),
            (MsgType::Imu, 2, 0),
            (MsgType::Gnss, 1, 0),
        ]
    );
    assert_eq!(d.stats().lost(), 0);
    assert_eq!(d.stats().restarts_by_stream, [1, 1, 0, 0, 0]);
}

/// COBS-encodes a hand-made raw frame with a valid CRC appended.
fn stuff_with_crc(body: &[u8]) -> Vec<u8> {
    let mut raw = body.to_vec();
    raw.extend_from_slice(&crc32c(body).to_le_bytes());
    let mut out = vec![0u8; raw.len() + raw.len() / 254 + 2];
    let n = cobs::encode(&raw, &mut out).unwrap();
    out.truncate(n);
    out.push(0);
    out
}

#[test]
fn decoder_names_each_kind_of_bad_frame() {
    let good = raw_bytes(&sample_frame(0));
    let body = &good[..good.len() - 4];

    // Version 2 with a valid CRC.
    let mut b = body.to_vec();
    b[0] = 2;
    assert_eq!(
        decode_one(&stuff_with_crc(&b)),
        Err(DecodeError::VersionMismatch { received: 2 })
    );
    // Unknown type 0x7f.
    let mut b = body.to_vec();
    b[1] = 0x7f;
    assert_eq!(
        decode_one(&stuff_with_crc(&b)),
        Err(DecodeError::UnknownType { msg_type: 0x7f })
    );
    // IMU payload one byte short.
    assert_eq!(
        decode_one(&stuff_with_crc(&body[..body.len() - 1])),
        Err(DecodeError::BadLength {
            msg_type: MsgType::Imu,
            len: 65,
            expected: 66
        })
    );
    // Shorter than header + CRC.
    assert_eq!(
        decode_one(&[0x04, 1, 1, 1, 0]),
        Err(DecodeError::TooShort { len: 3 })
    );
    // Bad CRC: flip one payload bit.
    let mut raw = good.clone();
    raw[20] ^= 0x10;
    let mut out = vec![0u8; 100];
    let n = cobs::encode(&raw, &mut out).unwrap();
    out.truncate(n);
    out.push(0);
    assert!(matches!(decode_one(&out), Err(DecodeError::BadCrc { .. })));
    // GNSS with fix quality 9.
    let g = raw_bytes(&sample_frame(1));
    let mut b = g[..g.len() - 4].to_vec();
    let q_at = 5 + 8 * 4 + 24 * 3;
    b[q_at] = 9;
    assert_eq!(
        decode_one(&stuff_with_crc(&b)),
        Err(DecodeError::InvalidField {
            msg_type: MsgType::Gnss,
            field: "quality",
            value: 9
        })
    );
    // Invalid COBS: a code pointing past the end.
    assert!(matches!(
        decode_one(&[0x09, 1, 2, 0]),
        Err(DecodeError::Cobs(cobs::CobsError::Truncated { at: 0 }))
    ));
    // Overflow: 500 non-zero bytes.
    let mut long = vec![0x55u8; 500];
    long.push(0);
    assert_eq!(
        decode_one(&long),
        Err(DecodeError::Overflow {
            capacity: MAX_ENCODED_LEN
        })
    );
    // Each of those is counted once, in its own counter.
    let mut d = FrameDecoder::new();
    let mut all = Vec::new();
    let mut vb = body.to_vec();
    vb[0] = 2;
    all.extend(stuff_with_crc(&vb));
    all.extend(&long);
    all.extend(wire_bytes(&sample_frame(0)));
    let n = d.feed(&all).count();
    assert_eq!(n, 3);
    let s = d.stats();
    assert_eq!((s.version_mismatches, s.overflows, s.frames_ok), (1, 1, 1));
    assert_eq!(s.rejected(), 2);
    assert_eq!(s.bytes, all.len() as u64);
}

#[test]
fn error_messages_name_the_problem() {
    let e = DecodeError::BadLength {
        msg_type: MsgType::Gnss,
        len: 3,
        expected: 107,
    };
    assert_eq!(e.to_string(), "gnss payload of 3 bytes, expected 107");
    let e = DecodeError::BadCrc {
        received: 1,
        computed: 0xdeadbeef,
    };
    assert_eq!(
        e.to_string(),
        "bad CRC: frame carries 0x00000001, computed 0xdeadbeef"
    );
    assert_eq!(
        DecodeError::VersionMismatch { received: 3 }.to_string(),
        "protocol version 3, this decoder speaks version 1"
    );
}

#[test]
fn decode_raw_accepts_what_encode_raw_writes_for_every_quality() {
    for q in 0..=6u8 {
        let Payload::Gnss(mut g) = sample_gnss() else {
            unreachable!()
        };
        g.quality = FixQuality::from_rtklib_q(q);
        g.has_velocity = q % 2 == 0;
        let f = Frame {
            seq: 65535,
            flags: 0xFF,
            payload: Payload::Gnss(g),
        };
        let raw = raw_bytes(&f);
        assert_eq!(decode_raw(&raw).unwrap(), f);
    }
}
