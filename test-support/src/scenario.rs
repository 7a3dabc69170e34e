//! The simulator's scenario built in code for the tests: `ScenarioToml` is
//! `nav_sim::ScenarioBuilder` (the product's scenario types, one definition of the format),
//! and the drives several tests share.
//!
//! ```
//! use test_support::scenario::four_minute_drive;
//! let sc = four_minute_drive("doc").scenario();
//! assert_eq!(sc.imu.rate_hz, 100.0);
//! assert_eq!(sc.segments.len(), 10);
//! ```

/// The builder of a scenario and its TOML text (`nav_sim::ScenarioBuilder`).
pub use nav_sim::ScenarioBuilder as ScenarioToml;

/// The 4-minute test drive of the `host-sim run` tests, named `name`: 100 Hz, 30 s static,
/// accelerate to 10 m/s, 90 deg right on 30 m, cruise 30 s, 180 deg left on 25 m, accelerate
/// to 15 m/s, cruise 2 min, 45 deg right on 50 m, brake to a stop, 10 s static.
pub fn four_minute_drive(name: &str) -> ScenarioToml {
    ScenarioToml::new(name)
        .description("4 min test drive")
        .start(30.5, 114.3, 20.0, 120.0)
        .gps_time(2300, 200000.0)
        .imu_rate_hz(100.0)
        .stationary(30.0)
        .accelerate(10.0, 10.0)
        .turn(90.0, 30.0)
        .cruise(30.0)
        .turn(-180.0, 25.0)
        .accelerate(15.0, 10.0)
        .cruise(120.0)
        .turn(45.0, 50.0)
        .brake(0.0, 10.0)
        .stationary(10.0)
}

/// The short drive of the bridge's replay tests (`hw-bridge/tests/it/e2e_pty.rs`,
/// `tests/tests/it/bridge_replay.rs`), named `name`: 200 Hz, 20 s static, accelerate to 12 m/s,
/// 90 deg right on 40 m, cruise 40 s, 60 deg left on 50 m, brake to a stop, 5 s static
/// (about 90 s).
pub fn bridge_replay_drive(name: &str) -> ScenarioToml {
    ScenarioToml::new(name)
        .description("short drive for the bridge's send/record/replay tests")
        .start(48.2, 16.37, 220.0, 30.0)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(200.0)
        .stationary(20.0)
        .accelerate(12.0, 8.0)
        .turn(90.0, 40.0)
        .cruise(40.0)
        .turn(-60.0, 50.0)
        .brake(0.0, 8.0)
        .stationary(5.0)
}

/// The 6-minute drive of the run and smoother simulation tests (`nav-engine/tests/it/run_sim.rs`,
/// `smooth_sim.rs`), named `name`: 100 Hz, 60 s static, accelerate to 12 m/s, cruise, 90 deg
/// right on 40 m, a 5 m hill over 300 m, 120 deg left on 30 m, accelerate to 18 m/s, 60 deg
/// right on 60 m, brake to a stop, 20 s static.
pub fn six_minute_drive(name: &str) -> ScenarioToml {
    ScenarioToml::new(name)
        .description("6 min test drive")
        .start(48.199, 16.37, 220.0, 30.0)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(100.0)
        .stationary(60.0)
        .accelerate(12.0, 10.0)
        .cruise(30.0)
        .turn(90.0, 40.0)
        .cruise(40.0)
        .hill(5.0, 300.0)
        .turn(-120.0, 30.0)
        .accelerate(18.0, 10.0)
        .cruise(40.0)
        .turn(60.0, 60.0)
        .brake(0.0, 10.0)
        .stationary(20.0)
}
