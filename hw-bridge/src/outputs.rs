//! Output files written while a replay decodes: each file is written under a `.partial` name,
//! appended to as frames arrive and flushed at checkpoints, and renamed to its final name only
//! when the replay is finished. A killed replay leaves `*.partial` files holding everything up
//! to the last checkpoint; a file without the suffix is complete.
//!
//! The output folder is opened as a [`nav_engine::run::outdir::OutDir`] ([`open_out`]): a
//! folder holding one of the replay's inputs (the capture, the configuration and the files
//! it names, the case folder) is refused before anything is written, and so is a folder
//! another run or replay is writing into (the lock names its pid). Every file is created new
//! (a file or link under its name is replaced, never written through); the summary and the
//! filter's outputs are written in the stage folder and moved into place at the end.
//!
//! The text formats are those of `nav_io` (the same digits, byte for byte: the test
//! `streamed_outputs_equal_nav_io_writers_byte_for_byte` checks it).

use anyhow::Context;
use nav_core::types::{GnssFix, ImuSample, NavSolution};
use nav_core::wire::Health;
use nav_engine::run::outdir::{create_new_file, OutDir};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Suffix of a file still being written.
pub const PARTIAL_SUFFIX: &str = ".partial";

/// The `.partial` name of `path`.
pub fn partial_name(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_os_string();
    s.push(PARTIAL_SUFFIX);
    PathBuf::from(s)
}

/// Opens the output folder `dir` of a replay reading `capture` (and, with the filter's run
/// `filter`, the files of its configuration and case folder): see the module notes.
pub fn open_out(
    dir: &Path,
    capture: &Path,
    filter: Option<&nav_engine::RunSpec>,
) -> anyhow::Result<OutDir> {
    let mut inputs = vec![capture.to_path_buf()];
    if let Some(spec) = filter {
        inputs.extend(
            nav_engine::run::prepare::run_inputs(spec)
                .with_context(|| format!("preparing the filter from {}", spec.config.display()))?,
        );
    }
    Ok(OutDir::open(dir, &inputs)?)
}

/// Writes `contents` to `path` through its `.partial` name (created new) and a rename.
pub fn write_atomically(path: &Path, contents: &[u8]) -> anyhow::Result<()> {
    let tmp = partial_name(path);
    create_new_file(&tmp)
        .and_then(|mut f| f.write_all(contents))
        .with_context(|| format!("writing {}", tmp.display()))?;
    rename(&tmp, path)
}

/// Renames `from` to `to`.
pub fn rename(from: &Path, to: &Path) -> anyhow::Result<()> {
    std::fs::rename(from, to)
        .with_context(|| format!("renaming {} to {}", from.display(), to.display()))
}

/// One text file being appended to.
struct Stream {
    final_path: PathBuf,
    w: BufWriter<File>,
}

