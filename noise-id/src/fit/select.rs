//! Term selection: every subset of the terms fitted, the eligible one with the lowest BIC
//! chosen ([`fit_select`]).
use super::*;

/// One candidate model of [`fit_select`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Candidate {
    /// Its terms.
    pub terms: Terms,
    /// Weighted sum of squared residuals (with the common model-error floor).
    pub chi2: f64,
    /// Number of parameters (linear coefficients, plus T_B).
    pub n_params: usize,
    /// Bayesian information criterion `chi2 + n_params ln(n_points)`.
    pub bic: f64,
    /// Why the candidate was not eligible (`None`: eligible).
    pub rejected: Option<String>,
}

/// Result of [`fit_select`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Selection {
    /// The fit of the selected model.
    pub fit: FitResult,
    /// Every candidate that was fitted.
    pub candidates: Vec<Candidate>,
}

impl Terms {
    /// Number of terms (the Gauss-Markov term counts once).
    pub fn count(&self) -> usize {
        [self.quant, self.white, self.gm, self.rw, self.flicker]
            .iter()
            .filter(|&&b| b)
            .count()
    }
    /// Short name like `white+gm+rw`.
    pub fn label(&self) -> String {
        let mut v = Vec::new();
        for (on, n) in [
            (self.quant, "quant"),
            (self.white, "white"),
            (self.gm, "gm"),
            (self.rw, "rw"),
            (self.flicker, "flicker"),
        ] {
            if on {
                v.push(n);
            }
        }
        v.join("+")
    }
    /// Every non-empty subset of these terms (with the white term whenever this set has it).
    pub fn subsets(&self) -> Vec<Terms> {
        let on = [self.quant, self.white, self.gm, self.rw, self.flicker];
        (1u32..32)
            .map(|mask| {
                let b = |k: usize| mask & (1 << k) != 0 && on[k];
                Terms {
                    quant: b(0),
                    white: b(1),
                    gm: b(2),
                    rw: b(3),
                    flicker: b(4),
                }
            })
            .filter(|t| t.count() > 0 && (t.white || !self.white))
            .fold(Vec::new(), |mut v, t| {
                if !v.contains(&t) {
                    v.push(t);
                }
                v
            })
    }
}

