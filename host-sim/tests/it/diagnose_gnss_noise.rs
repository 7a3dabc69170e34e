//! The GNSS side of `nav_diagnose::diagnose` and of the robust gate: fixes whose declared sigmas
//! are too small. A slow rover (0.2 m/s, stops, RTK every 3 s declared at 6/4/10 mm, true errors
//! 10x that): the default run is not worse than the gate-off run, the diagnosis names the GNSS
//! noise scale (about 10) and writes it to `augmented.toml`, whose run is not worse than the
//! gate-off run either. A drive whose GNSS errors are 6x the declared (white and correlated)
//! gets a scale within 30 % of 6; a clean drive gets none.
use host_sim::diagnose::write_outputs;
use nav_core::config::Gating;
use nav_core::types::{GnssFix, ImuSample};
use nav_diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use nav_engine::metrics::Metrics;
use nav_engine::{Prepared, RunSpec};
use nav_sim::errors::Axes3;
use nav_sim::{simulate, ErrorModel};
use std::path::Path;
use test_support::runcase::TACTICAL_NOISE;
use test_support::scenario::ScenarioToml;

const WEEK: u16 = 2227;
const SOW0: f64 = 118_800.0;
/// The rover's declared RTK sigmas, north/east/down, m.
const DECLARED: [f64; 3] = [0.006, 0.004, 0.010];

/// A turn at 5 deg/s (the simulator's turn by radius needs 0.5 m/s).
fn slow_turn(angle_deg: f64) -> nav_sim::scenario::Segment {
    nav_sim::scenario::Segment::Turn {
        angle_deg,
        rate_deg_s: Some(5.0),
        radius_m: None,
        ramp_s: None,
    }
}

/// The slow rover of `run_slow_rover.rs`: 0.2 m/s, turns at 5 deg/s, three stops; about 5 min.
fn rover() -> ScenarioToml {
    ScenarioToml::new("slow-rover")
        .start(48.1990, 16.3700, 220.0, 130.0)
        .gps_time(WEEK, SOW0)
        .imu_rate_hz(125.0)
        .stationary(20.0)
        .accelerate(0.2, 2.0)
        .cruise(10.0)
        .segment(slow_turn(90.0))
        .cruise(30.0)
        .brake(0.0, 2.0)
        .stationary(15.0)
        .accelerate(0.2, 2.0)
        .segment(slow_turn(-120.0))
        .cruise(40.0)
        .brake(0.0, 2.0)
        .stationary(15.0)
        .accelerate(0.2, 2.0)
        .cruise(30.0)
        .segment(slow_turn(60.0))
        .cruise(40.0)
        .brake(0.0, 2.0)
        .stationary(5.0)
}

/// A car drive of about 8 minutes at 10-20 m/s with turns, hills and stops.
fn drive() -> ScenarioToml {
    let mut s = ScenarioToml::new("drive")
        .start(48.1990, 16.3700, 220.0, 40.0)
        .gps_time(WEEK, SOW0)
        .imu_rate_hz(100.0)
        .stationary(30.0);
    for lap in 0..2 {
        let l = f64::from(lap);
        s = s
            .accelerate(12.0 + 3.0 * l, 8.0)
            .turn(90.0, 30.0)
            .cruise(20.0)
            .turn(-135.0, 25.0)
            .hill(6.0, 300.0)
            .accelerate(18.0, 6.0)
            .turn(180.0, 40.0)
            .brake(4.0, 6.0)
            .turn(-90.0, 12.0)
            .accelerate(14.0, 7.0)
            .hill(-5.0, 250.0)
            .stop()
            .stationary(10.0);
    }
    s
}

