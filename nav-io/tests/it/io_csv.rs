//! Generic IMU CSV logs: unit mapping, sample conventions checked on analytic signals, column
//! names, fixed rate, RTKLIB time tags, malformed input; IMU mounting rotation.

use nav_io::{
    read_imu_csv, read_imu_csv_raw, read_time_tag, AccelUnit, Column, CsvTime, ImuCsvColumns,
    ImuCsvFormat, IoError, Mounting, RateUnit, SampleConvention,
};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const G0: f64 = 9.80665;

fn fmt_seconds(units: (RateUnit, AccelUnit), conv: SampleConvention) -> ImuCsvFormat {
    ImuCsvFormat {
        skip_lines: 0,
        skip_last_rows: 0,
        names_line: None,
        columns: ImuCsvColumns {
            time: Some(Column::Index(1)),
            gyro: [Column::Index(2), Column::Index(3), Column::Index(4)],
            accel: [Column::Index(5), Column::Index(6), Column::Index(7)],
            temperature: None,
            week: None,
        },
        gyro_unit: units.0,
        accel_unit: units.1,
        time: CsvTime::Seconds,
        time_offset_s: 0.0,
        convention: conv,
    }
}

fn write(dir: &Path, name: &str, s: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, s).unwrap();
    p
}

/// Jittered time stamps 8..11 ms apart (like the real drive), deterministic.
fn jittered_times(n: usize, t0: f64) -> Vec<f64> {
    let mut t = vec![t0];
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    for _ in 1..n {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let ms = 8 + (state >> 33) % 4; // 8, 9, 10, 11 ms
        let last = *t.last().unwrap();
        t.push(last + ms as f64 * 1e-3);
    }
    t
}

// Analytic signal per axis: y(t) = a sin(w t + p) + b. Integral F(t) = -a/w cos(w t + p) + b t.
struct Sig {
    a: f64,
    w: f64,
    p: f64,
    b: f64,
}
impl Sig {
    fn y(&self, t: f64) -> f64 {
        self.a * (self.w * t + self.p).sin() + self.b
    }
    fn integral(&self, t0: f64, t1: f64) -> f64 {
        let f = |t: f64| -self.a / self.w * (self.w * t + self.p).cos() + self.b * t;
        f(t1) - f(t0)
    }
    /// max |y''| = a w^2
    fn max_ydd(&self) -> f64 {
        self.a * self.w * self.w
    }
}

fn signals() -> (Vec<Sig>, Vec<Sig>) {
    // gyro in deg/s, accel in g: the file units; checked after conversion to SI.
    let gyro = vec![
        Sig {
            a: 30.0,
            w: 2.0 * PI * 1.3,
            p: 0.2,
            b: 0.5,
        },
        Sig {
            a: 12.0,
            w: 2.0 * PI * 0.7,
            p: 1.0,
            b: -0.1,
        },
        Sig {
            a: 45.0,
            w: 2.0 * PI * 2.1,
            p: -0.4,
            b: 0.0,
        },
    ];
    let accel = vec![
        Sig {
            a: 0.3,
            w: 2.0 * PI * 0.9,
            p: 0.0,
            b: 0.02,
        },
        Sig {
            a: 0.1,
            w: 2.0 * PI * 1.7,
            p: 0.5,
            b: 0.0,
        },
        Sig {
            a: 0.05,
            w: 2.0 * PI * 3.0,
            p: 2.0,
            b: -1.0,
        },
    ];
    (gyro, accel)
}

