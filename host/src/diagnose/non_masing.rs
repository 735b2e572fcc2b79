//! A finding of form: whether the gear's loops follow Masing's rule (`non_masing`).
//!
//! Masing's rule, with Madelung's for any history: the branch after a reversal is a function of
//! the travel since that reversal, so the large loop fixes every loop inside it, wherever it
//! sits and whatever its size. The micro-slip kind follows it; a Preisach density that changes
//! with the relays' centre, Bouc–Wen, peak-oriented materials and the genetic kind's inner
//! branches (each shaped by the turning point it heads for) do not.
//!
//! The test compares two nested forms ([`masing_forms_with_columns`]), with the accepted torque
//! effects beside both: Masing's (the micro-slip kind's slip elements, each split into its
//! travel on rising and on falling legs, with the spring, every coefficient of either sign, so
//! that one loop of any shape is followed), and the free form, which adds the Preisach kind's
//! cells: relays that switch at places on the loop, not at a travel from the last reversal.
//! What the cells fit better is how the loops differ from what Masing's rule makes of one
//! another. It is named on an effect's tests: the information criterion drops by more than
//! [`MIN_BIC_DROP`] for the cells' weights, they explain at least [`MIN_EXPLAINED`] of Masing's
//! weighted residual, the free form predicts the held-out cycles (fitted without them) better,
//! and each independent part of the recording, fitted alone, shows it by the same two tests;
//! and only where the free form describes the recording, its weighted residual within
//! [`STRUCTURE_FACTOR`] of the noise (else what the cells add may be a shape that neither
//! form has). A motion that runs one loop over and over cannot show it and is not tested
//! ([`one_loop`]): one loop of any shape follows Masing's rule.
//!
//! Its magnitude is the torque Masing's rule misses: the RMS difference between the two forms
//! along the recording, N·m.
use super::effects::Effect;
use super::form::{columns_of, STRUCTURE_FACTOR};
use super::observed::Observed;
use super::{share_below, weights_on, MIN_BIC_DROP, MIN_EXPLAINED};
use crate::fit::motion::{masing_forms_of_runs, masing_forms_with_columns, FormFit, FormRun};
use crate::gear::Reversals;
use crate::prepare::{reversals, NoiseModel};
use rayon::prelude::*;
use serde::Serialize;

/// The loops against Masing's rule, measured and tested.
#[derive(Clone, Debug, Serialize)]
pub struct NonMasing {
    /// The torque Masing's rule misses: the RMS difference between the free form and Masing's
    /// along the recording, N·m.
    pub magnitude_nm: f64,
    /// Drop of the information criterion from Masing's form to the free one.
    pub delta_bic: f64,
    /// Share of Masing's weighted residual that the free form explains.
    pub explained: f64,
    /// The free form's weighted residual against the noise's (1: the noise alone).
    pub free_to_noise: f64,
    /// RMS on the held-out cycles of each form fitted without them, N·m: Masing's, free.
    pub held_out_rms: Option<[f64; 2]>,
    /// The information criterion's drop and the share explained on each part alone.
    pub halves: Option<[[f64; 2]; 2]>,
    /// Runs whose start state both forms estimated: they start still, at a standstill found in
    /// the data, where the motion before may have left a remanence (0 on one recording).
    pub remanent_starts: usize,
    /// Why it is not named; `None` when it is.
    pub rejected: Option<String>,
    /// The torque of each form fitted on every sample, N·m, at every sample (0 before the
    /// hysteresis state is known): Masing's and the free one's, for the picture.
    #[serde(skip)]
    pub torque: [Vec<f64>; 2],
}

/// Whether the loops were tested against Masing's rule, and what they showed.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "tested", rename_all = "snake_case")]
pub enum NonMasingCheck {
    /// Tested: named when `rejected` is `None`.
    Yes(NonMasing),
    /// Not tested, and why.
    No { why: String },
}

impl NonMasingCheck {
    /// The departure from Masing's rule, when it was tested and named.
    pub fn named(&self) -> Option<&NonMasing> {
        match self {
            NonMasingCheck::Yes(found) if found.rejected.is_none() => Some(found),
            _ => None,
        }
    }
}

/// Turning points within this share of the deflection's range of its largest or smallest value
/// are on the one loop a motion runs.
pub const SAME_LOOP: f64 = 0.05;

