//! The parameter files `host-sim allan` writes: `allan_params.toml`, a `[noise]` section of a
//! run configuration (pasted verbatim into one, see `nav_io::noisecfg`), and
//! `allan_sim_errors.toml`, the same fit in the layout of the simulator's sensor error model.
use super::cli::{Analysis, AxisResult};
use nav_core::config::units;
use noise_id::fit::{self, FitResult, SensorKind};
use std::fmt::Write as _;
use std::path::Path;

/// Turn-on bias sigmas for the `[noise]` section (not identifiable from a static record).
#[derive(Clone, Copy, Debug, Default)]
pub struct BiasInit {
    /// Accelerometer turn-on bias sigma, ug.
    pub accel_ug: Option<f64>,
    /// Gyro turn-on bias sigma, deg/h.
    pub gyro_deg_per_h: Option<f64>,
}

/// Ratio of a Gauss-Markov process's Allan-deviation peak to the flicker floor of the same
/// height: `B = ratio sqrt(S_B T_B)` (nav-core's units).
const GM_TO_FLICKER: f64 = units::GM_PEAK_ADEV / units::FLICKER_FLOOR_ADEV;
/// The Allan deviation of a first-order Gauss-Markov process peaks at tau = 1.89 T_B.
const GM_PEAK_TAU_OVER_TB: f64 = 1.89;

/// The filter's noise terms of one axis (SI), from its fit.
#[derive(Clone, Debug)]
struct AxisNoise {
    s_n: fit::Est,
    s_b: fit::Est,
    t_b_s: f64,
    s_k: fit::Est,
    notes: Vec<String>,
}

fn axis_noise(a: &AxisResult, f: &FitResult) -> AxisNoise {
    let mut notes = Vec::new();
    let mut s_n = f.s_n;
    if s_n.value.is_nan() || s_n.value <= 0.0 {
        // the filter needs white noise: the slope method's N (or, failing that, nothing)
        if let Some(sl) = a.slope.as_ref().filter(|s| s.n > 0.0) {
            s_n = fit::Est {
                value: sl.n * sl.n,
                sigma: f64::NAN,
            };
            notes.push(format!(
                "{}: the selected model has no white noise; s_n is the slope method's N^2",
                a.name
            ));
        }
    }
    let mut s_b = f.s_b;
    let mut t_b_s = f.t_b_s.value;
    if s_b.value.is_nan() || s_b.value <= 0.0 || !t_b_s.is_finite() {
        s_b = fit::Est {
            value: 0.0,
            sigma: f64::NAN,
        };
        t_b_s = f64::NAN;
    }
    if f.terms.flicker && f.flicker_b2.value > 0.0 {
        let b = f.flicker_b2.value.sqrt();
        if s_b.value > 0.0 {
            notes.push(format!(
                "{}: the flicker floor B = {b:.3e} has no filter state and is left out (the \
                 Gauss-Markov term stands for the bias instability)",
                a.name
            ));
        } else {
            // a Gauss-Markov process whose ADEV peak matches the floor, at the model's minimum
            let tau_min = f.model_adev_minimum().0;
            if tau_min.is_finite() && tau_min > 0.0 {
                t_b_s = tau_min / GM_PEAK_TAU_OVER_TB;
                s_b = fit::Est {
                    value: (b / GM_TO_FLICKER).powi(2) / t_b_s,
                    sigma: f64::NAN,
                };
                notes.push(format!(
                    "{}: flicker floor B = {b:.3e} written as a Gauss-Markov term with the same \
                     Allan-deviation peak at the model's minimum ({tau_min:.1} s: T_B = {t_b_s:.1} s)",
                    a.name
                ));
            }
        }
    }
    if f.q2.value > 0.0 {
        notes.push(format!(
            "{}: quantization Q = {:.3e} (increment units) has no filter term: left out",
            a.name,
            f.q2.value.sqrt()
        ));
    }
    AxisNoise {
        s_n,
        s_b,
        t_b_s,
        s_k: f.s_k,
        notes,
    }
}

fn fmt_num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        "nan".into()
    }
}

fn fmt_arr(v: [f64; 3]) -> String {
    format!("[{}]", v.map(fmt_num).join(", "))
}

