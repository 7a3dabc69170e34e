//! Your own IMU/GNSS stream through the navigator.
//!
//! ```text
//! cargo run -p nav-core --example own_stream                     # a generated 120 s drive
//! cargo run -p nav-core --example own_stream -- IMU.txt GNSS.txt # your files
//! ```
//!
//! File formats (whitespace-separated, one record a line, `#` starts a comment line, time
//! order):
//!
//! * IMU (the KF-GINS IMU text format): `t_s dtheta_x dtheta_y dtheta_z dv_x dv_y dv_z`:
//!   GPS seconds of week at the END of the sample interval, angle increments (rad) and
//!   velocity increments (m/s) over the interval since the previous sample, body axes
//!   forward-right-down.
//! * GNSS: `t_s lat_deg lon_deg h_m sd_n_m sd_e_m sd_d_m [vn ve vd sd_vn sd_ve sd_vd]`:
//!   antenna position (WGS84, ellipsoidal height) with 1-sigma north/east/down (m), and
//!   optionally the NED velocity with its 1-sigma (m/s).
//!
//! The navigator starts on the first valid fix (roll and pitch from levelling the samples
//! before it, yaw from the GNSS course when the fix has a velocity above 2 m/s), runs the
//! NBK model (18 states, f32 covariance, the MCU's configuration), applies every fix at the
//! IMU epoch nearest to it, and prints a solution every 10 s and at the end.

use nalgebra::Vector3;
use nav_core::config::FilterConfig;
use nav_core::earth::{self, Llh};
use nav_core::model::LAYOUT_NBK;
use nav_core::navigator::{
    AlignMode, FirstFixAlign, FixEvent, GnssEvent, NavigatorConfig, NavigatorNbk,
};
use nav_core::strapdown::{NavState, Strapdown};
use nav_core::types::{FixQuality, GnssFix, ImuSample, NavSolution};
use std::error::Error;

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (imu, gnss, truth) = match args.as_slice() {
        [] => {
            let (imu, gnss, truth) = generate(120.0, 100.0);
            println!(
                "generated: {} IMU samples (100 Hz), {} GNSS fixes (1 Hz), a 10 m/s drive \
                 heading 60 deg",
                imu.len(),
                gnss.len()
            );
            (imu, gnss, Some(truth))
        }
        [i, g] => (read_imu(i)?, read_gnss(g)?, None),
        _ => return Err("usage: own_stream [IMU.txt GNSS.txt] (formats: see the source)".into()),
    };

    let mut cfg = FilterConfig::source_nbk_model();
    cfg.use_gnss_velocity = gnss.iter().any(|g| g.has_velocity);
    let align = AlignMode::FirstFix(FirstFixAlign::default());
    let mut nav = NavigatorNbk::new(LAYOUT_NBK, NavigatorConfig::new(cfg, align))?;

    let mut fixes = gnss.iter().peekable();
    let mut next_print = f64::NEG_INFINITY;
    let mut rejected = 0;
    for s in &imu {
        // every fix up to this sample's time first (it waits for the nearest epoch)
        while let Some(g) = fixes.next_if(|g| g.t_s <= s.t_s) {
            if let GnssEvent::Aligned(a) = nav.push_gnss(g)? {
                println!(
                    "aligned at {:.2} s: roll {:.2} pitch {:.2} yaw {:.2} deg (heading {})",
                    a.t_s,
                    a.rpy_rad[0].to_degrees(),
                    a.rpy_rad[1].to_degrees(),
                    a.rpy_rad[2].to_degrees(),
                    if a.heading_known {
                        "from the GNSS course"
                    } else {
                        "unknown"
                    }
                );
                next_print = a.t_s + 10.0;
            }
        }
        let step = nav.push_imu(s)?;
        rejected += step
            .fixes
            .iter()
            .filter(|f| matches!(f, FixEvent::Rejected(_)))
            .count();
        if let Some(sol) = nav.solution().filter(|sol| sol.t_s >= next_print) {
            print_solution(&sol);
            next_print += 10.0;
        }
    }
    for g in fixes {
        nav.push_gnss(g)?;
    }
    nav.flush();

    let sol = nav
        .solution()
        .ok_or("the navigator never started (no valid fix)")?;
    println!("final:");
    print_solution(&sol);
    let c = nav.counters();
    println!(
        "IMU: {} integrated, {} implausible; GNSS: {} used ({} down-weighted, {} resets), {} \
         rejected ({rejected} seen in the events), {} refused, {} dropped",
        c.imu_integrated,
        c.imu_implausible,
        c.gnss_used,
        c.gnss_downweighted,
        c.gnss_resets,
        c.gnss_rejected,
        c.gnss_refused,
        c.gnss_dropped
    );
    if let (Some(t), Some(st)) = (truth, nav.state()) {
        let d = earth::ned_offset_m(&t.pos, &st.pos);
        let dv = st.vel_ned_mps - t.vel_ned_mps;
        println!(
            "error against the generated truth: position N {:+.3} E {:+.3} D {:+.3} m, \
             velocity {:.4} m/s",
            d.x,
            d.y,
            d.z,
            dv.norm()
        );
    }
    Ok(())
}

