//! Shared helpers of the wire-codec tests: sample frames, proptest strategies, and a bitwise
//! frame comparison (two frames are the same when they encode to the same bytes, which
//! compares every f64 bit for bit, NaN payloads included).
#![allow(dead_code)]

use nav_core::types::{FixQuality, GnssFix, ImuSample, NavSolution};
use nav_core::wire::{
    encode, encode_raw, Config, Frame, Health, ImuFrame, Payload, MAX_FRAME_LEN, MAX_RAW_LEN,
};
use proptest::prelude::*;

pub fn deg(x: f64) -> f64 {
    x.to_radians()
}

pub fn sample_imu() -> Payload {
    Payload::Imu(ImuFrame {
        sample: ImuSample {
            t_s: 388_800.005,
            dtheta_rad: [1.0e-5, -2.5e-6, 3.0e-4],
            dv_mps: [0.0123, -0.0045, -0.049],
            temperature_c: 25.5,
        },
        status: 0,
    })
}

pub fn sample_gnss() -> Payload {
    Payload::Gnss(GnssFix {
        t_s: 388_801.0,
        lat_rad: deg(30.5),
        lon_rad: deg(114.3),
        h_m: 25.0,
        pos_std_ned_m: [0.5, 0.5, 1.0],
        vel_ned_mps: [1.0, 2.0, -0.1],
        vel_std_ned_mps: [0.05, 0.05, 0.1],
        has_velocity: true,
        quality: FixQuality::Single,
        num_sats: 12,
    })
}

pub fn sample_nav() -> Payload {
    Payload::Nav(NavSolution {
        week: 2300,
        t_s: 388_801.0,
        lat_rad: deg(30.5),
        lon_rad: deg(114.3),
        h_m: 25.0,
        vel_ned_mps: [1.0, 2.0, -0.1],
        rpy_rad: [deg(1.0), deg(-2.0), deg(45.0)],
        // f32-representable so the round trip is exact.
        pos_std_ned_m: [0.5, 0.5, 1.0],
        vel_std_ned_mps: [0.0625, 0.0625, 0.125],
        att_std_rad: [0.001_953_125, 0.001_953_125, 0.015_625],
        status: 3,
    })
}

pub fn sample_config() -> Payload {
    Payload::Config(Config {
        model: nav_core::wire::model::NBK,
        flags: nav_core::wire::CONFIG_USE_GNSS_VELOCITY,
        nav_divider: 20,
        imu_rate_hz: 200.0,
        gnss_rate_hz: 1.0,
        lever_arm_frd_m: [0.1, -0.2, -0.85],
    })
}

pub fn sample_health() -> Payload {
    Payload::Health(Health {
        uptime_ms: 3_600_000,
        rx_frames_ok: 720_000,
        rx_rejected: 3,
        rx_crc_errors: 2,
        rx_lost: 4,
        imu_epochs: 719_990,
        gnss_updates: 3600,
        gnss_rejected: 1,
        epoch_ticks_max: 41_000,
        stack_peak_bytes: 6144,
        filter_status: 0,
        imu_implausible: 2,
        imu_gaps: 5,
        nhc_updates: 30_000,
        zupt_updates: 1_200,
        zaru_updates: 1_150,
    })
}

pub fn all_samples() -> [Payload; 5] {
    [
        sample_imu(),
        sample_gnss(),
        sample_nav(),
        sample_config(),
        sample_health(),
    ]
}

/// The un-stuffed bytes of a frame (header, payload, CRC).
pub fn raw_bytes(f: &Frame) -> Vec<u8> {
    let mut raw = [0u8; MAX_RAW_LEN];
    let n = encode_raw(f, &mut raw).unwrap();
    raw[..n].to_vec()
}

/// The wire bytes of a frame (COBS + delimiter).
pub fn wire_bytes(f: &Frame) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let n = encode(f, &mut out).unwrap();
    out[..n].to_vec()
}

