//! The diagnosis's runs with their navigation records in temporary files instead of memory
//! ([`NavFile`]: [`NAV_RECORD_BYTES`] a record). The full-rate runs (the configuration's and
//! the final model's, every IMU epoch: `nav_before.txt`, `nav_after.txt`) keep their file to
//! the end; a search run's file (search rate) is read for its metrics, its written-solution
//! check and its records nearest the fixes, then removed. In memory stays what is
//! proportional to the GNSS fixes (innovation records, records nearest the fixes) and the
//! outage snapshots. The metrics are computed from the file as
//! [`nav_engine::run::execute::execute_case`] and [`metrics::compute`] compute them from
//! memory (the online accumulators of a streamed `host-sim run`: identical numbers). The runs
//! the search reads only the innovations of keep nothing else ([`run_innovations`]).
//!
//! The files live in a temporary folder ([`tempfile::TempDir`]) shared by the [`NavFile`]s
//! made in it, removed when the last of them (and the diagnosis holding the folder) is
//! dropped, also when the diagnosis ends with an error.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::imu_cache::Case;
use crate::DiagnoseError;
use nav_core::model::ImuCorrection;
use nav_core::types::NavSolution;
use nav_engine::metrics::{self, Metrics, ResidualAcc, SampleAcc, TruthMatcher};
use nav_engine::run::{
    coast_outages_with, CoastMode, CoastPlan, EpochRecord, FixUse, InnovationRecord,
    OutageSnapshot, RunError, RunOptions, RunOutput, RunSink, Streams,
};
use nav_io::IoError;

/// Bytes of one navigation record in a [`NavFile`]: the GPS week (u16), the 19 f64 of the
/// solution (time, position, velocity, attitude and their standard deviations, in the order
/// of [`NavSolution`]'s fields) and the status word (u32), little-endian, exactly the values
/// of the record (read back bit for bit).
pub const NAV_RECORD_BYTES: usize = 2 + 19 * 8 + 4;

fn encode(s: &NavSolution) -> [u8; NAV_RECORD_BYTES] {
    let mut b = [0u8; NAV_RECORD_BYTES];
    let f: [f64; 19] = [
        s.t_s,
        s.lat_rad,
        s.lon_rad,
        s.h_m,
        s.vel_ned_mps[0],
        s.vel_ned_mps[1],
        s.vel_ned_mps[2],
        s.rpy_rad[0],
        s.rpy_rad[1],
        s.rpy_rad[2],
        s.pos_std_ned_m[0],
        s.pos_std_ned_m[1],
        s.pos_std_ned_m[2],
        s.vel_std_ned_mps[0],
        s.vel_std_ned_mps[1],
        s.vel_std_ned_mps[2],
        s.att_std_rad[0],
        s.att_std_rad[1],
        s.att_std_rad[2],
    ];
    let (week, rest) = b.split_at_mut(2);
    week.copy_from_slice(&s.week.to_le_bytes());
    let (vals, status) = rest.split_at_mut(19 * 8);
    for (dst, v) in vals.chunks_exact_mut(8).zip(f) {
        dst.copy_from_slice(&v.to_le_bytes());
    }
    status.copy_from_slice(&s.status.to_le_bytes());
    b
}

fn decode(b: &[u8; NAV_RECORD_BYTES]) -> NavSolution {
    let (week, rest) = b.split_at(2);
    let (vals, status) = rest.split_at(19 * 8);
    let mut f = [0.0f64; 19];
    for (v, src) in f.iter_mut().zip(vals.chunks_exact(8)) {
        let mut x = [0u8; 8];
        x.copy_from_slice(src);
        *v = f64::from_le_bytes(x);
    }
    let mut w = [0u8; 2];
    w.copy_from_slice(week);
    let mut st = [0u8; 4];
    st.copy_from_slice(status);
    NavSolution {
        week: u16::from_le_bytes(w),
        t_s: f[0],
        lat_rad: f[1],
        lon_rad: f[2],
        h_m: f[3],
        vel_ned_mps: [f[4], f[5], f[6]],
        rpy_rad: [f[7], f[8], f[9]],
        pos_std_ned_m: [f[10], f[11], f[12]],
        vel_std_ned_mps: [f[13], f[14], f[15]],
        att_std_rad: [f[16], f[17], f[18]],
        status: u32::from_le_bytes(st),
    }
}

