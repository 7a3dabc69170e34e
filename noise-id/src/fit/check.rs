//! Does the selected model follow the curve? ([`check_model`]): the fit's residuals against
//! the 95 % confidence band of each Allan variance estimate, widened by the model-error floor
//! that the fullest model needs; a run of misses on one side is a model that is wrong there,
//! and the candidate that fits best within the band is named.
use super::*;

/// Two-sided 95 % normal quantile: the band is `|r| <= Z95` for the normalized residual `r`.
pub const Z95: f64 = 1.959_963_984_540_054;
/// Consecutive fitted taus outside the band, on one side, that make a miss.
pub const MIN_RUN: usize = 3;

/// A stretch of taus where the model is outside the band on one side.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Miss {
    /// First tau of the stretch (s).
    pub tau_from_s: f64,
    /// Last tau of the stretch (s).
    pub tau_to_s: f64,
    /// Number of fitted taus in it.
    pub n_points: usize,
    /// Largest relative error of the model's Allan deviation in it, `model / measured - 1`
    /// (negative: the model is below the curve).
    pub worst_rel_adev: f64,
}

/// A model that follows the curve better than the selected one.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Alternative {
    /// Its terms (those the fit kept non-zero).
    pub terms: Terms,
    /// Its chi-square with the check's weights.
    pub chi2: f64,
    /// Its fitted taus outside the band.
    pub n_outside: usize,
    /// Its misses (empty when it follows the curve within the band).
    pub misses: Vec<Miss>,
}

/// Result of [`check_model`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ModelCheck {
    /// Model-error floor of the band (relative, on the Allan variance): the fullest model's.
    pub model_error_rel: f64,
    /// The selected model's chi-square with the check's weights.
    pub chi2: f64,
    /// Number of fitted taus.
    pub n_points: usize,
    /// The selected model's fitted taus outside the band.
    pub n_outside: usize,
    /// Where the selected model misses the curve (empty: it follows it).
    pub misses: Vec<Miss>,
    /// The best-fitting other model when the selected one misses (fewest misses, then fewest
    /// parameters, then the smallest BIC), if it does better.
    pub alternative: Option<Alternative>,
}

/// Normalized residuals of `f` with model-error floor `eps`:
/// `(meas - model) / (model sqrt(2 / EDF + eps^2))` per fitted tau.
fn normalized(f: &FitResult, points: &[DevPoint], eps: f64) -> Vec<(f64, f64, f64, f64)> {
    f.residuals
        .iter()
        .map(|&(tau, meas, model, _)| {
            let edf = points
                .iter()
                .find(|p| p.tau_s == tau)
                .map_or(f64::INFINITY, fit_edf);
            let r = (meas - model) / (model * (2.0 / edf + eps * eps).sqrt());
            (tau, meas, model, r)
        })
        .collect()
}

/// The runs of at least [`MIN_RUN`] consecutive residuals beyond [`Z95`] on one side, and the
/// number of residuals beyond it.
fn misses_of(res: &[(f64, f64, f64, f64)]) -> (Vec<Miss>, usize) {
    let n_outside = res.iter().filter(|r| r.3.abs() > Z95).count();
    let mut out = Vec::new();
    let mut i = 0;
    while i < res.len() {
        let s = res[i].3;
        if s.abs() <= Z95 || !s.is_finite() {
            i += 1;
            continue;
        }
        let mut j = i;
        while j + 1 < res.len() && res[j + 1].3.abs() > Z95 && res[j + 1].3.signum() == s.signum() {
            j += 1;
        }
        if j + 1 - i >= MIN_RUN {
            let worst = res[i..=j]
                .iter()
                .map(|r| (r.2 / r.1).sqrt() - 1.0)
                .max_by(|a, b| a.abs().total_cmp(&b.abs()))
                .unwrap_or(f64::NAN);
            out.push(Miss {
                tau_from_s: res[i].0,
                tau_to_s: res[j].0,
                n_points: j + 1 - i,
                worst_rel_adev: worst,
            });
        }
        i = j + 1;
    }
    (out, n_outside)
}

/// The terms a fit kept (non-zero).
fn kept_terms(f: &FitResult) -> Terms {
    Terms {
        quant: f.terms.quant && f.q2.value > 0.0,
        white: f.terms.white && f.s_n.value > 0.0,
        gm: f.terms.gm && f.s_b.value > 0.0,
        rw: f.terms.rw && f.s_k.value > 0.0,
        flicker: f.terms.flicker && f.flicker_b2.value > 0.0,
    }
}

/// The model-error floor of the check's band: the relative error the fullest five-term
/// model needs for a reduced chi-square of 1 (iterated with the refit), and the options
/// (diagonal EDF weights, all five terms, that floor) the check fits candidates with.
pub(super) fn band_floor(
    points: &[DevPoint],
    opt: &FitOptions,
) -> Result<(f64, FitOptions), FitError> {
    let all = Terms {
        quant: true,
        white: true,
        gm: true,
        rw: true,
        flicker: true,
    };
    let mut o = FitOptions {
        terms: all,
        model_error_rel: 0.0,
        weighting: Weighting::Edf,
        ..opt.clone()
    };
    let edf_of = |f: &FitResult| -> Vec<f64> {
        normalized(f, points, 0.0)
            .iter()
            .map(|r| {
                points
                    .iter()
                    .find(|p| p.tau_s == r.0)
                    .map_or(f64::INFINITY, fit_edf)
            })
            .collect()
    };
    let mut full = fit(points, &o)?;
    for _ in 0..4 {
        let eps = super::select::model_error_for(&full, &edf_of(&full));
        if (eps - o.model_error_rel).abs() <= 1e-3 * eps.max(1e-12) {
            break;
        }
        o.model_error_rel = eps;
        full = fit(points, &o)?;
    }
    Ok((o.model_error_rel, o))
}

