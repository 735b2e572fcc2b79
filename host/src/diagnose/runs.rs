//! Several runs of one gear (`diagnose RUN1.csv RUN2.csv …`): each run diagnosed alone, from its
//! own start, as `diagnose` does one; then what the runs say together.
//!
//! - **Effects:** each effect named (or kept undecided) in some run, with its verdict and
//!   estimate in every run, and whether the runs that name it read one magnitude: no two of
//!   them disagree ([`estimates_disagree`], the rule the halves and the rates of one run follow).
//!   Where they agree, their inverse-variance mean.
//! - **The deflection's zero:** the θ0 each run read at rest, and whether it is one zero
//!   (no two 3 standard errors of their difference apart) or moves between runs.
//! - **Asymmetry:** a run of one cycle cannot check it on its own parts (each part a leg, one
//!   side of the loop), so the runs are the parts: it is named when every run whose loop the
//!   form describes passes the tests on its whole recording, and all of them read it with one
//!   sign, their magnitudes within [`super::MAX_HALF_SPREAD`] of one another.
//!
//! - **Masing's rule:** tested on the runs at once, each from rest or from a remanence it
//!   estimates (a run that starts at a standstill found in the data), where they hold loops of
//!   more than one size ([`non_masing::check_runs`]): what "record several amplitudes" asks.
//! - **A rate effect** across runs at different rates, where a run at one rate cannot tell one
//!   ([`rates_across::check`]): what "record the same loop at a second rate" asks.
//!
//! The effects are not searched for jointly: each run has its own baseline and its own search,
//! so an effect below one run's noise stays unnamed there even where pooling the runs would
//! show it.
use super::asymmetry::{Asymmetry, AsymmetryCheck, MIN_ASYMMETRY};
use super::effects::Effect;
use super::form::STRUCTURE_FACTOR;
use super::non_masing::{self, NonMasingCheck, RunOfMany};
use super::rates_across::{self, RateAcross};
use super::{diagnose_dataset, estimates_disagree, magnitudes_differ, DiagnoseError, DiagnoseOutcome, MIN_HALF_Z};
use crate::input::Dataset;
use crate::prepare::OriginSource;
use model_core::Params;
use serde::Serialize;

/// Every run's diagnosis, in the order given, and what they show together.
pub struct RunsOutcome {
    pub runs: Vec<DiagnoseOutcome>,
    pub across: Across,
}

/// What the runs show together.
#[derive(Clone, Debug, Serialize)]
pub struct Across {
    /// Each effect named or kept undecided in at least one run.
    pub effects: Vec<EffectAcross>,
    /// The deflection's zero each run read at rest; `None` when no run has a rest window.
    pub zero: Option<ZeroAcross>,
    pub asymmetry: AsymmetryAcross,
    /// Masing's rule tested on the runs at once ([`non_masing::check_runs`]).
    pub non_masing: NonMasingCheck,
    /// A rate effect tested across runs at different rates, where some run could not tell one
    /// alone ([`rates_across::check`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rate: Option<RateAcross>,
}

/// An effect in one run.
#[derive(Clone, Copy, Debug, Serialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum RunVerdict {
    /// Named, with its magnitude and standard error (from its z; `None` where z is 0), in the
    /// effect's unit.
    Named { magnitude: f64, error: Option<f64> },
    /// Kept as either of two, with its magnitude in its own place.
    Undecided { magnitude: f64 },
    /// Tried and refused, with its estimate there and its standard error (`None` where z is 0).
    Refused { magnitude: f64, error: Option<f64> },
    /// Not searched for: the run cannot reveal it, or its form cannot tell it.
    CannotTell,
}

/// One effect across the runs.
#[derive(Clone, Debug, Serialize)]
pub struct EffectAcross {
    pub effect: Effect,
    pub unit: &'static str,
    /// Its verdict in each run, in the order given.
    pub runs: Vec<RunVerdict>,
    /// How many runs name it.
    pub named_in: usize,
    /// The runs that name it read one magnitude.
    pub agree: bool,
    /// Their inverse-variance mean and its standard error, where they agree.
    pub pooled: Option<[f64; 2]>,
}