#[test]
fn trapezoid_convention_integrates_point_samples_to_second_order_on_an_analytic_signal() {
    let dir = tempfile::tempdir().unwrap();
    let (gyro, accel) = signals();
    let t = jittered_times(3000, 1000.0);
    let mut s = String::new();
    for &tk in &t {
        write!(s, "{tk}").unwrap();
        for g in &gyro {
            write!(s, ",{:e}", g.y(tk)).unwrap();
        }
        for a in &accel {
            write!(s, ",{:e}", a.y(tk)).unwrap();
        }
        s.push('\n');
    }
    let p = write(dir.path(), "point.csv", &s);
    let fmt = fmt_seconds(
        (RateUnit::DegPerS, AccelUnit::G),
        SampleConvention::Trapezoid,
    );
    let rec = read_imu_csv(&p, &fmt).unwrap();
    assert_eq!(rec.samples.len(), t.len() - 1, "n rows give n-1 increments");
    assert_eq!(rec.gaps.count(), 0);
    let mut worst_ratio: f64 = 0.0;
    for (k, inc) in rec.samples.iter().enumerate() {
        let (t0, t1) = (t[k], t[k + 1]);
        assert_eq!(inc.t_s, t1, "stamped at the end of the interval");
        let dt = t1 - t0;
        for ax in 0..3 {
            let exact_g = gyro[ax].integral(t0, t1) * PI / 180.0;
            let bound_g = dt.powi(3) / 12.0 * gyro[ax].max_ydd() * PI / 180.0 + 1e-15;
            let err_g = (inc.dtheta_rad[ax] - exact_g).abs();
            assert!(
                err_g <= bound_g * 1.0001,
                "gyro {ax} step {k}: {err_g} > {bound_g}"
            );
            worst_ratio = worst_ratio.max(err_g / bound_g);
            let exact_a = accel[ax].integral(t0, t1) * G0;
            let bound_a = dt.powi(3) / 12.0 * accel[ax].max_ydd() * G0 + 1e-15;
            let err_a = (inc.dv_mps[ax] - exact_a).abs();
            assert!(
                err_a <= bound_a * 1.0001,
                "accel {ax} step {k}: {err_a} > {bound_a}"
            );
        }
    }
    // the bound is attained up to the curvature variation, i.e. the error really is O(dt^3)
    assert!(worst_ratio > 0.5, "worst error/bound = {worst_ratio}");
    // Total angle over the record: within the sum of the per-step bounds.
    let total: f64 = rec.samples.iter().map(|s| s.dtheta_rad[2]).sum();
    let exact = gyro[2].integral(t[0], *t.last().unwrap()) * PI / 180.0;
    let bound: f64 = t
        .windows(2)
        .map(|w| (w[1] - w[0]).powi(3) / 12.0 * gyro[2].max_ydd() * PI / 180.0)
        .sum();
    assert!(
        (total - exact).abs() <= bound,
        "{total} vs {exact} (bound {bound})"
    );
}

#[test]
fn trapezoid_error_falls_eightfold_when_the_interval_halves() {
    let sig = Sig {
        a: 1.0,
        w: 2.0 * PI * 2.0,
        p: 0.3,
        b: 0.0,
    };
    let mut errs = Vec::new();
    for dt in [0.01, 0.005] {
        let dir = tempfile::tempdir().unwrap();
        let mut s = String::new();
        let n = (1.0 / dt) as usize + 1;
        for k in 0..n {
            let t = k as f64 * dt;
            writeln!(s, "{t:e} {:e} 0 0 0 0 0", sig.y(t)).unwrap();
        }
        let p = write(dir.path(), "u.txt", &s);
        let fmt = fmt_seconds(
            (RateUnit::RadPerS, AccelUnit::Mps2),
            SampleConvention::Trapezoid,
        );
        let rec = read_imu_csv(&p, &fmt).unwrap();
        let max_err = rec
            .samples
            .iter()
            .enumerate()
            .map(|(k, inc)| {
                (inc.dtheta_rad[0] - sig.integral(k as f64 * dt, (k + 1) as f64 * dt)).abs()
            })
            .fold(0.0, f64::max);
        errs.push(max_err);
    }
    let ratio = errs[0] / errs[1];
    assert!(
        (ratio - 8.0).abs() < 0.2,
        "error ratio {ratio} (errors {errs:?})"
    );
}

