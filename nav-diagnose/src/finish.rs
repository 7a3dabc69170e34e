//! The end of the search: the time offset held, the noise re-fitted with the effects, the final
//! run with every fix, the figures before and after, what was not added and the verdict.
use super::*;

/// The data with the IMU (and the truth, on the IMU clock) moved onto the GNSS clock for a
/// time offset `dt` (s, a fix tagged t is the antenna at IMU time t + dt): every IMU and
/// truth time minus `dt`, as `imu.time_offset_s` of `augmented.toml` does.
pub(crate) fn on_gnss_clock(case: &Case, dt: f64) -> Case {
    case.adjusted(Adjust {
        time_shift_s: dt,
        ..*case.imu.adjust()
    })
}

/// The time offset the final noise would absorb: when the search's final model (`s.cur`, its
/// noise tuned) moves the added `time_offset` by more than [`validate::MIN_Z`] combined sigmas
/// from its estimate when it was added (`|new - old| / sqrt(s_old^2 + s_new^2)`), the offset
/// is held at that estimate (the IMU data moved onto the GNSS clock, [`on_gnss_clock`], its
/// state removed), the noise re-fitted there with the other effects, and this model kept
/// unless the joint one predicts the held-out windows significantly better (paired test).
/// A larger white noise lets the filter absorb part of the offset into its velocity and
/// position states: on the real drive the offset was 0.106 s when added, 0.039 +- 0.0016 s
/// with the white-noise PSDs x512/x1024. Returns the data and options of the final model
/// when the offset is held.
pub(crate) fn hold_time_offset(ctx: &Ctx<'_>, s: &mut Search) -> Option<(Data, RunOptions)> {
    let info = s
        .added_info
        .iter()
        .find(|e| e.name == Block::TimeOffset.name())?;
    let (e0, s0) = (*info.estimate.first()?, *info.sigma.first()?);
    let (e1, s1) = effect_values(&s.cur.run, Block::TimeOffset.name());
    let (e1, s1) = (*e1.first()?, *s1.first()?);
    let z = (e1 - e0).abs() / (s0 * s0 + s1 * s1).sqrt();
    if z.is_nan() || z <= validate::MIN_Z {
        return None;
    }
    let p = ctx.p;
    let moved = Data {
        case: on_gnss_clock(&p.case, e0),
        ..p.clone()
    };
    let others: Vec<Block> = s
        .added
        .iter()
        .copied()
        .filter(|b| *b != Block::TimeOffset)
        .collect();
    let mut o = options_with(&p.opts, &others);
    let mut label = format!("time offset held at {e0:.4} s (its estimate when added)");
    if ctx.dopts.tune_noise {
        let base = spill::run_innovations(&moved.case, &ctx.searching(&o)).ok()?;
        let t = noise::tune(
            &moved.case,
            &ctx.searching(&o),
            &residual_stats(&base.innovations),
        );
        t.chosen.apply(&mut o);
        label.push_str(&format!(", noise re-tuned: {}", t.chosen.describe()));
    }
    let ev = match ctx.evaluate_case(&moved.case, &o) {
        Ok(ev) => ev,
        Err(e) => {
            s.warnings
                .push(format!("the run with the time offset held failed: {e}"));
            return None;
        }
    };
    // the joint model (the offset moved to e1) against the held one
    let joint = validate::compare_windows(&ev.windows, &s.cur.windows);
    let keep = joint.verdict != HeldoutVerdict::Better;
    let reason = format!(
        "the final noise moved time_offset {e0:.4} -> {e1:.4} s ({z:.1} sigma); the joint \
         model against the offset held: {}",
        joint.describe()
    );
    s.steps.push(Step {
        label,
        accepted: keep,
        reason: Some(reason),
        errors: ev.errors,
        heldout: Some(validate::compare_windows(&s.cur.windows, &ev.windows)),
    });
    if !keep {
        return None;
    }
    s.cur = ev;
    s.time_offset_held = Some(e0);
    Some((moved, o))
}

