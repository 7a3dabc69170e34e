//! The search's context and state: a model's run scored on the held-out windows, the base
//! run, the bias step judged before the search and after each added effect, the start of the search.
use super::*;

pub(crate) fn error_summary(m: &Metrics, output_vs_fixes: f64) -> ErrorSummary {
    ErrorSummary {
        reference: if m.reference == "truth" {
            "truth"
        } else {
            "withheld_gnss"
        },
        outages: m.outage_summary.count,
        outage_max_3d_rms_m: outage_error_m(m),
        outage_end_horizontal_rms_m: m.outage_summary.end_horizontal_m.rms,
        overall_3d_rms_m: m.overall.pos_3d_m.rms,
        gnss_residual_horizontal_rms_m: m.gnss_residuals.horizontal_m.rms,
        output_vs_fixes_horizontal_rms_m: output_vs_fixes,
    }
}

pub(crate) fn effect_values(out: &RunOutput, name: &str) -> (Vec<f64>, Vec<f64>) {
    out.final_effects
        .iter()
        .find(|e| e.name == name)
        .map_or((Vec::new(), Vec::new()), |e| {
            (e.value.clone(), e.std.clone())
        })
}

pub(crate) fn dim_of(o: &RunOptions) -> usize {
    o.model.layout().dim() + o.extra_blocks.iter().map(|b| b.dim()).sum::<usize>()
}

/// A run of the search with its metrics, errors and held-out window errors.
#[derive(Clone)]
pub(crate) struct Eval {
    pub(crate) run: Arc<RunOutput>,
    pub(crate) metrics: Metrics,
    pub(crate) errors: StepErrors,
    /// Error per held-out window, m ([`validate::window_errors_m`]).
    pub(crate) windows: Vec<f64>,
}

/// Navigation record rate of the search's runs, Hz: enough for the metrics' interpolation
/// (records at most 0.05 s apart), an eighth of the memory of every epoch at 200 Hz.
pub const SEARCH_NAV_RATE_HZ: f64 = 25.0;

/// Rate of the epoch records of a search run whose model carries a GNSS error state
/// (`gnss_position_gm`), Hz: the state's estimate predicts the withheld fixes
/// ([`spill::predict_withheld_fixes`]).
pub const SEARCH_GNSS_ERROR_RATE_HZ: f64 = 2.0;

/// Options of a search run: navigation recorded at [`SEARCH_NAV_RATE_HZ`] (when the IMU is
/// faster), no epoch records (the estimates come from the final state) unless the model
/// carries a GNSS error state ([`SEARCH_GNSS_ERROR_RATE_HZ`]).
pub fn search_recording(o: &RunOptions) -> RunOptions {
    let mut o = o.clone();
    o.record.nav_rate_hz = Some(
        o.record
            .nav_rate_hz
            .map_or(SEARCH_NAV_RATE_HZ, |r| r.min(SEARCH_NAV_RATE_HZ)),
    );
    let gnss_error = prior::carried(&o, Block::GnssPositionGm);
    o.record.epoch_rate_hz = Some(if gnss_error {
        SEARCH_GNSS_ERROR_RATE_HZ
    } else {
        0.0
    });
    o
}

/// What the search needs besides the options of a model: the case, the held-out windows
/// and whether to score the smoothed solution too.
pub(crate) struct Ctx<'a> {
    pub(crate) p: &'a Data,
    pub(crate) dopts: &'a DiagnoseOptions,
    pub(crate) plan: HeldoutPlan,
    /// The outages the diagnosis withholds beyond the imposed ones.
    pub(crate) withheld: Vec<Outage>,
    /// The fixes withheld one at a time to judge a GNSS-side candidate
    /// ([`validate::interleaved_fixes`]), s.
    pub(crate) interleaved: Vec<f64>,
    /// The temporary folder of the runs' navigation files ([`spill`]).
    pub(crate) folder: spill::TempFolder,
    /// Search runs so far (names their files).
    pub(crate) runs: std::sync::atomic::AtomicUsize,
}