#[test]
fn interval_mean_convention_is_exact_for_interval_mean_data() {
    let dir = tempfile::tempdir().unwrap();
    let (gyro, accel) = signals();
    let t = jittered_times(500, 5.0);
    let mut s = String::new();
    // row 0 has no preceding interval: any value
    for (k, &tk) in t.iter().enumerate() {
        write!(s, "{tk}").unwrap();
        for sig in gyro.iter().chain(&accel) {
            let v = if k == 0 {
                0.0
            } else {
                sig.integral(t[k - 1], tk) / (tk - t[k - 1])
            };
            write!(s, " {v:e}").unwrap();
        }
        s.push('\n');
    }
    let p = write(dir.path(), "mean.txt", &s);
    let fmt = fmt_seconds(
        (RateUnit::DegPerS, AccelUnit::G),
        SampleConvention::IntervalMean,
    );
    let rec = read_imu_csv(&p, &fmt).unwrap();
    for (k, inc) in rec.samples.iter().enumerate() {
        for ax in 0..3 {
            let e = gyro[ax].integral(t[k], t[k + 1]) * PI / 180.0;
            assert!(
                (inc.dtheta_rad[ax] - e).abs() < 1e-14 + 1e-12 * e.abs(),
                "{k} {ax}"
            );
            let e = accel[ax].integral(t[k], t[k + 1]) * G0;
            assert!(
                (inc.dv_mps[ax] - e).abs() < 1e-14 + 1e-12 * e.abs(),
                "{k} {ax}"
            );
        }
    }
    // the trapezoid rule on the same rows is NOT exact (this is a real choice)
    let fmt_t = fmt_seconds(
        (RateUnit::DegPerS, AccelUnit::G),
        SampleConvention::Trapezoid,
    );
    let rt = read_imu_csv(&p, &fmt_t).unwrap();
    let diff = (rt.samples[100].dtheta_rad[2] - rec.samples[100].dtheta_rad[2]).abs();
    assert!(diff > 1e-6, "{diff}");
}

#[test]
fn raw_accessor_returns_si_rates_and_specific_forces_with_unit_conversion() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "r.csv",
        "1.00,90,-180,0,1,0,-1\n1.01,0,0,57.29577951308232,0,2,0\n",
    );
    let raw = read_imu_csv_raw(
        &p,
        &fmt_seconds(
            (RateUnit::DegPerS, AccelUnit::G),
            SampleConvention::Trapezoid,
        ),
    )
    .unwrap();
    assert_eq!(raw.samples.len(), 2);
    let s = &raw.samples[0];
    assert!((s.gyro_radps[0] - PI / 2.0).abs() < 1e-15);
    assert!((s.gyro_radps[1] + PI).abs() < 1e-15);
    assert_eq!(s.accel_mps2, [G0, 0.0, -G0]);
    assert!((raw.samples[1].gyro_radps[2] - 1.0).abs() < 1e-15);
    assert_eq!(raw.samples[1].accel_mps2[1], 2.0 * G0);
    let raw2 = read_imu_csv_raw(
        &p,
        &fmt_seconds(
            (RateUnit::RadPerS, AccelUnit::Mps2),
            SampleConvention::Trapezoid,
        ),
    )
    .unwrap();
    assert_eq!(raw2.samples[0].gyro_radps[0], 90.0);
    assert_eq!(raw2.samples[0].accel_mps2[2], -1.0);
}

