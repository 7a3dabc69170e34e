//! Hardware-in-the-loop on the emulator: qemu's UART0 on a unix socket
//! (`-chardev socket,...,server=on,wait=on`, so the guest starts only once the host is
//! connected and no byte is lost), `socat` exposing it as a pty (what a serial-port program
//! such as `hw-bridge` opens), and the host side of two tests:
//!
//! - [`uart_echo`]: raw bytes both ways through the firmware's CMSDK UART driver;
//! - [`frame_link`]: the `nav` application: wire frames (configuration, IMU, GNSS) in,
//!   navigation solutions and health frames out, compared with the same application code
//!   (`firmware/src/app.rs`, compiled into xtask) run on the host on the same bytes.

use crate::embedded;
use crate::fwapp::NavApp;
use crate::time::TimeBase;
use anyhow::{bail, Context, Result};
use nav_core::config::FilterConfig;
use nav_core::earth::{self, Llh};
use nav_core::model::Layout;
use nav_core::types::{FixQuality, GnssFix, ImuSample};
use nav_core::wire::{self, Encoder, FrameDecoder, Health, ImuFrame, Payload, MAX_FRAME_LEN};
use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

/// A running qemu whose UART0 is reachable as a pty.
pub struct QemuLink {
    qemu: Child,
    socat: Child,
    tty: File,
    rx: Receiver<Vec<u8>>,
    pending: Vec<u8>,
    dir: PathBuf,
}

