//! A rate effect across runs recorded at different rates. A run at one rate cannot tell damping
//! or a channel delay from hysteresis (the loop opens alike at that rate), and its report asks
//! for "the same loop at a second rate". Runs at different rates can: a rate-independent
//! hysteresis opens every run's loop alike, damping and a delay in proportion to the rate.
//!
//! The test form is Masing's of [`super::non_masing::check_runs`] (every slip element of the
//! grid, either sign: any rate-independent Masing hysteresis), on every run at once, each from
//! rest, each with its own torque offset and its accepted effects. A rate effect is one column
//! with one coefficient for all the runs: the deflection rate (damping, N·m·s/rad), or −dT/dt,
//! each run's own micro-slip torque differentiated in time (a channel delay, s). The one that explains
//! more is named on the tests of one run's search, with runs in the place of samples:
//! - the information criterion drops by more than [`MIN_BIC_DROP`], it explains at least
//!   [`MIN_EXPLAINED`] of the form's weighted residual, and the form with it leaves at most
//!   [`STRUCTURE_FACTOR`] times the noise;
//! - its rival in its place fits worse by more than [`MIN_BIC_DROP`] (else it is kept undecided
//!   between the two);
//! - the slower and the faster runs, each fitted alone, do not disagree
//!   ([`estimates_disagree`]): a rate too slow to show it agrees with anything;
//! - the runs held out one by one (each fitted on the others) are predicted better with it.
use super::effects::Effect;
use super::form::{delay_on_the_form, torque_column, STRUCTURE_FACTOR};
use super::non_masing::RunOfMany;
use super::observed::MIN_RATE_SPREAD;
use super::{estimates_disagree, share_below, weights_on, MIN_BIC_DROP, MIN_EXPLAINED};
use crate::fit::motion::{masing_form_of_runs, FormFit, FormRun};
use crate::gear::Reversals;
use crate::prepare::{reversals, NoiseModel};
use rayon::prelude::*;
use serde::Serialize;

/// What the runs at different rates show of a rate effect.
#[derive(Clone, Debug, Serialize)]
pub struct RateAcross {
    /// Each run's rate: the median of its motion's instantaneous frequency, rad/s.
    #[serde(rename = "frequencies_rad_per_s")]
    pub frequencies: Vec<Option<f64>>,
    #[serde(flatten)]
    pub verdict: RateVerdict,
}

/// The test's outcome.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum RateVerdict {
    /// Named, with its magnitude on the form and its standard error, in its unit; the slower
    /// and faster runs' own estimates.
    Named { effect: Effect, magnitude: f64, error: f64, delta_bic: f64, explained: f64, slow_fast: [f64; 2] },
    /// A rate effect the runs show, whose mechanism they cannot tell: either of two, each
    /// magnitude in its place.
    Undecided { effects: [Effect; 2], magnitudes: [f64; 2], delta_bic: f64, explained: f64 },
    /// The best of them, refused, and why.
    Refused { effect: Effect, magnitude: f64, why: String },
    /// Not tested, and why.
    Untested { why: String },
}

/// The rate effects tested.
const RATE_EFFECTS: [Effect; 2] = [Effect::ViscousDamping, Effect::ChannelDelay];

/// Tests a rate effect across `runs`, where some run could not reveal one alone; `None` where
/// every run could (each run's own search tried them).
pub fn check(runs: &[RunOfMany]) -> Option<RateAcross> {
    let untold = |run: &RunOfMany| run.observed.cannot_reveal.iter().any(|(e, _)| *e == Effect::ViscousDamping);
    if runs.len() < 2 || !runs.iter().any(untold) {
        return None;
    }
    let frequencies: Vec<Option<f64>> = runs.iter().map(|run| run.observed.frequency).collect();
    let verdict = verdict(runs, &frequencies);
    Some(RateAcross { frequencies, verdict })
}

/// The runs as the test form sees them: reversals, weights from the known state on, own columns.
struct Setting<'a> {
    runs: &'a [RunOfMany<'a>],
    reversals: Vec<Reversals>,
    weights: Vec<Vec<f64>>,
    /// Each run's own columns: a torque offset and its accepted effects but the rate effects.
    own: Vec<Vec<Vec<f64>>>,
    /// Each rate effect's column along each run.
    candidates: Vec<(Effect, Vec<Vec<f64>>)>,
    noise: NoiseModel,
}