fn print_solution(s: &NavSolution) {
    println!(
        "  t {:.2} s  lat {:.8} lon {:.8} deg  h {:.3} m  v NED {:+.3} {:+.3} {:+.3} m/s  \
         rpy {:+.2} {:+.2} {:+.2} deg  sd N/E {:.3}/{:.3} m  status {:#x}",
        s.t_s,
        s.lat_rad.to_degrees(),
        s.lon_rad.to_degrees(),
        s.h_m,
        s.vel_ned_mps[0],
        s.vel_ned_mps[1],
        s.vel_ned_mps[2],
        s.rpy_rad[0].to_degrees(),
        s.rpy_rad[1].to_degrees(),
        s.rpy_rad[2].to_degrees(),
        s.pos_std_ned_m[0],
        s.pos_std_ned_m[1],
        s.status
    );
}

/// A level drive at constant velocity (10 m/s, heading 60 deg): the IMU measures the earth
/// and transport rates and the specific force that holds the vehicle on its path; the truth
/// is the strapdown integration of those increments, the fixes the truth with a small
/// deterministic noise (2 cm, 2 cm/s). The IMU starts 2 s before the first fix.
fn generate(seconds: f64, imu_hz: f64) -> (Vec<ImuSample>, Vec<GnssFix>, NavState) {
    let dt = 1.0 / imu_hz;
    let yaw = 60f64.to_radians();
    let v = Vector3::new(10.0 * yaw.cos(), 10.0 * yaw.sin(), 0.0);
    let start = NavState::from_rpy(
        400_000.0,
        Llh::from_deg(47.07, 15.44, 360.0),
        v,
        [0.0, 0.0, yaw],
    );
    let mut truth = Strapdown::new(start);
    let mut noise = Lcg(12345);
    let (mut imu, mut gnss) = (Vec::new(), Vec::new());
    let n = (seconds * imu_hz).round() as u64;
    for k in 1..=n {
        let s = *truth.state();
        let lat = s.pos.lat_rad;
        let w_ie = earth::earth_rate_ned_radps(lat);
        let w_en = earth::transport_rate_ned_radps(lat, s.pos.h_m, &s.vel_ned_mps);
        // dv/dt = f + g - (2 w_ie + w_en) x v = 0 for a constant velocity
        let f_n =
            (2.0 * w_ie + w_en).cross(&s.vel_ned_mps) - earth::gravity_ned_mps2(lat, s.pos.h_m);
        let to_body = s.q_nb.inverse();
        let sample = ImuSample {
            t_s: start.t_s + k as f64 * dt,
            dtheta_rad: (to_body * (w_ie + w_en) * dt).into(),
            dv_mps: (to_body * f_n * dt).into(),
            temperature_c: f64::NAN,
        };
        if truth.update(&sample).is_err() {
            break;
        }
        imu.push(sample);
        if k % imu_hz as u64 == 0 && k as f64 * dt >= 2.0 {
            let t = truth.state();
            let p = earth::displace(
                &t.pos,
                &Vector3::new(
                    0.02 * noise.next(),
                    0.02 * noise.next(),
                    0.04 * noise.next(),
                ),
            );
            gnss.push(GnssFix {
                t_s: t.t_s,
                lat_rad: p.lat_rad,
                lon_rad: p.lon_rad,
                h_m: p.h_m,
                pos_std_ned_m: [0.02, 0.02, 0.04],
                vel_ned_mps: (t.vel_ned_mps
                    + Vector3::new(
                        0.02 * noise.next(),
                        0.02 * noise.next(),
                        0.04 * noise.next(),
                    ))
                .into(),
                vel_std_ned_mps: [0.02, 0.02, 0.04],
                has_velocity: true,
                quality: FixQuality::RtkFixed,
                num_sats: 18,
            });
        }
    }
    (imu, gnss, *truth.state())
}

/// A small deterministic pseudo-random source, uniform in [-1.7, 1.7] (unit variance).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * 3f64.sqrt()
    }
}

fn fields(line: &str) -> Option<Result<Vec<f64>, std::num::ParseFloatError>> {
    let l = line.trim();
    if l.is_empty() || l.starts_with('#') {
        return None;
    }
    Some(l.split_whitespace().map(str::parse).collect())
}

fn read_imu(path: &str) -> Result<Vec<ImuSample>, Box<dyn Error>> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let Some(v) = fields(line) else { continue };
        let v = v.map_err(|e| format!("{path} line {}: {e}", i + 1))?;
        let [t, gx, gy, gz, ax, ay, az] = v[..] else {
            return Err(format!("{path} line {}: expected 7 numbers", i + 1).into());
        };
        out.push(ImuSample {
            t_s: t,
            dtheta_rad: [gx, gy, gz],
            dv_mps: [ax, ay, az],
            temperature_c: f64::NAN,
        });
    }
    Ok(out)
}

fn read_gnss(path: &str) -> Result<Vec<GnssFix>, Box<dyn Error>> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let Some(v) = fields(line) else { continue };
        let v = v.map_err(|e| format!("{path} line {}: {e}", i + 1))?;
        let (p, vel) = match v.len() {
            7 => (&v[..7], None),
            13 => (&v[..7], Some(&v[7..])),
            n => {
                return Err(
                    format!("{path} line {}: expected 7 or 13 numbers, got {n}", i + 1).into(),
                )
            }
        };
        let mut fix = GnssFix {
            t_s: p[0],
            lat_rad: p[1].to_radians(),
            lon_rad: p[2].to_radians(),
            h_m: p[3],
            pos_std_ned_m: [p[4], p[5], p[6]],
            quality: FixQuality::Single,
            ..GnssFix::default()
        };
        if let Some(w) = vel {
            fix.vel_ned_mps = [w[0], w[1], w[2]];
            fix.vel_std_ned_mps = [w[3], w[4], w[5]];
            fix.has_velocity = true;
        }
        out.push(fix);
    }
    Ok(out)
}
