//! Benchmark of a full `diagnose` (issue 7): a 40-minute drive at 200 Hz (RTK at 1 Hz, the
//! source's tactical IMU, a temperature column so all 9 candidates are considered, one
//! undeclared effect: a 1000 ppm gyro z scale factor), 30 s GNSS outages every 100 s.
//!
//! `cargo run --release -p host-sim --example diagnose_bench` prints the simulation time, the
//! diagnose wall time (all rounds, candidates in parallel on the rayon pool: set
//! RAYON_NUM_THREADS=2 for the 2-core figure) and the result.
use std::time::Instant;

use host_sim::diagnose::{diagnose, DiagnoseOptions};
use host_sim::run::cli::Prepared;
use host_sim::run::{CaseData, InitSpec, Model, Outage, RunOptions};
use host_sim::sim::errors::{Axes3, Temperature};
use host_sim::sim::{simulate, ErrorModel, Scenario};
use nav_core::config::FilterConfig;
use nav_core::filter::InitialUncertainty;

fn scenario() -> Scenario {
    let mut s = String::from(
        r#"
name = "diagnose-bench"
description = "40 min at 200 Hz"
[start]
lat_deg = 48.2
lon_deg = 16.37
h_m = 220.0
heading_deg = 30.0
gps_week = 2227
sow_s = 118800.0
[imu]
rate_hz = 200.0
[[segment]]
kind = "static"
duration_s = 30.0
"#,
    );
    // one lap is about 3.6 minutes; 11 laps
    for lap in 0..11 {
        let sp = 12.0 + f64::from(lap % 3) * 3.0;
        s.push_str(&format!(
            r#"
[[segment]]
kind = "accelerate"
to_speed_mps = {sp}
duration_s = 8.0
[[segment]]
kind = "turn"
angle_deg = 90.0
radius_m = 35.0
[[segment]]
kind = "cruise"
duration_s = 40.0
[[segment]]
kind = "turn"
angle_deg = -135.0
radius_m = 30.0
[[segment]]
kind = "hill"
height_m = 6.0
length_m = 400.0
[[segment]]
kind = "cruise"
duration_s = 40.0
[[segment]]
kind = "turn"
angle_deg = 180.0
radius_m = 45.0
[[segment]]
kind = "brake"
to_speed_mps = 4.0
duration_s = 6.0
[[segment]]
kind = "turn"
angle_deg = -135.0
radius_m = 12.0
[[segment]]
kind = "accelerate"
to_speed_mps = {sp}
duration_s = 7.0
[[segment]]
kind = "cruise"
duration_s = 30.0
[[segment]]
kind = "stop"
[[segment]]
kind = "static"
duration_s = 10.0
"#
        ));
    }
    Scenario::from_toml_str(&s, "diagnose-bench").expect("scenario")
}

fn main() {
    let mut e = ErrorModel::preset("seed-nbk").expect("preset");
    e.temperature = Some(Temperature {
        start_c: 15.0,
        rise_c: 25.0,
        tau_s: 600.0,
        reference_c: None,
        report_noise_c: 0.02,
    });
    e.gyro.scale_factor_ppm = Axes3([0.0, 0.0, 1000.0]);
    let t = Instant::now();
    let case = simulate(&scenario(), &e, 42).expect("simulate");
    let t0 = case.meas.imu[0].t_s;
    let t_end = case.meas.imu.last().map_or(t0, |s| s.t_s);
    println!(
        "simulated {:.1} min, {} IMU samples, {} fixes in {:.1} s",
        (t_end - t0) / 60.0,
        case.meas.imu.len(),
        case.meas.gnss.len(),
        t.elapsed().as_secs_f64()
    );
    let mut opts = RunOptions::new(
        Model::Nbk,
        FilterConfig::source_nbk_model(),
        InitSpec::FromTruth {
            pos_err_m: [0.0; 3],
            vel_err_mps: [0.0; 3],
            att_err_rad: [0.0; 3],
            unc: InitialUncertainty {
                att_sigma_rad: [1e-4, 1e-4, 5e-4],
                vel_sigma_mps: [0.01; 3],
                pos_sigma_m: [0.02; 3],
            },
        },
    );
    let mut start = t0 + 150.0;
    while start + 30.0 < t_end - 10.0 {
        opts.outages.push(Outage {
            start_s: start,
            duration_s: 30.0,
        });
        start += 100.0;
    }
    let p = Prepared {
        case: CaseData::from(&case),
        opts,
        week: 2227,
        description: "diagnose benchmark".into(),
    };
    let t = Instant::now();
    let d = diagnose(&p, &DiagnoseOptions::default()).expect("diagnose");
    let secs = t.elapsed().as_secs_f64();
    let dg = &d.diagnosis;
    let runs: usize = dg.rounds.iter().map(|r| r.candidates.len()).sum();
    let noise_runs = dg.noise_tuning.as_ref().map_or(0, |t| {
        let one = |t: &host_sim::diagnose::NoiseTuning| t.scales.len() - 1 + t.refinement.len();
        one(t) + t.with_effects.as_deref().map_or(0, |t2| one(t2) + 1)
    });
    println!(
        "diagnose: {secs:.1} s on {} threads ({} rounds, {} candidate runs, {} noise-tuning runs, \
         {} steps + 2 full runs); verdict: {}",
        rayon::current_num_threads(),
        dg.rounds.len(),
        runs,
        noise_runs,
        dg.steps.len(),
        dg.verdict
    );
    for a in &dg.added_effects {
        println!("  {} {:?} +- {:?}", a.name, a.estimate, a.sigma);
    }
    println!(
        "outage error before {:.3} m, after {:.3} m",
        dg.error_before.outage_max_3d_rms_m, dg.error_after.outage_max_3d_rms_m
    );
}
