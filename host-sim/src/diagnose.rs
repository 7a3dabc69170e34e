//! `host-sim diagnose`: the command line of the diagnosis ([`nav_diagnose`]): its arguments
//! mapped to [`DiagnoseOptions`], the output folder, the console summary and the plots
//! ([`plots`]).
pub mod plots;

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::run::cli::RunArgs;
use nav_diagnose::{diagnose_cached, imu_cache, DiagnoseOptions, DiagnoseOutput, Outcome};
use nav_engine::run::outdir::OutDir;
use nav_engine::Prepared;

/// Arguments of `host-sim diagnose`: the same as `run`, plus the search limits.
#[derive(clap::Args, Debug)]
pub struct DiagnoseArgs {
    /// Inputs as for `run`; `--out` receives diagnosis.json, nav_before.txt, nav_after.txt,
    /// report.md with its PNG plots, and the augmented configuration. `--smooth` scores the
    /// held-out check on the Rauch-Tung-Striebel smoothed solution of every candidate run (the
    /// outage fixes stay withheld from the filter and so from the smoother) instead of the
    /// forward one; the evidence stays the forward innovations' ([`DiagnoseOptions::smooth`]).
    #[command(flatten)]
    pub run: RunArgs,
    /// Largest number of effects to add.
    #[arg(long, default_value_t = 4)]
    pub max_effects: usize,
    /// Keep the configuration's IMU noise (by default the white-noise and bias PSDs are
    /// fitted per sensor by maximum innovation likelihood before and after the effect search).
    #[arg(long)]
    pub no_tune_noise: bool,
    /// Accepted for compatibility: noise tuning is the default.
    #[arg(long, hide = true)]
    pub tune_noise: bool,
    /// Evidence margin, nats, below which two eligible candidates are reported as ambiguous.
    #[arg(long, default_value_t = 3.0)]
    pub ambiguity_margin: f64,
}

/// Writes everything `host-sim diagnose` writes into `dir`: the diagnosis's files
/// ([`nav_diagnose::write_files`]: `diagnosis.json`, `nav_before.txt`, `nav_after.txt`,
/// `report.md`, `augmented.toml` given the configuration `config`) and the plots `report.md`
/// links ([`plots::write_plots`]).
pub fn write_outputs(
    dir: &Path,
    p: &Prepared,
    d: &DiagnoseOutput,
    config: Option<&Path>,
) -> anyhow::Result<()> {
    nav_diagnose::write_files(dir, p, d, config)?;
    plots::write_plots(dir, p, d)
}

/// `[a, b, c]` with 4 significant digits (the console summary; `diagnosis.json` keeps full
/// precision).
fn short_list(v: &[f64]) -> String {
    let items: Vec<String> = v
        .iter()
        .map(|x| {
            let a = x.abs();
            if a == 0.0 || (1e-3..1e4).contains(&a) {
                format!(
                    "{:.*}",
                    (3 - a.log10().floor().max(-3.0) as i32).max(0) as usize,
                    x
                )
            } else {
                format!("{x:.3e}")
            }
        })
        .collect();
    format!("[{}]", items.join(", "))
}

/// What `host-sim diagnose` keeps when SIGINT/SIGTERM stop it (the message on stderr).
pub const KEPT_ON_STOP: &str =
    "the diagnosis ends its runs and keeps the search rounds decided so far as \
     report.md.partial, diagnosis.json.partial and nav_before.txt.partial in the output folder \
     (nothing before the first round is decided)";

/// What `host-sim diagnose` keeps when SIGINT/SIGTERM end it at once (while it loads its
/// inputs or writes its outputs).
pub const KEPT_ON_EXIT: &str = "the diagnosis keeps no partial output, the output folder as it was";

/// `round N decided: ...` on stderr (the progress of the search).
fn say_round(n: usize, r: &nav_diagnose::Round) {
    match &r.added {
        Some(a) => eprintln!("round {n} decided: {a} added"),
        None => eprintln!("round {n} decided: nothing added"),
    }
}

