//! Writers of receiver messages for a [`GnssFix`]: NMEA 0183 RMC + GGA + GST sentences and a
//! u-blox UBX NAV-PVT frame, as a receiver would send them (for test logs, simulated
//! receivers and the bridge). Times: the fix's GPS seconds of `week`; UTC = GPST - `leap_s`.
//!
//! Resolution: NMEA time 0.01 s, latitude/longitude 1e-7 arc-minute (0.2 mm), height 1 mm,
//! speed 0.001 kn, course 0.01 deg, sigmas 1 mm (GGA writes the height as MSL with a geoid
//! separation of 0, so MSL + separation = the fix's ellipsoidal height); NAV-PVT 1 ms,
//! 1e-7 deg (11 mm), 1 mm, 1 mm/s.
use nav_core::types::{FixQuality, GnssFix};

/// The UTC calendar time of GPS seconds `sow` of `week` with GPST - UTC = `leap_s`:
/// (year, month, day, hour, minute, second with fraction).
pub fn utc_of_gps(week: i64, sow: f64, leap_s: i32) -> super::ubx::UtcTime {
    use chrono::{Datelike, Timelike};
    let total = week as f64 * super::super::gpstime::SECONDS_PER_WEEK + sow - f64::from(leap_s);
    let whole = total.floor();
    let frac = total - whole;
    let epoch = chrono::NaiveDate::from_ymd_opt(1980, 1, 6)
        .and_then(|d| d.and_hms_opt(0, 0, 0))
        .unwrap_or_default();
    let t = epoch + chrono::Duration::seconds(whole as i64);
    (
        t.year(),
        t.month(),
        t.day(),
        t.hour(),
        t.minute(),
        f64::from(t.second()) + frac,
    )
}

fn checksum(body: &str) -> String {
    let c = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{c:02X}")
}

/// `ddmm.mmmmmmm,N` / `dddmm.mmmmmmm,E` of an angle in degrees.
fn nmea_angle(deg: f64, lat: bool) -> String {
    let (pos, neg) = if lat { ('N', 'S') } else { ('E', 'W') };
    let a = deg.abs();
    let mut d = a.floor();
    let mut m = (a - d) * 60.0;
    if (m * 1e7).round() >= 60.0 * 1e7 {
        d += 1.0;
        m = 0.0;
    }
    let h = if deg < 0.0 { neg } else { pos };
    if lat {
        format!("{:02}{:010.7},{h}", d as u32, m)
    } else {
        format!("{:03}{:010.7},{h}", d as u32, m)
    }
}

/// GGA fix-quality code of a fix quality.
fn gga_quality(q: FixQuality) -> u8 {
    match q {
        FixQuality::NoFix => 0,
        FixQuality::Single | FixQuality::Ppp => 1,
        FixQuality::Dgnss | FixQuality::Sbas => 2,
        FixQuality::RtkFixed => 4,
        FixQuality::RtkFloat => 5,
    }
}

/// One NMEA epoch for `fix`: RMC (date, speed over ground and course when the fix has a
/// velocity), GGA (position,
/// quality, satellites) and GST (latitude/longitude/altitude sigmas), with checksums,
/// without line ends.
pub fn nmea_epoch(fix: &GnssFix, week: i64, leap_s: i32) -> [String; 3] {
    // rounded to the 0.01 s of the time field (the 1 ms keeps the floor below off 59.99999)
    let t = (fix.t_s * 100.0).round() / 100.0 + 1e-3;
    let (y, mo, d, h, mi, s) = utc_of_gps(week, t, leap_s);
    let cs = (s * 100.0).floor() as u32;
    let time = format!("{h:02}{mi:02}{:02}.{:02}", cs / 100, cs % 100);
    let lat = nmea_angle(fix.lat_rad.to_degrees(), true);
    let lon = nmea_angle(fix.lon_rad.to_degrees(), false);
    let [vn, ve, _] = fix.vel_ned_mps;
    let speed_kn = vn.hypot(ve) * 3600.0 / 1852.0;
    let course = ve.atan2(vn).to_degrees().rem_euclid(360.0);
    let date = format!("{d:02}{mo:02}{:02}", y.rem_euclid(100));
    let status = if fix.quality == FixQuality::NoFix {
        'V'
    } else {
        'A'
    };
    // a fix without a velocity leaves speed and course empty
    let (speed, course) = if fix.has_velocity {
        (format!("{speed_kn:.3}"), format!("{course:.2}"))
    } else {
        (String::new(), String::new())
    };
    let rmc = checksum(&format!(
        "GPRMC,{time},{status},{lat},{lon},{speed},{course},{date},,,D"
    ));
    let gga = checksum(&format!(
        "GPGGA,{time},{lat},{lon},{},{:02},0.8,{:.3},M,0.000,M,1.0,0001",
        gga_quality(fix.quality),
        fix.num_sats,
        fix.h_m
    ));
    let [sn, se, sd] = fix.pos_std_ned_m;
    let gst = checksum(&format!(
        "GPGST,{time},{:.3},{:.3},{:.3},0.0,{sn:.3},{se:.3},{sd:.3}",
        sn.hypot(se),
        sn.max(se),
        sn.min(se)
    ));
    [rmc, gga, gst]
}