/// Whether every turning point from sample `from` on lies within [`SAME_LOOP`] of the range of
/// the deflection's largest value (a maximum) or its smallest (a minimum): one loop, run over
/// and over. On such a loop the forms differ only in the shapes their columns can take (the
/// corpus' genetic gears, whose loops are sharper at their tips than the slip elements' grid
/// follows: the cells fitted them better on 27 of 58 recordings of seed 3000).
fn one_loop(theta: &[f64], turning_points: &[usize], from: usize) -> bool {
    let (lo, hi) = theta[from.min(theta.len())..]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    let tolerance = SAME_LOOP * (hi - lo);
    turning_points.iter().filter(|&&i| i >= from).all(|&i| theta[i] >= hi - tolerance || theta[i] <= lo + tolerance)
}

/// The two forms fitted on the samples of nonzero weight.
struct Pair {
    masing: FormFit,
    free: FormFit,
    /// Samples fitted.
    fitted: usize,
}

impl Pair {
    /// The free form's weighted residual per degree of freedom: 1 where it leaves the noise.
    fn variance(&self) -> f64 {
        self.free.chi2 / (self.fitted as f64 - self.free.parameters as f64).max(1.0)
    }

    /// Why the forms fitted on every sample do not name it, on the tests of the whole data
    /// (before the held-out samples and the parts); `None` when they pass.
    fn refusal(&self) -> Option<String> {
        let [delta_bic, explained] = self.evidence();
        let free_to_noise = self.variance().sqrt();
        if delta_bic < 0.0 {
            Some(format!(
                "the information criterion rises by {:.1} with the cells (it must drop by more than {MIN_BIC_DROP})",
                -delta_bic
            ))
        } else if !(delta_bic > MIN_BIC_DROP) {
            Some(format!(
                "the information criterion drops by {delta_bic:.1} (it must drop by more than {MIN_BIC_DROP})"
            ))
        } else if explained < MIN_EXPLAINED {
            Some(format!(
                "the free form explains {} % of Masing's residual, less than {:.0} %",
                share_below(explained, MIN_EXPLAINED),
                100.0 * MIN_EXPLAINED
            ))
        } else if !(free_to_noise <= STRUCTURE_FACTOR) {
            Some(format!(
                "the free form leaves {free_to_noise:.1}× the noise: neither form describes the loops, and what it \
                 fits better may be a shape that neither has, not Masing's rule"
            ))
        } else {
            None
        }
    }

    /// Drop of the information criterion from Masing's form to the free one, and the share of
    /// Masing's weighted residual it explains.
    fn evidence(&self) -> [f64; 2] {
        let extra = self.free.parameters.saturating_sub(self.masing.parameters) as f64;
        let drop = self.masing.chi2 - self.free.chi2;
        [drop / self.variance() - extra * (self.fitted as f64).ln(), drop / self.masing.chi2]
    }
}