/// The noise re-fitted with the effects in the model (from the configuration's noise); kept
/// unless its held-out errors are significantly higher. Returns the final model's options.
pub(crate) fn retune_noise(ctx: &Ctx<'_>, s: &mut Search) -> RunOptions {
    let p = ctx.p;
    let mut final_opts = options_with(&s.base_opts, &s.added);
    let Some(mut t) = s.noise_tuning.take() else {
        return final_opts;
    };
    if s.added.is_empty() {
        s.noise_tuning = Some(t);
        return final_opts;
    }
    let with = options_with(&p.opts, &s.added);
    if let Ok(base_with) = spill::run_innovations(&p.case, &ctx.searching(&with)) {
        let mut t2 = noise::tune(
            &p.case,
            &ctx.searching(&with),
            &residual_stats(&base_with.innovations),
        );
        let mut o = with.clone();
        t2.chosen.apply(&mut o);
        let label = format!("noise re-tuned with the effects: {}", t2.chosen.describe());
        if o.filter != final_opts.filter || o.gnss_sigma_scale != final_opts.gnss_sigma_scale {
            match ctx.evaluate(&o) {
                Ok(ev) => {
                    let h = validate::compare_windows(&s.cur.windows, &ev.windows);
                    let why = noise_heldout_check(&s.cur.errors, &ev.errors, &h).err();
                    let worse = why.is_some();
                    s.steps.push(Step {
                        label,
                        accepted: !worse,
                        reason: why,
                        errors: ev.errors,
                        heldout: Some(h),
                    });
                    if !worse {
                        t2.adopted = true;
                        final_opts = o;
                        s.cur = ev;
                    }
                }
                Err(e) => s.warnings.push(format!("re-tuned noise run failed: {e}")),
            }
        } else {
            t2.adopted = t.adopted;
        }
        t.with_effects = Some(Box::new(t2));
    }
    s.noise_tuning = Some(t);
    final_opts
}

/// Where the final model's misfit sits when no effect of the vocabulary explains it: the
/// strongest paying candidate left unexplained in the last round, or a NIS mean above its
/// band; None otherwise.
pub(crate) fn unexplained_misfit(
    s: &Search,
    residuals_after: &ResidualStats,
) -> Option<stats::Unexplained> {
    let left = s.rounds.last().and_then(|r| r.unexplained.clone());
    let high_nis = residuals_after.nis_mean > residuals_after.nis_band[1];
    if left.is_none() && !high_nis {
        return None;
    }
    let spans = stats::misfit_spans(&s.cur.run.innovations, stats::MISFIT_BIN_S);
    let t0 = s.cur.run.nav.first().map_or(0.0, |n| n.t_s);
    let mut what = match &left {
        Some(u) => format!("likelihood gain no effect of the vocabulary explains: {u}"),
        None => format!(
            "NIS mean {:.2} above its band (expected {:.2})",
            residuals_after.nis_mean, residuals_after.nis_expected
        ),
    };
    if spans.is_empty() {
        what.push_str("; no stretch of the drive stands out (the misfit is spread)");
    } else {
        let list: Vec<String> = spans
            .iter()
            .take(5)
            .map(|m| {
                format!(
                    "{:.1}-{:.1} min (NIS {:.1})",
                    (m.start_s - t0) / 60.0,
                    (m.end_s - t0) / 60.0,
                    m.nis_mean
                )
            })
            .collect();
        what.push_str(&format!("; the misfit sits at {}", list.join(", ")));
    }
    Some(stats::Unexplained {
        summary: what,
        spans,
    })
}

/// The base run: its summary, its navigation records, its metrics.
pub(crate) type BaseRun = (Arc<RunOutput>, spill::NavFile, Metrics);

/// The final run with every fix (its navigation to a file, [`spill`]); when it fails, the
/// current search run stands for it, with a warning (its navigation is the search's record
/// of it: the records nearest the fixes).
pub(crate) fn final_run(
    ctx: &Ctx<'_>,
    s: &mut Search,
    final_opts: &RunOptions,
) -> Result<(Arc<RunOutput>, spill::NavFile, Metrics), DiagnoseError> {
    match spill::run_to_file(&ctx.p.case, final_opts, &ctx.folder, "after") {
        Ok((r, nav, m)) => Ok((Arc::new(r), nav, m)),
        Err(e) => {
            s.warnings.push(format!(
                "the final run with every fix failed ({}): the after figures are the last \
                 search run's (held-out windows withheld), nav_after.txt its records nearest \
                 the fixes",
                error::chain(&e)
            ));
            let nav = spill::NavFile::from_slice(&ctx.folder, "after-search", &s.cur.run.nav)?;
            Ok((s.cur.run.clone(), nav, s.cur.metrics.clone()))
        }
    }
}

