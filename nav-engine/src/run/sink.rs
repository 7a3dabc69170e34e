//! The file sink of a streaming run: `nav.txt`, `std.txt`, `bias.txt` and `innovations.txt`
//! written (as `NAME.partial`, see [`super::output::write_all`]) while the filter runs,
//! and the metrics computed online ([`crate::metrics::SampleAcc`]): memory independent of
//! the record's length. What it keeps: running sums (overall, outside the outages, per outage,
//! GNSS residuals), while an outage's coasting track is open, that track, and the truth (when
//! there is one) as a stream read as the solution advances ([`super::truth::TruthFeed`]:
//! one record ahead, and the records inside an outage until its coasting tracks are in).
//!
//! The text of every file is the one [`super::output`] writes from a [`super::RunOutput`]
//! (same functions per line): `nav.txt` is byte-identical to the in-memory path.
//!
//! The formatting and writing run on a writer thread of their own: the records go to it in
//! batches of [`BATCH`] through a bounded channel (at most [`QUEUE`] batches in flight, so the
//! memory stays bounded; the writer hands the emptied batches back for reuse), and the filter
//! thread only computes the metrics. A write error stops
//! the writer; the filter thread sees it at its next batch (or at [`FileSink::finish`]).

use super::coast::CoastTrack;
use super::engine::{RunHead, RunSink};
use super::output::{self, PARTIAL_SUFFIX};
use super::truth::{TruthFeed, TruthSource};
use super::{
    solution_is_finite, EpochRecord, FixUse, InnovationRecord, Outage, OutageSnapshot, RunError,
};
use crate::metrics::{self, Metrics, OutageMetrics, SampleAcc, TruthMatcher};
use nav_core::types::NavSolution;
use nav_io::IoError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::JoinHandle;

/// Records per message to the writer thread.
pub const BATCH: usize = 512;
/// Batches in flight between the filter thread and the writer thread.
pub const QUEUE: usize = 4;

/// A buffered file that counts the bytes written (to cut it back after a fault).
struct Out {
    path: PathBuf,
    w: BufWriter<File>,
    n: u64,
    /// Length before the first non-finite record (cut there after a fault).
    cut: Option<u64>,
}

/// Bytes of `nav.txt` between two early write-backs ([`Syncer`]).
const SYNC_EVERY_BYTES: u64 = 16 << 20;

/// Starts the disk write-back of a file while it is being written: a thread of its own
/// calls `sync_data` on a clone of the handle each time it is asked (at most one request
/// waiting, further ones dropped while it is busy), so the final `sync_all` before the
/// rename only has the last part to write instead of the whole file. The thread only waits
/// on the disk; the data written and the final `sync_all` are unchanged.
struct Syncer {
    tx: Option<SyncSender<()>>,
    thread: Option<JoinHandle<()>>,
    next_at: u64,
}

impl Syncer {
    /// For `f` (a failed clone or thread start leaves the write-back to the final sync).
    fn new(f: &File) -> Self {
        let mut s = Self {
            tx: None,
            thread: None,
            next_at: SYNC_EVERY_BYTES,
        };
        if let Ok(f) = f.try_clone() {
            let (tx, rx) = sync_channel::<()>(1);
            if let Ok(h) = std::thread::Builder::new()
                .name("run-sync".into())
                .spawn(move || {
                    for () in rx {
                        // an error here shows again at the final sync_all, which reports it
                        let _ = f.sync_data();
                    }
                })
            {
                s.tx = Some(tx);
                s.thread = Some(h);
            }
        }
        s
    }

    /// Asks for a write-back when `written` bytes have gone out since the last request.
    fn poke(&mut self, written: u64) {
        if written >= self.next_at {
            self.next_at = written + SYNC_EVERY_BYTES;
            if let Some(tx) = &self.tx {
                let _ = tx.try_send(());
            }
        }
    }

    /// Stops the thread (after its current write-back).
    fn stop(&mut self) {
        self.tx = None;
        if let Some(h) = self.thread.take() {
            let _ = h.join();
        }
    }
}

impl Drop for Syncer {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A writer that counts the bytes that went through it (a line formatted straight into the
/// file's buffer, no intermediate line vector).
struct Counted<'a, W: Write> {
    w: &'a mut W,
    n: &'a mut u64,
}

impl<W: Write> Write for Counted<'_, W> {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        let k = self.w.write(b)?;
        *self.n += k as u64;
        Ok(k)
    }

    fn write_all(&mut self, b: &[u8]) -> std::io::Result<()> {
        self.w.write_all(b)?;
        *self.n += b.len() as u64;
        Ok(())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.w.flush()
    }
}

