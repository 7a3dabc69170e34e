//! The embedded half: toolchain set-up from Debian's packages, cross builds with
//! `-Zbuild-std=core`, qemu runs and ELF size reports.
//!
//! The recipe (see `docs/DESIGN.md`): Debian's `rustc-web` (rustc >= 1.89 at
//! `/usr/bin/rustc`) with its `rust-web-src` standard-library source builds `core` for
//! `thumbv7em-none-eabihf`; rustup's `rust-lld` links; `qemu-system-arm -machine mps2-an386`
//! runs the result. Everything built by the Debian rustc goes to `target/embedded`, so the
//! host builds (rustup's rustc) keep their own fingerprints.

use crate::{cargo, root, run};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The MCU target triple.
pub const TARGET: &str = "thumbv7em-none-eabihf";
const DEB_RUSTC: &str = "/usr/bin/rustc";
const DEB_CLIPPY: &str = "/usr/bin/cargo-clippy";
const DEB_CORE_SRC: &str = "/usr/lib/rustlib/src/rust/library/core";

struct Need {
    what: &'static str,
    ok: bool,
    package: &'static str,
}

fn rustc_minor(path: &str) -> Option<u32> {
    let out = Command::new(path).arg("--version").output().ok()?;
    let s = String::from_utf8_lossy(&out.stdout);
    // "rustc 1.96.0 (...)"
    let ver = s.split_whitespace().nth(1)?;
    ver.split('.').nth(1)?.parse().ok()
}

fn needs() -> Vec<Need> {
    vec![
        Need {
            what: "Debian rustc >= 1.89 at /usr/bin/rustc",
            ok: rustc_minor(DEB_RUSTC).is_some_and(|m| m >= 89),
            package: "rustc-web",
        },
        Need {
            what: "Rust standard library source for -Zbuild-std (/usr/lib/rustlib/src)",
            ok: Path::new(DEB_CORE_SRC).join("Cargo.toml").exists(),
            package: "rust-web-src",
        },
        Need {
            what: "clippy for the Debian rustc (/usr/bin/cargo-clippy)",
            ok: Path::new(DEB_CLIPPY).exists(),
            package: "rust-web-clippy",
        },
        Need {
            what: "qemu-system-arm (mps2-an386 board)",
            ok: which("qemu-system-arm").is_some(),
            package: "qemu-system-arm",
        },
        Need {
            what: "socat (virtual serial ports for the bridge and HIL tests)",
            ok: which("socat").is_some(),
            package: "socat",
        },
    ]
}

pub(crate) fn which(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false)
}

/// Installs the embedded toolchain and emulator when missing; idempotent and fast when all is
/// present. Uses apt-get only as root; otherwise fails with the exact command to run.
pub fn setup() -> Result<()> {
    let ns = needs();
    for n in &ns {
        eprintln!(
            "  [{}] {} (package {})",
            if n.ok { "ok" } else { "missing" },
            n.what,
            n.package
        );
    }
    let missing: Vec<&str> = ns.iter().filter(|n| !n.ok).map(|n| n.package).collect();
    if !missing.is_empty() {
        if !is_root() {
            bail!("{}", not_root_message(&missing));
        }
        run(Command::new("apt-get").args(["update", "-qq"]))?;
        let mut cmd = Command::new("apt-get");
        cmd.args(["install", "-y", "-qq", "--no-install-recommends"])
            .args(&missing)
            .env("DEBIAN_FRONTEND", "noninteractive");
        run(&mut cmd)?;
        let still: Vec<&str> = needs()
            .into_iter()
            .filter(|n| !n.ok)
            .map(|n| n.what)
            .collect();
        if !still.is_empty() {
            bail!("still missing after apt-get install: {}", still.join("; "));
        }
    }
    let lld = rust_lld()?;
    eprintln!("  [ok] linker {}", lld.display());
    Ok(())
}

/// What a user without root is told when packages are missing: the packages, `cargo xtask
/// setup` and the apt-get command to run as root.
fn not_root_message(missing: &[&str]) -> String {
    format!(
        "missing packages {}: run `cargo xtask setup` as root, or as root: \
         apt-get update && apt-get install -y {}",
        missing.join(", "),
        missing.join(" ")
    )
}

/// Runs [`setup`] when a part of the embedded toolchain or the emulator is missing (it
/// installs them as root, and otherwise fails naming `cargo xtask setup` and the apt-get
/// command); does nothing when all is present. Every embedded build goes through it.
pub fn ensure_toolchain() -> Result<()> {
    if needs().iter().all(|n| n.ok) {
        return Ok(());
    }
    eprintln!("  the embedded toolchain or emulator is missing: running `cargo xtask setup`");
    setup().context(
        "the firmware commands need the embedded toolchain and emulator (Debian rustc with its \
         library source, qemu-system-arm, socat)",
    )
}