/// A UBX frame: sync, class, id, little-endian length, payload, 8-bit Fletcher checksum.
pub fn ubx_frame(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
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

/// A UBX NAV-PVT frame (class 0x01, id 0x07, 92-byte payload) for `fix`: iTOW, the UTC date
/// and time (flagged valid and fully resolved), fix type 3-D with `gnssFixOK` and the
/// carrier/differential flags of the quality, position, `hAcc` = the larger horizontal
/// sigma, `vAcc`, NED velocity and `sAcc` = the largest velocity sigma (1000 m/s for a fix
/// without a velocity).
pub fn ubx_nav_pvt(fix: &GnssFix, week: i64, leap_s: i32) -> Vec<u8> {
    let (y, mo, d, h, mi, s) = utc_of_gps(week, fix.t_s, leap_s);
    let mut b = vec![0u8; 92];
    let itow = (fix.t_s * 1000.0).round().rem_euclid(604_800_000.0) as u32;
    b[0..4].copy_from_slice(&itow.to_le_bytes());
    b[4..6].copy_from_slice(&(y as u16).to_le_bytes());
    b[6] = mo as u8;
    b[7] = d as u8;
    b[8] = h as u8;
    b[9] = mi as u8;
    let whole = s.floor();
    b[10] = whole as u8;
    b[11] = 0x07; // validDate, validTime, fullyResolved
    let nanos = ((s - whole) * 1e9).round() as i32;
    b[16..20].copy_from_slice(&nanos.to_le_bytes());
    let (fix_type, flags) = match fix.quality {
        FixQuality::NoFix => (0u8, 0u8),
        FixQuality::RtkFixed => (3, 0x83),
        FixQuality::RtkFloat => (3, 0x43),
        FixQuality::Dgnss | FixQuality::Sbas => (3, 0x03),
        FixQuality::Single | FixQuality::Ppp => (3, 0x01),
    };
    b[20] = fix_type;
    b[21] = flags;
    b[23] = fix.num_sats;
    let e7 = |r: f64| ((r.to_degrees() * 1e7).round() as i32).to_le_bytes();
    let mm = |m: f64| ((m * 1e3).round() as i32).to_le_bytes();
    let umm = |m: f64| ((m * 1e3).round().max(0.0) as u32).to_le_bytes();
    b[24..28].copy_from_slice(&e7(fix.lon_rad));
    b[28..32].copy_from_slice(&e7(fix.lat_rad));
    b[32..36].copy_from_slice(&mm(fix.h_m));
    b[36..40].copy_from_slice(&mm(fix.h_m));
    let [sn, se, sd] = fix.pos_std_ned_m;
    b[40..44].copy_from_slice(&umm(sn.max(se)));
    b[44..48].copy_from_slice(&umm(sd));
    for i in 0..3 {
        b[48 + 4 * i..52 + 4 * i].copy_from_slice(&mm(fix.vel_ned_mps[i]));
    }
    let [vn, ve, _] = fix.vel_ned_mps;
    b[60..64].copy_from_slice(&mm(vn.hypot(ve)));
    // NAV-PVT always has a velocity: a fix without one gets sAcc = 1000 m/s (no information)
    let s_acc = if fix.has_velocity {
        fix.vel_std_ned_mps.iter().fold(0.0f64, |a, v| a.max(*v))
    } else {
        1000.0
    };
    b[68..72].copy_from_slice(&umm(s_acc));
    ubx_frame(0x01, 0x07, &b)
}
