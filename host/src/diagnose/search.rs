//! The greedy search: try every revealable effect, accept the one that explains most if the
//! evidence is strong, repeat.
use super::effects::Effect;
use super::extended::{columns, fit_extended, ExtendedFit, ExtendedFitError};
use super::form::{self, Structure};
use super::locate::torque;
use super::observed::Observed;
use super::{DiagnoseError, Diagnosis, Evidence, Finding, Rejection};
use super::{MAX_HALF_SPREAD, MIN_BIC_DROP, MIN_EXPLAINED, MIN_HALF_Z};
use crate::fit::total_noise_weights;
use model_core::{Model, Params};
use rayon::prelude::*;

/// Runs the greedy search for missing physics from the `baseline` parameters.
pub fn diagnose(observed: &Observed, baseline_params: Params<f64>) -> Result<Diagnosis, DiagnoseError> {
    let n = observed.data.theta.len();
    let all: Vec<usize> = (0..n).collect();
    let baseline_model = Model::new(baseline_params).map_err(DiagnoseError::Baseline)?;
    let weights = match &observed.noise {
        Some(noise) => total_noise_weights(&observed.data, &baseline_model, noise).map_err(DiagnoseError::Baseline)?,
        None => vec![1.0; n],
    };
    let seed = ExtendedFit::start(baseline_params, baseline_model.r(), n);
    let baseline = fit_extended(observed, &all, &weights, &[], &seed).map_err(DiagnoseError::BaselineRefit)?;
    let mut current = baseline.clone();
    let mut findings = Vec::new();
    let mut rejected = Vec::new();
    let ln_n = (n as f64).ln();
    loop {
        let candidates: Vec<Effect> =
            observed.revealable().into_iter().filter(|e| !current.active.contains(e)).collect();
        let variance = current.chi2 / (n as f64 - current.degrees_of_freedom() as f64).max(1.0);
        // One candidate at a time: each fit holds its columns for every sample, so fitting them
        // side by side would multiply the memory by the threads (each solve runs in parallel).
        let mut trials: Vec<(Effect, ExtendedFit, Evidence)> = candidates
            .iter()
            .filter_map(|&effect| {
                let mut active = current.active.clone();
                active.push(effect);
                // An effect whose columns cannot be fitted is no candidate.
                let fit = fit_extended(observed, &all, &weights, &active, &current).ok()?;
                let drop = (current.chi2 - fit.chi2).max(0.0);
                let evidence = Evidence {
                    delta_bic: drop / variance - columns(effect) as f64 * ln_n,
                    explained: drop / current.chi2,
                    z: fit.magnitude(effect) / fit.magnitude_error(effect),
                    halves: None,
                    halves_z: None,
                };
                Some((effect, fit, evidence))
            })
            .collect();
        trials.sort_by(|a, b| b.2.explained.total_cmp(&a.2.explained));
        let mut accepted: Vec<(Effect, Evidence)> = Vec::new();
        let mut accepted_fit = None;
        // Strong alone but inconsistent: perhaps only because another effect is missing too.
        let mut strong: Vec<(Effect, ExtendedFit)> = Vec::new();
        rejected.clear();
        for (effect, fit, mut evidence) in trials {
            let magnitude = fit.magnitude(effect);
            let reason = if evidence.delta_bic < MIN_BIC_DROP {
                Some(format!("information criterion drops by {:.1}, less than {MIN_BIC_DROP}", evidence.delta_bic))
            } else if evidence.explained < MIN_EXPLAINED {
                Some(format!(
                    "explains {:.1} % of the residual, less than {:.0} %",
                    100.0 * evidence.explained,
                    100.0 * MIN_EXPLAINED
                ))
            } else if accepted_fit.is_some() {
                Some("weaker than the effect accepted in this round; tried again next round".into())
            } else {
                let reason = halves_check(observed, &weights, &current, &fit, effect, &mut evidence);
                if reason.is_some() {
                    strong.push((effect, fit.clone()));
                }
                reason
            };
            match reason {
                Some(reason) => rejected.push(Rejection { effect, reason, magnitude, evidence }),
                None => {
                    accepted.push((effect, evidence));
                    accepted_fit = Some(fit);
                }
            }
        }
        if accepted_fit.is_none() {
            if let Some((pair, fit)) = consistent_pair(observed, &all, &weights, &current, &strong, variance, ln_n) {
                rejected.retain(|r| !pair.iter().any(|(e, _)| *e == r.effect));
                accepted = pair;
                accepted_fit = Some(fit);
            }
        }
        let Some(fit) = accepted_fit else { break };
        let rss_before =
            unweighted_rss(observed, &current, &all).map_err(|source| refit_error(&current.active, source.into()))?;
        let rss_after =
            unweighted_rss(observed, &fit, &all).map_err(|source| refit_error(&fit.active, source.into()))?;
        for (effect, evidence) in accepted {
            findings.push(Finding {
                effect,
                magnitude: fit.magnitude(effect),
                unit: effect.unit(),
                meaning: effect.magnitude_meaning(),
                location: location_words(effect, &fit),
                rss_before,
                rss_after,
                evidence,
            });
        }
        current = fit;
    }
    let final_fit = fit_extended(observed, &all, &weights, &current.active, &current)
        .map_err(|source| refit_error(&current.active, source))?;
    for finding in &mut findings {
        finding.magnitude = final_fit.magnitude(finding.effect);
    }
    let held_out_rms = held_out(observed, &weights, &baseline, &final_fit)?;
    let final_residuals = final_fit.residuals(observed, &all).map_err(|e| refit_error(&final_fit.active, e.into()))?;
    match form::judge(observed, &weights, &final_fit, &final_residuals, held_out_rms.map(|h| h.1)) {
        structure @ (Structure::Noise | Structure::Unexplained(_)) => Ok(Diagnosis {
            baseline,
            findings,
            rejected,
            final_fit,
            weights,
            held_out_rms,
            model_form: None,
            unexplained: match structure {
                Structure::Unexplained(unexplained) => Some(unexplained),
                _ => None,
            },
        }),
        Structure::Form { form: model_form, kept } => {
            // The effects that stood in for the loop's shape are not named; the others stay.
            let (kept_findings, withdrawn): (Vec<Finding>, Vec<Finding>) =
                findings.into_iter().partition(|f| kept.contains(&f.effect));
            for finding in withdrawn {
                rejected.push(Rejection {
                    effect: finding.effect,
                    reason: format!(
                        "stands in for the loop's shape: the {} model explains the recording without it",
                        model_form.model
                    ),
                    magnitude: finding.magnitude,
                    evidence: finding.evidence,
                });
            }
            let final_fit = fit_extended(observed, &all, &weights, &kept, &baseline)
                .map_err(|source| refit_error(&kept, source))?;
            let held_out_rms = held_out(observed, &weights, &baseline, &final_fit)?;
            Ok(Diagnosis {
                final_fit,
                baseline,
                findings: kept_findings,
                rejected,
                weights,
                held_out_rms,
                model_form: Some(model_form),
                unexplained: None,
            })
        }
    }
}

