//! The files a streamed run reads while the filter runs ([`super::prepare::load`] with
//! `stream_imu`, [`super::execute::execute_streaming`]): the IMU ([`ImuStream`]) and the GNSS
//! fixes ([`GnssStream`]), each either a text file (case directories, KF-GINS
//! configurations) or the file a run configuration names, read through
//! [`RunConfig::open_imu`] / [`RunConfig::open_gnss`] (any format they read: IMU text or CSV
//! with tick clocks, tag files and the mounting rotation; GNSS text, CSV, NMEA, UBX, RTKLIB
//! `.pos`, with the quality filter).
//!
//! What a loaded run learns from the whole data before the filter starts, a streamed one gets
//! from short separate reads: the first IMU time (a given initial state, the outage times),
//! the last one only when periodic outages need it (a full pass, nothing kept), the GNSS
//! file's errors, count, week, warnings and drops (a check pass over the fixes, nothing kept),
//! and the mounting check ([`read_prefix`]: the first [`MOUNTING_PREFIX_S`] of IMU
//! data and the fixes of that span). The IMU gap report of the loaded description is not
//! made up front: the engine's IMU guard reports the gaps as it meets them (run summary,
//! `metrics.json` `imu`).

use crate::mounting::{ImuInput, MountingCheck, MountingChecker};
use anyhow::bail;
use nav_core::types::{GnssFix, ImuSample};
use nav_io::runcfg::GnssReadSummary;
use nav_io::{GnssTextReader, ImuFileKind, ImuTextReader, IoError, RunConfig};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// A run configuration and the folder its relative paths are resolved against.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigFiles {
    /// The configuration.
    pub config: Arc<RunConfig>,
    /// Its folder.
    pub dir: PathBuf,
}

/// Where a streamed run's IMU samples come from.
#[derive(Debug, Clone, PartialEq)]
pub enum ImuFile {
    /// An IMU text file (plain or gzip), increments as in the file.
    Text(PathBuf),
    /// The IMU file of a run configuration ([`RunConfig::open_imu`]: increments in body axes,
    /// the configuration's time offsets applied).
    Config(ConfigFiles),
}

/// IMU samples with their 1-based file lines, as a reader yields them.
pub type ImuLines = Box<dyn Iterator<Item = Result<(ImuSample, usize), IoError>>>;

impl ImuFile {
    /// The file.
    pub fn path(&self) -> PathBuf {
        match self {
            Self::Text(p) => p.clone(),
            Self::Config(c) => RunConfig::resolve(&c.dir, &c.config.imu.path),
        }
    }

    /// Opens the file (read from its start).
    pub fn open(&self) -> Result<ImuLines, IoError> {
        Ok(match self {
            Self::Text(p) => Box::new(ImuTextReader::open(p)?),
            Self::Config(c) => Box::new(c.config.open_imu(&c.dir)?),
        })
    }

    /// True when each increment covers the whole interval since the previous sample even
    /// across a time gap (see [`nav_io::ImuOrigin::increments_span_gaps`]): what the reader
    /// says (`ImuFileReader::increments_span_gaps`: CSV rate logs), known from the
    /// configuration without opening the file (a tagged CSV's opening reads it whole).
    pub fn increments_span_gaps(&self) -> bool {
        match self {
            Self::Text(_) => false,
            Self::Config(c) => c.config.imu.format == ImuFileKind::Csv,
        }
    }

    /// Time of the first sample and, when `last` is asked, of the last one (the whole file
    /// is read then, nothing kept; otherwise the second value is the first time too).
    pub fn time_span(&self, last: bool) -> anyhow::Result<(f64, f64)> {
        let mut rd = self.open()?;
        let Some(first) = rd.next().transpose()? else {
            bail!("no IMU samples in {}", self.path().display());
        };
        let t0 = first.0.t_s;
        let mut t1 = t0;
        if last {
            for r in rd {
                t1 = r?.0.t_s;
            }
        }
        Ok((t0, t1))
    }
}

