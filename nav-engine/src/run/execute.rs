//! Running a prepared case ([`super::prepare::Prepared`]): in memory ([`execute`]) or
//! streaming the IMU with the outputs written as the filter goes ([`execute_streaming`]).
//!
//! Outputs in the output directory: `nav.txt`, `std.txt`, `bias.txt`, `innovations.txt`,
//! `metrics.json` (against the truth when there is one, else against the withheld fixes; with
//! outages also free-inertial coasting baselines, see [`super::coast`]; and the IMU report:
//! gaps bridged, samples rejected, with file and line).
//!
//! Every output is written as `NAME.partial`, synced, and renamed to `NAME` only when all of
//! them are written: after a full disk or any write error no file under a final name
//! exists (outputs of an earlier run in the folder are removed first). A fault in the middle
//! of the data (a gap longer than the allowed one, a numerical failure, an implausible
//! sample when those stop the run) stops the run: the error names the file and line of the
//! sample, the outputs up to it stay as `*.partial` (metrics.json.partial says
//! `"complete": false` and the fault).

use super::coast::{coast_outages, CoastMode};
use super::outdir::OutDir;
use super::output;
use super::prepare::{ImuStream, Prepared};
use super::streams::ImuFile;
use super::truth::TruthFile;
use super::{CaseData, CoastPlan, FixSource, RunOptions, RunOutput, Streams};
use crate::metrics::{self, Metrics};
use anyhow::Context;
use nav_core::model::ImuCorrection;
use nav_core::types::NavSolution;
use std::path::{Path, PathBuf};

