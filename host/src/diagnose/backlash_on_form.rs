//! A backlash the search on the genetic form did not name, tried on the micro-slip form where
//! that form is named ([`super::form::judge`]). On the genetic form a backlash is judged against
//! the genetic loop's misfit: the 20 µrad dead band concealed in OpenSees' catalogue and
//! asymmetric springs "explained 1.0 % and 0.4 % of the residual" there and was refused, where
//! on the form it lowers the information criterion by hundreds (`bash bench/opensees/run.sh`,
//! its diagnosis corpus).
//!
//! A backlash moves the deflection the form runs on, so it is no column: its width is searched
//! for on a grid (×√2 from 2σθ to half the deflection's half-range, then ×2^¼ around the best),
//! each width one least-squares solve of the form on a subsample of at most
//! [`SUBSAMPLE`] samples spread over the recording, turning points kept. Where the best width
//! does not lower the subsample's χ² by [`MIN_HALF_Z`]² noise variances, it is refused there:
//! each interleaved part, half of those samples, would have to show it by as much. Otherwise it
//! is named when, at the best width, on every sample:
//! - the information criterion drops by more than [`MIN_BIC_DROP`] (the 5 % of the residual a
//!   torque effect must also explain is not asked, as for a backlash re-tested on the form:
//!   [`super::form`]);
//! - the form with it leaves at most [`STRUCTURE_FACTOR`] times the noise;
//! - the held-out samples are predicted better with it, each fitted without them;
//! - each interleaved part alone shows it (|z| ≥ [`MIN_HALF_Z`] on the subsample) with widths
//!   within [`super::MAX_HALF_SPREAD`] of their mean.
use super::effects::backlash;
use super::form::STRUCTURE_FACTOR;
use super::observed::Observed;
use super::{magnitudes_differ, weights_on, Evidence, MIN_BIC_DROP, MIN_HALF_Z};
use crate::fit::motion::{micro_slip_with_columns, ColumnsFit, SpringShape};
use crate::prepare::{reversals, NoiseModel};
use rayon::prelude::*;

/// Most samples the width search fits at a time.
pub const SUBSAMPLE: usize = 4096;

/// A backlash named on the form: its width (rad) there, its evidence, the form's unweighted RSS
/// without and with it, (N·m)², and the form with it: its torque at every sample and its RMS on
/// the held-out samples fitted without them, N·m.
#[derive(Clone, Debug)]
pub struct Named {
    pub width: f64,
    pub evidence: Evidence,
    pub rss_before: f64,
    pub rss_after: f64,
    pub predicted: Vec<f64>,
    pub held_out_rms: Option<f64>,
}

/// What the form says of a backlash: named, or refused with its best width, evidence and why.
#[derive(Clone, Debug)]
pub enum Verdict {
    Named(Named),
    Refused { width: f64, evidence: Evidence, why: String },
}

/// The form on the deflection moved by a backlash `width` (rad), with torque `columns` beside
/// it, weighed by `weights` (a sample of weight 0 is followed, not fitted).
fn form_at(
    theta: &[f64],
    torque: &[f64],
    noise: NoiseModel,
    weights: &[f64],
    columns: &[&[f64]],
    width: f64,
) -> Option<ColumnsFit> {
    let moved: Vec<f64> = theta.iter().map(|&t| backlash(t, width)).collect();
    micro_slip_with_columns(&moved, torque, &reversals(&moved), Some(noise), weights, columns, SpringShape::Free).ok()
}

/// The recording thinned to every k-th sample and its turning points: its deflection, torque,
/// each weighting's weights and each column, at those samples.
struct Thinned {
    theta: Vec<f64>,
    torque: Vec<f64>,
    weightings: Vec<Vec<f64>>,
    columns: Vec<Vec<f64>>,
}

impl Thinned {
    fn of(observed: &Observed, weightings: &[Vec<f64>], columns: &[&[f64]]) -> Thinned {
        let data = &observed.data;
        let n = data.theta.len();
        let stride = n.div_ceil(SUBSAMPLE).max(1);
        let turning = reversals(&data.theta).indices;
        let mut turns = turning.iter().copied().peekable();
        let kept: Vec<usize> = (0..n).filter(|&i| turns.next_if_eq(&i).is_some() || i % stride == 0).collect();
        let gather = |values: &[f64]| kept.iter().map(|&i| values[i]).collect::<Vec<f64>>();
        Thinned {
            theta: gather(&data.theta),
            torque: gather(&data.torque),
            weightings: weightings.iter().map(|w| gather(w)).collect(),
            columns: columns.iter().map(|c| gather(c)).collect(),
        }
    }