/// The temporary folder of a diagnosis's files, removed when the last holder drops it.
pub type TempFolder = Arc<tempfile::TempDir>;

/// Creates the temporary folder of a diagnosis (in the system's temporary directory).
pub fn temp_folder() -> Result<TempFolder, DiagnoseError> {
    let d = tempfile::Builder::new()
        .prefix("host-sim-diagnose-")
        .tempdir()
        .map_err(DiagnoseError::TempFolder)?;
    Ok(Arc::new(d))
}

/// Navigation records of one run in a file of fixed-size records ([`NAV_RECORD_BYTES`]) in
/// the diagnosis's temporary folder, read back as often as needed ([`Self::records`]).
#[derive(Debug, Clone)]
pub struct NavFile {
    folder: TempFolder,
    path: PathBuf,
    len: usize,
    first_t_s: Option<f64>,
    last_t_s: Option<f64>,
}

impl NavFile {
    /// Writes `nav` into the file `name` of `folder`.
    pub fn from_slice(
        folder: &TempFolder,
        name: &str,
        nav: &[NavSolution],
    ) -> Result<Self, IoError> {
        let mut w = NavWriter::create(folder, name)?;
        for s in nav {
            w.push(s)?;
        }
        w.finish()
    }

    /// Number of records.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True without records.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Time of the first record, s.
    pub fn first_t_s(&self) -> Option<f64> {
        self.first_t_s
    }