impl Out {
    fn create(path: PathBuf) -> Result<Self, RunError> {
        let f = super::outdir::create_new_file(&path).map_err(|source| {
            RunError::Output(IoError::Open {
                path: path.clone(),
                source,
            })
        })?;
        Ok(Self {
            path,
            w: BufWriter::with_capacity(1 << 16, f),
            n: 0,
            cut: None,
        })
    }

    fn err(&self, source: std::io::Error) -> RunError {
        RunError::Output(IoError::Write {
            path: self.path.clone(),
            source,
        })
    }

    fn write(&mut self, b: &[u8]) -> Result<(), RunError> {
        self.w.write_all(b).map_err(|e| self.err(e))?;
        self.n += b.len() as u64;
        Ok(())
    }

    /// Flushes, cuts back to the first non-finite record when `cut`, syncs.
    fn finish(mut self, cut: bool) -> Result<PathBuf, RunError> {
        self.w.flush().map_err(|e| self.err(e))?;
        let f = self.w.get_ref();
        if cut {
            if let Some(c) = self.cut {
                f.set_len(c).map_err(|e| self.err(e))?;
            }
        }
        f.sync_all().map_err(|e| self.err(e))?;
        Ok(self.path)
    }
}

/// A record for the writer thread (88 bytes: the `nav.txt` line's numbers, the rarer
/// records boxed).
enum Rec {
    /// A line of `nav.txt`: its numbers ([`nav_io::text::nav_line_values`]) and whether the
    /// solution is finite ([`solution_is_finite`]).
    Nav([f64; 10], bool),
    /// A line of `std.txt` and of `bias.txt` (the header of `bias.txt` before the first).
    Epoch(Box<EpochRecord>),
    /// A line of `innovations.txt`.
    Inn(Box<InnovationRecord>),
    /// Raw bytes for `std.txt` (its header).
    StdRaw(Vec<u8>),
}

// a batch of records stays small (the common `Nav` record is not padded to a rare one's size)
const _: () = assert!(std::mem::size_of::<Rec>() <= 88);

/// The files and their formatting, owned by the writer thread.
struct Writer {
    week: u16,
    nav: Out,
    /// Early write-back of `nav.txt` (the big one).
    nav_sync: Syncer,
    std: Out,
    bias: Out,
    inn: Out,
    bias_head: bool,
    line: Vec<u8>,
    /// The `nav.txt` lines not yet written: formatted in place into a block, written to the
    /// file when it is full and at the end ([`Writer::flush_nav`]).
    nav_block: Box<nav_io::BlockBuf>,
}

impl Writer {
    fn rec(&mut self, r: &Rec) -> Result<(), RunError> {
        let mut l = std::mem::take(&mut self.line);
        l.clear();
        let res = match r {
            Rec::Nav(v, finite) => self.nav_line(v, *finite),
            Rec::Epoch(e) => self.epoch_lines(&mut l, e),
            Rec::Inn(i) => output::innovation_line(&mut l, i)
                .map_err(|e| self.inn.err(e))
                .and_then(|()| self.inn.write(&l)),
            Rec::StdRaw(b) => self.std.write(b),
        };
        self.line = l;
        res
    }

    fn nav_line(&mut self, v: &[f64; 10], finite: bool) -> Result<(), RunError> {
        if self.nav.cut.is_none() && !finite {
            // the bytes written plus those still in the block
            self.nav.cut = Some(self.nav.n + self.nav_block.pending() as u64);
        }
        let Out { w, n, .. } = &mut self.nav;
        let r = nav_io::text::push_nav_values(
            &mut *self.nav_block,
            &mut Counted { w, n },
            self.week,
            v,
        );
        r.map_err(|e| self.nav.err(e))?;
        self.nav_sync.poke(self.nav.n);
        Ok(())
    }

    /// Writes the `nav.txt` lines still in the block to the file's buffer.
    fn flush_nav(&mut self) -> Result<(), RunError> {
        let Out { w, n, .. } = &mut self.nav;
        let r = self.nav_block.flush(&mut Counted { w, n });
        r.map_err(|e| self.nav.err(e))
    }