impl Ctx<'_> {
    /// A model's options as the search runs it: the diagnosis's windows withheld too.
    pub(crate) fn searching(&self, o: &RunOptions) -> RunOptions {
        let mut o = search_recording(o);
        o.outages.extend(self.withheld.iter().copied());
        o
    }

    /// The prediction error of a model at each fix withheld one at a time
    /// ([`validate::fix_errors_m`]): a run with those fixes withheld (and the imposed outages,
    /// not the diagnosis's windows), m.
    pub(crate) fn fix_errors(&self, o: &RunOptions) -> Result<Vec<f64>, nav_engine::run::RunError> {
        let mut ro = search_recording(o);
        ro.outages
            .extend(validate::single_fix_outages(&self.interleaved));
        let out = spill::run_innovations(&self.p.case, &ro)?;
        Ok(validate::fix_errors_m(&out.innovations, &self.interleaved))
    }

    /// Runs a model with the held-out windows withheld and scores it.
    pub(crate) fn evaluate(&self, o: &RunOptions) -> Result<Eval, nav_engine::run::RunError> {
        self.evaluate_case(&self.p.case, o)
    }

    /// [`Self::evaluate`] on other data (the same fixes: the IMU data moved or corrected).
    pub(crate) fn evaluate_case(
        &self,
        case: &Case,
        o: &RunOptions,
    ) -> Result<Eval, nav_engine::run::RunError> {
        let mut ro = self.searching(o);
        ro.smoother_history |= self.dopts.smooth;
        if !self.dopts.smooth {
            return self.evaluate_from_file(case, &ro);
        }
        // the smoother's run in memory: the samples read into a case of their own
        let case = &in_memory(case).map_err(nav_engine::run::RunError::Input)?;
        let mut out = run_filter(case, &ro)?;
        let estimates: Vec<(f64, Vec<f64>)> = std::mem::take(&mut out.epochs)
            .into_iter()
            .map(|e| (e.t_s, e.estimates))
            .collect();
        let track = spill::gnss_error_track(&out.state_names, &estimates);
        spill::predict_withheld_fixes(
            &mut out.innovations,
            &track,
            ro.filter.effects.gnss_position_gm.t_s,
        );
        let m = metrics::compute(&out, case.truth.as_deref());
        let mut e = validate::step_errors(&out, &m);
        e.written_vs_fixes_m = validate::written_solution_vs_fixes_m(&out, &case.gnss);
        if self.dopts.smooth {
            // a run the smoother refuses keeps None: scored on the forward solution
            if let Ok((so, _, _)) = nav_engine::smooth::apply::smooth_run(case, &out) {
                e.heldout_outage_smoothed_m = validate::heldout_outage_error_m(&so);
            }
            out.history = None;
        }
        Ok(self.scored(out, m, e))
    }

    /// [`Self::evaluate`] without the smoother: the run's navigation (search rate) in a file
    /// of its own ([`spill`]), read for the metrics and the written-solution check, and its
    /// records nearest the fixes kept: the same numbers, memory proportional to the fixes.
    pub(crate) fn evaluate_from_file(
        &self,
        case: &Case,
        ro: &RunOptions,
    ) -> Result<Eval, nav_engine::run::RunError> {
        use nav_engine::run::RunError;
        // the same model on the same data scored before ([`crate::memo`])
        let key = crate::memo::RunMemo::key(case, ro);
        let rate = ro.record.nav_rate_hz;
        if let Some(ev) = case.memo().eval(&key, rate) {
            return Ok(ev);
        }
        let name = format!(
            "search-{}",
            self.runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        );
        let (mut out, nav) = spill::run_nav_to_file(case, ro, &self.folder, &name)?;
        let read = |out: &RunOutput| -> Result<_, nav_io::IoError> {
            let m = spill::metrics_of(case, out, &nav, false)?;
            let mut e = validate::step_errors(out, &m);
            e.written_vs_fixes_m = validate::written_solution_vs_fixes_file(out, &nav, &case.gnss)?;
            Ok((m, e, spill::nav_at_fixes(&nav, &out.innovations)?))
        };
        let res = read(&out);
        spill::remove(nav);
        let (m, e, kept) = res.map_err(RunError::Output)?;
        out.nav = kept;
        let ev = self.scored(out, m, e);
        case.memo().keep_eval(key, rate, &ev);
        Ok(ev)
    }

    /// The run scored on the held-out windows; its navigation thinned to what the search
    /// reads of it afterwards ([`nav_at_fixes`]).
    pub(crate) fn scored(
        &self,
        mut run: RunOutput,
        metrics: Metrics,
        mut errors: StepErrors,
    ) -> Eval {
        let windows = validate::window_errors_m(&run, &self.plan.windows);
        errors.heldout_windows_rms_m = rms_finite(&windows);
        nav_at_fixes(&mut run);
        Eval {
            run: Arc::new(run),
            metrics,
            errors,
            windows,
        }
    }
}

