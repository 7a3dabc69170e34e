//! Monte Carlo consistency of the NBK filter on NBK data (the "filter is consistent"
//! criterion): 30 seeded 10-minute drives at 100 Hz with 1 Hz RTK-grade GNSS, the truth's
//! accelerometer bias a true Gauss-Markov + random-walk process with the source's identified
//! parameters, gyro biases random constants. The drive (accelerations and turns) makes heading
//! and the horizontal accelerometer biases observable.

use nav_core::config::{FilterConfig, Gating};
use nav_core::filter::Filter;
use nav_core::model::{
    BlockKind, Layout, IDX_ATT, IDX_POS, IDX_VEL, LAYOUT_NBK, LAYOUT_NBK_SINGLE,
};
use test_support::filter_sim::*;
use test_support::stats::chi2_inv;

const RUNS: usize = 30;
const DURATION_S: usize = 600;

struct McResult {
    /// per GNSS epoch: sum over runs of NEES (att, vel, pos)
    nees_sum: Vec<[f64; 3]>,
    /// accelerometer bias samples within 3 sigma / total
    bias_in: usize,
    bias_total: usize,
    /// gyro bias samples within 3 sigma / total
    gbias_in: usize,
    gbias_total: usize,
    /// sum of the NIS of all updates
    nis_sum: f64,
}

fn run_mc<const N: usize>(layout: Layout) -> McResult {
    let mut res = McResult {
        nees_sum: vec![[0.0; 3]; DURATION_S],
        bias_in: 0,
        bias_total: 0,
        gbias_in: 0,
        gbias_total: 0,
        nis_sum: 0.0,
    };
    let cfg = FilterConfig {
        lever_arm_body_m: SimConfig::nbk(100.0).lever_arm_body_m,
        // consistency, not gating, is under test here: every fix is used
        gating: Gating::disabled(),
        ..FilterConfig::source_nbk_model()
    };
    for run in 0..RUNS {
        let mut sim = Sim::new(SimConfig::nbk(100.0), 1000 + run as u64);
        let unc = test_uncertainty();
        let mut f: Filter<f64, N> = start_filter(&mut sim, layout, &cfg, &unc);
        let mut g = 0;
        while g < DURATION_S {
            let e = sim.step();
            f.propagate(&e.imu).expect("propagate");
            let Some(fix) = e.gnss else { continue };
            let out = f.update_gnss(&fix).expect("update");
            assert!(out.accepted);
            res.nis_sum += out.nis;
            let (phi, dv, dr) = nav_errors(f.nav_state(), &e.truth);
            let p = f.covariance();
            res.nees_sum[g][0] += nees3(p, IDX_ATT, &phi);
            res.nees_sum[g][1] += nees3(p, IDX_VEL, &dv);
            res.nees_sum[g][2] += nees3(p, IDX_POS, &dr);
            let (ba, sa) = f.imu_error(BlockKind::AccelBias).unwrap();
            for i in 0..3 {
                res.bias_total += 1;
                if (ba[i] - e.accel_bias_mps2[i]).abs() <= 3.0 * sa[i] {
                    res.bias_in += 1;
                }
            }
            let (bg, sg) = f.imu_error(BlockKind::GyroBias).unwrap();
            for i in 0..3 {
                res.gbias_total += 1;
                if (bg[i] - e.gyro_bias_radps[i]).abs() <= 3.0 * sg[i] {
                    res.gbias_in += 1;
                }
            }
            g += 1;
        }
    }
    res
}

#[test]
fn nbk_filter_on_nbk_data_is_consistent_over_30_monte_carlo_runs() {
    let t0 = std::time::Instant::now();
    let r = run_mc::<{ LAYOUT_NBK.dim() }>(LAYOUT_NBK);
    let m = RUNS as f64;
    let lo = chi2_inv(0.025, 3.0 * m) / m;
    let hi = chi2_inv(0.975, 3.0 * m) / m;
    let names = ["attitude", "velocity", "position"];
    let n_ep = r.nees_sum.len() as f64;
    for (k, name) in names.iter().enumerate() {
        let avg: Vec<f64> = r.nees_sum.iter().map(|s| s[k] / m).collect();
        let grand = avg.iter().sum::<f64>() / n_ep;
        let inside = avg.iter().filter(|v| **v >= lo && **v <= hi).count() as f64 / n_ep;
        let below = avg.iter().filter(|v| **v < lo).count() as f64 / n_ep;
        println!(
            "{name}: average NEES {grand:.3} (band [{lo:.3}, {hi:.3}], 3 dof), epochs inside {:.1}% (below {:.1}%)",
            100.0 * inside,
            100.0 * below
        );
        assert!(
            grand >= lo && grand <= hi,
            "{name} average NEES {grand} outside [{lo}, {hi}]"
        );
        assert!(
            inside >= 0.90,
            "{name}: only {:.1}% of epochs inside the band",
            100.0 * inside
        );
    }
    let nis = r.nis_sum / (m * n_ep);
    let n_upd = m * n_ep;
    let (nlo, nhi) = (
        chi2_inv(0.005, 3.0 * n_upd) / n_upd,
        chi2_inv(0.995, 3.0 * n_upd) / n_upd,
    );
    println!("average NIS {nis:.3} over {n_upd} updates (99% band [{nlo:.3}, {nhi:.3}])");
    assert!(nis > nlo && nis < nhi, "average NIS {nis}");
    let frac = r.bias_in as f64 / r.bias_total as f64;
    let gfrac = r.gbias_in as f64 / r.gbias_total as f64;
    println!(
        "accelerometer bias within 3 sigma: {:.2}% of {} samples; gyro bias {:.2}% ({:.1} s)",
        100.0 * frac,
        r.bias_total,
        100.0 * gfrac,
        t0.elapsed().as_secs_f64()
    );
    assert!(
        frac >= 0.99,
        "accelerometer bias inside 3 sigma only {:.2}%",
        100.0 * frac
    );
}

/// The source's single-state variant (Gauss-Markov and random-walk noise in one state that
/// decays with 1/T_B) on the same NBK data: the decaying state cannot hold the 100 ug turn-on
/// (random-constant/random-walk) part of the bias, so the filter is measurably inconsistent.
/// This is the difference DESIGN.md asks the study to show; the exact two-state model above is
/// consistent on the same runs.
#[test]
fn single_state_nbk_variant_is_inconsistent_on_data_with_a_turn_on_bias() {
    let r = run_mc::<{ LAYOUT_NBK_SINGLE.dim() }>(LAYOUT_NBK_SINGLE);
    let m = RUNS as f64;
    let hi = chi2_inv(0.975, 3.0 * m) / m;
    let n_ep = r.nees_sum.len() as f64;
    let mut grand = [0.0; 3];
    for (k, name) in ["attitude", "velocity", "position"].iter().enumerate() {
        grand[k] = r.nees_sum.iter().map(|s| s[k] / m).sum::<f64>() / n_ep;
        println!("single-state: {name} average NEES {:.3}", grand[k]);
    }
    let frac = r.bias_in as f64 / r.bias_total as f64;
    println!(
        "single-state: accel bias within 3 sigma {:.2}%, average NIS {:.3}",
        100.0 * frac,
        r.nis_sum / (m * n_ep)
    );
    assert!(grand[1] > hi && grand[2] > hi, "{grand:?}");
    assert!(frac < 0.5, "{frac}");
}