/// The final run with every fix (the final model's options `final_opts`), the figures
/// before (the base run's position errors `error_before`) and after, what was not added, the
/// verdict and the warnings.
pub(crate) fn finish(
    ctx: &Ctx<'_>,
    mut s: Search,
    all: &[Block],
    base: &Eval,
    (before, before_nav, errors_before): BaseRun,
    (final_opts, error_before): (RunOptions, ErrorSummary),
) -> Result<DiagnoseOutput, DiagnoseError> {
    let p = ctx.p;
    let final_gnss_sigma_scale = (final_opts.gnss_sigma_scale != p.opts.gnss_sigma_scale)
        .then_some(final_opts.gnss_sigma_scale);
    let final_gm = final_opts.filter.effects.gnss_position_gm;
    let final_gnss_error_prior = (prior::carried(&final_opts, Block::GnssPositionGm)
        && final_gm != p.opts.filter.effects.gnss_position_gm)
        .then(|| nav_io::GnssErrorPrior::from(final_gm));
    let changed = final_opts.filter != p.opts.filter
        || final_gnss_sigma_scale.is_some()
        || !s.added.is_empty()
        || s.bias_step.is_some();
    let (after, after_nav, errors_after) = if changed {
        final_run(ctx, &mut s, &final_opts)?
    } else {
        (before.clone(), before_nav.clone(), errors_before.clone())
    };
    // the added effects' estimates in the final model
    for e in &mut s.added_info {
        let (est, sig) = effect_values(&after, &e.name);
        if !est.is_empty() {
            e.estimate = est;
            e.sigma = sig;
        }
    }
    let residuals_before = residual_stats(&before.innovations);
    let residuals_after = residual_stats(&after.innovations);
    let output_clock_shift_s = s
        .added_info
        .iter()
        .find(|e| e.name == Block::TimeOffset.name())
        .or_else(|| {
            s.added_info
                .iter()
                .find(|e| e.name == Block::ImuClockDrift.name())
        })
        .and_then(|e| e.estimate.first())
        .map_or(0.0, |dt| -dt);
    let ovf = |run: &RunOutput, nav: &spill::NavFile| {
        validate::written_solution_vs_fixes_file(run, nav, &p.case.gnss)
    };
    let error_after = error_summary(&errors_after, ovf(&after, &after_nav)?);
    let undetected = undetected(all, &s);
    let s_held = s.time_offset_held.is_some();
    let unexplained = unexplained_misfit(&s, &residuals_after);
    let heldout_change = validate::compare_windows(&base.windows, &s.cur.windows);
    let verdict = verdict(
        &s,
        unexplained.as_ref(),
        final_gnss_sigma_scale.map(|g| (g, p.opts.gnss_sigma_scale)),
    );
    warn(
        &mut s,
        &residuals_before,
        &residuals_after,
        &heldout_change,
        changed,
    );
    if let Some(u) = &unexplained {
        s.warnings.push(u.summary.clone());
    }
    let final_noise_psd =
        (final_opts.filter != options_with(&p.opts, &s.added).filter).then(|| {
            let f = &final_opts.filter;
            [
                f.accel.s_n[0],
                f.accel.s_b[0],
                f.accel.s_k[0],
                f.gyro.s_n[0],
                f.gyro.s_b[0],
                f.gyro.s_k[0],
            ]
        });
    Ok(DiagnoseOutput {
        diagnosis: Diagnosis {
            added_effects: s.added_info,
            verdict,
            noise_tuning: s.noise_tuning,
            final_noise_psd,
            final_gnss_sigma_scale,
            final_gnss_error_prior,
            steps: s.steps,
            undetected,
            unexplained,
            warnings: s.warnings,
            candidates_considered: validate::names(all),
            heldout_windows: ctx.plan.clone(),
            window_errors_before_m: base.windows.clone(),
            window_errors_after_m: s.cur.windows.clone(),
            heldout_change: changed.then_some(heldout_change),
            residuals_before,
            residuals_after,
            rounds: s.rounds,
            output_clock_shift_s,
            time_offset_held_s: s.time_offset_held,
            bias_step: s.bias_step,
            bias_step_not_kept: s.bias_step_not_kept,
            error_before,
            error_after,
            errors_before,
            errors_after,
        },
        before,
        before_nav,
        after,
        after_nav,
        after_nav_shift_s: if s_held { 0.0 } else { output_clock_shift_s },
    })
}