/// Keeps of a search run's navigation only the records the search reads once the run is
/// scored: the first one (the time origin of the misfit spans) and, for each innovation
/// record, the one nearest its fix ([`regressor_correlation`]: the nearest record in the
/// thinned list is the nearest in the whole one). At most one record (168 bytes) per fix
/// plus one, instead of one per navigation epoch.
pub(crate) fn nav_at_fixes(run: &mut RunOutput) {
    let nav = std::mem::take(&mut run.nav);
    let mut keep = vec![false; nav.len()];
    if let Some(k) = keep.first_mut() {
        *k = true;
    }
    for r in &run.innovations {
        if let Some(k) = stats::nearest(&nav, r.t_s, |s| s.t_s).and_then(|i| keep.get_mut(i)) {
            *k = true;
        }
    }
    run.nav = nav
        .into_iter()
        .zip(keep)
        .filter_map(|(s, k)| k.then_some(s))
        .collect();
}

pub(crate) fn rms_finite(v: &[f64]) -> Option<f64> {
    let f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    (!f.is_empty()).then(|| (f.iter().map(|x| x * x).sum::<f64>() / f.len() as f64).sqrt())
}

/// The state of the search between its steps.
pub(crate) struct Search {
    /// The configuration's options with the adopted noise (no effects).
    pub(crate) base_opts: RunOptions,
    /// The current model's run.
    pub(crate) cur: Eval,
    pub(crate) noise_tuning: Option<NoiseTuning>,
    pub(crate) pending_noise: Option<NoiseFactors>,
    pub(crate) last_noise_refusal: Option<Step>,
    pub(crate) added: Vec<Block>,
    pub(crate) added_info: Vec<AddedEffect>,
    pub(crate) rounds: Vec<Round>,
    pub(crate) steps: Vec<Step>,
    pub(crate) warnings: Vec<String>,
    /// The bias step removed from the data before the search ([`find_bias_step`]).
    pub(crate) bias_step: Option<changepoint::BiasStep>,
    /// The bias step found but not kept by the held-out rule.
    pub(crate) bias_step_not_kept: Option<changepoint::BiasStep>,
    /// The time offset held at its estimate when it was added ([`hold_time_offset`]): the
    /// final model runs on the IMU data moved onto the GNSS clock, without the state.
    pub(crate) time_offset_held: Option<f64>,
    /// Step candidates judged after added effects so far ([`late_bias_step`]).
    pub(crate) late_steps_judged: usize,
    /// Whether the kept bias step was refitted with a candidate ([`refit_step_with_effect`]).
    pub(crate) step_refitted: bool,
    /// The last round's fitted prior of the GNSS error state candidate
    /// ([`gnss_error::fit`]): the next round's fit starts there, an added state keeps it.
    pub(crate) gnss_error_fit: Option<gnss_error::GnssErrorFit>,
}

impl Search {
    /// Adopts the tuned noise `k` with its run `ev` as the current model: the base options
    /// take it, the tuning is marked adopted and nothing is pending or refused any more.
    pub(crate) fn adopt_noise(&mut self, k: NoiseFactors, ev: Eval) {
        if let Some(t) = self.noise_tuning.as_mut() {
            t.adopted = true;
        }
        k.apply(&mut self.base_opts);
        self.pending_noise = None;
        self.last_noise_refusal = None;
        self.cur = ev;
    }
}

/// The data of `case` with its IMU samples in memory (for the smoother's runs).
pub(crate) fn in_memory(case: &Case) -> Result<nav_engine::run::CaseData, nav_io::IoError> {
    let mut c = (**case).clone();
    let mut lines = Vec::with_capacity(case.imu.len());
    for r in case.imu.read_from(0)? {
        let (s, line) = r?;
        c.imu.push(s);
        lines.push(line);
    }
    let info = case.imu.cache().info();
    c.imu_origin = info.path.clone().map(|path| nav_io::ImuOrigin {
        path,
        lines,
        increments_span_gaps: info.increments_span_gaps,
    });
    Ok(c)
}

