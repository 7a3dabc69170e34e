//! Turning a simulated case into the frame sequence `send` streams, and collecting decoded
//! frames by type (what `replay` and the tests compare).

use nav_core::types::{GnssFix, ImuSample, NavSolution};
use nav_core::wire::{Config, Frame, Health, ImuFrame, Payload};

/// The payloads of a case in sending order, each with its time (s): every IMU sample in order,
/// and each GNSS fix right after the first IMU sample whose time is at or past the fix time
/// (as a board sees it: the fix arrives during the IMU interval that contains it). Fixes after
/// the last IMU sample come at the end.
pub fn case_payloads(imu: &[ImuSample], gnss: &[GnssFix]) -> Vec<(f64, Payload)> {
    let mut out = Vec::with_capacity(imu.len() + gnss.len());
    let mut g = gnss.iter().peekable();
    for s in imu {
        out.push((
            s.t_s,
            Payload::Imu(ImuFrame {
                sample: *s,
                status: 0,
            }),
        ));
        while let Some(f) = g.next_if(|f| f.t_s <= s.t_s) {
            out.push((s.t_s, Payload::Gnss(*f)));
        }
    }
    for f in g {
        out.push((f.t_s, Payload::Gnss(*f)));
    }
    out
}

/// Decoded frames sorted by type, in arrival order.
#[derive(Debug, Default, Clone)]
pub struct FrameLog {
    /// Every frame, in arrival order.
    pub frames: Vec<Frame>,
    /// IMU samples.
    pub imu: Vec<ImuSample>,
    /// IMU status words, parallel to `imu`.
    pub imu_status: Vec<u16>,
    /// GNSS fixes.
    pub gnss: Vec<GnssFix>,
    /// Navigation solutions.
    pub nav: Vec<NavSolution>,
    /// Configuration frames.
    pub config: Vec<Config>,
    /// Health frames.
    pub health: Vec<Health>,
}

impl FrameLog {
    /// Adds a frame.
    pub fn push(&mut self, f: Frame) {
        match f.payload {
            Payload::Imu(ImuFrame { sample, status }) => {
                self.imu.push(sample);
                self.imu_status.push(status);
            }
            Payload::Gnss(g) => self.gnss.push(g),
            Payload::Nav(n) => self.nav.push(n),
            Payload::Config(c) => self.config.push(c),
            Payload::Health(h) => self.health.push(h),
        }
        self.frames.push(f);
    }
}
