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
pub mod motion;
pub mod spring;

use crate::gear::reversal_band;
use crate::input::Dataset;
use crate::numeric::median;
use crate::numeric::optimize::{brent, pso, PsoOptions};
use crate::prepare::{prepare, FitData, NoiseModel, Prepared, SegmentError};
use baselines::{lines_per_branch, three_segment, BranchLine, ThreeSegment};
use basis::Basis;
use model_core::{GearModel, Identifiable, Kind, Model, Params};
pub use motion::MotionFit;

#[derive(Clone, Debug)]
pub struct FitOptions {
    pub seed: u64,
    pub particles: usize,
    pub max_iterations: usize,
    /// Weight residuals by total noise; `None` fits plain least squares (loop tables).
    pub noise: Option<NoiseModel>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { seed: 1, particles: 16, max_iterations: 60, noise: None }
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
    /// Fitting the `index`-th of `of` model kinds to a recording.
    Kind {
        kind: Kind,
        index: usize,
        of: usize,
    },
}

/// Which model `fit` identifies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelChoice {
    Kind(Kind),
    /// Every kind, on the first three quarters of a recording; the one with the lowest error on
    /// the last quarter wins.
    Auto,
    /// The paper's symmetric-loop rule on every leg of a recording (each leg on the loop of its
    /// own amplitude, from the offline segmentation): the fit before the stateful models, kept
    /// for comparison (the fit benchmark's peers implement it).
    Loop,
}

/// What the fit of a recording found: the chosen model and every candidate tried.
#[derive(Clone, Debug)]
pub struct MotionOutcome {
    pub chosen: MotionFit,
    /// Every kind fitted, the chosen one included, in [`Kind::ALL`] order.
    pub candidates: Vec<MotionFit>,
    /// Samples held out of every fit (the last quarter with `auto`, else none).
    pub held_out: usize,
    /// The reversal band the stateful models used, rad.
    pub band_rad: f64,
    /// The noise the residuals were weighted by.
    pub noise: Option<NoiseModel>,
    /// Half the range of the fitted deflections, rad: the loop amplitude a genetic model's h
    /// is reported at.
    pub reference_amplitude: f64,
}

/// The identified model: the loop fit of a loop table, or a stateful model of a recording.
#[derive(Clone, Debug)]
pub enum Identified {
    Loop(Fit),
    Motion(Box<MotionOutcome>),
}

impl Identified {
    /// The model a params file holds.
    pub fn model(&self) -> GearModel<f64> {
        match self {
            Identified::Loop(fit) => GearModel::paper(fit.params),
            Identified::Motion(outcome) => outcome.chosen.model,
        }
    }
}

/// Everything `swg-host fit` computes: the prepared data, the fit, the baselines beside it,
/// and the RSS of other parameter sets on the same data.
#[derive(Clone, Debug)]
pub struct FitOutcome {
    pub prepared: Prepared,
    pub identified: Identified,
    pub lines: Vec<BranchLine>,
    pub three_segment: Option<ThreeSegment>,
    /// RSS of each set given to compare, (N·m)², in order.
    pub compared_rss: Vec<f64>,
}

