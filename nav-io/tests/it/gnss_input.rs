//! NMEA 0183 and UBX NAV-PVT input: real-looking sentences and packets with checksums,
//! malformed ones, and arbitrary chunking of a mixed receiver stream.

use nav_core::types::{FixQuality, GnssFix};
use nav_io::gnss::nmea_epoch::gps_seconds_of_week;
use nav_io::gnss::{GnssError, GnssEvent, GnssStream, NmeaAssembler, NmeaOptions};
use proptest::prelude::*;

/// NMEA checksum (XOR of the characters between `$` and `*`), computed independently.
fn with_checksum(body: &str) -> String {
    let ck = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{ck:02X}")
}

// A real receiver log (2011-05-28, Dublin area): GGA and RMC as recorded, checksums included.
const GGA1: &str = "$GPGGA,092750.000,5321.6802,N,00630.3372,W,1,8,1.03,61.7,M,55.2,M,,*76";
const RMC1: &str = "$GPRMC,092750.000,A,5321.6802,N,00630.3372,W,0.02,31.66,280511,,,A*43";

fn epoch(t: &str, lat: &str, gst: bool) -> Vec<String> {
    let mut v = vec![
        with_checksum(&format!(
            "GPRMC,{t},A,{lat},N,00630.3372,W,10.0,90.0,280511,,,A"
        )),
        with_checksum("GPVTG,90.0,T,,M,10.0,N,18.5,K,A"),
        with_checksum(&format!(
            "GPGGA,{t},{lat},N,00630.3372,W,2,09,0.9,61.7,M,55.2,M,,"
        )),
        with_checksum("GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1"),
    ];
    if gst {
        v.push(with_checksum(&format!(
            "GPGST,{t},1.2,0.9,0.7,30.0,0.8,0.6,1.5"
        )));
    }
    v
}

fn fixes(ev: Vec<GnssEvent>) -> Vec<GnssFix> {
    ev.into_iter()
        .map(|e| match e {
            GnssEvent::Fix(f) => f,
            GnssEvent::Error(e) => panic!("unexpected error {e}"),
        })
        .collect()
}

#[test]
fn recorded_gga_and_rmc_checksums_are_accepted_and_mapped() {
    let mut a = NmeaAssembler::new(NmeaOptions {
        leap_seconds: 15, // GPS - UTC in 2011
        hdop_uere_m: Some(2.0),
        velocity_std_mps: None,
    });
    assert!(a.push_sentence(RMC1).is_empty());
    assert!(a.push_sentence(GGA1).is_empty());
    let f = fixes(a.flush().into_iter().collect());
    assert_eq!(f.len(), 1);
    let f = f[0];
    // 2011-05-28 is a Saturday (day 6 of the GPS week); 09:27:50 UTC + 15 s.
    assert_eq!(
        f.t_s,
        6.0 * 86400.0 + 9.0 * 3600.0 + 27.0 * 60.0 + 50.0 + 15.0
    );
    assert!((f.lat_rad.to_degrees() - (53.0 + 21.6802 / 60.0)).abs() < 1e-9);
    assert!((f.lon_rad.to_degrees() + (6.0 + 30.3372 / 60.0)).abs() < 1e-9);
    assert!(
        (f.h_m - (61.7 + 55.2)).abs() < 1e-4,
        "MSL + geoid separation"
    );
    assert_eq!(f.quality, FixQuality::Single);
    assert_eq!(f.num_sats, 8);
    // No GST: HDOP x UERE fallback.
    let s = 1.03f32 as f64 * 2.0;
    assert_eq!(f.pos_std_ned_m, [s, s, 1.5 * s]);
    assert!(!f.has_velocity);
    assert!(f.is_valid());
}