    fn epoch_lines(&mut self, l: &mut Vec<u8>, r: &EpochRecord) -> Result<(), RunError> {
        if !solution_is_finite(&r.nav) {
            if self.std.cut.is_none() {
                self.std.cut = Some(self.std.n);
            }
            if self.bias.cut.is_none() {
                self.bias.cut = Some(self.bias.n);
            }
        }
        if !self.bias_head {
            output::bias_header(l, Some(r)).map_err(|e| self.bias.err(e))?;
            self.bias.write(l)?;
            l.clear();
            self.bias_head = true;
        }
        output::std_line(l, r).map_err(|e| self.std.err(e))?;
        self.std.write(l)?;
        l.clear();
        output::bias_line(l, r).map_err(|e| self.bias.err(e))?;
        self.bias.write(l)
    }
}

/// Writes the outputs of a run as it goes (on a writer thread) and computes its metrics
/// online (on the caller's thread).
pub struct FileSink<'a> {
    dir: PathBuf,
    /// Records not yet sent to the writer.
    batch: Vec<Rec>,
    tx: Option<SyncSender<Vec<Rec>>>,
    /// Emptied batches handed back by the writer (their memory reused, not allocated anew).
    spent: Receiver<Vec<Rec>>,
    writer: Option<JoinHandle<Result<Writer, RunError>>>,
    residuals: metrics::ResidualAcc,
    /// The solution against the truth, read as it advances (None: no truth).
    truth: Option<TruthMatcher<TruthFeed<'a>>>,
    samples: SampleAcc,
    outages: Vec<Outage>,
    coasting: [Option<Vec<OutageMetrics>>; 2],
    nav_count: u64,
    last_nav_t: f64,
    nav_rate_hz: Option<f64>,
    nav_dec: Option<super::Decimator>,
}

/// Names of the coasting modes of [`super::engine::CoastPlan`] (index = mode).
pub const COAST_MODE_NAMES: [&str; 2] =
    ["raw: no sensor-error correction", "static gyro bias only"];

impl<'a> FileSink<'a> {
    /// Opens the `.partial` files in `dir` (created new: a file or link under such a name is
    /// replaced, never written through; a run writes into the stage folder of an
    /// [`super::outdir::OutDir`]). `outages` must be the
    /// run's outages and `truth` the reference when there is one (its records in time order,
    /// read as the solution advances; a slice in memory is `slice.iter().copied().map(Ok)`).
    /// `nav_rate_hz`: rate of `nav.txt` (None: every record; the metrics always see every
    /// record).
    pub fn create(
        dir: &Path,
        week: u16,
        nav_rate_hz: Option<f64>,
        outages: &[Outage],
        truth: Option<TruthSource<'a>>,
    ) -> Result<Self, RunError> {
        std::fs::create_dir_all(dir).map_err(|source| {
            RunError::Output(IoError::Write {
                path: dir.to_path_buf(),
                source,
            })
        })?;
        let [p_nav, p_std, p_bias, p_inn, _] =
            output::OUTPUT_NAMES.map(|n| output::partial_path(dir, n));
        let mut outages = outages.to_vec();
        super::outage::normalise(&mut outages).map_err(RunError::Options)?;
        let mut inn = Out::create(p_inn)?;
        let mut head = Vec::new();
        output::innovations_header(&mut head).map_err(|e| inn.err(e))?;
        inn.write(&head)?;
        let nav = Out::create(p_nav)?;
        let nav_sync = Syncer::new(nav.w.get_ref());
        let mut w = Writer {
            week,
            nav,
            nav_sync,
            std: Out::create(p_std)?,
            bias: Out::create(p_bias)?,
            inn,
            bias_head: false,
            line: Vec::with_capacity(256),
            nav_block: nav_io::BlockBuf::boxed(),
        };
        let (tx, rx) = sync_channel::<Vec<Rec>>(QUEUE);
        // at most QUEUE + 2 batches exist at once: the returned ones fit without waiting
        let (spent_tx, spent) = sync_channel::<Vec<Rec>>(QUEUE + 2);
        let writer = std::thread::Builder::new()
            .name("run-writer".into())
            .spawn(move || {
                for mut batch in rx {
                    for r in &batch {
                        w.rec(r)?;
                    }
                    batch.clear();
                    // dropped when the filter thread has enough (or is gone)
                    let _ = spent_tx.try_send(batch);
                }
                w.flush_nav()?;
                Ok(w)
            })
            .map_err(|source| {
                RunError::Output(IoError::Write {
                    path: dir.to_path_buf(),
                    source,
                })
            })?;
        Ok(Self {
            dir: dir.to_path_buf(),
            batch: Vec::with_capacity(BATCH),
            tx: Some(tx),
            spent,
            writer: Some(writer),
            residuals: metrics::ResidualAcc::default(),
            truth: truth.map(|t| TruthMatcher::new(TruthFeed::new(t, &outages))),
            samples: SampleAcc::new(&outages),
            outages,
            coasting: [None, None],
            nav_count: 0,
            last_nav_t: f64::NAN,
            nav_rate_hz: nav_rate_hz.filter(|r| *r > 0.0),
            nav_dec: None,
        })
    }

