//! The held-out windows' RMS veto of [`nav_diagnose::decide`]: a candidate whose windows are
//! significantly lower is not eligible when their RMS rises, unless one window alone carries
//! the rise. The window errors are those measured on the sweep's drives (10 minutes at 50 Hz,
//! three 60 s gaps of the GNSS file and 17 windows of 8 s).
use nav_diagnose::validate::compare_windows;
use nav_diagnose::{decide, Decision};

/// Accelerometer misalignment seed 107: the configuration's windows and the candidate's.
/// The 8 s windows fall from 5-17 cm to 3-8 cm; one gap rises 1.94 -> 4.40 m while the other
/// two fall 2.41 -> 0.37 and 1.33 -> 1.56 m: the RMS rises 0.758 -> 1.048 m on one window.
const BASE_107: [f64; 20] = [
    0.10, 2.41, 0.10, 0.11, 0.07, 0.09, 0.08, 1.94, 0.10, 0.11, 0.09, 0.06, 0.05, 1.33, 0.11, 0.12,
    0.05, 0.08, 0.13, 0.17,
];
const MISALIGNMENT_107: [f64; 20] = [
    0.04, 0.37, 0.05, 0.05, 0.05, 0.08, 0.04, 4.40, 0.05, 0.03, 0.06, 0.06, 0.03, 1.56, 0.08, 0.03,
    0.04, 0.06, 0.06, 0.07,
];

#[test]
fn one_window_alone_does_not_veto_a_candidate_with_significantly_lower_windows() {
    let h = compare_windows(&BASE_107, &MISALIGNMENT_107);
    assert!(h.new_rms_m > h.current_rms_m, "{}", h.describe());
    assert!(!h.rms_raised_beyond_one_window, "{}", h.describe());
    let (d, why) = decide(571.1, 30.6, false, &h);
    assert_eq!(d, Decision::Eligible, "{why}");
}

#[test]
fn a_rms_rise_over_two_windows_still_vetoes() {
    // the same drive with a second gap as much worse as the first
    let mut worse = MISALIGNMENT_107;
    worse[13] = 4.0;
    let h = compare_windows(&BASE_107, &worse);
    assert_eq!(h.verdict, nav_diagnose::HeldoutVerdict::Better);
    assert!(h.rms_raised_beyond_one_window, "{}", h.describe());
    let (d, why) = decide(571.1, 30.6, false, &h);
    assert_eq!(d, Decision::NotSignificant, "{why}");
    assert!(why.contains("RMS raised"), "{why}");
}

/// A held-out RMS that rises by less than a millimetre is shown as a rise: the change in mm
/// follows the two RMS values when they print alike, and equal values print without it.
#[test]
fn a_sub_millimetre_rms_change_is_shown_with_its_sign() {
    let mut new = BASE_107;
    new[1] += 0.002;
    let h = compare_windows(&BASE_107, &new);
    assert!(h.new_rms_m > h.current_rms_m, "{}", h.describe());
    let d = h.describe();
    assert!(d.contains("RMS 0.759 -> 0.759 m (+0.318 mm)"), "{d}");
    let same = compare_windows(&BASE_107, &BASE_107).describe();
    assert!(same.contains("RMS 0.759 -> 0.759 m,"), "{same}");
}