/// Two effects, each strong alone but inconsistent alone, fitted together: accepted when the
/// pair lowers the information criterion, each explains its share on top of the other, and
/// each passes the consistency checks in the joint fit (a concealed effect can spoil the
/// halves or the rate check of another).
fn consistent_pair(
    observed: &Observed,
    all: &[usize],
    weights: &[f64],
    current: &ExtendedFit,
    strong: &[(Effect, ExtendedFit)],
    variance: f64,
    ln_n: f64,
) -> Option<(Vec<(Effect, Evidence)>, ExtendedFit)> {
    for (i, (a, fit_a)) in strong.iter().enumerate() {
        for (b, fit_b) in &strong[i + 1..] {
            let mut active = current.active.clone();
            active.extend([*a, *b]);
            let Ok(pair) = fit_extended(observed, all, weights, &active, current) else { continue };
            let mut evidence = Vec::new();
            for (effect, alone_with_other) in [(*a, fit_b), (*b, fit_a)] {
                let drop = (alone_with_other.chi2 - pair.chi2).max(0.0);
                let mut e = Evidence {
                    delta_bic: drop / variance - columns(effect) as f64 * ln_n,
                    explained: drop / alone_with_other.chi2,
                    z: pair.magnitude(effect) / pair.magnitude_error(effect),
                    halves: None,
                    halves_z: None,
                };
                let passes = e.delta_bic >= MIN_BIC_DROP
                    && e.explained >= MIN_EXPLAINED
                    && halves_check(observed, weights, current, &pair, effect, &mut e).is_none();
                if !passes {
                    break;
                }
                evidence.push((effect, e));
            }
            if evidence.len() == 2 {
                return Some((evidence, pair));
            }
        }
    }
    None
}

