//! The diagnosis's IMU record in a temporary file instead of memory ([`ImuCache`]:
//! [`IMU_RECORD_BYTES`] a sample): the record is decoded once (from the IMU file of the
//! configuration, or from the samples of a case in memory) into fixed-size little-endian
//! records holding exactly the values the filter uses and the file line of each sample, and
//! every run of the diagnosis streams from it ([`ImuView::stream`]). The data a model runs on
//! is the record through an [`Adjust`]ment applied as the samples are read: a bias step
//! removed ([`super::changepoint::BiasStep`]), the times moved onto the GNSS clock (a held
//! time offset), instead of a corrected copy of the record. The diagnosis's [`Case`] is the
//! view with the fixes (and the truth, when given) in memory.
//!
//! The file lives in the diagnosis's temporary folder ([`super::spill::TempFolder`]) and
//! goes with it: at the end, on an error, and on SIGINT/SIGTERM (the reads notice a
//! requested stop, [`nav_engine::run::interrupt::requested`], and end with an error; the
//! command then removes the folder and exits with `128 + signal`).

use std::fs::File;
use std::io::{BufWriter, ErrorKind, Read, Seek, SeekFrom, Write};
use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nav_core::types::ImuSample;
use nav_engine::run::prepare::{Loaded, Prepared};
use nav_engine::run::{interrupt, CaseData, ImuItem, ImuSourceInfo, RunError, RunOptions};
use nav_io::IoError;

use super::changepoint::BiasStepSensor;
use super::memo::RunMemo;
use super::spill::TempFolder;

/// Bytes of one sample in an [`ImuCache`]: time (s), angle increments (rad), velocity
/// increments (m/s), temperature (degC, NaN when absent) as 8 f64, and the 1-based file line
/// (u64, 0 when unknown), little-endian: the sample read back bit for bit.
pub const IMU_RECORD_BYTES: usize = 8 * 8 + 8;

/// Samples read between two looks at a requested stop.
const STOP_CHECK_SAMPLES: usize = 4096;

/// Samples of one read of the record file ([`CacheReader`]): 72 KiB.
pub const READ_BLOCK_SAMPLES: usize = 1024;

fn encode(s: &ImuSample, line: usize) -> [u8; IMU_RECORD_BYTES] {
    let mut b = [0u8; IMU_RECORD_BYTES];
    let f = s.to_values();
    let (vals, l) = b.split_at_mut(64);
    for (dst, v) in vals.chunks_exact_mut(8).zip(f) {
        dst.copy_from_slice(&v.to_le_bytes());
    }
    l.copy_from_slice(&(line as u64).to_le_bytes());
    b
}

fn decode(b: &[u8; IMU_RECORD_BYTES]) -> (ImuSample, usize) {
    let mut f = [0.0f64; 8];
    for (v, src) in f.iter_mut().zip(b.chunks_exact(8)) {
        let mut x = [0u8; 8];
        x.copy_from_slice(src);
        *v = f64::from_le_bytes(x);
    }
    let mut l = [0u8; 8];
    l.copy_from_slice(&b[64..]);
    let s = ImuSample::from_values(f);
    (s, usize::try_from(u64::from_le_bytes(l)).unwrap_or(0))
}

/// The error of a stop requested by SIGINT/SIGTERM while the record is read.
fn stopped(path: &Path, sig: i32) -> IoError {
    IoError::Read {
        path: path.to_path_buf(),
        line: 0,
        source: std::io::Error::new(
            ErrorKind::Interrupted,
            format!("{}: stopped", interrupt::signal_name(sig)),
        ),
    }
}

/// The decoded IMU record in a file of fixed-size records ([`IMU_RECORD_BYTES`]) in the
/// diagnosis's temporary folder, with what the diagnosis asks of the whole record.
#[derive(Debug)]
pub struct ImuCache {
    /// Keeps the folder (and so the file) alive.
    folder: TempFolder,
    path: PathBuf,
    len: usize,
    first_t_s: Option<f64>,
    first_temperature_c: Option<f64>,
    info: ImuSourceInfo,
}