/// Runs the filter on a prepared case in memory and computes the metrics (with coasting
/// baselines when there are outages).
pub fn execute(
    p: &Prepared,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<(RunOutput, Metrics)> {
    execute_case(&p.case, &p.opts, progress)
}

/// [`execute`] on a case and options apart (the case is not copied).
pub fn execute_case(
    case: &CaseData,
    opts: &RunOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<(RunOutput, Metrics)> {
    let (out, _) = super::run_case(case, opts, CoastPlan::default(), progress)?;
    let truth = case.truth.as_deref();
    let mut m = metrics::compute(&out, truth);
    if !out.snapshots.is_empty() {
        let raw = coast_outages(case, &out, CoastMode::Raw);
        m.coasting.push(metrics::coasting_metrics(
            "raw: no sensor-error correction",
            &raw,
            &out.outages,
            truth,
        ));
        if let Some(b) = out.init.static_gyro_bias_radps {
            let c = ImuCorrection {
                gyro_bias_radps: b,
                ..ImuCorrection::default()
            };
            let st = coast_outages(case, &out, CoastMode::Fixed(Box::new(c)));
            m.coasting.push(metrics::coasting_metrics(
                "static gyro bias only",
                &st,
                &out.outages,
                truth,
            ));
        }
    }
    Ok((out, m))
}

/// Where the IMU samples and GNSS fixes of a run come from.
pub enum Source<'a> {
    /// The prepared run's files ([`ImuStream`], with its GNSS stream when it has one: read as
    /// the filter goes), or the case in memory when `None`.
    Files(Option<&'a ImuStream>),
    /// Samples and fixes pushed into a [`super::live::LiveRun`].
    Pushed(super::live::Feeds),
}

impl<'a> Source<'a> {
    /// The engine's streams over this source (`truth`: records the initialisation may start
    /// from).
    pub fn open<'b>(
        self,
        p: &'b Prepared,
        truth: Option<&'b [NavSolution]>,
    ) -> Result<Streams<'b>, super::RunError>
    where
        'a: 'b,
    {
        let case_fixes = || -> FixSource<'b> { Box::new(p.case.gnss.iter().copied().map(Ok)) };
        match self {
            Source::Files(Some(st)) => {
                let info = super::ImuSourceInfo {
                    path: Some(st.file.path()),
                    increments_span_gaps: st.file.increments_span_gaps(),
                };
                let imu = Box::new(threaded_tapped_reader(
                    st.file.clone(),
                    st.time_offset_s,
                    st.mounting.clone(),
                ));
                let gnss = match &st.gnss {
                    // the fixes read as the filter goes (memory independent of the length)
                    Some(g) => g.source()?,
                    None => case_fixes(),
                };
                Ok(Streams {
                    imu,
                    info,
                    gnss,
                    truth,
                })
            }
            Source::Files(None) => {
                let (it, info) = super::case_imu_stream(&p.case);
                Ok(Streams {
                    imu: Box::new(it),
                    info,
                    gnss: case_fixes(),
                    truth,
                })
            }
            Source::Pushed(feeds) => Ok(feeds.streams(truth)),
        }
    }
}

/// Runs the filter on a prepared case with the IMU streamed from `imu` (or from the case's
/// samples in memory when `None`), writing the outputs in `dir` as it goes
/// ([`super::sink::FileSink`]: `*.partial`, renamed when complete) and computing the metrics
/// online, with the coasting baselines. `truth`: a truth file read as the solution advances
/// ([`super::truth`]; None: the case's truth in memory, if any). `nav_rate_hz`: rate of
/// `nav.txt` (None: every IMU epoch). A fault mid-run leaves the outputs up to it as
/// `*.partial` and returns [`super::RunError::Fault`] (its `partial` holds the summary, no
/// records); so does an error reading the streamed IMU file in the middle (the error names
/// file and line; the run ends at the last sample before it, `metrics.json.partial` says
/// `"complete": false` and the error), and so does SIGINT/SIGTERM once
/// [`super::interrupt::install`] is in place (the run ends at the next IMU sample); other
/// errors leave no output.
///
/// The folder `dir` is an [`OutDir`]: refused when it holds one of `inputs` (the files the
/// run reads, [`super::prepare::Loaded::inputs`]) or when another run is writing into it;
/// the files are written in its stage folder and moved into `dir` at the end, the complete
/// outputs of an earlier run staying in place until then (an incomplete run's `*.partial`
/// files are moved in beside them).
pub fn execute_streaming(
    p: &Prepared,
    imu: Option<&ImuStream>,
    truth: Option<&TruthFile>,
    dir: &Path,
    inputs: &[PathBuf],
    nav_rate_hz: Option<f64>,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<(RunOutput, Metrics)> {
    let to = DirOutput {
        dir,
        inputs,
        nav_rate_hz,
        staged: false,
    };
    run_to_dir(p, Source::Files(imu), truth, &to, progress)
}

/// The output folder of a run and what `nav.txt` holds.
#[derive(Debug, Clone, Copy)]
pub struct DirOutput<'a> {
    /// The output folder: opened as an [`OutDir`] (stage folder, lock, moved in at the end),
    /// or written into directly when `staged`.
    pub dir: &'a Path,
    /// The files the run reads (refused as outputs).
    pub inputs: &'a [PathBuf],
    /// Rate of `nav.txt`, Hz (None: every IMU epoch).
    pub nav_rate_hz: Option<f64>,
    /// `dir` is the stage folder of an [`OutDir`] the caller holds and commits (the files
    /// are written in it under `*.partial` names, renamed when complete).
    pub staged: bool,
}

/// [`execute_streaming`] on any [`Source`]: the run's records written into `to.dir` as they
/// are made, the metrics computed online.
pub fn run_to_dir(
    p: &Prepared,
    source: Source<'_>,
    truth: Option<&TruthFile>,
    to: &DirOutput<'_>,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<(RunOutput, Metrics)> {
    let _stoppable = super::interrupt::Stoppable::enter();
    let od = if to.staged {
        None
    } else {
        Some(OutDir::open(to.dir, to.inputs)?)
    };
    let stage = od.as_ref().map_or(to.dir, |o| o.stage());
    let opts = &p.opts;
    // the truth: the metrics' stream, and the records the initialisation looks at
    let truth_file = truth;
    let start = super::truth::start_records(opts, truth_file)?;
    let truth = start.as_deref().or(p.case.truth.as_deref());
    let metrics_truth: Option<super::truth::TruthSource<'_>> = match (truth_file, &p.case.truth) {
        (Some(f), _) => Some(f.records()),
        (None, Some(v)) => Some(Box::new(v.iter().copied().map(Ok))),
        (None, None) => None,
    };
    let mut sink =
        super::sink::FileSink::create(stage, p.week, to.nav_rate_hz, &opts.outages, metrics_truth)?;
    let coast = super::CoastPlan {
        raw: true,
        static_gyro_bias: true,
    };
    // a read error of the streamed IMU ends its samples; the run up to it is kept
    let mut read_err = None;
    let res = source.open(p, truth).and_then(|mut st| {
        st.imu = Box::new(StopAtError {
            inner: st.imu,
            err: &mut read_err,
        });
        super::run_engine(st, opts, coast, &mut sink, progress)
    });
    let end = Ended {
        sink,
        od,
        dir: to.dir,
    };
    match (res, read_err) {
        // the record ended at a read error: the outputs up to it, marked incomplete
        (Ok(out), Some(e)) => Err(end.stopped(&out, e.to_string())),
        // nothing run (e.g. the file unreadable from its first sample): the read error
        (Err(super::RunError::NoImu), Some(e)) => Err(e.into()),
        (res, _) => end.conclude(res),
    }
}

