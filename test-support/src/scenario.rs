//! The scenario TOML of host-sim's simulator (`host_sim::sim::Scenario`, format in
//! `scenarios/*.toml`), built in code: one builder instead of the same `[start]` /
//! `[[segment]]` text written inline in every test.
//!
//! ```
//! use test_support::scenario::ScenarioToml;
//! let toml = ScenarioToml::new("short")
//!     .start(30.5, 114.3, 20.0, 120.0)
//!     .gps_time(2300, 200000.0)
//!     .imu_rate_hz(100.0)
//!     .stationary(30.0)
//!     .accelerate(10.0, 10.0)
//!     .turn(90.0, 30.0)
//!     .cruise(30.0)
//!     .build();
//! assert!(toml.contains("[[segment]]\nkind = \"turn\"\nangle_deg = 90.0\nradius_m = 30.0\n"));
//! ```
use std::fmt::Write as _;

/// Builder of a scenario TOML text. Numbers are written with `{:?}` (always with a decimal
/// point, the shortest text that reads back to the same f64).
#[derive(Clone, Debug)]
pub struct ScenarioToml {
    name: String,
    description: Option<String>,
    start: Option<(f64, f64, f64, f64)>,
    gps_time: Option<(u32, f64)>,
    imu_rate_hz: Option<f64>,
    segments: String,
}

impl ScenarioToml {
    /// A scenario named `name`, no segments yet.
    pub fn new(name: &str) -> Self {
        Self {
            name: name.to_string(),
            description: None,
            start: None,
            gps_time: None,
            imu_rate_hz: None,
            segments: String::new(),
        }
    }

    /// `description = ...`.
    pub fn description(mut self, text: &str) -> Self {
        self.description = Some(text.to_string());
        self
    }

    /// `[start]`: latitude and longitude (deg), height (m), heading (deg).
    pub fn start(mut self, lat_deg: f64, lon_deg: f64, h_m: f64, heading_deg: f64) -> Self {
        self.start = Some((lat_deg, lon_deg, h_m, heading_deg));
        self
    }

    /// `[start]` GPS week and seconds of week of the first sample.
    pub fn gps_time(mut self, week: u32, sow_s: f64) -> Self {
        self.gps_time = Some((week, sow_s));
        self
    }

    /// `[imu] rate_hz` (the scenario's default when not given).
    pub fn imu_rate_hz(mut self, hz: f64) -> Self {
        self.imu_rate_hz = Some(hz);
        self
    }

    fn segment(mut self, kind: &str, fields: &[(&str, f64)]) -> Self {
        let _ = writeln!(self.segments, "[[segment]]\nkind = \"{kind}\"");
        for (k, v) in fields {
            let _ = writeln!(self.segments, "{k} = {v:?}");
        }
        self
    }

    /// A `static` segment of `duration_s` seconds.
    pub fn stationary(self, duration_s: f64) -> Self {
        self.segment("static", &[("duration_s", duration_s)])
    }

    /// An `accelerate` segment to `to_speed_mps` (m/s) in `duration_s` seconds.
    pub fn accelerate(self, to_speed_mps: f64, duration_s: f64) -> Self {
        self.segment(
            "accelerate",
            &[("to_speed_mps", to_speed_mps), ("duration_s", duration_s)],
        )
    }

    /// A `brake` segment to `to_speed_mps` (m/s) in `duration_s` seconds.
    pub fn brake(self, to_speed_mps: f64, duration_s: f64) -> Self {
        self.segment(
            "brake",
            &[("to_speed_mps", to_speed_mps), ("duration_s", duration_s)],
        )
    }

    /// A `cruise` segment at constant speed for `duration_s` seconds.
    pub fn cruise(self, duration_s: f64) -> Self {
        self.segment("cruise", &[("duration_s", duration_s)])
    }

    /// A `turn` of `angle_deg` (positive right) on a circle of `radius_m`.
    pub fn turn(self, angle_deg: f64, radius_m: f64) -> Self {
        self.segment("turn", &[("angle_deg", angle_deg), ("radius_m", radius_m)])
    }

    /// A `hill` of `height_m` over `length_m` of road.
    pub fn hill(self, height_m: f64, length_m: f64) -> Self {
        self.segment("hill", &[("height_m", height_m), ("length_m", length_m)])
    }

    /// A `stop`: brake to standstill (the segment's default deceleration).
    pub fn stop(mut self) -> Self {
        self.segments.push_str("[[segment]]\nkind = \"stop\"\n");
        self
    }

    /// The TOML text.
    pub fn build(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "name = {:?}", self.name);
        if let Some(d) = &self.description {
            let _ = writeln!(s, "description = {d:?}");
        }
        if self.start.is_some() || self.gps_time.is_some() {
            s.push_str("[start]\n");
            if let Some((lat, lon, h, hdg)) = self.start {
                let _ = writeln!(
                    s,
                    "lat_deg = {lat:?}\nlon_deg = {lon:?}\nh_m = {h:?}\nheading_deg = {hdg:?}"
                );
            }
            if let Some((week, sow)) = self.gps_time {
                let _ = writeln!(s, "gps_week = {week}\nsow_s = {sow:?}");
            }
        }
        if let Some(hz) = self.imu_rate_hz {
            let _ = writeln!(s, "[imu]\nrate_hz = {hz:?}");
        }
        s.push_str(&self.segments);
        s
    }
}
