//! Identification of the model from (θ, T, direction, A) samples.
//!
//! For a fixed r = β/ω the model is linear in c1, c2, c3 and k = α/(ω(1 + r²)):
//! `T = c1·θ + c2·θ³ + c3·θ⁵ + k·A·|cos φ|·(e^(−rφ) + r·sin φ − cos φ)`. So the search is
//! over r alone, each r answered exactly by a 4×4 weighted least-squares solve (variable
//! projection). The paper's particle swarm searches r globally (in asinh-scaled space, on a
//! subsample of long recordings); Brent's method then polishes r on every sample.
//!
//! Errors in θ: near |θ| = A the model's slope is unbounded, so deflection noise becomes
//! large torque residuals there. With a noise model, residuals are weighted by their total
//! noise 1/(σ_T² + σ_θ²·K²), K the model's stiffness at the sample, refitted a few times.
pub mod baselines;
pub mod basis;
pub mod held_out;
pub mod motion;
pub mod spring;
pub mod zero;

use crate::gear::{step_offline, Reversals};
use crate::input::{Branch, Dataset, LoopTable, Recording};
use crate::numeric::median;
use crate::numeric::optimize::{brent, pso, PsoOptions};
use crate::prepare::{
    from_loop_table, from_recording, reversals, FitData, NoiseModel, OfflineRun, Prepared, SegmentError, TurningBand,
};
use baselines::{lines_per_branch, three_segment, BranchLine, ThreeSegment};
use basis::Basis;
use held_out::{HeldOutRule, RunShape};
use model_core::{GearModel, Identifiable, Kind, Model, Params};
pub use motion::MotionFit;
use motion::{Motion, Run};
use zero::{fit_with_zero, FinalSolve, OriginSource, RunOrigin};

#[derive(Clone, Debug)]
pub struct FitOptions {
    pub seed: u64,
    pub particles: usize,
    pub max_iterations: usize,
    /// Weight residuals by total noise; `None` fits plain least squares (loop tables).
    pub noise: Option<NoiseModel>,
    /// A model of the same kind fitted to part of the same data, whose searched parameters the
    /// search may start from instead of searching globally (the refit on every sample).
    pub start: Option<GearModel<f64>>,
    /// Whether the micro-slip kind places its knots freely (`fit::spring`); else the knot
    /// rule's. The θ0 search compares its candidates on the rule's knots (`fit::zero`).
    pub free_knots: bool,
    /// With `start`, keep its nonlinear parameters (the genetic kind's r) and solve only the
    /// linear ones, weighted by its total noise: the points of a θ0 profile, and the fits of long
    /// recordings whose r a fit on a subsample of the same data found.
    pub hold_start: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            seed: 1,
            particles: 16,
            max_iterations: 60,
            noise: None,
            start: None,
            free_knots: true,
            hold_start: false,
        }
    }
}

/// The identifiable parameters (c1, c2, c3, h, r).
pub const IDENTIFIABLE_PARAMETERS: usize = 5;
/// Fewest samples `fit` accepts: one more than the identifiable parameters.
pub const MIN_POINTS: usize = IDENTIFIABLE_PARAMETERS + 1;
/// Search range of r = β/ω. Beyond it e^(−rφ) spans more than 10²⁰⁰ over one loop.
pub const R_LIMIT: f64 = 50.0;
/// PSO runs on at most this many samples; the polish always uses all of them.
const PSO_SAMPLES: usize = 1024;
/// Reweighting rounds for the total-noise weights.
const REWEIGHTINGS: usize = 2;

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SearchSummary {
    pub method: &'static str,
    pub seed: u64,
    pub particles: usize,
    pub pso_iterations: usize,
    pub pso_samples: usize,
    pub evaluations: usize,
    pub reweightings: usize,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// Canonical parameters: ω = 1, β = r, α = h·(1 + r²)/A.
    pub params: Params<f64>,
    pub identifiable: Identifiable<f64>,
    /// The amplitude A that `identifiable.h` refers to, rad.
    pub reference_amplitude: f64,
    /// The fitted deflections' range, [min, max] rad with 0 inside: the spring's identified range.
    pub range: [f64; 2],
    /// Unweighted residual sum of squares, (N·m)².
    pub rss: f64,
    /// Unweighted RMS residual, N·m.
    pub rms: f64,
    pub n: usize,
    pub noise: Option<NoiseModel>,
    pub search: SearchSummary,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    #[error("{n} points, fewer than the {need} needed to fit {IDENTIFIABLE_PARAMETERS} parameters (c1, c2, c3, h, r) with a residual left")]
    TooFewPoints { n: usize, need: usize },
    #[error("the deflection is zero everywhere: nothing to fit")]
    NoDeflection,
    #[error("the data do not determine the model (all columns collinear)")]
    Degenerate,
    #[error("the fitted model cannot be evaluated: {0}")]
    Model(#[from] model_core::Error),
}

/// Where a long fit is, for a progress bar.
#[derive(Clone, Copy, Debug)]
pub enum Stage {
    Swarm {
        iteration: usize,
        of: usize,
    },
    Polish {
        round: usize,
        of: usize,
    },
    /// Fitting the `index`-th of `of` model kinds to the recordings.
    Kind {
        kind: Kind,
        index: usize,
        of: usize,
    },
    /// Refitting the chosen kind on every scored sample.
    Refit {
        kind: Kind,
    },
}

/// Which model `fit` identifies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelChoice {
    Kind(Kind),
    /// Every kind, once per fold without its held-out samples ([`held_out`]); the one with the
    /// lowest error on them, pooled over the folds, wins and is refitted on every sample.
    Auto,
    /// The paper's symmetric-loop rule on every leg of a recording (each leg on the loop of its
    /// own amplitude, from the offline segmentation): the fit before the stateful models, kept
    /// for comparison (the fit benchmark's peers implement it).
    Loop,
}

