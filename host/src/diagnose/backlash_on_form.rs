//! A backlash on the micro-slip form, where that form is named ([`super::form::judge`]): one the
//! search on the genetic form did not name is tried there, and one it named is measured there.
//! On the genetic form a backlash is judged against the genetic loop's misfit: the 20 µrad dead
//! band concealed in OpenSees' catalogue and asymmetric springs "explained 1.0 % and 0.4 % of
//! the residual" there and was refused, where on the form it lowers the information criterion
//! by hundreds; on four other materials the genetic form named it at 24–28 µrad, the form at
//! 18.4–18.7 (`bash bench/opensees/run.sh`, its diagnosis corpus).
//!
//! A backlash moves the deflection the form runs on, so it is no column: its width is searched
//! for on a grid (×√2 from 2σθ to half the deflection's half-range, then a parabola in ln w
//! through ×2^¼ steps about the best),
//! each width one least-squares solve of the form on a subsample of at most
//! [`SUBSAMPLE`] samples spread over the recording, turning points kept. Where the best width
//! does not lower the subsample's χ² by [`MIN_HALF_Z`]² noise variances, it is refused there:
//! each interleaved part, half of those samples, would have to show it by as much. Otherwise it
//! is named when, at the best width, on every sample:
//! - the information criterion drops by more than [`MIN_BIC_DROP`] (the 5 % of the residual a
//!   torque effect must also explain is not asked, as for a backlash re-tested on the form:
//!   [`super::form`]);
//! - the form with it leaves at most [`STRUCTURE_FACTOR`] times the noise;
//! - each interleaved part alone shows it (|z| ≥ [`MIN_HALF_Z`] on the subsample) with widths
//!   within [`super::MAX_HALF_SPREAD`] of their mean;
//! - the held-out samples are predicted better with it, each fitted without them.
use super::effects::backlash;
use super::form::{form_at, held_out_rms_along, noise_rms_of, STRUCTURE_FACTOR};
use super::observed::Observed;
use super::{magnitudes_differ, Evidence, FormAlong, MIN_BIC_DROP, MIN_HALF_Z};
use crate::fit::motion::ColumnsFit;
use crate::prepare::{reversals, NoiseModel};
use rayon::prelude::*;

/// Most samples the width search fits at a time.
pub const SUBSAMPLE: usize = 4096;

/// A backlash named on the form: its width (rad) there, its evidence, the form's unweighted RSS
/// without and with it, (N·m)², and the form with it, and its RMS on the held-out samples fitted
/// without them, N·m.
#[derive(Clone, Debug)]
pub struct Named {
    pub width: f64,
    pub evidence: Evidence,
    pub rss_before: f64,
    pub rss_after: f64,
    pub along: FormAlong,
    pub held_out_rms: Option<f64>,
}

/// What the form says of a backlash: named, or refused with its best width, evidence and why.
#[derive(Clone, Debug)]
pub enum Verdict {
    Named(Box<Named>),
    Refused { width: f64, evidence: Evidence, why: String },
}

/// Whether the torque is flat across the band |θ| < w/2, as it is behind a dead band (the gear
/// does not move there), against just outside it.
#[derive(Clone, Debug, PartialEq)]
pub enum Flatness {
    /// Its slope inside below half the slope outside, and below the slope outside by
    /// [`MIN_HALF_Z`] standard errors of their difference.
    Flat,
    /// As stiff inside as half the stiffness outside or more: a spring soft about zero, or a
    /// misfit of the form, not a dead band; why.
    Stiff(String),
    /// Too few samples inside or just outside, or not clear either way; why.
    Untold(String),
}