    /// Queues `r` for the writer (sends the batch when full).
    fn push(&mut self, r: Rec) -> Result<(), RunError> {
        self.batch.push(r);
        if self.batch.len() >= BATCH {
            self.send()?;
        }
        Ok(())
    }

    /// Sends the pending records to the writer; its error if it has stopped.
    fn send(&mut self) -> Result<(), RunError> {
        if self.batch.is_empty() {
            return Ok(());
        }
        let next = self
            .spent
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(BATCH));
        let b = std::mem::replace(&mut self.batch, next);
        let sent = match &self.tx {
            Some(tx) => tx.send(b).is_ok(),
            None => false,
        };
        if sent {
            Ok(())
        } else {
            // the writer stopped: its error
            self.join().map(|_| ())
        }
    }

    /// Closes the channel and waits for the writer: the files (flushed by nothing yet) or the
    /// writer's error.
    fn join(&mut self) -> Result<Writer, RunError> {
        self.tx = None;
        let gone = || {
            RunError::Output(IoError::Write {
                path: self.dir.clone(),
                source: std::io::Error::other("the output writer thread stopped"),
            })
        };
        match self.writer.take() {
            Some(h) => h.join().map_err(|_| gone())?,
            None => Err(gone()),
        }
    }

    /// After a complete run: reads the rest of the truth file (nothing kept) and returns its
    /// read error, so that a truth file is checked to its end as when it was loaded whole.
    pub fn check_truth_rest(&mut self) -> Result<(), RunError> {
        match &mut self.truth {
            Some(m) => m.source_mut().check_rest().map_err(RunError::Input),
            None => Ok(()),
        }
    }

    /// Truth records the sink holds (read ahead, and kept for the outages' coasting
    /// metrics), count.
    pub fn truth_held(&self) -> usize {
        self.truth.as_ref().map_or(0, |m| m.source().held())
    }

    /// Navigation records written to `nav.txt`.
    pub fn nav_count(&self) -> u64 {
        self.nav_count
    }

    /// Time of the last navigation record, s (NaN before the first).
    pub fn last_nav_t(&self) -> f64 {
        self.last_nav_t
    }

    /// Closes the files (cut back to the first non-finite record when `fault`), computes the
    /// metrics of `run` (the engine's summary) and writes `metrics.json` with `json` (which
    /// turns the metrics into the file's text). Complete runs get their final names.
    pub fn finish(
        mut self,
        run: &super::RunOutput,
        fault: Option<&str>,
        json: impl FnOnce(&Metrics) -> anyhow::Result<String>,
    ) -> anyhow::Result<Metrics> {
        self.send()?;
        let w = self.join()?;
        let coasting = std::mem::take(&mut self.coasting);
        let m = metrics::assemble(
            run,
            &self.residuals,
            &self.samples,
            self.truth.is_some(),
            if fault.is_some() {
                Vec::new()
            } else {
                coasting
                    .into_iter()
                    .zip(COAST_MODE_NAMES)
                    .filter_map(|(v, n)| Some((n.to_string(), v?)))
                    .collect()
            },
        );
        let cut = fault.is_some();
        let mut w = w;
        w.nav_sync.stop();
        let mut bias = w.bias;
        if !w.bias_head {
            let mut h = Vec::new();
            output::bias_header(&mut h, None).map_err(|e| bias.err(e))?;
            bias.write(&h)?;
        }
        // the four files flushed, cut and synced to disk at the same time (one thread each;
        // the disk waits overlap), metrics.json written meanwhile; errors reported in the
        // order of the files, as one after the other would
        let p_met = output::partial_path(&self.dir, "metrics.json");
        let outs = [(w.nav, cut), (w.std, cut), (bias, cut), (w.inn, false)];
        let (finished, met) = std::thread::scope(|sc| {
            let handles = outs.map(|(o, c)| sc.spawn(move || o.finish(c)));
            let met = json(&m).and_then(|text| {
                super::outdir::create_new_file(&p_met)
                    .and_then(|mut f| f.write_all(text.as_bytes()).and_then(|()| f.sync_all()))
                    .map_err(|source| {
                        anyhow::Error::from(IoError::Write {
                            path: p_met.clone(),
                            source,
                        })
                    })
            });
            let finished = handles.map(|h| {
                h.join().unwrap_or_else(|_| {
                    Err(RunError::Output(IoError::Write {
                        path: self.dir.clone(),
                        source: std::io::Error::other("finishing an output file failed"),
                    }))
                })
            });
            (finished, met)
        });
        let mut paths = Vec::with_capacity(5);
        for f in finished {
            paths.push(f?);
        }
        met?;
        paths.push(p_met);
        if fault.is_none() {
            for p in &paths {
                let s = p.to_string_lossy();
                let fin = PathBuf::from(s.strip_suffix(PARTIAL_SUFFIX).unwrap_or(&s));
                std::fs::rename(p, &fin).map_err(|source| IoError::Write {
                    path: fin.clone(),
                    source,
                })?;
            }
        }
        Ok(m)
    }
}

