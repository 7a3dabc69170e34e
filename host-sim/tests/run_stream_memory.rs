//! The streaming engine's memory does not grow with the record: hours of 200 Hz IMU data
//! generated on the fly (never stored, never written to disk) run through
//! `nav_engine::run::run_engine` while a counting global allocator tracks the live heap.
//! Loading the same record would take `n * size_of::<ImuSample>()` bytes for the samples
//! alone (plus a navigation record per sample); the test asserts the peak stays below a
//! small fixed bound instead, and that the run was a real one (every sample integrated, the
//! solution next to the fixes).

use nav_core::earth::{self, Llh};
use nav_core::types::{GnssFix, ImuSample, NavSolution};
use nav_engine::run::{
    run_engine, CoastPlan, EpochRecord, ImuItem, ImuSourceInfo, InnovationRecord, RunError,
    RunOptions, RunSink, Streams,
};
use test_support::{alloc, standing};

#[global_allocator]
static A: alloc::Counting = alloc::Counting;

/// Counts the records and keeps the last navigation record (nothing else).
#[derive(Default)]
struct Count {
    nav: u64,
    innovations: u64,
    accepted: u64,
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
        self.innovations += 1;
        if r.used == nav_engine::run::FixUse::Accepted {
            self.accepted += 1;
        }
        Ok(())
    }
    fn wants_epochs(&self) -> bool {
        false
    }
}

const RATE_HZ: f64 = 200.0;
const HOURS: f64 = 3.0;
const T0: f64 = 100_000.0;

#[test]
fn hours_of_imu_run_in_bounded_memory() {
    let pos = Llh::from_deg(30.5, 114.3, 20.0);
    let n = (HOURS * 3600.0 * RATE_HZ) as usize;
    // a level, north-facing, standing vehicle: body = NED; the gyros see the earth rate and
    // the accelerometers the reaction to gravity
    let mut gen = standing::imu(pos, T0, RATE_HZ, n).map(|sample| Ok(ImuItem { sample, line: 0 }));
    // GNSS at 1 Hz at the same place (held in memory: 150 B a fix)
    let fixes: Vec<GnssFix> =
        standing::fixes(pos, T0, 1.0, (HOURS * 3600.0) as usize - 1).collect();
    let mut opts = RunOptions::standing_start(T0, pos);
    opts.record.epoch_rate_hz = Some(0.0);
    let mut sink = Count::default();
    let base = alloc::reset_peak();
    let t = std::time::Instant::now();
    let out = run_engine(
        Streams {
            imu: Box::new(&mut gen),
            info: ImuSourceInfo::default(),
            gnss: Box::new(fixes.iter().copied().map(Ok)),
            truth: None,
        },
        &opts,
        CoastPlan::default(),
        &mut sink,
        &mut |_, _| {},
    )
    .expect("run");
    let peak = alloc::peak_bytes().saturating_sub(base);
    let secs = t.elapsed().as_secs_f64();
    let loaded = n * std::mem::size_of::<ImuSample>() + n * std::mem::size_of::<NavSolution>();
    println!(
        "{n} IMU samples ({HOURS} h at {RATE_HZ} Hz) in {secs:.1} s: peak live heap {:.2} MiB \
         during the run (GNSS list {:.2} MiB before it); loading the samples and keeping the \
         navigation would take {:.0} MiB",
        peak as f64 / 1048576.0,
        (fixes.capacity() * std::mem::size_of::<GnssFix>()) as f64 / 1048576.0,
        loaded as f64 / 1048576.0
    );
    assert_eq!(out.counters.imu_epochs, n as u64);
    assert_eq!(sink.nav, n as u64 + 1);
    assert_eq!(sink.innovations, fixes.len() as u64);
    assert!(
        sink.accepted as f64 > 0.99 * fixes.len() as f64,
        "{}",
        sink.accepted
    );
    let last = sink.last.expect("a solution");
    let p = Llh {
        lat_rad: last.lat_rad,
        lon_rad: last.lon_rad,
        h_m: last.h_m,
    };
    let d = earth::ned_offset_m(&pos, &p);
    assert!(d.norm() < 2.0, "final position {d:?} m from the fixes");
    // bounded: a fixed 8 MiB against hundreds of MiB when loaded
    assert!(
        peak < 8 << 20,
        "peak live heap {peak} B during the run (loaded: {loaded} B)"
    );
    assert!(
        loaded > 40 * peak,
        "the record must be far larger than the bound"
    );
}