/// Bitwise frame equality (see the module doc).
pub fn same_frame(a: &Frame, b: &Frame) -> bool {
    raw_bytes(a) == raw_bytes(b)
}

pub fn hex(b: &[u8]) -> String {
    b.iter()
        .map(|x| format!("{x:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

pub fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => any::<u64>().prop_map(f64::from_bits),
        4 => -1.0e6..1.0e6f64,
        1 => Just(0.0),
        1 => Just(f64::NAN),
    ]
}

pub fn f64x3() -> impl Strategy<Value = [f64; 3]> {
    [any_f64(), any_f64(), any_f64()]
}

pub fn quality() -> impl Strategy<Value = FixQuality> {
    (0u8..=6).prop_map(FixQuality::from_rtklib_q)
}

pub fn payload() -> impl Strategy<Value = Payload> {
    let imu = (any_f64(), f64x3(), f64x3(), any_f64(), any::<u16>()).prop_map(
        |(t_s, dtheta_rad, dv_mps, temperature_c, status)| {
            Payload::Imu(ImuFrame {
                sample: ImuSample {
                    t_s,
                    dtheta_rad,
                    dv_mps,
                    temperature_c,
                },
                status,
            })
        },
    );
    let gnss = (
        (any_f64(), any_f64(), any_f64(), any_f64()),
        (f64x3(), f64x3(), f64x3()),
        (any::<bool>(), quality(), any::<u8>()),
    )
        .prop_map(|((t_s, lat, lon, h), (ps, v, vs), (hv, q, n))| {
            Payload::Gnss(GnssFix {
                t_s,
                lat_rad: lat,
                lon_rad: lon,
                h_m: h,
                pos_std_ned_m: ps,
                vel_ned_mps: v,
                vel_std_ned_mps: vs,
                has_velocity: hv,
                quality: q,
                num_sats: n,
            })
        });
    let nav = (
        (any::<u16>(), any_f64(), any_f64(), any_f64(), any_f64()),
        (f64x3(), f64x3(), f64x3(), f64x3(), f64x3()),
        any::<u32>(),
    )
        .prop_map(|((week, t_s, lat, lon, h), (v, rpy, ps, vs, a), status)| {
            Payload::Nav(NavSolution {
                week,
                t_s,
                lat_rad: lat,
                lon_rad: lon,
                h_m: h,
                vel_ned_mps: v,
                rpy_rad: rpy,
                pos_std_ned_m: ps,
                vel_std_ned_mps: vs,
                att_std_rad: a,
                status,
            })
        });
    let config = (
        any::<u8>(),
        any::<u8>(),
        any::<u16>(),
        any::<f32>(),
        any::<f32>(),
        f64x3(),
    )
        .prop_map(|(model, flags, nav_divider, imu, gnss, lever)| {
            Payload::Config(Config {
                model,
                flags,
                nav_divider,
                imu_rate_hz: imu,
                gnss_rate_hz: gnss,
                lever_arm_frd_m: lever,
            })
        });
    let health = proptest::array::uniform16(any::<u32>()).prop_map(|v| {
        Payload::Health(Health {
            uptime_ms: v[0],
            rx_frames_ok: v[1],
            rx_rejected: v[2],
            rx_crc_errors: v[3],
            rx_lost: v[4],
            imu_epochs: v[5],
            gnss_updates: v[6],
            gnss_rejected: v[7],
            epoch_ticks_max: v[8],
            stack_peak_bytes: v[9],
            filter_status: v[10],
            imu_implausible: v[11],
            imu_gaps: v[12],
            nhc_updates: v[13],
            zupt_updates: v[14],
            zaru_updates: v[15],
        })
    });
    prop_oneof![6 => imu, 2 => gnss, 2 => nav, 1 => config, 1 => health]
}

pub fn frame() -> impl Strategy<Value = Frame> {
    (any::<u16>(), any::<u8>(), payload()).prop_map(|(seq, flags, payload)| Frame {
        seq,
        flags,
        payload,
    })
}