/// Effects not added, with what could have been seen.
pub(crate) fn undetected(all: &[Block], s: &Search) -> Vec<Undetected> {
    let mut v = Vec::new();
    for b in all {
        if s.added.contains(b) || prior::nested_in(&s.added, *b) {
            continue;
        }
        let last = s
            .rounds
            .iter()
            .rev()
            .flat_map(|r| r.candidates.iter())
            .find(|c| c.name == b.name() && !c.sigma.is_empty());
        if let Some(c) = last {
            v.push(Undetected {
                name: c.name.clone(),
                unit: b.unit().to_string(),
                bound: c.detectability_bound.clone(),
                min_bound: validate::min_bound(&c.detectability_bound),
                estimate: c.estimate.clone(),
                reason: c.refused.clone().unwrap_or_else(|| "not reached".into()),
            });
        }
    }
    v
}

/// "none detectable" or the names added, the GNSS noise scale when the final model changed
/// it (`gnss`: the final and the configuration's sigma_scale), with the ambiguities and any
/// unexplained misfit.
pub(crate) fn verdict(
    s: &Search,
    unexplained: Option<&stats::Unexplained>,
    gnss: Option<(nav_io::SigmaScale, nav_io::SigmaScale)>,
) -> String {
    let mut verdict = if s.added_info.is_empty() {
        "none detectable".to_string()
    } else {
        s.added_info
            .iter()
            .map(|e| e.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some((g, c)) = gnss {
        let k = g.horizontal / c.horizontal;
        let kv = g.vertical / c.vertical;
        let g = format!("GNSS noise scale x{k:.2} horizontal, x{kv:.2} vertical");
        verdict = if s.added_info.is_empty() {
            g
        } else {
            format!("{verdict}; {g}")
        };
    }
    for r in &s.rounds {
        if let Some(a) = &r.ambiguous {
            verdict.push_str(&format!("; {a}"));
        }
    }
    if let Some(b) = &s.bias_step {
        verdict.push_str(&format!("; {} at {:.1} s", b.name, b.t_s));
    }
    if let Some(u) = unexplained.filter(|u| !u.spans.is_empty()) {
        verdict.push_str(&format!(
            "; unexplained misfit ({} stretch(es) of high NIS)",
            u.spans.len()
        ));
    }
    verdict
}

pub(crate) fn warn(
    s: &mut Search,
    residuals_before: &ResidualStats,
    residuals_after: &ResidualStats,
    heldout_change: &HeldoutComparison,
    changed: bool,
) {
    let (nis, dim) = (residuals_before.nis_mean, residuals_before.nis_expected);
    if dim > 0.0 && !(0.5 * dim..=2.0 * dim).contains(&residuals_after.nis_mean) {
        let after_nis = residuals_after.nis_mean;
        s.warnings.push(format!(
            "model inconsistent with the data even after the diagnosis: NIS mean {after_nis:.1} \
             (base {nis:.1}) for an expected {dim:.1}; the inconsistency is not only the IMU \
             noise levels (GNSS sigmas, vibration, unmodelled effects)"
        ));
    }
    if residuals_before.updates < 30 {
        s.warnings.push(format!(
            "only {} GNSS updates: little evidence either way",
            residuals_before.updates
        ));
    }
    if changed && heldout_change.verdict == HeldoutVerdict::Worse {
        s.warnings.push(format!(
            "the final model predicts the held-out windows significantly worse than the \
             configuration: {}",
            heldout_change.describe()
        ));
    }
}
