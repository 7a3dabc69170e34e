//! `stream`: live decode of a board's frames and a GNSS receiver, with health.

use super::*;
use crate::frames::FrameLog;
use crate::serial;
use crate::status::{decoder_summary, StatusLine};
use nav_core::model::StateModel;
use nav_core::types::GnssFix;
use nav_core::wire::{DecoderStats, FrameDecoder, Payload};
use nav_io::gnss::{GnssEvent, GnssStream, NmeaOptions};
use std::io::Read;
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// `stream` options (the command line's `hw-bridge stream` arguments convert into them).
#[derive(Debug, Clone, PartialEq)]
pub struct StreamOptions {
    /// Port of the navigation board (wire-protocol frames).
    pub port: String,
    /// Baud rate of `port`, bit/s.
    pub baud: u32,
    /// Port of a separate GNSS receiver (NMEA and/or UBX).
    pub gnss_port: Option<String>,
    /// Baud rate of `gnss_port`, bit/s.
    pub gnss_baud: u32,
    /// GPS - UTC leap seconds for NMEA input, s.
    pub leap_seconds: i64,
    /// Stop after this many seconds (None: until the ports close).
    pub duration_s: Option<f64>,
    /// Run the filter on the host too: the firmware's own application (18-state NBK, f32
    /// covariance, started at the first fix) on the IMU frames of `port` and the GNSS fixes
    /// of both ports.
    pub host_filter: bool,
}

/// Default of `stream --gnss-baud`, bit/s.
pub const DEFAULT_GNSS_BAUD: u32 = 38_400;

impl StreamOptions {
    /// Streaming the board on `port` at [`DEFAULT_BAUD`], no GNSS receiver, no time limit, no
    /// host filter.
    pub fn new(port: impl Into<String>) -> Self {
        Self {
            port: port.into(),
            baud: DEFAULT_BAUD,
            gnss_port: None,
            gnss_baud: DEFAULT_GNSS_BAUD,
            leap_seconds: DEFAULT_LEAP_SECONDS,
            duration_s: None,
            host_filter: false,
        }
    }
}

/// The wall clock as the application's time base (only its health timing fields use it).
struct WallClock(Instant);
impl nav_app::TimeBase for WallClock {
    const HZ: u32 = 1_000_000;
    fn now_ticks(&mut self) -> u64 {
        self.0.elapsed().as_micros() as u64
    }
}

/// The host filter of `stream --host-filter`.
type HostApp = nav_app::NavApp<{ <nav_core::model::ModelNbk as StateModel>::DIM }>;

fn host_app() -> anyhow::Result<HostApp> {
    nav_app::NavApp::new::<nav_core::model::ModelNbk>(
        nav_core::config::FilterConfig::source_nbk_model(),
        0,
        0,
    )
    .map_err(|e| anyhow::anyhow!("host filter: {e}"))
}

/// Feeds a payload to the host filter (IMU samples and GNSS fixes only; its own output
/// frames are discarded).
fn host_feed(app: &mut HostApp, p: &Payload, clock: &mut WallClock) {
    if matches!(p, Payload::Imu(_) | Payload::Gnss(_)) {
        let mut sink: Vec<u8> = Vec::new();
        let _ = app.handle(p, &mut sink, clock);
    }
}

enum PortEvent {
    Board(Vec<u8>),
    Gnss(Vec<u8>),
    Lost(&'static str, String),
}

fn reader_thread(
    path: String,
    baud: u32,
    tx: mpsc::Sender<PortEvent>,
    wrap: fn(Vec<u8>) -> PortEvent,
    name: &'static str,
) -> anyhow::Result<()> {
    let mut port = serial::open(&path, baud, Duration::from_millis(100))?;
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 4096];
        loop {
            match port.read(&mut buf) {
                Ok(0) => std::thread::sleep(Duration::from_millis(5)),
                Ok(n) => {
                    if tx.send(wrap(buf[..n].to_vec())).is_err() {
                        return;
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => {
                    let _ = tx.send(PortEvent::Lost(name, e.to_string()));
                    std::thread::sleep(Duration::from_millis(200));
                    match serial::open(&path, baud, Duration::from_millis(100)) {
                        Ok(p) => port = p,
                        Err(_) => continue,
                    }
                }
            }
        }
    });
    Ok(())
}