/// An IMU file the run streams instead of loading ([`super::prepare::load`]), and the GNSS
/// file streamed with it.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuStream {
    /// How it is read (its path and gap convention: [`ImuFile::path`],
    /// [`ImuFile::increments_span_gaps`]).
    pub file: ImuFile,
    /// Offset added to every time stamp, s ([`super::prepare::RunSpec::imu_time_offset_s`];
    /// a configuration's own offsets are applied by its reader).
    pub time_offset_s: f64,
    /// The GNSS file read while the filter runs (then `prepared.case.gnss` is empty); None:
    /// the fixes are in `prepared.case.gnss`.
    pub gnss: Option<GnssStream>,
    /// The mounting check made on the run's own reading of the IMU file
    /// ([`super::prepare::load_checking_in_run`]); None: made before the run
    /// ([`read_prefix`]) or not at all.
    pub mounting: Option<MountingTap>,
}

impl ImuStream {
    /// The IMU file `file`, no extra time offset, no GNSS stream.
    pub fn new(file: ImuFile) -> Self {
        Self {
            file,
            time_offset_s: 0.0,
            gnss: None,
            mounting: None,
        }
    }
}

/// Where a streamed run's GNSS fixes come from.
#[derive(Debug, Clone, PartialEq)]
pub enum GnssFile {
    /// A GNSS text file (plain or gzip), 7 or 13 fields per line.
    Text(PathBuf),
    /// The GNSS file of a run configuration ([`RunConfig::open_gnss`]: quality filter and
    /// `[gnss] time_offset_s` applied).
    Config(ConfigFiles),
}

/// GNSS fixes as a reader yields them.
pub type Fixes = Box<dyn Iterator<Item = Result<GnssFix, IoError>>>;

impl GnssFile {
    /// Opens the file (read from its start); the fixes as in the file (sigmas not scaled).
    pub fn open(&self) -> Result<Fixes, IoError> {
        Ok(match self {
            Self::Text(p) => Box::new(GnssTextReader::open(p)?),
            Self::Config(c) => Box::new(c.config.open_gnss(&c.dir)?),
        })
    }

    /// The file.
    pub fn path(&self) -> PathBuf {
        match self {
            Self::Text(p) => p.clone(),
            Self::Config(c) => RunConfig::resolve(&c.dir, &c.config.gnss.path),
        }
    }
}

/// A GNSS file the run streams instead of loading ([`ImuStream::gnss`]): read once by
/// [`super::prepare::load`] to check it (the reader's errors before the run starts, nothing
/// kept), then again while the filter runs.
#[derive(Debug, Clone, PartialEq)]
pub struct GnssStream {
    /// How it is read (its path: [`GnssFile::path`]).
    pub file: GnssFile,
    /// Fixes in the file (counted by the check), after the quality filter.
    pub fixes: usize,
    /// What the check pass learnt besides the fixes: the GPS week the file states, the
    /// records dropped by the quality filter, the reader's warnings (empty for text files).
    pub summary: GnssReadSummary,
}

impl GnssStream {
    /// Checks a GNSS text file (parsed to its end, nothing kept) and counts its fixes.
    pub fn check(path: &Path) -> anyhow::Result<Self> {
        Self::check_file(GnssFile::Text(path.to_path_buf()))
    }

    /// Checks the GNSS file of a run configuration (read to its end through
    /// [`RunConfig::open_gnss`], nothing kept): its fixes counted, its summary kept.
    pub fn check_config(c: ConfigFiles) -> anyhow::Result<Self> {
        Self::check_file(GnssFile::Config(c))
    }

    fn check_file(file: GnssFile) -> anyhow::Result<Self> {
        fn count(rd: impl Iterator<Item = Result<GnssFix, IoError>>) -> Result<usize, IoError> {
            rd.map(|r| r.map(|_| 1)).sum()
        }
        let (fixes, summary) = match &file {
            GnssFile::Text(p) => (count(GnssTextReader::open(p)?)?, GnssReadSummary::default()),
            GnssFile::Config(c) => {
                let mut rd = c.config.open_gnss(&c.dir)?;
                (count(&mut rd)?, rd.summary().clone())
            }
        };
        Ok(Self {
            file,
            fixes,
            summary,
        })
    }

    /// The fixes as the engine's stream, as in the file (the engine applies
    /// [`super::RunOptions::gnss_sigma_scale`]).
    pub fn source(&self) -> Result<super::FixSource<'static>, super::RunError> {
        let rd = self.file.open().map_err(super::RunError::Input)?;
        Ok(Box::new(rd.map(|r| r.map_err(super::RunError::Input))))
    }
}