#[test]
fn gga_gst_rmc_vtg_epochs_combine_and_emit_without_latency_after_the_first() {
    let mut a = NmeaAssembler::new(NmeaOptions {
        velocity_std_mps: Some((0.1, 0.3)),
        ..NmeaOptions::default()
    });
    let mut out = Vec::new();
    for (k, t) in ["120000.00", "120001.00", "120002.00"].iter().enumerate() {
        let lat = format!("53{:07.4}", 21.0 + k as f64 * 0.001);
        for s in epoch(t, &lat, true) {
            let ev = a.push_sentence(&s);
            out.push((k, s.clone(), ev));
        }
    }
    // First epoch: emitted when the second starts (its RMC). Second: emitted at its GST.
    let emitted: Vec<(usize, String)> = out
        .iter()
        .filter(|(_, _, ev)| !ev.is_empty())
        .map(|(k, s, _)| (*k, s[3..6].to_string()))
        .collect();
    assert_eq!(
        emitted,
        vec![(1, "RMC".into()), (1, "GST".into()), (2, "GST".into())]
    );
    let all: Vec<GnssFix> = out.into_iter().flat_map(|(_, _, ev)| fixes(ev)).collect();
    assert_eq!(all.len(), 3);
    let f = all[1];
    // 2011-05-28 12:00:01 UTC + 18 s (default leap seconds).
    assert_eq!(f.t_s, 6.0 * 86400.0 + 12.0 * 3600.0 + 1.0 + 18.0);
    assert!((f.lat_rad.to_degrees() - (53.0 + 21.001 / 60.0)).abs() < 1e-9);
    assert_eq!(f.quality, FixQuality::Dgnss);
    assert_eq!(f.num_sats, 9);
    assert_eq!(f.pos_std_ned_m, [0.8f32 as f64, 0.6f32 as f64, 1.5]);
    // 10 knots due east.
    assert!(f.has_velocity);
    assert!(f.vel_ned_mps[0].abs() < 1e-9);
    assert!((f.vel_ned_mps[1] - 10.0 * 1852.0 / 3600.0).abs() < 1e-9);
    assert_eq!(f.vel_std_ned_mps, [0.1, 0.1, 0.3]);
    assert!(f.is_valid());
    assert!(all.iter().all(|f| f.is_valid()));
}

