//! The readers on the real recordings in ../shared/data: the rtklibexplorer drive (raw IMU CSV
//! with its RTKLIB time tag, the GPST CSV, the .pos solution) and an ADIS16405 static run.
//! When the data folder is missing these tests print SKIPPED (and fail when CI=true).

use nav_core::earth::gravity_mps2;
use nav_io::{
    read_imu_csv, read_imu_csv_raw, read_rtklib_pos, AccelUnit, Column, CsvTime, ImuCsvColumns,
    ImuCsvFormat, Mounting, PosOptions, RateUnit, RawImuSample, SampleConvention,
};
use std::path::PathBuf;

fn data_dir(test: &str) -> Option<PathBuf> {
    test_support::real_data(test)
}

fn gpst_csv_format() -> ImuCsvFormat {
    let n = |s: &str| Column::Name(s.to_string());
    ImuCsvFormat {
        skip_lines: 1,
        skip_last_rows: 0,
        names_line: Some(1),
        columns: ImuCsvColumns {
            time: Some(n("gpst_sow_s")),
            gyro: [n("gx_dps"), n("gy_dps"), n("gz_dps")],
            accel: [n("ax_g"), n("ay_g"), n("az_g")],
            temperature: None,
            week: None,
        },
        gyro_unit: RateUnit::DegPerS,
        accel_unit: AccelUnit::G,
        time: CsvTime::Seconds,
        time_offset_s: 0.0,
        convention: SampleConvention::Trapezoid,
    }
}

fn mean_f(s: &[RawImuSample]) -> [f64; 3] {
    let mut m = [0.0; 3];
    for x in s {
        for (mk, a) in m.iter_mut().zip(x.accel_mps2) {
            *mk += a / s.len() as f64;
        }
    }
    m
}