impl ImuCache {
    /// Writes `samples` (with their 1-based file lines, 0 when unknown) into the file
    /// `imu.bin` of `folder`; `info`: where they come from (messages, the gap rule). A read
    /// error of `samples` is returned as it is (it names the input file and line); memory is a
    /// write buffer whatever the length.
    pub fn write(
        folder: &TempFolder,
        samples: impl Iterator<Item = Result<(ImuSample, usize), IoError>>,
        info: ImuSourceInfo,
    ) -> Result<Self, IoError> {
        let path = folder.path().join("imu.bin");
        let werr = |source| IoError::Write {
            path: path.clone(),
            source,
        };
        let f = File::create(&path).map_err(werr)?;
        let mut w = BufWriter::with_capacity(64 * 1024, f);
        let mut len = 0usize;
        let mut first_t_s = None;
        let mut first_temperature_c = None;
        for r in samples {
            if len.is_multiple_of(STOP_CHECK_SAMPLES) {
                if let Some(sig) = interrupt::requested() {
                    return Err(stopped(&path, sig));
                }
            }
            let (s, line) = r?;
            w.write_all(&encode(&s, line)).map_err(werr)?;
            len += 1;
            first_t_s.get_or_insert(s.t_s);
            if first_temperature_c.is_none() && s.temperature_c.is_finite() {
                first_temperature_c = Some(s.temperature_c);
            }
        }
        w.flush().map_err(werr)?;
        Ok(Self {
            folder: folder.clone(),
            path,
            len,
            first_t_s,
            first_temperature_c,
            info,
        })
    }

    /// The samples of a case in memory, with their file lines and source as
    /// [`nav_engine::run::case_imu_stream`] gives them to a run.
    pub fn from_case(folder: &TempFolder, case: &CaseData) -> Result<Self, IoError> {
        let (it, info) = nav_engine::run::case_imu_stream(case);
        // the in-memory stream yields no errors
        let samples = it.filter_map(Result::ok).map(|i| Ok((i.sample, i.line)));
        Self::write(folder, samples, info)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.len
    }

    /// The temporary folder the file is in (kept alive by the cache).
    pub fn folder(&self) -> &TempFolder {
        &self.folder
    }

    /// True without samples.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Time of the first sample, s.
    pub fn first_t_s(&self) -> Option<f64> {
        self.first_t_s
    }

    /// Temperature of the first sample that has one, degC (None: no temperature column).
    pub fn first_temperature_c(&self) -> Option<f64> {
        self.first_temperature_c
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Where the samples come from.
    pub fn info(&self) -> &ImuSourceInfo {
        &self.info
    }

    /// The samples from index `from` on, with their file lines, read from the file in blocks
    /// of [`READ_BLOCK_SAMPLES`] (a buffer of memory whatever the length); a read error names
    /// the file.
    pub fn read_from(&self, from: usize) -> Result<CacheReader, IoError> {
        let rerr = |source| IoError::Read {
            path: self.path.clone(),
            line: 0,
            source,
        };
        let mut f = File::open(&self.path).map_err(|source| IoError::Open {
            path: self.path.clone(),
            source,
        })?;
        let from = from.min(self.len);
        if from > 0 {
            f.seek(SeekFrom::Start((from * IMU_RECORD_BYTES) as u64))
                .map_err(rerr)?;
        }
        Ok(CacheReader {
            f,
            block: Vec::new(),
            end: 0,
            pos: 0,
            path: self.path.clone(),
            first: from,
            left: self.len - from,
            read: 0,
        })
    }

    /// `file line N` of sample `index` (or `IMU sample index` when its line is unknown), as
    /// [`CaseData::locate_imu`] says it.
    pub fn locate(&self, index: usize) -> String {
        let line = self
            .read_from(index)
            .ok()
            .and_then(|mut r| r.next())
            .and_then(Result::ok)
            .map_or(0, |(_, l)| l);
        self.info.locate(index, line)
    }
}

/// The samples of an [`ImuCache`] (with their file lines), read from the file a block of
/// [`READ_BLOCK_SAMPLES`] at a time and decoded one by one.
pub struct CacheReader {
    f: File,
    /// The block read last: its whole records are `block[..end]`.
    block: Vec<u8>,
    /// End of the whole records in `block`, bytes.
    end: usize,
    /// Offset of the next record in `block`, bytes.
    pos: usize,
    path: PathBuf,
    /// Index of the first sample read.
    first: usize,
    /// Samples not yet returned.
    left: usize,
    /// Samples returned.
    read: usize,
}

impl CacheReader {
    /// Reads the next block: at most [`READ_BLOCK_SAMPLES`] records, no more than are left,
    /// as many whole records as the file holds (an error when it ends before the next one:
    /// the records before it are returned first).
    fn refill(&mut self) -> std::io::Result<()> {
        let want = self.left.min(READ_BLOCK_SAMPLES) * IMU_RECORD_BYTES;
        // the block's buffer zeroed once, at its first fill (not at every block)
        if self.block.len() < want {
            self.block.resize(want, 0);
        }
        self.pos = 0;
        self.end = 0;
        let mut got = 0;
        while got < want {
            match self.block.get_mut(got..want).map(|b| self.f.read(b)) {
                Some(Ok(0)) | None => break,
                Some(Ok(n)) => got += n,
                Some(Err(e)) if e.kind() == ErrorKind::Interrupted => {}
                Some(Err(e)) => return Err(e),
            }
        }
        let whole = got - got % IMU_RECORD_BYTES;
        self.end = whole;
        if whole == 0 {
            let k = self.first + self.read;
            return Err(std::io::Error::new(
                ErrorKind::UnexpectedEof,
                format!(
                    "the file ends before sample {k} (byte offset {}): {} sample(s) missing",
                    k * IMU_RECORD_BYTES,
                    self.left
                ),
            ));
        }
        Ok(())
    }
}

impl Iterator for CacheReader {
    type Item = Result<(ImuSample, usize), IoError>;