/// Why [`fit_dataset`] failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FitDatasetError {
    #[error(transparent)]
    Segment(#[from] SegmentError),
    #[error("fit failed: {0}")]
    Fit(#[from] FitError),
    #[error("the {0} model needs a recording: a loop table is one symmetric loop (use the genetic model)")]
    NeedsRecording(&'static str),
    #[error("{n} samples: too few to hold a quarter out for --model auto; name a model")]
    TooFewToHoldOut { n: usize },
    #[error("parameter set {index} to compare cannot be evaluated on this data: {source}")]
    Compared {
        index: usize,
        #[source]
        source: model_core::Error,
    },
}

/// The `fit` pipeline: prepare `dataset`, identify the model `choice` names, fit the
/// baselines, and evaluate the `compare` sets on the same samples. A loop table is one loop:
/// it takes the genetic loop fit (`Auto` means genetic there). A recording takes the stateful
/// models, run along it from rest.
pub fn fit_dataset(
    dataset: &Dataset,
    choice: ModelChoice,
    compare: &[GearModel<f64>],
    seed: u64,
    mut progress: impl FnMut(Stage),
) -> Result<FitOutcome, FitDatasetError> {
    let prepared = prepare(dataset)?;
    let options = FitOptions { seed, noise: prepared.noise, ..FitOptions::default() };
    let data = &prepared.data;
    let band = reversal_band(prepared.noise.map_or(0.0, |n| n.deflection_rad));
    let identified = match (dataset, choice) {
        (Dataset::LoopTable(_), ModelChoice::Kind(kind)) if !kind.has_symmetric_loop() => {
            return Err(FitDatasetError::NeedsRecording(kind.name()))
        }
        (Dataset::LoopTable(_), _) | (_, ModelChoice::Loop) => Identified::Loop(fit(data, &options, progress)?),
        (Dataset::Recording(_), ModelChoice::Kind(_) | ModelChoice::Auto) => {
            let n = data.theta.len();
            let (kinds, training): (Vec<Kind>, usize) = match choice {
                ModelChoice::Kind(kind) => (vec![kind], n),
                _ => (Kind::ALL.to_vec(), n * 3 / 4),
            };
            if training < MIN_POINTS || (choice == ModelChoice::Auto && n - training < MIN_POINTS) {
                return Err(FitDatasetError::TooFewToHoldOut { n });
            }
            let motion =
                motion::Motion { theta: &data.theta, torque: &data.torque, training, noise: prepared.noise, band };
            let mut candidates = Vec::new();
            for (k, kind) in kinds.iter().enumerate() {
                progress(Stage::Kind { kind: *kind, index: k + 1, of: kinds.len() });
                candidates.push(motion::fit_kind(*kind, &motion, &options)?);
            }
            let chosen = candidates
                .iter()
                .min_by(|a, b| a.held_out_rms.unwrap_or(a.rms).total_cmp(&b.held_out_rms.unwrap_or(b.rms)))
                .cloned()
                .ok_or(FitError::Degenerate)?;
            Identified::Motion(Box::new(MotionOutcome {
                chosen,
                candidates,
                held_out: n - training,
                band_rad: band,
                noise: prepared.noise,
                reference_amplitude: {
                    let fitted = &data.theta[..training];
                    let (lo, hi) =
                        fitted.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| (l.min(t), h.max(t)));
                    (hi - lo) / 2.0
                },
            }))
        }
    };
    let lines = lines_per_branch(&data.theta, &data.torque, &prepared.branch);
    let three_segment = three_segment(&data.theta, &data.torque);
    let compared_rss = compare
        .iter()
        .enumerate()
        .map(|(index, model)| {
            // A loop table's samples are on one symmetric loop: a model that has the loop's
            // stateless form is evaluated on it, any other run along the samples.
            let on_loop = match &identified {
                Identified::Loop(_) => model.paper_params().map(Model::new).transpose(),
                Identified::Motion(_) => Ok(None),
            };
            match on_loop {
                Ok(Some(on_loop)) => rss(&on_loop, data),
                Ok(None) => crate::gear::run(model, &data.theta, band)
                    .map(|e| e.iter().zip(&data.torque).map(|(e, t)| (t - e.torque).powi(2)).sum())
                    .map_err(|(_, e)| e),
                Err(e) => Err(e),
            }
            .map_err(|source| FitDatasetError::Compared { index, source })
        })
        .collect::<Result<_, _>>()?;
    Ok(FitOutcome { prepared, identified, lines, three_segment, compared_rss })
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
    Ok(Fit {
        params,
        identifiable: params.identifiable(reference_amplitude)?,
        reference_amplitude,
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
    let (var_t, var_theta) = (noise.torque_nm.powi(2), noise.deflection_rad.powi(2));
    weights.clear();
    // At once, not by doubling: the first weights go into an empty buffer (unit weights are
    // not stored).
    weights.reserve_exact(data.theta.len());
    for i in 0..data.theta.len() {
        let stiffness = model.stiffness(data.theta[i], data.direction[i], data.amplitude[i])?;
        weights.push(1.0 / (var_t + var_theta * stiffness * stiffness).max(f64::MIN_POSITIVE));
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