/// `stream`: live decode of a board's frames (and a GNSS receiver's fixes) with a status
/// line showing the latest solution, GNSS fix and link health.
pub fn stream(a: &StreamOptions) -> anyhow::Result<StreamOutcome> {
    let (tx, rx) = mpsc::channel();
    reader_thread(
        a.port.clone(),
        a.baud,
        tx.clone(),
        PortEvent::Board,
        "board",
    )?;
    if let Some(g) = &a.gnss_port {
        reader_thread(g.clone(), a.gnss_baud, tx.clone(), PortEvent::Gnss, "gnss")?;
    }
    drop(tx);
    let mut dec = FrameDecoder::new();
    let mut gnss = GnssStream::new(NmeaOptions {
        leap_seconds: a.leap_seconds,
        ..NmeaOptions::default()
    });
    let mut status = StatusLine::new(Duration::from_millis(250), true);
    let mut log = FrameLog::default();
    let mut last_rx_fix: Option<GnssFix> = None;
    let mut host = a.host_filter.then(host_app).transpose()?;
    let mut clock = WallClock(Instant::now());
    let start = Instant::now();
    loop {
        if a.duration_s.is_some_and(|d| start.elapsed() >= secs(d)) {
            break;
        }
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(PortEvent::Board(b)) => {
                for f in dec.feed(&b).flatten() {
                    if let Some(h) = host.as_mut() {
                        host_feed(h, &f.payload, &mut clock);
                    }
                    log.push(f);
                }
                // Keep only the latest of each kind for display.
                log.frames.clear();
                log.imu.drain(..log.imu.len().saturating_sub(1));
                log.imu_status
                    .drain(..log.imu_status.len().saturating_sub(1));
                log.gnss.drain(..log.gnss.len().saturating_sub(1));
                log.nav.drain(..log.nav.len().saturating_sub(1));
                log.health.drain(..log.health.len().saturating_sub(1));
            }
            Ok(PortEvent::Gnss(b)) => {
                for ev in gnss.feed(&b) {
                    if let GnssEvent::Fix(f) = ev {
                        if let Some(h) = host.as_mut() {
                            host_feed(h, &Payload::Gnss(f), &mut clock);
                        }
                        last_rx_fix = Some(f);
                    }
                }
            }
            Ok(PortEvent::Lost(name, e)) => {
                status.message(&format!("{name} port lost: {e}; reopening"));
                if name == "board" {
                    dec.reset_link();
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        }
        let s = *dec.stats();
        status.update(u64::from(s.frames_ok), false, || {
            status_text(&s, &log, host.as_ref(), last_rx_fix)
        });
    }
    status.finish();
    Ok(StreamOutcome {
        stats: *dec.stats(),
        host_solution: host.as_ref().and_then(|h| h.filter()).map(|f| f.solution()),
        host_imu_epochs: host.as_ref().map_or(0, |h| h.counters().imu_epochs),
        host_gnss_updates: host.as_ref().map_or(0, |h| h.counters().gnss_updates),
    })
}

/// What `stream` saw.
#[derive(Debug, Clone, Copy)]
pub struct StreamOutcome {
    /// Decoder counters of the board port.
    pub stats: DecoderStats,
    /// The host filter's last solution ([`StreamOptions::host_filter`], once started).
    pub host_solution: Option<nav_core::types::NavSolution>,
    /// IMU epochs the host filter ran.
    pub host_imu_epochs: u32,
    /// GNSS fixes the host filter used.
    pub host_gnss_updates: u32,
}

/// The host filter of `stream --host-filter` run offline on payloads (what a live stream of
/// them must reproduce exactly): its last solution, IMU epochs and GNSS updates.
pub fn host_filter_offline(
    payloads: &[Payload],
) -> anyhow::Result<(Option<nav_core::types::NavSolution>, u32, u32)> {
    let mut app = host_app()?;
    let mut clock = WallClock(Instant::now());
    for p in payloads {
        host_feed(&mut app, p, &mut clock);
    }
    let c = *app.counters();
    Ok((
        app.filter().map(|f| f.solution()),
        c.imu_epochs,
        c.gnss_updates,
    ))
}

/// The status line's text: the decoder's counts, the board's latest solution (or IMU time),
/// the host filter's solution, the board's health and the receiver's latest fix (degrees, m,
/// m/s).
fn status_text(
    s: &DecoderStats,
    log: &FrameLog,
    host: Option<&HostApp>,
    last_rx_fix: Option<GnssFix>,
) -> String {
    let mut t = decoder_summary(s);
    if let Some(n) = log.nav.last() {
        t.push_str(&format!(
            " | nav t {:.2} lat {:.7} lon {:.7} h {:.2} v {:.2} {:.2} {:.2} yaw {:.2} st {:#x}",
            n.t_s,
            n.lat_rad.to_degrees(),
            n.lon_rad.to_degrees(),
            n.h_m,
            n.vel_ned_mps[0],
            n.vel_ned_mps[1],
            n.vel_ned_mps[2],
            n.rpy_rad[2].to_degrees(),
            n.status
        ));
    } else if let Some(i) = log.imu.last() {
        t.push_str(&format!(" | imu t {:.3}", i.t_s));
    }
    if let Some(n) = host.and_then(|h| h.filter()).map(|f| f.solution()) {
        t.push_str(&format!(
            " | host t {:.2} lat {:.7} lon {:.7} h {:.2} yaw {:.2} std {:.2} {:.2} {:.2}",
            n.t_s,
            n.lat_rad.to_degrees(),
            n.lon_rad.to_degrees(),
            n.h_m,
            n.rpy_rad[2].to_degrees(),
            n.pos_std_ned_m[0],
            n.pos_std_ned_m[1],
            n.pos_std_ned_m[2]
        ));
    }
    if let Some(h) = log.health.last() {
        t.push_str(&format!(
            " | board rx ok {} crc {} lost {} gnss upd {}",
            h.rx_frames_ok, h.rx_crc_errors, h.rx_lost, h.gnss_updates
        ));
    }
    if let Some(f) = last_rx_fix {
        t.push_str(&format!(
            " | rx gnss t {:.1} {:?} sats {} std {:.2} {:.2} {:.2}",
            f.t_s,
            f.quality,
            f.num_sats,
            f.pos_std_ned_m[0],
            f.pos_std_ned_m[1],
            f.pos_std_ned_m[2]
        ));
    }
    t
}
