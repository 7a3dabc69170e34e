//! RTKLIB `.pos` reader: layouts (calendar/week-tow time, GPST/UTC, deg/dms/ECEF position,
//! with and without velocities), quality filter, errors, and the real drive's solution file.

use nalgebra::{Matrix3, Vector3};
use nav_core::earth::{ecef_to_ned_dcm, geodetic_to_ecef_m, Llh};
use nav_core::types::FixQuality;
use nav_io::{read_rtklib_pos, IoError, PosOptions, PosPositionFormat, PosTimeSystem};
use std::path::{Path, PathBuf};

fn write(dir: &tempfile::TempDir, name: &str, s: &str) -> PathBuf {
    let p = dir.path().join(name);
    std::fs::write(&p, s).unwrap();
    p
}

const HDR_LLH: &str = "% program   : RTKPOST ver.demo5\n\
% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)\n\
%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio    vn(m/s)    ve(m/s)    vu(m/s)      sdvn     sdve     sdvu    sdvne    sdveu    sdvun\n";

#[test]
fn pos_calendar_gpst_with_velocity_converts_up_to_down_and_computes_week_and_sow() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        &dir,
        "a.pos",
        &format!(
            "{HDR_LLH}2025/07/08 19:34:18.499  40.096626800 -105.147448300  1601.4740   1  21   0.0099   0.0098   0.0100   0.0010  -0.0020   0.0030   0.00    0.0   0.0100  -0.0020   0.0090   0.0587   0.0586   0.0585   0.0000   0.0000   0.0000\n\
2025/07/08 19:34:18.749  40.096626900 -105.147448300  1601.4760   2  21   0.0200   0.0200   0.0300   0.0000   0.0000   0.0000   0.00    0.0   0.0010   0.0020  -0.0060   0.0558   0.0558   0.0558   0.0000   0.0000   0.0000\n"
        ),
    );
    let r = read_rtklib_pos(&p, &PosOptions::default()).unwrap();
    assert_eq!(r.time_system, PosTimeSystem::Gpst);
    assert_eq!(r.position_format, PosPositionFormat::LlhDeg);
    assert!(r.has_velocity);
    assert_eq!(r.week, Some(2374));
    assert_eq!(r.epochs, 2);
    assert_eq!(r.fixes.len(), 2);
    let f = &r.fixes[0];
    // 2025-07-08 is day 2 of GPS week 2374: 2*86400 + 19*3600 + 34*60 + 18.499
    assert!((f.t_s - (2.0 * 86400.0 + 19.0 * 3600.0 + 34.0 * 60.0 + 18.499)).abs() < 1e-9);
    assert!((f.t_s - 243258.499).abs() < 1e-9);
    assert!((f.lat_rad.to_degrees() - 40.0966268).abs() < 1e-12);
    assert!((f.lon_rad.to_degrees() + 105.1474483).abs() < 1e-12);
    assert_eq!(f.h_m, 1601.474);
    assert_eq!(f.pos_std_ned_m, [0.0099, 0.0098, 0.01]);
    assert_eq!(
        f.vel_ned_mps,
        [0.01, -0.002, -0.009],
        "vu = +0.009 up is vd = -0.009"
    );
    assert_eq!(f.vel_std_ned_mps, [0.0587, 0.0586, 0.0585]);
    assert_eq!(f.quality, FixQuality::RtkFixed);
    assert_eq!(f.num_sats, 21);
    assert_eq!(r.fixes[1].quality, FixQuality::RtkFloat);
    assert_eq!(r.fixes[1].vel_ned_mps[2], 0.006);
    // fixed only
    let r1 = read_rtklib_pos(&p, &PosOptions { max_q: 1 }).unwrap();
    assert_eq!(r1.fixes.len(), 1);
    assert_eq!(r1.dropped_by_quality, 1);
    assert_eq!(r1.count_by_q[1], 1);
    assert_eq!(r1.count_by_q[2], 1);
}

