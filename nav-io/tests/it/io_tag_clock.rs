//! The tick clock against an RTKLIB time tag's arrival times ([`nav_io::tick_clock_fit`]): a
//! synthetic log with a known lag and rate, and the real drive (`../shared/data`, skipped with
//! a visible SKIPPED message when missing, an error with CI=true), whose tag shows that the
//! stretch of the tick span to the tag span is not a clock-rate correction (configs/drive0708.toml).
use nav_io::{read_time_tag, tick_clock_fit, TimeTag};

fn tag(pairs: Vec<(u32, u32)>) -> TimeTag {
    TimeTag {
        header: "TIMETAG RTKLIB demo5".into(),
        tick_at_open_ms: 0,
        start_week: 2374,
        start_sow_s: 0.0,
        pairs,
        trailing_bytes: 0,
    }
}

#[test]
fn a_known_lag_and_rate_are_recovered_from_the_lower_envelope() {
    // 100 Hz rows of 40 bytes, ticks from 5000 ms; the logger receives them in chunks every
    // 15-16 ms with 120 ms + 50 ppm of lag plus up to 9 ms of buffering
    let rows: Vec<(u64, f64)> = (0..60_000u64)
        .map(|k| (40 * (k + 1), 5000.0 + 10.0 * k as f64))
        .collect();
    let arrival = |k: usize| {
        let t = 10.0 * k as f64;
        120.0 + t * (1.0 + 50e-6) + [0.0, 3.0, 9.0, 1.0, 6.0][k % 5]
    };
    let mut pairs = Vec::new();
    let (mut ms, mut k) = (125u32, 0usize);
    while ms < 599_000 {
        // the rows that had arrived by `ms` (arrivals are increasing: 10 ms apart, jitter < 10)
        while k + 1 < rows.len() && arrival(k + 1) <= f64::from(ms) {
            k += 1;
        }
        pairs.push((ms, rows[k].0 as u32));
        ms += 15 + (pairs.len() % 2) as u32; // 15 and 16 ms apart, as in the real tag
    }
    let f = tick_clock_fit(&tag(pairs), &rows, 10_000.0).expect("fit");
    println!("{f:?}");
    assert!((f.rate_ppm - 50.0).abs() < 5.0, "{f:?}");
    // within the 1 ms of the tag's integer milliseconds
    assert!((f.lag_ms - 120.0).abs() < 1.0, "{f:?}");
    // at most: lag at the end + buffering + a row interval + a pair interval
    assert!(
        f.max_lag_ms <= 120.0 + 600.0 * 50e-3 + 9.0 + 10.0 + 16.0,
        "{f:?}"
    );
    assert!(f.rms_ms < 1.0, "{f:?}");
    assert!(f.windows >= 59);
    // too little data: no fit
    assert!(tick_clock_fit(&tag(vec![(130, 40)]), &rows, 10_000.0).is_none());
}

#[test]
fn drive0708_ticks_run_at_the_loggers_rate_so_the_tag_stretch_is_not_a_clock_correction() {
    let Some(d) = test_support::real_data_in(
        "drive0708_ticks_run_at_the_loggers_rate_so_the_tag_stretch_is_not_a_clock_correction",
        "rtklibexplorer-drive0708",
    ) else {
        return;
    };
    let tg = read_time_tag(d.join("imu_1934.csv.tag")).unwrap();
    let text = std::fs::read_to_string(d.join("imu_1934.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // the tag counts the bytes as logged: CR LF line ends (the stored file has LF only)
    let last_pos = u64::from(tg.pairs.last().unwrap().1);
    assert_eq!(last_pos, text.len() as u64 + lines.len() as u64);
    let mut pos = 0u64;
    let rows: Vec<(u64, f64)> = lines
        .iter()
        .map(|l| {
            pos += l.len() as u64 + 2;
            (pos, l.rsplit(',').next().unwrap().trim().parse().unwrap())
        })
        .collect();
    let f = tick_clock_fit(&tg, &rows, 10_000.0).expect("fit");
    // the stretch of configs/drive0708.toml before (the source's converter): tag span over
    // the used rows' tick span
    let used = &rows[1..rows.len() - 1];
    let stretch_ppm =
        (f64::from(tg.last_tick_ms()) / (used[used.len() - 1].1 - used[0].1) - 1.0) * 1e6;
    println!(
        "drive0708: lag {:.2} ms + {:.2} ppm x t (RMS {:.2} ms, max lag {:.0} ms, {} pairs, {} windows); stretch {stretch_ppm:.0} ppm",
        f.lag_ms, f.rate_ppm, f.rms_ms, f.max_lag_ms, f.pairs_used, f.windows
    );
    // measured: 130.28 ms + 12.6 ppm, 0.36 ms RMS; the stretch is +292 ppm
    assert!((f.lag_ms - 130.3).abs() < 1.0, "{f:?}");
    assert!(f.rate_ppm.abs() < 20.0, "{f:?}");
    assert!(f.rms_ms < 1.0, "{f:?}");
    assert!(f.max_lag_ms < 160.0, "{f:?}");
    assert!((stretch_ppm - 292.0).abs() < 1.0, "{stretch_ppm}");
    // the stretch's ramp over the drive is 0.16 s, the tick clock's own drift 7 ms
    let span_s = (rows[rows.len() - 1].1 - rows[0].1) * 1e-3;
    assert!(stretch_ppm * 1e-6 * span_s > 0.15);
    assert!(f.rate_ppm.abs() * 1e-6 * span_s < 0.011);
}