/// rustup's `rust-lld` (the Debian rustc package does not ship a linker for the thumb target).
fn rust_lld() -> Result<PathBuf> {
    let out = Command::new("rustc")
        .env_remove("RUSTC")
        .args(["--print", "sysroot"])
        .output()
        .context("running `rustc --print sysroot`")?;
    let sysroot = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
    let cands = [
        sysroot.join("lib/rustlib/x86_64-unknown-linux-gnu/bin/rust-lld"),
        PathBuf::from("/usr/lib/rustlib/x86_64-unknown-linux-gnu/bin/rust-lld"),
        PathBuf::from("/usr/bin/rust-lld"),
        PathBuf::from("/usr/bin/ld.lld"),
    ];
    cands.into_iter().find(|p| p.is_file()).context(
        "no rust-lld found (rustup toolchain's lib/rustlib/*/bin/rust-lld, or Debian's lld: apt-get install lld)",
    )
}

/// A cargo command set up for the thumb target with the Debian rustc and `-Zbuild-std=core`.
fn embedded_cargo(program: Option<&str>) -> Result<Command> {
    let mut cmd = match program {
        Some(p) => Command::new(p),
        None => cargo(),
    };
    ensure_toolchain()?;
    let lld = rust_lld()?;
    cmd.env("RUSTC", DEB_RUSTC)
        .env("RUSTC_BOOTSTRAP", "1")
        .env("CARGO_TARGET_DIR", root().join("target").join("embedded"))
        .env("CARGO_TARGET_THUMBV7EM_NONE_EABIHF_LINKER", lld)
        .env_remove("RUSTC_WORKSPACE_WRAPPER")
        .env_remove("RUSTFLAGS");
    Ok(cmd)
}

/// `cargo clippy -D warnings` on nav-core built for the thumb target (Debian's clippy, which
/// matches the Debian rustc that builds `core`). Only `core` is available (`-Zbuild-std=core`):
/// any `extern crate alloc` or `std`-only dependency fails this check; the firmware build then
/// compiles nav-core for the board the same way.
pub fn clippy_nav_core_thumb() -> Result<()> {
    let mut cmd = embedded_cargo(Some(DEB_CLIPPY))?;
    cmd.env("CARGO", cargo().get_program()).args([
        "clippy",
        "-p",
        "nav-core",
        "--target",
        TARGET,
        "-Zbuild-std=core",
        "--release",
        "--",
        "-D",
        "warnings",
    ]);
    run(&mut cmd)
}

/// A board the firmware builds for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Board {
    /// The emulated Arm MPS2-AN386 (qemu-system-arm -machine mps2-an386), the default.
    Mps2An386,
    /// A real board: STM32F407 with an ICM-42688-P on SPI1 and the frame link on USART2.
    Stm32f407,
}

impl Board {
    /// Name as on the command line and in `firmware/boards/<name>/`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Mps2An386 => "mps2-an386",
            Self::Stm32f407 => "stm32f407",
        }
    }
    /// Cargo feature arguments selecting the board (and the default model).
    fn feature_args(self) -> &'static [&'static str] {
        match self {
            Self::Mps2An386 => &[],
            Self::Stm32f407 => &[
                "--no-default-features",
                "--features",
                "board-stm32f407,model-nbk",
            ],
        }
    }
    /// The binaries built for the board.
    pub fn bins(self) -> &'static [&'static str] {
        match self {
            Self::Mps2An386 => &["firmware", "bench", "nav", "uart-echo", "ontarget"],
            Self::Stm32f407 => &["nav"],
        }
    }
}

/// The ELFs of one board's build, copied to `target/embedded/<board>/` so that building
/// another board (same cargo target directory, other features) does not overwrite them.
pub struct FwBuild {
    /// The board.
    pub board: Board,
    dir: PathBuf,
}

impl FwBuild {
    /// Path of binary `bin`'s ELF.
    pub fn elf(&self, bin: &str) -> PathBuf {
        self.dir.join(bin)
    }
    /// All ELFs of the build with their binary names.
    pub fn elfs(&self) -> Vec<(&'static str, PathBuf)> {
        self.board
            .bins()
            .iter()
            .map(|b| (*b, self.elf(b)))
            .collect()
    }
}

/// Cross-builds the firmware (release) for `board`: every binary of the board.
pub fn fw_build(board: Board) -> Result<FwBuild> {
    run(&mut fw_build_command(board)?)?;
    fw_collect(board)
}

/// The cargo command that cross-builds the firmware (release) for `board` (run in the
/// workspace root). Every board builds into the same cargo target directory, so a second
/// board reuses the first one's `core`, `compiler_builtins`, nalgebra and nav-core.
pub fn fw_build_command(board: Board) -> Result<Command> {
    let mut cmd = embedded_cargo(None)?;
    cmd.args([
        "build",
        "--manifest-path",
        "firmware/Cargo.toml",
        "--target",
        TARGET,
        "-Zbuild-std=core",
        "--release",
    ])
    .args(board.feature_args());
    Ok(cmd)
}

