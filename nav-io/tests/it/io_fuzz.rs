//! No input makes a reader panic: random bytes, random near-valid lines (numbers, NaN, inf,
//! text, dates, separators), gzip and truncated gzip of them are fed to every reader. Whatever
//! a reader accepts must satisfy its format's invariants (finite values, increasing time).

use nav_io::tag::parse_time_tag;
use nav_io::{
    parse_kf_gins_yaml, parse_run_config, read_gnss_text, read_imu_csv, read_imu_text,
    read_nav_text, read_rtklib_pos, AccelUnit, Column, CsvTime, ImuCsvColumns, ImuCsvFormat,
    PosOptions, RateUnit, SampleConvention,
};
use proptest::prelude::*;
use std::io::Write;
use std::path::Path;

fn csv_formats() -> Vec<ImuCsvFormat> {
    let secs = ImuCsvFormat {
        skip_lines: 0,
        skip_last_rows: 0,
        names_line: None,
        columns: ImuCsvColumns {
            time: Some(Column::Index(1)),
            gyro: [Column::Index(2), Column::Index(3), Column::Index(4)],
            accel: [Column::Index(5), Column::Index(6), Column::Index(7)],
            temperature: Some(Column::Index(8)),
            week: None,
        },
        gyro_unit: RateUnit::DegPerS,
        accel_unit: AccelUnit::G,
        time: CsvTime::Seconds,
        time_offset_s: 0.0,
        convention: SampleConvention::Trapezoid,
    };
    let mut named = secs.clone();
    named.skip_lines = 1;
    named.columns.time = Some(Column::Name("t".into()));
    named.columns.gyro[0] = Column::Name("gx".into());
    let mut ticks = secs.clone();
    ticks.time = CsvTime::TicksMs {
        tag_file: Some("missing.tag".into()),
        stretch_to_tag_end: true,
    };
    ticks.skip_last_rows = 3;
    let mut ticks_no_tag = secs.clone();
    ticks_no_tag.time = CsvTime::TicksMs {
        tag_file: None,
        stretch_to_tag_end: true,
    };
    ticks_no_tag.convention = SampleConvention::IntervalMean;
    vec![secs, named, ticks, ticks_no_tag, ImuCsvFormat::adis16405()]
}

fn check_all(p: &Path, bytes: &[u8]) {
    if let Ok(r) = read_imu_text(p) {
        assert!(r.samples.iter().all(|s| s.is_finite()));
        assert!(r.samples.windows(2).all(|w| w[1].t_s > w[0].t_s));
        assert!(r.gaps.total_missing_s >= 0.0);
    }
    if let Ok(r) = nav_io::read_imu_bin(p) {
        assert!(r.samples.iter().all(|s| s.is_finite()));
        assert!(r.samples.windows(2).all(|w| w[1].t_s > w[0].t_s));
    }
    if let Ok(g) = read_gnss_text(p) {
        assert!(g
            .iter()
            .all(|f| f.lat_rad.abs() <= std::f64::consts::FRAC_PI_2 + 1e-12 && f.h_m.is_finite()));
        assert!(g.windows(2).all(|w| w[1].t_s > w[0].t_s));
    }
    if let Ok(n) = read_nav_text(p) {
        assert!(n
            .iter()
            .all(|s| s.t_s.is_finite() && s.rpy_rad.iter().all(|a| a.is_finite())));
    }
    for q in [1, 6] {
        if let Ok(r) = read_rtklib_pos(p, &PosOptions { max_q: q }) {
            assert_eq!(r.epochs, r.fixes.len() + r.dropped_by_quality);
            assert!(r.fixes.windows(2).all(|w| w[1].t_s > w[0].t_s));
            assert!(r
                .fixes
                .iter()
                .all(|f| f.t_s.is_finite() && f.lat_rad.is_finite()));
        }
    }
    for f in csv_formats() {
        if let Ok(r) = read_imu_csv(p, &f) {
            assert!(r.samples.iter().all(|s| s.is_finite()), "{f:?}");
            assert!(r.samples.windows(2).all(|w| w[1].t_s > w[0].t_s));
        }
    }
    let _ = parse_time_tag(p, bytes);
    let text = String::from_utf8_lossy(bytes);
    let _ = parse_kf_gins_yaml(p, &text);
    let _ = parse_run_config(p, &text);
}

fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|v| format!("{v}")),
        (-1000i64..1_000_000).prop_map(|v| v.to_string()),
        (0.0f64..1.0).prop_map(|v| format!("{v:e}")),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("1e999".to_string()),
        Just("abc".to_string()),
        Just(String::new()),
        Just("2025/07/08".to_string()),
        Just("2025/02/30".to_string()),
        Just("19:34:18.499".to_string()),
        Just("99:99:99".to_string()),
        Just("1.0000000".to_string()),
        Just("-0".to_string()),
        Just("99999999999999999999999".to_string()),
        Just("%".to_string()),
        Just("#".to_string()),
        Just("é".to_string()),
    ]
}

fn line() -> impl Strategy<Value = String> {
    (
        proptest::collection::vec(token(), 0..26),
        prop_oneof![Just(" "), Just(","), Just("\t"), Just(" , ")],
    )
        .prop_map(|(t, sep)| t.join(sep))
}

fn lines() -> impl Strategy<Value = Vec<u8>> {
    (proptest::collection::vec(line(), 0..40), any::<bool>()).prop_map(|(l, crlf)| {
        let mut s = String::new();
        if !l.is_empty() {
            s.push_str("%  GPST   latitude(deg) longitude(deg) height(m) Q ns\n");
        }
        for x in l {
            s.push_str(&x);
            s.push_str(if crlf { "\r\n" } else { "\n" });
        }
        s.into_bytes()
    })
}

fn gz(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic_any_reader(bytes in proptest::collection::vec(any::<u8>(), 0..3000)) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("random.bin");
        std::fs::write(&p, &bytes).unwrap();
        check_all(&p, &bytes);
        // the same behind a gzip header, and a truncated gzip stream
        let z = gz(&bytes);
        std::fs::write(&p, &z).unwrap();
        check_all(&p, &z);
        std::fs::write(&p, &z[..z.len() / 2]).unwrap();
        check_all(&p, &z[..z.len() / 2]);
    }

    #[test]
    fn random_near_valid_lines_never_panic_any_reader(bytes in lines(), zip in any::<bool>()) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("lines.txt");
        let data = if zip { gz(&bytes) } else { bytes };
        std::fs::write(&p, &data).unwrap();
        check_all(&p, &data);
    }

    #[test]
    fn random_tag_files_never_panic(head in any::<bool>(), body in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut b = Vec::new();
        if head {
            b.extend_from_slice(b"TIMETAG RTKLIB demo5");
            b.resize(60, 0);
        }
        b.extend_from_slice(&body);
        if let Ok(t) = parse_time_tag(Path::new("x.tag"), &b) {
            prop_assert!(t.start_sow_s.is_finite() && (0.0..604_800.0).contains(&t.start_sow_s));
            prop_assert!(t.pairs.windows(2).all(|w| w[1].0 >= w[0].0));
        }
    }
}
