//! Calendar dates to GPS week and seconds of week (GPST has no leap seconds), and UTC to GPST
//! with the leap-second table.

/// Seconds in a GPS week.
pub const SECONDS_PER_WEEK: f64 = 604_800.0;

/// Days from 1970-01-01 to the proleptic Gregorian date `y-m-d` (negative before 1970).
/// Valid for any year representable in i64 without overflow (|y| < 1e15).
pub fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    // H. Hinnant's algorithm.
    let y = if m <= 2 { y - 1 } else { y };
    let era = if y >= 0 { y } else { y - 399 } / 400;
    let yoe = y - era * 400;
    let mp = (i64::from(m) + 9) % 12;
    let doy = (153 * mp + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Days in month `m` of year `y`.
pub fn days_in_month(y: i64, m: u32) -> u32 {
    match m {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if (y % 4 == 0 && y % 100 != 0) || y % 400 == 0 => 29,
        2 => 28,
        _ => 0,
    }
}

/// Days from 1970-01-01 to the GPS epoch 1980-01-06.
const GPS_EPOCH_DAYS: i64 = 3657;

/// GPS week and seconds of week of a GPST calendar time (`sec` may have a fraction).
/// Times before the GPS epoch give negative weeks.
pub fn gpst_week_sow(y: i64, mo: u32, d: u32, h: u32, mi: u32, sec: f64) -> (i64, f64) {
    let days = days_from_civil(y, mo, d) - GPS_EPOCH_DAYS;
    let week = days.div_euclid(7);
    let dow = days.rem_euclid(7);
    let sow = dow as f64 * 86_400.0 + f64::from(h) * 3600.0 + f64::from(mi) * 60.0 + sec;
    (week, sow)
}

/// UTC dates (y, m, d) from which GPST - UTC took the given whole number of seconds.
const LEAP_TABLE: [(i64, u32, u32, i32); 18] = [
    (1981, 7, 1, 1),
    (1982, 7, 1, 2),
    (1983, 7, 1, 3),
    (1985, 7, 1, 4),
    (1988, 1, 1, 5),
    (1990, 1, 1, 6),
    (1991, 1, 1, 7),
    (1992, 7, 1, 8),
    (1993, 7, 1, 9),
    (1994, 7, 1, 10),
    (1996, 1, 1, 11),
    (1997, 7, 1, 12),
    (1999, 1, 1, 13),
    (2006, 1, 1, 14),
    (2009, 1, 1, 15),
    (2012, 7, 1, 16),
    (2015, 7, 1, 17),
    (2017, 1, 1, 18),
];

/// The largest GPST - UTC of the leap-second table, s (18, from 2017-01-01 on).
pub const MAX_GPST_MINUS_UTC_S: i32 = LEAP_TABLE[LEAP_TABLE.len() - 1].3;

/// GPST - UTC in seconds at the UTC date `y-m-d` (0 before 1981-07-01; 18 from 2017 on, the
/// last leap second announced when this table was written).
pub fn gpst_minus_utc_s(y: i64, m: u32, d: u32) -> i32 {
    let day = days_from_civil(y, m, d);
    LEAP_TABLE
        .iter()
        .rev()
        .find(|(ly, lm, ld, _)| day >= days_from_civil(*ly, *lm, *ld))
        .map_or(0, |e| e.3)
}

/// GPST - UTC in seconds at a UTC time given on the GPS week count: `week` and `utc_sow`
/// are the UTC calendar time counted like GPS weeks and seconds of week from 1980-01-06
/// 00:00:00 (86,400 s a day, no leap seconds; what a UTC time of day plus a date, converted
/// without leap seconds, gives). The offset changes at 00:00:00 UTC of the table's dates.
pub fn gpst_minus_utc_at_utc_week_sow(week: i64, utc_sow: f64) -> i32 {
    let day_in_week = (utc_sow / 86_400.0).floor() as i64;
    let day = GPS_EPOCH_DAYS + week * 7 + day_in_week;
    LEAP_TABLE
        .iter()
        .rev()
        .find(|(ly, lm, ld, _)| day >= days_from_civil(*ly, *lm, *ld))
        .map_or(0, |e| e.3)
}

/// GPS week and seconds of week of a GPST time given as seconds since 1970-01-01 00:00:00 in
/// the GPST time scale (RTKLIB's `gtime_t` convention: `time` + `sec`).
pub fn gpst_week_sow_from_epoch_s(secs: f64) -> (i64, f64) {
    let from_gps_epoch = secs - GPS_EPOCH_DAYS as f64 * 86_400.0;
    let week = (from_gps_epoch / SECONDS_PER_WEEK).floor();
    (week as i64, from_gps_epoch - week * SECONDS_PER_WEEK)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(1980, 1, 6), GPS_EPOCH_DAYS);
        assert_eq!(gpst_week_sow(1980, 1, 6, 0, 0, 0.0), (0, 0.0));
        // GPS week 1024 rollover: 1999-08-22
        assert_eq!(gpst_week_sow(1999, 8, 22, 0, 0, 0.0), (1024, 0.0));
        // 2025-07-08 is a Tuesday of week 2374 (week started Sunday 2025-07-06)
        let (w, s) = gpst_week_sow(2025, 7, 8, 19, 34, 21.854);
        assert_eq!(w, 2374);
        assert!((s - 243_261.854).abs() < 1e-9);
        assert_eq!(gpst_minus_utc_s(2025, 7, 8), 18);
        assert_eq!(gpst_minus_utc_s(2016, 12, 31), 17);
        assert_eq!(gpst_minus_utc_s(1980, 1, 6), 0);
        // the UTC week count of 2016-12-31 23:59:59 and 2017-01-01 00:00:00 (week 1929 began
        // on Sunday 2016-12-25: Saturday 23:59:59 is 604,799 s, the next midnight week 1930)
        assert_eq!(gpst_minus_utc_at_utc_week_sow(1929, 604_799.5), 17);
        assert_eq!(gpst_minus_utc_at_utc_week_sow(1930, 0.0), 18);
        assert_eq!(gpst_minus_utc_at_utc_week_sow(1929, 0.0), 17);
        assert_eq!(gpst_minus_utc_at_utc_week_sow(0, 0.0), 0);
        assert_eq!(days_in_month(2024, 2), 29);
        assert_eq!(days_in_month(1900, 2), 28);
        // 1752003261.854 s = 2025-07-08 19:34:21.854 (the drive's tag start)
        let (w, s) = gpst_week_sow_from_epoch_s(1_752_003_261.0 + 0.854);
        assert_eq!(w, 2374);
        assert!((s - 243_261.854).abs() < 1e-6);
    }
}
