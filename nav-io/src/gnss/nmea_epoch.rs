//! Assembles the NMEA 0183 sentences of one epoch (GGA position, GST standard deviations,
//! RMC date/speed/course or VTG speed/course) into one [`GnssFix`].
//!
//! Sentences are parsed and their checksums verified by the `nmea` crate. An epoch is the set
//! of sentences carrying the same UTC time (VTG has none and joins the epoch being assembled).
//! The first epoch is emitted when the next one starts; from then on the assembler knows which
//! sentence types the receiver sends per epoch and emits each epoch as soon as all of them
//! have arrived (no one-epoch latency).
//!
//! Mapping:
//! * time: GPS seconds of week from the UTC date (RMC; carried over between epochs, advanced
//!   at midnight) and time of day plus [`NmeaOptions::leap_seconds`];
//! * position: GGA latitude/longitude; ellipsoidal height = GGA altitude (MSL) + geoid
//!   separation (0 when the receiver leaves it empty);
//! * standard deviations: GST latitude/longitude/altitude error sigmas; without GST, NaN (the
//!   fix is then not `is_valid`) unless [`NmeaOptions::hdop_uere_m`] gives a fallback;
//! * quality: GGA fix type (GPS -> single, DGPS -> DGNSS, RTK -> fixed, float RTK -> float,
//!   PPS -> single, others -> no fix); satellites: GGA;
//! * velocity: RMC or VTG speed over ground and course give north/east velocity; NMEA has no
//!   vertical velocity, so `has_velocity` is set only when [`NmeaOptions::velocity_std_mps`]
//!   says how much to trust it (down velocity 0 with the given vertical sigma).

use super::{GnssError, GnssEvent, WEEK_S};
use chrono::{Duration, NaiveDate, NaiveTime, Timelike};
use nav_core::types::{FixQuality, GnssFix};
use nmea::sentences::{FixType, GgaData, GstData, RmcData, VtgData};
use nmea::ParseResult;

/// Options of the NMEA mapping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NmeaOptions {
    /// GPS - UTC, s (18 since 2017-01-01).
    pub leap_seconds: i64,
    /// Without GST: sigma north = east = HDOP x this, down = 1.5 x HDOP x this, m.
    pub hdop_uere_m: Option<f64>,
    /// Horizontal and vertical velocity sigmas, m/s; `Some` makes fixes carry velocity.
    pub velocity_std_mps: Option<(f64, f64)>,
}

impl Default for NmeaOptions {
    fn default() -> Self {
        Self {
            leap_seconds: 18,
            hdop_uere_m: None,
            velocity_std_mps: None,
        }
    }
}

const GGA: u8 = 1;
const RMC: u8 = 2;
const GST: u8 = 4;
const VTG: u8 = 8;

#[derive(Debug, Default)]
struct Epoch {
    time: Option<NaiveTime>,
    gga: Option<GgaData>,
    rmc: Option<RmcData>,
    gst: Option<GstData>,
    vtg: Option<VtgData>,
    seen: u8,
    emitted: bool,
}

/// Sentence-to-fix assembler (see the module doc).
#[derive(Debug)]
pub struct NmeaAssembler {
    opts: NmeaOptions,
    cur: Epoch,
    expected: Option<u8>,
    pending_vtg: Option<VtgData>,
    last_date: Option<(NaiveDate, NaiveTime)>,
    sentences: u64,
    errors: u64,
    ignored: u64,
}

/// GPS seconds of week of a UTC date and time.
pub fn gps_seconds_of_week(date: NaiveDate, time: NaiveTime, leap_seconds: i64) -> f64 {
    let gps_epoch = NaiveDate::from_ymd_opt(1980, 1, 6).unwrap_or_default();
    let days = date.signed_duration_since(gps_epoch).num_days();
    let secs =
        days.rem_euclid(7) * 86_400 + i64::from(time.num_seconds_from_midnight()) + leap_seconds;
    let whole = secs.rem_euclid(WEEK_S as i64) as f64;
    whole + f64::from(time.nanosecond().min(999_999_999)) * 1e-9
}

impl NmeaAssembler {
    /// A fresh assembler.
    pub fn new(opts: NmeaOptions) -> Self {
        Self {
            opts,
            cur: Epoch::default(),
            expected: None,
            pending_vtg: None,
            last_date: None,
            sentences: 0,
            errors: 0,
            ignored: 0,
        }
    }

