//! The output folder of a run (`host-sim run` / `diagnose`, `hw-bridge replay`), written so
//! that nothing but the run's own outputs can change:
//!
//! - **Inputs are never outputs.** [`check_inputs`] refuses an `--out` that holds any of the
//!   run's inputs (same canonical folder, same folder identity (device, inode), or a file in
//!   `--out` that is an input under another name: a hard link), naming the input, before
//!   anything is created, written or deleted.
//! - **One run at a time.** [`OutDir::open`] takes an advisory lock on `OUT/.nav-out.lock`
//!   (`flock`: released by the system when the process ends, however it ends, so a dead
//!   run's lock never blocks) holding the owner's pid; a second run into the same folder
//!   refuses with that pid.
//! - **Staged, then moved.** The outputs are written in a fresh folder `OUT/.nav-out-stage-*`
//!   (created exclusively with mode 0700 by `mkdir`, which never goes through an existing
//!   link; its files created new), and [`OutDir::commit`] renames each file into `OUT` when the
//!   run is over. A rename replaces a link placed under an output's name instead of
//!   writing through it. The previous outputs stay in place until then.
//!
//! What a run leaves in `OUT`:
//! - complete: every output under its final name (`metrics.json` renamed last, after the
//!   old one is removed: a folder where `metrics.json` is present is complete); the
//!   `NAME.partial` files an earlier incomplete run left under those names are removed;
//! - stopped by a fault, a read error mid-run or SIGINT/SIGTERM: the outputs up to there as
//!   `NAME.partial`, with `metrics.json.partial` saying `"complete": false` and why; the
//!   previous complete outputs (final names) untouched;
//! - any other error, or killed outright (SIGKILL, a second Ctrl-C): nothing changed in
//!   `OUT`; the stage folder left behind is removed by the next run into `OUT` (under the
//!   lock, a stage folder can only be a dead run's).

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Name of the lock file in the output folder (holds the owner's pid).
pub const LOCK_NAME: &str = ".nav-out.lock";
/// Prefix of the stage folders in the output folder.
pub const STAGE_PREFIX: &str = ".nav-out-stage-";
/// Names moved into place last on [`OutDir::commit`] (their presence marks a complete run).
pub const MARKERS: [&str; 3] = ["metrics.json", "diagnosis.json", "replay-summary.txt"];

/// Why an output folder cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum OutDirError {
    /// `--out` holds one of the run's inputs.
    #[error(
        "--out {} holds the input {} ({how}): the outputs would be written over the run's own \
         inputs; choose another output location (nothing was written)",
        out.display(),
        input.display()
    )]
    HoldsInput {
        /// The output folder.
        out: PathBuf,
        /// The input it holds.
        input: PathBuf,
        /// How it was found (same folder, same file under another name).
        how: &'static str,
    },
    /// Another process is writing into the folder.
    #[error(
        "--out {}: another run (pid {pid}) is writing into this folder (lock {}); wait for it \
         to end or choose another output folder (nothing was written)",
        out.display(),
        lock.display()
    )]
    Busy {
        /// The output folder.
        out: PathBuf,
        /// The lock file.
        lock: PathBuf,
        /// The owner's pid as the lock file says it (`unknown` when unreadable).
        pid: String,
    },
    /// The lock file is not a plain file of its own (a link, a hard link, a device).
    #[error("{}: not a regular file with a single name; remove it (nothing was written)", path.display())]
    BadLock {
        /// The lock file.
        path: PathBuf,
    },
    /// The output file exists and replacing it was not asked for.
    #[error(
        "{} exists ({what}); pass --force to replace it, or choose another name (nothing was \
         written)",
        path.display()
    )]
    Exists {
        /// The output file.
        path: PathBuf,
        /// What it is (its size, or a link and where it points).
        what: String,
    },
    /// Another process is writing the same output file (it holds the lock on its
    /// `.partial` file).
    #[error(
        "{}: another process is writing this file (it holds {}); wait for it to end or choose \
         another name (nothing was written)",
        path.display(),
        partial.display()
    )]
    FileBusy {
        /// The output file.
        path: PathBuf,
        /// Its `.partial` file, locked by the other writer.
        partial: PathBuf,
    },
    /// The output file's `.partial` name holds something no process is writing: the data
    /// of an interrupted writer, or a link.
    #[error(
        "{} holds {what}; move it away (or pass --force to remove it) before writing {} \
         (nothing was written)",
        partial.display(),
        path.display()
    )]
    Leftover {
        /// The output file.
        path: PathBuf,
        /// Its `.partial` name.
        partial: PathBuf,
        /// What is there.
        what: String,
    },
    /// The output's name holds the other kind of entry: a file where a folder is written, a
    /// folder where a file is.
    #[error("{} is {what}, not {want}: choose another name (nothing was written)", path.display())]
    WrongKind {
        /// The output's name.
        path: PathBuf,
        /// What is there (its size, or a link and where it points).
        what: String,
        /// What the output is ("a folder", "a file").
        want: &'static str,
    },
    /// A file-system operation failed.
    #[error("{}: {what}: {source}", path.display())]
    Io {
        /// The path concerned.
        path: PathBuf,
        /// What was being done.
        what: &'static str,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
}