#[test]
fn pos_week_tow_format_without_velocity_and_quality_filter() {
    let dir = tempfile::tempdir().unwrap();
    let s = "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n\
2374 243258.500   40.0966268 -105.1474483  1601.474   5  12   1.2000   0.9000   2.5000   0.1  -0.2   0.3   0.00    0.0\n\
2374 243259.500   40.0966268 -105.1474483  1601.474   1  12   0.0100   0.0100   0.0200   0.0   0.0   0.0   1.00  999.9\n\
2374 243260.500   40.0966268 -105.1474483  1601.474   4  12   0.5000   0.5000   0.8000   0.0   0.0   0.0   1.00    0.0\n";
    let p = write(&dir, "b.pos", s);
    let r = read_rtklib_pos(&p, &PosOptions { max_q: 2 }).unwrap();
    assert!(!r.has_velocity);
    assert_eq!(r.epochs, 3);
    assert_eq!(r.fixes.len(), 1);
    assert_eq!(r.dropped_by_quality, 2);
    assert_eq!(r.count_by_q, [0, 1, 0, 0, 1, 1, 0, 0]);
    assert_eq!(r.fixes[0].t_s, 243259.5);
    assert!(!r.fixes[0].has_velocity);
    let all = read_rtklib_pos(&p, &PosOptions { max_q: 6 }).unwrap();
    assert_eq!(all.fixes.len(), 3);
    assert_eq!(all.fixes[0].quality, FixQuality::Single);
    assert_eq!(all.fixes[0].pos_std_ned_m, [1.2, 0.9, 2.5]);
    // invalid option
    let e = read_rtklib_pos(&p, &PosOptions { max_q: 0 }).unwrap_err();
    assert!(e.to_string().contains("max_q"));
}

#[test]
fn pos_utc_time_is_converted_to_gpst_with_18_leap_seconds_and_week_rollover_stays_monotonic() {
    let dir = tempfile::tempdir().unwrap();
    // Saturday 2025-07-12 23:59:50 UTC = 2025-07-13 00:00:08 GPST (next week, 8 s)
    let s = "%  UTC                   latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n\
2025/07/12 23:59:40.000   40.0 -105.0  1600.0   1  12   0.01 0.01 0.02 0 0 0 0 0\n\
2025/07/12 23:59:50.000   40.0 -105.0  1600.0   1  12   0.01 0.01 0.02 0 0 0 0 0\n";
    let p = write(&dir, "utc.pos", s);
    let r = read_rtklib_pos(&p, &PosOptions::default()).unwrap();
    assert_eq!(r.time_system, PosTimeSystem::Utc);
    // first record: 23:59:58 GPST Saturday = 604798 s of week 2374
    assert_eq!(r.week, Some(2374));
    assert!((r.fixes[0].t_s - 604_798.0).abs() < 1e-9);
    // second one is in week 2375 (8 s), continued past 604800
    assert!((r.fixes[1].t_s - 604_808.0).abs() < 1e-9);
}

#[test]
fn pos_dms_latitude_longitude_variant() {
    let dir = tempfile::tempdir().unwrap();
    let s = "%  GPST                  latitude(d'\")   longitude(d'\")  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n\
2025/07/08 19:34:18.500   40 05 47.85648 -105 08 50.81388  1601.4740   1  21   0.0099   0.0099   0.0100   0.0000   0.0000   0.0000   0.00    0.0\n\
2025/07/08 19:34:18.750   -0 30 00.00000  -0 15 00.00000  10.0   1  21   0.0099   0.0099   0.0100   0.0000   0.0000   0.0000   0.00    0.0\n";
    let p = write(&dir, "dms.pos", s);
    let r = read_rtklib_pos(&p, &PosOptions::default()).unwrap();
    assert_eq!(r.position_format, PosPositionFormat::LlhDms);
    let f = &r.fixes[0];
    assert!((f.lat_rad.to_degrees() - (40.0 + 5.0 / 60.0 + 47.85648 / 3600.0)).abs() < 1e-12);
    assert!((f.lon_rad.to_degrees() + (105.0 + 8.0 / 60.0 + 50.81388 / 3600.0)).abs() < 1e-12);
    assert!(
        (r.fixes[1].lat_rad.to_degrees() + 0.5).abs() < 1e-12,
        "sign of -0 degrees"
    );
    assert!((r.fixes[1].lon_rad.to_degrees() + 0.25).abs() < 1e-12);
}

fn rtklib_sd(p: &Matrix3<f64>) -> [f64; 6] {
    let s = |v: f64| v.signum() * v.abs().sqrt();
    [
        p[(0, 0)].sqrt(),
        p[(1, 1)].sqrt(),
        p[(2, 2)].sqrt(),
        s(p[(0, 1)]),
        s(p[(1, 2)]),
        s(p[(2, 0)]),
    ]
}