/// The torque's slope dT/dθ (N·m/rad) over the samples whose deflection lies in `band` (|θ|
/// from, to), pooled over each pass through it (consecutive samples between turning points,
/// three or more, each about its own mean: each pass holds its own torque), with its standard
/// error and the samples used; `None` with fewer than two passes.
fn pooled_slope(theta: &[f64], torque: &[f64], turning: &[usize], band: (f64, f64)) -> Option<(f64, f64, usize)> {
    let inside = |i: usize| (band.0..band.1).contains(&theta[i].abs());
    let mut passes: Vec<std::ops::Range<usize>> = Vec::new();
    let mut start = None;
    let mut turns = turning.iter().copied().peekable();
    for i in 0..=theta.len() {
        let reversal = turns.next_if_eq(&i).is_some();
        if start.is_some() && !(i < theta.len() && inside(i) && !reversal) {
            passes.extend(start.map(|s| s..i).filter(|pass| pass.len() >= 3));
            start = None;
        }
        if start.is_none() && i < theta.len() && inside(i) {
            start = Some(i);
        }
    }
    if passes.len() < 2 {
        return None;
    }
    let mean = |values: &[f64]| values.iter().sum::<f64>() / values.len() as f64;
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for pass in &passes {
        let (x, t) = (&theta[pass.clone()], &torque[pass.clone()]);
        let (mx, mt) = (mean(x), mean(t));
        sxx += x.iter().map(|v| (v - mx).powi(2)).sum::<f64>();
        sxy += x.iter().zip(t).map(|(v, w)| (v - mx) * (w - mt)).sum::<f64>();
    }
    let slope = sxy / sxx;
    let samples: usize = passes.iter().map(|p| p.len()).sum();
    let rss: f64 = passes
        .iter()
        .map(|pass| {
            let (x, t) = (&theta[pass.clone()], &torque[pass.clone()]);
            let (mx, mt) = (mean(x), mean(t));
            x.iter().zip(t).map(|(v, w)| (w - mt - slope * (v - mx)).powi(2)).sum::<f64>()
        })
        .sum();
    let variance = rss / (samples as f64 - passes.len() as f64 - 1.0).max(1.0);
    let error = (variance / sxx).sqrt();
    (slope.is_finite() && error.is_finite()).then_some((slope, error, samples))
}

/// Whether the torque is flat inside a dead band of `width` (rad) and stiff just outside it
/// (w/2 ≤ |θ| < 3w/2). Behind a real dead band the gear does not move, so its torque holds;
/// the form takes a band for a spring soft about zero too, or for its own misfit, and there
/// the torque inside is as stiff as outside. On `simulate`'s catalogue gear under nested
/// motion (a 14000 N·m/rad first segment) the form named 24 µrad at 1.5 mrad and 80 µrad at
/// 2 mrad, and on a Bouc–Wen gear with damping 68 µrad: inside 14800, 14800 and 8400 N·m/rad,
/// outside 13000, 15000 and 8200 (the refusals' words, `bash bench/backlash.sh`'s gears).
pub fn flatness(observed: &Observed, width: f64) -> Flatness {
    let data = &observed.data;
    let turning = reversals(&data.theta).indices;
    let slope = |band| pooled_slope(&data.theta, &data.torque, &turning, band);
    let (Some((inside, inside_error, inside_samples)), Some((outside, outside_error, _))) =
        (slope((0.0, width / 2.0)), slope((width / 2.0, 1.5 * width)))
    else {
        return Flatness::Untold(format!(
            "too few passes through the band (|θ| < {:.3e} rad) and just beyond it to tell a dead band, where the \
             torque holds, from a spring soft about zero",
            width / 2.0
        ));
    };
    let words = format!(
        "the torque's slope inside the band (|θ| < {:.3e} rad, {inside_samples} samples) is {inside:.0} ± \
         {inside_error:.0} N·m/rad, just beyond it {outside:.0} ± {outside_error:.0}",
        width / 2.0
    );
    if inside >= outside / 2.0 {
        Flatness::Stiff(format!("{words}: the gear moves inside it, so not a dead band"))
    } else if outside - inside < MIN_HALF_Z * inside_error.hypot(outside_error) {
        Flatness::Untold(format!("{words}: not clearly flatter inside"))
    } else {
        Flatness::Flat
    }
}

/// The recording thinned to one sample in each block of `stride` and its turning points: its
/// deflection, torque, weights (all samples', then each interleaved part's alone) and each
/// column, at those samples. The sample taken moves within its block by the golden ratio's
/// steps: a fixed phase aliased with a periodic motion (a 0.5 Hz sine at 1 kHz, 2 M samples,
/// stride 489, took the same four phases every cycle) and showed a dead band that every sample
/// did not.
struct Thinned {
    theta: Vec<f64>,
    torque: Vec<f64>,
    weightings: [Vec<f64>; 3],
    columns: Vec<Vec<f64>>,
}