/// What `fit` identifies from: one loop table, or one or more recordings, each a run from its
/// own start, that share one parameter set.
#[derive(Clone, Copy, Debug)]
pub enum FitInput<'a> {
    LoopTable(&'a LoopTable),
    Recordings(&'a [Recording]),
}

/// How a recording took part in a fit.
#[derive(Clone, Debug)]
pub struct RunOutcome {
    /// Its samples.
    pub samples: usize,
    /// Its turning points, reversals and noise, as the offline model follows it.
    pub offline: OfflineRun,
    /// The fold (0-based) of `auto`'s fits that held it out whole, when whole runs were held out.
    pub held_out_fold: Option<usize>,
    /// Its samples held out (of a run held out whole: all its scored samples).
    pub held_out_samples: usize,
}

/// The kinds `auto` fits and chooses among: every kind. On the measured spring the three
/// fitted runs rank Bouc–Wen first by held-out error, while the repeats at the same amplitudes
/// rank micro-slip first (`bash bench/real.sh`, tables 1 and 5): three runs cannot tell, and
/// the held-out rule cannot see the runs it is not given.
pub const AUTO_KINDS: [Kind; 4] = [Kind::Genetic, Kind::MicroSlip, Kind::BoucWen, Kind::Preisach];

/// What the fit of recordings found: the chosen model and every candidate tried.
#[derive(Clone, Debug)]
pub struct MotionOutcome {
    /// The model written: with `auto` the chosen kind refitted on every scored sample.
    pub chosen: MotionFit,
    /// Every kind fitted, in [`AUTO_KINDS`] order: with `auto` once per fold without its
    /// held-out samples and judged on them, pooled over the folds; else the one kind named.
    pub candidates: Vec<MotionFit>,
    /// The θ0 each candidate fitted, rad, in their order: none where every run starts at rest.
    /// With `auto`, its first fold's: where the kinds place a zero the data do not fix, they
    /// disagree (the measured spring without its rest: by up to 3 mrad), and the report shows it.
    pub candidate_zeros: Vec<Option<f64>>,
    /// The kinds `auto` could not fit without the held-out samples of some fold, with why:
    /// not judged, not chosen.
    pub not_judged: Vec<(Kind, FitError)>,
    /// How `auto` chose the held-out samples (none for a named kind).
    pub held_out_rule: Option<HeldOutRule>,
    /// The noise the residuals were weighted by.
    pub noise: Option<NoiseModel>,
    /// Half the range of the fitted deflections, rad: the loop amplitude a genetic model's h
    /// is reported at.
    pub reference_amplitude: f64,
    /// Each run's θ0 and torque offset, in the order given (the model's θ0 is the first's).
    pub origins: Vec<RunOrigin>,
}

impl MotionOutcome {
    /// The candidate of the chosen kind, as `auto` judged it (fitted without the held-out
    /// samples).
    pub fn chosen_candidate(&self) -> Option<&MotionFit> {
        self.candidates.iter().find(|c| c.model.kind() == self.chosen.model.kind())
    }
}

/// The identified model: the loop fit of a loop table, or a stateful model of recordings.
#[derive(Clone, Debug)]
pub enum Identified {
    Loop(Fit),
    Motion(Box<MotionOutcome>),
}

impl Identified {
    /// The model a params file holds.
    pub fn model(&self) -> GearModel<f64> {
        match self {
            Identified::Loop(fit) => {
                let mut model = GearModel::paper(fit.params);
                model.spring.range = fit.range;
                model
            }
            Identified::Motion(outcome) => outcome.chosen.model,
        }
    }
}

/// Everything `swg-host fit` computes: the fit, the baselines beside it, and the RSS of other
/// parameter sets on the same data.
#[derive(Clone, Debug)]
pub struct FitOutcome {
    /// The samples of a loop fit (a loop table, or recordings with `genetic-loop`).
    pub prepared: Option<Prepared>,
    /// Each recording, in the order given (none for a loop table).
    pub runs: Vec<RunOutcome>,
    pub identified: Identified,
    pub lines: Vec<BranchLine>,
    pub three_segment: Option<ThreeSegment>,
    /// RSS of each set given to compare, (N·m)², in order: on a loop table's points, or on the
    /// scored samples of the recordings, each run from rest along its reversals.
    pub compared_rss: Vec<f64>,
}

/// Why [`fit_input`] failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FitDatasetError {
    /// A recording (by its index in the order given) cannot be fitted.
    #[error("{source}")]
    Run {
        index: usize,
        #[source]
        source: SegmentError,
    },
    #[error("fit failed: {0}")]
    Fit(#[from] FitError),
    #[error("the {0} model needs a recording: a loop table is one symmetric loop (use the genetic model)")]
    NeedsRecording(&'static str),
    #[error("no recording to fit")]
    NoInput,
    #[error(
        "{fitted} samples fitted and {held_out} held out: too few to judge the kinds for --model auto (it holds out \
         {rule}); record at least one whole cycle (to one extreme, the other and back) after the scored start (from \
         rest, or after the motion has visited both its extremes), or three or more runs; or name a model \
         (--model micro-slip, bouc-wen, preisach or genetic)"
    )]
    TooFewToHoldOut { fitted: usize, held_out: usize, rule: String },
    #[error(
        "no model kind could be fitted without the samples --model auto holds out ({rule}): {}; record more \
         cycles or runs, or name a model (--model micro-slip, bouc-wen, preisach or genetic)",
        errors.join("; ")
    )]
    NoKindJudged { rule: String, errors: Vec<String> },
    #[error("parameter set {index} to compare cannot be evaluated on this data: {source}")]
    Compared {
        index: usize,
        #[source]
        source: model_core::Error,
    },
}