#[test]
fn pos_ecef_layout_is_converted_to_geodetic_with_ned_sigmas_and_velocity() {
    let llh = Llh::from_deg(40.0966268, -105.1474483, 1601.474);
    let r = geodetic_to_ecef_m(&llh);
    let c = ecef_to_ned_dcm(&llh); // C_e^n
    let p_ned = Matrix3::from_diagonal(&Vector3::new(
        0.02f64.powi(2),
        0.03f64.powi(2),
        0.05f64.powi(2),
    ));
    let p_ecef = c.transpose() * p_ned * c;
    let v_ned = Vector3::new(3.0, -4.0, 0.5);
    let v_ecef = c.transpose() * v_ned;
    let pv_ecef = c.transpose() * (p_ned * 4.0) * c;
    let sd = rtklib_sd(&p_ecef);
    let sdv = rtklib_sd(&pv_ecef);
    let line = format!(
        "2025/07/08 19:34:18.500 {:.4} {:.4} {:.4} 1 21 {} {} {} {} {} {} 0.0 0.0 {} {} {} {} {} {} {} {} {}\n",
        r.x, r.y, r.z, sd[0], sd[1], sd[2], sd[3], sd[4], sd[5], v_ecef.x, v_ecef.y, v_ecef.z,
        sdv[0], sdv[1], sdv[2], sdv[3], sdv[4], sdv[5]
    );
    let s = format!("%  GPST                      x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns   sdx(m)   sdy(m)   sdz(m)  sdxy(m)  sdyz(m)  sdzx(m) age(s)  ratio  vx(m/s) vy(m/s) vz(m/s) sdvx sdvy sdvz sdvxy sdvyz sdvzx\n{line}");
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "ecef.pos", &s);
    let rec = read_rtklib_pos(&p, &PosOptions::default()).unwrap();
    assert_eq!(rec.position_format, PosPositionFormat::Ecef);
    let f = &rec.fixes[0];
    assert!((f.lat_rad - llh.lat_rad).abs() * 6.4e6 < 1e-3);
    assert!((f.lon_rad - llh.lon_rad).abs() * 6.4e6 < 1e-3);
    assert!((f.h_m - llh.h_m).abs() < 1e-3);
    for (k, want) in [0.02, 0.03, 0.05].iter().enumerate() {
        assert!(
            (f.pos_std_ned_m[k] - want).abs() < 1e-9,
            "{:?}",
            f.pos_std_ned_m
        );
        assert!(
            (f.vel_std_ned_mps[k] - 2.0 * want).abs() < 1e-9,
            "{:?}",
            f.vel_std_ned_mps
        );
        assert!((f.vel_ned_mps[k] - v_ned[k]).abs() < 1e-9);
    }
}

fn pos_err(body: &str) -> (IoError, String) {
    let dir = tempfile::tempdir().unwrap();
    let p = write(&dir, "bad_solution.pos", &format!("{HDR_LLH}{body}"));
    let e = read_rtklib_pos(&p, &PosOptions::default()).unwrap_err();
    let m = e.to_string();
    assert!(m.contains("bad_solution.pos"), "{m}");
    (e, m)
}

const GOOD: &str = "2025/07/08 19:34:18.499 40.0966268 -105.1474483 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0 0.01 -0.002 0.009 0.0587 0.0587 0.0587 0 0 0\n";

