//! The diagnosis report (`report.md`, the text; it links the plots `innovations.png`,
//! `nis.png`, `evidence.png` and `errors.png`, which the caller draws: `host-sim diagnose`)
//! and the augmented configuration (`augmented.toml`).
use std::fmt::Write as _;
use std::path::Path;

use crate::DiagnoseError;

use super::{DiagnoseOutput, Diagnosis};
use nav_engine::run::prepare::Prepared;

/// `+12.3 % [+4.0, +20.1]`.
fn gain_ci(h: &super::HeldoutComparison) -> String {
    let pc = |x: f64| {
        if x.is_finite() {
            format!("{:+.1}", 100.0 * x)
        } else {
            "-inf".into()
        }
    };
    format!(
        "{} % [{}, {}]",
        pc(h.gain),
        pc(h.gain_ci90[0]),
        pc(h.gain_ci90[1])
    )
}

fn fmt_vec(v: &[f64]) -> String {
    let s: Vec<String> = v.iter().map(|x| format!("{x:.4e}")).collect();
    format!("[{}]", s.join(", "))
}

/// An optional number with 3 decimals, `-` for none.
fn fmt_opt(x: Option<f64>) -> String {
    x.map_or("-".to_string(), |v| format!("{v:.3}"))
}

/// The text of `report.md` for the diagnosis `d` of the case described by `description`.
pub fn markdown(description: &str, d: &DiagnoseOutput) -> String {
    let dg = &d.diagnosis;
    let mut s = String::new();
    let _ = writeln!(s, "# Diagnosis\n\n{}\n", description);
    let _ = writeln!(s, "Verdict: **{}**\n", dg.verdict);
    if let Some(t) = &dg.noise_tuning {
        noise_section(&mut s, t);
    }
    heldout_section(&mut s, dg, d.t0_s());
    steps_section(&mut s, dg);
    not_added_section(&mut s, dg);
    added_section(&mut s, dg);
    errors_section(&mut s, dg);
    residuals_section(&mut s, dg);
    evidence_section(&mut s, dg);
    s
}

/// Writes `report.md` ([`markdown`]) into `dir` (the plots it links are the caller's).
pub fn write_report(dir: &Path, p: &Prepared, d: &DiagnoseOutput) -> Result<(), DiagnoseError> {
    let path = dir.join("report.md");
    std::fs::write(&path, markdown(&p.description, d))
        .map_err(|source| DiagnoseError::Write { path, source })
}

/// The noise tuning: stage 1 and stage 0 tables, the re-tuning with the effects.
pub(crate) fn noise_section(s: &mut String, t: &crate::NoiseTuning) {
    let _ = writeln!(
        s,
        "Noise tuning (default; `--no-tune-noise` keeps the configuration's): stage 1 factor \
         on both white-noise PSDs **{}** (evidence {:.1} nats); all stages: **{}** (evidence \
         {:.1} nats); NIS mean {:.2} -> {:.2} (expected {:.2}); {}\n",
        t.chosen_scale,
        t.evidence,
        t.chosen.describe(),
        t.total_evidence,
        t.nis_before,
        t.nis_after,
        t.nis_expected,
        if t.adopted {
            "adopted"
        } else if t.chosen.is_one() {
            "nothing to change"
        } else {
            "NOT adopted (held-out check, see the steps)"
        }
    );
    let _ = writeln!(
        s,
        "| factor on the white-noise PSDs | log-likelihood [nats] | NIS mean |"
    );
    let _ = writeln!(s, "|---|---|---|");
    for ((k, ll), nis) in t.scales.iter().zip(&t.log_likelihood).zip(&t.nis_mean) {
        let _ = writeln!(s, "| {k} | {ll:.1} | {nis:.2} |");
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "GNSS noise scale (factor on the declared sigmas, 1 when they are right): \
         horizontal **{:.3}**, vertical **{:.3}** (stage 0 evidence {:.1} nats).\n",
        t.chosen.gnss_horizontal, t.chosen.gnss_vertical, t.gnss_evidence
    );
    let _ = writeln!(
        s,
        "| factor on the GNSS sigmas | log-likelihood [nats] | NIS mean |"
    );
    let _ = writeln!(s, "|---|---|---|");
    for ((k, ll), nis) in t
        .gnss_scales
        .iter()
        .zip(&t.gnss_log_likelihood)
        .zip(&t.gnss_nis_mean)
    {
        let _ = writeln!(s, "| {k:.3} | {ll:.1} | {nis:.2} |");
    }
    let _ = writeln!(s);
    if let Some(t2) = &t.with_effects {
        let _ = writeln!(
            s,
            "Re-tuned with the added effects in the model: **{}** (evidence {:.1} nats, NIS \
             {:.2} -> {:.2}); {}.\n",
            t2.chosen.describe(),
            t2.total_evidence,
            t2.nis_before,
            t2.nis_after,
            if t2.adopted { "adopted" } else { "not adopted" }
        );
    }
}