    /// χ² of the form at each `(weighting, width)` and the parameters it solves for (∞ and 0
    /// where it cannot be fitted).
    fn chi2(&self, noise: NoiseModel, jobs: &[(usize, f64)]) -> Vec<(f64, usize)> {
        let columns: Vec<&[f64]> = self.columns.iter().map(Vec::as_slice).collect();
        jobs.par_iter()
            .map(|&(k, w)| {
                form_at(&self.theta, &self.torque, noise, &self.weightings[k], &columns, w)
                    .map_or((f64::INFINITY, 0), |fit| (fit.chi2, fit.parameters))
            })
            .collect()
    }

    /// The weighted samples of weighting `k`.
    fn fitted(&self, k: usize) -> usize {
        self.weightings[k].iter().filter(|w| **w > 0.0).count()
    }
}

/// Where in `widths` (`widths[0]` = 0, no backlash) `chi2` is least past the first, and the z of
/// its drop from no backlash, the variance from the weighted samples `fitted`.
fn best(widths: &[f64], chi2: &[f64], fitted: usize, parameters: usize) -> (usize, f64) {
    let at = (1..widths.len()).min_by(|&a, &b| chi2[a].total_cmp(&chi2[b])).unwrap_or(0);
    let variance = chi2[at] / (fitted as f64 - parameters as f64).max(1.0);
    let z = ((chi2[0] - chi2[at]).max(0.0) / variance).sqrt();
    (at, if z.is_finite() { z } else { 0.0 })
}

/// The width of least χ² by a parabola in ln w through three widths a ratio apart and their χ²,
/// kept between the outer two; `None` where the three do not bend upward.
fn vertex(widths: &[f64], chi2: &[f64]) -> Option<f64> {
    let ([w0, w1, w2], [c0, c1, c2]) = (<[f64; 3]>::try_from(widths).ok()?, <[f64; 3]>::try_from(chi2).ok()?);
    let curvature = c0 - 2.0 * c1 + c2;
    if !(curvature > 0.0) {
        return None;
    }
    // In steps of ln(w1/w0) from w1.
    let offset = (0.5 * (c0 - c2) / curvature).clamp(-1.0, 1.0);
    let width = w1 * (w1 / w0).powf(offset);
    (width.is_finite() && (w0..=w2).contains(&width)).then_some(width)
}