    /// Sentences seen.
    pub fn sentences(&self) -> u64 {
        self.sentences
    }

    /// Sentences rejected.
    pub fn errors(&self) -> u64 {
        self.errors
    }

    /// Sentences of types not used (GSA, GSV, ...).
    pub fn ignored(&self) -> u64 {
        self.ignored
    }

    /// Feeds one sentence (`$..*hh`, with or without CR/LF); returns completed fixes/errors.
    pub fn push_sentence(&mut self, text: &str) -> Vec<GnssEvent> {
        self.sentences += 1;
        let t = text.trim();
        let mut out = Vec::new();
        let parsed = nmea::parse_str(t);
        let result = match parsed {
            Err(e) => Err(e.to_string()),
            Ok(ParseResult::GGA(d)) => {
                let time = d.fix_time;
                self.timed(time, GGA, &mut out, |ep| ep.gga = Some(d))
            }
            Ok(ParseResult::RMC(d)) => {
                let time = d.fix_time;
                self.timed(time, RMC, &mut out, |ep| ep.rmc = Some(d))
            }
            Ok(ParseResult::GST(d)) => {
                let time = d.time;
                self.timed(time, GST, &mut out, |ep| ep.gst = Some(d))
            }
            Ok(ParseResult::VTG(d)) => {
                if self.cur.time.is_some() && !self.cur.emitted {
                    self.cur.vtg = Some(d);
                    self.cur.seen |= VTG;
                    self.maybe_emit(&mut out);
                } else {
                    self.pending_vtg = Some(d);
                }
                Ok(())
            }
            Ok(_) => {
                self.ignored += 1;
                Ok(())
            }
        };
        if let Err(reason) = result {
            self.errors += 1;
            out.push(GnssEvent::Error(GnssError::Nmea {
                index: self.sentences,
                sentence: t.chars().take(100).collect(),
                reason,
            }));
        }
        out
    }

    /// End of input: emits the epoch being assembled, if not yet emitted.
    pub fn flush(&mut self) -> Option<GnssEvent> {
        let ep = std::mem::take(&mut self.cur);
        self.finish(ep)
    }

    fn timed(
        &mut self,
        time: Option<NaiveTime>,
        bit: u8,
        out: &mut Vec<GnssEvent>,
        set: impl FnOnce(&mut Epoch),
    ) -> Result<(), String> {
        let time = time.ok_or_else(|| "sentence has no UTC time".to_string())?;
        if self.cur.time.is_some_and(|t| t != time) {
            let ep = std::mem::take(&mut self.cur);
            out.extend(self.finish(ep));
        }
        if self.cur.time.is_none() {
            self.cur.time = Some(time);
            if let Some(v) = self.pending_vtg.take() {
                self.cur.vtg = Some(v);
                self.cur.seen |= VTG;
            }
        }
        set(&mut self.cur);
        self.cur.seen |= bit;
        self.maybe_emit(out);
        Ok(())
    }

    fn maybe_emit(&mut self, out: &mut Vec<GnssEvent>) {
        if self.cur.emitted {
            return;
        }
        if let Some(e) = self.expected {
            if self.cur.seen & e == e {
                self.cur.emitted = true;
                out.push(self.build(&self.cur_snapshot()));
            }
        }
    }

    fn cur_snapshot(&self) -> Snapshot {
        Snapshot::of(&self.cur)
    }

    fn finish(&mut self, ep: Epoch) -> Option<GnssEvent> {
        ep.time?;
        self.expected = Some(ep.seen | GGA);
        if ep.emitted {
            return None;
        }
        let snap = Snapshot::of(&ep);
        Some(self.build(&snap))
    }