/// The `fit` pipeline of one dataset ([`fit_input`]).
pub fn fit_dataset(
    dataset: &Dataset,
    choice: ModelChoice,
    compare: &[GearModel<f64>],
    seed: u64,
    progress: impl Fn(Stage) + Sync,
) -> Result<FitOutcome, FitDatasetError> {
    let input = match dataset {
        Dataset::LoopTable(table) => FitInput::LoopTable(table),
        Dataset::Recording(recording) => FitInput::Recordings(std::slice::from_ref(recording)),
    };
    fit_input(input, choice, compare, seed, progress)
}

/// The `fit` pipeline: identify the model `choice` names, fit the baselines, and evaluate the
/// `compare` sets on the same samples. A loop table is one loop: it takes the genetic loop fit
/// (`Auto` means genetic there). Recordings take the stateful models, run along each from rest
/// following its reversals offline, fitted and scored from where its motion has wiped out an
/// unknown start state.
pub fn fit_input(
    input: FitInput<'_>,
    choice: ModelChoice,
    compare: &[GearModel<f64>],
    seed: u64,
    progress: impl Fn(Stage) + Sync,
) -> Result<FitOutcome, FitDatasetError> {
    match input {
        FitInput::LoopTable(table) => {
            if let ModelChoice::Kind(kind) = choice {
                if !kind.has_symmetric_loop() {
                    return Err(FitDatasetError::NeedsRecording(kind.name()));
                }
            }
            let prepared = from_loop_table(table);
            let options = FitOptions { seed, noise: None, ..FitOptions::default() };
            let fitted = fit(&prepared.data, &options, &progress)?;
            let data = &prepared.data;
            let lines = lines_per_branch(&data.theta, &data.torque, &prepared.branch);
            let three_segment = three_segment(&data.theta, &data.torque);
            let compared_rss = compare
                .iter()
                .enumerate()
                .map(|(index, model)| {
                    // A loop table's points are on one symmetric loop: a model that has the
                    // loop's stateless form is evaluated on it, any other run along the points.
                    match model.paper_params().map(Model::new).transpose() {
                        Ok(Some(on_loop)) => rss(&on_loop, data),
                        Ok(None) => offline_rss(model, &data.theta, &data.torque, 0.0, &reversals(&data.theta), 0),
                        Err(e) => Err(e),
                    }
                    .map_err(|source| FitDatasetError::Compared { index, source })
                })
                .collect::<Result<_, _>>()?;
            Ok(FitOutcome {
                prepared: Some(prepared),
                runs: Vec::new(),
                identified: Identified::Loop(fitted),
                lines,
                three_segment,
                compared_rss,
            })
        }
        FitInput::Recordings(recordings) => fit_recordings(recordings, choice, compare, seed, progress),
    }
}