/// The channels of one sensor kind as IMU axes x, y, z: the `gx gy gz` / `ax ay az` keys, or
/// a single channel of that kind for all three; a missing axis takes the largest of the others.
fn group(an: &Analysis, kind: SensorKind) -> Option<(Vec<&AxisResult>, String)> {
    let of_kind: Vec<&AxisResult> = an
        .axes
        .iter()
        .filter(|a| a.kind == kind && a.fit.is_ok())
        .collect();
    if of_kind.is_empty() {
        return None;
    }
    let prefix = if kind == SensorKind::Gyro { 'g' } else { 'a' };
    let keyed: Vec<Option<&AxisResult>> = ['x', 'y', 'z']
        .iter()
        .map(|c| {
            let k = format!("{prefix}{c}");
            of_kind.iter().copied().find(|a| a.name == k)
        })
        .collect();
    if keyed.iter().all(Option::is_some) {
        return Some((keyed.into_iter().flatten().collect(), String::new()));
    }
    if of_kind.len() == 1 {
        let a = of_kind[0];
        return Some((
            vec![a; 3],
            format!("the single channel {} stands for all three axes", a.name),
        ));
    }
    // some axes: the others take the noisiest present one (largest white noise)
    let worst = of_kind
        .iter()
        .copied()
        .max_by(|a, b| {
            let s = |x: &AxisResult| x.fit.as_ref().map_or(0.0, |f| f.s_n.value);
            s(a).total_cmp(&s(b))
        })
        .unwrap_or(of_kind[0]);
    let missing: Vec<String> = ['x', 'y', 'z']
        .iter()
        .zip(&keyed)
        .filter(|(_, k)| k.is_none())
        .map(|(c, _)| format!("{prefix}{c}"))
        .collect();
    Some((
        keyed.into_iter().map(|k| k.unwrap_or(worst)).collect(),
        format!(
            "{} not analysed (or its fit failed): {} stands in",
            missing.join(", "),
            worst.name
        ),
    ))
}

/// `allan_params.toml`: the identified noise as a `[noise]` section of a run configuration
/// (`[noise.accel]` / `[noise.gyro]` with per-axis `s_n`, `s_b`, `t_b_s`, `s_k` in SI, the
/// keys of `nav_io::noisecfg`), to paste verbatim. The filter has one Gauss-Markov
/// correlation time per sensor: `t_b_s` is the geometric mean of the axes' T_B and each
/// axis's `s_b` is rescaled to keep its stationary sigma `sqrt(S_B T_B / 2)`. Terms the filter
/// has no state for (quantization; flicker next to a Gauss-Markov term) are left out and said
/// so in comments; a flicker floor alone becomes the Gauss-Markov term with the same
/// Allan-deviation peak. Uncertainties (1 sigma) are comments.
pub fn noise_section_toml(an: &Analysis, source: &Path, bias: &BiasInit) -> String {
    let mut head = String::new();
    let mut body = String::new();
    let _ = writeln!(
        head,
        "# IMU noise identified by `host-sim allan` from {} ({} samples, tau0 = {:.6} s).\n\
         # A [noise] section of a run configuration (nav-io/src/noisecfg.rs): paste it verbatim.\n\
         # SI, two-sided PSDs (IEEE 952), per IMU axis [x, y, z]: s_n white noise [m^2/s^3 | rad^2/s],\n\
         # s_b Gauss-Markov driving PSD [m^2/s^5 | rad^2/s^3] with its correlation time t_b_s [s],\n\
         # s_k bias random walk [m^2/s^5 | rad^2/s^3].",
        source.display(),
        an.n_samples,
        an.tau0_s
    );
    let mut any_bias_state = false;
    let mut notes: Vec<String> = Vec::new();
    for (kind, table) in [
        (SensorKind::Accel, "noise.accel"),
        (SensorKind::Gyro, "noise.gyro"),
    ] {
        let Some((axes, how)) = group(an, kind) else {
            continue;
        };
        if !how.is_empty() {
            notes.push(format!("{table}: {how}"));
        }
        any_bias_state |= sensor_table(&mut body, &mut notes, kind, table, &axes, bias);
    }
    let others: Vec<&AxisResult> = an
        .axes
        .iter()
        .filter(|a| a.kind == SensorKind::Other)
        .collect();
    for a in others {
        notes.push(format!(
            "channel {} has no unit (give --x-unit to make it a gyro or accelerometer): \
             S_N = {}, S_B = {}, T_B = {} s, S_K = {} in its own units",
            a.name,
            a.fit.as_ref().map_or("-".into(), |f| fmt_num(f.s_n.value)),
            a.fit.as_ref().map_or("-".into(), |f| fmt_num(f.s_b.value)),
            a.fit
                .as_ref()
                .map_or("-".into(), |f| fmt_num(f.t_b_s.value)),
            a.fit.as_ref().map_or("-".into(), |f| fmt_num(f.s_k.value)),
        ));
    }
    for n in &notes {
        let _ = writeln!(head, "# Note: {n}");
    }
    if body.is_empty() {
        return head;
    }
    let model = if any_bias_state { "nbk" } else { "n" };
    let _ = writeln!(
        head,
        "\n[noise]\nmodel = \"{model}\"   # {}",
        if any_bias_state {
            "Gauss-Markov and/or random-walk bias states"
        } else {
            "white noise and constant biases: no bias process was identified"
        }
    );
    head.push_str(&body);
    head
}