    /// Time of the last record, s.
    pub fn last_t_s(&self) -> Option<f64> {
        self.last_t_s
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The records in time order, read from the file (a buffer of memory whatever the
    /// length); a read error names the file.
    pub fn records(&self) -> Result<NavRecords, IoError> {
        let f = File::open(&self.path).map_err(|source| IoError::Open {
            path: self.path.clone(),
            source,
        })?;
        Ok(NavRecords {
            r: BufReader::with_capacity(64 * 1024, f),
            path: self.path.clone(),
            left: self.len,
            index: 0,
        })
    }

    /// Every record in memory (for tests and small runs: memory proportional to the run).
    pub fn load(&self) -> Result<Vec<NavSolution>, IoError> {
        self.records()?.collect()
    }

    /// The folder the file is in (kept alive by the file).
    pub fn folder(&self) -> &TempFolder {
        &self.folder
    }
}

/// The records of a [`NavFile`], read one by one.
pub struct NavRecords {
    r: BufReader<File>,
    path: PathBuf,
    left: usize,
    index: usize,
}

impl Iterator for NavRecords {
    type Item = Result<NavSolution, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.left == 0 {
            return None;
        }
        let mut b = [0u8; NAV_RECORD_BYTES];
        self.left -= 1;
        self.index += 1;
        Some(match self.r.read_exact(&mut b) {
            Ok(()) => Ok(decode(&b)),
            Err(source) => {
                // nothing more after a read error
                self.left = 0;
                Err(IoError::Read {
                    path: self.path.clone(),
                    line: self.index,
                    source,
                })
            }
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.left, Some(self.left))
    }
}

/// Writes a [`NavFile`] record by record.
struct NavWriter {
    folder: TempFolder,
    path: PathBuf,
    w: BufWriter<File>,
    len: usize,
    first_t_s: Option<f64>,
    last_t_s: Option<f64>,
}

impl NavWriter {
    fn create(folder: &TempFolder, name: &str) -> Result<Self, IoError> {
        let path = folder.path().join(format!("{name}.nav.bin"));
        let f = File::create(&path).map_err(|source| IoError::Open {
            path: path.clone(),
            source,
        })?;
        Ok(Self {
            folder: folder.clone(),
            path,
            w: BufWriter::with_capacity(64 * 1024, f),
            len: 0,
            first_t_s: None,
            last_t_s: None,
        })
    }

    fn werr(&self, source: std::io::Error) -> IoError {
        IoError::Write {
            path: self.path.clone(),
            source,
        }
    }

    fn push(&mut self, s: &NavSolution) -> Result<(), IoError> {
        self.w.write_all(&encode(s)).map_err(|e| self.werr(e))?;
        self.len += 1;
        self.first_t_s.get_or_insert(s.t_s);
        self.last_t_s = Some(s.t_s);
        Ok(())
    }

    fn finish(mut self) -> Result<NavFile, IoError> {
        self.w.flush().map_err(|e| self.werr(e))?;
        Ok(NavFile {
            folder: self.folder,
            path: self.path,
            len: self.len,
            first_t_s: self.first_t_s,
            last_t_s: self.last_t_s,
        })
    }
}

/// The sink of a diagnosis run with its navigation: the records to a [`NavFile`] without their
/// standard deviations (NaN: `nav_*.txt`, the metrics and the search read none, and the
/// attitude sigmas cost a matrix inverse per record), innovation records and
/// outage snapshots in memory; of the epoch records (recorded only when the run's options ask
/// for them: a model with a GNSS error state, [`search_recording`](crate::search_recording))
/// the time and the state estimates.
struct SpillSink {
    nav: NavWriter,
    innovations: Vec<InnovationRecord>,
    snapshots: Vec<OutageSnapshot>,
    estimates: Vec<(f64, Vec<f64>)>,
    wants_epochs: bool,
}

impl RunSink for SpillSink {
    fn nav(&mut self, s: &NavSolution) -> Result<(), RunError> {
        self.nav.push(s).map_err(RunError::Output)
    }
    fn epoch(&mut self, r: EpochRecord) -> Result<(), RunError> {
        if self.wants_epochs {
            self.estimates.push((r.t_s, r.estimates));
        }
        Ok(())
    }
    fn innovation(&mut self, r: &InnovationRecord) -> Result<(), RunError> {
        self.innovations.push(*r);
        Ok(())
    }
    fn snapshot(&mut self, s: &OutageSnapshot) {
        self.snapshots.push(*s);
    }
    fn wants_epochs(&self) -> bool {
        self.wants_epochs
    }
    fn wants_nav_std(&self) -> bool {
        // nothing the diagnosis writes or computes reads them (nav_*.txt has no sigmas)
        false
    }
}

/// The sink of a run the search reads only the innovations of (and, for a model with a GNSS
/// error state, the state estimates of its epoch records: [`predict_withheld_fixes`]).
#[derive(Default)]
struct InnovationsOnly {
    innovations: Vec<InnovationRecord>,
    estimates: Vec<(f64, Vec<f64>)>,
    wants_epochs: bool,
}

impl RunSink for InnovationsOnly {
    fn nav(&mut self, _s: &NavSolution) -> Result<(), RunError> {
        Ok(())
    }
    fn epoch(&mut self, r: EpochRecord) -> Result<(), RunError> {
        if self.wants_epochs {
            self.estimates.push((r.t_s, r.estimates));
        }
        Ok(())
    }
    fn innovation(&mut self, r: &InnovationRecord) -> Result<(), RunError> {
        self.innovations.push(*r);
        Ok(())
    }
    fn wants_epochs(&self) -> bool {
        self.wants_epochs
    }
    fn wants_nav_std(&self) -> bool {
        false
    }
}

/// Whether a run of `opts` records the epochs whose estimates predict its withheld fixes: a
/// model with a GNSS error state whose options ask for epoch records.
fn wants_gnss_error(opts: &RunOptions) -> bool {
    opts.record.epoch_rate_hz.is_none_or(|r| r > 0.0)
        && crate::prior::carried(opts, nav_core::model::Block::GnssPositionGm)
}

/// A run of `opts` on `case` keeping only its innovation records (in the returned summary;
/// its `nav`, `epochs` and `snapshots` empty): what the noise trials, the bias-step fit and
/// the re-tuning read of a run, in memory proportional to the fixes. The same records and
/// errors as [`nav_engine::run::run_filter`]'s.
pub fn run_innovations(case: &Case, opts: &RunOptions) -> Result<RunOutput, RunError> {
    // the same model on the same data asked for before ([`crate::memo`])
    let key = crate::memo::RunMemo::key(case, opts);
    if let Some(out) = case.memo().innovations(&key) {
        return Ok(out);
    }
    let mut sink = InnovationsOnly {
        wants_epochs: wants_gnss_error(opts),
        ..InnovationsOnly::default()
    };
    // no navigation records: the sink drops them (the filter is the same at any rate)
    let mut no_nav = opts.clone();
    no_nav.record.nav_rate_hz = Some(0.0);
    let opts = &no_nav;
    let mut out = run_case(case, opts, &mut sink)?;
    out.innovations = sink.innovations;
    predict_withheld(&mut out, &sink.estimates, opts);
    case.memo().keep_innovations(key, &out);
    Ok(out)
}

/// A full-rate run of `opts` on `case` (every navigation record, as `host-sim run` records
/// them) with its navigation in the file `name` of `folder`: the run's summary (its `nav`
/// and `epochs` empty, its innovations and snapshots kept), the records and the metrics
/// (with the coasting baselines), the same as [`nav_engine::run::execute::execute_case`]'s.
pub fn run_to_file(
    case: &Case,
    opts: &RunOptions,
    folder: &TempFolder,
    name: &str,
) -> Result<(RunOutput, NavFile, Metrics), DiagnoseError> {
    let (out, nav) = run_nav_to_file(case, opts, folder, name)?;
    let m = metrics_of(case, &out, &nav, true)?;
    Ok((out, nav, m))
}

/// A run of `opts` on `case` with its navigation records in the file `name` of `folder`
/// (the run's summary: its `nav` and `epochs` empty, its innovations and snapshots kept).
pub fn run_nav_to_file(
    case: &Case,
    opts: &RunOptions,
    folder: &TempFolder,
    name: &str,
) -> Result<(RunOutput, NavFile), RunError> {
    let mut sink = SpillSink {
        nav: NavWriter::create(folder, name).map_err(RunError::Output)?,
        innovations: Vec::new(),
        snapshots: Vec::new(),
        estimates: Vec::new(),
        wants_epochs: wants_gnss_error(opts),
    };
    let mut out = run_case(case, opts, &mut sink)?;
    out.innovations = sink.innovations;
    out.snapshots = sink.snapshots;
    predict_withheld(&mut out, &sink.estimates, opts);
    let nav = sink.nav.finish().map_err(RunError::Output)?;
    Ok((out, nav))
}

/// Runs `opts` on `case` into `sink`: the IMU record decoded as it is read, the case's fixes
/// and truth, no coasting baselines. Returns the run's summary (its record lists empty).
fn run_case(case: &Case, opts: &RunOptions, sink: &mut dyn RunSink) -> Result<RunOutput, RunError> {
    let (it, info) = case.imu.stream()?;
    let streams = Streams {
        imu: it,
        info,
        gnss: Box::new(case.gnss.iter().copied().map(Ok)),
        truth: case.truth.as_deref(),
    };
    nav_engine::run::run_engine(streams, opts, CoastPlan::default(), sink, &mut |_, _| {})
}

/// The withheld fixes of `out`'s innovations predicted with the run's GNSS error estimate
/// (`estimates`: time, every state's estimate; nothing changes without the
/// `gnss_position_gm` block), as [`predict_withheld_fixes`] does.
fn predict_withheld(out: &mut RunOutput, estimates: &[(f64, Vec<f64>)], opts: &RunOptions) {
    let track = gnss_error_track(&out.state_names, estimates);
    predict_withheld_fixes(
        &mut out.innovations,
        &track,
        opts.filter.effects.gnss_position_gm.t_s,
    );
}

/// The GNSS error estimate of a model with the `gnss_position_gm` block over a run: (time, s;
/// N, E, D error, m) of each epoch record of `estimates` (time, every state's estimate in the
/// order of `state_names`); empty without the block.
pub fn gnss_error_track(
    state_names: &[String],
    estimates: &[(f64, Vec<f64>)],
) -> Vec<(f64, [f64; 3])> {
    let name = format!("{}_x", nav_core::model::Block::GnssPositionGm.name());
    let Some(i) = state_names.iter().position(|n| *n == name) else {
        return Vec::new();
    };
    estimates
        .iter()
        .filter_map(|(t, e)| Some((*t, [*e.get(i)?, *e.get(i + 1)?, *e.get(i + 2)?])))
        .collect()
}

/// Makes each withheld fix's innovation of `innovations` the fix against its prediction by
/// the model: with a
/// GNSS error state (`track`: [`gnss_error_track`]; nothing to do when empty) a fix is
/// predicted as the antenna position plus the error the model expects it to carry, the
/// estimate of the last epoch record before it decayed with the correlation time `tau_s`
/// (the filter's own prediction inside a withheld window, where no fix updates it). The
/// engine records a withheld fix against the antenna position alone, as it does for a model
/// without the state; the fixes the filter used are already innovations of the full model.
pub fn predict_withheld_fixes(
    innovations: &mut [InnovationRecord],
    track: &[(f64, [f64; 3])],
    tau_s: f64,
) {
    if track.is_empty() {
        return;
    }
    for r in innovations
        .iter_mut()
        .filter(|r| r.used == FixUse::Withheld)
    {
        let i = track.partition_point(|(t, _)| *t <= r.t_s);
        let Some((t, e)) = i.checked_sub(1).and_then(|i| track.get(i)) else {
            continue;
        };
        let decay = if tau_s > 0.0 {
            (-(r.t_s - t) / tau_s).exp()
        } else {
            0.0
        };
        for (x, e) in r.innovation.iter_mut().zip(e) {
            *x -= decay * e;
        }
    }
}

/// The metrics of a run whose navigation is in `nav` (`run`'s own `nav` unused), as
/// [`nav_engine::run::execute::execute_case`] computes them (`coasting`: with the coasting
/// baselines through the outages) or [`metrics::compute`] (without): against the case's
/// truth when it has one (read with the records), else against the withheld fixes.
pub fn metrics_of(
    case: &Case,
    run: &RunOutput,
    nav: &NavFile,
    coasting: bool,
) -> Result<Metrics, IoError> {
    let truth = case.truth.as_deref();
    let mut residuals = ResidualAcc::default();
    for r in &run.innovations {
        residuals.push(r);
    }
    let mut samples = SampleAcc::new(&run.outages);
    match truth {
        Some(tr) => {
            let mut m = TruthMatcher::new(tr.iter().copied());
            for s in nav.records()? {
                m.push(&s?, |e| samples.push(&e));
            }
        }
        None => {
            let withheld =
                metrics::errors_vs_fixes(run.innovations.iter(), |r| r.used == FixUse::Withheld);
            for e in &withheld {
                samples.push(e);
            }
        }
    }
    let mut m = metrics::assemble(run, &residuals, &samples, truth.is_some(), Vec::new());
    if coasting && !run.snapshots.is_empty() {
        let coast = |mode| coast_outages_with(&case.gnss, run, mode, |k| case.imu.samples_from(k));
        let raw = coast(CoastMode::Raw);
        m.coasting.push(metrics::coasting_metrics(
            "raw: no sensor-error correction",
            &raw,
            &run.outages,
            truth,
        ));
        if let Some(b) = run.init.static_gyro_bias_radps {
            let c = ImuCorrection {
                gyro_bias_radps: b,
                ..ImuCorrection::default()
            };
            let st = coast(CoastMode::Fixed(Box::new(c)));
            m.coasting.push(metrics::coasting_metrics(
                "static gyro bias only",
                &st,
                &run.outages,
                truth,
            ));
        }
    }
    Ok(m)
}

/// The records of `nav` a search run keeps once scored: the first one and, for each of
/// `innovations`, the one nearest its fix time (as [`crate::stats`] picks it in the
/// whole list). Reads the file twice, holding its times (8 bytes a record) meanwhile.
pub fn nav_at_fixes(
    nav: &NavFile,
    innovations: &[InnovationRecord],
) -> Result<Vec<NavSolution>, IoError> {
    let times: Vec<f64> = nav
        .records()?
        .map(|r| r.map(|s| s.t_s))
        .collect::<Result<_, _>>()?;
    let mut keep = vec![false; times.len()];
    if let Some(k) = keep.first_mut() {
        *k = true;
    }
    for r in innovations {
        let i = super::stats::nearest(&times, r.t_s, |t| *t);
        if let Some(k) = i.and_then(|i| keep.get_mut(i)) {
            *k = true;
        }
    }
    drop(times);
    let mut out = Vec::new();
    for (r, k) in nav.records()?.zip(keep) {
        let s = r?;
        if k {
            out.push(s);
        }
    }
    Ok(out)
}

/// Removes a run's file before the folder goes (a search run's, once scored).
pub fn remove(nav: NavFile) {
    // the folder's removal at the end takes it if this fails
    let _ = std::fs::remove_file(&nav.path);
}