fn io_err<'a>(
    path: &'a Path,
    what: &'static str,
) -> impl FnOnce(std::io::Error) -> OutDirError + 'a {
    move |source| OutDirError::Io {
        path: path.to_path_buf(),
        what,
        source,
    }
}

/// (device, inode) of a file (unix; elsewhere nothing, and only paths are compared).
#[cfg(unix)]
fn identity(m: &std::fs::Metadata) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    Some((m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn identity(_: &std::fs::Metadata) -> Option<(u64, u64)> {
    None
}

/// Refuses an output folder `out` that holds any of `inputs` (files or folders a run reads):
/// an input whose folder is `out` (by canonical path, or by the folder's (device, inode),
/// e.g. through a bind mount), an input that is a link inside `out`, `out` itself as an
/// input, or a file in `out` that is an input under another name (a hard link). Inputs that
/// do not exist are skipped (their reader reports them). A folder that does not exist yet
/// holds nothing.
pub fn check_inputs(out: &Path, inputs: &[PathBuf]) -> Result<(), OutDirError> {
    let Ok(out_meta) = std::fs::metadata(out) else {
        return Ok(());
    };
    let out_canon = out.canonicalize().map_err(io_err(out, "resolving"))?;
    let out_id = identity(&out_meta);
    let holds = |input: &Path, how| OutDirError::HoldsInput {
        out: out.to_path_buf(),
        input: input.to_path_buf(),
        how,
    };
    // the identities of the entries of `out` (a hard link to an input has the input's)
    let mut entries = Vec::new();
    if let Ok(rd) = std::fs::read_dir(out) {
        for e in rd.flatten() {
            if let Ok(m) = std::fs::metadata(e.path()) {
                if let Some(id) = identity(&m) {
                    entries.push(id);
                }
            }
        }
    }
    for input in inputs {
        let Ok(in_meta) = std::fs::metadata(input) else {
            continue;
        };
        let in_canon = input.canonicalize().map_err(io_err(input, "resolving"))?;
        if in_canon == out_canon || (identity(&in_meta).is_some() && identity(&in_meta) == out_id) {
            return Err(holds(input, "it is the output folder itself"));
        }
        // the folder the input's name is in (a link in `out` to a file elsewhere counts)
        let named_in = input
            .parent()
            .map(|p| {
                if p.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    p
                }
            })
            .and_then(|p| p.canonicalize().ok());
        if named_in.as_deref() == Some(out_canon.as_path()) {
            return Err(holds(input, "it is in the output folder"));
        }
        if let Some(parent) = in_canon.parent() {
            if parent == out_canon {
                return Err(holds(input, "it is in the output folder"));
            }
            let pid = std::fs::metadata(parent).ok().and_then(|m| identity(&m));
            if pid.is_some() && pid == out_id {
                return Err(holds(input, "its folder is the output folder"));
            }
        }
        if let Some(id) = identity(&in_meta) {
            if in_meta.is_file() && entries.contains(&id) {
                return Err(holds(
                    input,
                    "the same file is in the output folder under another name",
                ));
            }
        }
    }
    Ok(())
}

/// Refuses an output file `out` that is the input `input` (same canonical path, or the same
/// (device, inode)); either missing: nothing to compare.
pub fn check_not_input(out: &Path, input: &Path) -> Result<(), OutDirError> {
    let (Ok(a), Ok(b)) = (std::fs::metadata(out), std::fs::metadata(input)) else {
        return Ok(());
    };
    let same_id = identity(&a).is_some() && identity(&a) == identity(&b);
    let same_path = out.canonicalize().ok() == input.canonicalize().ok();
    if same_id || same_path {
        return Err(OutDirError::HoldsInput {
            out: out.to_path_buf(),
            input: input.to_path_buf(),
            how: "the output file is the input",
        });
    }
    Ok(())
}

/// Creates `path` as a new file: whatever is under that name (a file, a link) is removed
/// first and the file is created exclusively (`O_EXCL`: an existing name, a link included,
/// is an error, never followed).
pub fn create_new_file(path: &Path) -> std::io::Result<File> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                "a folder has this name",
            ))
        }
        Ok(_) => std::fs::remove_file(path)?,
        Err(_) => {}
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
}