fn fit_recordings(
    recordings: &[Recording],
    choice: ModelChoice,
    compare: &[GearModel<f64>],
    seed: u64,
    progress: impl Fn(Stage) + Sync,
) -> Result<FitOutcome, FitDatasetError> {
    use rayon::prelude::*;
    if recordings.is_empty() {
        return Err(FitDatasetError::NoInput);
    }
    let offline: Vec<OfflineRun> = recordings.par_iter().map(OfflineRun::of).collect();
    for (index, (recording, run)) in recordings.iter().zip(&offline).enumerate() {
        if run.reversals.indices.is_empty() {
            let TurningBand { band, range, .. } = TurningBand::of(&recording.deflection);
            return Err(FitDatasetError::Run { index, source: SegmentError::NoReversal { range, band } });
        }
    }
    let noise = pooled_noise(recordings, &offline);
    let options = FitOptions { seed, noise: Some(noise), ..FitOptions::default() };
    let all_fitted = Motion {
        runs: recordings
            .iter()
            .zip(&offline)
            .map(|(r, o)| Run {
                remanent_start: o.remanent_start,
                ..Run::fitted_from(&r.deflection, &r.torque, &o.reversals, o.scored_from)
            })
            .collect(),
        noise: Some(noise),
        rest_jitter: rest_jitter(&offline),
    };
    let at_rest: Vec<Option<RunOrigin>> = offline.iter().map(RunOrigin::at_rest).collect();
    // The model's θ0 is the first run's (the others' rest points differ by the remanence of the
    // loops between them).
    let with_zero = |(mut fit, origins): (MotionFit, Vec<RunOrigin>)| {
        fit.model.zero = origins.first().map_or(0.0, |o| o.zero_rad);
        (fit, origins)
    };
    let fitted_zero =
        |origins: &[RunOrigin]| origins.iter().find(|o| o.source == OriginSource::Fitted).map(|o| o.zero_rad);
    let motion_outcome = |chosen, candidates, candidate_zeros, held_out_rule, origins, not_judged| MotionOutcome {
        chosen,
        candidates,
        candidate_zeros,
        not_judged,
        held_out_rule,
        noise: Some(noise),
        reference_amplitude: reference_amplitude(&all_fitted),
        origins,
    };
    let mut held_out_spans = None;
    let (prepared, identified) = match choice {
        ModelChoice::Loop => {
            let prepared = concatenated_loop_data(recordings)?;
            let fitted = fit(&prepared.data, &options, &progress)?;
            (Some(prepared), Identified::Loop(fitted))
        }
        ModelChoice::Kind(kind) => {
            progress(Stage::Kind { kind, index: 1, of: 1 });
            let (chosen, origins) =
                with_zero(fit_with_zero(kind, &all_fitted, &at_rest, &options, FinalSolve::EverySample)?);
            (
                None,
                Identified::Motion(Box::new(motion_outcome(
                    chosen.clone(),
                    vec![chosen],
                    vec![fitted_zero(&origins)],
                    None,
                    origins,
                    Vec::new(),
                ))),
            )
        }
        ModelChoice::Auto => {
            let shapes: Vec<RunShape> = recordings
                .iter()
                .zip(&offline)
                .map(|(r, o)| RunShape { theta: &r.deflection, reversals: &o.reversals, scored_from: o.scored_from })
                .collect();
            let (folds, rule) = held_out::hold_out(&shapes);
            let trainings: Vec<Motion> = folds
                .iter()
                .map(|fold| {
                    let mut training = all_fitted.clone();
                    for (run, spans) in training.runs.iter_mut().zip(fold) {
                        run.spans.clone_from(spans);
                    }
                    training
                })
                .collect();
            for training in &trainings {
                let (fitted, held) = (training.fitted(), training.held_out());
                if fitted < MIN_POINTS || held < MIN_POINTS {
                    return Err(FitDatasetError::TooFewToHoldOut { fitted, held_out: held, rule: rule.describe() });
                }
            }
            // Every kind once per fold, side by side, each judged on the samples held out of it.
            let jobs: Vec<(Kind, &Motion)> =
                AUTO_KINDS.iter().flat_map(|&kind| trainings.iter().map(move |training| (kind, training))).collect();
            let fold_fits: Vec<Result<(MotionFit, Vec<RunOrigin>), FitError>> = jobs
                .par_iter()
                .enumerate()
                .map(|(k, &(kind, training))| {
                    progress(Stage::Kind { kind, index: k + 1, of: jobs.len() });
                    fit_with_zero(kind, training, &at_rest, &options, FinalSolve::Strided).map(with_zero)
                })
                .collect();
            // A kind that cannot be fitted without some held-out samples is not judged (a run
            // from rest up and back holds out its return: its rise alone does not determine the
            // genetic kind); the others still are.
            let (mut candidates, mut not_judged) = (Vec::new(), Vec::new());
            for (&kind, fits) in AUTO_KINDS.iter().zip(fold_fits.chunks(trainings.len())) {
                match fits.iter().cloned().collect::<Result<Vec<_>, _>>() {
                    Ok(fits) => candidates.push(pooled_over_folds(&fits)),
                    Err(error) => not_judged.push((kind, error)),
                }
            }
            if candidates.is_empty() {
                return Err(FitDatasetError::NoKindJudged {
                    rule: rule.describe(),
                    errors: not_judged.iter().map(|(kind, e)| format!("{}: {e}", kind.name())).collect(),
                });
            }
            let fits: Vec<&MotionFit> = candidates.iter().map(|(fit, _)| fit).collect();
            let (best, best_origins) = pick(&fits).and_then(|k| candidates.get(k)).ok_or(FitError::Degenerate)?;
            // The written parameters use every sample; θ0 is the one the chosen kind's fit found
            // on the training samples (its search is the costly part of a fit without rest).
            let kind = best.model.kind();
            progress(Stage::Refit { kind });
            // Long recordings keep the training fit's r, polished on a subsample of 3/4 of the
            // same samples (a polish on all of them would run on a subsample too).
            let refit = FitOptions { start: Some(best.model), hold_start: all_fitted.is_long(), ..options };
            let known: Vec<Option<RunOrigin>> = best_origins.iter().copied().map(Some).collect();
            let (chosen, origins) =
                with_zero(fit_with_zero(kind, &all_fitted, &known, &refit, FinalSolve::EverySample)?);
            let candidate_zeros = candidates.iter().map(|(_, origins)| fitted_zero(origins)).collect();
            let candidates = candidates.into_iter().map(|(fit, _)| fit).collect();
            held_out_spans = Some(folds);
            (
                None,
                Identified::Motion(Box::new(motion_outcome(
                    chosen,
                    candidates,
                    candidate_zeros,
                    Some(rule),
                    origins,
                    not_judged,
                ))),
            )
        }
    };
    let (lines, three_segment) = match &prepared {
        Some(p) => {
            (lines_per_branch(&p.data.theta, &p.data.torque, &p.branch), three_segment(&p.data.theta, &p.data.torque))
        }
        None => {
            let origins = match &identified {
                Identified::Motion(outcome) => outcome.origins.clone(),
                Identified::Loop(_) => Vec::new(),
            };
            recording_baselines(recordings, &offline, &origins)
        }
    };
    let compared_rss = compare
        .iter()
        .enumerate()
        .map(|(index, model)| {
            recordings
                .iter()
                .zip(&offline)
                .map(|(r, o)| {
                    let (placed, origin) = RunOrigin::place(model, o);
                    let offset = origin.map_or(0.0, |o| o.torque_offset_nm);
                    offline_rss(&placed, &r.deflection, &r.torque, offset, &o.reversals, o.scored_from)
                })
                .sum::<Result<f64, _>>()
                .map_err(|source| FitDatasetError::Compared { index, source })
        })
        .collect::<Result<_, _>>()?;
    let runs = recordings
        .iter()
        .zip(offline)
        .enumerate()
        .map(|(k, (recording, offline))| {
            let held_out_samples = held_out_spans.as_ref().map_or(0, |folds: &Vec<held_out::Fold>| {
                folds
                    .iter()
                    .filter_map(|fold| fold.get(k))
                    .flat_map(|spans| spans.iter().filter(|s| s.held_out).map(|s| s.range.len()))
                    .sum()
            });
            let held_out_fold = match &identified {
                Identified::Motion(outcome) => match &outcome.held_out_rule {
                    Some(HeldOutRule::Runs { whole, .. }) => whole.iter().position(|held| held.contains(&k)),
                    _ => None,
                },
                Identified::Loop(_) => None,
            };
            RunOutcome { samples: recording.deflection.len(), held_out_fold, held_out_samples, offline }
        })
        .collect();
    Ok(FitOutcome { prepared, runs, identified, lines, three_segment, compared_rss })
}