/// Writes IMU, GNSS (text format) and truth of `sc` simulated with `errors`, and a run
/// configuration with the tactical noise and a static alignment; returns its path.
fn write_case(dir: &Path, sc: &ScenarioToml, errors: &ErrorModel, seed: u64) -> std::path::PathBuf {
    let case = simulate(&sc.scenario(), errors, seed).unwrap();
    let imu: &[ImuSample] = &case.meas.imu;
    let gnss: &[GnssFix] = &case.meas.gnss;
    nav_io::write_imu_text(dir.join("imu.txt"), imu).unwrap();
    nav_io::write_gnss_text(dir.join("gnss.txt"), gnss).unwrap();
    nav_io::write_nav_text(dir.join("truth.nav"), &case.trajectory.truth).unwrap();
    let cfg = format!(
        r#"name = "gnss-noise"
[imu]
path = "imu.txt"
format = "text"
[gnss]
path = "gnss.txt"
format = "text"
[truth]
path = "truth.nav"
format = "nav_text"
[init]
pos_std_m = [0.05, 0.05, 0.1]
vel_std_mps = [0.05, 0.05, 0.05]
att_std_deg = [1.0, 1.0, 5.0]
[init.align]
static_s = 10.0
{TACTICAL_NOISE}"#
    );
    let p = dir.join("run.toml");
    std::fs::write(&p, cfg).unwrap();
    p
}

fn load(config: &Path, gate: Option<Gating>) -> Prepared {
    let mut spec = RunSpec::new(config);
    spec.set.filter.gating = gate;
    nav_engine::load(&spec, false).unwrap().prepared
}

/// Horizontal RMS error against the truth, m, and the run's metrics.
fn run_error(p: &Prepared) -> (f64, Metrics) {
    let (_, m) = nav_engine::execute(p, &mut |_, _| {}).unwrap();
    assert_eq!(m.reference, "truth");
    (m.overall.pos_horizontal_m.rms, m)
}

/// The diagnosis's GNSS noise scale (horizontal, vertical) of the final model, when named
/// (the configurations here declare no scale: the final scale is the fitted one).
fn gnss_scale(d: &Diagnosis) -> Option<(f64, f64)> {
    let g = d.final_gnss_sigma_scale?;
    assert!(d.verdict.contains("GNSS noise scale"), "{}", d.verdict);
    Some((g.horizontal, g.vertical))
}

fn summary(d: &Diagnosis) -> String {
    let mut s = format!("verdict: {}\n", d.verdict);
    for st in &d.steps {
        s += &format!(
            "  step {}{}: GNSS prior residual {:.3} m, NIS {:.2}{}\n",
            st.label,
            if st.accepted { "" } else { " (refused)" },
            st.errors.gnss_prior_horizontal_rms_m,
            st.errors.nis_mean,
            st.reason
                .as_deref()
                .map_or(String::new(), |r| format!(": {r}"))
        );
    }
    if let Some(t) = &d.noise_tuning {
        s += &format!(
            "  noise tuning: {} (adopted {}), NIS {:.2} -> {:.2} (expected {:.1})\n",
            t.chosen.describe(),
            t.adopted,
            t.nis_before,
            t.nis_after,
            t.nis_expected
        );
    }
    s
}

fn rover_errors(factor: f64) -> ErrorModel {
    let mut e = ErrorModel::preset("tactical").unwrap();
    e.gnss.rate_hz = 1.0 / 3.0;
    e.gnss.white_sigma_ned_m = Axes3(DECLARED.map(|s| s * factor));
    e.gnss.gm_sigma_ned_m = Axes3([0.0; 3]);
    e.gnss.reported_std_ned_m = Some(Axes3(DECLARED));
    e
}

/// The robust gate against the gate off on the rover with 10x understated sigmas. The gate
/// does not know the innovation level of the first fixes: until it has seen 10
/// (`RobustGating::warmup_fixes`) it rejects only beyond the re-acquisition gate (x100), and
/// once the level is known (a persistent mismatch) it is widened to twice the window median.
/// Before (rejection from the third fix on, the gate at the median): 4 fixes rejected, 2
/// down-weighted, horizontal RMS 0.158 m against 0.099 m with the gate off.
#[test]
fn rover_with_understated_rtk_sigmas_default_gate_not_worse_than_gate_off() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_case(dir.path(), &rover(), &rover_errors(10.0), 7);
    let (e_default, m_default) = run_error(&load(&cfg, None));
    let (e_off, m_off) = run_error(&load(&cfg, Some(Gating::disabled())));
    let g = &m_default.gating;
    println!(
        "rover 10x: horizontal RMS default gate {e_default:.4} m, gate off {e_off:.4} m; \
         GNSS prior residual {:.4} / {:.4} m; {} rejected, {} down-weighted; {}",
        m_default.gnss_residuals.horizontal_m.rms,
        m_off.gnss_residuals.horizontal_m.rms,
        m_default.gnss_residuals.rejected,
        g.downweighted,
        g.message
    );
    assert!(
        e_default <= e_off * 1.02,
        "default {e_default} m vs gate off {e_off} m"
    );
    // every fix used (a few down-weighted), and the run says the innovations were larger
    // than predicted (the diagnosis names the GNSS noise scale, see the next test)
    assert_eq!(m_default.gnss_residuals.rejected, 0);
    assert!(g.downweighted <= 3, "{g:?}");
    assert!(g.max_gate_widening > 50.0, "{g:?}");
    assert!(g.message.contains("larger than predicted"), "{}", g.message);
    // the learned sigma scale stays opt-in
    assert_eq!(g.sigma_scaled_fixes, 0);
}