#[test]
fn columns_by_name_fixed_rate_offset_and_temperature() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "named.csv",
        "# a comment line\n# az_g, temp_C , gx_dps,gy_dps,gz_dps, ax_g, ay_g  (units in names)\n-1.0,25.5,0.1,0.2,0.3,0.0,0.0\n-1.0,nan,0.1,0.2,0.3,0.0,0.0\n-1.0,26.0,0.1,0.2,0.3,0.0,0.0\n",
    );
    let fmt = ImuCsvFormat {
        skip_lines: 2,
        skip_last_rows: 0,
        names_line: None,
        columns: ImuCsvColumns {
            time: None,
            gyro: [
                Column::Name("gx_dps".into()),
                Column::Name("GY_DPS".into()),
                Column::Name("gz_dps".into()),
            ],
            accel: [
                Column::Name("ax_g".into()),
                Column::Name("ay_g".into()),
                Column::Name("az_g".into()),
            ],
            temperature: Some(Column::Name("temp_C".into())),
            week: None,
        },
        gyro_unit: RateUnit::DegPerS,
        accel_unit: AccelUnit::G,
        time: CsvTime::FixedRate {
            rate_hz: 50.0,
            start_s: 100.0,
        },
        time_offset_s: -0.125,
        convention: SampleConvention::Trapezoid,
    };
    let raw = read_imu_csv_raw(&p, &fmt).unwrap();
    assert_eq!(raw.samples.len(), 3);
    assert_eq!(raw.lines, vec![3, 4, 5]);
    let t: Vec<f64> = raw.samples.iter().map(|s| s.t_s).collect();
    assert!(
        (t[0] - 99.875).abs() < 1e-12 && (t[2] - 99.915).abs() < 1e-12,
        "{t:?}"
    );
    assert_eq!(raw.samples[0].accel_mps2, [0.0, 0.0, -G0]);
    assert!((raw.samples[0].gyro_radps[1] - 0.2f64.to_radians()).abs() < 1e-16);
    assert_eq!(raw.samples[0].temperature_c, 25.5);
    assert!(raw.samples[1].temperature_c.is_nan());
    let inc = raw.to_increments(SampleConvention::Trapezoid);
    assert_eq!(inc.samples.len(), 2);
    assert!(inc.samples[0].temperature_c.is_nan());
    assert_eq!(inc.samples[1].temperature_c, 26.0);
    // unknown name: a configuration error listing the names
    let mut bad = fmt.clone();
    bad.columns.gyro[0] = Column::Name("wx".into());
    let e = read_imu_csv_raw(&p, &bad).unwrap_err();
    assert!(matches!(e, IoError::Config { .. }));
    assert!(
        e.to_string().contains("wx") && e.to_string().contains("gx_dps"),
        "{e}"
    );
    let mut bad = fmt.clone();
    bad.columns.gyro[0] = Column::Index(0);
    assert!(read_imu_csv_raw(&p, &bad)
        .unwrap_err()
        .to_string()
        .contains("1-based"));
}

fn err_msg(dir: &Path, content: &str, fmt: &ImuCsvFormat) -> (IoError, String) {
    let p = write(dir, "broken_log.csv", content);
    let e = read_imu_csv_raw(&p, fmt).unwrap_err();
    let m = e.to_string();
    assert!(m.contains("broken_log.csv"), "{m}");
    (e, m)
}