    #[inline]
    fn next(&mut self) -> Option<Self::Item> {
        if self.left == 0 {
            return None;
        }
        if self.read.is_multiple_of(STOP_CHECK_SAMPLES) {
            if let Some(sig) = interrupt::requested() {
                self.left = 0;
                return Some(Err(stopped(&self.path, sig)));
            }
        }
        if self.pos >= self.end {
            if let Err(source) = self.refill() {
                self.left = 0;
                return Some(Err(IoError::Read {
                    path: self.path.clone(),
                    line: 0,
                    source,
                }));
            }
        }
        let rec = self
            .block
            .get(self.pos..self.pos + IMU_RECORD_BYTES)
            .and_then(|b| <&[u8; IMU_RECORD_BYTES]>::try_from(b).ok())?;
        self.pos += IMU_RECORD_BYTES;
        self.left -= 1;
        self.read += 1;
        Some(Ok(decode(rec)))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (0, Some(self.left))
    }
}

/// IMU samples as the engine's stream.
pub type ImuItems = Box<dyn Iterator<Item = Result<ImuItem, RunError>>>;

/// The adjusted samples of a view with their file lines ([`ImuView::read_from`]): each record
/// decoded and adjusted in one step.
pub struct Adjusted {
    r: CacheReader,
    /// The recorded time of the sample before the next one (the bias step's interval).
    prev: Option<f64>,
    adjust: Adjust,
}

impl Iterator for Adjusted {
    type Item = Result<(ImuSample, usize), IoError>;

    #[inline]
    fn next(&mut self) -> Option<Self::Item> {
        Some(self.r.next()?.map(|(s, line)| {
            let sample = self.adjust.apply(s, self.prev);
            self.prev = Some(s.t_s);
            (sample, line)
        }))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.r.size_hint()
    }
}

/// The adjusted samples of a view from its first one as the engine's items
/// ([`ImuView::stream`]).
struct Items(Adjusted);

impl Iterator for Items {
    type Item = Result<ImuItem, RunError>;

    fn next(&mut self) -> Option<Self::Item> {
        Some(match self.0.next()? {
            Ok((sample, line)) => Ok(ImuItem { sample, line }),
            Err(e) => Err(RunError::Input(e)),
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.0.size_hint()
    }
}

/// What a model's data changes of the recorded IMU samples, applied as they are read.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Adjust {
    /// A bias step removed: the sensor, the step time (s) and the step (SI, body axes),
    /// subtracted times the interval from that sensor's increments of every sample whose
    /// interval starts at or after the step time.
    pub bias_step: Option<(BiasStepSensor, f64, [f64; 3])>,
    /// Subtracted from every sample time after the bias step is removed, s (a time offset
    /// held: the data moved onto the GNSS clock).
    pub time_shift_s: f64,
}

impl Adjust {
    /// The sample `s` adjusted; `prev`: the recorded time of the sample before it (None for
    /// the first sample).
    pub fn apply(&self, mut s: ImuSample, prev: Option<f64>) -> ImuSample {
        if let Some((sensor, t_s, step)) = &self.bias_step {
            let start = prev.unwrap_or(s.t_s);
            let dt = s.t_s - start;
            if start >= *t_s && dt > 0.0 {
                let v: &mut [f64; 3] = match sensor {
                    BiasStepSensor::Accel => &mut s.dv_mps,
                    BiasStepSensor::Gyro => &mut s.dtheta_rad,
                };
                for (x, b) in v.iter_mut().zip(step) {
                    *x -= b * dt;
                }
            }
        }
        if self.time_shift_s != 0.0 {
            s.t_s -= self.time_shift_s;
        }
        s
    }
}

/// The IMU data a model runs on: the record in its [`ImuCache`] through an [`Adjust`]ment.
#[derive(Debug, Clone)]
pub struct ImuView {
    cache: Arc<ImuCache>,
    adjust: Adjust,
}

impl ImuView {
    /// The record as recorded.
    pub fn new(cache: Arc<ImuCache>) -> Self {
        Self {
            cache,
            adjust: Adjust::default(),
        }
    }