/// The base model's search run (windows withheld; the full run, its navigation read back
/// into memory, when the diagnosis withholds nothing).
pub(crate) fn base_eval(
    ctx: &Ctx<'_>,
    before: &RunOutput,
    before_nav: &spill::NavFile,
    errors_before: &Metrics,
) -> Result<Eval, DiagnoseError> {
    let p = ctx.p;
    let mut se = validate::step_errors(before, errors_before);
    se.written_vs_fixes_m =
        validate::written_solution_vs_fixes_file(before, before_nav, &p.case.gnss)?;
    Ok(if ctx.withheld.is_empty() && !ctx.dopts.smooth {
        let run = RunOutput {
            nav: before_nav.load()?,
            ..before.clone()
        };
        ctx.scored(run, errors_before.clone(), se)
    } else {
        ctx.evaluate(&p.opts)?
    })
}

/// A bias step is not a state: found as a change point in the base run's innovations
/// ([`changepoint::find_bias_step`]), with the case the step is removed from.
pub(crate) fn find_bias_step(
    p: &Data,
    before: &RunOutput,
) -> Option<(changepoint::BiasStep, Data)> {
    let s = changepoint::find_bias_step(&p.case, &p.opts, before)?;
    let stepped = Data {
        case: s.corrected_case(&p.case),
        ..p.clone()
    };
    Some((s, stepped))
}

/// A bias step found by the change-point search, judged on the held-out windows as an
/// effect is ([`decide`]: its evidence, its estimate at least 2 sigma, its held-out windows
/// significantly lower than the recorded data's; not kept otherwise).
pub(crate) enum StepJudged {
    /// No step found.
    None,
    /// Kept: the step, the base model's run on the data with it removed, its model step.
    Kept(changepoint::BiasStep, Box<Eval>, Step),
    /// Not kept: the step (with its comparison and reason) and its refused model step.
    NotKept(changepoint::BiasStep, Step),
}

/// Judges the bias step `found` (with the data it is removed from) on the held-out windows
/// against the base model's search run `base`; returns the context the search runs on (the
/// corrected data when the step is kept, the recorded data otherwise) and the judgement.
/// When the IMU file carries a temperature (the temperature block of the step's sensor is
/// among the candidates `all`), a step is kept only if it explains the misfit better than
/// that block ([`temperature_explains`]).
pub(crate) fn judge_bias_step<'a>(
    ctx: Ctx<'a>,
    base: &Eval,
    found: Option<&'a (changepoint::BiasStep, Data)>,
    all: &[Block],
) -> Result<(Ctx<'a>, StepJudged), DiagnoseError> {
    let Some((b, stepped)) = found else {
        return Ok((ctx, StepJudged::None));
    };
    let recorded = ctx.p;
    let sctx = Ctx { p: stepped, ..ctx };
    let cur = sctx.evaluate(&recorded.opts)?;
    let (mut b, mut step, mut kept) = judge_step(b, &base.windows, &cur, "bias step removed");
    if kept {
        if let Some(why) = temperature_explains(&sctx, recorded, (base, &cur), &b, all)? {
            kept = false;
            step.accepted = false;
            step.reason = Some(why.clone());
            b.reason = Some(why);
        }
    }
    Ok(if kept {
        (sctx, StepJudged::Kept(b, Box::new(cur), step))
    } else {
        (
            Ctx {
                p: recorded,
                ..sctx
            },
            StepJudged::NotKept(b, step),
        )
    })
}

/// Why a bias step is not kept although it passed [`decide`], when the IMU file carries a
/// temperature: the temperature block of its sensor (among the candidates `all`), run on the
/// `recorded` data, has at least the step's evidence (log-likelihood gain over the base
/// model's run `base` less the BIC penalty: 3 coefficients against the step's 4 parameters;
/// `stepped`, the base model's run on the data with the step removed). A bias that follows the recorded
/// temperature is a temperature coefficient, and it is judged as one in the rounds. On the
/// undeclared drives with a gyro temperature coefficient of 0.3-0.6 deg/h/degC over a 20 degC
/// warm-up (10 minutes, 50 Hz) the change-point search took the warm-up for a gyro step of
/// about 15 deg/h at 155 s on seed 103 and named it; a true step does not follow the
/// temperature and keeps its evidence. None when the step stays kept (or no temperature).
fn temperature_explains(
    ctx: &Ctx<'_>,
    recorded: &Data,
    (base, stepped): (&Eval, &Eval),
    b: &changepoint::BiasStep,
    all: &[Block],
) -> Result<Option<String>, DiagnoseError> {
    let t = match b.sensor {
        changepoint::BiasStepSensor::Accel => Block::AccelTemperatureBias,
        changepoint::BiasStepSensor::Gyro => Block::GyroTemperatureBias,
    };
    if !all.contains(&t) {
        return Ok(None);
    }
    let temp = ctx.evaluate_case(&recorded.case, &options_with(&recorded.opts, &[t]))?;
    let n_meas = residual_stats(&base.run.innovations)
        .scalar_measurements
        .max(2) as f64;
    let ll0 = base.errors.log_likelihood;
    let temp_penalty = 0.5 * prior::added_params(&[], t) as f64 * n_meas.ln();
    let temp_evidence = temp.errors.log_likelihood - ll0 - temp_penalty;
    let step_evidence = stepped.errors.log_likelihood - ll0 - b.bic_penalty;
    Ok((temp_evidence >= step_evidence).then(|| {
        format!(
            "{} explains the change at least as well as the step (evidence {temp_evidence:.1} \
             against {step_evidence:.1} nats): a bias following the recorded temperature",
            t.name()
        )
    }))
}

