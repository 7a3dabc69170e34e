//! A [`Scenario`] built in code: the start, the IMU rate and the segments one call each,
//! without TOML text.
//!
//! ```
//! use nav_sim::{Scenario, ScenarioBuilder};
//! let b = ScenarioBuilder::new("short")
//!     .start(30.5, 114.3, 20.0, 120.0)
//!     .gps_time(2300, 200000.0)
//!     .imu_rate_hz(100.0)
//!     .stationary(30.0)
//!     .accelerate(10.0, 10.0)
//!     .turn(90.0, 30.0)
//!     .cruise(30.0);
//! let toml = b.build();
//! assert!(toml.contains("[[segment]]\nkind = \"turn\"\nangle_deg = 90.0\nradius_m = 30.0\n"));
//! // the text reads back to the same scenario
//! let back = Scenario::from_toml_str(&toml, "doc").unwrap();
//! assert_eq!(back, b.scenario());
//! assert_eq!(back.segments.len(), 4);
//! assert_eq!(back.start.gps_week, 2300);
//! ```
use crate::scenario::{HeadingSpec, ImuRate, Scenario, Segment, Start, Vehicle, WheelSpeedSpec};

/// Builder of a [`Scenario`] and its TOML text. Without
/// [`start`](Self::start) / [`gps_time`](Self::gps_time) the start is 0 deg, 0 deg, 0 m,
/// heading 0, week 0, second 0; without [`imu_rate_hz`](Self::imu_rate_hz) the scenario's
/// default rate.
#[derive(Clone, Debug)]
pub struct ScenarioBuilder {
    scenario: Scenario,
}

impl ScenarioBuilder {
    /// A scenario named `name`, no segments yet.
    pub fn new(name: &str) -> Self {
        Self {
            scenario: Scenario {
                name: name.to_string(),
                description: String::new(),
                start: Start {
                    lat_deg: 0.0,
                    lon_deg: 0.0,
                    h_m: 0.0,
                    heading_deg: 0.0,
                    gps_week: 0,
                    sow_s: 0.0,
                },
                imu: ImuRate::default(),
                vehicle: Vehicle::default(),
                segments: Vec::new(),
            },
        }
    }

    /// `description = ...`.
    pub fn description(mut self, text: &str) -> Self {
        self.scenario.description = text.to_string();
        self
    }

    /// `[start]`: latitude and longitude (deg), height (m), heading (deg).
    pub fn start(mut self, lat_deg: f64, lon_deg: f64, h_m: f64, heading_deg: f64) -> Self {
        let s = &mut self.scenario.start;
        (s.lat_deg, s.lon_deg, s.h_m, s.heading_deg) = (lat_deg, lon_deg, h_m, heading_deg);
        self
    }

    /// `[start]` GPS week and seconds of week (s) of the first sample.
    pub fn gps_time(mut self, week: u16, sow_s: f64) -> Self {
        self.scenario.start.gps_week = week;
        self.scenario.start.sow_s = sow_s;
        self
    }

    /// `[imu] rate_hz`, Hz.
    pub fn imu_rate_hz(mut self, hz: f64) -> Self {
        self.scenario.imu.rate_hz = hz;
        self
    }

    /// `[vehicle.odometer]`: a wheel-speed odometer.
    pub fn odometer(mut self, spec: WheelSpeedSpec) -> Self {
        self.scenario.vehicle.odometer = Some(spec);
        self
    }

    /// `[vehicle.heading]`: a dual-antenna GNSS heading.
    pub fn heading(mut self, spec: HeadingSpec) -> Self {
        self.scenario.vehicle.heading = Some(spec);
        self
    }

    /// Any segment.
    pub fn segment(mut self, segment: Segment) -> Self {
        self.scenario.segments.push(segment);
        self
    }

    /// A `static` segment of `duration_s` seconds.
    pub fn stationary(self, duration_s: f64) -> Self {
        self.segment(Segment::Static { duration_s })
    }

    /// An `accelerate` segment to `to_speed_mps` (m/s) in `duration_s` seconds.
    pub fn accelerate(self, to_speed_mps: f64, duration_s: f64) -> Self {
        self.segment(Segment::Accelerate {
            delta_speed_mps: None,
            to_speed_mps: Some(to_speed_mps),
            duration_s,
        })
    }

    /// A `brake` segment to `to_speed_mps` (m/s) in `duration_s` seconds.
    pub fn brake(self, to_speed_mps: f64, duration_s: f64) -> Self {
        self.segment(Segment::Brake {
            delta_speed_mps: None,
            to_speed_mps: Some(to_speed_mps),
            duration_s,
        })
    }

    /// A `cruise` segment at constant speed for `duration_s` seconds.
    pub fn cruise(self, duration_s: f64) -> Self {
        self.segment(Segment::Cruise { duration_s })
    }

    /// A `turn` of `angle_deg` (positive right) on a circle of `radius_m` (m).
    pub fn turn(self, angle_deg: f64, radius_m: f64) -> Self {
        self.segment(Segment::Turn {
            angle_deg,
            rate_deg_s: None,
            radius_m: Some(radius_m),
            ramp_s: None,
        })
    }

    /// A `hill` of `height_m` (m) over `length_m` (m) of road.
    pub fn hill(self, height_m: f64, length_m: f64) -> Self {
        self.segment(Segment::Hill {
            height_m,
            length_m,
            ramp_s: None,
        })
    }

    /// A `stop`: brake to standstill (the segment's default deceleration).
    pub fn stop(self) -> Self {
        self.segment(Segment::Stop { duration_s: None })
    }

    /// The scenario.
    pub fn scenario(&self) -> Scenario {
        self.scenario.clone()
    }

    /// The TOML text ([`Scenario::to_toml_string`]).
    pub fn build(&self) -> String {
        self.scenario.to_toml_string()
    }
}