#[test]
fn pos_malformed_records_give_errors_naming_line_and_column() {
    // header is 3 lines: the good record is line 4, the bad one line 5
    let (e, m) = pos_err(&format!(
        "{GOOD}2025/07/08 19:34:18.749 40.0966268 -105.1474483 1601.474 1 21 0.0099\n"
    ));
    assert!(
        matches!(
            e,
            IoError::TooFewFields {
                line: 5,
                column: 9,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(m.contains("sde_m"), "{m}");
    let (e, _) = pos_err(&format!(
        "{GOOD}2025/07/08 19:34:18.749 40.0966268 -105.1474483 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0 0.01 -0.002\n"
    ));
    assert!(matches!(e, IoError::TooFewFields { line: 5, .. }), "{e:?}");
    let (e, m) = pos_err(&format!(
        "{GOOD}2025/07/08 19:34:18.749 40.0966268 west 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0\n"
    ));
    assert!(
        matches!(
            e,
            IoError::NotANumber {
                line: 5,
                column: 4,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(m.contains("longitude_deg"), "{m}");
    let (e, _) = pos_err(&format!(
        "{GOOD}2025/07/08 19:34:18.749 40.0966268 -105.1474483 nan 1 21 0.0099 0.0099 0.01 0 0 0 0 0\n"
    ));
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: 5,
                column: 5,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, m) = pos_err(&format!(
        "{GOOD}2025/07/08 19:34:18.499 40.0966268 -105.1474483 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0\n"
    ));
    assert!(
        matches!(e, IoError::NonMonotonicTime { line: 5, .. }),
        "{e:?}"
    );
    assert!(m.contains("non-monotonic"), "{m}");
    let (e, _) = pos_err("2025/13/08 19:34:18.499 40.0966268 -105.1474483 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0\n");
    assert!(
        matches!(
            e,
            IoError::InvalidValue {
                line: 4,
                column: 1,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, _) = pos_err("2025/07/08 19:34:18.499 40.0966268 -105.1474483 1601.474 9 21 0.0099 0.0099 0.01 0 0 0 0 0\n");
    assert!(
        matches!(
            e,
            IoError::InvalidValue {
                line: 4,
                column: 6,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, _) = pos_err("2025/07/08 19:3418.499 40.0966268 -105.1474483 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0\n");
    assert!(
        matches!(
            e,
            IoError::InvalidValue {
                line: 4,
                column: 2,
                ..
            }
        ),
        "{e:?}"
    );
}

#[test]
fn pos_enu_baseline_files_are_rejected_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        &dir,
        "enu.pos",
        "%  GPST                  e-baseline(m)  n-baseline(m)  u-baseline(m)   Q  ns\n2374 1.0 1 2 3 1 5 0 0 0 0 0 0 0 0\n",
    );
    let e = read_rtklib_pos(&p, &PosOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("baseline") && e.to_string().contains("line 1"),
        "{e}"
    );
}

fn drive_pos(dir: &Path) -> PathBuf {
    dir.join("rtklibexplorer-drive0708/gnss_1934_sf.pos")
}

#[test]
fn pos_real_drive0708_has_2197_epochs_2189_fixed_at_4_hz() {
    let Some(d) = test_support::real_data("pos_real_drive0708_has_2197_epochs_2189_fixed_at_4_hz")
    else {
        return;
    };
    let r = read_rtklib_pos(drive_pos(&d), &PosOptions { max_q: 6 }).unwrap();
    assert_eq!(r.epochs, 2197);
    assert_eq!(r.fixes.len(), 2197);
    assert_eq!(r.count_by_q[1], 2189);
    assert_eq!(r.count_by_q[2], 8);
    assert_eq!(r.week, Some(2374));
    assert!(r.has_velocity);
    let first = r.fixes.first().unwrap();
    let last = r.fixes.last().unwrap();
    // 19:34:18.499 and 19:43:27.499 GPST on Tuesday 2025-07-08
    assert!((first.t_s - 243_258.499).abs() < 1e-6, "{}", first.t_s);
    assert!((last.t_s - 243_807.499).abs() < 1e-6, "{}", last.t_s);
    let dt: Vec<f64> = r.fixes.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    let median = {
        let mut s = dt.clone();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    };
    assert!((median - 0.25).abs() < 1e-6);
    assert!((first.lat_rad.to_degrees() - 40.0966268).abs() < 1e-9);
    assert!((first.h_m - 1601.474).abs() < 1e-9);
    assert_eq!(first.vel_ned_mps, [0.01, -0.002, -0.009]);
    assert!(r.fixes.iter().all(|f| f.is_valid()));
    let fixed = read_rtklib_pos(drive_pos(&d), &PosOptions { max_q: 1 }).unwrap();
    assert_eq!(fixed.fixes.len(), 2189);
    assert_eq!(fixed.dropped_by_quality, 8);
}

/// A UTF-8 byte-order mark before the header of a `.pos` file is skipped: the same fixes and
/// layout as without it.
#[test]
fn pos_with_a_utf8_byte_order_mark_reads_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let body = format!(
        "{HDR_LLH}2025/07/08 19:34:18.499  40.096626800 -105.147448300  1601.4740   1  21   0.0099   0.0098   0.0100   0.0010  -0.0020   0.0030   0.00    0.0   0.0100  -0.0020   0.0090   0.0587   0.0586   0.0585   0.0000   0.0000   0.0000\n"
    );
    let a = read_rtklib_pos(write(&dir, "a.pos", &body), &PosOptions::default()).unwrap();
    let b = read_rtklib_pos(
        write(&dir, "b.pos", &format!("\u{feff}{body}")),
        &PosOptions::default(),
    )
    .unwrap();
    assert_eq!(a.fixes.len(), 1);
    assert_eq!(a.fixes, b.fixes);
    assert_eq!(
        (b.time_system, b.position_format, b.has_velocity),
        (PosTimeSystem::Gpst, PosPositionFormat::LlhDeg, true)
    );
}