/// Seconds of IMU data, from the first sample, that the mounting check of a streamed run
/// reads ([`read_prefix`]).
pub const MOUNTING_PREFIX_S: f64 = 600.0;

/// What [`read_prefix`] learnt of the start of a streamed run's files.
#[derive(Debug, Clone, PartialEq)]
pub struct Prefix {
    /// Time of the first IMU sample, s (the configuration's offsets applied, not the run's
    /// extra one).
    pub first_t_s: f64,
    /// The mounting check on the prefix ([`crate::mounting::check_mounting`]: mounting,
    /// units, sample rate, GNSS time offset); its warnings end with those about a last line
    /// cut short in the IMU or GNSS file ([`nav_io::incomplete_last_line`]: a log still being
    /// written, whose last line the readers drop).
    pub mounting: MountingCheck,
}

/// Reads the start of a streamed run's files in a pass of its own before the run: the first
/// IMU time, and the mounting check on the first [`MOUNTING_PREFIX_S`] of the IMU file and the
/// fixes of that span (`gnss`: the streamed GNSS file, or else the fixes in memory) with
/// memory bounded by the check's own window ([`MountingChecker`]). The IMU as the
/// configuration gives it (the run's extra `--imu-time-offset` is not applied, as the loaded
/// check does not), the fixes unscaled. Errors opening the IMU file or in its first sample
/// are returned; a read error after that ends the pass quietly (the check covers what came
/// before it): the run itself reports it, with the outputs up to it.
pub fn read_prefix(
    imu: &ImuFile,
    gnss: Option<&GnssFile>,
    fixes_in_memory: &[GnssFix],
) -> anyhow::Result<Prefix> {
    let mut samples = imu.open()?;
    let Some(first) = samples.next().transpose()? else {
        bail!("no IMU samples in {}", imu.path().display());
    };
    let first_t_s = first.0.t_s;
    let mut c = PrefixCheck::new(
        imu_input(imu),
        first_t_s + MOUNTING_PREFIX_S,
        prefix_fixes(gnss, fixes_in_memory),
    );
    let rest = samples.map_while(Result::ok).map(|(s, _)| s);
    for s in std::iter::once(first.0).chain(rest) {
        if !c.push_imu(&s) {
            break;
        }
    }
    let mut mounting = c.finish();
    mounting.warnings.extend(cut_lines(imu, gnss));
    Ok(Prefix {
        first_t_s,
        mounting,
    })
}

/// What the IMU file holds, for the mounting check's warnings.
fn imu_input(imu: &ImuFile) -> ImuInput {
    match imu {
        ImuFile::Config(c) if c.config.imu.format == ImuFileKind::Csv => ImuInput::CsvRates,
        _ => ImuInput::Increments,
    }
}

/// The fixes the mounting check reads: the streamed GNSS file's (read up to its first error;
/// none when it cannot be opened), or else those in memory.
fn prefix_fixes<'a>(
    gnss: Option<&GnssFile>,
    fixes_in_memory: &'a [GnssFix],
) -> Box<dyn Iterator<Item = GnssFix> + 'a> {
    match gnss {
        Some(f) => match f.open() {
            Ok(rd) => Box::new(rd.map_while(Result::ok)),
            Err(_) => Box::new(std::iter::empty()),
        },
        None => Box::new(fixes_in_memory.iter().copied()),
    }
}

/// The warnings about a last line cut short in the IMU or GNSS file
/// ([`nav_io::incomplete_last_line`]).
pub(crate) fn cut_lines(imu: &ImuFile, gnss: Option<&GnssFile>) -> Vec<String> {
    let files = std::iter::once(imu.path()).chain(gnss.map(GnssFile::path));
    // a file that cannot be read here is reported by its reader
    files
        .filter_map(|p| nav_io::incomplete_last_line(&p).ok().flatten())
        .map(|cut| cut.to_string())
        .collect()
}

/// The mounting check over the IMU samples up to `end_s` and the fixes up to it, fed one
/// sample at a time ([`MountingChecker`], the fixes up to each sample pushed first).
struct PrefixCheck<'a> {
    c: MountingChecker,
    end_s: f64,
    fixes: Box<dyn Iterator<Item = GnssFix> + 'a>,
    ahead: Option<GnssFix>,
}