/// The held-out windows with their errors before and after, and the unexplained misfit.
fn heldout_section(s: &mut String, dg: &Diagnosis, t0: f64) {
    let _ = writeln!(s, "## Held-out windows\n\n{}.\n", dg.heldout_windows.how);
    let _ = writeln!(
        s,
        "| window | kind | start [min] | end [min] | error before [m] | error after [m] |\n|---|---|---|---|---|---|"
    );
    let om = |x: Option<&f64>| {
        x.filter(|v| v.is_finite())
            .map_or("-".to_string(), |v| format!("{v:.3}"))
    };
    for (i, w) in dg.heldout_windows.windows.iter().enumerate() {
        let _ = writeln!(
            s,
            "| {} | {:?} | {:.2} | {:.2} | {} | {} |",
            i + 1,
            w.kind,
            (w.start_s - t0) / 60.0,
            (w.end_s - t0) / 60.0,
            om(dg.window_errors_before_m.get(i)),
            om(dg.window_errors_after_m.get(i))
        );
    }
    if let Some(h) = &dg.heldout_change {
        let _ = writeln!(
            s,
            "\nFinal model against the configuration: {}.",
            h.describe()
        );
    }
    s.push('\n');
    if let Some(u) = &dg.unexplained {
        let _ = writeln!(s, "## Unexplained\n\n{}\n", u.summary);
    }
}

/// Every model change with its errors, and the output clock of `nav_after.txt`.
fn steps_section(s: &mut String, dg: &Diagnosis) {
    steps_table(s, &dg.steps);
    if dg.output_clock_shift_s != 0.0 {
        let _ = writeln!(
            s,
            "nav_after.txt is on the GNSS clock: its times are the IMU times {:+.4} s (minus the \
             time offset estimate).\n",
            dg.output_clock_shift_s
        );
    }
}

/// The table of the model changes `steps` with their errors.
pub(crate) fn steps_table(s: &mut String, steps: &[super::Step]) {
    let _ = writeln!(
        s,
        "## Steps (every model change; a change whose held-out errors are significantly higher is not made)\n"
    );
    let _ = writeln!(
        s,
        "| step | kept | held-out windows RMS [m] | held-out gain vs the step before | GNSS prior residual, horizontal RMS [m] | outage error vs truth [m] | 3D RMS with GNSS vs truth [m] | NIS mean | why |\n|---|---|---|---|---|---|---|---|---|"
    );
    let o = fmt_opt;
    for st in steps {
        let e = &st.errors;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.3} | {} | {} | {:.2} | {} |",
            st.label,
            if st.accepted { "yes" } else { "no" },
            o(e.heldout_windows_rms_m),
            st.heldout.as_ref().map_or("-".into(), gain_ci),
            e.gnss_prior_horizontal_rms_m,
            o(e.truth_outage_m),
            o(e.truth_with_gnss_3d_rms_m),
            e.nis_mean,
            st.reason.as_deref().unwrap_or("")
        );
    }
    s.push('\n');
}

/// The effects not added with their detectability bounds, the warnings, the candidates.
fn not_added_section(s: &mut String, dg: &Diagnosis) {
    if !dg.undetected.is_empty() {
        let _ = writeln!(
            s,
            "Not added, with the detectability bound on this drive (the smallest magnitude that \
             would have been found):\n\n| effect | bound (smallest state) | bound per state | unit | last estimate | why not |\n|---|---|---|---|---|---|"
        );
        for u in &dg.undetected {
            let _ = writeln!(
                s,
                "| {} | {:.3e} | {} | {} | {} | {} |",
                u.name,
                u.min_bound,
                fmt_vec(&u.bound),
                u.unit,
                fmt_vec(&u.estimate),
                u.reason
            );
        }
        s.push('\n');
    }
    for w in &dg.warnings {
        let _ = writeln!(s, "Warning: {w}\n");
    }
    let _ = writeln!(
        s,
        "Candidates considered: {}\n",
        dg.candidates_considered.join(", ")
    );
}