impl Setting<'_> {
    /// Masing's form on the runs `fitted` (the others followed at weight 0), with the shared
    /// column of `effect` where given: its fit, the samples it weighs, and its last coefficient.
    fn fit(&self, fitted: &[usize], effect: Option<Effect>) -> Option<(FormFit, usize)> {
        let zeros: Vec<Vec<f64>> = self.weights.iter().map(|w| vec![0.0; w.len()]).collect();
        let shared = effect.and_then(|e| self.candidates.iter().find(|(c, _)| *c == e)).map(|(_, columns)| columns);
        let form_runs: Vec<FormRun> = self
            .runs
            .iter()
            .enumerate()
            .map(|(k, run)| {
                let mut extra: Vec<&[f64]> = fitted
                    .iter()
                    .flat_map(|&j| self.own[j].iter().map(move |c| if j == k { c.as_slice() } else { &[][..] }))
                    .collect();
                extra.extend(shared.map(|columns| columns[k].as_slice()));
                FormRun {
                    theta: &run.observed.data.theta,
                    torque: &run.observed.data.torque,
                    reversals: &self.reversals[k],
                    weights: if fitted.contains(&k) { &self.weights[k] } else { &zeros[k] },
                    extra,
                    remanent_start: run.remanent_start,
                }
            })
            .collect();
        let fit = masing_form_of_runs(&form_runs, Some(self.noise)).ok()?;
        let count = fitted.iter().map(|&k| self.weights[k].iter().filter(|&&w| w > 0.0).count()).sum();
        Some((fit, count))
    }

    /// The shared coefficient of `effect` on the runs `fitted`, and its standard error from the
    /// likelihood ratio against the form without it.
    fn estimate(&self, fitted: &[usize], effect: Effect) -> Option<(f64, f64)> {
        let ((with, n), (without, _)) = (self.fit(fitted, Some(effect))?, self.fit(fitted, None)?);
        let variance = with.chi2 / (n as f64 - with.parameters as f64).max(1.0);
        let z = ((without.chi2 - with.chi2).max(0.0) / variance).sqrt();
        let magnitude = *with.extra.last()?;
        Some((magnitude, if z > 0.0 { (magnitude / z).abs() } else { f64::INFINITY }))
    }

    /// The sum of squared residuals of the runs held out one by one (each about its own mean:
    /// its offset is not known to a fit without it), with and without `effect`.
    fn held_out(&self, effect: Effect) -> Option<[f64; 2]> {
        let all: Vec<usize> = (0..self.runs.len()).collect();
        let per_run: Option<Vec<[f64; 2]>> = all
            .par_iter()
            .map(|&k| {
                let others: Vec<usize> = all.iter().copied().filter(|&j| j != k).collect();
                let start: usize = self.weights[..k].iter().map(Vec::len).sum();
                let at: Vec<usize> = (0..self.weights[k].len()).filter(|&i| self.weights[k][i] > 0.0).collect();
                let spread = |fit: &FormFit| {
                    let torque = &self.runs[k].observed.data.torque;
                    let residual: Vec<f64> = at.iter().map(|&i| torque[i] - fit.predicted[start + i]).collect();
                    let mean = residual.iter().sum::<f64>() / residual.len().max(1) as f64;
                    residual.iter().map(|r| (r - mean).powi(2)).sum::<f64>()
                };
                let (with, _) = self.fit(&others, Some(effect))?;
                let (without, _) = self.fit(&others, None)?;
                Some([spread(&without), spread(&with)])
            })
            .collect();
        per_run.map(|runs| runs.iter().fold([0.0; 2], |[a, b], [x, y]| [a + x, b + y]))
    }
}