impl<'a> PrefixCheck<'a> {
    fn new(input: ImuInput, end_s: f64, fixes: Box<dyn Iterator<Item = GnssFix> + 'a>) -> Self {
        Self {
            c: MountingChecker::for_input(input),
            end_s,
            fixes,
            ahead: None,
        }
    }

    /// Takes the sample `s` (as the configuration gives it) when it is within the prefix;
    /// false when it is after it (not taken: the check is complete).
    fn push_imu(&mut self, s: &ImuSample) -> bool {
        if s.t_s > self.end_s {
            return false;
        }
        // the fixes up to this sample first (the checker's contract)
        while let Some(g) = self.ahead.take().or_else(|| self.fixes.next()) {
            if g.t_s <= s.t_s {
                self.c.push_fix(&g);
            } else {
                self.ahead = Some(g);
                break;
            }
        }
        self.c.push_imu(s);
        true
    }

    /// The check, with the fixes after the last sample taken up to the prefix end.
    fn finish(mut self) -> MountingCheck {
        for g in self.ahead.take().into_iter().chain(&mut self.fixes) {
            if g.t_s > self.end_s {
                break;
            }
            self.c.push_fix(&g);
        }
        self.c.finish()
    }
}

/// The mounting check of a streamed run made on the run's own reading of the IMU file
/// instead of a pass of its own before the run ([`read_prefix`]): the reader thread feeds it
/// the samples of the first [`MOUNTING_PREFIX_S`] as it parses them (the configuration's
/// times, before the run's extra offset), with the fixes of that span read beside them, and
/// leaves the result here once it has passed the prefix or stopped before its end (the check
/// then covers what was read, as [`read_prefix`] after a read error). The same check, bit
/// for bit, as [`read_prefix`] makes when the run reads the prefix; nothing is held but the
/// checker's own window.
#[derive(Debug, Clone)]
pub struct MountingTap {
    input: ImuInput,
    end_s: f64,
    gnss: Option<GnssFile>,
    /// The fixes of the prefix when they are in memory (no streamed GNSS file).
    fixes: Arc<[GnssFix]>,
    result: Arc<Mutex<Option<MountingCheck>>>,
}

impl PartialEq for MountingTap {
    /// The same tap (its result shared), not an equal one.
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.result, &other.result)
    }
}

impl MountingTap {
    /// A tap for the IMU file `imu` whose first sample is at `first_t_s` (s, the
    /// configuration's times), checked against the streamed GNSS file `gnss` or else the
    /// fixes in memory.
    pub fn new(
        imu: &ImuFile,
        first_t_s: f64,
        gnss: Option<&GnssFile>,
        fixes_in_memory: &[GnssFix],
    ) -> Self {
        let end_s = first_t_s + MOUNTING_PREFIX_S;
        let fixes: Arc<[GnssFix]> = match gnss {
            Some(_) => Arc::from(Vec::new()),
            None => fixes_in_memory
                .iter()
                .copied()
                .take_while(|g| g.t_s <= end_s)
                .collect(),
        };
        Self {
            input: imu_input(imu),
            end_s,
            gnss: gnss.cloned(),
            fixes,
            result: Arc::new(Mutex::new(None)),
        }
    }

    /// The check once the run has read the prefix (or stopped): None before.
    pub fn result(&self) -> Option<MountingCheck> {
        self.result.lock().ok().and_then(|r| r.clone())
    }

    /// A check fed by `observe` (one call per sample read, in order) that leaves its result
    /// in the tap when it is complete or dropped.
    pub(crate) fn start(&self) -> TapCheck {
        TapCheck {
            check: Some(self.prefix_check()),
            result: Arc::clone(&self.result),
        }
    }

    /// The check on a pass of its own over the prefix of `imu` (the file this tap was made
    /// for), as [`read_prefix`] makes it before a run, without the cut-line warnings: for a
    /// run that stopped before its own reading completed the check (an initialisation that
    /// failed, perhaps for what the check names). The tap's result is left as it is.
    pub fn check_on_own_pass(&self, imu: &ImuFile) -> anyhow::Result<MountingCheck> {
        let mut c = self.prefix_check();
        for s in imu.open()?.map_while(Result::ok).map(|(s, _)| s) {
            if !c.push_imu(&s) {
                break;
            }
        }
        Ok(c.finish())
    }