/// Runs `host-sim diagnose`.
///
/// The outputs are written in the stage folder of `--out` ([`OutDir`]: refused when it holds
/// one of the inputs or another run is writing into it) and moved into place at the end.
/// SIGINT/SIGTERM (once [`nav_engine::run::interrupt::install`] is in place) end the
/// diagnosis's runs at their next IMU read; the search rounds decided before the signal are
/// written as `report.md.partial`, `diagnosis.json.partial` and `nav_before.txt.partial`
/// ([`nav_diagnose::write_partial_files`]; nothing before the first round is decided), the
/// previous complete outputs untouched, and the command ends with an error naming what it
/// kept (exit `128 + signal`).
pub fn run(args: DiagnoseArgs) -> anyhow::Result<()> {
    let l = crate::run::cli::load(&args.run, true)?;
    let od = OutDir::open(&args.run.out, &l.inputs)?;
    let truth_file = l.truth_stream.clone();
    // a signal from here ends the runs (the IMU reads notice it) instead of the process,
    // so that the rounds decided are kept and the temporary folder goes
    let stoppable = nav_engine::run::interrupt::Stoppable::enter();
    let (mut p, imu) = imu_cache::load_cached(l)?;
    println!("{}", p.description);
    let dopts = DiagnoseOptions {
        max_effects: args.max_effects,
        candidates: None,
        tune_noise: !args.no_tune_noise,
        ambiguity_margin: args.ambiguity_margin,
        smooth: args.run.smooth,
    };
    // a streamed truth goes to the diagnosis and is read again for the report once the
    // diagnosis's data are gone (one copy in memory at a time)
    let case = match &truth_file {
        Some(_) => std::mem::take(&mut p.case),
        None => p.case.clone(),
    };
    let quiet = args.run.quiet;
    let outcome = diagnose_cached(case, &p.opts, imu, &dopts, &mut |n, r| {
        if !quiet {
            say_round(n, r);
        }
    })?;
    let dir: &PathBuf = &args.run.out;
    let d = match outcome {
        Outcome::Complete(d) => d,
        Outcome::Interrupted(i) => return keep_partial(od, &p, *i, dir),
    };
    drop(stoppable);
    if let Some(t) = &truth_file {
        p.case.truth = Some(t.open()?.collect::<Result<_, _>>()?);
    }
    write_outputs(od.stage(), &p, &d, Some(&args.run.config))?;
    let moving = nav_engine::run::interrupt::Stoppable::enter();
    od.commit()
        .with_context(|| format!("moving the outputs into {}", dir.display()))?;
    drop(moving);
    if let Some(sig) = nav_engine::run::interrupt::requested() {
        // the signal came once the diagnosis was complete: its outputs are in place
        anyhow::bail!(
            "{}: received as the diagnosis ended; its complete outputs are in {}",
            nav_engine::run::interrupt::signal_name(sig),
            dir.display()
        );
    }
    summary(&d);
    println!("wrote {}", dir.display());
    Ok(())
}

/// A diagnosis stopped by a signal: the rounds it decided written as `*.partial` and moved
/// into `dir` (nothing when none was decided: the stage folder removed), and the error
/// naming what was kept.
fn keep_partial(
    od: OutDir,
    p: &Prepared,
    i: nav_diagnose::Interrupted,
    dir: &Path,
) -> anyhow::Result<()> {
    let Some(kept) = &i.kept else {
        drop(od);
        anyhow::bail!(
            "{}: stopped before the search decided its first round; nothing kept, the output \
             folder as it was",
            i.signal
        );
    };
    let written = nav_diagnose::write_partial_files(od.stage(), &p.description, p.week, kept)
        .map_err(anyhow::Error::from)
        .and_then(|w| Ok((w, od.commit()?)));
    match written {
        Ok((w, _)) => {
            let names: Vec<String> = w
                .iter()
                .filter_map(|f| f.file_name())
                .map(|n| n.to_string_lossy().into_owned())
                .collect();
            anyhow::bail!(
                "{}: stopped after round {} of the search; the decided rounds are kept in {} as \
                 {} (incomplete: the search did not finish, no nav_after.txt or augmented.toml; \
                 the previous complete outputs untouched)",
                i.signal,
                kept.0.after_round,
                dir.display(),
                names.join(", ")
            )
        }
        Err(e) => anyhow::bail!(
            "{}: stopped after round {} of the search; writing its partial diagnosis failed: \
             {e:#}",
            i.signal,
            kept.0.after_round
        ),
    }
}