fn verdict(runs: &[RunOfMany], frequencies: &[Option<f64>]) -> RateVerdict {
    let untested = |why: String| RateVerdict::Untested { why };
    let known: Vec<f64> = frequencies.iter().flatten().copied().collect();
    let (slowest, fastest) = known.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &f| (lo.min(f), hi.max(f)));
    if known.len() < runs.len() || !(fastest >= MIN_RATE_SPREAD * slowest) {
        return untested(format!(
            "the runs are recorded at one rate (their frequencies spread {:.2}×, {MIN_RATE_SPREAD}× needed): record \
             the same loop at half and at twice the frequency",
            fastest / slowest
        ));
    }
    let noises: Option<Vec<NoiseModel>> = runs.iter().map(|run| run.observed.noise).collect();
    let Some(noises) = noises else { return untested("a run gives no noise estimate to judge it by".into()) };
    let noise = noises.iter().fold(NoiseModel { torque_nm: 0.0, deflection_rad: 0.0 }, |a, b| NoiseModel {
        torque_nm: a.torque_nm.max(b.torque_nm),
        deflection_rad: a.deflection_rad.max(b.deflection_rad),
    });
    let reversals: Vec<Reversals> = runs.iter().map(|run| reversals(&run.observed.data.theta)).collect();
    let weights: Vec<Vec<f64>> =
        runs.iter().map(|run| weights_on(run.weights, run.observed.known_state_from..run.weights.len())).collect();
    let own: Vec<Vec<Vec<f64>>> = runs
        .iter()
        .map(|run| {
            let constant = vec![1.0; run.observed.data.theta.len()];
            let effects = run.active.iter().filter(|e| !e.is_rate_dependent() && **e != Effect::TorqueOffset);
            std::iter::once(constant).chain(effects.filter_map(|&effect| torque_column(run.observed, effect))).collect()
        })
        .collect();
    let candidates: Option<Vec<(Effect, Vec<Vec<f64>>)>> = RATE_EFFECTS
        .iter()
        .map(|&effect| {
            let columns: Option<Vec<Vec<f64>>> = runs
                .iter()
                .zip(&reversals)
                .map(|(run, reversals)| match effect {
                    Effect::ChannelDelay => delay_on_the_form(run.observed, reversals, noise, run.weights, &[]),
                    _ => torque_column(run.observed, effect),
                })
                .collect();
            columns.map(|columns| (effect, columns))
        })
        .collect();
    let Some(candidates) = candidates else { return untested("a run gives no deflection rate".into()) };
    let setting = Setting { runs, reversals, weights, own, candidates, noise };
    let all: Vec<usize> = (0..runs.len()).collect();
    let Some((base, n)) = setting.fit(&all, None) else {
        return untested("the form cannot be fitted to these runs".into());
    };
    let fits: Option<Vec<(Effect, FormFit)>> =
        RATE_EFFECTS.par_iter().map(|&e| setting.fit(&all, Some(e)).map(|(fit, _)| (e, fit))).collect();
    let Some(mut fits) = fits else { return untested("the form cannot be fitted with a rate effect".into()) };
    fits.sort_by(|a, b| a.1.chi2.total_cmp(&b.1.chi2));
    let Ok([(effect, best), (rival, second)]) = <[(Effect, FormFit); 2]>::try_from(fits) else {
        return untested("the form cannot be fitted with each rate effect".into());
    };
    let variance = best.chi2 / (n as f64 - best.parameters as f64).max(1.0);
    let drop = (base.chi2 - best.chi2).max(0.0);
    let delta_bic = drop / variance - (n as f64).ln();
    let explained = drop / base.chi2;
    let magnitude = best.extra.last().copied().unwrap_or(0.0);
    // Every refusal says how well the form describes the runs: where it leaves structure, an
    // effect is judged against a misfit (the genetic gear's loops, sharper at their tips than
    // the slip elements follow: a damping of 25 N·m·s/rad read 24.7 and explained 0.2 %).
    let leaves = variance.sqrt();
    let refused = |why: String| RateVerdict::Refused {
        effect,
        magnitude,
        why: format!("{why} (the form with it leaves {leaves:.1}× the noise)"),
    };
    if !(delta_bic > MIN_BIC_DROP) {
        return refused(format!("ΔBIC {delta_bic:.1}, not above {MIN_BIC_DROP}"));
    }
    if explained < MIN_EXPLAINED {
        return refused(format!(
            "explains {} % of the form's residual, less than {:.0} %",
            share_below(explained, MIN_EXPLAINED),
            100.0 * MIN_EXPLAINED
        ));
    }
    if !(leaves <= STRUCTURE_FACTOR) {
        return refused(format!("over {STRUCTURE_FACTOR}× the noise: no form here to judge it on"));
    }
    // The slower and the faster runs, by their rate.
    let mut by_rate = all.clone();
    by_rate.sort_by(|&a, &b| frequencies[a].unwrap_or(0.0).total_cmp(&frequencies[b].unwrap_or(0.0)));
    let (slow, fast) = by_rate.split_at(by_rate.len() / 2);
    let (Some((ms, es)), Some((mf, ef))) = (setting.estimate(slow, effect), setting.estimate(fast, effect)) else {
        return refused("the slower and the faster runs cannot each be fitted alone".into());
    };
    if estimates_disagree(ms, es, mf, ef) {
        return refused(format!(
            "{ms:.4e} {unit} on the slower runs and {mf:.4e} {unit} on the faster: the loop's opening does not scale \
             with the rate",
            unit = effect.unit()
        ));
    }
    match setting.held_out(effect) {
        Some([without, with]) if with < without => {}
        Some([without, with]) => {
            return refused(format!(
                "the runs held out (each fitted on the others) are not predicted better with it (RSS {without:.4} → \
                 {with:.4} (N·m)²)"
            ))
        }
        None => return refused("the runs held out could not be fitted without them".into()),
    }
    if (second.chi2 - best.chi2) / variance <= MIN_BIC_DROP {
        let rival_magnitude = second.extra.last().copied().unwrap_or(0.0);
        return RateVerdict::Undecided {
            effects: [effect, rival],
            magnitudes: [magnitude, rival_magnitude],
            delta_bic,
            explained,
        };
    }
    let z = (drop / variance).sqrt();
    RateVerdict::Named {
        effect,
        magnitude,
        error: if z > 0.0 { (magnitude / z).abs() } else { f64::INFINITY },
        delta_bic,
        explained,
        slow_fast: [ms, mf],
    }
}
