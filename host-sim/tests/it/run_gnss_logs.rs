//! A run from raw files with a configuration only, with an NMEA log and a UBX log
//! as the GNSS input. A simulated drive's fixes are written as NMEA RMC/GGA/GST and as UBX
//! NAV-PVT by `nav_io::gnss::encode`; `host-sim run` on each gives the accuracy of the run on
//! the simulator's own GNSS text file, and the UBX run gets its GPS week from NAV-PVT's UTC
//! date.
use nav_io::gnss::encode::{nmea_epoch, ubx_nav_pvt};
use std::path::Path;
use test_support::cli::Bin;
use test_support::runcase::{case_config, run_case, simulate_case, TACTICAL_NOISE};
use test_support::scenario::four_minute_drive;

const HOST_SIM: Bin = Bin::new(env!("CARGO_BIN_EXE_host-sim"));

const WEEK: i64 = 2300;
const LEAP_S: i32 = 18;

fn config(case: &Path, gnss: &str, format: &str, log: &str) -> String {
    case_config(
        &format!("gnss-{format}"),
        case,
        gnss,
        format,
        log,
        TACTICAL_NOISE,
    )
}

/// (horizontal RMS outside the outage, horizontal error at the outage's end, first week in
/// nav.txt, run output)
fn run(dir: &Path, name: &str, cfg: &str) -> (f64, f64, u16, String) {
    let (so, out) = run_case(HOST_SIM, dir, name, cfg);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["reference"], "truth", "{name}");
    let nav = nav_io::read_nav_text(out.join("nav.txt")).unwrap();
    (
        m["outside_outages"]["pos_horizontal_m"]["rms"]
            .as_f64()
            .unwrap(),
        m["per_outage"][0]["end"]["horizontal_m"].as_f64().unwrap(),
        nav[0].week,
        so,
    )
}

#[test]
fn runs_from_nmea_and_ubx_logs_match_the_run_from_the_gnss_text() {
    let dir = tempfile::tempdir().unwrap();
    // the 4-minute test drive, in Seattle heading 30 deg
    let case = simulate_case(
        HOST_SIM,
        dir.path(),
        "case",
        &four_minute_drive("gnss-logs-drive")
            .start(47.6, -122.3, 40.0, 30.0)
            .build(),
        "tactical",
        5,
    );
    // The simulated receiver is an RTK one (the text file has no quality column); the
    // simulator writes no GNSS velocity, so the receiver's is the truth's plus white noise
    // of the rtk preset's 0.02 m/s (deterministic normals).
    let truth = nav_io::read_nav_text(case.join("truth.nav")).unwrap();
    let mut fixes = nav_io::read_gnss_text(case.join("gnss.txt")).unwrap();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut normal = move || {
        let mut u = || {
            seed ^= seed >> 12;
            seed ^= seed << 25;
            seed ^= seed >> 27;
            ((seed.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (a, b) = (u(), u());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    };
    for f in &mut fixes {
        f.quality = nav_core::types::FixQuality::RtkFixed;
        let k = truth
            .partition_point(|s| s.t_s < f.t_s)
            .min(truth.len() - 1);
        assert!((truth[k].t_s - f.t_s).abs() < 1e-3, "truth at the fix time");
        for i in 0..3 {
            f.vel_ned_mps[i] = truth[k].vel_ned_mps[i] + 0.02 * normal();
        }
        f.vel_std_ned_mps = [0.02; 3];
        f.has_velocity = true;
    }
    assert!(fixes.len() > 200);
    let nmea: String = fixes
        .iter()
        .flat_map(|f| nmea_epoch(f, WEEK, LEAP_S))
        .map(|l| l + "\r\n")
        .collect();
    std::fs::write(case.join("gnss.nmea"), nmea).unwrap();
    let ubx: Vec<u8> = fixes
        .iter()
        .flat_map(|f| ubx_nav_pvt(f, WEEK, LEAP_S))
        .collect();
    std::fs::write(case.join("gnss.ubx"), ubx).unwrap();

    // the logs read back to the fixes within the formats' resolution
    let opts = nav_io::GnssLogOptions {
        vel_sigma_mps: Some([0.02, 0.05]),
        ..nav_io::GnssLogOptions::default()
    };
    for (label, r) in [
        (
            "nmea",
            nav_io::read_nmea_log(case.join("gnss.nmea"), &opts, 1).unwrap(),
        ),
        (
            "ubx",
            nav_io::read_ubx_log(case.join("gnss.ubx"), &opts, 1).unwrap(),
        ),
    ] {
        assert_eq!(r.fixes.len(), fixes.len(), "{label}");
        let mut worst = [0.0f64; 4];
        for (a, b) in r.fixes.iter().zip(&fixes) {
            let dn = (a.lat_rad - b.lat_rad) * 6.37e6;
            let de = (a.lon_rad - b.lon_rad) * 6.37e6 * b.lat_rad.cos();
            worst[0] = worst[0].max((a.t_s - b.t_s).abs());
            worst[1] = worst[1].max(dn.hypot(de));
            worst[2] = worst[2].max((a.h_m - b.h_m).abs());
            worst[3] = worst[3].max(
                (a.vel_ned_mps[0] - b.vel_ned_mps[0]).hypot(a.vel_ned_mps[1] - b.vel_ned_mps[1]),
            );
        }
        println!("{label}: worst |dt| {:.2e} s, horizontal {:.2e} m, height {:.2e} m, velocity {:.2e} m/s", worst[0], worst[1], worst[2], worst[3]);
        assert!(
            worst[0] < 1e-6 && worst[1] < 0.01 && worst[2] < 1e-3 && worst[3] < 5e-3,
            "{label}: {worst:?}"
        );
    }
    let (rms_t, out_t, _, so) = run(dir.path(), "text", &config(&case, "gnss.txt", "text", ""));
    println!("text:\n{so}");
    // NMEA: speed and course only (no vertical velocity): sigmas stated in [gnss.log]
    let (rms_n, out_n, week_n, so) = run(
        dir.path(),
        "nmea",
        &config(
            &case,
            "gnss.nmea",
            "nmea",
            "[gnss.log]\nvel_sigma_mps = [0.02, 0.05]",
        ),
    );
    println!("nmea:\n{so}");
    let (rms_u, out_u, week_u, so) = run(dir.path(), "ubx", &config(&case, "gnss.ubx", "ubx", ""));
    println!("ubx:\n{so}");
    println!(
        "horizontal RMS with GNSS: text {rms_t:.4} m, NMEA {rms_n:.4} m, UBX {rms_u:.4} m; \
         30 s outage end: {out_t:.3} / {out_n:.3} / {out_u:.3} m"
    );
    assert_eq!(week_n, WEEK as u16);
    assert_eq!(week_u, WEEK as u16, "the week from NAV-PVT's UTC date");
    // Measured (seed 5): text 0.0363 m, NMEA 0.0369 m, UBX 0.0424 m with GNSS; outage end
    // 0.451 / 0.462 / 0.539 m. UBX is a little worse: NAV-PVT's 1e-7 deg (11 mm) position
    // resolution and hAcc (the larger horizontal sigma) for both axes.
    for (label, rms, out) in [("NMEA", rms_n, out_n), ("UBX", rms_u, out_u)] {
        assert!(rms < 0.15, "{label}: {rms} m");
        assert!(
            rms < 1.1 * rms_t + 0.005,
            "{label}: {rms} m vs text {rms_t} m"
        );
        assert!(
            out < 1.2 * out_t + 0.1,
            "{label}: {out} m vs text {out_t} m"
        );
    }
}
