//! Where the fitted model and a recording disagree, which physics the model leaves out, and
//! how much better the model gets with it.
//!
//! Every effect of [`Effect`] enters the fit as extra linear columns beside the model's own:
//! torque effects directly (friction ±1 by direction, damping the deflection rate, drift the
//! warming times θ, an offset 1), deflection effects (backlash, kinematic error) as
//! Gauss–Newton columns K·∂θ_elastic/∂magnitude, iterated to convergence. So an effect costs
//! a few weighted least-squares solves, and a greedy search can try each one.
//!
//! An effect is accepted only on strong evidence: the Bayesian information criterion must
//! drop by more than 10 (Kass & Raftery's "very strong"), the effect must explain at least
//! 5 % of the remaining weighted residual (a concealed effect at half the noise explains
//! 20 %: smaller gains are what model mismatch and noise structure produce), and the two
//! independent halves of the recording, fitted alone, must each show it clearly (|z| > 3)
//! with magnitudes within ±25 % of their mean.
pub mod asymmetry;
mod backlash_on_form;
pub mod effects;
mod extended;
pub mod form;
pub mod kinks;
mod locate;
pub mod non_masing;
mod observed;
mod on_form;
pub mod passivity;
pub mod ratcheting;
pub mod rates_across;
pub mod runs;
mod search;

pub use effects::Effect;
pub use extended::{fit_extended, EffectState, ExtendedFit, ExtendedFitError};
pub use locate::{locate, Observation};
pub use observed::{local_slope, Observed};
pub use on_form::Untellable;
pub use search::diagnose;

use crate::fit::motion::{Motion, Run};
use crate::fit::zero::{fit_with_zero, FinalSolve};
use crate::fit::{fit, FitError, FitOptions};
use crate::input::{Dataset, Recording};
use crate::prepare::{prepare, reversals, OfflineRun, OriginSource, RunOrigin, SegmentError};
use model_core::{GearModel, Kind, Params};
use serde::Serialize;

/// ΔBIC an effect must reach.
pub const MIN_BIC_DROP: f64 = 10.0;
/// Share of the weighted residual an effect must explain.
pub const MIN_EXPLAINED: f64 = 0.05;
/// Significance each half must show.
pub const MIN_HALF_Z: f64 = 3.0;

/// A share below `limit` in percent, with the decimals that keep it below the limit as printed:
/// "4.98 %, less than 5 %", not "5.0 %, less than 5 %" (a new user's trial).
pub(crate) fn share_below(share: f64, limit: f64) -> String {
    let (percent, limit) = (100.0 * share, 100.0 * limit);
    let decimals =
        (1..4).find(|&d| format!("{percent:.d$}", d = d).parse::<f64>().is_ok_and(|p| p < limit)).unwrap_or(4);
    format!("{percent:.decimals$}")
}

/// Largest difference of the halves' magnitudes, relative to their mean.
pub const MAX_HALF_SPREAD: f64 = 0.5;

/// Two magnitudes of one effect differ: in sign, or by more than [`MAX_HALF_SPREAD`] of their
/// mean.
fn magnitudes_differ(a: f64, b: f64) -> bool {
    a.signum() != b.signum() || (a - b).abs() > MAX_HALF_SPREAD * (a + b).abs() / 2.0
}

/// Two estimates with their standard errors disagree: [`MIN_HALF_Z`] standard errors of their
/// difference apart, and their magnitudes differ ([`magnitudes_differ`]). Both, since a rate too
/// slow to show an effect agrees with anything, and a form's own misfit moves an estimate by
/// more than its error.
fn estimates_disagree(a: f64, error_a: f64, b: f64, error_b: f64) -> bool {
    (a - b).abs() / error_a.hypot(error_b) > MIN_HALF_Z && magnitudes_differ(a, b)
}

/// `weights` on `samples` alone, 0 elsewhere: a fit of those samples that follows the others.
fn weights_on(weights: &[f64], samples: impl IntoIterator<Item = usize>) -> Vec<f64> {
    let mut alone = vec![0.0; weights.len()];
    for i in samples {
        alone[i] = weights[i];
    }
    alone
}

