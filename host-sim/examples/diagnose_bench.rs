//! Benchmark of a full `diagnose`: a 40-minute drive at 200 Hz (RTK at 1 Hz, the
//! source's tactical IMU, a temperature column so all 9 candidates are considered, one
//! undeclared effect: a 1000 ppm gyro z scale factor), 30 s GNSS outages every 100 s.
//!
//! `cargo run --release -p host-sim --example diagnose_bench` prints the simulation time, the
//! diagnose wall time (all rounds, candidates in parallel on the rayon pool: set
//! RAYON_NUM_THREADS=2 for the 2-core figure) and the result.
use host_sim::run::case_data;
use std::time::Instant;

use host_sim::run::cli::Prepared;
use nav_core::config::FilterConfig;
use nav_diagnose::{diagnose, DiagnoseOptions};
use nav_engine::run::{InitSpec, Model, PeriodicOutages, RunOptions};
use nav_sim::errors::{Axes3, Temperature};
use nav_sim::ScenarioBuilder;
use nav_sim::{simulate, ErrorModel, Scenario};
use test_support::truth_start::TRUTH_START_UNCERTAINTY;

fn scenario() -> Scenario {
    let mut b = ScenarioBuilder::new("diagnose-bench")
        .description("40 min at 200 Hz")
        .start(48.2, 16.37, 220.0, 30.0)
        .gps_time(2227, 118800.0)
        .imu_rate_hz(200.0)
        .stationary(30.0);
    // one lap is about 3.6 minutes; 11 laps
    for lap in 0..11 {
        let sp = 12.0 + f64::from(lap % 3) * 3.0;
        b = b
            .accelerate(sp, 8.0)
            .turn(90.0, 35.0)
            .cruise(40.0)
            .turn(-135.0, 30.0)
            .hill(6.0, 400.0)
            .cruise(40.0)
            .turn(180.0, 45.0)
            .brake(4.0, 6.0)
            .turn(-135.0, 12.0)
            .accelerate(sp, 7.0)
            .cruise(30.0)
            .stop()
            .stationary(10.0);
    }
    b.scenario()
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
        InitSpec::exact_truth(TRUTH_START_UNCERTAINTY),
    );
    // 30 s every 100 s from 150 s, the last ending at least 10 s before the data
    let outages = PeriodicOutages {
        first_start_s: 150.0,
        duration_s: 30.0,
        period_s: 100.0,
    };
    opts.outages = outages.expand(t0, t_end - 10.0);
    let p = Prepared {
        case: case_data(&case),
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
        let one = |t: &nav_diagnose::NoiseTuning| t.scales.len() - 1 + t.refinement.len();
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