    /// A fresh check over the prefix with this tap's fixes.
    fn prefix_check(&self) -> PrefixCheck<'static> {
        let fixes = Arc::clone(&self.fixes);
        let it: Box<dyn Iterator<Item = GnssFix>> = match &self.gnss {
            Some(f) => prefix_fixes(Some(f), &[]),
            None => Box::new((0..fixes.len()).filter_map(move |i| fixes.get(i).copied())),
        };
        PrefixCheck::new(self.input, self.end_s, it)
    }
}

/// A [`MountingTap`]'s check in the reader thread.
pub(crate) struct TapCheck {
    check: Option<PrefixCheck<'static>>,
    result: Arc<Mutex<Option<MountingCheck>>>,
}

impl TapCheck {
    /// Feeds the sample `s` (the configuration's times); after the prefix the check is
    /// completed and further samples cost one branch.
    #[inline]
    pub(crate) fn observe(&mut self, s: &ImuSample) {
        if let Some(c) = &mut self.check {
            if !c.push_imu(s) {
                self.complete();
            }
        }
    }

    fn complete(&mut self) {
        if let Some(c) = self.check.take() {
            let m = c.finish();
            if let Ok(mut r) = self.result.lock() {
                *r = Some(m);
            }
        }
    }
}

impl Drop for TapCheck {
    fn drop(&mut self) {
        self.complete();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A configuration of `format` ("text" or "csv") over `imu` in `dir`.
    fn files(dir: &Path, format: &str) -> ConfigFiles {
        let csv = "[imu.csv]\nskip_lines = 0\ngyro_unit = \"rad/s\"\naccel_unit = \"m/s^2\"\n\
                   convention = \"interval_mean\"\n[imu.csv.columns]\ntime = 1\n\
                   gyro = [2, 3, 4]\naccel = [5, 6, 7]\n[imu.csv.time]\nkind = \"seconds\"\n";
        let text = format!(
            "name = \"t\"\n[imu]\npath = \"imu.{format}\"\nformat = \"{format}\"\n{}\
             [gnss]\npath = \"gnss.txt\"\nformat = \"text\"\n\
             [init]\npos_std_m = [1.0, 1.0, 1.0]\nvel_std_mps = [0.1, 0.1, 0.1]\n\
             att_std_deg = [1.0, 1.0, 1.0]\n[init.align]\nstatic_s = 10.0\n\
             [noise]\nmodel = \"n\"\n[noise.accel]\nn_ug_per_sqrt_hz = 100.0\n\
             [noise.gyro]\nn_deg_per_s_per_sqrt_hz = 0.005\n",
            if format == "csv" { csv } else { "" }
        );
        let config = nav_io::parse_run_config(&dir.join("run.toml"), &text).unwrap();
        ConfigFiles {
            config: Arc::new(config),
            dir: dir.to_path_buf(),
        }
    }

    #[test]
    fn the_configurations_gap_convention_and_first_time_without_the_reader_say_what_it_says() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(
            d.join("imu.text"),
            "100.00 0 0 0 0 0 -0.098\n100.01 0 0 0 0 0 -0.098\n100.02 0 0 0 0 0 -0.098\n",
        )
        .unwrap();
        std::fs::write(
            d.join("imu.csv"),
            "100.00,0,0,0,0,0,-9.8\n100.01,0,0,0,0,0,-9.8\n100.02,0,0,0,0,0,-9.8\n",
        )
        .unwrap();
        for format in ["text", "csv"] {
            let c = files(d, format);
            let reader = c.config.open_imu(d).unwrap();
            let f = ImuFile::Config(c.clone());
            assert_eq!(f.increments_span_gaps(), reader.increments_span_gaps());
            assert_eq!(f.increments_span_gaps(), format == "csv");
            assert_eq!(f.path(), reader.path());
            let times: Vec<f64> = reader.map(|r| r.unwrap().0.t_s).collect();
            let (a, b) = f.time_span(true).unwrap();
            assert_eq!((a, b), (times[0], *times.last().unwrap()), "{format}");
            assert_eq!(f.time_span(false).unwrap(), (a, a));
            let st = ImuStream::new(f);
            assert_eq!(st.file.increments_span_gaps(), format == "csv");
            assert!(st.file.path().ends_with(format!("imu.{format}")));
        }
    }
}