/// What is at `path` without following a link, for a message (None: nothing).
fn describe(path: &Path) -> Option<String> {
    let m = std::fs::symlink_metadata(path).ok()?;
    Some(if m.file_type().is_symlink() {
        match std::fs::read_link(path) {
            Ok(t) => format!("a link to {}", t.display()),
            Err(_) => "a link".to_string(),
        }
    } else if m.is_dir() {
        "a folder".to_string()
    } else if m.is_file() {
        format!("a file of {} bytes", m.len())
    } else {
        "a special file".to_string()
    })
}

/// An output file written under its `.partial` name (`NAME.partial` beside it) and moved to
/// its name by [`StagedFile::commit`]:
/// - an existing file or link under the name is refused unless `force` (then replaced by
///   the rename, a link never written through);
/// - the `.partial` file is created new (`O_EXCL`: a link there is never followed) and
///   locked (`flock`) while written: a second writer of the same name refuses; a `.partial`
///   file nobody holds (an interrupted writer's data) or a link there is refused unless
///   `force` (then removed);
/// - [`StagedFile::commit`] syncs the file and moves it to its name; without `force` a file
///   that appeared under the name meanwhile is not replaced (the data stay in `.partial`,
///   and the error says so);
/// - dropped without [`StagedFile::commit`] (an error, a kill): the `.partial` file stays,
///   holding what was written.
#[derive(Debug)]
pub struct StagedFile {
    dest: PathBuf,
    partial: PathBuf,
    force: bool,
    file: File,
}

