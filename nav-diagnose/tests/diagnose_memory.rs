//! `diagnose`'s memory does not grow with the record beyond what is proportional to the
//! GNSS fixes and the search's transient runs: a 5-minute and a 25-minute 200 Hz record
//! (a standing vehicle, fixes at 1 Hz) are generated sample by sample straight into the
//! diagnosis's IMU record file ([`ImuCache::write`], as `host-sim diagnose` decodes the IMU
//! file) and diagnosed ([`diagnose_cached`]) with the cheapest options that still run the
//! search (no noise tuning, one candidate) while a counting global allocator tracks the live
//! heap from before the record is written: the IMU record itself (64 bytes a sample) is
//! never in memory, and nothing is allowed for it.
//!
//! What the diagnosis holds per fix (innovation records of the base, search and candidate
//! runs, the search runs' navigation records nearest the fixes, the withheld fixes' error
//! samples, the IMU samples the candidates' regressors read) is allowed [`PER_FIX_BYTES`];
//! while a search run is thinned to its records
//! nearest the fixes, the times of its navigation at the search rate (`SEARCH_NAV_RATE_HZ`,
//! [`THINNING_BYTES`] a record) are held, for at most [`SEARCH_RUNS_AT_ONCE`] runs at a time.
//! The navigation itself (168 bytes a record: every IMU epoch for the base and final runs,
//! what `nav_before.txt` and `nav_after.txt` hold, the search rate for the search runs) must
//! not be in memory: it is in the diagnosis's temporary files.

use nav_core::earth::Llh;
use nav_core::model::Block;
use nav_core::types::{GnssFix, ImuSample, NavSolution};
use nav_diagnose::imu_cache::ImuCache;
use nav_diagnose::{
    diagnose, diagnose_cached, spill, DiagnoseOptions, Outcome, SEARCH_NAV_RATE_HZ,
};
use nav_engine::run::{CaseData, ImuSourceInfo, InnovationRecord, RunOptions};
use nav_engine::Prepared;
use test_support::{alloc, standing};

#[global_allocator]
static A: alloc::Counting = alloc::Counting;

const RATE_HZ: f64 = 200.0;
const T0: f64 = 100_000.0;

/// Bytes the diagnosis may hold per GNSS fix: eight innovation records, eight navigation
/// records and eight GNSS fixes' worth (base, search and candidate runs, and their copies
/// while a round is decided), and the two IMU samples per fix the regressors of each search
/// run alive at once read.
const PER_FIX_BYTES: usize = 8
    * (std::mem::size_of::<InnovationRecord>()
        + std::mem::size_of::<NavSolution>()
        + std::mem::size_of::<GnssFix>())
    + SEARCH_RUNS_AT_ONCE * 2 * std::mem::size_of::<ImuSample>();

/// Bytes held per search-rate navigation record while a search run is thinned: its time and
/// a flag.
const THINNING_BYTES: usize = 9;

/// Search runs alive at once while they are scored (the rayon pool of the candidates and a
/// current one).
const SEARCH_RUNS_AT_ONCE: usize = 3;

/// The standing vehicle's IMU samples over `minutes`.
fn imu(minutes: f64) -> impl Iterator<Item = ImuSample> {
    let n = (minutes * 60.0 * RATE_HZ) as usize;
    standing::imu(position(), T0, RATE_HZ, n)
}

fn position() -> Llh {
    Llh::from_deg(30.5, 114.3, 20.0)
}

/// The case of `minutes` (its IMU samples not in it: [`imu`]) and its options.
fn prepared(minutes: f64) -> Prepared {
    let pos = position();
    let gnss = standing::fixes(pos, T0, 1.0, (minutes * 60.0) as usize - 1).collect();
    let opts = RunOptions::standing_start(T0, pos);
    Prepared {
        case: CaseData {
            imu: Vec::new(),
            gnss,
            truth: None,
            imu_origin: None,
        },
        opts,
        week: 2227,
        description: "standing vehicle".into(),
    }
}

/// Entries in the folder.
fn entries(dir: &std::path::Path) -> usize {
    std::fs::read_dir(dir).unwrap().count()
}