fn wait_for(path: &Path, what: &str, child: &mut Child) -> Result<()> {
    let t0 = Instant::now();
    while !path.exists() {
        if let Some(st) = child.try_wait()? {
            bail!("{what} exited ({st}) before creating {}", path.display());
        }
        if t0.elapsed() > Duration::from_secs(20) {
            bail!("{what} did not create {} within 20 s", path.display());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(())
}

impl QemuLink {
    /// Starts `elf` on qemu mps2-an386 (`-icount shift=5`: deterministic tick counts) with
    /// UART0 on a socket, connects socat, opens the pty.
    pub fn start(elf: &Path, name: &str) -> Result<Self> {
        // unix socket paths are limited to 107 bytes: keep them short, under the temp dir
        let dir = std::env::temp_dir().join(format!("navcore-hil-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let sock = dir.join("uart0.sock");
        let tty = dir.join("uart0.tty");
        let _ = std::fs::remove_file(&sock);
        let _ = std::fs::remove_file(&tty);
        let mut q = embedded::qemu_base();
        q.args(["-icount", &format!("shift={}", crate::budget::ICOUNT_SHIFT)])
            .arg("-chardev")
            .arg(format!(
                "socket,id=u0,path={},server=on,wait=on",
                sock.display()
            ))
            .args(["-serial", "chardev:u0", "-kernel"])
            .arg(elf)
            .stdin(Stdio::null());
        eprintln!("  $ {}", crate::show(&q));
        let mut qemu = q.spawn().context("starting qemu-system-arm")?;
        wait_for(&sock, "qemu", &mut qemu)?;
        let mut s = Command::new("socat");
        // wait-slave: socat connects (and qemu starts the guest) only once the pty is open
        // here, so nothing the firmware sends at boot can hit a pty nobody holds
        s.arg(format!("pty,raw,echo=0,wait-slave,link={}", tty.display()))
            .arg(format!("unix-connect:{}", sock.display()))
            .stdin(Stdio::null());
        eprintln!("  $ {}", crate::show(&s));
        let mut socat = s.spawn().context("starting socat")?;
        if let Err(e) = wait_for(&tty, "socat", &mut socat) {
            let _ = qemu.kill();
            let _ = socat.kill();
            return Err(e);
        }
        let tty_file = OpenOptions::new()
            .read(true)
            .write(true)
            .open(&tty)
            .with_context(|| format!("opening {}", tty.display()))?;
        let mut reader = tty_file.try_clone()?;
        let (txc, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 || txc.send(buf[..n].to_vec()).is_err() {
                    break;
                }
            }
        });
        Ok(Self {
            qemu,
            socat,
            tty: tty_file,
            rx,
            pending: Vec::new(),
            dir,
        })
    }

    /// Writes all bytes to the pty.
    pub fn write_all(&mut self, b: &[u8]) -> Result<()> {
        self.tty.write_all(b).context("writing to the pty")
    }

    /// Receives until `done(&received)` holds or `timeout` passes; returns everything received.
    pub fn read_until(
        &mut self,
        timeout: Duration,
        mut done: impl FnMut(&[u8]) -> bool,
    ) -> Result<Vec<u8>> {
        let t0 = Instant::now();
        while !done(&self.pending) {
            let left = timeout.saturating_sub(t0.elapsed());
            if left.is_zero() {
                bail!(
                    "timed out after {:.0} s with {} bytes received",
                    timeout.as_secs_f64(),
                    self.pending.len()
                );
            }
            match self.rx.recv_timeout(left.min(Duration::from_millis(200))) {
                Ok(chunk) => self.pending.extend_from_slice(&chunk),
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    bail!("the pty closed with {} bytes received", self.pending.len())
                }
            }
        }
        Ok(std::mem::take(&mut self.pending))
    }

    /// Waits for qemu to exit (the firmware's semihosting exit code).
    pub fn wait_exit(mut self, timeout: Duration) -> Result<ExitStatus> {
        let t0 = Instant::now();
        loop {
            if let Some(st) = self.qemu.try_wait()? {
                return Ok(st);
            }
            if t0.elapsed() > timeout {
                bail!("qemu did not exit within {:.0} s", timeout.as_secs_f64());
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for QemuLink {
    fn drop(&mut self) {
        let _ = self.qemu.kill();
        let _ = self.qemu.wait();
        let _ = self.socat.kill();
        let _ = self.socat.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The `uart-echo` binary's banner.
const ECHO_BANNER: &[u8] = b"uart-echo ready\n";
/// Its transform.
const ECHO_XOR: u8 = 0xA5;

/// UART loopback: every byte value, several times, through the pty, the socket, the UART
/// driver's Read, its Write and back; the firmware transforms each byte (XOR 0xA5) so a link
/// looping back on itself cannot pass.
pub fn uart_echo(elf: &Path) -> Result<()> {
    let mut link = QemuLink::start(elf, "echo")?;
    let banner = link.read_until(Duration::from_secs(60), |b| b.len() >= ECHO_BANNER.len())?;
    if banner != ECHO_BANNER {
        bail!(
            "expected the banner {:?}, got {:?}",
            String::from_utf8_lossy(ECHO_BANNER),
            String::from_utf8_lossy(&banner)
        );
    }
    let data: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8 ^ (i as u8))
        .collect();
    let t0 = Instant::now();
    link.write_all(&(data.len() as u32).to_le_bytes())?;
    link.write_all(&data)?;
    let n = data.len();
    let back = link.read_until(Duration::from_secs(120), |b| b.len() >= n)?;
    let dt = t0.elapsed().as_secs_f64();
    let want: Vec<u8> = data.iter().map(|b| b ^ ECHO_XOR).collect();
    if back != want {
        let first = back.iter().zip(&want).position(|(a, b)| a != b);
        bail!(
            "echo differs: {} bytes back for {} sent, first difference at {:?}",
            back.len(),
            n,
            first
        );
    }
    let st = link.wait_exit(Duration::from_secs(30))?;
    if !st.success() {
        bail!("uart-echo firmware exited with {st}");
    }
    eprintln!(
        "  uart echo: banner + {n} bytes (all 256 values) sent, {n} transformed bytes back, identical ({dt:.2} s); firmware exit 0"
    );
    Ok(())
}

/// Settings of the frame-link scenario.
const IMU_HZ: f64 = 200.0;
const IMU_EPOCHS: u32 = 600;
const GNSS_EVERY: u32 = 200;
const NAV_DIVIDER: u16 = 20;
/// The nav binary's own settings (firmware/src/bin/nav.rs).
const FW_NAV_DIVIDER: u16 = 20;
const FW_HEALTH_EVERY: u32 = 200;

/// The bytes the host sends: a configuration, 600 IMU frames (3 s at 200 Hz, at rest with
/// noise), a GNSS fix after every 200th, and a health request at the end.
fn scenario() -> Vec<u8> {
    let p = Llh::from_deg(48.0, 11.0, 500.0);
    let g = earth::gravity_mps2(p.lat_rad, p.h_m);
    let w = earth::OMEGA_IE_RADPS;
    let mut seed = 7u64;
    let mut rnd = move || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((seed >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
    };
    let mut enc = Encoder::new();
    let mut out = Vec::new();
    let mut push = |p: Payload, out: &mut Vec<u8>| {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = enc.encode(&p, &mut buf).unwrap_or(0);
        out.extend_from_slice(&buf[..n]);
    };
    push(
        Payload::Config(wire::Config {
            model: wire::model::NBK,
            flags: 0,
            nav_divider: NAV_DIVIDER,
            imu_rate_hz: IMU_HZ as f32,
            gnss_rate_hz: 1.0,
            lever_arm_frd_m: [0.0; 3],
        }),
        &mut out,
    );
    let dt = 1.0 / IMU_HZ;
    for k in 1..=IMU_EPOCHS {
        let t = 345_600.0 + f64::from(k) * dt;
        let rate = [
            w * p.lat_rad.cos() + 1e-5 * rnd(),
            1e-5 * rnd(),
            -w * p.lat_rad.sin() + 1e-5 * rnd(),
        ];
        let f = [1e-3 * rnd(), 1e-3 * rnd(), -g + 1e-3 * rnd()];
        let s = ImuSample {
            t_s: t,
            dtheta_rad: rate.map(|r| r * dt),
            dv_mps: f.map(|a| a * dt),
            temperature_c: 25.0,
        };
        push(
            Payload::Imu(ImuFrame {
                sample: s,
                status: 0,
            }),
            &mut out,
        );
        if k % GNSS_EVERY == 0 {
            push(
                Payload::Gnss(GnssFix {
                    t_s: t,
                    lat_rad: p.lat_rad + 1e-8 * rnd(),
                    lon_rad: p.lon_rad + 1e-8 * rnd(),
                    h_m: p.h_m + 0.1 * rnd(),
                    pos_std_ned_m: [0.5, 0.5, 1.0],
                    vel_ned_mps: [0.0; 3],
                    vel_std_ned_mps: [0.1; 3],
                    has_velocity: true,
                    quality: FixQuality::Single,
                    num_sats: 12,
                }),
                &mut out,
            );
        }
    }
    push(Payload::Health(Health::default()), &mut out);
    out
}

/// A clock for the host run of the application (timing fields are not compared).
struct HostClock(u64);
impl TimeBase for HostClock {
    const HZ: u32 = 25_000_000;
    fn now_ticks(&mut self) -> u64 {
        self.0 += 1;
        self.0
    }
}

fn decode_all(bytes: &[u8]) -> Result<Vec<Payload>> {
    let mut dec = FrameDecoder::new();
    let mut out = Vec::new();
    for item in dec.feed(bytes) {
        out.push(
            item.map_err(|e| anyhow::anyhow!("decoding the firmware's output: {e}"))?
                .payload,
        );
    }
    Ok(out)
}

/// The same application the firmware's `nav` binary runs (default model NBK, 18 states).
fn host_app() -> NavApp<{ nav_core::model::LAYOUT_NBK.dim() }> {
    let layout: Layout = nav_core::model::LAYOUT_NBK;
    NavApp::new(
        layout,
        FilterConfig::source_nbk_model(),
        FW_NAV_DIVIDER,
        FW_HEALTH_EVERY,
    )
}

/// Frame link through the `nav` application, compared with the host. Returns the peak stack
/// the firmware reported in its last health frame, bytes.
pub fn frame_link(elf: &Path) -> Result<u64> {
    let input = scenario();
    // the host: the same application code on the same bytes
    let mut host = host_app();
    let mut host_out: Vec<u8> = Vec::new();
    let mut clk = HostClock(0);
    host.feed(&input, &mut host_out, &mut clk)
        .map_err(|e| anyhow::anyhow!("host app: {e:?}"))?;
    let want = decode_all(&host_out)?;
    let n_want = want.len();
    let n_nav = want.iter().filter(|p| matches!(p, Payload::Nav(_))).count();
    let n_health = n_want - n_nav;
    if n_nav == 0 {
        bail!("the host run produced no navigation solution: the scenario is broken");
    }

    let mut link = QemuLink::start(elf, "nav")?;
    let t0 = Instant::now();
    link.write_all(&input)?;
    let got_bytes = link.read_until(Duration::from_secs(240), |b| {
        b.iter().filter(|&&x| x == 0).count() >= n_want
    })?;
    let dt = t0.elapsed().as_secs_f64();
    let got = decode_all(&got_bytes)?;
    drop(link);
    if got.len() != n_want {
        bail!(
            "the firmware sent {} frames, the host app {} ({} nav + {} health)",
            got.len(),
            n_want,
            n_nav,
            n_health
        );
    }
    let mut nav_exact = 0usize;
    let mut last_health = None;
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        match (g, w) {
            (Payload::Nav(a), Payload::Nav(b)) => {
                // bit-exact: same code, same operation order, same libm on both sides
                let fa = nav_bits(a);
                let fb = nav_bits(b);
                if fa != fb {
                    bail!(
                        "frame {i}: the firmware's solution differs from the host's (t = {} s): MCU {:?} host {:?}",
                        b.t_s,
                        a,
                        b
                    );
                }
                nav_exact += 1;
            }
            (Payload::Health(a), Payload::Health(b)) => {
                let strip = |h: &Health| Health {
                    uptime_ms: 0,
                    epoch_ticks_max: 0,
                    stack_peak_bytes: 0,
                    ..*h
                };
                if strip(a) != strip(b) {
                    bail!("frame {i}: health counters differ: MCU {a:?} host {b:?}");
                }
                last_health = Some(*a);
            }
            _ => bail!("frame {i}: the firmware sent {g:?} where the host sent {w:?}"),
        }
    }
    let h = last_health.context("no health frame received")?;
    eprintln!(
        "  frame link: {} bytes in ({} frames), {} frames back in {:.1} s: {} navigation solutions bit-exact with the host run of the same app, {} health frames with equal counters",
        input.len(),
        h.rx_frames_ok,
        got.len(),
        dt,
        nav_exact,
        got.len() - nav_exact
    );
    eprintln!(
        "  firmware health: {} IMU epochs, {} GNSS updates, {} rejected, longest epoch {} ticks = {:.0} instructions, peak stack {} B, filter status {:#x}",
        h.imu_epochs,
        h.gnss_updates,
        h.gnss_rejected,
        h.epoch_ticks_max,
        crate::budget::instructions(f64::from(h.epoch_ticks_max)),
        h.stack_peak_bytes,
        h.filter_status
    );
    if h.gnss_updates == 0 || h.gnss_rejected != 0 || h.rx_rejected != 0 {
        bail!("the firmware did not use the fixes cleanly: {h:?}");
    }
    Ok(u64::from(h.stack_peak_bytes))
}

/// Every field of a solution as bits (f64 to_bits; the f32 sigmas travel as f32 on the wire).
fn nav_bits(n: &nav_core::types::NavSolution) -> Vec<u64> {
    let mut v = vec![
        u64::from(n.week),
        n.t_s.to_bits(),
        n.lat_rad.to_bits(),
        n.lon_rad.to_bits(),
        n.h_m.to_bits(),
        u64::from(n.status),
    ];
    for a in [
        n.vel_ned_mps,
        n.rpy_rad,
        n.pos_std_ned_m,
        n.vel_std_ned_mps,
        n.att_std_rad,
    ] {
        v.extend(a.iter().map(|x| x.to_bits()));
    }
    v
}