/// Tests a backlash on the form with the torque `columns` of the effects in the model beside
/// it, `weights` the form's noise weights. `None` where the form cannot be fitted.
pub fn test(observed: &Observed, noise: NoiseModel, weights: &[f64], columns: &[&[f64]]) -> Option<Verdict> {
    let data = &observed.data;
    let n = data.theta.len();
    let half_range = data.theta.iter().fold(0.0f64, |m, t| m.max(t.abs()));
    let sigma = noise.deflection_rad.max(f64::MIN_POSITIVE);
    let mut widths = vec![0.0];
    let mut w = 2.0 * sigma;
    while w <= 0.5 * half_range {
        widths.push(w);
        w *= std::f64::consts::SQRT_2;
    }
    if widths.len() < 2 {
        return None;
    }
    let [a, b] = &observed.parts;
    let weightings = [weights.to_vec(), weights_on(weights, a.iter().copied()), weights_on(weights, b.iter().copied())];
    let thinned = Thinned::of(observed, &weightings, columns);
    let coarse = thinned.chi2(noise, &widths.iter().map(|&w| (0, w)).collect::<Vec<_>>());
    // The form's, its columns' and the width.
    let parameters = coarse[0].1 + 1;
    let chi2 = |values: &[(f64, usize)]| values.iter().map(|v| v.0).collect::<Vec<f64>>();
    let (at, z) = best(&widths, &chi2(&coarse), thinned.fitted(0), parameters);
    if z < MIN_HALF_Z {
        // Each part alone, half of these samples, must show it by as much: the solves on every
        // sample (a third of the time at 60 k samples) are spared where none can pass.
        let drop = (coarse[0].0 - coarse[at].0).max(0.0);
        let evidence = Evidence {
            delta_bic: z * z - (thinned.fitted(0) as f64).ln(),
            explained: drop / coarse[0].0,
            z,
            halves: None,
            halves_z: None,
        };
        let why = format!(
            "on the micro-slip form no dead band fits clearly better than none (z = {z:.1} on {} samples, below {MIN_HALF_Z})",
            thinned.fitted(0)
        );
        return Some(Verdict::Refused { width: widths[at], evidence, why });
    }
    // Around the best coarse width: a finer step for all the samples, and the coarse ones for
    // each part alone.
    let step = 2f64.powf(0.25);
    let near: Vec<f64> = std::iter::once(0.0)
        .chain(widths[at.saturating_sub(2).max(1)..(at + 3).min(widths.len())].iter().copied())
        .collect();
    let jobs: Vec<(usize, f64)> = [(0, widths[at] / step), (0, widths[at] * step)]
        .into_iter()
        .chain([1, 2].into_iter().flat_map(|k| near.iter().map(move |&w| (k, w))))
        .collect();
    let refined = thinned.chi2(noise, &jobs);
    let width =
        vertex(&[widths[at] / step, widths[at], widths[at] * step], &[refined[0].0, coarse[at].0, refined[1].0])
            .unwrap_or(widths[at]);
    let halves = [1, 2].map(|k| {
        let part = &chi2(&refined[2..])[(k - 1) * near.len()..k * near.len()];
        let (at, z) = best(&near, part, thinned.fitted(k), parameters);
        (near[at], z)
    });
    let without = form_at(&data.theta, &data.torque, noise, weights, columns, 0.0)?;

    // On every sample, at the width found.
    let with = form_at(&data.theta, &data.torque, noise, weights, columns, width)?;
    let drop = (without.chi2 - with.chi2).max(0.0);
    let variance = with.chi2 / (n as f64 - parameters as f64).max(1.0);
    let evidence = Evidence {
        delta_bic: drop / variance - (n as f64).ln(),
        explained: drop / without.chi2,
        z: (drop / variance).sqrt(),
        halves: Some([halves[0].0, halves[1].0]),
        halves_z: Some([halves[0].1, halves[1].1]),
    };
    let rss = |fit: &ColumnsFit| data.torque.iter().zip(&fit.predicted).map(|(t, p)| (t - p).powi(2)).sum::<f64>();
    let rms_after = (rss(&with) / n as f64).sqrt();
    let noise_rms = (weights.iter().map(|w| 1.0 / w).sum::<f64>() / n as f64).sqrt();
    let held_out = held_out_rms(observed, noise, weights, columns, width);
    let refused = if evidence.delta_bic <= MIN_BIC_DROP {
        Some(format!("on the micro-slip form: ΔBIC {:.1}, not above {MIN_BIC_DROP}", evidence.delta_bic))
    } else if rms_after > STRUCTURE_FACTOR * noise_rms {
        Some(format!(
            "the micro-slip form with it leaves RMS {rms_after:.4} N·m, over {STRUCTURE_FACTOR}× the noise's \
             {noise_rms:.4}: no form here to judge it on"
        ))
    } else if let Err(why) = &held_out {
        Some(why.clone())
    } else if halves[0].1 < MIN_HALF_Z || halves[1].1 < MIN_HALF_Z {
        Some(format!(
            "on the micro-slip form not clear in both halves alone (z = {:.1} and {:.1})",
            halves[0].1, halves[1].1
        ))
    } else if magnitudes_differ(halves[0].0, halves[1].0) {
        Some(format!("on the micro-slip form the halves disagree: {:.4e} and {:.4e} rad", halves[0].0, halves[1].0))
    } else {
        None
    };
    Some(match refused {
        Some(why) => Verdict::Refused { width, evidence, why },
        None => Verdict::Named(Named {
            width,
            evidence,
            rss_before: rss(&without),
            rss_after: rss(&with),
            held_out_rms: held_out.ok().flatten(),
            predicted: with.predicted,
        }),
    })
}

/// The form's RMS on the held-out samples with a backlash `width`, fitted on the training
/// samples alone, where it predicts them better than without (`None` when nothing is held out);
/// why not otherwise.
fn held_out_rms(
    observed: &Observed,
    noise: NoiseModel,
    weights: &[f64],
    columns: &[&[f64]],
    width: f64,
) -> Result<Option<f64>, String> {
    let held = observed.held_out();
    if held.is_empty() {
        return Ok(None);
    }
    let data = &observed.data;
    let training = weights_on(weights, observed.training().iter().copied());
    let rms = |width: f64| {
        form_at(&data.theta, &data.torque, noise, &training, columns, width).map(|fit| {
            (held.iter().map(|&i| (data.torque[i] - fit.predicted[i]).powi(2)).sum::<f64>() / held.len() as f64).sqrt()
        })
    };
    match (rms(0.0), rms(width)) {
        (Some(before), Some(after)) if after < before => Ok(Some(after)),
        (Some(before), Some(after)) => Err(format!(
            "on the micro-slip form it does not predict the held-out samples better (RMS {before:.4} → {after:.4} N·m)"
        )),
        _ => Err("on the micro-slip form it could not be fitted without the held-out samples".into()),
    }
}