fn refit_error(active: &[Effect], source: ExtendedFitError) -> DiagnoseError {
    let effects = active.iter().map(|e| format!(" + {}", e.name())).collect();
    DiagnoseError::Refit { effects, source }
}

/// Fits each half alone; `None` when both show the effect clearly and agree.
fn halves_check(
    observed: &Observed,
    weights: &[f64],
    current: &ExtendedFit,
    fit: &ExtendedFit,
    effect: Effect,
    evidence: &mut Evidence,
) -> Option<String> {
    let halves: Vec<Result<ExtendedFit, ExtendedFitError>> =
        observed.parts.par_iter().map(|part| fit_extended(observed, part, weights, &fit.active, current)).collect();
    let (Ok(a), Ok(b)) = (&halves[0], &halves[1]) else {
        return Some("could not be fitted on each half alone".into());
    };
    let (ma, mb) = (a.magnitude(effect), b.magnitude(effect));
    let (za, zb) = (ma / a.magnitude_error(effect), mb / b.magnitude_error(effect));
    evidence.halves = Some([ma, mb]);
    evidence.halves_z = Some([za, zb]);
    let full = fit.magnitude(effect);
    let spread = if effect == Effect::KinematicError {
        let ((xa, ya), (xb, yb)) = (a.kinematic_vector(), b.kinematic_vector());
        (xa - xb).hypot(ya - yb)
    } else {
        (ma - mb).abs()
    };
    if effect == Effect::Backlash && full <= 0.0 {
        Some("the dead band width fits to zero".into())
    } else if za.abs() < MIN_HALF_Z || zb.abs() < MIN_HALF_Z {
        Some(format!("not clear in both halves alone (z = {za:.1} and {zb:.1})"))
    } else if ma.signum() != mb.signum() || spread > MAX_HALF_SPREAD * (ma + mb).abs() / 2.0 {
        Some(format!("the halves disagree: {ma:.4e} and {mb:.4e} {}", effect.unit()))
    } else if effect.is_rate_dependent() {
        rate_check(observed, weights, fit, effect)
    } else {
        None
    }
}

/// A rate effect must have one magnitude at slow and at fast motion: with everything else of
/// the fit held (h in particular, which a single rate confounds with damping), the effect's
/// coefficient is re-estimated on the samples slower and faster than the median instantaneous
/// frequency, beside the other rate effect's column (damping beside friction and friction
/// beside damping), which takes what the other physics leaves. Rate-independent hysteresis
/// taken for damping gives a damping that falls as the rate rises, and damping taken for
/// friction a friction that grows with it. `None` when both parts agree.
fn rate_check(observed: &Observed, weights: &[f64], fit: &ExtendedFit, effect: Effect) -> Option<String> {
    // With one rate at each place on the loop there is nothing to compare: damping is then not
    // revealable at all, and friction's sign is a direction, tested by the halves alone.
    let (Some(parts), Some(rate)) = (&observed.rate_parts, &observed.rate) else {
        return None;
    };
    let sign = |i: usize| match observed.data.direction[i] {
        model_core::Direction::Rising => 1.0,
        model_core::Direction::Falling => -1.0,
    };
    // The effect's own column and the other rate effect's, per sample.
    let columns = |i: usize| match effect {
        Effect::CoulombFriction => [sign(i), rate[i]],
        _ => [rate[i], sign(i)],
    };
    let magnitude = fit.magnitude(effect);
    let mut estimates = Vec::new();
    for part in parts {
        let residuals = fit.residuals(observed, part).ok()?;
        let (mut g, mut h) = ([[0.0; 2]; 2], [0.0; 2]);
        for (&i, r) in part.iter().zip(&residuals) {
            let x = columns(i);
            let without = r + magnitude * x[0];
            for a in 0..2 {
                h[a] += weights[i] * x[a] * without;
                for b in 0..2 {
                    g[a][b] += weights[i] * x[a] * x[b];
                }
            }
        }
        let det = g[0][0] * g[1][1] - g[0][1] * g[1][0];
        if !(det > 0.0) {
            return Some("no motion in part of the recording".into());
        }
        let estimate = (g[1][1] * h[0] - g[0][1] * h[1]) / det;
        let other = (g[0][0] * h[1] - g[1][0] * h[0]) / det;
        let chi2: f64 = part
            .iter()
            .zip(&residuals)
            .map(|(&i, r)| {
                let x = columns(i);
                let e = r + (magnitude - estimate) * x[0] - other * x[1];
                weights[i] * e * e
            })
            .sum();
        let variance = chi2 / (part.len() as f64 - 2.0).max(1.0);
        let error = (variance * g[1][1] / det).sqrt();
        estimates.push((estimate, estimate / error));
    }
    let [(ms, zs), (mf, zf)] = [estimates[0], estimates[1]];
    if zs.abs() < MIN_HALF_Z || zf.abs() < MIN_HALF_Z {
        Some(format!("not clear at both the slower and the faster motion (z = {zs:.1} and {zf:.1})"))
    } else if ms.signum() != mf.signum() || (ms - mf).abs() > MAX_HALF_SPREAD * (ms + mf).abs() / 2.0 {
        Some(format!(
            "{ms:.4e} {unit} at the slower and {mf:.4e} {unit} at the faster motion: {}",
            if effect == Effect::CoulombFriction {
                "the opening grows with the rate, so it is damping, not friction"
            } else {
                "the loop's opening does not scale with the rate, so it is hysteresis shape, not a rate effect"
            },
            unit = effect.unit()
        ))
    } else {
        None
    }
}