/// A step found as a change point judged ([`decide`]: its evidence over the BIC penalty, its
/// largest z, and the held-out windows of `cur`, the run on the data with it removed, against
/// `before_windows`, m): the step with its comparison and reason, the model step labelled
/// `label` and the step's description, and whether it is kept.
fn judge_step(
    b: &changepoint::BiasStep,
    before_windows: &[f64],
    cur: &Eval,
    label: &str,
) -> (changepoint::BiasStep, Step, bool) {
    let h = validate::compare_windows(before_windows, &cur.windows);
    let z = validate::max_z(&b.step, &b.sigma);
    let (decision, why) = decide(b.delta_log_likelihood - b.bic_penalty, z, false, &h);
    let mut b = b.clone();
    b.heldout = Some(h);
    b.reason = Some(why.clone());
    let kept = decision == Decision::Eligible;
    let step = Step {
        label: format!("{label}: {}", b.describe()),
        accepted: kept,
        reason: Some(why),
        errors: cur.errors,
        heldout: Some(h),
    };
    (b, step, kept)
}

/// Search rounds while an effect pays and fewer than [`DiagnoseOptions::max_effects`] are
/// added; with `until_added` the rounds stop after the one that adds an effect. True when
/// they stopped there (more rounds may pay). `decided` sees the search after each round; no
/// round starts once SIGINT/SIGTERM asked for a stop.
pub(crate) fn search_rounds(
    ctx: &Ctx<'_>,
    s: &mut Search,
    all: &[Block],
    until_added: bool,
    decided: &mut dyn FnMut(&Search),
) -> bool {
    let n0 = s.added.len();
    while s.added.len() < ctx.dopts.max_effects {
        if nav_engine::run::interrupt::requested().is_some() {
            return false;
        }
        let more = search_round(ctx, s, all);
        decided(s);
        if !more {
            return false;
        }
        if until_added && s.added.len() > n0 {
            return true;
        }
    }
    false
}

/// How many step candidates the searches after the added effects judge at most in all
/// ([`late_bias_step`]): a refused one ends its stretch and the change point is looked for
/// after it, and again with the next added effect, so a constant effect's misfit the step
/// search takes for a step does not hide a later true step; bounded so the cost stays that
/// of a few step searches.
pub(crate) const MAX_LATE_STEP_CANDIDATES: usize = 3;