impl StagedFile {
    /// Creates `NAME.partial` for the output file `dest` (see the type's notes).
    pub fn create(dest: &Path, force: bool) -> Result<Self, OutDirError> {
        let mut p = dest.as_os_str().to_os_string();
        p.push(".partial");
        let partial = PathBuf::from(p);
        if let Ok(m) = std::fs::symlink_metadata(dest) {
            if m.is_dir() {
                return Err(OutDirError::WrongKind {
                    path: dest.to_path_buf(),
                    what: "a folder".into(),
                    want: "a file",
                });
            }
            if !force {
                return Err(OutDirError::Exists {
                    path: dest.to_path_buf(),
                    what: describe(dest).unwrap_or_default(),
                });
            }
        }
        if let Some(what) = describe(&partial) {
            let m = std::fs::symlink_metadata(&partial).map_err(io_err(&partial, "reading"))?;
            if m.is_file() {
                // a writer holding it?
                let f = std::fs::OpenOptions::new()
                    .read(true)
                    .open(&partial)
                    .map_err(io_err(&partial, "opening"))?;
                if let Err(std::fs::TryLockError::WouldBlock) = f.try_lock() {
                    return Err(OutDirError::FileBusy {
                        path: dest.to_path_buf(),
                        partial,
                    });
                }
            }
            if !force || m.is_dir() {
                let what = if m.is_file() {
                    format!("{what}, the data of an interrupted writer")
                } else {
                    what
                };
                return Err(OutDirError::Leftover {
                    path: dest.to_path_buf(),
                    partial,
                    what,
                });
            }
            std::fs::remove_file(&partial).map_err(io_err(&partial, "removing"))?;
        }
        let mut o = std::fs::OpenOptions::new();
        o.read(true).write(true).create_new(true);
        #[cfg(unix)]
        {
            use std::os::unix::fs::OpenOptionsExt;
            o.custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC);
        }
        let file = o.open(&partial).map_err(|e| {
            if e.kind() == std::io::ErrorKind::AlreadyExists {
                // created by another writer between the look and the creation
                OutDirError::FileBusy {
                    path: dest.to_path_buf(),
                    partial: partial.clone(),
                }
            } else {
                io_err(&partial, "creating")(e)
            }
        })?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                return Err(OutDirError::FileBusy {
                    path: dest.to_path_buf(),
                    partial,
                })
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(io_err(&partial, "locking")(e)),
        }
        Ok(Self {
            dest: dest.to_path_buf(),
            partial,
            force,
            file,
        })
    }

    /// The `.partial` file being written.
    pub fn partial(&self) -> &Path {
        &self.partial
    }

    /// The output file's name.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// A handle to write the `.partial` file through (the same open file: the lock holds
    /// while either is open).
    pub fn writer(&self) -> Result<File, OutDirError> {
        self.file
            .try_clone()
            .map_err(io_err(&self.partial, "opening for writing"))
    }

    /// Syncs the `.partial` file and moves it to its name (see the type's notes).
    pub fn commit(self) -> Result<PathBuf, OutDirError> {
        self.file
            .sync_all()
            .map_err(io_err(&self.partial, "syncing"))?;
        if !self.force {
            // no replacement: a hard link fails when the name exists
            match std::fs::hard_link(&self.partial, &self.dest) {
                Ok(()) => {
                    std::fs::remove_file(&self.partial)
                        .map_err(io_err(&self.partial, "removing"))?;
                    return Ok(self.dest);
                }
                Err(_) if describe(&self.dest).is_some() => {
                    return Err(OutDirError::Exists {
                        path: self.dest.clone(),
                        what: format!(
                            "{}, which appeared while writing; the new data are kept in {}",
                            describe(&self.dest).unwrap_or_default(),
                            self.partial.display()
                        ),
                    })
                }
                // a file system without hard links: the rename below
                Err(_) => {}
            }
        }
        std::fs::rename(&self.partial, &self.dest)
            .map_err(io_err(&self.dest, "moving into place"))?;
        Ok(self.dest)
    }
}

/// Opens the lock file without following a link and checks that it is a regular file with a
/// single name (a hard link to another file would let the pid written into it land there).
fn open_lock(path: &Path) -> Result<File, OutDirError> {
    let mut o = std::fs::OpenOptions::new();
    o.read(true).write(true).create(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC);
        o.mode(0o644);
    }
    let f = o.open(path).map_err(|e| {
        if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
            OutDirError::BadLock {
                path: path.to_path_buf(),
            }
        } else {
            io_err(path, "opening the lock file")(e)
        }
    })?;
    let m = f
        .metadata()
        .map_err(io_err(path, "reading the lock file"))?;
    #[cfg(unix)]
    let single = {
        use std::os::unix::fs::MetadataExt;
        m.nlink() == 1
    };
    #[cfg(not(unix))]
    let single = true;
    if !m.is_file() || !single {
        return Err(OutDirError::BadLock {
            path: path.to_path_buf(),
        });
    }
    Ok(f)
}

/// An output folder in use by this run: locked, with the stage folder the outputs are
/// written in (see the module notes). Dropped without [`OutDir::commit`], the stage folder
/// is removed and `OUT` is as it was.
#[derive(Debug)]
pub struct OutDir {
    out: PathBuf,
    stage: tempfile::TempDir,
    /// Held (locked) for the life of the run.
    _lock: File,
}