/// Tests the loops of `observed` against Masing's rule, with the accepted effects `active` beside
/// both forms and the search's `weights` (1/σ² of each sample's noise), on the samples from
/// [`Observed::known_state_from`] on: the forms run from rest, and before that sample a recording that does
/// not start at rest holds a hysteresis state they do not know.
pub fn check(observed: &Observed, weights: &[f64], active: &[Effect]) -> NonMasingCheck {
    let known_state_from = observed.known_state_from;
    let untested = |why: &str| NonMasingCheck::No { why: why.to_string() };
    if observed.time.is_none() {
        return untested("a loop table holds one loop, which both forms follow alike");
    }
    let Some(noise) = observed.noise else { return untested("the data give no noise estimate to judge it by") };
    let data = &observed.data;
    let reversals = reversals(&data.theta);
    if one_loop(&data.theta, &reversals.indices, known_state_from) {
        return untested(
            "the motion runs one loop (every turning point at its largest or smallest deflection): Masing's rule \
             relates loops of different sizes or places, and one loop of any shape follows it; record small loops \
             inside a large one, a biased oscillation or several amplitudes",
        );
    }
    let mut columns = columns_of(observed, &reversals, noise, weights, active);
    // A torque offset beside both forms always, as beside the kinks' scan and the asymmetry's
    // springs: the cells took one up that the search could not tell without the torque read at
    // rest, and named a micro-slip gear with 0.3 N·m non-Masing (ΔBIC 16374, a new user's trial).
    if !active.contains(&Effect::TorqueOffset) {
        columns.push((Effect::TorqueOffset, vec![1.0; data.theta.len()]));
    }
    let extra: Vec<&[f64]> = columns.iter().map(|(_, c)| c.as_slice()).collect();
    let pair = |weights: &[f64]| -> Option<Pair> {
        let [masing, free] =
            masing_forms_with_columns(&data.theta, &data.torque, &reversals, Some(noise), weights, &extra).ok()?;
        Some(Pair { masing, free, fitted: weights.iter().filter(|&&w| w > 0.0).count() })
    };
    let known = |i: usize| i >= known_state_from;
    let only = |samples: &[usize]| weights_on(weights, samples.iter().copied().filter(|&i| known(i)));
    let held_out: Vec<usize> = observed.held_out().iter().copied().filter(|&i| known(i)).collect();
    // One pair at a time (each pair's two forms side by side, which keeps both cores busy):
    // each form holds its torque at every sample, 16 bytes a sample a pair; the whole
    // recording's pair is kept for the picture.
    let Some(whole) = pair(&only(observed.samples())) else {
        return untested("the forms cannot be fitted to this data");
    };
    let [delta_bic, explained] = whole.evidence();
    let free_to_noise = whole.variance().sqrt();
    let scored = (known_state_from..data.torque.len()).filter(|&i| weights[i] > 0.0);
    let (sum, count) = scored.fold((0.0, 0usize), |(sum, count), i| {
        (sum + (whole.free.predicted[i] - whole.masing.predicted[i]).powi(2), count + 1)
    });
    let magnitude_nm = (sum / count.max(1) as f64).sqrt();
    let early = whole.refusal();
    let torque = [whole.masing.predicted, whole.free.predicted];
    // The held-out cycles and the parts are fitted only where the rest passes: four more pairs.
    let (held_out_rms, halves) = match early {
        Some(_) => (None, None),
        None => {
            let held_out_rms =
                (!held_out.is_empty()).then(|| pair(&only(&observed.training()))).flatten().map(|trained| {
                    let rms = |fit: &FormFit| {
                        (held_out.iter().map(|&i| (data.torque[i] - fit.predicted[i]).powi(2)).sum::<f64>()
                            / held_out.len() as f64)
                            .sqrt()
                    };
                    [rms(&trained.masing), rms(&trained.free)]
                });
            let halves: Option<Vec<[f64; 2]>> =
                observed.parts.iter().map(|part| pair(&only(part)).map(|p| p.evidence())).collect();
            (held_out_rms, halves.and_then(|h| <[[f64; 2]; 2]>::try_from(h).ok()))
        }
    };
    let rejected = early.or_else(|| match (held_out_rms, halves) {
        (Some([masing, free]), _) if !(free < masing) => Some(format!(
            "the free form does not predict the held-out cycles better ({free:.4} against {masing:.4} N·m)"
        )),
        (_, None) => Some("the two parts of the recording cannot each be fitted alone".to_string()),
        (_, Some(parts)) => not_in_each(parts, "of the recording"),
    });
    NonMasingCheck::Yes(NonMasing {
        magnitude_nm,
        delta_bic,
        explained,
        free_to_noise,
        held_out_rms,
        halves,
        remanent_starts: 0,
        rejected,
        torque,
    })
}

/// Why the two parts (`which`) do not each show it, by the evidence of each: `None` when each
/// drops the information criterion by more than [`MIN_BIC_DROP`] and explains [`MIN_EXPLAINED`].
fn not_in_each(parts: [[f64; 2]; 2], which: &str) -> Option<String> {
    parts.iter().any(|&[bic, share]| !(bic > MIN_BIC_DROP) || share < MIN_EXPLAINED).then(|| {
        format!(
            "not shown by each part {which} alone (ΔBIC {:.0} and {:.0}, explained {:.1} % and {:.1} %)",
            parts[0][0],
            parts[1][0],
            100.0 * parts[0][1],
            100.0 * parts[1][1]
        )
    })
}

/// One run of [`check_runs`]: its observations (with the first sample whose hysteresis state is
/// known), the search's weights, the effects accepted on it and whether it may start at a
/// remanence.
pub struct RunOfMany<'a> {
    pub observed: &'a Observed,
    pub weights: &'a [f64],
    pub active: &'a [Effect],
    /// Whether it starts at a standstill found in the data, its start state estimated
    /// ([`crate::prepare::OfflineRun::remanent_start`]).
    pub remanent_start: bool,
}