/// The numbers behind accepting or rejecting an effect.
#[derive(Clone, Debug, Serialize)]
pub struct Evidence {
    /// Drop of the Bayesian information criterion, Δχ²/s² − p·ln n.
    pub delta_bic: f64,
    /// Share of the weighted residual the effect explains.
    pub explained: f64,
    /// Magnitude over its standard error on the whole recording.
    pub z: f64,
    /// Magnitudes fitted on each independent half alone.
    pub halves: Option<[f64; 2]>,
    pub halves_z: Option<[f64; 2]>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Finding {
    pub effect: Effect,
    pub magnitude: f64,
    pub unit: &'static str,
    pub meaning: &'static str,
    #[serde(rename = "where")]
    pub location: String,
    /// Unweighted RSS, (N·m)², before and after adding this effect.
    pub rss_before: f64,
    pub rss_after: f64,
    pub evidence: Evidence,
    /// It gives energy back over a cycle ([`Effect::gives_energy_back`]): the measurement, not
    /// the gear.
    pub active: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct Rejection {
    pub effect: Effect,
    pub reason: String,
    pub magnitude: f64,
    pub evidence: Evidence,
}

/// A torque the recording shows and the model keeps, whose mechanism it cannot tell: either
/// of two effects of the same form ([`Effect::rival`]), each with its magnitude fitted alone.
#[derive(Clone, Debug, Serialize)]
pub struct Undecided {
    pub effects: [Effect; 2],
    pub magnitudes: [f64; 2],
    pub units: [&'static str; 2],
    /// Why the data cannot tell, and what would.
    pub words: String,
    /// Unweighted RSS, (N·m)², before and after keeping it.
    pub rss_before: f64,
    pub rss_after: f64,
}

/// The result of [`diagnose`].
#[derive(Clone, Debug)]
pub struct Diagnosis {
    pub baseline: ExtendedFit,
    pub findings: Vec<Finding>,
    pub rejected: Vec<Rejection>,
    pub final_fit: ExtendedFit,
    pub weights: Vec<f64>,
    /// RMS on the held-out part, N·m, of the baseline and the final model fitted without it.
    pub held_out_rms: Option<(f64, f64)>,
    /// The baseline's form is what the recording disagrees with (then no effect is named).
    pub model_form: Option<form::ModelForm>,
    /// Torques kept in the final model without a name: either of two effects.
    pub undecided: Vec<Undecided>,
    /// Effects the named form cannot tell from this data, and why (not refused).
    pub untellable: Vec<Untellable>,
    /// Structure that neither the vocabulary nor a model kind explains.
    pub unexplained: Option<form::Unexplained>,
    /// The final model where it is the named form with the torque effects beside it (and a
    /// backlash named on it, run on the deflection it moves; not a kinematic error, which the
    /// form cannot take): its torque along the recording. `final_fit` is then the genetic model
    /// with the same effects, whose magnitudes the form's replace (its backlash's too).
    pub final_form: Option<FinalForm>,
}

impl Diagnosis {
    /// The effects the findings of form on the micro-slip form (asymmetry, Masing's rule) fit
    /// beside their forms: every effect of the final model, and the rival of each torque kept
    /// undecided (the kinks' scan takes the final model's own). A damping kept for a channel
    /// delay it could not be told from (one rate each way) misses the delay's torque where the
    /// stiffness changes; the Preisach cells took it up and named a catalogue gear's loops
    /// non-Masing (a new user's trial: ΔBIC 2562).
    pub fn beside_the_form(&self) -> Vec<Effect> {
        let mut effects = self.final_fit.active.clone();
        for rival in self.undecided.iter().map(|u| u.effects[1]) {
            if !effects.contains(&rival) {
                effects.push(rival);
            }
        }
        effects
    }
}

/// The named form with the torque effects beside it, as the final model.
#[derive(Clone, Debug)]
pub struct FinalForm {
    /// The model kind: `micro-slip`.
    pub kind: &'static str,
    /// The form fitted with them.
    pub along: FormAlong,
}

/// A form fitted with torque effects beside it: the form's model alone (θ0 = 0 on the
/// deflection as the diagnosis measures it, from the zero it read at rest, and moved by a
/// backlash named on the form), and the torque of the form with the effects at every sample, N·m.
#[derive(Clone, Debug)]
pub struct FormAlong {
    pub model: GearModel<f64>,
    pub predicted: Vec<f64>,
}

/// Why a diagnosis could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiagnoseError {
    #[error(transparent)]
    Segment(#[from] SegmentError),
    #[error("baseline fit failed: {0}")]
    Fit(#[from] FitError),
    #[error("the baseline parameters cannot be evaluated on this data: {0}")]
    Baseline(#[source] model_core::Error),
    #[error("the baseline model cannot be refitted with the effects' columns: {0}")]
    BaselineRefit(#[source] ExtendedFitError),
    #[error("the model (baseline{effects}) cannot be refitted: {source}")]
    Refit {
        effects: String,
        #[source]
        source: ExtendedFitError,
    },
}

/// Everything `swg-host diagnose` computes: what the data offer, the diagnosis, and the
/// residuals of the baseline and of the final model at every sample.
#[derive(Clone, Debug)]
pub struct DiagnoseOutcome {
    pub observed: Observed,
    pub diagnosis: Diagnosis,
    /// Measured minus baseline torque, N·m, every sample.
    pub before: Vec<f64>,
    /// Measured minus final-model torque, N·m, every sample.
    pub after: Vec<f64>,
    /// Where the baseline's residual concentrates.
    pub locate: Vec<Observation>,
    /// The energy the gear takes per closed loop, and whether the loop runs the active way.
    pub passivity: Option<passivity::Passivity>,
    /// The deflection's zero θ0 (and the torque) read in the recording's rest window, which the
    /// deflection was measured from; `None` without one.
    pub origin: Option<RunOrigin>,
    /// Whether the spring's two sides differ, about that zero.
    pub asymmetry: asymmetry::AsymmetryCheck,
    /// Whether the spring's stiffness steps at some deflections.
    pub kinks: kinks::KinksCheck,
    /// Whether the loops follow Masing's rule.
    pub non_masing: non_masing::NonMasingCheck,
    /// Whether loops run over and over drift.
    pub ratcheting: ratcheting::RatchetingCheck,
    /// Whether the recording starts at a standstill found in the data, not declared
    /// ([`OfflineRun::remanent_start`]): its hysteresis may start at a remanence.
    pub remanent_start: bool,
}

/// Where a recording's hysteresis state is known: from its first sample scored
/// ([`OfflineRun::scored_from`]: 0 from rest, else once the motion has visited both its
/// extremes), and whether it may start at a remanence ([`OfflineRun::remanent_start`]).
struct Start {
    known_from: usize,
    remanent: bool,
}

/// `dataset` with its deflection measured from its zero θ0 where it is a recording that starts
/// at rest: θ0 is what it reads there, as `fit` and `predict` place each run (without a rest,
/// the fitted zero of a recording centred off the encoders' zero, [`fitted_zero`]). The genetic
/// baseline is symmetric about θ = 0 and measures its loop's amplitude from there: on the
/// measured spring (θ0 = −8.4 mrad), unzeroed, the baseline left RMS 6.3 N·m on run 5-1 (6.5× what
/// the noise would), called the deflection 5.6 mrad from zero at its closest, and held out
/// 1.6·10⁵ N·m. The torque read at rest is reported, not removed: the `torque_offset` test
/// judges it with the rest of the effects.
///
/// Also where the hysteresis state is known ([`Start`]), and the torque read at rest with its
/// standard error (N·m), where the rest window is long enough to read it.
fn zeroed(dataset: Dataset) -> (Dataset, Option<RunOrigin>, Start, Option<(f64, f64)>) {
    match dataset {
        Dataset::Recording(mut recording) => {
            let run = OfflineRun::of(&recording);
            let origin = RunOrigin::at_rest(&run).or_else(|| fitted_zero(&recording, &run));
            if let Some(origin) = &origin {
                recording.deflection.iter_mut().for_each(|theta| *theta -= origin.zero_rad);
            }
            let rest_torque = run.rest.and_then(|rest| {
                rest.torque_nm.map(|torque| (torque, run.noise.torque_nm / (rest.samples.max(1) as f64).sqrt()))
            });
            let start = Start { known_from: run.scored_from, remanent: run.remanent_start };
            (Dataset::Recording(recording), origin, start, rest_torque)
        }
        table => (table, None, Start { known_from: 0, remanent: false }, None),
    }
}

/// How far off the encoders' zero a recording's deflection range must be centred, as a fraction
/// of its half-width, for `diagnose` to fit θ0 where no rest reads it ([`fitted_zero`]).
const OFF_CENTRE: f64 = 0.25;

/// θ0 of a recording that does not start at rest, as `fit` finds it for such a run (`fit::zero`:
/// where the kind's misfit is least, the encoders' zero unless another is significantly better),
/// by the genetic and the micro-slip kind, whichever fits the recording better. A recording that
/// starts mid-motion with its encoders zeroed 0.5 mrad off a 1 mrad loop of a micro-slip gear
/// had the symmetric genetic baseline fitted about the encoders' zero, and a damping of −1846
/// N·m·s/rad named that the gear does not have. One kind is not enough: the micro-slip kind
/// placed a genetic gear's zero 1 mrad off (and a torque offset of −19 N·m was named), and the
/// genetic kind a micro-slip gear's 0.07 mrad off.
///
/// Only where the deflection's range is centred off the encoders' zero by more than
/// [`OFF_CENTRE`] of its half-width: fitted on every recording without a rest, the zero moved
/// within its error on the corpus' gears zeroed right, and the effects judged about it went
/// from 58 to 53 right on seed 0, with false alarms (`tests/diagnose_corpus.rs`).
fn fitted_zero(recording: &Recording, run: &OfflineRun) -> Option<RunOrigin> {
    let scored = recording.deflection.get(run.scored_from..)?;
    let (lo, hi) = scored.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    if run.reversals.indices.is_empty() || !((lo + hi).abs() > OFF_CENTRE * (hi - lo)) {
        return None;
    }
    let fitted = Run::fitted_from(&recording.deflection, &recording.torque, &run.reversals, run.scored_from);
    let motion = Motion { runs: vec![fitted], noise: Some(run.noise), rest_jitter: 0.0 };
    let options = FitOptions { noise: Some(run.noise), ..Default::default() };
    let by = |kind: Kind| fit_with_zero(kind, &motion, &[None], &options, FinalSolve::Strided).ok();
    let (genetic, micro_slip) = rayon::join(|| by(Kind::Genetic), || by(Kind::MicroSlip));
    let (_, origins) = [genetic, micro_slip].into_iter().flatten().min_by(|(a, _), (b, _)| a.rss.total_cmp(&b.rss))?;
    origins.first().copied()
}

/// The `diagnose` pipeline: prepare the data, fit the baseline (unless `baseline` is given),
/// search for missing physics, and say where the baseline's residual concentrates. Takes the
/// dataset: the observations keep the recording's time and input angle, and its other columns
/// are freed before the search (at 10 M samples, 24 bytes a sample less at the peak).
pub fn diagnose_dataset(
    dataset: Dataset,
    baseline: Option<Params<f64>>,
    seed: u64,
) -> Result<DiagnoseOutcome, DiagnoseError> {
    let (dataset, origin, start, rest_torque) = zeroed(dataset);
    let known_state_from = start.known_from;
    let mut prepared = prepare(&dataset)?;
    let baseline = match baseline {
        Some(params) => params,
        None => {
            let options = FitOptions { seed, noise: prepared.noise, ..Default::default() };
            fit(&prepared.data, &options, |_| {})?.params
        }
    };
    // From the recording's own columns, before the observations take what they keep of it.
    let passivity = match (&dataset, &prepared.segmentation, &prepared.noise) {
        (Dataset::Recording(recording), Some(segmentation), Some(noise)) => {
            Some(passivity::of_recording(recording, &segmentation.turning_points, noise))
        }
        (Dataset::LoopTable(table), _, _) => passivity::of_loop_table(table),
        _ => None,
    };
    // The diagnosis holds the samples once: moved from `prepared`, not copied.
    let data = std::mem::take(&mut prepared.data);
    let mut observed = Observed::with_data(dataset, &prepared, data, known_state_from);
    observed.rest_torque = rest_torque;
    if let Some(RunOrigin { zero_rad, zero_se_rad, source: OriginSource::Fitted, .. }) = origin {
        // A zero fitted where no rest reads it moves the loop as an offset does (by K·Δθ0): a
        // measured run cut before its rest read 4.2 N·m of offset about a zero fitted 1.6 mrad
        // from its rest (a new user's trial). `fit` takes the offset as 0 there too.
        observed.cannot_reveal.push((
            Effect::TorqueOffset,
            format!(
                "the deflection's zero is fitted ({:.4} ± {:.4} mrad: no rest before the motion), and an offset \
                 moves the loop as a zero off by offset/stiffness does: record the gear standing still before the \
                 motion",
                1e3 * zero_rad,
                1e3 * zero_se_rad.unwrap_or(0.0)
            ),
        ));
    }
    let diagnosis = diagnose(&observed, baseline)?;
    let before = diagnosis.baseline.residuals(&observed, observed.samples()).map_err(DiagnoseError::Baseline)?;
    let after = match &diagnosis.final_form {
        Some(form) => observed.data.torque.iter().zip(&form.along.predicted).map(|(t, p)| t - p).collect(),
        None => {
            diagnosis.final_fit.residuals(&observed, observed.samples()).map_err(|source| DiagnoseError::Refit {
                effects: diagnosis.final_fit.active.iter().map(|e| format!(" + {}", e.name())).collect(),
                source: source.into(),
            })?
        }
    };
    let locate = locate(&observed, &before);
    let beside = diagnosis.beside_the_form();
    // About a zero read at rest only: a fitted one is where the symmetric kinds fit best (a new
    // user's trial: measured runs cut before their rest read +1.2 to +3.5 % about theirs).
    let read_zero = origin.filter(|o| o.source != OriginSource::Fitted);
    let asymmetry =
        asymmetry::check(&observed, &diagnosis.weights, &beside, read_zero.map(|o| o.zero_se_rad.unwrap_or(0.0)));
    // Side by side: the kinks' scan runs on one core (one run's normal equations).
    let (kinks, non_masing) = rayon::join(
        || kinks::check(&observed, &diagnosis.weights, &diagnosis.final_fit),
        || non_masing::check(&observed, &diagnosis.weights, &beside),
    );
    let ratcheting = match (&observed.time, &observed.noise) {
        // A torque that drifts with the temperature drifts at the turning points too: where the
        // recording warms and no thermal drift is in the model, the two cannot be told apart (a
        // warming micro-slip gear whose thermal drift the search refused was named ratcheting).
        (Some(_), Some(_))
            if observed.warming.is_some() && !diagnosis.final_fit.active.contains(&Effect::ThermalDrift) =>
        {
            ratcheting::RatchetingCheck::No {
                why: "the temperature changes over the recording and no thermal drift is in the model: a drift of the \
                      loops cannot be told from the torque's drift with the temperature"
                    .to_string(),
            }
        }
        (Some(time), Some(noise)) => {
            let theta = &observed.data.theta;
            ratcheting::check(time, theta, &observed.data.torque, &reversals(theta), &after, noise.deflection_rad)
        }
        _ => ratcheting::RatchetingCheck::No { why: "a loop table holds one loop, not its cycles".to_string() },
    };
    Ok(DiagnoseOutcome {
        observed,
        diagnosis,
        before,
        after,
        locate,
        passivity,
        origin,
        asymmetry,
        kinks,
        non_masing,
        ratcheting,
        remanent_start: start.remanent,
    })
}

#[cfg(test)]
mod tests {
    use super::share_below;

    #[test]
    fn a_share_below_the_limit_is_printed_below_it() {
        assert_eq!(share_below(0.032, 0.05), "3.2");
        assert_eq!(share_below(0.0498, 0.05), "4.98");
        assert_eq!(share_below(0.04996, 0.05), "4.996");
    }
}