/// Relative model error `eps` that makes the weighted residuals of `f` consistent with their
/// variances: `sum r_i^2 / (m_i^2 (2 / EDF_i + eps^2)) = n - p` (0 if the statistical scatter
/// alone already explains them).
pub(super) fn model_error_for(f: &FitResult, edf: &[f64]) -> f64 {
    let dof = f.n_points as f64 - f.n_free as f64;
    if dof < 1.0 {
        return 0.0;
    }
    let chi2 = |eps: f64| {
        f.residuals
            .iter()
            .zip(edf)
            .map(|(r, e)| (r.1 - r.2).powi(2) / (r.2 * r.2 * (2.0 / e + eps * eps)))
            .sum::<f64>()
    };
    if chi2(0.0) <= dof {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while chi2(hi) > dof && hi < 1e6 {
        hi *= 4.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if chi2(mid) > dof {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// A value at least twice its uncertainty (false for NaN).
fn significant(e: Est) -> bool {
    e.value.partial_cmp(&(2.0 * e.sigma)) != Some(std::cmp::Ordering::Less) && e.sigma.is_finite()
}

/// Term selection: fits every subset of `opt.terms` (keeping the white-noise term if it is
/// in the set) and returns the eligible one with the smallest Bayesian information criterion
/// among those that follow the curve within the 95 % band of [`check_model`].
///
/// Real curves deviate from any few-term power-law model by more than the tiny statistical
/// scatter of the short-tau estimates (EDF ~ 1e5), which would make every extra term look
/// significant. So a common relative model error `eps` is first estimated from the fullest
/// model (the floor that makes its reduced chi-square 1, iterated with the refit) and used
/// in the weights of every candidate (the fit with no eligible candidate is the fullest); with `eps = 0` (simulated data that follow the model)
/// this is the ordinary weighted least squares. A candidate is not eligible when NNLS put
/// one of its terms at zero (it is then a smaller candidate), when its T_B ends at the edge
/// of the search range (then the Gauss-Markov term is only a second white-noise or
/// random-walk term), or when a parameter is less than twice its uncertainty. Of the
/// eligible candidates in BIC order, the first that also follows the curve ([`MIN_RUN`] or
/// more consecutive taus beyond the band on one side is a miss) is selected: a simpler
/// model that misses the curve gives biased coefficients (white noise alone on a curve with
/// a Gauss-Markov bump puts the bump's power into the white-noise level). When no
/// significant candidate follows the curve, the first that follows it is taken (its
/// candidate line says a parameter is below twice its uncertainty); when none does, the
/// first significant one, and [`check_model`] says where it misses.
pub fn fit_select(points: &[DevPoint], opt: &FitOptions) -> Result<Selection, FitError> {
    let edf_of = |f: &FitResult| -> Vec<f64> {
        f.residuals
            .iter()
            .map(|r| {
                points
                    .iter()
                    .find(|p| p.tau_s == r.0)
                    .map_or(f64::INFINITY, fit_edf)
            })
            .collect()
    };
    // Estimates do not depend on the sandwich (it only changes the covariance), so the
    // screening uses the cheaper diagonal-EDF covariance; the significance test below uses
    // the requested one.
    let mut o = opt.clone();
    o.model_error_rel = 0.0;
    if o.weighting == Weighting::EdfSandwich {
        o.weighting = Weighting::Edf;
    }
    let mut full = fit(points, &o)?;
    for _ in 0..4 {
        let eps = model_error_for(&full, &edf_of(&full));
        if (eps - o.model_error_rel).abs() <= 1e-3 * eps.max(1e-12) {
            break;
        }
        o.model_error_rel = eps;
        full = fit(points, &o)?;
    }
    let mut candidates = Vec::new();
    for terms in opt.terms.subsets() {
        let f = fit(points, &FitOptions { terms, ..o.clone() })?;
        let n_params = terms.count() + usize::from(terms.gm);
        let bic = f.chi2 + n_params as f64 * (f.n_points as f64).ln();
        let rejected = if nonzero(&f).iter().any(|(on, e)| *on && e.value <= 0.0) {
            Some("a term is at zero".to_string())
        } else if terms.gm
            && ((f.t_b_s.value / f.t_b_range_s.0).ln() < 0.05
                || (f.t_b_range_s.1 / f.t_b_s.value).ln() < 0.05)
        {
            Some(format!(
                "T_B = {:.3} s at the edge of the search range {:.3} - {:.1} s",
                f.t_b_s.value, f.t_b_range_s.0, f.t_b_range_s.1
            ))
        } else {
            None
        };
        candidates.push(Candidate {
            terms,
            chi2: f.chi2,
            n_params,
            bic,
            rejected,
        });
    }
    // In BIC order, the first eligible candidate whose parameters are all significant with
    // the requested covariance and that follows the curve within the check's band; failing
    // that, the first that follows the curve; failing that, the first significant one.
    let mut order: Vec<usize> = (0..candidates.len())
        .filter(|&k| candidates[k].rejected.is_none())
        .collect();
    order.sort_by(|&a, &b| candidates[a].bic.total_cmp(&candidates[b].bic));
    let fin = FitOptions {
        weighting: opt.weighting,
        ..o.clone()
    };
    let (band_eps, _) = super::check::band_floor(points, opt)?;
    let mut significant_first: Option<(usize, FitResult)> = None;
    let mut following_first: Option<(usize, FitResult)> = None;
    let mut chosen = None;
    for k in order {
        let f = fit(
            points,
            &FitOptions {
                terms: candidates[k].terms,
                ..fin.clone()
            },
        )?;
        let sig = nonzero(&f).iter().all(|(on, e)| !*on || significant(*e))
            && (!f.terms.gm || significant(f.t_b_s));
        let follows = super::check::follows_curve(points, &f, band_eps);
        if sig && follows {
            chosen = Some(f);
            break;
        }
        if sig {
            candidates[k].rejected = Some("misses the curve beyond its 95 % band".into());
            significant_first.get_or_insert((k, f));
        } else {
            candidates[k].rejected = Some("a parameter is below twice its uncertainty".into());
            if follows {
                following_first.get_or_insert((k, f));
            }
        }
    }
    let fit = match chosen.or_else(|| {
        let (k, f) = following_first.or(significant_first)?;
        candidates[k].rejected = None;
        Some(f)
    }) {
        Some(f) => f,
        None => fit(points, &fin)?,
    };
    Ok(Selection { fit, candidates })
}

/// (term on, estimate) of the linear coefficients of a fit.
fn nonzero(f: &FitResult) -> [(bool, Est); 5] {
    [
        (f.terms.quant, f.q2),
        (f.terms.white, f.s_n),
        (f.terms.gm, f.s_b),
        (f.terms.rw, f.s_k),
        (f.terms.flicker, f.flicker_b2),
    ]
}