fn unweighted_rss(observed: &Observed, fit: &ExtendedFit, subset: &[usize]) -> Result<f64, model_core::Error> {
    // Summed in order as they come: the sum over [`ExtendedFit::residuals`], without the vector.
    let model = Model::new(fit.params)?;
    subset
        .iter()
        .map(|&i| {
            let r = observed.data.torque[i] - fit.predict(observed, &model, i)?;
            Ok(r * r)
        })
        .sum()
}

/// RMS on the held-out samples of each model refitted on the training samples only; `None`
/// when the data are too few to hold any out.
fn held_out(
    observed: &Observed,
    weights: &[f64],
    baseline: &ExtendedFit,
    final_fit: &ExtendedFit,
) -> Result<Option<(f64, f64)>, DiagnoseError> {
    if observed.held_out.is_empty() || observed.training.len() < 10 {
        return Ok(None);
    }
    let rms = |fit: &ExtendedFit| -> Result<f64, DiagnoseError> {
        let trained = fit_extended(observed, &observed.training, weights, &fit.active, fit)
            .map_err(|source| refit_error(&fit.active, source))?;
        let residuals = trained
            .residuals(observed, &observed.held_out)
            .map_err(|source| refit_error(&fit.active, source.into()))?;
        Ok((residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len() as f64).sqrt())
    };
    Ok(Some((rms(baseline)?, rms(final_fit)?)))
}

fn location_words(effect: Effect, fit: &ExtendedFit) -> String {
    let s = &fit.state;
    match effect {
        Effect::Backlash => format!(
            "around zero torque: the deflection jumps by {:.3e} rad while the torque crosses zero",
            s.backlash
        ),
        Effect::CoulombFriction => format!(
            "on both directions, the whole loop: the torque is {} N·m higher while the deflection rises than while it falls",
            torque(2.0 * s.coulomb)
        ),
        Effect::ViscousDamping => {
            "grows with the deflection rate: largest where the loop crosses zero deflection, zero at the turning points".into()
        }
        Effect::KinematicError => format!(
            "periodic in the input angle: 2 cycles per input revolution ({:.3e} rad), 4 per revolution {:.3e} rad",
            s.kinematic[0].hypot(s.kinematic[1]),
            s.kinematic[2].hypot(s.kinematic[3])
        ),
        Effect::ThermalDrift => {
            "drifts with temperature: the loop's slope changes as the gear warms".into()
        }
        Effect::TorqueOffset => "everywhere: the whole loop is shifted in torque".into(),
    }
}