/// Copies the ELFs of the last [`fw_build_command`] for `board` out of cargo's release
/// directory into `target/embedded/<board>/`, where the next board's build leaves them alone.
pub fn fw_collect(board: Board) -> Result<FwBuild> {
    let out = root().join("target/embedded").join(TARGET).join("release");
    let dir = root().join("target/embedded").join(board.name());
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    for bin in board.bins() {
        let src = out.join(bin);
        if !src.is_file() {
            bail!("firmware ELF not found at {}", src.display());
        }
        std::fs::copy(&src, dir.join(bin))
            .with_context(|| format!("copying {} to {}", src.display(), dir.display()))?;
    }
    Ok(FwBuild { board, dir })
}

/// The qemu command line for the emulated board, without `-kernel` and serial options.
pub fn qemu_base() -> Command {
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args([
        "-cpu",
        "cortex-m4",
        "-machine",
        "mps2-an386",
        "-nographic",
        "-monitor",
        "none",
        "-semihosting-config",
        "enable=on,target=native",
    ]);
    cmd
}

/// Runs the firmware ELF on qemu (mps2-an386) with semihosting; its exit code is the
/// firmware's verdict. Killed after 300 s.
pub fn fw_run(elf: &Path) -> Result<()> {
    let q = qemu_base();
    let mut cmd = Command::new("timeout");
    cmd.arg("300")
        .arg(q.get_program())
        .args(q.get_args())
        .args(["-serial", "none", "-kernel"])
        .arg(elf)
        .stdin(Stdio::null());
    run(&mut cmd).context("firmware on qemu reported failure (see its output above)")
}

/// Prints flash and static RAM use of every ELF of a build; returns the sizes.
pub fn fw_size(build: &FwBuild) -> Result<Vec<(&'static str, ElfSize)>> {
    let mut out = Vec::new();
    eprintln!(
        "  board {}: {:<10} {:>9} {:>9} {:>9} {:>9} {:>11} {:>9}",
        build.board.name(),
        "binary",
        "text",
        "rodata",
        "data",
        "bss",
        "flash",
        "RAM"
    );
    for (bin, elf) in build.elfs() {
        let s = elf_size(&elf)?;
        eprintln!(
            "  board {}: {:<10} {:>9} {:>9} {:>9} {:>9} {:>6.1} KiB {:>5.1} KiB",
            build.board.name(),
            bin,
            s.text,
            s.rodata,
            s.data,
            s.bss,
            s.flash() as f64 / 1024.0,
            s.ram() as f64 / 1024.0
        );
        out.push((bin, s));
    }
    eprintln!("  (flash = text + rodata + data; RAM = static data + bss, stack not included)");
    Ok(out)
}

/// Section sizes of an ELF, bytes, grouped as a linker map would.
#[derive(Debug, Clone, Copy)]
pub struct ElfSize {
    /// Executable code.
    pub text: u64,
    /// Read-only data (including vector table and exception tables).
    pub rodata: u64,
    /// Initialised data (in flash, copied to RAM).
    pub data: u64,
    /// Zero-initialised data and uninitialised RAM sections.
    pub bss: u64,
}

impl ElfSize {
    /// Flash use: text + rodata + the data initialisers.
    pub fn flash(&self) -> u64 {
        self.text + self.rodata + self.data
    }
    /// Static RAM use: data + bss.
    pub fn ram(&self) -> u64 {
        self.data + self.bss
    }
}

/// Reads allocated section sizes from an ELF file.
pub fn elf_size(elf: &Path) -> Result<ElfSize> {
    use object::{Object, ObjectSection, SectionFlags, SectionKind};
    let bytes = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    let file = object::File::parse(&*bytes).context("parsing ELF")?;
    let mut s = ElfSize {
        text: 0,
        rodata: 0,
        data: 0,
        bss: 0,
    };
    for sec in file.sections() {
        let alloc = match sec.flags() {
            SectionFlags::Elf { sh_flags } => sh_flags & u64::from(object::elf::SHF_ALLOC) != 0,
            _ => false,
        };
        if !alloc {
            continue;
        }
        let size = sec.size();
        match sec.kind() {
            SectionKind::Text => s.text += size,
            SectionKind::Data => s.data += size,
            SectionKind::UninitializedData | SectionKind::UninitializedTls => s.bss += size,
            _ => {
                // .uninit (stack reservations) and the like are RAM; read-only kinds are flash.
                let name = sec.name().unwrap_or("");
                if name.starts_with(".uninit") {
                    s.bss += size;
                } else {
                    s.rodata += size;
                }
            }
        }
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::not_root_message;

    #[test]
    fn a_user_without_root_is_told_the_setup_command_and_the_apt_get_line() {
        let m = not_root_message(&["rustc-web", "qemu-system-arm"]);
        assert!(m.contains("`cargo xtask setup` as root"), "{m}");
        assert!(
            m.ends_with("apt-get update && apt-get install -y rustc-web qemu-system-arm"),
            "{m}"
        );
    }
}