#[test]
fn rover_with_understated_rtk_sigmas_gets_a_gnss_scale_near_10() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_case(dir.path(), &rover(), &rover_errors(10.0), 7);
    let (e_off, _) = run_error(&load(&cfg, Some(Gating::disabled())));
    let p = load(&cfg, None);
    let d = diagnose(&p, &DiagnoseOptions::default()).unwrap();
    let out = dir.path().join("diag");
    write_outputs(&out, &p, &d, Some(&cfg)).unwrap();
    println!("{}", summary(&d.diagnosis));
    let (kh, kv) = gnss_scale(&d.diagnosis).expect("GNSS noise scale named");
    println!("rover 10x: GNSS noise scale horizontal {kh} vertical {kv}");
    assert!((5.0..=20.0).contains(&kh), "horizontal scale {kh}");
    assert!((5.0..=20.0).contains(&kv), "vertical scale {kv}");
    // the augmented configuration carries it, and its run is not worse than the gate-off run
    let aug = out.join("augmented.toml");
    let text = std::fs::read_to_string(&aug).unwrap();
    assert!(text.contains("sigma_scale"), "{text}");
    let pa = load(&aug, None);
    assert_eq!(pa.opts.gnss_sigma_scale.horizontal, kh);
    assert_eq!(pa.opts.gnss_sigma_scale.vertical, kv);
    let (e_after, _) = run_error(&pa);
    println!("rover 10x: after (augmented.toml) {e_after:.4} m vs gate off {e_off:.4} m");
    assert!(
        e_after <= e_off * 1.02,
        "after {e_after} m vs gate off {e_off} m"
    );
}

fn drive_errors(white: f64, gm: f64) -> ErrorModel {
    let mut e = ErrorModel::preset("tactical").unwrap();
    // declared 2 / 2 / 4 cm; true white and Gauss-Markov parts scaled
    let w = [0.015, 0.015, 0.03];
    let c = [0.013, 0.013, 0.026];
    e.gnss.white_sigma_ned_m = Axes3(w.map(|s| s * white));
    e.gnss.gm_sigma_ned_m = Axes3(c.map(|s| s * gm));
    e.gnss.gm_tau_s = 30.0;
    e.gnss.reported_std_ned_m = Some(Axes3([0.02, 0.02, 0.04]));
    e
}

#[test]
fn drive_with_gnss_errors_6x_the_declared_gets_a_scale_near_6() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_case(dir.path(), &drive(), &drive_errors(6.0, 5.0), 11);
    let p = load(&cfg, None);
    let d = diagnose(&p, &DiagnoseOptions::default()).unwrap();
    println!("{}", summary(&d.diagnosis));
    let (kh, kv) = gnss_scale(&d.diagnosis).expect("GNSS noise scale named");
    println!("drive 6x: GNSS noise scale horizontal {kh} vertical {kv}");
    assert!((kh / 6.0 - 1.0).abs() <= 0.3, "horizontal scale {kh}");
    assert!((kv / 6.0 - 1.0).abs() <= 0.3, "vertical scale {kv}");
}

#[test]
fn clean_drive_gets_no_gnss_scale() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = write_case(dir.path(), &drive(), &drive_errors(1.0, 1.0), 11);
    let p = load(&cfg, None);
    let d = diagnose(&p, &DiagnoseOptions::default()).unwrap();
    println!("{}", summary(&d.diagnosis));
    let t = d.diagnosis.noise_tuning.as_ref().unwrap();
    println!(
        "clean drive: GNSS scale estimate {:?}",
        t.final_gnss_scale()
    );
    assert_eq!(gnss_scale(&d.diagnosis), None);
}
