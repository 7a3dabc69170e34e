//! The streaming engine's memory does not grow with the record, GNSS fixes included: two
//! hours of 200 Hz IMU data AND of 10 Hz GNSS fixes, both generated on the fly (never stored,
//! never written to disk), run through `nav_engine::run::run_engine` with imposed
//! outages and their coasting baselines (the engine reads the fixes ahead to each outage's
//! end) while a counting global allocator tracks the live heap. Holding the fixes alone would
//! take `n_fix * size_of::<GnssFix>()` bytes; the test asserts the peak stays below a small
//! fixed bound (2 MiB) and below half of that, and that the run was a real one (every sample
//! integrated, every fix used or withheld, every outage coasted with its withheld fixes).
//!
//! A test binary of its own: the allocator's counters are process-wide (another test running
//! at the same time would count too).

use nav_core::earth::{self, Llh};
use nav_core::types::{GnssFix, NavSolution};
use nav_engine::run::{
    run_engine, CoastPlan, CoastTrack, EpochRecord, FixUse, ImuItem, ImuSourceInfo,
    InnovationRecord, Outage, RunError, RunOptions, RunSink, Streams,
};
use test_support::{alloc, standing};

#[global_allocator]
static A: alloc::Counting = alloc::Counting;

/// Counts the records (nothing else is kept but the last navigation record).
#[derive(Default)]
struct Count {
    nav: u64,
    accepted: u64,
    withheld: u64,
    tracks: u64,
    track_fixes: u64,
    last: Option<NavSolution>,
}

impl RunSink for Count {
    fn nav(&mut self, s: &NavSolution) -> Result<(), RunError> {
        self.nav += 1;
        self.last = Some(*s);
        Ok(())
    }
    fn epoch(&mut self, _r: EpochRecord) -> Result<(), RunError> {
        Ok(())
    }
    fn innovation(&mut self, r: &InnovationRecord) -> Result<(), RunError> {
        match r.used {
            FixUse::Accepted => self.accepted += 1,
            FixUse::Withheld => self.withheld += 1,
            _ => {}
        }
        Ok(())
    }
    fn coast(&mut self, _mode: usize, track: CoastTrack) {
        self.tracks += 1;
        self.track_fixes += track.fixes.len() as u64;
    }
    fn wants_epochs(&self) -> bool {
        false
    }
}

const RATE_HZ: f64 = 200.0;
const GNSS_HZ: f64 = 10.0;
const HOURS: f64 = 2.0;
const T0: f64 = 100_000.0;
/// An outage of 10 s every 10 min, the first at 5 min.
const OUTAGE_EVERY_S: f64 = 600.0;
const OUTAGE_S: f64 = 10.0;

#[test]
fn hours_of_imu_and_gnss_run_in_bounded_memory() {
    let pos = Llh::from_deg(30.5, 114.3, 20.0);
    let n = (HOURS * 3600.0 * RATE_HZ) as usize;
    // a level, north-facing, standing vehicle: body = NED; the gyros see the earth rate and
    // the accelerometers the reaction to gravity
    let mut imu = standing::imu(pos, T0, RATE_HZ, n).map(|sample| Ok(ImuItem { sample, line: 0 }));
    // GNSS at 10 Hz at the same place, generated as the engine reads them
    let n_fix = (HOURS * 3600.0 * GNSS_HZ) as usize - 1;
    let gnss = standing::fixes(pos, T0, GNSS_HZ, n_fix).map(Ok);
    let mut opts = RunOptions::standing_start(T0, pos);
    opts.record.epoch_rate_hz = Some(0.0);
    let n_out = (HOURS * 3600.0 / OUTAGE_EVERY_S) as usize;
    opts.outages = (0..n_out)
        .map(|k| Outage {
            start_s: T0 + 300.0 + k as f64 * OUTAGE_EVERY_S,
            duration_s: OUTAGE_S,
        })
        .collect();
    let mut sink = Count::default();
    let base = alloc::reset_peak();
    let t = std::time::Instant::now();
    let out = run_engine(
        Streams {
            imu: Box::new(&mut imu),
            info: ImuSourceInfo::default(),
            gnss: Box::new(gnss),
            truth: None,
        },
        &opts,
        CoastPlan {
            raw: true,
            static_gyro_bias: false,
        },
        &mut sink,
        &mut |_, _| {},
    )
    .expect("run");
    let peak = alloc::peak_bytes().saturating_sub(base);
    let secs = t.elapsed().as_secs_f64();
    let held = n_fix * std::mem::size_of::<GnssFix>();
    println!(
        "{n} IMU samples and {n_fix} fixes ({HOURS} h at {RATE_HZ} / {GNSS_HZ} Hz, {n_out} \
         outages coasted) in {secs:.1} s: peak live heap {:.2} MiB during the run; holding the \
         fixes would take {:.1} MiB",
        peak as f64 / 1048576.0,
        held as f64 / 1048576.0
    );
    // a real run: every sample integrated, every fix counted, used or withheld
    assert_eq!(out.counters.imu_epochs, n as u64);
    assert_eq!(sink.nav, n as u64 + 1);
    assert_eq!(out.counters.gnss_total, n_fix as u64);
    let per_outage = (OUTAGE_S * GNSS_HZ) as u64;
    assert_eq!(sink.withheld, n_out as u64 * per_outage);
    assert_eq!(out.counters.gnss_withheld, sink.withheld);
    assert!(
        sink.accepted as f64 > 0.99 * (n_fix as u64 - sink.withheld) as f64,
        "{} accepted",
        sink.accepted
    );
    // every outage coasted, with all its withheld fixes (read ahead at its snapshot)
    assert_eq!(sink.tracks, n_out as u64);
    assert_eq!(sink.track_fixes, sink.withheld);
    let last = sink.last.expect("a solution");
    let p = Llh {
        lat_rad: last.lat_rad,
        lon_rad: last.lon_rad,
        h_m: last.h_m,
    };
    let d = earth::ned_offset_m(&pos, &p);
    assert!(d.norm() < 2.0, "final position {d:?} m from the fixes");
    // bounded: a fixed 2 MiB (0.67 MiB measured), and less than half of what the fixes alone
    // would take
    assert!(
        peak < 2 << 20,
        "peak live heap {peak} B during the run (fixes: {held} B)"
    );
    assert!(
        held > 2 * peak,
        "peak live heap {peak} B: not below half of the fixes' {held} B"
    );
}