/// `auto`'s pick among `candidates` (its index): the lowest held-out error, or a kind of fewer
/// parameters within one standard error of it (the one-standard-error rule of cross-validation).
/// Fitted without those samples, a kind that follows the training samples by its many
/// parameters is not rewarded on them; and where the held-out samples cannot tell two kinds
/// apart, the simpler is the one they support. (The Preisach kind holds the micro-slip kind as a
/// special case: on a micro-slip gear the two held out 0.0349 N·m each, and Preisach, picked
/// by the fourth decimal, predicted a wider motion with 0.131 N·m RMS within the fitted range,
/// where micro-slip stays under 0.1 (`host/tests/predict_cli.rs`): its relays end at the
/// fitted range.)
fn pick(candidates: &[&MotionFit]) -> Option<usize> {
    let held = |k: usize| candidates[k].held_out_rms.unwrap_or(candidates[k].rms);
    let best = (0..candidates.len()).min_by(|&a, &b| held(a).total_cmp(&held(b)))?;
    (0..candidates.len())
        .filter(|&k| {
            k == best || within_one_standard_error(&candidates[k].held_out_pieces, &candidates[best].held_out_pieces)
        })
        .min_by(|&a, &b| candidates[a].parameters.cmp(&candidates[b].parameters).then(held(a).total_cmp(&held(b))))
}

/// Whether a kind's held-out RSS exceeds the best kind's by at most one standard error: the
/// mean of their differences over the held-out spans (paired: the same spans, in order) within
/// the standard error of that mean.
fn within_one_standard_error(pieces: &[f64], best: &[f64]) -> bool {
    if pieces.len() != best.len() || pieces.len() < 2 {
        return false;
    }
    let m = pieces.len() as f64;
    let differences: Vec<f64> = pieces.iter().zip(best).map(|(a, b)| a - b).collect();
    let mean = differences.iter().sum::<f64>() / m;
    let variance = differences.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (m - 1.0);
    mean <= (variance / m).sqrt()
}