impl Thinned {
    fn of(observed: &Observed, weights: &[f64], columns: &[&[f64]]) -> Thinned {
        let data = &observed.data;
        let n = data.theta.len();
        let stride = n.div_ceil(SUBSAMPLE).max(1);
        let taken =
            |block: usize| block * stride + ((block as f64 * 0.618_033_988_749_895).fract() * stride as f64) as usize;
        let turning = reversals(&data.theta).indices;
        let mut turns = turning.iter().copied().peekable();
        let kept: Vec<usize> = (0..n).filter(|&i| turns.next_if_eq(&i).is_some() || i == taken(i / stride)).collect();
        let gather = |values: &[f64]| kept.iter().map(|&i| values[i]).collect::<Vec<f64>>();
        // Each part's weights at the samples kept, without a vector of every sample's.
        let part = |samples: &[usize]| {
            kept.iter().map(|i| if samples.binary_search(i).is_ok() { weights[*i] } else { 0.0 }).collect()
        };
        let [a, b] = &observed.parts;
        Thinned {
            theta: gather(&data.theta),
            torque: gather(&data.torque),
            weightings: [gather(weights), part(a), part(b)],
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
    let thinned = Thinned::of(observed, weights, columns);
    let coarse = thinned.chi2(noise, &widths.iter().map(|&w| (0, w)).collect::<Vec<_>>());
    // The form's, its columns' and the width.
    let parameters = coarse[0].1 + 1;
    let chi2 = |values: &[(f64, usize)]| values.iter().map(|v| v.0).collect::<Vec<f64>>();
    let (at, z) = best(&widths, &chi2(&coarse), thinned.fitted(0), parameters);
    // The evidence on the subsample, where a refusal there spares the fits on every sample.
    let subsample_evidence = |halves: Option<[(f64, f64); 2]>| Evidence {
        delta_bic: z * z - (thinned.fitted(0) as f64).ln(),
        explained: (coarse[0].0 - coarse[at].0).max(0.0) / coarse[0].0,
        z,
        halves: halves.map(|h| h.map(|(width, _)| width)),
        halves_z: halves.map(|h| h.map(|(_, z)| z)),
    };
    if z < MIN_HALF_Z {
        // Each part alone, half of these samples, must show it by as much: the solves on every
        // sample (a third of the time at 60 k samples) are spared where none can pass.
        let evidence = subsample_evidence(None);
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
    // Each part's width placed between the coarse widths as the whole's is, where it has a
    // coarse neighbour on either side (else the grid's).
    let halves = [1, 2].map(|k| {
        let part = &chi2(&refined[2..])[(k - 1) * near.len()..k * near.len()];
        let (at, z) = best(&near, part, thinned.fitted(k), parameters);
        let placed =
            (at > 1 && at + 1 < near.len()).then(|| vertex(&near[at - 1..=at + 1], &part[at - 1..=at + 1])).flatten();
        (placed.unwrap_or(near[at]), z)
    });
    if let Flatness::Stiff(why) | Flatness::Untold(why) = flatness(observed, width) {
        let why = format!("on the micro-slip form: {why}");
        return Some(Verdict::Refused { width, evidence: subsample_evidence(Some(halves)), why });
    }
    // On every sample, one fit at a time: each holds its torque at every sample (16 MB at 2 M).
    let rss = |fit: &ColumnsFit| observed.rss(&fit.predicted);
    let scored = observed.scored_count();
    let (chi2_without, rss_before) =
        form_at(&data.theta, &data.torque, noise, weights, columns, 0.0).map(|fit| (fit.chi2, rss(&fit)))?;
    let with = form_at(&data.theta, &data.torque, noise, weights, columns, width)?;
    let drop = (chi2_without - with.chi2).max(0.0);
    let variance = with.chi2 / (scored as f64 - parameters as f64).max(1.0);
    let evidence = Evidence {
        delta_bic: drop / variance - (scored as f64).ln(),
        explained: drop / chi2_without,
        z: (drop / variance).sqrt(),
        halves: Some([halves[0].0, halves[1].0]),
        halves_z: Some([halves[0].1, halves[1].1]),
    };
    let rss_after = rss(&with);
    let rms_after = (rss_after / scored.max(1) as f64).sqrt();
    let noise_rms = noise_rms_of(weights);
    let mut held_out = None;
    let refused = if evidence.delta_bic <= MIN_BIC_DROP {
        Some(format!("on the micro-slip form: ΔBIC {:.1}, not above {MIN_BIC_DROP}", evidence.delta_bic))
    } else if rms_after > STRUCTURE_FACTOR * noise_rms {
        Some(format!(
            "the micro-slip form with it leaves RMS {rms_after:.4} N·m, over {STRUCTURE_FACTOR}× the noise's \
             {noise_rms:.4}: no form here to judge it on"
        ))
    } else if halves[0].1 < MIN_HALF_Z || halves[1].1 < MIN_HALF_Z {
        Some(format!(
            "on the micro-slip form not clear in both halves alone (z = {:.1} and {:.1})",
            halves[0].1, halves[1].1
        ))
    } else if magnitudes_differ(halves[0].0, halves[1].0) {
        Some(format!("on the micro-slip form the halves disagree: {:.4e} and {:.4e} rad", halves[0].0, halves[1].0))
    } else {
        // Two fits more, asked last.
        match held_out_rms(observed, noise, weights, columns, width) {
            Ok(rms) => {
                held_out = rms;
                None
            }
            Err(why) => Some(why),
        }
    };
    Some(match refused {
        Some(why) => Verdict::Refused { width, evidence, why },
        None => Verdict::Named(Box::new(Named {
            width,
            evidence,
            rss_before,
            rss_after,
            held_out_rms: held_out,
            along: FormAlong { model: with.model, predicted: with.predicted },
        })),
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
    if observed.held_out().is_empty() {
        return Ok(None);
    }
    let rms = |width: f64| {
        let moved: Vec<f64> = observed.data.theta.iter().map(|&t| backlash(t, width)).collect();
        held_out_rms_along(observed, &moved, &reversals(&moved), noise, weights, columns)
    };
    match (rms(0.0), rms(width)) {
        (Some(before), Some(after)) if after < before => Ok(Some(after)),
        (Some(before), Some(after)) => Err(format!(
            "on the micro-slip form it does not predict the held-out samples better (RMS {before:.4} → {after:.4} N·m)"
        )),
        _ => Err("on the micro-slip form it could not be fitted without the held-out samples".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triangle wave of ±1 mrad, 401 samples a leg, its turning points, and the torque of a
    /// spring of stiffness `k` behind a dead band of `width` (rad), hysteresis-free.
    fn triangle(k: f64, width: f64) -> (Vec<f64>, Vec<f64>, Vec<usize>) {
        let leg = 400;
        let theta: Vec<f64> = (0..=4 * leg)
            .map(|i| {
                let phase = (i % (2 * leg)) as f64 / leg as f64;
                let up = if phase <= 1.0 { phase } else { 2.0 - phase };
                (2.0 * up - 1.0) * 1e-3
            })
            .collect();
        let torque = theta.iter().map(|&t| k * backlash(t, width)).collect();
        (theta, torque, vec![leg, 2 * leg, 3 * leg])
    }

    #[test]
    fn the_slope_is_flat_inside_a_dead_band_and_the_springs_beside_it() {
        let (theta, torque, turning) = triangle(20000.0, 1e-4);
        let (inside, ..) = pooled_slope(&theta, &torque, &turning, (0.0, 5e-5)).unwrap();
        let (outside, ..) = pooled_slope(&theta, &torque, &turning, (5e-5, 1.5e-4)).unwrap();
        assert!(inside.abs() < 1e-6, "{inside}");
        assert!((outside - 20000.0).abs() < 1e-6, "{outside}");
        // A spring without a dead band has one slope across the same band.
        let (theta, torque, turning) = triangle(20000.0, 0.0);
        let (inside, ..) = pooled_slope(&theta, &torque, &turning, (0.0, 5e-5)).unwrap();
        assert!((inside - 20000.0).abs() < 1e-6, "{inside}");
    }

    #[test]
    fn a_band_passed_fewer_than_twice_has_no_slope() {
        let (theta, torque, _) = triangle(20000.0, 1e-4);
        // The first leg alone passes the band once.
        assert!(pooled_slope(&theta[..401], &torque[..401], &[], (0.0, 5e-5)).is_none());
    }
}