/// One sensor's table of `allan_params.toml` (`[noise.accel]` or `[noise.gyro]`) appended to
/// `body` from its three axes' fits, notes about the fit appended to `notes`; true when the
/// table has a Gauss-Markov or random-walk bias term. Nothing is written unless all three
/// axes have a fit.
fn sensor_table(
    body: &mut String,
    notes: &mut Vec<String>,
    kind: SensorKind,
    table: &str,
    axes: &[&AxisResult],
    bias: &BiasInit,
) -> bool {
    let mut any_bias_state = false;
    let mut n: Vec<AxisNoise> = Vec::new();
    for a in axes {
        let Ok(f) = &a.fit else { continue };
        let an_ = axis_noise(a, f);
        if n.iter().all(|x| x.notes != an_.notes) {
            notes.extend(an_.notes.iter().cloned());
        }
        n.push(an_);
    }
    if n.len() != 3 {
        return false;
    }
    let terms: Vec<String> = axes
        .iter()
        .map(|a| {
            a.fit
                .as_ref()
                .map_or("-".into(), |f| format!("{} {}", a.name, f.terms.label()))
        })
        .collect();
    let _ = writeln!(body, "\n[{table}]");
    let _ = writeln!(body, "# selected terms: {}", terms.join(", "));
    let pick = |g: fn(&AxisNoise) -> fit::Est| -> ([f64; 3], [f64; 3]) {
        let v = [g(&n[0]).value, g(&n[1]).value, g(&n[2]).value];
        let s = [g(&n[0]).sigma, g(&n[1]).sigma, g(&n[2]).sigma];
        (v, s)
    };
    let (s_n, s_n_sig) = pick(|x| x.s_n);
    let _ = writeln!(body, "s_n = {}", fmt_arr(s_n));
    let _ = writeln!(body, "# 1 sigma: s_n {}", fmt_arr(s_n_sig));
    let (mut s_b, s_b_sig) = pick(|x| x.s_b);
    let tbs: Vec<f64> = n
        .iter()
        .filter(|x| x.s_b.value > 0.0)
        .map(|x| x.t_b_s)
        .collect();
    if !tbs.is_empty() {
        let t_common = (tbs.iter().map(|t| t.ln()).sum::<f64>() / tbs.len() as f64).exp();
        for (v, x) in s_b.iter_mut().zip(&n) {
            if x.s_b.value > 0.0 {
                *v *= x.t_b_s / t_common;
            }
        }
        let _ = writeln!(body, "s_b = {}", fmt_arr(s_b));
        let _ = writeln!(body, "t_b_s = {}", fmt_num(t_common));
        let _ = writeln!(
            body,
            "# per-axis T_B {} s (one t_b_s per sensor: s_b rescaled to keep each axis's \
             stationary sigma); 1 sigma of the fitted s_b {}",
            fmt_arr(
                n.iter()
                    .map(|x| x.t_b_s)
                    .collect::<Vec<_>>()
                    .try_into()
                    .unwrap_or([f64::NAN; 3])
            ),
            fmt_arr(s_b_sig)
        );
        any_bias_state = true;
    }
    let (s_k, s_k_sig) = pick(|x| x.s_k);
    if s_k.iter().any(|v| *v > 0.0) {
        let _ = writeln!(body, "s_k = {}", fmt_arr(s_k));
        let _ = writeln!(body, "# 1 sigma: s_k {}", fmt_arr(s_k_sig));
        any_bias_state = true;
    }
    let (key, val, unit) = match kind {
        SensorKind::Gyro => (
            "bias_init_deg_per_h",
            bias.gyro_deg_per_h,
            "--gyro-bias-init-deg-per-h",
        ),
        _ => ("bias_init_ug", bias.accel_ug, "--accel-bias-init-ug"),
    };
    match val {
        Some(v) => {
            let _ = writeln!(body, "{key} = {}", fmt_num(v));
        }
        None => {
            let _ = writeln!(
                body,
                "# {key} = ...  (turn-on bias: not identifiable from one static record; give the \
                 datasheet value here or with `allan {unit}`; absent = 0)"
            );
        }
    }
    any_bias_state
}

