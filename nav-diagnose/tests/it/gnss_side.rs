//! The judgement of a GNSS-side effect (`gnss_position_gm`): a model with the GNSS error state
//! predicts a withheld fix as the antenna position plus the state's estimate
//! (`spill::predict_withheld_fixes`), and the fixes withheld one at a time
//! (`validate::interleaved_fixes`) are every 4th after the warm-up, clear of the held-out
//! windows, with their prediction errors read back per fix (`validate::fix_errors_m`).

use nav_diagnose::spill::{gnss_error_track, predict_withheld_fixes};
use nav_diagnose::validate::{
    fix_errors_m, interleaved_fixes, single_fix_outages, HeldoutWindow, INTERLEAVE_CLEAR_S,
    INTERLEAVE_EVERY, WARM_UP_S,
};
use nav_diagnose::WindowKind;
use nav_engine::run::{FixUse, InnovationRecord};

fn record(t_s: f64, used: FixUse, inn: [f64; 3]) -> InnovationRecord {
    InnovationRecord {
        t_s,
        used,
        outage: None,
        dim: 3,
        innovation: [inn[0], inn[1], inn[2], 0.0, 0.0, 0.0],
        innovation_var: [f64::NAN; 6],
        nis: f64::NAN,
        nis_threshold: f64::NAN,
        quality: 1,
    }
}

#[test]
fn a_withheld_fix_is_predicted_with_the_gnss_error_estimate() {
    let names: Vec<String> = [
        "pos_n_m",
        "gnss_position_gm_x",
        "gnss_position_gm_y",
        "gnss_position_gm_z",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let estimates = vec![
        (10.0, vec![0.0, 0.1, -0.2, 0.3]),
        (10.5, vec![0.0, 0.2, -0.4, 0.6]),
    ];
    let track = gnss_error_track(&names, &estimates);
    assert_eq!(
        track,
        vec![(10.0, [0.1, -0.2, 0.3]), (10.5, [0.2, -0.4, 0.6])]
    );
    // without the block: no track
    assert!(gnss_error_track(&names[..1], &estimates).is_empty());
    let mut recs = vec![
        record(10.2, FixUse::Withheld, [1.0, 1.0, 1.0]),
        record(10.7, FixUse::Withheld, [1.0, 1.0, 1.0]),
        record(10.7, FixUse::Accepted, [1.0, 1.0, 1.0]),
        record(9.0, FixUse::Withheld, [1.0, 1.0, 1.0]),
    ];
    let tau = 100.0;
    predict_withheld_fixes(&mut recs, &track, tau);
    let d = (-0.2f64 / tau).exp();
    let close = |a: [f64; 6], b: [f64; 3]| a[..3].iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
    // the estimate of the last record before the fix, decayed over the time since
    assert!(
        close(
            recs[0].innovation,
            [1.0 - 0.1 * d, 1.0 + 0.2 * d, 1.0 - 0.3 * d]
        ),
        "{:?}",
        recs[0]
    );
    assert!(
        close(
            recs[1].innovation,
            [1.0 - 0.2 * d, 1.0 + 0.4 * d, 1.0 - 0.6 * d]
        ),
        "{:?}",
        recs[1]
    );
    // a used fix's innovation is the filter's own (the full model), a fix before the first
    // record is left alone
    assert!(close(recs[2].innovation, [1.0; 3]));
    assert!(close(recs[3].innovation, [1.0; 3]));
}

#[test]
fn every_fourth_fix_clear_of_the_windows_is_withheld_on_its_own() {
    let times: Vec<f64> = (0..600).map(|i| 1000.0 + f64::from(i)).collect();
    let w = HeldoutWindow {
        kind: WindowKind::GnssGap,
        start_s: 1200.5,
        end_s: 1260.0,
    };
    let fixes = interleaved_fixes(&times, std::slice::from_ref(&w));
    assert!(fixes.iter().all(|&t| t >= 1000.0 + WARM_UP_S));
    assert!(fixes
        .iter()
        .all(|&t| t < w.start_s - INTERLEAVE_CLEAR_S || t > w.end_s + INTERLEAVE_CLEAR_S));
    let eligible = times
        .iter()
        .filter(|&&t| {
            t >= 1000.0 + WARM_UP_S
                && (t < w.start_s - INTERLEAVE_CLEAR_S || t > w.end_s + INTERLEAVE_CLEAR_S)
        })
        .count();
    assert_eq!(fixes.len(), eligible.div_ceil(INTERLEAVE_EVERY));
    // each withheld by an outage of its own that holds only it
    for (o, t) in single_fix_outages(&fixes).iter().zip(&fixes) {
        assert!(o.contains(*t) && !o.contains(t - 1.0) && !o.contains(t + 1.0));
    }
    // the errors read back per fix; NaN where the run has no withheld record
    let recs = vec![
        record(fixes[0], FixUse::Withheld, [3.0, 4.0, 0.0]),
        record(fixes[1], FixUse::Accepted, [1.0, 0.0, 0.0]),
    ];
    let e = fix_errors_m(&recs, &fixes[..2]);
    assert!((e[0] - 5.0).abs() < 1e-12 && e[1].is_nan(), "{e:?}");
}

/// The paired comparison on single withheld fixes is the windows' test, described per fix.
#[test]
fn single_fix_comparisons_say_fixes_and_windows_say_windows() {
    use nav_diagnose::validate::{compare_fixes, compare_windows};
    let cur = [1.0, 1.2, 0.9, 1.1, 1.3, 1.0, 0.8, 1.2, 1.1, 1.0, 0.9, 1.4];
    let new: Vec<f64> = cur.iter().map(|e| 0.5 * e).collect();
    let w = compare_windows(&cur, &new);
    let f = compare_fixes(&cur, &new);
    assert_eq!(
        (w.gain, w.p_better, w.verdict),
        (f.gain, f.p_better, f.verdict)
    );
    assert!(
        w.describe().contains("12 of 12 windows lower"),
        "{}",
        w.describe()
    );
    assert!(
        f.describe().contains("12 of 12 fixes lower"),
        "{}",
        f.describe()
    );
}