/// Peak live heap of the diagnosis of `minutes` of record, from before its IMU record is
/// written, bytes, and the number of fixes; `tmp`: the temporary directory the diagnosis
/// writes into (its folder there is removed with the output).
fn peak_of(minutes: f64, tmp: &std::path::Path) -> (usize, usize) {
    let p = prepared(minutes);
    let dopts = DiagnoseOptions {
        max_effects: 1,
        candidates: Some(vec![Block::LeverArm]),
        tune_noise: false,
        ambiguity_margin: 3.0,
        smooth: false,
    };
    let case = p.case.clone();
    let base = alloc::reset_peak();
    let t = std::time::Instant::now();
    let folder = spill::temp_folder().unwrap();
    let samples = imu(minutes).map(|s| Ok((s, 0)));
    let cache = ImuCache::write(&folder, samples, ImuSourceInfo::default()).unwrap();
    let n_imu = cache.len();
    drop(folder);
    let Outcome::Complete(out) =
        diagnose_cached(case, &p.opts, cache, &dopts, &mut |_, _| {}).expect("diagnose")
    else {
        panic!("the diagnosis was interrupted")
    };
    let peak = alloc::peak_bytes().saturating_sub(base);
    let d = &out.diagnosis;
    println!(
        "{minutes} min: {} IMU samples, {} fixes: diagnosed in {:.1} s, peak {:.2} MiB; {}",
        n_imu,
        p.case.gnss.len(),
        t.elapsed().as_secs_f64(),
        peak as f64 / 1048576.0,
        d.verdict
    );
    // a real diagnosis: the base run at every IMU epoch (and the initial one), windows
    // withheld, the candidate run
    assert_eq!(n_imu, imu(minutes).count());
    assert_eq!(out.before_nav.len(), n_imu + 1);
    assert!(
        d.heldout_windows.windows.len() >= 5,
        "{:?}",
        d.heldout_windows
    );
    let tried = &d.rounds.first().expect("a round").candidates;
    assert_eq!(tried.len(), 1);
    assert!(tried[0].delta_log_likelihood.is_some(), "{:?}", tried[0]);
    assert!(d.residuals_before.updates as f64 > 0.9 * p.case.gnss.len() as f64);
    assert_eq!(entries(tmp), 1, "the diagnosis's temporary folder");
    drop(out);
    assert_eq!(
        entries(tmp),
        0,
        "the temporary folder is removed with the output"
    );
    (peak, p.case.gnss.len())
}

#[test]
fn diagnosis_memory_does_not_grow_with_the_record_beyond_the_fixes() {
    // the diagnosis's temporary files in a folder of this test's own (the only test of
    // this binary: the variable is read by nothing else)
    let tmp = tempfile::tempdir().unwrap();
    std::env::set_var("TMPDIR", tmp.path());
    // an error (no IMU sample) leaves no temporary folder either
    let empty = prepared(1.0);
    let dopts = DiagnoseOptions::default();
    assert!(diagnose(&empty, &dopts).is_err());
    assert_eq!(entries(tmp.path()), 0);
    let (short, short_fixes) = peak_of(5.0, tmp.path());
    let (long, long_fixes) = peak_of(25.0, tmp.path());
    let extra_s = (long_fixes - short_fixes) as f64;
    let search_nav = SEARCH_RUNS_AT_ONCE * (extra_s * SEARCH_NAV_RATE_HZ) as usize * THINNING_BYTES;
    let allowance = (long_fixes - short_fixes) * PER_FIX_BYTES + search_nav;
    // what the full-rate navigation of the base run alone would add, and the IMU record
    let full_rate = (extra_s * RATE_HZ) as usize * std::mem::size_of::<NavSolution>();
    let record = (extra_s * RATE_HZ) as usize * std::mem::size_of::<ImuSample>();
    println!(
        "growth {:.2} MiB for {extra_s} s more: allowed {:.2} MiB ({:.2} MiB of it the search \
         runs' thinning); one full-rate navigation would be {:.2} MiB, the IMU record {:.2} MiB",
        long.saturating_sub(short) as f64 / 1048576.0,
        allowance as f64 / 1048576.0,
        search_nav as f64 / 1048576.0,
        full_rate as f64 / 1048576.0,
        record as f64 / 1048576.0
    );
    assert!(
        long <= short + allowance,
        "peak {long} B for 25 min against {short} B for 5 min: growth beyond {allowance} B"
    );
    assert!(
        allowance < full_rate && allowance < record,
        "the bound must be below a full-rate navigation and the IMU record"
    );
}