/// Tests the loops of several runs of one gear against Masing's rule: the two forms of [`check`]
/// fitted on every run at once, one spring and one hysteresis, with each run's own torque offset
/// and accepted effects beside them. Each run starts from rest, or at a start state the forms
/// estimate where it starts at a standstill found in the data: a remanence that the forms run
/// from rest cannot follow is not a departure from Masing's rule. A run at each amplitude is
/// what Masing's rule relates; runs that each run one loop, all between the same extremes,
/// cannot show it.
/// Named on [`check`]'s tests, with runs where it takes the recording's parts: the held-out
/// samples are whole runs (each run but the largest held out once, fitted on the others), and
/// the two parts are alternate runs, each of which must hold loops of more than one size.
pub fn check_runs(runs: &[RunOfMany]) -> NonMasingCheck {
    let untested = |why: &str| NonMasingCheck::No { why: why.to_string() };
    if runs.len() < 2 {
        return untested("one run");
    }
    let noises: Option<Vec<NoiseModel>> = runs.iter().map(|run| run.observed.noise).collect();
    let (Some(noises), true) = (noises, runs.iter().all(|run| run.observed.time.is_some())) else {
        return untested("a loop table, or a run without a noise estimate, is among the runs");
    };
    // The coarser noise of any run: the knot rule's spacing and the narrowest slip element
    // must hold on every run.
    let noise = noises.iter().fold(NoiseModel { torque_nm: 0.0, deflection_rad: 0.0 }, |a, b| NoiseModel {
        torque_nm: a.torque_nm.max(b.torque_nm),
        deflection_rad: a.deflection_rad.max(b.deflection_rad),
    });
    let reversals: Vec<Reversals> = runs.iter().map(|run| reversals(&run.observed.data.theta)).collect();
    // Each run's extent of known state: its smallest and largest deflection.
    let extents: Vec<[f64; 2]> = runs
        .iter()
        .map(|run| {
            let theta = &run.observed.data.theta[run.observed.known_state_from.min(run.observed.data.theta.len())..];
            theta.iter().fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], &t| [lo.min(t), hi.max(t)])
        })
        .collect();
    let one_loop_over = |members: &[usize]| {
        let (lo, hi) = members
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &k| (lo.min(extents[k][0]), hi.max(extents[k][1])));
        let tolerance = SAME_LOOP * (hi - lo);
        members.iter().all(|&k| {
            let run = &runs[k];
            one_loop(&run.observed.data.theta, &reversals[k].indices, run.observed.known_state_from)
                && (extents[k][0] - lo).abs() <= tolerance
                && (hi - extents[k][1]).abs() <= tolerance
        })
    };
    let all: Vec<usize> = (0..runs.len()).collect();
    if one_loop_over(&all) {
        return untested(
            "every run runs one loop between the same extremes: Masing's rule relates loops of different sizes; \
             record runs at several amplitudes",
        );
    }
    // Each run's own columns: a torque offset (a sensor zeroed as each log starts) and its
    // accepted effects, zero on the other runs.
    let own: Vec<Vec<Vec<f64>>> = runs
        .iter()
        .zip(&reversals)
        .zip(&noises)
        .map(|((run, reversals), &noise)| {
            let constant = vec![1.0; run.observed.data.theta.len()];
            let effects = columns_of(run.observed, reversals, noise, run.weights, run.active);
            std::iter::once(constant)
                .chain(effects.into_iter().filter(|(e, _)| *e != Effect::TorqueOffset).map(|(_, c)| c))
                .collect()
        })
        .collect();
    let known_weights: Vec<Vec<f64>> =
        runs.iter().map(|run| weights_on(run.weights, run.observed.known_state_from..run.weights.len())).collect();
    // The forms with the runs `fitted` weighted and the others followed at weight 0.
    let pair = |fitted: &[usize]| -> Option<Pair> {
        let zeros: Vec<Vec<f64>> = runs.iter().map(|run| vec![0.0; run.weights.len()]).collect();
        let form_runs: Vec<FormRun> = runs
            .iter()
            .enumerate()
            .map(|(k, run)| FormRun {
                theta: &run.observed.data.theta,
                torque: &run.observed.data.torque,
                reversals: &reversals[k],
                weights: if fitted.contains(&k) { &known_weights[k] } else { &zeros[k] },
                remanent_start: run.remanent_start,
                // The fitted runs' own columns only: a run followed at weight 0 gives its own none.
                extra: fitted
                    .iter()
                    .flat_map(|&j| own[j].iter().map(move |c| if j == k { c.as_slice() } else { &[][..] }))
                    .collect(),
            })
            .collect();
        let [masing, free] = masing_forms_of_runs(&form_runs, Some(noise)).ok()?;
        let count = fitted.iter().map(|&k| known_weights[k].iter().filter(|&&w| w > 0.0).count()).sum();
        Some(Pair { masing, free, fitted: count })
    };
    let Some(whole) = pair(&all) else { return untested("the forms cannot be fitted to these runs") };
    let [delta_bic, explained] = whole.evidence();
    let free_to_noise = whole.variance().sqrt();
    // The forms' torque runs through the runs in turn.
    let starts: Vec<usize> = runs
        .iter()
        .scan(0, |start, run| {
            let first = *start;
            *start += run.weights.len();
            Some(first)
        })
        .collect();
    let scored = || {
        runs.iter().enumerate().flat_map(|(k, run)| {
            (run.observed.known_state_from..run.weights.len())
                .filter(move |&i| run.weights[i] > 0.0)
                .map(move |i| (k, i))
        })
    };
    let (sum, count) = scored().fold((0.0, 0usize), |(sum, count), (k, i)| {
        let at = starts[k] + i;
        (sum + (whole.free.predicted[at] - whole.masing.predicted[at]).powi(2), count + 1)
    });
    let magnitude_nm = (sum / count.max(1) as f64).sqrt();
    let early = whole.refusal();
    let (held_out_rms, halves) = match early {
        Some(_) => (None, None),
        None => {
            // Every run but the largest, held out once: the others do not reach its extremes.
            let largest = (0..runs.len())
                .max_by(|&a, &b| (extents[a][1] - extents[a][0]).total_cmp(&(extents[b][1] - extents[b][0])));
            let held: Vec<usize> = all.iter().copied().filter(|&k| Some(k) != largest).collect();
            let errors: Option<Vec<[f64; 3]>> = held
                .par_iter()
                .map(|&k| {
                    let others: Vec<usize> = all.iter().copied().filter(|&j| j != k).collect();
                    let trained = pair(&others)?;
                    // The run's own torque offset is not known to the forms fitted without it:
                    // each form's residual is taken about its mean over the run.
                    let run = &runs[k];
                    let at: Vec<usize> =
                        (run.observed.known_state_from..run.weights.len()).filter(|&i| run.weights[i] > 0.0).collect();
                    let spread = |predicted: &[f64]| {
                        let residual: Vec<f64> =
                            at.iter().map(|&i| run.observed.data.torque[i] - predicted[starts[k] + i]).collect();
                        let mean = residual.iter().sum::<f64>() / residual.len().max(1) as f64;
                        residual.iter().map(|r| (r - mean).powi(2)).sum::<f64>()
                    };
                    Some([spread(&trained.masing.predicted), spread(&trained.free.predicted), at.len() as f64])
                })
                .collect();
            let held_out_rms = errors.map(|errors| {
                let [m, f, n] = errors.iter().fold([0.0; 3], |[a, b, c], [x, y, z]| [a + x, b + y, c + z]);
                [(m / n.max(1.0)).sqrt(), (f / n.max(1.0)).sqrt()]
            });
            let parts: [Vec<usize>; 2] = [
                all.iter().copied().filter(|k| k % 2 == 0).collect(),
                all.iter().copied().filter(|k| k % 2 == 1).collect(),
            ];
            let halves = if parts.iter().any(|part| one_loop_over(part)) {
                None
            } else {
                let evidence: Option<Vec<[f64; 2]>> =
                    parts.iter().map(|part| pair(part).map(|p| p.evidence())).collect();
                evidence.and_then(|e| <[[f64; 2]; 2]>::try_from(e).ok())
            };
            (held_out_rms, halves)
        }
    };
    let rejected = early.or_else(|| match (held_out_rms, halves) {
        (None, _) => Some("the runs held out could not be fitted without them".to_string()),
        (Some([masing, free]), _) if !(free < masing) => Some(format!(
            "the free form does not predict the runs held out (each fitted on the others) better ({free:.4} against \
             {masing:.4} N·m)"
        )),
        (_, None) => Some(
            "the two parts (alternate runs) cannot each show it: each must hold loops of more than one size; record \
             each amplitude twice, in turn"
                .to_string(),
        ),
        (_, Some(parts)) => not_in_each(parts, "(alternate runs)"),
    });
    NonMasingCheck::Yes(NonMasing {
        magnitude_nm,
        delta_bic,
        explained,
        free_to_noise,
        held_out_rms,
        halves,
        remanent_starts: runs.iter().filter(|run| run.remanent_start).count(),
        rejected,
        torque: [Vec::new(), Vec::new()],
    })
}