/// `allan_sim_errors.toml`: `[accel]` / `[gyro]` in the layout of the simulator's sensor error
/// model (`white_psd`, `gm_psd`, `gm_tau_s`, `rw_psd`, `flicker_b`, `quantization_step`, per axis x y z,
/// SI, two-sided PSDs), `[x]` for a single generic channel, and `[uncertainty.*]` with the
/// 1-sigma of every value.
pub fn sim_errors_toml(an: &Analysis, source: &Path) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Noise parameters identified by `host-sim allan` from {} ({} samples, tau0 = {:.6} s).\n\
         # Fit of the overlapping Allan variance (corrected model of docs/DESIGN.md), SI units,\n\
         # two-sided PSDs (IEEE 952): white_psd S_N [m^2/s^3 | rad^2/s], gm_psd S_B [m^2/s^5 |\n\
         # rad^2/s^3], gm_tau_s T_B [s], rw_psd S_K [m^2/s^5 | rad^2/s^3], flicker_b B (IEEE 952,\n\
         # Allan floor 0.664 B) [m/s^2 | rad/s], quantization_step = sqrt(12) Q [m/s | rad].\n\
         # [accel] and [gyro] have the layout of the simulator's sensor error model (host-sim\n\
         # simulate --errors); the run configuration's [noise] section is allan_params.toml. A term the\n\
         # fit set to zero (or term selection dropped) is 0 (gm_tau_s then 1 as a placeholder).",
        source.display(),
        an.n_samples,
        an.tau0_s
    );
    let groups: [(&str, [&str; 3]); 2] =
        [("accel", ["ax", "ay", "az"]), ("gyro", ["gx", "gy", "gz"])];
    let get = |name: &str| {
        an.axes
            .iter()
            .find(|a| a.name == name)
            .and_then(|a| a.fit.as_ref().ok())
    };
    let fmt_arr = |v: [f64; 3]| {
        format!(
            "[{}]",
            v.iter()
                .map(|x| if x.is_finite() {
                    format!("{x:e}")
                } else {
                    "nan".into()
                })
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    type Field = (&'static str, fn(&FitResult) -> fit::Est);
    let fields: [Field; 6] = [
        ("white_psd", |f| f.s_n),
        ("gm_psd", |f| f.s_b),
        ("gm_tau_s", |f| f.t_b_s),
        ("rw_psd", |f| f.s_k),
        ("flicker_b", |f| {
            let b = f.flicker_b2.value.max(0.0).sqrt();
            fit::Est {
                value: b,
                sigma: if b > 0.0 {
                    f.flicker_b2.sigma / (2.0 * b)
                } else {
                    f64::NAN
                },
            }
        }),
        ("quantization_step", |f| {
            let q = f.q2.value.max(0.0).sqrt();
            fit::Est {
                value: 12f64.sqrt() * q,
                sigma: if q > 0.0 {
                    12f64.sqrt() * f.q2.sigma / (2.0 * q)
                } else {
                    f64::NAN
                },
            }
        }),
    ];
    let value = |name: &str, f: &FitResult, e: fit::Est| {
        if name == "gm_tau_s" && (f.s_b.value.is_nan() || f.s_b.value <= 0.0) {
            1.0
        } else {
            e.value
        }
    };
    let mut unc = String::new();
    for (group, keys) in groups {
        if !keys.iter().any(|k| get(k).is_some()) {
            continue;
        }
        let _ = writeln!(s, "\n[{group}]");
        let _ = writeln!(unc, "\n[uncertainty.{group}]");
        for (fname, fget) in fields {
            let mut v = [f64::NAN; 3];
            let mut u = [f64::NAN; 3];
            for (i, k) in keys.iter().enumerate() {
                if let Some(f) = get(k) {
                    v[i] = value(fname, f, fget(f));
                    u[i] = fget(f).sigma;
                }
            }
            let _ = writeln!(s, "{fname} = {}", fmt_arr(v));
            let _ = writeln!(unc, "{fname} = {}", fmt_arr(u));
        }
    }
    if let Some(f) = get("x") {
        let _ = writeln!(s, "\n[x]");
        let _ = writeln!(unc, "\n[uncertainty.x]");
        for (fname, fget) in fields {
            let e = fget(f);
            let fmt1 = |x: f64| {
                if x.is_finite() {
                    format!("{x:e}")
                } else {
                    "nan".into()
                }
            };
            let _ = writeln!(s, "{fname} = {}", fmt1(value(fname, f, e)));
            let _ = writeln!(unc, "{fname} = {}", fmt1(e.sigma));
        }
    }
    s.push_str(&unc);
    s
}