/// The console summary of a complete diagnosis.
fn summary(d: &DiagnoseOutput) {
    let dg = &d.diagnosis;
    println!("held-out windows: {}", dg.heldout_windows.how);
    println!("effects the model lacks: {}", dg.verdict);
    for w in &dg.warnings {
        println!("warning: {w}");
    }
    for e in &dg.added_effects {
        println!(
            "added {}: estimate {} sigma {} [{}] likelihood gain {:.1} nats, evidence {:.1} nats, {}",
            e.name,
            short_list(&e.estimate),
            short_list(&e.sigma),
            e.unit,
            e.delta_log_likelihood,
            e.evidence,
            e.heldout.describe()
        );
    }
    for u in &dg.undetected {
        println!(
            "not added {}: detectability bound {:.3e} [{}] ({})",
            u.name, u.min_bound, u.unit, u.reason
        );
    }
    for st in &dg.steps {
        let e = &st.errors;
        println!(
            "model after step `{}`{}: held-out windows RMS {} m; its search run (held-out fixes withheld): GNSS prior residual {:.3} m, solution vs the used fixes {:.3} m, NIS {:.2}{}",
            st.label,
            if st.accepted { "" } else { " (refused)" },
            e.heldout_windows_rms_m.map_or("-".into(), |x| format!("{x:.3}")),
            e.gnss_prior_horizontal_rms_m,
            e.written_vs_fixes_m,
            e.nis_mean,
            st.reason
                .as_ref()
                .map_or(String::new(), |r| format!(": {r}"))
        );
    }
    let rms = |v: &[f64]| {
        let f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        (f.iter().map(|x| x * x).sum::<f64>() / f.len().max(1) as f64).sqrt()
    };
    let outage = if dg.error_before.outage_max_3d_rms_m.is_finite() {
        format!(
            "outage position error ({}): before {:.3} m, after {:.3} m",
            dg.error_before.reference,
            dg.error_before.outage_max_3d_rms_m,
            dg.error_after.outage_max_3d_rms_m
        )
    } else {
        // no imposed outage: the held-out windows are the record's own
        format!(
            "held-out windows ({}, RMS): before {:.3} m, after {:.3} m",
            dg.window_errors_before_m.len(),
            rms(&dg.window_errors_before_m),
            rms(&dg.window_errors_after_m)
        )
    };
    println!(
        "{outage}; runs with every fix: GNSS prior residual (horizontal): before {:.3} m, after {:.3} m; written solution vs the used fixes (horizontal, at the final model's antenna; posterior: favours no time offset; nav_after.txt follows the filter's running estimate of an added lever arm, its convergence counts here, a run of augmented.toml starts at the estimate): before {:.3} m, after {:.3} m{}",
        dg.error_before.gnss_residual_horizontal_rms_m,
        dg.error_after.gnss_residual_horizontal_rms_m,
        dg.error_before.output_vs_fixes_horizontal_rms_m,
        dg.error_after.output_vs_fixes_horizontal_rms_m,
        if dg.output_clock_shift_s != 0.0 {
            format!(" (nav_after.txt on the GNSS clock: IMU time {:+.4} s)", dg.output_clock_shift_s)
        } else {
            String::new()
        }
    );
}
