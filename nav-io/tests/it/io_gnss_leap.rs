//! A GNSS log crossing the leap second 2016-12-31 23:59:60 UTC (GPS - UTC 17 s before, 18 s
//! after): NMEA times (UTC time of day + RMC date) stay on GPS time after it, and a UBX log's
//! NAV-PVT times (iTOW, GPS time) and week are unaffected by its UTC date.

use nav_core::types::{FixQuality, GnssFix};
use nav_io::gnss::encode::ubx_nav_pvt;
use nav_io::{read_nmea_log, read_ubx_log, GnssLogOptions};

/// NMEA checksum (XOR of the characters between `$` and `*`).
fn ck(body: &str) -> String {
    let c = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{c:02X}")
}

/// RMC + GGA + GST at UTC `time` (hhmmss.ss) on `date` (ddmmyy).
fn epoch(date: &str, time: &str) -> String {
    let lat = "4811.9400";
    [
        ck(&format!(
            "GPRMC,{time},A,{lat},N,01622.2000,E,0.4,90.0,{date},,,A"
        )),
        ck(&format!(
            "GPGGA,{time},{lat},N,01622.2000,E,4,12,0.8,220.0,M,0.0,M,1.0,0001"
        )),
        ck(&format!("GPGST,{time},0.03,0.02,0.02,0.0,0.02,0.02,0.04")),
    ]
    .iter()
    .map(|s| format!("{s}\r\n"))
    .collect()
}

// 2016-12-31 is the Saturday of GPS week 1929: 23:59:58 UTC is 604,798 s of the UTC week,
// GPS 604,798 + 17 = 604,815 s of week 1929 (past the week's end: week 1930 begins at GPS
// 2016-12-31 23:59:43 UTC).
const WEEK: i64 = 1929;

#[test]
fn an_nmea_log_across_the_2016_leap_second_stays_on_gps_time() {
    let dir = tempfile::tempdir().unwrap();
    let mut log = String::new();
    // 1 Hz: 23:59:58, 23:59:59, 23:59:60 (the leap second), 00:00:00, 00:00:01, 00:00:02
    for t in ["235958.00", "235959.00", "235960.00"] {
        log += &epoch("311216", t);
    }
    for t in ["000000.00", "000001.00", "000002.00"] {
        log += &epoch("010117", t);
    }
    let p = dir.path().join("leap.nmea");
    std::fs::write(&p, &log).unwrap();
    let r = read_nmea_log(&p, &GnssLogOptions::default(), 6).unwrap();
    // the 23:59:60 epoch cannot be parsed (second 60) and is skipped as a bad sentence
    assert_eq!(r.fixes.len(), 5, "{r:?}");
    assert!(r.bad_skipped >= 1, "{r:?}");
    // GPS time of the first fix: 23:59:58 UTC + 17 s = week 1930, 15 s
    assert_eq!(r.week, Some(WEEK + 1));
    let t: Vec<f64> = r.fixes.iter().map(|f| f.t_s).collect();
    // before: + 17 s; after 00:00:00 UTC: + 18 s. The UTC clock reads 1 s between 23:59:59
    // and 00:00:00, GPS time advances 2 s (the leap second in between).
    let want = [15.0, 16.0, 18.0, 19.0, 20.0];
    for (got, w) in t.iter().zip(want) {
        assert!((got - w).abs() < 1e-9, "times {t:?}, want {want:?}");
    }
    assert!(
        r.warnings.iter().any(|w| w.contains("leap second")),
        "{:?}",
        r.warnings
    );
    // a leap_seconds given in the configuration is used throughout (the user's choice)
    let fixed = GnssLogOptions {
        leap_seconds: Some(17),
        ..GnssLogOptions::default()
    };
    let r17 = read_nmea_log(&p, &fixed, 6).unwrap();
    let t17: Vec<f64> = r17.fixes.iter().map(|f| f.t_s).collect();
    assert_eq!(t17, vec![15.0, 16.0, 17.0, 18.0, 19.0]);
}

#[test]
fn a_ubx_log_across_the_2016_leap_second_keeps_itow_and_the_week() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = Vec::new();
    // GPS 604,795 s of week 1929 .. 20 s of week 1930, 1 Hz: the UTC date written into each
    // NAV-PVT uses the offset in force at that instant (17 s before 2017-01-01, 18 s after)
    let mut times = Vec::new();
    for k in 0..30 {
        let (week, sow) = if 604_795 + k < 604_800 {
            (WEEK, (604_795 + k) as f64)
        } else {
            (WEEK + 1, (604_795 + k - 604_800) as f64)
        };
        let gps_abs = week as f64 * 604_800.0 + sow;
        // 2017-01-01 00:00:00 UTC = GPS week 1930, 18 s
        let leap = if gps_abs >= 1930.0 * 604_800.0 + 18.0 {
            18
        } else {
            17
        };
        let fix = GnssFix {
            t_s: sow,
            lat_rad: 48.199f64.to_radians(),
            lon_rad: 16.37f64.to_radians(),
            h_m: 220.0,
            pos_std_ned_m: [0.02, 0.02, 0.04],
            quality: FixQuality::RtkFixed,
            num_sats: 12,
            ..GnssFix::default()
        };
        bytes.extend(ubx_nav_pvt(&fix, week, leap));
        times.push(gps_abs - WEEK as f64 * 604_800.0);
    }
    let p = dir.path().join("leap.ubx");
    std::fs::write(&p, &bytes).unwrap();
    let r = read_ubx_log(&p, &GnssLogOptions::default(), 6).unwrap();
    assert_eq!(r.fixes.len(), 30);
    assert_eq!(r.week, Some(WEEK));
    for (f, want) in r.fixes.iter().zip(&times) {
        assert!((f.t_s - want).abs() < 1e-6, "{} vs {want}", f.t_s);
    }
    // one second apart throughout
    for w in r.fixes.windows(2) {
        assert!((w[1].t_s - w[0].t_s - 1.0).abs() < 1e-6);
    }
}