/// A run's file sink and output folder once the engine has returned.
struct Ended<'s, 'd> {
    sink: super::sink::FileSink<'s>,
    od: Option<OutDir>,
    dir: &'d Path,
}

impl Ended<'_, '_> {
    fn commit(od: Option<OutDir>) -> anyhow::Result<()> {
        if let Some(od) = od {
            od.commit()?;
        }
        Ok(())
    }

    /// The outputs of a complete run, or of one the engine stopped.
    fn conclude(
        mut self,
        res: Result<RunOutput, super::RunError>,
    ) -> anyhow::Result<(RunOutput, Metrics)> {
        // a complete run: the rest of the truth file checked (as when it was loaded whole)
        let res = res.and_then(|out| self.sink.check_truth_rest().map(|()| out));
        let dir = self.dir;
        match res {
            Ok(out) => {
                let od = self.od;
                let m = self
                    .sink
                    .finish(&out, None, |m| metrics_json(m, &out, None))
                    .and_then(|m| Ok((m, Self::commit(od)?)))
                    .map(|(m, _)| m)
                    .with_context(|| {
                        format!(
                            "writing the outputs in {}: incomplete, left as *{} (no file under \
                             its final name)",
                            dir.display(),
                            output::PARTIAL_SUFFIX
                        )
                    })?;
                Ok((out, m))
            }
            Err(super::RunError::Fault {
                location,
                t_s,
                cause,
                partial,
            }) => Err(self.stopped(&partial, format!("{location} (t = {t_s:.6} s): {cause}"))),
            Err(e @ super::RunError::Output(_)) => {
                // what was written, moved in as *.partial (best effort: the disk may be full)
                drop(self.sink);
                let _ = Self::commit(self.od);
                Err(anyhow::Error::new(e).context(format!(
                    "writing the outputs in {}: incomplete, left as *{} (no file under its final \
                     name)",
                    dir.display(),
                    output::PARTIAL_SUFFIX
                )))
            }
            // the stage folder removed with `od`: the output folder as it was
            Err(e) => Err(e.into()),
        }
    }

    /// The outputs up to a fault (`*.partial`, `metrics.json` saying `"complete": false`)
    /// and the error naming it.
    fn stopped(self, out: &RunOutput, fault: String) -> anyhow::Error {
        let t_last = self.sink.last_nav_t();
        let od = self.od;
        let written = self
            .sink
            .finish(out, Some(&fault), |m| metrics_json(m, out, Some(&fault)))
            .and_then(|m| Ok((m, Self::commit(od)?)));
        match written {
            Ok(_) => anyhow::anyhow!(
                "{fault}; the run stopped there. Outputs up to t = {t_last:.3} s are in \
                 {}/*{} (incomplete)",
                self.dir.display(),
                output::PARTIAL_SUFFIX
            ),
            Err(w) => anyhow::anyhow!(
                "{fault}; the run stopped there, and writing the partial outputs failed too: \
                 {w:#}"
            ),
        }
    }
}

/// The samples of `inner` up to its first error, which is kept in `err` (the stream ends
/// there).
struct StopAtError<'a, I> {
    inner: I,
    err: &'a mut Option<super::RunError>,
}

impl<I: Iterator<Item = Result<super::ImuItem, super::RunError>>> Iterator for StopAtError<'_, I> {
    type Item = Result<super::ImuItem, super::RunError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.err.is_some() {
            return None;
        }
        if let Some(sig) = super::interrupt::requested() {
            *self.err = Some(super::RunError::Interrupted {
                signal: super::interrupt::signal_name(sig),
            });
            return None;
        }
        match self.inner.next()? {
            Ok(it) => Some(Ok(it)),
            Err(e) => {
                *self.err = Some(e);
                None
            }
        }
    }
}

/// Samples per message from the reader thread.
pub const READ_CHUNK: usize = 2048;
/// Messages in flight between the reader thread and the filter.
pub const READ_QUEUE: usize = 4;