impl OutDir {
    /// Checks `inputs` ([`check_inputs`]), creates `out` when missing, locks it, removes the
    /// stage folders of dead runs and creates a fresh stage folder.
    pub fn open(out: &Path, inputs: &[PathBuf]) -> Result<Self, OutDirError> {
        check_inputs(out, inputs)?;
        if std::fs::metadata(out).is_ok_and(|m| !m.is_dir()) {
            return Err(OutDirError::WrongKind {
                path: out.to_path_buf(),
                what: describe(out).unwrap_or_default(),
                want: "a folder",
            });
        }
        std::fs::create_dir_all(out).map_err(io_err(out, "creating the output folder"))?;
        let lock_path = out.join(LOCK_NAME);
        let mut lock = open_lock(&lock_path)?;
        match lock.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let mut s = String::new();
                let _ = lock.read_to_string(&mut s);
                let pid = s.trim();
                return Err(OutDirError::Busy {
                    out: out.to_path_buf(),
                    lock: lock_path,
                    pid: if pid.is_empty() { "unknown" } else { pid }.to_string(),
                });
            }
            Err(std::fs::TryLockError::Error(e)) => {
                return Err(io_err(&lock_path, "locking")(e));
            }
        }
        lock.set_len(0)
            .and_then(|()| writeln!(lock, "{}", std::process::id()))
            .map_err(io_err(&lock_path, "writing the lock file"))?;
        // under the lock, a stage folder is a dead run's
        if let Ok(rd) = std::fs::read_dir(out) {
            for e in rd.flatten() {
                let stale = e.file_name().to_string_lossy().starts_with(STAGE_PREFIX)
                    && e.file_type().is_ok_and(|t| t.is_dir());
                if stale {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        let stage = tempfile::Builder::new()
            .prefix(STAGE_PREFIX)
            .tempdir_in(out)
            .map_err(io_err(out, "creating the stage folder"))?;
        Ok(Self {
            out: out.to_path_buf(),
            stage,
            _lock: lock,
        })
    }

    /// The stage folder: write the outputs here.
    pub fn stage(&self) -> &Path {
        self.stage.path()
    }

    /// The output folder.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// Moves every file of the stage folder into the output folder under its name (the
    /// [`MARKERS`] last, the old marker removed before the first rename), removes the
    /// `NAME.partial` an earlier run left beside each final name written, and removes the
    /// stage folder. Returns the paths written.
    pub fn commit(self) -> Result<Vec<PathBuf>, OutDirError> {
        let stage = self.stage.path();
        let mut names: Vec<std::ffi::OsString> = std::fs::read_dir(stage)
            .map_err(io_err(stage, "listing the stage folder"))?
            .flatten()
            .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
            .map(|e| e.file_name())
            .collect();
        let is_marker = |n: &std::ffi::OsString| MARKERS.iter().any(|m| n == *m);
        names.sort_by_key(|n| (is_marker(n), n.clone()));
        for n in names.iter().filter(|n| is_marker(n)) {
            let p = self.out.join(n);
            if std::fs::symlink_metadata(&p).is_ok_and(|m| !m.is_dir()) {
                std::fs::remove_file(&p).map_err(io_err(&p, "removing the previous output"))?;
            }
        }
        let mut done = Vec::with_capacity(names.len());
        for n in &names {
            let to = self.out.join(n);
            std::fs::rename(stage.join(n), &to).map_err(io_err(&to, "moving into place"))?;
            let name = n.to_string_lossy();
            if !name.ends_with(".partial") {
                let stale = self.out.join(format!("{name}.partial"));
                if std::fs::symlink_metadata(&stale).is_ok_and(|m| !m.is_dir()) {
                    let _ = std::fs::remove_file(&stale);
                }
            }
            done.push(to);
        }
        self.stage
            .close()
            .map_err(io_err(&self.out, "removing the stage folder"))?;
        Ok(done)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commit_moves_files_and_keeps_old_ones_until_then() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        std::fs::create_dir(&out).unwrap();
        std::fs::write(out.join("nav.txt"), "old").unwrap();
        std::fs::write(out.join("nav.txt.partial"), "older").unwrap();
        let o = OutDir::open(&out, &[]).unwrap();
        std::fs::write(o.stage().join("nav.txt"), "new").unwrap();
        std::fs::write(o.stage().join("metrics.json"), "{}").unwrap();
        assert_eq!(std::fs::read_to_string(out.join("nav.txt")).unwrap(), "old");
        // a second open while the first holds the lock: refused with the pid
        let e = OutDir::open(&out, &[]).unwrap_err().to_string();
        assert!(e.contains(&format!("pid {}", std::process::id())), "{e}");
        let done = o.commit().unwrap();
        assert_eq!(done.len(), 2);
        assert_eq!(std::fs::read_to_string(out.join("nav.txt")).unwrap(), "new");
        assert!(!out.join("nav.txt.partial").exists());
        let left: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(STAGE_PREFIX))
            .collect();
        assert!(left.is_empty());
        // the lock is free again
        drop(OutDir::open(&out, &[]).unwrap());
    }

    #[test]
    fn a_file_as_the_folder_or_a_folder_as_the_file_is_named_so() {
        let d = tempfile::tempdir().unwrap();
        let file = d.path().join("afile");
        std::fs::write(&file, "keep").unwrap();
        let e = OutDir::open(&file, &[]).unwrap_err().to_string();
        assert!(
            e.ends_with("afile is a file of 4 bytes, not a folder: choose another name (nothing was written)"),
            "{e}"
        );
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
        let dir = d.path().join("adir");
        std::fs::create_dir(&dir).unwrap();
        for force in [false, true] {
            let e = StagedFile::create(&dir, force).unwrap_err().to_string();
            assert!(
                e.ends_with(
                    "adir is a folder, not a file: choose another name (nothing was written)"
                ),
                "{e}"
            );
        }
        assert!(!d.path().join("adir.partial").exists());
    }

    #[test]
    fn inputs_in_the_folder_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let input = out.join("truth.txt");
        std::fs::write(&input, "x").unwrap();
        let e = OutDir::open(&out, std::slice::from_ref(&input)).unwrap_err();
        assert!(matches!(e, OutDirError::HoldsInput { .. }), "{e}");
        assert!(e.to_string().contains("truth.txt"), "{e}");
        // out given as a relative path with `..`, the input elsewhere but hard-linked inside
        let other = d.path().join("data.txt");
        std::fs::write(&other, "y").unwrap();
        std::fs::hard_link(&other, out.join("nav.txt")).unwrap();
        let e = check_inputs(&out.join("..").join("out"), &[other]).unwrap_err();
        assert!(e.to_string().contains("another name"), "{e}");
        // the output folder itself as an input (a case folder)
        assert!(check_inputs(&out, std::slice::from_ref(&out)).is_err());
        // a folder that does not exist holds nothing
        assert!(check_inputs(&d.path().join("none"), &[input]).is_ok());
        assert!(!d.path().join("none").exists());
    }

    #[test]
    fn a_staged_file_never_replaces_a_file_that_appeared_without_force() {
        let d = tempfile::tempdir().unwrap();
        let dest = d.path().join("c.cap");
        let f = StagedFile::create(&dest, false).unwrap();
        f.writer().unwrap().write_all(b"new").unwrap();
        // a second writer of the same name refuses while the first holds it, even forced
        let e = StagedFile::create(&dest, true).unwrap_err();
        assert!(matches!(e, OutDirError::FileBusy { .. }), "{e}");
        std::fs::write(&dest, b"appeared").unwrap();
        let e = f.commit().unwrap_err();
        assert!(e.to_string().contains("kept in"), "{e}");
        assert_eq!(std::fs::read(&dest).unwrap(), b"appeared");
        assert_eq!(
            std::fs::read(d.path().join("c.cap.partial")).unwrap(),
            b"new"
        );
        // forced: the leftover removed, the file replaced
        let f = StagedFile::create(&dest, true).unwrap();
        f.writer().unwrap().write_all(b"newer").unwrap();
        assert_eq!(f.commit().unwrap(), dest);
        assert_eq!(std::fs::read(&dest).unwrap(), b"newer");
        assert!(!d.path().join("c.cap.partial").exists());
    }

    #[cfg(unix)]
    #[test]
    fn a_linked_lock_file_is_refused_and_its_target_untouched() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let victim = d.path().join("victim");
        std::fs::write(&victim, "keep").unwrap();
        std::os::unix::fs::symlink(&victim, out.join(LOCK_NAME)).unwrap();
        let e = OutDir::open(&out, &[]).unwrap_err();
        assert!(matches!(e, OutDirError::BadLock { .. }), "{e}");
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
    }
}