    /// The record.
    pub fn cache(&self) -> &ImuCache {
        &self.cache
    }

    /// The adjustment applied.
    pub fn adjust(&self) -> &Adjust {
        &self.adjust
    }

    /// The same record with another adjustment.
    pub fn with_adjust(&self, adjust: Adjust) -> Self {
        Self {
            cache: self.cache.clone(),
            adjust,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.cache.len()
    }

    /// True without samples.
    pub fn is_empty(&self) -> bool {
        self.cache.is_empty()
    }

    /// The adjusted samples from index `from` on, with their file lines (the sample before
    /// `from` is read too, for the bias step's interval).
    pub fn read_from(&self, from: usize) -> Result<Adjusted, IoError> {
        let mut r = self.cache.read_from(from.saturating_sub(1))?;
        let mut prev = None;
        if from > 0 {
            prev = r.next().transpose()?.map(|(s, _)| s.t_s);
        }
        Ok(Adjusted {
            r,
            prev,
            adjust: self.adjust,
        })
    }

    /// The adjusted samples from index `from` on; a read error ends them (the coasting
    /// baselines, [`nav_engine::run::coast_outages_with`]).
    pub fn samples_from(&self, from: usize) -> impl Iterator<Item = ImuSample> {
        let it = self.read_from(from).ok().into_iter().flatten();
        it.map_while(Result::ok).map(|(s, _)| s)
    }

    /// The samples as the engine's IMU stream (a read error ends the run with it), and
    /// where they come from.
    pub fn stream(&self) -> Result<(ImuItems, ImuSourceInfo), RunError> {
        let it = Items(self.read_from(0).map_err(RunError::Input)?);
        Ok((Box::new(it), self.cache.info().clone()))
    }

    /// Time of the first sample (adjusted), s.
    pub fn first_t_s(&self) -> Option<f64> {
        self.cache.first_t_s().map(|t| t - self.adjust.time_shift_s)
    }

    /// True when the samples carry a temperature.
    pub fn has_temperature(&self) -> bool {
        self.cache.first_temperature_c().is_some()
    }

    /// The samples the regressors at the times `t_s` (sorted) read
    /// ([`super::stats::regressor_correlation`]), in time order: the first two samples, the
    /// first with a temperature, and for each time the nearest sample (the later one on a tie)
    /// and the one before it. The nearest sample to each of `t_s` in this list is the nearest
    /// in the whole record and its predecessor there is its predecessor in the record:
    /// memory proportional to the times, one pass over the record.
    pub fn near(&self, t_s: &[f64]) -> Result<Vec<ImuSample>, IoError> {
        let mut out: Vec<ImuSample> = Vec::new();
        let mut last_kept: Option<usize> = None;
        let mut keep = |k: usize, s: Option<ImuSample>| {
            if let Some(s) = s.filter(|_| last_kept.is_none_or(|l| k > l)) {
                out.push(s);
                last_kept = Some(k);
            }
        };
        // the two samples before the current one
        let (mut p1, mut p2): (Option<ImuSample>, Option<ImuSample>) = (None, None);
        let mut ti = 0usize;
        let mut temperature_seen = false;
        let mut n = 0usize;
        for (k, r) in self.read_from(0)?.enumerate() {
            let (s, _) = r?;
            n = k + 1;
            // the times this sample is the first at or after: the nearest is it or p1
            while let Some(&t) = t_s.get(ti) {
                if s.t_s < t {
                    break;
                }
                match p1 {
                    Some(p) if (t - p.t_s).abs() < (s.t_s - t).abs() => {
                        keep(k.wrapping_sub(2), p2);
                        keep(k - 1, p1);
                    }
                    _ => {
                        keep(k.wrapping_sub(1), p1);
                        keep(k, Some(s));
                    }
                }
                ti += 1;
            }
            let first_temperature = !temperature_seen && s.temperature_c.is_finite();
            temperature_seen |= first_temperature;
            if k < 2 || first_temperature {
                keep(k.wrapping_sub(1), p1);
                keep(k, Some(s));
            }
            p2 = p1;
            p1 = Some(s);
        }
        // times after the last sample: the last one is the nearest
        if ti < t_s.len() && n > 0 {
            keep(n.wrapping_sub(2), p2);
            keep(n - 1, p1);
        }
        Ok(out)
    }
}

/// The data of a diagnosis: the fixes and the truth (when given) in memory ([`CaseData`],
/// its IMU list empty; reached through `Deref`), the IMU samples in the record's file as the
/// model sees them ([`ImuView`]).
#[derive(Debug, Clone)]
pub struct Case {
    data: CaseData,
    /// The IMU samples.
    pub imu: ImuView,
    /// The runs made on this data and its adjusted views ([`RunMemo`]).
    memo: Arc<RunMemo>,
}

impl Case {
    /// The fixes and truth of `data` (its IMU samples and origin dropped) with the IMU record
    /// `cache`, as recorded.
    pub fn new(data: CaseData, cache: Arc<ImuCache>) -> Self {
        Self {
            data: CaseData {
                imu: Vec::new(),
                imu_origin: None,
                ..data
            },
            imu: ImuView::new(cache),
            memo: Arc::default(),
        }
    }