/// The deflection's zero across the runs.
#[derive(Clone, Debug, Serialize)]
pub struct ZeroAcross {
    /// Each run's θ0 and its standard error, rad, where it has a rest window to read it.
    pub runs: Vec<Option<[f64; 2]>>,
    /// The runs read one zero: no two of them 3 standard errors of their difference apart.
    pub one_zero: bool,
    /// Its inverse-variance mean and standard error, rad, where they do; the error no smaller
    /// than the best run's, whose encoders' rounding every run shares.
    pub pooled: Option<[f64; 2]>,
    /// The largest and smallest zero read, rad.
    pub range: [f64; 2],
}

/// The spring's asymmetry across the runs.
#[derive(Clone, Debug, Serialize)]
pub struct AsymmetryAcross {
    /// Each run's (k₊ − k₋) over their mean where it was tested, in the order given.
    pub runs: Vec<Option<f64>>,
    /// Named across the runs.
    pub named: bool,
    /// The mean of the runs that judge it, where named.
    pub magnitude: Option<f64>,
    /// What the runs show, and what would tell where they cannot.
    pub words: String,
}

/// Why several runs could not be diagnosed: which run (0-based), and why.
#[derive(Debug, thiserror::Error)]
#[error("run {}: {source}", index + 1)]
pub struct RunsError {
    pub index: usize,
    #[source]
    pub source: DiagnoseError,
}

/// Diagnoses each of `datasets` alone (`diagnose_dataset`, from `baseline` or a baseline fitted
/// with `seed`), then what they show together. `progress` is told before each run (its index,
/// of how many).
pub fn diagnose_runs(
    datasets: Vec<Dataset>,
    baseline: Option<Params<f64>>,
    seed: u64,
    progress: impl Fn(usize, usize),
) -> Result<RunsOutcome, RunsError> {
    let count = datasets.len();
    let mut runs = Vec::with_capacity(count);
    // One run at a time: each diagnosis keeps both cores busy, and the next one's samples are
    // read only when it starts.
    for (index, dataset) in datasets.into_iter().enumerate() {
        progress(index, count);
        runs.push(diagnose_dataset(dataset, baseline, seed).map_err(|source| RunsError { index, source })?);
    }
    let beside: Vec<Vec<Effect>> = runs.iter().map(|outcome| outcome.diagnosis.beside_the_form()).collect();
    let many: Vec<RunOfMany> = runs
        .iter()
        .zip(&beside)
        .map(|(outcome, beside)| RunOfMany {
            observed: &outcome.observed,
            weights: &outcome.diagnosis.weights,
            active: beside,
            remanent_start: outcome.remanent_start,
        })
        .collect();
    let across = Across {
        effects: effects_across(&runs),
        zero: zero_across(&runs),
        asymmetry: asymmetry_across(&runs),
        non_masing: non_masing::check_runs(&many),
        rate: rates_across::check(&many),
    };
    Ok(RunsOutcome { runs, across })
}

/// The standard error of an estimate from its z, where it is finite.
fn error_from_z(magnitude: f64, z: f64) -> Option<f64> {
    Some((magnitude / z).abs()).filter(|error| error.is_finite())
}

/// The verdict of `effect` in one run.
fn verdict(outcome: &DiagnoseOutcome, effect: Effect) -> RunVerdict {
    let diagnosis = &outcome.diagnosis;
    if let Some(f) = diagnosis.findings.iter().find(|f| f.effect == effect) {
        return RunVerdict::Named { magnitude: f.magnitude, error: error_from_z(f.magnitude, f.evidence.z) };
    }
    for u in &diagnosis.undecided {
        if let Some(k) = u.effects.iter().position(|e| *e == effect) {
            return RunVerdict::Undecided { magnitude: u.magnitudes[k] };
        }
    }
    match diagnosis.rejected.iter().find(|r| r.effect == effect) {
        Some(r) => RunVerdict::Refused { magnitude: r.magnitude, error: error_from_z(r.magnitude, r.evidence.z) },
        None => RunVerdict::CannotTell,
    }
}

/// Whether no two of `estimates` (value, standard error) disagree.
fn all_agree(estimates: &[[f64; 2]], disagree: impl Fn([f64; 2], [f64; 2]) -> bool) -> bool {
    estimates.iter().enumerate().all(|(i, &a)| estimates[i + 1..].iter().all(|&b| !disagree(a, b)))
}