#[test]
fn malformed_csv_rows_give_errors_naming_file_line_column_and_meaning() {
    let dir = tempfile::tempdir().unwrap();
    let fmt = fmt_seconds(
        (RateUnit::DegPerS, AccelUnit::G),
        SampleConvention::Trapezoid,
    );
    let (e, m) = err_msg(dir.path(), "1,0,0,0,0,0,1\n2,0,0,0,0,0\n", &fmt);
    assert!(
        matches!(
            e,
            IoError::TooFewFields {
                line: 2,
                column: 7,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(m.contains("accel_z [g]"), "{m}");
    let (e, m) = err_msg(dir.path(), "1,0,0,0,0,0,1\n2,0,x0,0,0,0,1\n", &fmt);
    assert!(
        matches!(
            e,
            IoError::NotANumber {
                line: 2,
                column: 3,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(m.contains("gyro_y [deg/s]") && m.contains("x0"), "{m}");
    let (e, _) = err_msg(dir.path(), "1,0,0,0,0,0,1\n2,0,0,0,NaN,0,1\n", &fmt);
    assert!(
        matches!(
            e,
            IoError::NonFinite {
                line: 2,
                column: 5,
                ..
            }
        ),
        "{e:?}"
    );
    let (e, m) = err_msg(
        dir.path(),
        "1,0,0,0,0,0,1\n2,0,0,0,0,0,1\n1.5,0,0,0,0,0,1\n",
        &fmt,
    );
    assert!(
        matches!(
            e,
            IoError::NonMonotonicTime {
                line: 3,
                column: 1,
                prev_line: 2,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(m.contains("time [s]"), "{m}");
}

#[test]
fn csv_time_gaps_are_counted_and_the_increment_spans_the_gap() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = String::new();
    let mut t = Vec::new();
    for k in 0..200 {
        if (100..120).contains(&k) {
            continue;
        }
        t.push(k as f64 * 0.01);
        writeln!(s, "{},1,0,0,0,0,-1", k as f64 * 0.01).unwrap();
    }
    let p = write(dir.path(), "gap.csv", &s);
    let fmt = fmt_seconds(
        (RateUnit::RadPerS, AccelUnit::G),
        SampleConvention::Trapezoid,
    );
    let raw = read_imu_csv_raw(&p, &fmt).unwrap();
    assert_eq!(raw.gaps.count(), 1);
    assert_eq!(raw.gaps.gaps[0].line, 101);
    assert!((raw.gaps.total_missing_s - 0.20).abs() < 1e-9);
    let inc = raw.to_increments(SampleConvention::Trapezoid);
    assert_eq!(inc.samples.len(), 179, "nothing invented");
    assert_eq!(inc.gaps.count(), 1);
    let g = &inc.gaps.gaps[0];
    // the increment ending after the gap covers 0.21 s of a constant 1 rad/s
    assert!((inc.samples[g.index].dtheta_rad[0] - 0.21).abs() < 1e-12);
    assert!((inc.samples[g.index].t_s - 1.2).abs() < 1e-12);
}

/// A demo5 tag file: 60-byte header, tick at open, uint32 seconds, f64 fraction, pairs.
fn tag_bytes(start_s: u32, frac: f64, pairs: &[(u32, u32)]) -> Vec<u8> {
    let mut b = vec![0u8; 60];
    b[..20].copy_from_slice(b"TIMETAG RTKLIB demo5");
    b.extend_from_slice(&123456u32.to_le_bytes());
    b.extend_from_slice(&start_s.to_le_bytes());
    b.extend_from_slice(&frac.to_le_bytes());
    for (t, p) in pairs {
        b.extend_from_slice(&t.to_le_bytes());
        b.extend_from_slice(&p.to_le_bytes());
    }
    b
}

#[test]
fn ticks_with_a_time_tag_are_placed_in_gps_time_and_stretched_to_the_tag_end() {
    let dir = tempfile::tempdir().unwrap();
    // 2025-07-08 19:34:21.500 GPST = 1752003261.5 s "since 1970" in GPST = sow 243261.5
    std::fs::write(
        dir.path().join("log.csv.tag"),
        tag_bytes(1_752_003_261, 0.5, &[(15, 40), (1005, 900), (2002, 1800)]),
    )
    .unwrap();
    let mut s = String::new();
    for k in 0..=200 {
        // ticks 10 ms apart from 5000 ms; the sensor clock runs 0.1 % fast vs the tag span
        writeln!(s, "0,0,1,0,0,0,{}", 5000 + 10 * k).unwrap();
    }
    let p = write(dir.path(), "log.csv", &s);
    let mut fmt = ImuCsvFormat::rtklib_demo5_icm("log.csv.tag");
    fmt.skip_lines = 0;
    fmt.skip_last_rows = 0;
    let raw = read_imu_csv_raw(&p, &fmt).unwrap();
    let tag = raw.tag.as_ref().unwrap();
    assert_eq!(tag.start_week, 2374);
    assert!((tag.start_sow_s - 243_261.5).abs() < 1e-6);
    assert_eq!(tag.last_tick_ms(), 2002);
    assert!((raw.stretch - 2002.0 / 2000.0).abs() < 1e-12);
    assert!((raw.samples[0].t_s - 243_261.5).abs() < 1e-6);
    assert!((raw.samples[200].t_s - (243_261.5 + 2.002)).abs() < 1e-6);
    assert!((raw.samples[100].t_s - (243_261.5 + 1.001)).abs() < 1e-6);
    // column mapping of this layout: accel first (g), gyro after (deg/s)
    assert_eq!(raw.samples[0].accel_mps2, [0.0, 0.0, G0]);
    // without the stretch: plain tick differences
    fmt.time = CsvTime::TicksMs {
        tag_file: Some("log.csv.tag".into()),
        stretch_to_tag_end: false,
    };
    let raw = read_imu_csv_raw(&p, &fmt).unwrap();
    assert!((raw.samples[200].t_s - (243_261.5 + 2.0)).abs() < 1e-6);
    // without a tag: ticks in seconds
    fmt.time = CsvTime::TicksMs {
        tag_file: None,
        stretch_to_tag_end: true,
    };
    let raw = read_imu_csv_raw(&p, &fmt).unwrap();
    assert!((raw.samples[1].t_s - 5.01).abs() < 1e-12);
}

#[test]
fn a_tag_file_that_does_not_match_the_log_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("t.tag"),
        tag_bytes(1_752_003_261, 0.5, &[(10, 1), (3000, 2)]),
    )
    .unwrap();
    let mut s = String::new();
    for k in 0..=200 {
        writeln!(s, "0,0,1,0,0,0,{}", 10 * k).unwrap();
    }
    let p = write(dir.path(), "log.csv", &s);
    let mut fmt = ImuCsvFormat::rtklib_demo5_icm("t.tag");
    fmt.skip_lines = 0;
    fmt.skip_last_rows = 0;
    let e = read_imu_csv_raw(&p, &fmt).unwrap_err();
    assert!(e.to_string().contains("wrong tag file"), "{e}");
    // not a tag file at all
    std::fs::write(dir.path().join("t.tag"), [b'x'; 200]).unwrap();
    let e = read_imu_csv_raw(&p, &fmt).unwrap_err();
    assert!(e.to_string().contains("TIMETAG"), "{e}");
    // too short
    std::fs::write(dir.path().join("t.tag"), b"TIMETAG RTKLIB demo5").unwrap();
    let e = read_time_tag(dir.path().join("t.tag")).unwrap_err();
    assert!(e.to_string().contains("too short"), "{e}");
    // pairs going backwards
    std::fs::write(
        dir.path().join("t.tag"),
        tag_bytes(1_752_003_261, 0.5, &[(10, 1), (5, 2)]),
    )
    .unwrap();
    let e = read_time_tag(dir.path().join("t.tag")).unwrap_err();
    assert!(e.to_string().contains("backwards"), "{e}");
}

fn close3(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() < tol)
}

#[test]
fn mounting_rotation_maps_axes_as_expected() {
    // identity
    assert_eq!(
        Mounting::identity().to_body([1.0, 2.0, 3.0]),
        [1.0, 2.0, 3.0]
    );
    // yaw +90: the body is yawed 90 deg from the IMU: body x = IMU y, body y = -IMU x
    let m = Mounting::from_rpy_deg([0.0, 0.0, 90.0]);
    assert!(close3(m.to_body([1.0, 0.0, 0.0]), [0.0, -1.0, 0.0], 1e-15));
    assert!(close3(m.to_body([0.0, 1.0, 0.0]), [1.0, 0.0, 0.0], 1e-15));
    // roll 180 then yaw 180 (the drive's orientation): x -> -x, y -> y, z -> -z
    let m = Mounting::from_rpy_deg([180.0, 0.0, 180.0]);
    assert!(close3(m.to_body([1.0, 2.0, 3.0]), [-1.0, 2.0, -3.0], 1e-14));
    // pitch +10 deg: an IMU x reading tilted up shows in body as x and z
    let m = Mounting::from_rpy_deg([0.0, 10.0, 0.0]);
    let v = m.to_body([1.0, 0.0, 0.0]);
    let (s, c) = 10f64.to_radians().sin_cos();
    assert!(close3(v, [c, 0.0, s], 1e-15), "{v:?}");
    // increments are rotated like vectors
    let mut inc = vec![nav_core::types::ImuSample {
        t_s: 1.0,
        dtheta_rad: [0.1, 0.0, 0.0],
        dv_mps: [0.0, 0.0, 9.8],
        temperature_c: f64::NAN,
    }];
    Mounting::from_rpy_deg([180.0, 0.0, 180.0]).rotate_increments(&mut inc);
    assert!(close3(inc[0].dtheta_rad, [-0.1, 0.0, 0.0], 1e-15));
    assert!(close3(inc[0].dv_mps, [0.0, 0.0, -9.8], 1e-14));
}

#[test]
fn drive_readme_mounting_is_euler_addition_equal_to_composing_the_flipped_correction() {
    // GNSS_IMU adds [180,0,180] + [0,-6.79,5.35] as Euler angles.
    let sum = Mounting::from_rpy_deg([180.0, -6.79, 185.35]).c_b_imu();
    let composed = Mounting {
        rpy_deg: [180.0, 0.0, 180.0],
        then_rpy_deg: vec![[0.0, 6.79, -5.35]],
    }
    .c_b_imu();
    assert!((sum - composed).abs().max() < 1e-12, "{sum} vs {composed}");
    // composing the README numbers literally is a different rotation (13.6 deg apart)
    let literal = Mounting {
        rpy_deg: [180.0, 0.0, 180.0],
        then_rpy_deg: vec![[0.0, -6.79, 5.35]],
    }
    .c_b_imu();
    let d = sum.transpose() * literal;
    let angle = ((d.trace() - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    assert!(angle > 10.0, "{angle}");
}

/// Date-time text in the time column (`kind = "text"`, the GNSS CSV's name and keys): the same
/// time stamps as the GPS seconds of week they spell, in GPS time and in UTC (18 leap seconds
/// in 2025), across midnight; a field that does not match the format names file, line,
/// column and the format.
#[test]
fn date_time_text_times_are_the_gps_seconds_they_spell() {
    let dir = tempfile::tempdir().unwrap();
    // 2025-07-08 is a Tuesday: GPS week 2374 began on Sunday 2025-07-06 00:00 GPS time
    let sow0 = 2.0 * 86_400.0 + 86_399.99;
    let mut text = String::new();
    let mut sow = String::new();
    for k in 0..4 {
        let t = sow0 + 0.005 * k as f64;
        let (day, s_of_day) = if t >= 3.0 * 86_400.0 {
            (9, t - 3.0 * 86_400.0)
        } else {
            (8, t - 2.0 * 86_400.0)
        };
        let (h, m, s) = (
            (s_of_day / 3600.0).floor(),
            ((s_of_day % 3600.0) / 60.0).floor(),
            s_of_day % 60.0,
        );
        let row = format!(",0.1,0.2,0.3,0,0,-1.0,{k}\n");
        let _ = write!(text, "2025-07-{day:02}T{h:02}:{m:02}:{s:06.3}{row}");
        let _ = write!(sow, "{t:.3}{row}");
    }
    let units = (RateUnit::DegPerS, AccelUnit::G);
    let mut f_text = fmt_seconds(units, SampleConvention::Trapezoid);
    f_text.time = CsvTime::Text {
        format: "%Y-%m-%dT%H:%M:%S%.f".into(),
        scale: nav_io::TimeScale::Gps,
    };
    let f_sow = fmt_seconds(units, SampleConvention::Trapezoid);
    let p_text = write(dir.path(), "text.csv", &text);
    let p_sow = write(dir.path(), "sow.csv", &sow);
    let a = read_imu_csv_raw(&p_text, &f_text).unwrap();
    let b = read_imu_csv_raw(&p_sow, &f_sow).unwrap();
    assert_eq!(a.samples.len(), 4);
    for (x, y) in a.samples.iter().zip(&b.samples) {
        assert!((x.t_s - y.t_s).abs() < 1e-9, "{} vs {}", x.t_s, y.t_s);
        assert_eq!(x.gyro_radps, y.gyro_radps);
    }
    // past midnight the seconds continue in the first row's week
    assert!(a.samples[3].t_s > 3.0 * 86_400.0);
    // UTC text: 18 s later in GPS time
    f_text.time = CsvTime::Text {
        format: "%Y-%m-%dT%H:%M:%S%.f".into(),
        scale: nav_io::TimeScale::Utc,
    };
    let u = read_imu_csv_raw(&p_text, &f_text).unwrap();
    assert!((u.samples[0].t_s - a.samples[0].t_s - 18.0).abs() < 1e-9);
    // a field that does not match
    let bad = write(
        dir.path(),
        "bad.csv",
        &text.replacen("2025-07-08T23:59:59.995", "2025-07-08 23:59:59.995", 1),
    );
    let e = read_imu_csv_raw(&bad, &f_text).unwrap_err().to_string();
    assert!(
        e.contains("bad.csv") && e.contains("line 2") && e.contains("%Y-%m-%dT%H:%M:%S%.f"),
        "{e}"
    );
}

#[test]
fn week_and_seconds_columns_continue_across_the_week_rollover() {
    let dir = tempfile::tempdir().unwrap();
    // four rows 5 ms apart across the end of GPS week 2374
    let mut text = String::new();
    for k in 0..4 {
        let t = 604_799.99 + 0.005 * k as f64;
        let (w, sow) = if t >= 604_800.0 {
            (2375, t - 604_800.0)
        } else {
            (2374, t)
        };
        let _ = writeln!(text, "{w},{sow:.3},0.1,0.2,0.3,0,0,-1.0");
    }
    let units = (RateUnit::DegPerS, AccelUnit::G);
    let mut f = fmt_seconds(units, SampleConvention::Trapezoid);
    f.columns.week = Some(Column::Index(1));
    f.columns.time = Some(Column::Index(2));
    f.columns.gyro = [Column::Index(3), Column::Index(4), Column::Index(5)];
    f.columns.accel = [Column::Index(6), Column::Index(7), Column::Index(8)];
    f.time = CsvTime::WeekSow;
    let p = write(dir.path(), "week.csv", &text);
    let raw = read_imu_csv_raw(&p, &f).unwrap();
    let t: Vec<f64> = raw.samples.iter().map(|s| s.t_s).collect();
    for (k, got) in t.iter().enumerate() {
        let want = 604_799.99 + 0.005 * k as f64;
        assert!((got - want).abs() < 1e-9, "row {k}: {got} vs {want}");
    }
    // the same mapping read from TOML, with the key names the GNSS CSV uses
    let from_toml: ImuCsvFormat = toml::from_str(
        r#"gyro_unit = "deg/s"
accel_unit = "g"
[columns]
week = 1
time = 2
gyro = [3, 4, 5]
accel = [6, 7, 8]
[time]
kind = "week_sow"
"#,
    )
    .unwrap();
    assert_eq!(from_toml, f);
    // a week that is not an integer is named with its file, line and column
    let bad = write(
        dir.path(),
        "bad.csv",
        &text.replacen("2374,604799.995", "2374.5,604799.995", 1),
    );
    let e = read_imu_csv_raw(&bad, &f).unwrap_err().to_string();
    assert!(
        e.contains("bad.csv") && e.contains("line 2") && e.contains("week"),
        "{e}"
    );
    // the kind and the week column go together
    f.columns.week = None;
    let e = read_imu_csv_raw(&p, &f).unwrap_err().to_string();
    assert!(e.contains("week_sow") && e.contains("columns.week"), "{e}");
}

#[test]
fn increment_rows_are_taken_as_they_are_in_their_units() {
    let dir = tempfile::tempdir().unwrap();
    // rows of angle increments in deg and velocity increments in g s over 10 ms
    let mut text = String::new();
    for k in 0..5 {
        let t = 100.0 + 0.01 * k as f64;
        let _ = writeln!(
            text,
            "{t:.2},{},0.002,-0.003,0.0001,0.0,-0.01",
            0.001 * k as f64
        );
    }
    let mut f = fmt_seconds(
        (RateUnit::DegPerS, AccelUnit::G),
        SampleConvention::Increments,
    );
    let p = write(dir.path(), "inc.csv", &text);
    let rec = read_imu_csv(&p, &f).unwrap();
    // n rows give n - 1 increments, each the row's own values in rad and m/s
    assert_eq!(rec.samples.len(), 4);
    for (k, s) in rec.samples.iter().enumerate() {
        let row = (k + 1) as f64;
        assert!((s.t_s - (100.0 + 0.01 * row)).abs() < 1e-12);
        assert_eq!(s.dtheta_rad[0], (0.001 * row) * PI / 180.0);
        assert_eq!(s.dtheta_rad[1], 0.002 * PI / 180.0);
        assert_eq!(s.dv_mps[2], -0.01 * G0);
    }
    // the interval does not scale an increment (it does a rate)
    f.convention = SampleConvention::IntervalMean;
    let as_rates = read_imu_csv(&p, &f).unwrap();
    assert!((as_rates.samples[0].dv_mps[2] - rec.samples[0].dv_mps[2] * 0.01).abs() < 1e-12);
    let conv: SampleConvention = toml::from_str::<toml::Value>("c = \"increments\"")
        .unwrap()
        .get("c")
        .unwrap()
        .clone()
        .try_into()
        .unwrap();
    assert_eq!(conv, SampleConvention::Increments);
}