/// The samples of an IMU text file read and parsed by a thread of their own
/// ([`threaded_file_reader`]).
pub fn threaded_imu_reader(
    path: PathBuf,
    time_offset_s: f64,
) -> impl Iterator<Item = Result<super::ImuItem, super::RunError>> {
    threaded_file_reader(ImuFile::Text(path), time_offset_s)
}

/// The samples of an IMU file (a text file, or a run configuration's file in any format it
/// reads, opened in the thread) read and parsed by a thread of their own and handed over in
/// chunks through a bounded channel (at most [`READ_QUEUE`] x [`READ_CHUNK`] samples in
/// flight): reading and parsing overlap the filter. `time_offset_s` is added to every time.
/// The thread stops at the first error (passed on after the samples before it) or when the
/// receiver is dropped.
pub fn threaded_file_reader(
    file: ImuFile,
    time_offset_s: f64,
) -> impl Iterator<Item = Result<super::ImuItem, super::RunError>> {
    threaded_tapped_reader(file, time_offset_s, None)
}

/// [`threaded_file_reader`] feeding the samples, as the file gives them, to the mounting
/// check of `tap` ([`super::streams::MountingTap`]) on the reader thread.
fn threaded_tapped_reader(
    file: ImuFile,
    time_offset_s: f64,
    tap: Option<super::streams::MountingTap>,
) -> impl Iterator<Item = Result<super::ImuItem, super::RunError>> {
    let path = file.path();
    super::reader_thread::read_in_chunks(
        "imu-reader",
        READ_CHUNK,
        READ_QUEUE,
        move || {
            let rd = file.open().map_err(super::RunError::Input)?;
            let mut check = tap.as_ref().map(super::streams::MountingTap::start);
            Ok(rd.map(move |r| match r {
                Ok((mut sample, line)) => {
                    if let Some(c) = &mut check {
                        c.observe(&sample);
                    }
                    sample.t_s += time_offset_s;
                    Ok(super::ImuItem { sample, line })
                }
                Err(e) => Err(super::RunError::Input(e)),
            }))
        },
        |source| super::RunError::Input(nav_io::IoError::Open { path, source }),
    )
}

/// `metrics.json`: the metrics, the IMU report (gaps, rejected samples) and, after a fault,
/// `"complete": false` with the fault.
pub fn metrics_json(m: &Metrics, out: &RunOutput, fault: Option<&str>) -> anyhow::Result<String> {
    #[derive(serde::Serialize)]
    struct File<'a> {
        #[serde(flatten)]
        metrics: &'a Metrics,
        imu: &'a super::ImuReport,
        complete: bool,
        #[serde(skip_serializing_if = "Option::is_none")]
        fault: Option<&'a str>,
    }
    Ok(serde_json::to_string_pretty(&File {
        metrics: m,
        imu: &out.imu_report,
        complete: fault.is_none(),
        fault,
    })?)
}

/// Lines of the run summary about the IMU data (empty when nothing happened).
pub fn imu_summary(out: &RunOutput) -> String {
    let r = &out.imu_report;
    let mut s = String::new();
    if r.gaps > 0 {
        s.push_str(&format!(
            "IMU: {} time gap(s) bridged ({} sample(s) missing at {:.4} s nominal; {} filled by \
             interpolation, {} spanned by the next increment)\n",
            r.gaps, r.missing_samples, r.nominal_dt_s, r.gaps_filled, r.gaps_spanned
        ));
    }
    if r.rejected > 0 {
        s.push_str(&format!(
            "IMU: {} sample(s) rejected as physically implausible\n",
            r.rejected
        ));
    }
    for e in r.events.iter().take(10) {
        s.push_str(&format!("  {}: {}\n", e.location, e.what));
    }
    if r.events.len() > 10 {
        s.push_str(&format!(
            "  ... {} more in metrics.json\n",
            r.events.len() - 10
        ));
    }
    s
}

/// Keeps the first record at or after each multiple of `1 / rate_hz` from the first record.
pub fn decimate(nav: &[NavSolution], rate_hz: f64) -> Vec<NavSolution> {
    let Some(first) = nav.first() else {
        return Vec::new();
    };
    let p = 1.0 / rate_hz;
    let mut next = first.t_s;
    let mut out = Vec::new();
    for s in nav {
        if s.t_s + 1e-6 * p >= next {
            out.push(*s);
            while next <= s.t_s + 1e-6 * p {
                next += p;
            }
        }
    }
    out
}
