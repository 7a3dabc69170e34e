//! A run configuration's own files are streamed by `host-sim run`
//! (`nav_engine::load_checking_in_run` + `execute_streaming`: the mounting check made on the
//! run's own reading): an IMU CSV log (200 Hz, time in seconds) and an RTKLIB
//! `.pos` GNSS file written by the test at two lengths (5 and 20 minutes), run while a
//! counting global allocator tracks the live heap. Loading would hold every IMU sample (and
//! its file line); streamed, the peak must not grow with the length beyond what the GNSS
//! reader itself holds (`RunConfig::open_gnss`, which reads its file whole inside until the
//! streaming GNSS readers land; measured here on its own at each length): the IMU part is
//! flat. The loaded path is measured too at 20 minutes, for the report.
//!
//! A test binary of its own: the allocator's counters are process-wide.

use nav_engine::{execute_streaming, load, load_checking_in_run, RunSpec};
use test_support::alloc;
use test_support::csvcase::write_csv_pos_case;

#[global_allocator]
static A: alloc::Counting = alloc::Counting;

const RATE_HZ: f64 = 200.0;

/// Peak live heap growth of `f`, bytes.
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = alloc::reset_peak();
    let r = f();
    (r, alloc::peak_bytes().saturating_sub(base))
}

struct Measured {
    run: usize,
    gnss: usize,
    loaded: Option<usize>,
}

fn measure(minutes: f64, with_loaded: bool) -> Measured {
    let dir = tempfile::tempdir().unwrap();
    let case = write_csv_pos_case(dir.path(), minutes, RATE_HZ, None);
    let cfg = nav_io::read_run_config(&case.config).unwrap();
    // the GNSS reader on its own: what it holds (all its fixes, until it streams)
    let (n, gnss) = peak_of(|| {
        let mut n = 0usize;
        for r in cfg.open_gnss(dir.path()).unwrap() {
            r.unwrap();
            n += 1;
        }
        n
    });
    assert_eq!(n, case.fixes);
    // the streamed run, outputs written
    let out = dir.path().join("out");
    let ((l, ran), run) = peak_of(|| {
        let l = load_checking_in_run(&RunSpec::new(&case.config)).unwrap();
        let ran = execute_streaming(
            &l.prepared,
            l.imu_stream.as_ref(),
            l.truth_stream.as_ref(),
            &out,
            &l.inputs,
            None,
            &mut |_, _| {},
        )
        .unwrap();
        (l, ran)
    });
    // streamed indeed, and a real run: every increment integrated, every fix used
    assert!(l.prepared.case.imu.is_empty() && l.prepared.case.gnss.is_empty());
    let st = l.imu_stream.as_ref().expect("streamed");
    assert!(st.file.increments_span_gaps());
    assert_eq!(st.gnss.as_ref().expect("GNSS streamed").fixes, case.fixes);
    assert_eq!(l.prepared.week, test_support::csvcase::WEEK);
    let (o, _) = ran;
    assert_eq!(o.counters.imu_epochs as usize, case.rows - 2);
    assert_eq!(o.counters.gnss_total as usize, case.fixes);
    assert_eq!(o.counters.gnss_accepted as usize, case.fixes);
    let nav_lines = std::fs::read_to_string(out.join("nav.txt"))
        .unwrap()
        .lines()
        .count();
    assert_eq!(nav_lines, case.rows - 1);
    let loaded = with_loaded.then(|| {
        peak_of(|| {
            let l = load(&RunSpec::new(&case.config), false).unwrap();
            assert_eq!(l.prepared.case.imu.len(), case.rows - 1);
            l
        })
        .1
    });
    println!(
        "{minutes} min ({} IMU rows, {} fixes): streamed run peak {:.3} MiB, GNSS reader alone \
         {:.3} MiB{}",
        case.rows,
        case.fixes,
        run as f64 / 1048576.0,
        gnss as f64 / 1048576.0,
        loaded.map_or(String::new(), |b| format!(
            ", loading alone {:.1} MiB",
            b as f64 / 1048576.0
        ))
    );
    Measured { run, gnss, loaded }
}

#[test]
fn a_configurations_csv_and_pos_files_stream_in_memory_flat_in_the_imu() {
    let short = measure(5.0, false);
    let long = measure(20.0, true);
    let grow = long.run as f64 - short.run as f64;
    let gnss_grow = long.gnss as f64 - short.gnss as f64;
    let imu_grow = grow - gnss_grow;
    // what loading the extra 15 minutes of IMU would add: the samples and their lines
    let extra = 15.0 * 60.0 * RATE_HZ;
    let loaded_extra = extra
        * (std::mem::size_of::<nav_core::types::ImuSample>() + std::mem::size_of::<usize>()) as f64;
    println!(
        "growth 5 -> 20 min: run {:.3} MiB, of which the GNSS reader {:.3} MiB, the rest {:.3} \
         MiB (loading the IMU would add {:.1} MiB)",
        grow / 1048576.0,
        gnss_grow / 1048576.0,
        imu_grow / 1048576.0,
        loaded_extra / 1048576.0
    );
    // the IMU part is flat: beyond the GNSS reader's own growth, no more than the reader
    // thread's chunks in flight (how many are queued when the peak comes depends on the
    // threads' scheduling, not on the length: the queue plus the chunk being filled and the
    // one being consumed) and 64 KiB for the allocator
    let in_flight = (nav_engine::run::execute::READ_QUEUE + 2)
        * nav_engine::run::execute::READ_CHUNK
        * std::mem::size_of::<nav_engine::run::ImuItem>();
    assert!(
        imu_grow <= (in_flight + 65536) as f64,
        "the run's peak grew by {grow} B, the GNSS reader's by {gnss_grow} B: more than the \
         {in_flight} B of IMU chunks in flight"
    );
    // ... which is a small part of what the loaded 15 minutes would add
    assert!(((in_flight + 65536) as f64) < loaded_extra / 10.0);
    assert!(imu_grow < loaded_extra / 10.0);
    // and the loaded path holds the record
    let loaded = long.loaded.expect("measured") as f64;
    assert!(loaded > loaded_extra, "{loaded}");
    assert!(long.run as f64 * 4.0 < loaded, "{} vs {loaded}", long.run);
}
