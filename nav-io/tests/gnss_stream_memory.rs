//! A run configuration's GNSS file is read one fix at a time in constant memory, whatever its
//! format: a file of 10,000 and one of 100,000 fixes (10 Hz, 17 min and 2.8 h; written by the
//! test in every format `[gnss] format` accepts, UBX also gzip-compressed) are read through
//! `RunConfig::open_gnss` while a counting global allocator tracks the live heap. The peak
//! must not grow with the length (at most 4 KiB more for ten times the fixes) and must stay
//! below 1 MiB, where the fixes alone would take 100,000 x `size_of::<GnssFix>()` (12 MB).
//! Every fix is checked (count, time order and spacing, time offset applied) and the summary
//! (week, drops) is the expected one. The whole-file readers are measured too, for the report.
//!
//! A test binary of its own: the allocator's counters are process-wide (another test running
//! at the same time would count too), and the one test runs the formats one after the other.

mod gnss_gen;

use gnss_gen::{Fmt, DT, T0, WEEK};
use nav_core::types::GnssFix;
use std::time::Instant;
use test_support::alloc;

#[global_allocator]
static A: alloc::Counting = alloc::Counting;

/// Peak heap above the base while `f` runs, bytes, and its wall time, s.
fn measure<T>(f: impl FnOnce() -> T) -> (T, usize, f64) {
    let base = alloc::reset_peak();
    let t0 = Instant::now();
    let out = f();
    let dt = t0.elapsed().as_secs_f64();
    (out, alloc::peak_bytes().saturating_sub(base), dt)
}

/// What one streamed read saw.
struct Seen {
    fixes: usize,
    week: Option<i64>,
    dropped: usize,
    warnings: usize,
}

const OFFSET_S: f64 = 0.25;

/// Reads the generated file of `fmt` through `open_gnss` and checks every fix.
fn stream(dir: &std::path::Path, fmt: Fmt) -> Seen {
    let gnss = fmt.gnss_section(&format!("time_offset_s = {OFFSET_S}\n"));
    let cfg = gnss_gen::config(dir, &gnss);
    let mut rd = cfg.open_gnss(dir).expect("open");
    let mut count = 0usize;
    let mut prev: Option<f64> = None;
    for r in &mut rd {
        let f: GnssFix = r.unwrap_or_else(|e| panic!("{fmt:?}: {e}"));
        assert!(f.is_valid(), "{fmt:?}: {f:?}");
        if let Some(p) = prev {
            let step = f.t_s - p;
            // one interval, two across a dropped no-fix record
            assert!(
                (step - DT).abs() < 2e-3 || (step - 2.0 * DT).abs() < 2e-3,
                "{fmt:?}: step {step} after {p}"
            );
        } else {
            assert!(
                (f.t_s - (T0 + OFFSET_S)).abs() < 2e-3,
                "{fmt:?}: first {}",
                f.t_s
            );
        }
        prev = Some(f.t_s);
        count += 1;
    }
    let s = rd.summary();
    Seen {
        fixes: count,
        week: s.week,
        dropped: s.dropped_by_quality,
        warnings: s.warnings.len(),
    }
}

/// Reads the generated file of `fmt` whole (the format's whole-file reader); the fixes.
fn whole(dir: &std::path::Path, fmt: Fmt) -> usize {
    let cfg = gnss_gen::config(dir, &fmt.gnss_section(""));
    let p = dir.join(&cfg.gnss.path);
    let opts = cfg.gnss.log.clone().unwrap_or_default();
    match fmt {
        Fmt::Text => nav_io::read_gnss_text(&p).unwrap().len(),
        Fmt::Pos => nav_io::read_rtklib_pos(&p, &nav_io::PosOptions::default())
            .unwrap()
            .fixes
            .len(),
        Fmt::Csv => nav_io::read_gnss_csv(&p, cfg.gnss.csv.as_ref().unwrap())
            .unwrap()
            .fixes
            .len(),
        Fmt::Nmea => nav_io::read_nmea_log(&p, &opts, 6).unwrap().fixes.len(),
        Fmt::Ubx | Fmt::UbxGz => nav_io::read_ubx_log(&p, &opts, 6).unwrap().fixes.len(),
    }
}

#[test]
fn every_gnss_format_streams_in_constant_memory_through_open_gnss() {
    let dir = tempfile::tempdir().unwrap();
    let lengths = [10_000usize, 100_000];
    println!(
        "format   fixes    file MB | streamed: peak KiB  time s | whole file: peak KiB  time s"
    );
    let mut failures = Vec::new();
    for fmt in Fmt::ALL {
        let mut peaks = Vec::new();
        for n in lengths {
            let p = gnss_gen::write_file(dir.path(), fmt, n);
            let size = std::fs::metadata(&p).unwrap().len();
            let (seen, peak, dt) = measure(|| stream(dir.path(), fmt));
            let (whole_n, whole_peak, whole_dt) = measure(|| whole(dir.path(), fmt));
            std::fs::remove_file(&p).unwrap();
            println!(
                "{:<7} {n:>7} {:>9.2} | {:>17.1} {:>7.3} | {:>19.1} {:>7.3}",
                format!("{fmt:?}"),
                size as f64 / 1e6,
                peak as f64 / 1024.0,
                dt,
                whole_peak as f64 / 1024.0,
                whole_dt
            );
            let want = gnss_gen::kept(fmt, n);
            assert_eq!(seen.fixes, want, "{fmt:?} {n}");
            assert_eq!(whole_n, want, "{fmt:?} {n}");
            assert_eq!(seen.dropped, n - want, "{fmt:?} {n}");
            assert_eq!(seen.week, fmt.has_week().then_some(WEEK), "{fmt:?}");
            // the CSV mapping's default velocity sigma is said once; nothing else to say
            let warnings = usize::from(fmt == Fmt::Csv);
            assert_eq!(seen.warnings, warnings, "{fmt:?}");
            // the fixes held whole would take this much
            let held = want * std::mem::size_of::<GnssFix>();
            assert!(
                whole_peak >= held,
                "{fmt:?}: whole-file peak {whole_peak} B below the fixes' {held} B"
            );
            peaks.push(peak);
        }
        let (short, long) = (peaks[0], peaks[1]);
        if long > short + 4096 || long > 1 << 20 {
            failures.push(format!(
                "{fmt:?}: peak {short} B for {} fixes, {long} B for {}",
                lengths[0], lengths[1]
            ));
        }
    }
    assert!(failures.is_empty(), "memory grows: {failures:?}");
}