/// A bias step looked for again after an effect is added ([`changepoint::find_bias_step`]
/// on the current model's search run), when the search before the effects found none: an
/// effect present from the start (a lever arm, a scale factor) inflates the base run's
/// innovations before a step, and the change-point search needs a consistent model before
/// the onset. Each step found is judged as the first search's ([`decide`]) against the
/// current model on the held-out windows; a refused one ends its stretch
/// ([`changepoint::stretch_end`]) and the search runs again on the fixes after it; the next
/// added effect (which may take away the misfit a refused step came from) starts the search
/// anew; at most [`MAX_LATE_STEP_CANDIDATES`] candidates in all. Returns the data with the
/// kept step removed (the search goes on, and the final model runs, there; the current
/// model's run is then that of these data); None when a step is kept already, the first
/// search's step was refused, no effect is added, or none is found or kept.
pub(crate) fn late_bias_step(ctx: &Ctx<'_>, s: &mut Search) -> Result<Option<Data>, DiagnoseError> {
    let first_refused = s.bias_step_not_kept.is_some() && s.late_steps_judged == 0;
    if s.bias_step.is_some() || first_refused || s.added.is_empty() {
        return Ok(None);
    }
    let model = options_with(&s.base_opts, &s.added);
    let opts = ctx.searching(&model);
    // an adopted noise model widens the innovations' variances and can hide a step's
    // inflation from the CUSUM: the configuration's noise with the added effects
    let mut conf: Option<(RunOptions, Arc<RunOutput>)> = None;
    let cur_run = s.cur.run.clone();
    let mut after = f64::NEG_INFINITY;
    while s.late_steps_judged < MAX_LATE_STEP_CANDIDATES {
        let mut found = changepoint::find_bias_step_after(&ctx.p.case, &opts, &cur_run, after)
            .map(|b| (b, cur_run.clone()));
        if found.is_none() && s.noise_tuning.as_ref().is_some_and(|t| t.adopted) {
            if conf.is_none() {
                let o = ctx.searching(&options_with(&ctx.p.opts, &s.added));
                conf = spill::run_innovations(&ctx.p.case, &o)
                    .ok()
                    .map(|r| (o, Arc::new(r)));
            }
            found = conf.as_ref().and_then(|(o, r)| {
                changepoint::find_bias_step_after(&ctx.p.case, o, r, after).map(|b| (b, r.clone()))
            });
        }
        let Some((b, run)) = found else {
            return Ok(None);
        };
        let stepped = Data {
            case: b.corrected_case(&ctx.p.case),
            ..ctx.p.clone()
        };
        let cur = ctx.evaluate_case(&stepped.case, &model)?;
        let (b, step, kept) = judge_step(
            &b,
            &s.cur.windows,
            &cur,
            "bias step removed (with the added effects)",
        );
        let why = step.reason.clone().unwrap_or_default();
        s.late_steps_judged += 1;
        s.steps.push(step);
        if kept {
            s.cur = cur;
            s.bias_step = Some(b);
            s.bias_step_not_kept = None;
            return Ok(Some(stepped));
        }
        s.warnings.push(format!(
            "{} at {:.1} s found as a change point with the added effects but not kept: {why}",
            b.name, b.t_s
        ));
        after = changepoint::stretch_end(&run.innovations, &b);
        s.bias_step_not_kept = Some(b);
    }
    Ok(None)
}

/// The strongest candidate of the search's last round (none added) that pays its BIC penalty
/// with an estimate at least 2 sigma from zero, its held-out windows not significantly
/// higher: the one [`refit_step_with_effect`] judges with the kept step refitted.
fn paying_candidate(s: &Search) -> Option<Block> {
    let round = s.rounds.last().filter(|r| r.added.is_none())?;
    let c = round
        .candidates
        .iter()
        .find(|c| c.decision == Decision::NotSignificant && c.evidence.is_some_and(|e| e > 0.0))?;
    let b = Block::effect_from_name(&c.name)?;
    let significant = is_noise_like(b) || c.max_z >= validate::MIN_Z;
    let not_worse = c
        .heldout
        .is_some_and(|h| h.verdict != HeldoutVerdict::Worse);
    (significant && not_worse).then_some(b)
}