impl Stream {
    fn create(dir: &Path, name: &str) -> anyhow::Result<Self> {
        let final_path = dir.join(name);
        let tmp = partial_name(&final_path);
        let f = create_new_file(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
        Ok(Self {
            final_path,
            w: BufWriter::new(f),
        })
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        let p = partial_name(&self.final_path);
        self.w
            .flush()
            .with_context(|| format!("writing {}", p.display()))
    }

    fn finish(mut self) -> anyhow::Result<PathBuf> {
        self.flush()?;
        let tmp = partial_name(&self.final_path);
        rename(&tmp, &self.final_path)?;
        Ok(self.final_path)
    }
}

/// `imu.txt` written without a temperature column, rewritten with it (as
/// `nav_io::write_imu_line` writes it) into `dest`: NaN up to line `from`, then the
/// temperatures of `temps` (one per line, formatted as that writer formats them).
fn with_temperatures(
    mut imu: Stream,
    mut temps: Stream,
    from: u64,
    dest: &Path,
) -> anyhow::Result<PathBuf> {
    use std::io::BufRead;
    imu.flush()?;
    temps.flush()?;
    let (src, t_src) = (
        partial_name(&imu.final_path),
        partial_name(&temps.final_path),
    );
    drop((imu.w, temps.w));
    let open = |p: &Path| {
        File::open(p)
            .map(std::io::BufReader::new)
            .with_context(|| format!("reading {}", p.display()))
    };
    let (lines, mut t_lines) = (open(&src)?.lines(), open(&t_src)?.lines());
    let tmp = partial_name(&imu.final_path.with_extension("txt.rewrite"));
    let mut w = BufWriter::new(
        create_new_file(&tmp).with_context(|| format!("creating {}", tmp.display()))?,
    );
    for (i, line) in (0u64..).zip(lines) {
        let line = line.with_context(|| format!("reading {}", src.display()))?;
        let t = if i < from {
            "NaN".to_string()
        } else {
            t_lines
                .next()
                .transpose()
                .with_context(|| format!("reading {}", t_src.display()))?
                .unwrap_or_else(|| "NaN".to_string())
        };
        io(writeln!(w, "{line} {t}"), &imu.final_path)?;
    }
    io(w.flush(), &imu.final_path)?;
    drop(w);
    rename(&tmp, dest)?;
    if src != dest {
        std::fs::remove_file(&src).with_context(|| format!("removing {}", src.display()))?;
    }
    std::fs::remove_file(&t_src).with_context(|| format!("removing {}", t_src.display()))?;
    Ok(dest.to_path_buf())
}

/// The header line of `health.txt`.
pub const HEALTH_HEADER: &str = "# uptime_ms rx_frames_ok rx_rejected rx_crc_errors rx_lost imu_epochs gnss_updates gnss_rejected epoch_ticks_max stack_peak_bytes filter_status imu_implausible imu_gaps nhc_updates zupt_updates zaru_updates";

/// The decoded frames of a replay as text files (`imu.txt`, `gnss.txt`, `board-nav.txt`,
/// `health.txt`), each created at its first line.
pub struct FrameFiles {
    dir: PathBuf,
    imu: Option<Stream>,
    /// Whether `imu.txt` has the temperature column (decided by its first sample).
    imu_temperature: bool,
    /// Whether any IMU sample had a finite temperature (host-sim's rule for the column).
    imu_any_temperature: bool,
    /// IMU lines written.
    imu_lines: u64,
    /// While `imu.txt` has no temperature column: from the first sample with a temperature
    /// on, every sample's temperature (`imu.temperature.partial`, one per line) and the line
    /// it starts at, for the rewrite at the end.
    temps: Option<(Stream, u64)>,
    gnss: Option<Stream>,
    nav: Option<Stream>,
    health: Option<Stream>,
    checkpoint: Duration,
    last_flush: Instant,
}

fn io<T>(r: std::io::Result<T>, path: &Path) -> anyhow::Result<T> {
    r.with_context(|| format!("writing {}", partial_name(path).display()))
}

impl FrameFiles {
    /// Files in `dir` (created when missing), flushed at least every `checkpoint`.
    pub fn new(dir: &Path, checkpoint: Duration) -> anyhow::Result<Self> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            imu: None,
            imu_temperature: false,
            imu_any_temperature: false,
            imu_lines: 0,
            temps: None,
            gnss: None,
            nav: None,
            health: None,
            checkpoint,
            last_flush: Instant::now(),
        })
    }

    /// Appends an IMU sample (format of `nav_io::write_imu_text`).
    pub fn imu(&mut self, s: &ImuSample) -> anyhow::Result<()> {
        let finite_t = s.temperature_c.is_finite();
        self.imu_any_temperature |= finite_t;
        if self.imu.is_none() {
            self.imu = Some(Stream::create(&self.dir, "imu.txt")?);
            self.imu_temperature = finite_t;
        }
        let with_temp = self.imu_temperature;
        if let Some(st) = self.imu.as_mut() {
            let r = nav_io::write_imu_line(&mut st.w, s, with_temp);
            io(r, &st.final_path)?;
        }
        if !with_temp && (finite_t || self.temps.is_some()) {
            if self.temps.is_none() {
                let st = Stream::create(&self.dir, "imu.temperature")?;
                self.temps = Some((st, self.imu_lines));
            }
            if let Some((st, _)) = self.temps.as_mut() {
                let r = writeln!(st.w, "{}", s.temperature_c);
                io(r, &st.final_path)?;
            }
        }
        self.imu_lines += 1;
        self.maybe_checkpoint()
    }

    /// Appends a GNSS fix (format of `nav_io::write_gnss_text`).
    pub fn gnss(&mut self, f: &GnssFix) -> anyhow::Result<()> {
        if self.gnss.is_none() {
            self.gnss = Some(Stream::create(&self.dir, "gnss.txt")?);
        }
        if let Some(st) = self.gnss.as_mut() {
            let r = nav_io::write_gnss_line(&mut st.w, f);
            io(r, &st.final_path)?;
        }
        self.maybe_checkpoint()
    }

    /// Appends a board solution to `board-nav.txt` (format of `nav_io::write_nav_text`).
    pub fn nav(&mut self, n: &NavSolution) -> anyhow::Result<()> {
        if self.nav.is_none() {
            self.nav = Some(Stream::create(&self.dir, "board-nav.txt")?);
        }
        if let Some(st) = self.nav.as_mut() {
            let r = nav_io::write_nav_line(&mut st.w, n);
            io(r, &st.final_path)?;
        }
        self.maybe_checkpoint()
    }

    /// Appends a health frame to `health.txt`.
    pub fn health(&mut self, x: &Health) -> anyhow::Result<()> {
        if self.health.is_none() {
            let mut st = Stream::create(&self.dir, "health.txt")?;
            let r = writeln!(st.w, "{HEALTH_HEADER}");
            io(r, &st.final_path)?;
            self.health = Some(st);
        }
        if let Some(st) = self.health.as_mut() {
            let r = writeln!(
                st.w,
                "{} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {}",
                x.uptime_ms,
                x.rx_frames_ok,
                x.rx_rejected,
                x.rx_crc_errors,
                x.rx_lost,
                x.imu_epochs,
                x.gnss_updates,
                x.gnss_rejected,
                x.epoch_ticks_max,
                x.stack_peak_bytes,
                x.filter_status,
                x.imu_implausible,
                x.imu_gaps,
                x.nhc_updates,
                x.zupt_updates,
                x.zaru_updates
            );
            io(r, &st.final_path)?;
        }
        self.maybe_checkpoint()
    }

    fn maybe_checkpoint(&mut self) -> anyhow::Result<()> {
        if self.last_flush.elapsed() >= self.checkpoint {
            self.flush()?;
        }
        Ok(())
    }

    /// Flushes every file (a checkpoint: a killed replay keeps everything written so far).
    pub fn flush(&mut self) -> anyhow::Result<()> {
        for s in [
            &mut self.imu,
            &mut self.gnss,
            &mut self.nav,
            &mut self.health,
        ]
        .into_iter()
        .flatten()
        {
            s.flush()?;
        }
        self.last_flush = Instant::now();
        Ok(())
    }

    /// Flushes and renames every file to its final name. `imu` is every sample appended:
    /// when the temperature column decided by the first sample differs from host-sim's rule
    /// (any sample with a finite temperature), `imu.txt` is rewritten as host-sim's writer
    /// writes it (its lines with the temperatures kept aside).
    pub fn finish(mut self) -> anyhow::Result<Vec<PathBuf>> {
        let mut done = Vec::new();
        if let Some(st) = self.imu.take() {
            match self.temps.take() {
                None => done.push(st.finish()?),
                Some((temps, from)) => {
                    let dest = st.final_path.clone();
                    done.push(with_temperatures(st, temps, from, &dest)?);
                }
            }
        }
        for s in [self.gnss.take(), self.nav.take(), self.health.take()]
            .into_iter()
            .flatten()
        {
            done.push(s.finish()?);
        }
        Ok(done)
    }

    /// Flushes every file and leaves it under its `.partial` name (a replay stopped before
    /// the end of its capture: the files hold everything decoded so far, `imu.txt.partial`
    /// with the temperature column as [`Self::finish`] writes it). Returns the paths kept.
    pub fn keep_partial(mut self) -> anyhow::Result<Vec<PathBuf>> {
        self.flush()?;
        let mut kept = Vec::new();
        if let Some(st) = self.imu.take() {
            let dest = partial_name(&st.final_path);
            match self.temps.take() {
                None => kept.push(dest),
                Some((temps, from)) => kept.push(with_temperatures(st, temps, from, &dest)?),
            }
        }
        for s in [self.gnss.take(), self.nav.take(), self.health.take()]
            .into_iter()
            .flatten()
        {
            kept.push(partial_name(&s.final_path));
        }
        Ok(kept)
    }
}