/// Whether `f` follows the curve: no run of [`MIN_RUN`] or more consecutive fitted taus
/// beyond the 95 % band (floor `eps`, from [`band_floor`]) on one side.
pub(super) fn follows_curve(points: &[DevPoint], f: &FitResult, eps: f64) -> bool {
    misses_of(&normalized(f, points, eps)).0.is_empty()
}

/// Checks whether `selected` (fitted to `points` with `opt`) follows the curve: its
/// residuals against the 95 % band of each estimate (statistical, from the EDF, widened by
/// the model-error floor the fullest five-term model needs, as [`fit_select`] estimates it).
/// When it misses ([`MIN_RUN`] or more consecutive taus beyond the band on one side), every
/// subset of the five terms with white noise is fitted and the one with the fewest misses,
/// then the fewest parameters, then the smallest BIC (`chi2 + p ln n`), is named if it does
/// better (the simplest model that follows the curve). Candidates whose T_B
/// ends at the edge of its search range are skipped (the Gauss-Markov term is then only a
/// second white-noise or random-walk term).
pub fn check_model(
    points: &[DevPoint],
    selected: &FitResult,
    opt: &FitOptions,
) -> Result<ModelCheck, FitError> {
    let (eps, o) = band_floor(points, opt)?;
    let all = o.terms;
    let res = normalized(selected, points, eps);
    let chi2 = res.iter().map(|r| r.3 * r.3).sum::<f64>();
    let (misses, n_outside) = misses_of(&res);
    let mut check = ModelCheck {
        model_error_rel: eps,
        chi2,
        n_points: res.len(),
        n_outside,
        misses,
        alternative: None,
    };
    if check.misses.is_empty() {
        return Ok(check);
    }
    let mine = kept_terms(selected);
    let n = res.len() as f64;
    let mut best: Option<((usize, usize, f64), Alternative)> = None;
    for terms in all.subsets() {
        let Ok(f) = fit(points, &FitOptions { terms, ..o.clone() }) else {
            continue;
        };
        let kept = kept_terms(&f);
        if kept != terms || kept == mine {
            // a smaller candidate (a term at zero) or the selected model itself
            continue;
        }
        if terms.gm
            && ((f.t_b_s.value / f.t_b_range_s.0).ln() < 0.05
                || (f.t_b_range_s.1 / f.t_b_s.value).ln() < 0.05)
        {
            continue;
        }
        let r = normalized(&f, points, eps);
        let c2 = r.iter().map(|x| x.3 * x.3).sum::<f64>();
        let (m, out) = misses_of(&r);
        let p = terms.count() + usize::from(terms.gm);
        let bic = c2 + p as f64 * n.ln();
        // fewest misses, then the simplest, then the smallest BIC
        let key = (m.len(), p, bic);
        if best.as_ref().is_none_or(|(bk, _)| {
            (key.0, key.1) < (bk.0, bk.1) || ((key.0, key.1) == (bk.0, bk.1) && key.2 < bk.2)
        }) {
            best = Some((
                key,
                Alternative {
                    terms,
                    chi2: c2,
                    n_outside: out,
                    misses: m,
                },
            ));
        }
    }
    check.alternative = best
        .map(|b| b.1)
        .filter(|a| a.misses.len() < check.misses.len() || a.chi2 < check.chi2);
    Ok(check)
}

impl ModelCheck {
    /// The warning to print for channel `name` (None when the model follows the curve).
    pub fn warning(&self, name: &str, model: &Terms) -> Option<String> {
        if self.misses.is_empty() {
            return None;
        }
        let where_: Vec<String> = self
            .misses
            .iter()
            .map(|m| {
                format!(
                    "tau {:.3}-{:.3} s ({} taus, model up to {:.0} % {} the curve)",
                    m.tau_from_s,
                    m.tau_to_s,
                    m.n_points,
                    100.0 * m.worst_rel_adev.abs(),
                    if m.worst_rel_adev < 0.0 {
                        "below"
                    } else {
                        "above"
                    }
                )
            })
            .collect();
        let mut s = format!(
            "{name}: the selected model {} misses the Allan deviation beyond its 95 % confidence \
             band (statistical, plus the {:.1} % model-error floor of the fullest model) at {}; \
             {} of {} taus outside, chi2 {:.1}",
            model.label(),
            100.0 * self.model_error_rel,
            where_.join(", "),
            self.n_outside,
            self.n_points,
            self.chi2
        );
        match &self.alternative {
            Some(a) => {
                let _ = std::fmt::Write::write_fmt(
                    &mut s,
                    format_args!(
                        ". Better: {} ({} of {} taus outside, chi2 {:.1}{}): --terms {} --no-select",
                        a.terms.label(),
                        a.n_outside,
                        self.n_points,
                        a.chi2,
                        if a.misses.is_empty() {
                            ", follows the curve"
                        } else {
                            ""
                        },
                        a.terms.label().replace('+', ",")
                    ),
                );
            }
            None => s.push_str(". No other combination of the five terms does better"),
        }
        Some(s)
    }
}