/// A kept bias step and the strongest paying candidate of the last round ([`paying_candidate`])
/// judged together, once, when no effect is eligible on the data with the step removed: the
/// step was fitted under a model without the candidate, so its magnitude absorbs part of an
/// effect present throughout (on the accelerometer scale factor + gyro step drive, seed 201, a
/// pitch-axis step of -0.90 deg/h at 5 sigma beside the true vertical one), and the effect
/// then no longer shows on the windows. The step is refitted at its time with the candidate
/// in the model ([`changepoint::refit_magnitude`]), and the candidate on the data with the
/// refitted step removed is judged against the current model as any candidate ([`decide`]:
/// evidence over the BIC penalty of its parameters, estimate 2 sigma, held-out windows
/// significantly lower). Returns the data with the refitted step removed when the candidate
/// is added (the search goes on, and the final model runs, there).
pub(crate) fn refit_step_with_effect(
    ctx: &Ctx<'_>,
    s: &mut Search,
) -> Result<Option<Data>, DiagnoseError> {
    if s.step_refitted {
        return Ok(None);
    }
    let (Some(kept), Some(b)) = (s.bias_step.clone(), paying_candidate(s)) else {
        return Ok(None);
    };
    s.step_refitted = true;
    let model = options_with(&s.base_opts, &prior::with_candidate(&s.added, b));
    let opts = ctx.searching(&model);
    // the candidate's run in the last round (the memo's)
    let at = ctx.evaluate(&model)?;
    let Some((step, sigma, _)) = changepoint::refit_magnitude(&ctx.p.case, &opts, &at.run, &kept)
    else {
        return Ok(None);
    };
    let refit = changepoint::BiasStep {
        step,
        sigma,
        magnitude: step.iter().map(|x| x * x).sum::<f64>().sqrt(),
        ..kept.clone()
    };
    let stepped = Data {
        case: refit.corrected_case(&ctx.p.case),
        ..ctx.p.clone()
    };
    let ev = ctx.evaluate_case(&stepped.case, &model)?;
    let n_meas = residual_stats(&s.cur.run.innovations)
        .scalar_measurements
        .max(2) as f64;
    let penalty = 0.5 * prior::added_params(&s.added, b) as f64 * n_meas.ln();
    let v = round::judge_joint(s, b, &ev, penalty);
    let label = format!(
        "{} with {} refitted: {}",
        b.name(),
        kept.name,
        refit.describe()
    );
    let why = v.why.clone();
    let h = v.heldout;
    if v.decision != Decision::Eligible {
        s.warnings.push(format!("{label}: not added: {why}"));
        return Ok(None);
    }
    s.steps.push(Step {
        label: format!("+ {label}"),
        accepted: true,
        reason: Some(why.clone()),
        errors: ev.errors,
        heldout: Some(h),
    });
    if let Some(r) = s.rounds.last_mut() {
        r.added = Some(b.name().to_string());
        r.unexplained = None;
        if let Some(c) = r.candidates.iter_mut().find(|c| c.name == b.name()) {
            c.decision = Decision::Added;
            c.reason = format!("added with {} refitted beside it: {why}", kept.name);
            c.refused = None;
        }
    }
    let freed = prior::is_frozen(&options_with(&s.base_opts, &s.added), b);
    round::add_joint(s, b, v, &ev, freed);
    s.bias_step = Some(changepoint::BiasStep {
        reason: Some(format!("refitted with {}: {why}", b.name())),
        heldout: Some(h),
        ..refit
    });
    s.cur = ev;
    Ok(Some(stepped))
}

/// The search's start on `ctx`'s data (the bias step removed when kept): the base model's
/// run there, the noise fitted on it, the first steps (the configuration on the recorded
/// data, the bias step's removal, kept or not).
pub(crate) fn start_search(
    ctx: &Ctx<'_>,
    base: &Eval,
    judged: StepJudged,
) -> Result<Search, DiagnoseError> {
    let p = ctx.p;
    let mut steps = vec![Step {
        label: "configuration".into(),
        accepted: true,
        reason: None,
        errors: base.errors,
        heldout: None,
    }];
    let mut warnings = Vec::new();
    let (cur, bias_step, bias_step_not_kept) = match judged {
        StepJudged::Kept(b, cur, st) => {
            steps.push(st);
            (*cur, Some(b), None)
        }
        StepJudged::NotKept(b, st) => {
            warnings.push(format!(
                "{} at {:.1} s found as a change point but not kept: {}",
                b.name,
                b.t_s,
                st.reason.as_deref().unwrap_or("")
            ));
            steps.push(st);
            (base.clone(), None, Some(b))
        }
        StepJudged::None => (base.clone(), None, None),
    };
    if ctx.plan.windows.is_empty() {
        warnings.push(
            "no held-out windows (too few fixes): no effect can be added (an effect needs a \
             significant held-out gain)"
                .to_string(),
        );
    }
    let rs = residual_stats(&cur.run.innovations);
    let noise_tuning = ctx
        .dopts
        .tune_noise
        .then(|| noise::tune(&p.case, &ctx.searching(&p.opts), &rs));
    let pending_noise = noise_tuning
        .as_ref()
        .map(|t| t.chosen)
        .filter(|k| !k.is_one());
    Ok(Search {
        base_opts: p.opts.clone(),
        steps,
        cur,
        noise_tuning,
        pending_noise,
        last_noise_refusal: None,
        added: Vec::new(),
        added_info: Vec::new(),
        rounds: Vec::new(),
        warnings,
        bias_step,
        bias_step_not_kept,
        time_offset_held: None,
        late_steps_judged: 0,
        step_refitted: false,
        gnss_error_fit: None,
    })
}