    /// The same data with the IMU samples adjusted by `adjust` (the truth's times moved by
    /// its time shift too: the truth is on the IMU clock).
    pub fn adjusted(&self, adjust: Adjust) -> Self {
        let mut data = self.data.clone();
        let dt = adjust.time_shift_s - self.imu.adjust().time_shift_s;
        if dt != 0.0 {
            for t in data.truth.iter_mut().flatten() {
                t.t_s -= dt;
            }
        }
        Self {
            data,
            imu: self.imu.with_adjust(adjust),
            memo: self.memo.clone(),
        }
    }

    /// The runs made on this data and its adjusted views: one memo for the diagnosis's data
    /// (its key holds the adjustment).
    pub(crate) fn memo(&self) -> &RunMemo {
        &self.memo
    }

    /// `file line N` of IMU sample `index` (or `IMU sample index` without its line).
    pub fn locate_imu(&self, index: usize) -> String {
        self.imu.cache().locate(index)
    }
}

impl Deref for Case {
    type Target = CaseData;

    fn deref(&self) -> &CaseData {
        &self.data
    }
}

/// What the diagnosis runs: its data and the configuration's options.
#[derive(Debug, Clone)]
pub struct Data {
    /// The data.
    pub case: Case,
    /// The configuration's options.
    pub opts: RunOptions,
}

/// The inputs of a streamed load ([`nav_engine::run::prepare::load`] with `stream_imu`)
/// made ready for the diagnosis without the IMU samples in memory: the IMU file decoded into
/// an [`ImuCache`] in a new temporary folder (the run's `--imu-time-offset` added, as a
/// loaded case has it), the streamed fixes and the truth (when given) read into the case.
/// A loaded case (no stream) has its samples written into the cache and dropped. The
/// returned case's IMU list is empty.
pub fn load_cached(l: Loaded) -> Result<(Prepared, ImuCache), crate::DiagnoseError> {
    let folder = super::spill::temp_folder()?;
    let mut p = l.prepared;
    let imu = match &l.imu_stream {
        Some(st) => {
            let dt = st.time_offset_s;
            let samples = st.file.open()?.map(move |r| {
                r.map(|(mut s, line)| {
                    s.t_s += dt;
                    (s, line)
                })
            });
            let info = ImuSourceInfo {
                path: Some(st.file.path()),
                increments_span_gaps: st.file.increments_span_gaps(),
            };
            if let Some(g) = &st.gnss {
                p.case.gnss = g.source()?.collect::<Result<_, _>>()?;
            }
            ImuCache::write(&folder, samples, info)?
        }
        None => ImuCache::from_case(&folder, &p.case)?,
    };
    if let Some(t) = &l.truth_stream {
        p.case.truth = Some(t.open()?.collect::<Result<_, _>>()?);
    }
    p.case.imu = Vec::new();
    p.case.imu_origin = None;
    Ok((p, imu))
}