/// The added effects with their evidence and held-out gains.
fn added_section(s: &mut String, dg: &Diagnosis) {
    added_table(s, &dg.added_effects);
}

/// The table of the effects `added` with their evidence and held-out gains (nothing when
/// empty).
pub(crate) fn added_table(s: &mut String, added: &[super::AddedEffect]) {
    let o = fmt_opt;
    if !added.is_empty() {
        let _ = writeln!(
            s,
            "| effect | estimate | 1-sigma | unit | likelihood gain [nats] | evidence (gain - BIC) [nats] | held-out gain [90 % CI] | p (lower errors) | runner-up (nats behind) | held-out windows RMS before -> after [m] | GNSS prior residual before -> after [m] |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
        for e in added {
            let ru = e
                .runner_up
                .as_ref()
                .map_or(String::from("-"), |(n, m)| format!("{n} ({m:.1})"));
            let _ = writeln!(
                s,
                "| {}{} | {} | {} | {} | {:.1} | {:.1} | {} | {:.4} | {} | {} -> {} | {:.3} -> {:.3} |",
                e.name,
                if e.freed { " (freed)" } else { "" },
                fmt_vec(&e.estimate),
                fmt_vec(&e.sigma),
                e.unit,
                e.delta_log_likelihood,
                e.evidence,
                gain_ci(&e.heldout),
                e.heldout.p_better,
                ru,
                o(e.before.heldout_windows_rms_m),
                o(e.after.heldout_windows_rms_m),
                e.before.gnss_prior_horizontal_rms_m,
                e.after.gnss_prior_horizontal_rms_m
            );
        }
        s.push('\n');
    }
}

/// The position errors before and after.
fn errors_section(s: &mut String, dg: &Diagnosis) {
    let _ = writeln!(s, "## Errors ({})\n", dg.error_before.reference);
    let _ = writeln!(s, "| | before | after |\n|---|---|---|");
    let (b, a) = (&dg.error_before, &dg.error_after);
    let _ = writeln!(
        s,
        "| outages compared | {} | {} |\n| RMS over outages of the max 3D error [m] | {:.3} | {:.3} |\n| RMS over outages of the end horizontal error [m] | {:.3} | {:.3} |\n| 3D RMS, all epochs [m] | {:.3} | {:.3} |\n| prior GNSS residual, horizontal RMS [m] | {:.3} | {:.3} |\n| written solution vs the USED GNSS fixes outside outages, horizontal RMS [m] (at the final model's antenna; posterior: favours no time offset; the after solution follows the filter's running estimate of an added lever arm, its convergence included; see docs/diagnose.md) | {:.3} | {:.3} |\n",
        b.outages,
        a.outages,
        b.outage_max_3d_rms_m,
        a.outage_max_3d_rms_m,
        b.outage_end_horizontal_rms_m,
        a.outage_end_horizontal_rms_m,
        b.overall_3d_rms_m,
        a.overall_3d_rms_m,
        b.gnss_residual_horizontal_rms_m,
        a.gnss_residual_horizontal_rms_m,
        b.output_vs_fixes_horizontal_rms_m,
        a.output_vs_fixes_horizontal_rms_m
    );
    let _ = writeln!(s, "![errors](errors.png)\n");
}

/// Residual statistics before and after: NIS, log-likelihood, whiteness.
fn residuals_section(s: &mut String, dg: &Diagnosis) {
    let _ = writeln!(s, "## Residuals\n");
    let _ = writeln!(s, "| | before | after |\n|---|---|---|");
    let (rb, ra) = (&dg.residuals_before, &dg.residuals_after);
    let _ = writeln!(
        s,
        "| fixes | {} | {} |\n| NIS mean (expected {:.2}, 95 % band {:.2}..{:.2}) | {:.2} | {:.2} |\n| log-likelihood [nats] | {:.1} | {:.1} |",
        rb.updates,
        ra.updates,
        rb.nis_expected,
        rb.nis_band[0],
        rb.nis_band[1],
        rb.nis_mean,
        ra.nis_mean,
        rb.log_likelihood,
        ra.log_likelihood
    );
    for (wb, wa) in rb.whiteness.iter().zip(&ra.whiteness) {
        let _ = writeln!(
            s,
            "| Ljung-Box Q, component {} (white: < {:.1}) | {:.1} | {:.1} |",
            wb.component, wb.ljung_box_q95, wb.ljung_box_q, wa.ljung_box_q
        );
    }
    for (wb, wa) in rb.whiteness.iter().zip(&ra.whiteness) {
        let last = |w: &super::Whiteness| w.allan_ratio.last().copied().unwrap_or([0.0; 2]);
        let (lb, la) = (last(wb), last(wa));
        let _ = writeln!(
            s,
            "| m AVAR(m) of component {} at m = {:.0} fixes (white: about 1) | {:.1} | {:.1} |",
            wb.component, lb[0], lb[1], la[1]
        );
    }
    let _ = writeln!(s, "\n![innovations](innovations.png)\n\n![nis](nis.png)\n");
}

/// The search round by round: every candidate's evidence and decision.
fn evidence_section(s: &mut String, dg: &Diagnosis) {
    let _ = writeln!(s, "## Evidence\n");
    rounds_tables(s, &dg.rounds);
    let _ = writeln!(s, "![evidence](evidence.png)");
}

/// One table per search round of `rounds`: every candidate's evidence and decision.
pub(crate) fn rounds_tables(s: &mut String, rounds: &[super::Round]) {
    for (i, r) in rounds.iter().enumerate() {
        let _ = writeln!(
            s,
            "Round {} (model effects: [{}]; added: {}):\n",
            i + 1,
            r.model_effects.join(", "),
            r.added.as_deref().unwrap_or("none")
        );
        for note in r.ambiguous.iter().chain(&r.unexplained) {
            let _ = writeln!(s, "{note}\n");
        }
        let _ = writeln!(
            s,
            "| candidate | estimate +- sigma | evidence [nats] | LL gain | BIC penalty | max z | regressor corr z | held-out gain [90 % CI] | p lower / p higher | decision | reason |\n|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for c in &r.candidates {
            let _ = writeln!(
                s,
                "| {}{} | {} +- {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} | {:?} | {} |",
                c.name,
                if c.freed { " (freed)" } else { "" },
                fmt_vec(&c.estimate),
                fmt_vec(&c.sigma),
                c.evidence.unwrap_or(f64::NAN),
                c.delta_log_likelihood.unwrap_or(f64::NAN),
                c.bic_penalty,
                c.max_z,
                c.correlation_z,
                c.heldout.as_ref().map_or("-".into(), gain_ci),
                c.heldout.as_ref().map_or("-".into(), |h| format!(
                    "{:.3} / {:.3}",
                    h.p_better, h.p_worse
                )),
                c.decision,
                c.reason
            );
        }
        s.push('\n');
    }
}

/// Writes `augmented.toml` into `dir`: the input configuration (a project TOML) with the
/// added lever-arm correction folded into `gnss.lever_arm_m`, the time offset into
/// `imu.time_offset_s` (the IMU on the GNSS clock, so the run's output is on the GNSS clock),
/// the tuned noise as SI PSDs in `[noise.accel]`/`[noise.gyro]`, the tuned GNSS noise scale as
/// `gnss.sigma_scale` (times the configuration's), the fitted prior of an added GNSS error
/// state as `gnss.error_state`, and its relative paths made
/// absolute; a comment header lists every
/// added effect with its estimate; the other added effects (IMU effect blocks) are listed in
/// the top-level `effects` key, so `host-sim run --config augmented.toml` runs the augmented
/// model. KF-GINS YAML inputs are not rewritten.
pub fn write_augmented_config(
    dir: &Path,
    config: &Path,
    d: &Diagnosis,
) -> Result<(), DiagnoseError> {
    let text = std::fs::read_to_string(config).map_err(|source| DiagnoseError::ReadConfig {
        path: config.to_path_buf(),
        source,
    })?;
    let Ok(mut doc) = text.parse::<toml::Table>() else {
        return Ok(());
    };
    absolute_paths(&mut doc, config);
    fold_gnss(&mut doc, d)?;
    fold_time_offset(&mut doc, d);
    if let Some(psd) = d.final_noise_psd {
        tuned_noise(&mut doc, psd);
    }
    effects_list(&mut doc, d);
    let head = header(config, d);
    let out = format!("{head}{}", toml::to_string_pretty(&doc).unwrap_or_default());
    let path = dir.join("augmented.toml");
    std::fs::write(&path, out).map_err(|source| DiagnoseError::Write { path, source })?;
    Ok(())
}

/// The input paths of the configuration `doc` (read from `config`) made absolute.
fn absolute_paths(doc: &mut toml::Table, config: &Path) {
    let cfg_dir = config.parent().map(Path::to_path_buf).unwrap_or_default();
    let cfg_dir = std::fs::canonicalize(&cfg_dir).unwrap_or(cfg_dir);
    for sec in ["imu", "gnss", "truth"] {
        if let Some(toml::Value::Table(t)) = doc.get_mut(sec) {
            if let Some(toml::Value::String(p)) = t.get_mut("path") {
                let abs = cfg_dir.join(&*p);
                *p = abs.display().to_string();
            }
        }
    }
}

/// The lever-arm estimate added to `gnss.lever_arm_m`, the tuned GNSS noise scale as
/// `gnss.sigma_scale`, the fitted GNSS error state prior as `gnss.error_state`.
fn fold_gnss(doc: &mut toml::Table, d: &Diagnosis) -> Result<(), DiagnoseError> {
    let gnss = doc
        .entry("gnss")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    if let toml::Value::Table(g) = gnss {
        for e in d.added_effects.iter().filter(|e| e.name == "lever_arm") {
            let old: Vec<f64> = g
                .get("lever_arm_m")
                .and_then(|v| v.as_array())
                .map(|a| a.iter().filter_map(|x| x.as_float()).collect())
                .unwrap_or_else(|| vec![0.0; 3]);
            let new: Vec<toml::Value> = (0..3)
                .map(|i| {
                    let o = old.get(i).copied().unwrap_or(0.0);
                    toml::Value::Float(o + e.estimate.get(i).copied().unwrap_or(0.0))
                })
                .collect();
            g.insert("lever_arm_m".into(), toml::Value::Array(new));
        }
        let mut put = |key: &'static str, v: Result<toml::Value, toml::ser::Error>| {
            let v = v.map_err(|source| DiagnoseError::GnssKey { key, source })?;
            g.insert(key.into(), v);
            Ok::<(), DiagnoseError>(())
        };
        // the configuration's scale times the tuned GNSS noise scale: one number when
        // horizontal and vertical agree, else the table form
        if let Some(s) = d.final_gnss_sigma_scale {
            put("sigma_scale", toml::Value::try_from(s))?;
        }
        // the fitted prior of the GNSS error state, which the `effects` key adds
        if let Some(e) = d.final_gnss_error_prior {
            put("error_state", toml::Value::try_from(e))?;
        }
    }
    Ok(())
}