impl Drop for FileSink<'_> {
    /// Stops the writer (if [`FileSink::finish`] did not) and waits for it.
    fn drop(&mut self) {
        self.tx = None;
        if let Some(h) = self.writer.take() {
            let _ = h.join();
        }
    }
}

impl RunSink for FileSink<'_> {
    fn start(&mut self, head: &RunHead<'_>) -> Result<(), RunError> {
        let mut l = Vec::new();
        output::std_header(&mut l, head.model, head.state_names).map_err(|source| {
            RunError::Output(IoError::Write {
                path: self.dir.clone(),
                source,
            })
        })?;
        if let Some(m) = &mut self.truth {
            m.source_mut().set_coast_modes(head.coast_modes);
        }
        self.push(Rec::StdRaw(l))
    }

    fn nav(&mut self, s: &NavSolution) -> Result<(), RunError> {
        if let Some(m) = &mut self.truth {
            let acc = &mut self.samples;
            m.push(s, |e| acc.push(&e));
            if let Some(e) = m.source_mut().take_err() {
                return Err(RunError::Input(e));
            }
        }
        let rate = self.nav_rate_hz;
        let dec = self
            .nav_dec
            .get_or_insert_with(|| super::Decimator::new(rate, s.t_s));
        if !dec.take(s.t_s) {
            return Ok(());
        }
        self.push(Rec::Nav(
            nav_io::text::nav_line_values(s),
            solution_is_finite(s),
        ))?;
        self.nav_count += 1;
        self.last_nav_t = s.t_s;
        Ok(())
    }

    fn epoch(&mut self, r: EpochRecord) -> Result<(), RunError> {
        self.push(Rec::Epoch(Box::new(r)))
    }

    /// `nav.txt` and the metrics read no standard deviation of a navigation record
    /// (`std.txt` takes them from the epoch records).
    fn wants_nav_std(&self) -> bool {
        false
    }

    fn innovation(&mut self, r: &InnovationRecord) -> Result<(), RunError> {
        self.push(Rec::Inn(Box::new(*r)))?;
        self.residuals.push(r);
        if self.truth.is_none() && r.used == FixUse::Withheld {
            for e in metrics::errors_vs_fixes(std::iter::once(r), |_| true) {
                self.samples.push(&e);
            }
        }
        Ok(())
    }

    fn snapshot(&mut self, s: &OutageSnapshot) {
        if let Some(m) = &mut self.truth {
            m.source_mut().outage_reached(s.outage);
        }
    }

    fn coast(&mut self, mode: usize, track: CoastTrack) {
        let per = match &mut self.truth {
            Some(m) => {
                let feed = m.source_mut();
                let per = metrics::coasting_track_metrics(
                    &track,
                    &self.outages,
                    Some(feed.outage_window(track.outage)),
                );
                feed.track_done(track.outage);
                per
            }
            None => metrics::coasting_track_metrics(&track, &self.outages, None),
        };
        if let Some(slot) = self.coasting.get_mut(mode) {
            slot.get_or_insert_with(Vec::new).extend(per);
        }
    }
}