/// The inverse-variance mean of `estimates` and its standard error; `None` without a finite one.
/// Where the estimates scatter more than their errors say (Birge's ratio R = √(χ²/(k − 1)) above
/// 1), the error is scaled by R: runs that pass as one magnitude (within 50 % of one another)
/// may still be many of their errors apart, and the pooled error must cover that scatter, not
/// shrink with the number of runs (0.20, 0.20 and 0.26 N·m, each ± 0.002, pooled to ± 0.001).
fn pooled(estimates: &[[f64; 2]]) -> Option<[f64; 2]> {
    let finite: Vec<([f64; 2], f64)> =
        estimates.iter().map(|&[m, e]| ([m, e], 1.0 / (e * e))).filter(|(_, w)| w.is_finite()).collect();
    let total: f64 = finite.iter().map(|(_, w)| w).sum();
    if !(total > 0.0 && total.is_finite()) {
        return None;
    }
    let mean = finite.iter().map(|([m, _], w)| m * w).sum::<f64>() / total;
    let chi2: f64 = finite.iter().map(|([m, _], w)| w * (m - mean).powi(2)).sum();
    let birge = if finite.len() > 1 { (chi2 / (finite.len() - 1) as f64).sqrt().max(1.0) } else { 1.0 };
    Some([mean, birge * total.sqrt().recip()])
}

fn effects_across(runs: &[DiagnoseOutcome]) -> Vec<EffectAcross> {
    let mut effects: Vec<Effect> = Vec::new();
    for outcome in runs {
        let diagnosis = &outcome.diagnosis;
        let kept =
            diagnosis.findings.iter().map(|f| f.effect).chain(diagnosis.undecided.iter().flat_map(|u| u.effects));
        for effect in kept {
            if !effects.contains(&effect) {
                effects.push(effect);
            }
        }
    }
    effects
        .into_iter()
        .map(|effect| {
            let verdicts: Vec<RunVerdict> = runs.iter().map(|outcome| verdict(outcome, effect)).collect();
            let named: Vec<[f64; 2]> = verdicts
                .iter()
                .filter_map(|v| match *v {
                    RunVerdict::Named { magnitude, error } => Some([magnitude, error.unwrap_or(f64::INFINITY)]),
                    _ => None,
                })
                .collect();
            let agree = all_agree(&named, |[a, ea], [b, eb]| estimates_disagree(a, ea, b, eb));
            EffectAcross {
                effect,
                unit: effect.unit(),
                named_in: named.len(),
                pooled: agree.then(|| pooled(&named)).flatten(),
                agree,
                runs: verdicts,
            }
        })
        .collect()
}

fn zero_across(runs: &[DiagnoseOutcome]) -> Option<ZeroAcross> {
    let zeros: Vec<Option<[f64; 2]>> = runs
        .iter()
        .map(|outcome| {
            // A zero fitted where a run has no rest is the form's, not a reading.
            let read = outcome.origin.filter(|o| o.source == OriginSource::RestWindow);
            read.and_then(|o| o.zero_se_rad.map(|se| [o.zero_rad, se]))
        })
        .collect();
    let read: Vec<[f64; 2]> = zeros.iter().flatten().copied().collect();
    if read.is_empty() {
        return None;
    }
    // The zero is read, not fitted: no form's misfit moves it, so its error alone judges.
    let one_zero = all_agree(&read, |[a, ea], [b, eb]| (a - b).abs() > MIN_HALF_Z * ea.hypot(eb));
    let range = read.iter().fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], [z, _]| [lo.min(*z), hi.max(*z)]);
    // Runs that read one zero read it through the same encoders, and share its rounding: a
    // reading at rest that hardly leaves one step is off by up to half a step in every run alike
    // (each run's error is then step/√12). Pooling does not average that away, so the pooled
    // zero is no more precise than the best run's: 4 runs of a gear zeroed 3 µrad off, in 20-bit
    // angles (a step of 6 µrad), each read 6.0 ± 1.7 µrad, and pooled to ± 0.9 µrad named an
    // offset twice the true one, 3.5 of its errors away.
    let best = read.iter().map(|[_, error]| *error).fold(f64::INFINITY, f64::min);
    let pooled = one_zero.then(|| pooled(&read)).flatten().map(|[mean, error]| [mean, error.max(best)]);
    Some(ZeroAcross { pooled, one_zero, range, runs: zeros })
}

