//! `host-sim run --smooth` in bounded memory (`nav_engine::smooth::run::execute_smoothed`):
//! a run configuration's IMU CSV (200 Hz) and `.pos` GNSS file, written by the test at two
//! lengths (5 and 20 minutes), smoothed while a counting global allocator tracks the live
//! heap. Holding the forward pass (navigation records at the IMU rate, the smoother's nodes)
//! grows with the record; written to temporary files and read back in blocks, the peak must
//! not grow beyond the reader threads' chunks in flight and what the GNSS reader itself holds
//! (measured here on its own at each length; its file is read twice: by the engine and for
//! the innovations against the smoothed trajectory). At 5 minutes the outputs are compared
//! byte for byte with the smoother run on the case held in memory (`smooth_run`).
//!
//! A test binary of its own: the allocator's counters are process-wide.

use nav_engine::run::execute::{execute, READ_CHUNK, READ_QUEUE};
use nav_engine::run::output;
use nav_engine::run::ImuItem;
use nav_engine::smooth::apply::smooth_run;
use nav_engine::smooth::run::{execute_smoothed, RECENT};
use nav_engine::{load, RunSpec};
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

fn spec(config: &std::path::Path) -> RunSpec {
    let mut s = RunSpec::new(config);
    s.set.smoother_history = true;
    s
}

struct Measured {
    run: usize,
    gnss: usize,
    nodes: usize,
    node_bytes: f64,
}

fn measure(minutes: f64, compare: bool) -> Measured {
    let dir = tempfile::tempdir().unwrap();
    let case = write_csv_pos_case(dir.path(), minutes, RATE_HZ, None);
    let cfg = nav_io::read_run_config(&case.config).unwrap();
    let (n, gnss) = peak_of(|| cfg.open_gnss(dir.path()).unwrap().count());
    assert_eq!(n, case.fixes);
    let out = dir.path().join("out");
    let ((l, ran), run) = peak_of(|| {
        let l = load(&spec(&case.config), true).unwrap();
        let ran = execute_smoothed(
            &l.prepared,
            l.imu_stream.as_ref(),
            l.truth_stream.as_ref(),
            &out,
            None,
            &|_, _, _, _| Ok("{}".into()),
            &mut |_, _| {},
        )
        .unwrap();
        (l, ran)
    });
    // streamed, and a real run: every increment integrated, every fix used, every record out
    assert!(l.prepared.case.imu.is_empty() && l.prepared.case.gnss.is_empty());
    let fwd = &ran.forward;
    assert_eq!(fwd.counters.imu_epochs as usize, case.rows - 2);
    assert_eq!(fwd.counters.gnss_accepted as usize, case.fixes);
    assert!(fwd.history.is_none());
    let rep = &ran.report;
    // a node per 0.1 s covariance prediction interval
    assert!(rep.nodes as f64 > 0.9 * minutes * 600.0, "{rep:?}");
    assert_eq!(rep.pinv_fallbacks, 0);
    let read = |name: &str| std::fs::read(out.join(name)).unwrap();
    let lines = |name: &str| read(name).iter().filter(|b| **b == b'\n').count();
    assert_eq!(lines("nav.txt"), case.rows - 1);
    assert_eq!(lines("nav_forward.txt"), case.rows - 1);
    assert_ne!(read("nav.txt"), read("nav_forward.txt"));
    // nothing left behind: the five outputs and nav_forward.txt only
    let mut names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "bias.txt",
            "innovations.txt",
            "metrics.json",
            "nav.txt",
            "nav_forward.txt",
            "std.txt"
        ]
    );
    if compare {
        // the smoother on the run held in memory, written by the in-memory writer
        let lm = load(&spec(&case.config), false).unwrap();
        let (fwd_mem, _) = execute(&lm.prepared, &mut |_, _| {}).unwrap();
        let (sm, _, _) = smooth_run(&lm.prepared.case, &fwd_mem).unwrap();
        let mem = dir.path().join("mem");
        std::fs::create_dir_all(&mem).unwrap();
        output::write_all(&mem, &sm, &sm.nav, l.prepared.week, "{}", true).unwrap();
        output::write_nav(&mem.join("nav_forward.txt"), &fwd_mem.nav, l.prepared.week).unwrap();
        for name in [
            "nav.txt",
            "std.txt",
            "bias.txt",
            "innovations.txt",
            "nav_forward.txt",
        ] {
            let a = read(name);
            let b = std::fs::read(mem.join(name)).unwrap();
            assert!(a == b, "{name} differs from the in-memory smoother's");
        }
    }
    println!(
        "{minutes} min ({} IMU rows, {} fixes, {} nodes; history {:.1} MB, smoothed {:.1} MB \
         on disk): smoothed run peak {:.3} MiB, GNSS reader alone {:.3} MiB",
        case.rows,
        case.fixes,
        rep.nodes,
        rep.history_bytes as f64 / 1e6,
        rep.smoothed_bytes as f64 / 1e6,
        run as f64 / 1048576.0,
        gnss as f64 / 1048576.0
    );
    Measured {
        run,
        gnss,
        nodes: rep.nodes,
        node_bytes: rep.history_bytes_per_node,
    }
}

#[test]
fn a_smoothed_run_is_flat_in_memory_and_equals_the_in_memory_smoother() {
    let short = measure(5.0, true);
    let long = measure(20.0, false);
    let grow = long.run as f64 - short.run as f64;
    let gnss_grow = long.gnss as f64 - short.gnss as f64;
    // the GNSS file is read twice in the second pass (the engine's fixes and the fixes of the
    // innovations), once in the first
    let rest = grow - 2.0 * gnss_grow.max(0.0);
    // what holding the forward pass of the extra 15 minutes would take: a navigation record
    // per IMU epoch and the history's nodes as they are stored on disk
    let extra_epochs = 15.0 * 60.0 * RATE_HZ;
    let extra_nodes = (long.nodes - short.nodes) as f64;
    let held = extra_epochs * std::mem::size_of::<nav_core::types::NavSolution>() as f64
        + extra_nodes * long.node_bytes;
    // the allowance, from the buffers: the IMU reader thread's chunks in flight (queue plus
    // the chunk being filled and the one consumed; per pass, the first pass's freed before
    // the second) and 64 KiB for the allocator; the smoother's blocks and its window of
    // recent records are the same at both lengths (their sizes are fixed, reached in the
    // first minute)
    let in_flight = (READ_QUEUE + 2) * READ_CHUNK * std::mem::size_of::<ImuItem>();
    println!(
        "growth 5 -> 20 min: {:.3} MiB, of which the GNSS reader {:.3} MiB (x2), the rest {:.3} \
         MiB (holding the forward pass would add {:.1} MiB; allowance {:.3} MiB; recent \
         window {RECENT} records)",
        grow / 1048576.0,
        gnss_grow / 1048576.0,
        rest / 1048576.0,
        held / 1048576.0,
        (in_flight + 65536) as f64 / 1048576.0
    );
    assert!(
        rest <= (in_flight + 65536) as f64,
        "the smoothed run's peak grew by {grow} B, the GNSS reader's by {gnss_grow} B: more \
         than the {in_flight} B of IMU chunks in flight"
    );
    assert!(((in_flight + 65536) as f64) < held / 10.0);
    // and the whole peak stays far below 64 MiB
    assert!(long.run < 64 << 20, "{}", long.run);
}