/// One kind's fits, one per fold, as one candidate: the first fold's model and origins (the
/// refit's start), its RMS pooled over the folds' fitted samples and its held-out RMS over every
/// held-out sample; `n` is the mean number of samples a fold's fit used.
fn pooled_over_folds(fits: &[(MotionFit, Vec<RunOrigin>)]) -> (MotionFit, Vec<RunOrigin>) {
    let (first, origins) = fits[0].clone();
    let fitted: usize = fits.iter().map(|(fit, _)| fit.n).sum();
    let held: usize = fits.iter().map(|(fit, _)| fit.held_out_samples).sum();
    let held_out_pieces: Vec<f64> = fits.iter().flat_map(|(fit, _)| fit.held_out_pieces.iter().copied()).collect();
    let held_rss: f64 = held_out_pieces.iter().sum();
    let pooled = MotionFit {
        held_out_pieces,
        n: fitted / fits.len(),
        rss: fits.iter().map(|(fit, _)| fit.rss).sum::<f64>() / fits.len() as f64,
        misfit: fits.iter().map(|(fit, _)| fit.misfit).sum::<f64>() / fits.len() as f64,
        rms: (fits.iter().map(|(fit, _)| fit.rss).sum::<f64>() / fitted.max(1) as f64).sqrt(),
        held_out_samples: held,
        held_out_rms: (held > 0).then(|| (held_rss / held as f64).sqrt()),
        evaluations: fits.iter().map(|(fit, _)| fit.evaluations).sum(),
        ..first
    };
    (pooled, origins)
}

/// The noise of several runs: each standard deviation the RMS over the runs, by sample count.
/// The deflection's standard deviation in the runs' rest windows, pooled (RMS), rad; 0 where no
/// run has a rest window long enough to tell.
fn rest_jitter(offline: &[OfflineRun]) -> f64 {
    let spreads: Vec<f64> = offline.iter().filter_map(|run| run.rest.and_then(|rest| rest.deflection_sd_rad)).collect();
    if spreads.is_empty() {
        0.0
    } else {
        (spreads.iter().map(|sd| sd * sd).sum::<f64>() / spreads.len() as f64).sqrt()
    }
}

fn pooled_noise(recordings: &[Recording], offline: &[OfflineRun]) -> NoiseModel {
    let total: usize = recordings.iter().map(|r| r.deflection.len()).sum();
    let pooled = |sigma: &dyn Fn(&NoiseModel) -> f64| {
        let sum: f64 =
            recordings.iter().zip(offline).map(|(r, o)| r.deflection.len() as f64 * sigma(&o.noise).powi(2)).sum();
        (sum / total.max(1) as f64).sqrt()
    };
    NoiseModel { torque_nm: pooled(&|n| n.torque_nm), deflection_rad: pooled(&|n| n.deflection_rad) }
}

/// Half the range of the fitted deflections, rad.
fn reference_amplitude(motion: &Motion) -> f64 {
    let (lo, hi) = motion
        .runs
        .iter()
        .flat_map(|run| run.spans.iter().filter(|s| !s.held_out).flat_map(|s| &run.theta[s.range.clone()]))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| (l.min(t), h.max(t)));
    (hi - lo) / 2.0
}

/// The recordings' samples, prepared for the loop fit, one after the other.
fn concatenated_loop_data(recordings: &[Recording]) -> Result<Prepared, FitDatasetError> {
    let mut all: Option<Prepared> = None;
    for (index, recording) in recordings.iter().enumerate() {
        let prepared = from_recording(recording).map_err(|source| FitDatasetError::Run { index, source })?;
        all = Some(match all {
            None => prepared,
            Some(mut all) => {
                all.data.theta.extend(prepared.data.theta);
                all.data.torque.extend(prepared.data.torque);
                all.data.direction.extend(prepared.data.direction);
                all.data.amplitude.extend(prepared.data.amplitude);
                all.branch.extend(prepared.branch);
                all.segmentation = None;
                all
            }
        });
    }
    all.ok_or(FitDatasetError::NoInput)
}