fn asymmetry_across(runs: &[DiagnoseOutcome]) -> AsymmetryAcross {
    let tested: Vec<Option<&Asymmetry>> = runs
        .iter()
        .map(|outcome| match &outcome.asymmetry {
            AsymmetryCheck::Yes(found) => Some(found),
            AsymmetryCheck::No { .. } => None,
        })
        .collect();
    let magnitudes = tested.iter().map(|t| t.map(|a| a.magnitude)).collect();
    // The runs that can judge it: the form describes their loop.
    let judging: Vec<(usize, &Asymmetry)> = tested
        .iter()
        .enumerate()
        .filter_map(|(k, t)| t.filter(|a| a.form_to_noise <= STRUCTURE_FACTOR).map(|a| (k, a)))
        .collect();
    let list = |runs: &[(usize, &Asymmetry)]| {
        runs.iter()
            .map(|(k, a)| format!("{:+.1} % (run {})", 100.0 * a.magnitude, k + 1))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let unjudged = tested.iter().filter(|t| t.is_some()).count() - judging.len();
    let beside = if unjudged > 0 {
        format!("; {unjudged} more tested, whose loop the micro-slip form leaves over {STRUCTURE_FACTOR}× the noise")
    } else {
        String::new()
    };
    let untested: Vec<&str> = runs
        .iter()
        .filter_map(|outcome| match &outcome.asymmetry {
            AsymmetryCheck::No { why } => Some(why.as_str()),
            AsymmetryCheck::Yes(_) => None,
        })
        .collect();
    let (named, magnitude, words) = match judging.as_slice() {
        [] if unjudged == 0 => {
            (false, None, format!("no run could test it: {}", untested.first().copied().unwrap_or_default()))
        }
        [] => (false, None, format!("no run's loop is one the form describes, so no run judges it{beside}")),
        [(k, a)] => (
            false,
            None,
            format!(
                "only run {} judges it ({:+.1} %){beside}: repeat that run, or record another whose loop the form \
                 describes, to check it on a second",
                k + 1,
                100.0 * a.magnitude
            ),
        ),
        judging => {
            let mean = judging.iter().map(|(_, a)| a.magnitude).sum::<f64>() / judging.len() as f64;
            let agree = judging
                .iter()
                .enumerate()
                .all(|(i, (_, a))| judging[i + 1..].iter().all(|(_, b)| !magnitudes_differ(a.magnitude, b.magnitude)));
            let failing: Vec<String> =
                judging.iter().filter(|(_, a)| !a.whole_passes).map(|(k, _)| (k + 1).to_string()).collect();
            if !(mean.abs() >= MIN_ASYMMETRY) {
                let below = format!("below the {:.0} % named", 100.0 * MIN_ASYMMETRY);
                (false, None, format!("{}: on average {:+.1} %, {below}{beside}", list(judging), 100.0 * mean))
            } else if !agree {
                (false, None, format!("the runs disagree: {}{beside}", list(judging)))
            } else if !failing.is_empty() {
                (
                    false,
                    None,
                    format!(
                        "the runs read one sign ({}), but run(s) {} do not show it on their own tests{beside}",
                        list(judging),
                        failing.join(", ")
                    ),
                )
            } else {
                (true, Some(mean), format!("named: {} agree, mean {:+.1} %{beside}", list(judging), 100.0 * mean))
            }
        }
    };
    AsymmetryAcross { runs: magnitudes, named, magnitude, words }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A refusal with z = 0 has no standard error: reported without one, not as an infinite one
    /// (which no report prints, so the whole report of the runs would fail).
    #[test]
    fn an_estimate_without_significance_has_no_standard_error() {
        assert_eq!(error_from_z(0.1, 0.0), None);
        assert_eq!(error_from_z(-0.1, 2.0), Some(0.05));
    }

    /// Estimates that scatter within their errors pool to the inverse-variance error; ones that
    /// scatter beyond it pool to an error that covers the scatter.
    #[test]
    fn a_pooled_error_covers_the_estimates_scatter() {
        let [mean, error] = pooled(&[[0.20, 0.002], [0.202, 0.002], [0.199, 0.002]]).unwrap();
        assert!((mean - 0.2003).abs() < 1e-4 && (error - 0.002 / 3f64.sqrt()).abs() < 1e-9, "{mean} ± {error}");
        let [mean, error] = pooled(&[[0.20, 0.002], [0.20, 0.002], [0.26, 0.002]]).unwrap();
        // The scatter's own standard error of the mean: sd 0.035 over √3.
        assert!((mean - 0.22).abs() < 1e-9 && error > 0.019, "{mean} ± {error}");
        assert_eq!(pooled(&[[0.3, 0.01]]), Some([0.3, 0.01]));
        assert_eq!(pooled(&[[0.3, f64::INFINITY]]), None);
    }
}