#[test]
fn bad_checksum_is_rejected_with_the_sentence_and_index() {
    let mut a = NmeaAssembler::new(NmeaOptions::default());
    a.push_sentence(RMC1);
    let bad = GGA1.replace("*76", "*77");
    let ev = a.push_sentence(&bad);
    match &ev[..] {
        [GnssEvent::Error(GnssError::Nmea {
            index,
            sentence,
            reason,
        })] => {
            assert_eq!(*index, 2);
            assert_eq!(sentence, &bad);
            assert!(reason.to_lowercase().contains("checksum"), "{reason}");
        }
        other => panic!("expected a checksum error, got {other:?}"),
    }
    assert_eq!(a.errors(), 1);
    // The epoch has no position: flushing it reports that clearly.
    match a.flush() {
        Some(GnssEvent::Error(GnssError::Epoch { utc_time, reason })) => {
            assert_eq!(utc_time, "09:27:50.000");
            assert!(reason.contains("no GGA"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn malformed_fields_and_missing_date_are_clear_errors() {
    let mut a = NmeaAssembler::new(NmeaOptions::default());
    let ev = a.push_sentence(&with_checksum(
        "GPGGA,092750.000,53X1.6802,N,00630.3372,W,1,8,1.03,61.7,M,55.2,M,,",
    ));
    assert!(
        matches!(
            &ev[..],
            [GnssEvent::Error(GnssError::Nmea { index: 1, .. })]
        ),
        "{ev:?}"
    );
    // GGA alone: no date anywhere.
    a.push_sentence(GGA1);
    match a.flush() {
        Some(GnssEvent::Error(e @ GnssError::Epoch { .. })) => {
            assert!(e.to_string().contains("needs an RMC"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    let ev = a.push_sentence("$GPGGA,no checksum at all");
    assert!(matches!(&ev[..], [GnssEvent::Error(_)]));
}

#[test]
fn no_gst_and_no_fallback_gives_an_invalid_fix_not_a_guess() {
    let mut a = NmeaAssembler::new(NmeaOptions::default());
    a.push_sentence(RMC1);
    a.push_sentence(GGA1);
    let f = fixes(a.flush().into_iter().collect())[0];
    assert!(f.pos_std_ned_m.iter().all(|s| s.is_nan()));
    assert!(!f.is_valid());
}

#[test]
fn gga_without_fix_maps_to_no_fix() {
    let mut a = NmeaAssembler::new(NmeaOptions::default());
    a.push_sentence(RMC1);
    a.push_sentence(&with_checksum("GPGGA,092750.000,,,,,0,00,99.99,,,,,,"));
    let f = fixes(a.flush().into_iter().collect())[0];
    assert_eq!(f.quality, FixQuality::NoFix);
    assert!(!f.is_valid());
}

#[test]
fn date_carries_over_and_advances_at_midnight() {
    let mut a = NmeaAssembler::new(NmeaOptions {
        leap_seconds: 18,
        hdop_uere_m: Some(1.0),
        velocity_std_mps: None,
    });
    // Saturday 23:59:59 with RMC, then 00:00:00 (Sunday, new GPS week) with GGA only.
    a.push_sentence(&with_checksum(
        "GPRMC,235959.00,A,5321.6802,N,00630.3372,W,0.0,,280511,,,A",
    ));
    a.push_sentence(&with_checksum(
        "GPGGA,235959.00,5321.6802,N,00630.3372,W,1,8,1.0,61.7,M,55.2,M,,",
    ));
    let mut got = fixes(a.push_sentence(&with_checksum(
        "GPGGA,000000.00,5321.6802,N,00630.3372,W,1,8,1.0,61.7,M,55.2,M,,",
    )));
    got.extend(fixes(a.flush().into_iter().collect()));
    assert_eq!(got.len(), 2);
    assert_eq!(got[0].t_s, (6.0 * 86400.0 + 86399.0 + 18.0) % 604800.0);
    assert_eq!(got[1].t_s, 18.0, "Sunday 00:00:00 UTC + 18 s leap");
}

#[test]
fn gps_week_seconds_match_a_hand_computed_date() {
    // 2024-03-13 (a Wednesday, day 3) 10:20:30.25 UTC + 18 s.
    let d = chrono::NaiveDate::from_ymd_opt(2024, 3, 13).unwrap();
    let t = chrono::NaiveTime::from_hms_milli_opt(10, 20, 30, 250).unwrap();
    assert_eq!(
        gps_seconds_of_week(d, t, 18),
        3.0 * 86400.0 + 10.0 * 3600.0 + 20.0 * 60.0 + 30.0 + 18.0 + 0.25
    );
}

// ---------------------------------------------------------------- UBX NAV-PVT

#[allow(clippy::too_many_arguments)]
fn nav_pvt(
    itow_ms: u32,
    fix_type: u8,
    flags: u8,
    num_sv: u8,
    lon_e7: i32,
    lat_e7: i32,
    height_mm: i32,
    h_acc_mm: u32,
    v_acc_mm: u32,
    vel_mm: [i32; 3],
    s_acc_mm: u32,
) -> Vec<u8> {
    let mut p = vec![0u8; 92];
    p[0..4].copy_from_slice(&itow_ms.to_le_bytes());
    p[4..6].copy_from_slice(&2024u16.to_le_bytes());
    p[6] = 3;
    p[7] = 13;
    p[8] = 10;
    p[20] = fix_type;
    p[21] = flags;
    p[23] = num_sv;
    p[24..28].copy_from_slice(&lon_e7.to_le_bytes());
    p[28..32].copy_from_slice(&lat_e7.to_le_bytes());
    p[32..36].copy_from_slice(&height_mm.to_le_bytes());
    p[36..40].copy_from_slice(&(height_mm - 30_000).to_le_bytes());
    p[40..44].copy_from_slice(&h_acc_mm.to_le_bytes());
    p[44..48].copy_from_slice(&v_acc_mm.to_le_bytes());
    for (i, v) in vel_mm.iter().enumerate() {
        p[48 + 4 * i..52 + 4 * i].copy_from_slice(&v.to_le_bytes());
    }
    p[68..72].copy_from_slice(&s_acc_mm.to_le_bytes());
    ubx_frame(0x01, 0x07, &p)
}

/// UBX frame with the 8-bit Fletcher checksum over class, id, length and payload.
fn ubx_frame(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
    let mut f = vec![0xB5, 0x62, class, id];
    f.extend((payload.len() as u16).to_le_bytes());
    f.extend(payload);
    let (mut a, mut b) = (0u8, 0u8);
    for &x in &f[2..] {
        a = a.wrapping_add(x);
        b = b.wrapping_add(a);
    }
    f.extend([a, b]);
    f
}

fn stream_all(bytes: &[u8]) -> (Vec<GnssEvent>, GnssStream) {
    let mut s = GnssStream::new(NmeaOptions::default());
    let mut ev = s.feed(bytes);
    ev.extend(s.finish());
    (ev, s)
}

fn sample_pvt() -> Vec<u8> {
    // 3-D fix, gnssFixOK, 14 satellites, 30.5 N 114.3 E, 25.123 m, hAcc 1.2 m, vAcc 2.3 m.
    nav_pvt(
        302_400_200,
        3,
        0x01,
        14,
        1_143_000_000,
        305_000_000,
        25_123,
        1_200,
        2_300,
        [1_000, -2_000, 50],
        150,
    )
}

#[test]
fn ubx_nav_pvt_maps_to_a_fix() {
    let (ev, s) = stream_all(&sample_pvt());
    let f = fixes(ev);
    assert_eq!(f.len(), 1);
    let f = f[0];
    assert_eq!(f.t_s, 302_400.2);
    assert!((f.lat_rad.to_degrees() - 30.5).abs() < 1e-12);
    assert!((f.lon_rad.to_degrees() - 114.3).abs() < 1e-12);
    assert!((f.h_m - 25.123).abs() < 1e-12);
    assert!((f.pos_std_ned_m[0] - 1.2).abs() < 1e-12);
    assert!((f.pos_std_ned_m[2] - 2.3).abs() < 1e-12);
    assert!((f.vel_ned_mps[1] + 2.0).abs() < 1e-12);
    assert!((f.vel_std_ned_mps[0] - 0.15).abs() < 1e-12);
    assert!(f.has_velocity);
    assert_eq!(f.quality, FixQuality::Single);
    assert_eq!(f.num_sats, 14);
    assert!(f.is_valid());
    assert_eq!(s.stats().ubx_packets, 1);
}

#[test]
fn ubx_fix_types_and_carrier_flags_map_to_quality() {
    let q = |fix_type, flags| {
        let mut p = sample_pvt();
        p[6 + 20] = fix_type;
        p[6 + 21] = flags;
        let n = p.len();
        let fixed = ubx_frame(0x01, 0x07, &p[6..n - 2]);
        fixes(stream_all(&fixed).0)[0].quality
    };
    assert_eq!(q(3, 0x01), FixQuality::Single);
    assert_eq!(q(3, 0x03), FixQuality::Dgnss);
    assert_eq!(q(3, 0x41), FixQuality::RtkFloat);
    assert_eq!(q(3, 0x81), FixQuality::RtkFixed);
    assert_eq!(q(4, 0x01), FixQuality::Single);
    assert_eq!(
        q(2, 0x01),
        FixQuality::NoFix,
        "2-D fix has an assumed height"
    );
    assert_eq!(q(3, 0x00), FixQuality::NoFix, "gnssFixOK not set");
    assert_eq!(q(0, 0x00), FixQuality::NoFix);
}

#[test]
fn ubx_bad_checksum_is_reported_and_the_next_packet_still_parses() {
    let mut bytes = sample_pvt();
    let n = bytes.len();
    bytes[n - 1] ^= 0xFF;
    bytes.extend(sample_pvt());
    let (ev, s) = stream_all(&bytes);
    let errors: Vec<&GnssEvent> = ev
        .iter()
        .filter(|e| matches!(e, GnssEvent::Error(_)))
        .collect();
    assert_eq!(errors.len(), 1, "{ev:?}");
    let msg = match errors[0] {
        GnssEvent::Error(e @ GnssError::Ubx { .. }) => e.to_string(),
        other => panic!("{other:?}"),
    };
    assert!(msg.contains("checksum"), "{msg}");
    assert_eq!(
        fixes(
            ev.into_iter()
                .filter(|e| matches!(e, GnssEvent::Fix(_)))
                .collect()
        )
        .len(),
        1
    );
    assert_eq!(s.stats().ubx_errors, 1);
}

fn mixed_stream() -> Vec<u8> {
    let mut b = Vec::new();
    for (k, t) in ["120000.00", "120001.00", "120002.00"].iter().enumerate() {
        for s in epoch(t, "5321.6802", true) {
            b.extend(s.as_bytes());
            b.extend(b"\r\n");
        }
        // Other UBX traffic (NAV-STATUS-like, class 1 id 3) and a NAV-PVT per epoch.
        b.extend(ubx_frame(0x01, 0x03, &[0u8; 16]));
        let mut p = sample_pvt();
        p[6] = p[6].wrapping_add(k as u8);
        let n = p.len();
        b.extend(ubx_frame(0x01, 0x07, &p[6..n - 2]));
    }
    b
}

#[test]
fn mixed_nmea_and_ubx_stream_yields_both_kinds_of_fix() {
    let (ev, s) = stream_all(&mixed_stream());
    let f = fixes(ev);
    // 3 NMEA epochs + 3 NAV-PVT.
    assert_eq!(f.len(), 6);
    let st = s.stats();
    assert_eq!(st.nmea_sentences, 15);
    assert_eq!(st.nmea_ignored, 3, "GSA");
    assert_eq!(st.nmea_errors, 0);
    assert_eq!(st.ubx_packets, 6);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn any_chunking_of_a_receiver_stream_gives_the_same_fixes(
        cuts in proptest::collection::vec(any::<usize>(), 0..40)
    ) {
        let bytes = mixed_stream();
        let (whole, _) = stream_all(&bytes);
        let mut cuts: Vec<usize> = cuts.iter().map(|c| c % (bytes.len() + 1)).collect();
        cuts.sort_unstable();
        cuts.push(bytes.len());
        let mut s = GnssStream::new(NmeaOptions::default());
        let mut ev = Vec::new();
        let mut prev = 0;
        for c in cuts {
            ev.extend(s.feed(&bytes[prev..c]));
            prev = c;
        }
        ev.extend(s.finish());
        prop_assert_eq!(format!("{ev:?}"), format!("{whole:?}"));
    }

    #[test]
    fn random_bytes_and_damaged_streams_never_panic(
        noise in proptest::collection::vec(any::<u8>(), 0..2000),
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..20),
    ) {
        let mut s = GnssStream::new(NmeaOptions::default());
        s.feed(&noise);
        let mut b = mixed_stream();
        let n = b.len();
        for (at, x) in flips {
            b[at % n] ^= x;
        }
        s.feed(&b);
        s.finish();
        prop_assert!(s.stats().bytes == (noise.len() + n) as u64);
    }
}