/// The time offset estimate moved into `imu.time_offset_s` (the IMU on the GNSS clock).
fn fold_time_offset(doc: &mut toml::Table, d: &Diagnosis) {
    if let Some(dt) = d
        .added_effects
        .iter()
        .find(|e| e.name == "time_offset")
        .and_then(|e| e.estimate.first())
    {
        // a fix tagged t is the antenna at IMU time t + dt: the IMU tags move by -dt onto the
        // GNSS clock (the run configuration's imu.time_offset_s is added to the IMU tags), so
        // the run's output is on the GNSS clock as nav_after.txt is
        let imu = doc
            .entry("imu")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let toml::Value::Table(t) = imu {
            let old = t
                .get("time_offset_s")
                .and_then(|v| v.as_float())
                .unwrap_or(0.0);
            t.insert("time_offset_s".into(), toml::Value::Float(old - dt));
        }
    }
}

/// The tuned IMU noise PSDs `psd` (SI, [`Diagnosis::final_noise_psd`]) as `[noise.accel]`
/// and `[noise.gyro]`, replacing every other spelling of the same parameter.
fn tuned_noise(doc: &mut toml::Table, psd: [f64; 6]) {
    // the tuned PSDs in SI (they include any white_noise_scale of the input)
    let noise = doc
        .entry("noise")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    if let toml::Value::Table(n) = noise {
        n.remove("white_noise_scale");
        type Keys<'a> = &'a [&'a str];
        let sensors: [(&str, [f64; 3], Keys, Keys, Keys); 2] = [
            (
                "accel",
                [psd[0], psd[1], psd[2]],
                &["s_n", "n_ug_per_sqrt_hz", "vrw_mps_per_sqrt_h"],
                &["s_b", "gm_sigma_ug"],
                &["s_k", "k_ug_per_sqrt_h", "k_ug_per_sqrt_hz"],
            ),
            (
                "gyro",
                [psd[3], psd[4], psd[5]],
                &["s_n", "arw_deg_per_sqrt_h", "n_deg_per_s_per_sqrt_hz"],
                &["s_b", "gm_sigma_deg_per_h"],
                &["s_k", "k_deg_per_h_per_sqrt_h", "k_deg_per_s_per_sqrt_hz"],
            ),
        ];
        for (name, v, white, gm, rw) in sensors {
            let t = n
                .entry(name)
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let toml::Value::Table(t) = t {
                for (keys, val) in [(white, v[0]), (gm, v[1]), (rw, v[2])] {
                    for k in keys {
                        t.remove(*k);
                    }
                    if val > 0.0 {
                        t.insert(keys[0].into(), toml::Value::Float(val));
                    }
                }
            }
        }
    }
}

/// The added IMU effect blocks appended to the top-level `effects` list.
fn effects_list(doc: &mut toml::Table, d: &Diagnosis) {
    let imu_effects: Vec<&str> = d
        .added_effects
        .iter()
        .map(|e| e.name.as_str())
        .filter(|n| !matches!(*n, "lever_arm" | "time_offset"))
        .collect();
    if !imu_effects.is_empty() {
        let mut list: Vec<toml::Value> = doc
            .get("effects")
            .and_then(|v| v.as_array())
            .cloned()
            .unwrap_or_default();
        for n in &imu_effects {
            if !list.iter().any(|v| v.as_str() == Some(n)) {
                list.push(toml::Value::String((*n).to_string()));
            }
        }
        doc.insert("effects".into(), toml::Value::Array(list));
    }
}

/// The comment header of `augmented.toml`: its origin, the verdict, every added effect, the
/// closing comments.
fn header(config: &Path, d: &Diagnosis) -> String {
    let mut head = format!(
        "# Written by host-sim diagnose from {} (paths made absolute).\n\
         # Verdict: {}. lever_arm is folded into [gnss], time_offset into [imu] (output on the GNSS clock), the other\n\
         # added effects are appended to the model by the `effects` key;\n",
        config.display(),
        d.verdict
    );
    for e in &d.added_effects {
        head.push_str(&format!(
            "# {}: estimate {:?} sigma {:?} [{}]\n",
            e.name, e.estimate, e.sigma, e.unit
        ));
    }
    head.push_str(&closing_comments(d));
    head
}

/// The last comment lines of `augmented.toml`: a named clock drift's rate as a recommendation
/// (the run configuration has no clock-rate key: only the constant `imu.time_offset_s`), then
/// how to run it.
fn closing_comments(d: &Diagnosis) -> String {
    let mut out = String::new();
    if let Some(e) = d.added_effects.iter().find(|e| e.name == "imu_clock_drift") {
        // the run configuration has no key for a clock rate (nav_io::RunConfig: only the
        // constant imu.time_offset_s), so the rate is a recommendation, not a setting
        let (dt0, rate) = (
            e.estimate.first().copied().unwrap_or(f64::NAN),
            e.estimate.get(1).copied().unwrap_or(f64::NAN),
        );
        let sr = e.sigma.get(1).copied().unwrap_or(f64::NAN);
        out.push_str(&format!(
            "# imu clock drift (recommendation, not applied: the run configuration has no \
             clock-rate key): imu_clock_rate_ppm = {:.2} (1-sigma {:.2}), offset at the start \
             {dt0:.4} s (IMU time tau is GNSS time tau - dt_0 - rate (tau - t_0)); the `effects` \
             list keeps imu_clock_drift so the run estimates it\n",
            rate * 1e6,
            sr * 1e6
        ));
    }
    out.push_str("# run with: host-sim run --config augmented.toml\n");
    out
}