/// The baselines on the scored samples of the recordings (as the fit's RSS), each sample on
/// the branch of its leg, in x = θ − θ0 and the torque less the offset of its run (`origins`, in
/// order; none for a loop fit).
fn recording_baselines(
    recordings: &[Recording],
    offline: &[OfflineRun],
    origins: &[RunOrigin],
) -> (Vec<BranchLine>, Option<ThreeSegment>) {
    let total: usize = offline.iter().zip(recordings).map(|(o, r)| r.deflection.len() - o.scored_from).sum();
    let (mut x, mut torque, mut branch) =
        (Vec::with_capacity(total), Vec::with_capacity(total), Vec::with_capacity(total));
    for (k, (r, o)) in recordings.iter().zip(offline).enumerate() {
        let (zero, offset) = origins.get(k).map_or((0.0, 0.0), |o| (o.zero_rad, o.torque_offset_nm));
        let along = o.reversals.project(&r.deflection).zip(o.reversals.directions(r.deflection.len())).zip(&r.torque);
        for ((p, d), t) in along.skip(o.scored_from) {
            let here = p.theta_m + p.offset - zero;
            x.push(here);
            torque.push(t - offset);
            branch.push(Branch::of(d, here));
        }
    }
    (lines_per_branch(&x, &torque, &branch), three_segment(&x, &torque))
}

/// Unweighted RSS of `model` run from rest along one recording following its reversals, over
/// its samples from `scored_from` on, (N·m)².
fn offline_rss(
    model: &GearModel<f64>,
    theta: &[f64],
    torque: &[f64],
    torque_offset: f64,
    reversals: &Reversals,
    scored_from: usize,
) -> Result<f64, model_core::Error> {
    let mut evaluator = model.evaluator(0.0)?;
    let mut rss = 0.0;
    for ((i, sample), measured) in reversals.project(theta).enumerate().zip(torque) {
        let predicted = step_offline(&mut evaluator, sample)?.torque + torque_offset;
        if i >= scored_from {
            rss += (measured - predicted).powi(2);
        }
    }
    Ok(rss)
}

/// Fits the model to `data`.
pub fn fit(data: &FitData, options: &FitOptions, mut progress: impl FnMut(Stage)) -> Result<Fit, FitError> {
    let n = data.theta.len();
    if n < MIN_POINTS {
        return Err(FitError::TooFewPoints { n, need: MIN_POINTS });
    }
    let scale = data.amplitude.iter().copied().fold(0.0, f64::max);
    if !(scale > 0.0) || data.theta.iter().all(|&t| t == 0.0) {
        return Err(FitError::NoDeflection);
    }
    let reference_amplitude = median(&data.amplitude);

    // Global search on an evenly strided subsample.
    let stride = n.div_ceil(PSO_SAMPLES);
    let sample = Basis::sampled(data, (0..n).step_by(stride), scale);
    let s_limit = R_LIMIT.asinh();
    let pso_options = PsoOptions {
        particles: options.particles,
        max_iterations: options.max_iterations,
        stall_iterations: 12,
        seed: options.seed,
    };
    let swarm = pso(
        |x| sample.objective(x[0]),
        &[(-s_limit, s_limit)],
        &pso_options,
        |iteration, _| progress(Stage::Swarm { iteration, of: options.max_iterations }),
    );
    let mut evaluations = swarm.evaluations;

    let mut full = Basis::new(data, scale);
    let rounds = if options.noise.is_some() { 1 + REWEIGHTINGS } else { 1 };
    let mut s = swarm.best[0];
    // The bracket widens by itself when the minimum lies on its edge.
    let half_width = (3.0 * swarm.spread[0]).clamp(0.02, 0.1);
    let solve = |full: &Basis<'_>, s: f64| -> Result<Params<f64>, FitError> {
        let r = s.sinh();
        let solution = full.solve(r).ok_or(FitError::Degenerate)?;
        full.params(r, &solution, reference_amplitude)
    };
    progress(Stage::Polish { round: 1, of: rounds });
    let mut params = match &options.noise {
        // With weights to come, the swarm's point is close enough to set them: polishing the
        // unweighted fit first would cost a third of a 20k-sample fit and change nothing.
        Some(_) => solve(&full, s)?,
        None => {
            let (polished, polish_evaluations) = polish(&full, s, half_width, s_limit);
            evaluations += polish_evaluations;
            s = polished;
            solve(&full, s)?
        }
    };
    if let Some(noise) = &options.noise {
        for round in 2..=rounds {
            progress(Stage::Polish { round, of: rounds });
            reweight(&mut full, data, &Model::new(params)?, noise)?;
            let (polished, polish_evaluations) = polish(&full, s, if round == 2 { half_width } else { 0.05 }, s_limit);
            evaluations += polish_evaluations;
            s = polished;
            params = solve(&full, s)?;
        }
    }
    let rss = rss(&Model::new(params)?, data)?;
    let range = data.theta.iter().fold([0.0f64, 0.0f64], |[lo, hi], &t| [lo.min(t), hi.max(t)]);
    Ok(Fit {
        params,
        identifiable: params.identifiable(reference_amplitude)?,
        reference_amplitude,
        range,
        rss,
        rms: (rss / n as f64).sqrt(),
        n,
        noise: options.noise,
        search: SearchSummary {
            method: "pso over r = beta/omega with c1, c2, c3, h by exact least squares; brent polish",
            seed: options.seed,
            particles: options.particles,
            pso_iterations: swarm.iterations,
            pso_samples: sample.len(),
            evaluations,
            reweightings: rounds - 1,
        },
    })
}