    fn build(&mut self, ep: &Snapshot) -> GnssEvent {
        let time = ep.time;
        let err = |reason: &str| {
            GnssEvent::Error(GnssError::Epoch {
                utc_time: time.format("%H:%M:%S%.3f").to_string(),
                reason: reason.to_string(),
            })
        };
        // Date: from this epoch's RMC, else carried over (next day when time wrapped).
        let date = match ep.rmc_date {
            Some(d) => Some(d),
            None => self
                .last_date
                .map(|(d, t)| if time < t { d + Duration::days(1) } else { d }),
        };
        if let Some(d) = date {
            self.last_date = Some((d, time));
        }
        let Some(gga) = ep.gga else {
            return err("no GGA sentence (position) in this epoch");
        };
        let Some(date) = date else {
            return err("no date yet: GPS time of week needs an RMC sentence with the date");
        };
        let t_s = gps_seconds_of_week(date, time, self.opts.leap_seconds);
        let quality = match (gga.fix_type, gga.lat, gga.lon) {
            (_, None, _) | (_, _, None) => FixQuality::NoFix,
            (Some(FixType::Gps | FixType::Pps), _, _) => FixQuality::Single,
            (Some(FixType::DGps), _, _) => FixQuality::Dgnss,
            (Some(FixType::Rtk), _, _) => FixQuality::RtkFixed,
            (Some(FixType::FloatRtk), _, _) => FixQuality::RtkFloat,
            _ => FixQuality::NoFix,
        };
        let nan3 = [f64::NAN; 3];
        let pos_std = match (ep.gst, gga.hdop, self.opts.hdop_uere_m) {
            (Some([n, e, d]), _, _) => [n, e, d],
            (None, Some(hdop), Some(uere)) => {
                let s = f64::from(hdop) * uere;
                [s, s, 1.5 * s]
            }
            _ => nan3,
        };
        // Speed over ground (knots) and course (deg true): RMC first, then VTG.
        let (sog_kn, cog_deg) = match ep.rmc_vel {
            (Some(s), c) => (Some(s), c),
            (None, _) => ep.vtg,
        };
        let vel_ne = match (sog_kn, cog_deg) {
            (Some(0.0), _) => Some([0.0, 0.0]),
            (Some(s), Some(c)) => {
                let v = f64::from(s) * 1852.0 / 3600.0;
                let c = f64::from(c).to_radians();
                Some([v * c.cos(), v * c.sin()])
            }
            _ => None,
        };
        let (has_velocity, vel, vel_std) = match (vel_ne, self.opts.velocity_std_mps) {
            (Some([vn, ve]), Some((sh, sv))) => (true, [vn, ve, 0.0], [sh, sh, sv]),
            (Some([vn, ve]), None) => (false, [vn, ve, 0.0], nan3),
            (None, _) => (false, [0.0; 3], nan3),
        };
        GnssEvent::Fix(GnssFix {
            t_s,
            lat_rad: gga.lat.map_or(f64::NAN, f64::to_radians),
            lon_rad: gga.lon.map_or(f64::NAN, f64::to_radians),
            h_m: gga.alt.map_or(f64::NAN, |a| a + gga.geoid.unwrap_or(0.0)),
            pos_std_ned_m: pos_std,
            vel_ned_mps: vel,
            vel_std_ned_mps: vel_std,
            has_velocity,
            quality,
            num_sats: gga.sats.map_or(0, |n| n.min(255) as u8),
        })
    }
}

/// The parts of an epoch the mapping uses (the `nmea` types are not `Clone`).
struct Snapshot {
    time: NaiveTime,
    gga: Option<GgaSnap>,
    rmc_date: Option<NaiveDate>,
    rmc_vel: (Option<f32>, Option<f32>),
    vtg: (Option<f32>, Option<f32>),
    gst: Option<[f64; 3]>,
}

#[derive(Clone, Copy)]
struct GgaSnap {
    fix_type: Option<FixType>,
    lat: Option<f64>,
    lon: Option<f64>,
    alt: Option<f64>,
    geoid: Option<f64>,
    hdop: Option<f32>,
    sats: Option<u32>,
}

impl Snapshot {
    fn of(ep: &Epoch) -> Self {
        Self {
            time: ep.time.unwrap_or_default(),
            gga: ep.gga.as_ref().map(|g| GgaSnap {
                fix_type: g.fix_type,
                lat: g.latitude,
                lon: g.longitude,
                alt: g.altitude.map(f64::from),
                geoid: g.geoid_separation.map(f64::from),
                hdop: g.hdop,
                sats: g.fix_satellites,
            }),
            rmc_date: ep.rmc.as_ref().and_then(|r| r.fix_date),
            rmc_vel: ep
                .rmc
                .as_ref()
                .map_or((None, None), |r| (r.speed_over_ground, r.true_course)),
            vtg: ep
                .vtg
                .as_ref()
                .map_or((None, None), |v| (v.speed_over_ground, v.true_course)),
            gst: ep.gst.as_ref().and_then(|g| {
                Some([
                    f64::from(g.lat_sd?),
                    f64::from(g.long_sd?),
                    f64::from(g.alt_sd?),
                ])
            }),
        }
    }
}