#[test]
fn drive0708_imu_with_time_tag_matches_the_gpst_csv_and_overlaps_the_pos_file() {
    let Some(d) =
        data_dir("drive0708_imu_with_time_tag_matches_the_gpst_csv_and_overlaps_the_pos_file")
    else {
        return;
    };
    let dir = d.join("rtklibexplorer-drive0708");
    let raw = read_imu_csv_raw(
        dir.join("imu_1934.csv"),
        &ImuCsvFormat::rtklib_demo5_icm("imu_1934.csv.tag"),
    )
    .unwrap();
    // 54,860 rows in the log, first and last dropped as the source's converter does
    assert_eq!(raw.samples.len(), 54_858);
    let tag = raw.tag.as_ref().unwrap();
    assert_eq!(tag.header, "TIMETAG RTKLIB demo5");
    assert_eq!(tag.start_week, 2374);
    assert!(
        (tag.start_sow_s - 243_261.854).abs() < 1e-6,
        "{}",
        tag.start_sow_s
    );
    assert_eq!(tag.pairs.len(), 37_632);
    assert_eq!(tag.trailing_bytes, 0);
    assert_eq!(tag.last_tick_ms(), 548_731);
    // README: stretch factor 1.00029
    assert!((raw.stretch - 548_731.0 / 548_571.0).abs() < 1e-12);
    assert!((raw.stretch - 1.00029).abs() < 5e-6, "{}", raw.stretch);
    // ~100 Hz, no gaps (intervals 8..11 ms, threshold 1.5 x median)
    let rate = raw.mean_rate_hz();
    assert!((rate - 100.0).abs() < 0.1, "{rate}");
    assert_eq!(raw.gaps.count(), 0, "{}", raw.gaps);
    assert!((raw.gaps.median_dt_s - 0.010).abs() < 1e-4);

    // Same samples and times as imu_1934_gpst.csv (printed with 4 decimals).
    let g = read_imu_csv_raw(dir.join("imu_1934_gpst.csv"), &gpst_csv_format()).unwrap();
    assert_eq!(g.samples.len(), raw.samples.len());
    let mut max_dt: f64 = 0.0;
    for (a, b) in raw.samples.iter().zip(&g.samples) {
        max_dt = max_dt.max((a.t_s - b.t_s).abs());
        assert_eq!(a.gyro_radps, b.gyro_radps);
        assert_eq!(a.accel_mps2, b.accel_mps2);
    }
    // 4 printed decimals (5e-5) plus the f64 resolution of "seconds since 1970" (2.4e-7 s)
    // used by the converter that wrote the GPST file
    assert!(max_dt <= 0.5e-4 + 1e-6, "max time difference {max_dt} s");

    // GNSS: 2,197 epochs, 2,189 fixed; the time spans overlap by > 540 s
    let pos = read_rtklib_pos(dir.join("gnss_1934_sf.pos"), &PosOptions { max_q: 6 }).unwrap();
    assert_eq!(pos.epochs, 2197);
    assert_eq!(pos.count_by_q[1], 2189);
    assert_eq!(pos.week, Some(tag.start_week));
    let (i0, i1) = (raw.samples[0].t_s, raw.samples.last().unwrap().t_s);
    let (g0, g1) = (pos.fixes[0].t_s, pos.fixes.last().unwrap().t_s);
    let overlap = i1.min(g1) - i0.max(g0);
    println!("IMU {i0:.3}..{i1:.3} s, GNSS {g0:.3}..{g1:.3} s, overlap {overlap:.3} s, rate {rate:.3} Hz");
    assert!(overlap > 540.0, "{overlap}");

    // Static start (first 15 s): specific force magnitude vs local normal gravity.
    let stat: Vec<RawImuSample> = raw
        .samples
        .iter()
        .copied()
        .filter(|s| s.t_s < i0 + 15.0)
        .collect();
    let f = mean_f(&stat);
    let fmag = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let p0 = &pos.fixes[0];
    let g_local = gravity_mps2(p0.lat_rad, p0.h_m);
    println!(
        "static |f| = {fmag:.4} m/s^2, local normal gravity {g_local:.4} m/s^2, f_imu = {f:?}"
    );
    // a consumer MEMS accelerometer: within 0.2 m/s^2 (20 mg) of gravity
    assert!((fmag - g_local).abs() < 0.2, "{fmag} vs {g_local}");
    assert!((fmag - 9.80).abs() < 0.2);
    // gyro at rest: below 0.5 deg/s on every axis (the IMU is unfiltered: noise ~ 1 deg/s)
    for k in 0..3 {
        let m: f64 = stat.iter().map(|s| s.gyro_radps[k]).sum::<f64>() / stat.len() as f64;
        assert!(
            m.to_degrees().abs() < 0.5,
            "gyro {k} mean {} deg/s",
            m.to_degrees()
        );
    }
    // After the source's mounting ([180,0,180] + [0,-6.79,5.35] as Euler angles), the
    // specific force at rest points up in body axes (-z) and the start is level in pitch.
    let mut body = stat.clone();
    Mounting::from_rpy_deg([180.0, -6.79, 185.35]).rotate_raw(&mut body);
    let fb = mean_f(&body);
    let pitch = (fb[0] / fmag).asin().to_degrees();
    let roll = (-fb[1]).atan2(-fb[2]).to_degrees();
    println!("body f = {fb:?}, pitch {pitch:.3} deg, roll {roll:.3} deg");
    assert!(fb[2] < -9.7);
    assert!(pitch.abs() < 0.1, "{pitch}");
    assert!(roll.abs() < 2.0, "{roll}");

    // Increments: n-1 of them, at ~100 Hz, summing to the trapezoid integral of f.
    let inc = read_imu_csv(
        dir.join("imu_1934.csv"),
        &ImuCsvFormat::rtklib_demo5_icm("imu_1934.csv.tag"),
    )
    .unwrap();
    assert_eq!(inc.samples.len(), raw.samples.len() - 1);
    assert!((inc.mean_rate_hz() - rate).abs() < 0.01);
}

#[test]
fn adis16405_static_run_reads_as_1e6_rows_at_100_hz_with_gravity_on_minus_z() {
    let Some(d) =
        data_dir("adis16405_static_run_reads_as_1e6_rows_at_100_hz_with_gravity_on_minus_z")
    else {
        return;
    };
    let p = d.join("adis16405/adis16405_static_1.csv.gz");
    let raw = read_imu_csv_raw(&p, &ImuCsvFormat::adis16405()).unwrap();
    assert_eq!(raw.samples.len(), 1_000_000);
    assert_eq!(raw.lines[0], 3);
    assert!((raw.samples.last().unwrap().t_s - 9999.99).abs() < 1e-6);
    assert_eq!(raw.gaps.count(), 0);
    // first row: -0.05,-0.3,0.7 deg/s ; -0.00666,0,-1.01565 g
    let s0 = &raw.samples[0];
    assert!((s0.gyro_radps[0] - (-0.05f64).to_radians()).abs() < 1e-15);
    assert!((s0.accel_mps2[2] - (-1.01565 * 9.80665)).abs() < 1e-12);
    let f = mean_f(&raw.samples);
    println!("ADIS16405 run 1 mean f = {f:?} m/s^2");
    // README: az about -1.016 g
    assert!((f[2] / 9.80665 + 1.016).abs() < 0.005, "{}", f[2] / 9.80665);
    let inc = raw.to_increments(SampleConvention::Trapezoid);
    assert_eq!(inc.samples.len(), 999_999);
    assert!((inc.samples[0].dv_mps[2] - 0.005 * (-1.01565 - 1.01898) * 9.80665).abs() < 1e-12);
}