/// Brent on s = asinh(r) around `s`, widening the bracket while the minimum sits on its edge.
pub fn polish(basis: &Basis<'_>, s: f64, half_width: f64, s_limit: f64) -> (f64, usize) {
    let mut evaluations = 0;
    let (mut center, mut half) = (s, half_width);
    loop {
        let lo = (center - half).max(-s_limit);
        let hi = (center + half).min(s_limit);
        let (x, _, used) = brent(|s| basis.objective(s), lo, hi, 1e-8);
        evaluations += used;
        let on_edge = (x - lo < 1e-3 * half && lo > -s_limit) || (hi - x < 1e-3 * half && hi < s_limit);
        if !on_edge || half > 2.0 * s_limit {
            return (x, evaluations);
        }
        center = x;
        half *= 4.0;
    }
}

/// Total-noise weights 1/(σ_T² + σ_θ²·K²), normalised to a mean of 1.
fn reweight(basis: &mut Basis<'_>, data: &FitData, model: &Model<f64>, noise: &NoiseModel) -> Result<(), FitError> {
    // The new weights go into the old ones' buffer: one weight vector at a time.
    let mut weights = basis.take_weights();
    total_noise_weights_into(data, model, noise, &mut weights)?;
    let mean = weights.iter().sum::<f64>() / weights.len() as f64;
    weights.iter_mut().for_each(|w| *w /= mean);
    basis.set_weights(weights);
    Ok(())
}

/// 1/(σ_T² + σ_θ²·K²) for every sample, K the model's stiffness there: the inverse variance
/// of a torque residual when both torque and deflection are noisy.
pub fn total_noise_weights(
    data: &FitData,
    model: &Model<f64>,
    noise: &NoiseModel,
) -> Result<Vec<f64>, model_core::Error> {
    let mut weights = Vec::with_capacity(data.theta.len());
    total_noise_weights_into(data, model, noise, &mut weights)?;
    Ok(weights)
}

/// [`total_noise_weights`] into `weights` (cleared first).
fn total_noise_weights_into(
    data: &FitData,
    model: &Model<f64>,
    noise: &NoiseModel,
    weights: &mut Vec<f64>,
) -> Result<(), model_core::Error> {
    weights.clear();
    // At once, not by doubling: the first weights go into an empty buffer (unit weights are
    // not stored).
    weights.reserve_exact(data.theta.len());
    for i in 0..data.theta.len() {
        let stiffness = model.stiffness(data.theta[i], data.direction[i], data.amplitude[i])?;
        weights.push(noise.weight(stiffness));
    }
    Ok(())
}

/// Unweighted residual sum of squares of `model` on `data`, (N·m)².
pub fn rss(model: &Model<f64>, data: &FitData) -> Result<f64, model_core::Error> {
    // Summed as they come, in order: the same sum as over [`residuals`], without the vector.
    (0..data.theta.len()).map(|i| residual(model, data, i).map(|e| e * e)).sum()
}

fn residual(model: &Model<f64>, data: &FitData, i: usize) -> Result<f64, model_core::Error> {
    Ok(data.torque[i] - model.torque(data.theta[i], data.direction[i], data.amplitude[i])?)
}

/// Measured minus modelled torque for every sample, N·m.
pub fn residuals(model: &Model<f64>, data: &FitData) -> Result<Vec<f64>, model_core::Error> {
    (0..data.theta.len()).map(|i| residual(model, data, i)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(parameters: usize, pieces: &[f64]) -> MotionFit {
        let held: f64 = pieces.iter().sum();
        MotionFit {
            model: GearModel::paper(Params { c1: 1e4, c2: 0.0, c3: 0.0, alpha: 1.0, beta: 0.0, omega: 1.0 }),
            parameters,
            n: 100,
            rss: 1.0,
            misfit: 1.0,
            rms: 0.1,
            held_out_samples: 10 * pieces.len(),
            held_out_rms: Some((held / (10 * pieces.len()) as f64).sqrt()),
            held_out_pieces: pieces.to_vec(),
            evaluations: 0,
        }
    }

    #[test]
    fn auto_takes_the_fewer_parameters_within_one_standard_error_of_the_lowest_held_out_error() {
        // The many-parameter kind is lower by 0.3 % on average, but the spans disagree by more.
        let rich = candidate(50, &[1.00, 1.03, 0.97, 1.01]);
        let lean = candidate(20, &[1.01, 1.01, 1.00, 1.00]);
        assert!(rich.held_out_rms < lean.held_out_rms);
        assert_eq!(pick(&[&rich, &lean]), Some(1));
        // Higher on every span, by 5 % on average: the held-out samples tell them apart.
        let worse = candidate(20, &[1.05, 1.08, 1.02, 1.06]);
        assert_eq!(pick(&[&rich, &worse]), Some(0));
        // One span gives no standard error: the lowest error wins.
        assert_eq!(pick(&[&candidate(50, &[1.00]), &candidate(20, &[1.001])]), Some(0));
    }
}
