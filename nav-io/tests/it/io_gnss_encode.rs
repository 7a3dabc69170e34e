//! The receiver-message writers (`nav_io::gnss::encode`) read back through the log readers:
//! NMEA RMC/GGA/GST and UBX NAV-PVT round trips within the formats' resolution, and the
//! GPS week of a UBX log derived from NAV-PVT's UTC date with the leap seconds, across a
//! week rollover (NAV-PVT has no week field).
use nav_core::types::{FixQuality, GnssFix};
use nav_io::gnss::encode::{nmea_epoch, ubx_nav_pvt, utc_of_gps};
use nav_io::{read_nmea_log, read_ubx_log, GnssLogOptions};

fn fix(k: usize, sow0: f64) -> GnssFix {
    GnssFix {
        t_s: sow0 + 0.2 * k as f64,
        lat_rad: (47.123_456_789 + 1e-6 * k as f64).to_radians(),
        lon_rad: (-122.987_654_321 - 2e-6 * k as f64).to_radians(),
        h_m: 123.456 + 0.01 * k as f64,
        pos_std_ned_m: [0.012, 0.015, 0.031],
        vel_ned_mps: [3.0, -4.0, 0.25],
        vel_std_ned_mps: [0.02, 0.02, 0.04],
        has_velocity: true,
        quality: FixQuality::RtkFixed,
        num_sats: 17,
    }
}

#[test]
fn utc_of_gps_uses_the_leap_seconds() {
    // GPS week 2305, day 3, 10:20:48 GPST = 2024-03-13 10:20:30 UTC (GPS - UTC = 18 s)
    let sow = 3.0 * 86400.0 + 10.0 * 3600.0 + 20.0 * 60.0 + 48.0;
    let (y, mo, d, h, mi, s) = utc_of_gps(2305, sow + 0.25, 18);
    assert_eq!((y, mo, d, h, mi), (2024, 3, 13, 10, 20));
    assert!((s - 30.25).abs() < 1e-9, "{s}");
}

#[test]
fn ubx_week_from_the_utc_date_across_a_week_rollover() {
    let dir = tempfile::tempdir().unwrap();
    // 2 s before the end of GPS week 2305 (in UTC still 18 s earlier): 20 fixes at 5 Hz
    let fixes: Vec<GnssFix> = (0..20).map(|k| fix(k, 604_798.0)).collect();
    let bytes: Vec<u8> = fixes
        .iter()
        .flat_map(|f| ubx_nav_pvt(f, 2305, 18))
        .collect();
    let p = dir.path().join("pvt.ubx");
    std::fs::write(&p, bytes).unwrap();
    let r = read_ubx_log(&p, &GnssLogOptions::default(), 6).unwrap();
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_eq!(r.week, Some(2305));
    assert_eq!(r.fixes.len(), 20);
    for (a, b) in r.fixes.iter().zip(&fixes) {
        // seconds continue past 604800 in the first fix's week
        assert!((a.t_s - b.t_s).abs() < 1e-6, "{} vs {}", a.t_s, b.t_s);
        assert!((a.lat_rad - b.lat_rad).abs().to_degrees() < 0.6e-7);
        assert!((a.lon_rad - b.lon_rad).abs().to_degrees() < 0.6e-7);
        assert!((a.h_m - b.h_m).abs() < 0.6e-3);
        for i in 0..3 {
            assert!((a.vel_ned_mps[i] - b.vel_ned_mps[i]).abs() < 0.6e-3);
        }
        assert!((a.pos_std_ned_m[0] - 0.015).abs() < 1e-9);
        assert!((a.pos_std_ned_m[2] - 0.031).abs() < 1e-9);
        assert_eq!(a.quality, FixQuality::RtkFixed);
    }
    // a log that starts in the next week: the week is 2306
    let later: Vec<u8> = fixes[12..]
        .iter()
        .flat_map(|f| ubx_nav_pvt(f, 2305, 18))
        .collect();
    std::fs::write(&p, later).unwrap();
    let r = read_ubx_log(&p, &GnssLogOptions::default(), 6).unwrap();
    assert_eq!(r.week, Some(2306));
    assert!((r.fixes[0].t_s - (fixes[12].t_s - 604_800.0)).abs() < 1e-6);
    // a stated leap-second count (`[gnss.log] leap_seconds`) is used instead of the table
    let opts = GnssLogOptions {
        leap_seconds: Some(18),
        ..GnssLogOptions::default()
    };
    assert_eq!(read_ubx_log(&p, &opts, 6).unwrap().week, Some(2306));
}

#[test]
fn nmea_writer_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let sow0 = 3.0 * 86400.0 + 36000.0 + 0.2;
    let fixes: Vec<GnssFix> = (0..10).map(|k| fix(k, sow0)).collect();
    let text: String = fixes
        .iter()
        .flat_map(|f| nmea_epoch(f, 2305, 18))
        .map(|l| l + "\r\n")
        .collect();
    let p = dir.path().join("log.nmea");
    std::fs::write(&p, text).unwrap();
    let opts = GnssLogOptions {
        vel_sigma_mps: Some([0.05, 0.1]),
        ..GnssLogOptions::default()
    };
    let r = read_nmea_log(&p, &opts, 6).unwrap();
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_eq!(r.week, Some(2305));
    assert_eq!(r.fixes.len(), 10);
    for (a, b) in r.fixes.iter().zip(&fixes) {
        assert!((a.t_s - b.t_s).abs() < 1e-6, "{} vs {}", a.t_s, b.t_s);
        let dn = (a.lat_rad - b.lat_rad) * 6.4e6;
        let de = (a.lon_rad - b.lon_rad) * 6.4e6 * b.lat_rad.cos();
        assert!(dn.abs() < 1e-3 && de.abs() < 1e-3, "{dn} {de}");
        assert!((a.h_m - b.h_m).abs() < 1e-3);
        for i in 0..3 {
            assert!((a.pos_std_ned_m[i] - b.pos_std_ned_m[i]).abs() < 1e-6);
        }
        // speed and course: the horizontal velocity, down 0
        assert!((a.vel_ned_mps[0] - 3.0).abs() < 1e-3 && (a.vel_ned_mps[1] + 4.0).abs() < 1e-3);
        assert_eq!(a.quality, FixQuality::RtkFixed);
    }
}
