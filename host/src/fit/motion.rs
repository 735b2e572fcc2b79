//! Fits of the stateful models to recordings of any motion: the genetic kind with Madelung's
//! rules and the micro-slip kind. A fit takes one or more runs (recordings) that share one
//! parameter set; the model runs along each run from rest at its first sample, following the
//! run's reversals offline ([`crate::gear::step_offline`]), as `predict` runs it, and the least
//! squares count only the samples fitted ([`Role::Fitted`]).
//!
//! Both kinds' spring is the free-form spring of knots ([`super::spring`]), linear in the knots'
//! stiffnesses K_j ≥ 0, in x = θ − θ0 with each run's θ0 ([`Run::zero`]).
//!
//! - genetic: for a fixed r the model is linear in the K_j and k (h = w·k on every branch of
//!   half-width w), so each r is an exact solve on the spring's columns and the hysteretic part
//!   run with k = 1; r is searched by the swarm and polished by Brent on strided subsamples of
//!   the motion, then the linear parameters are solved on every sample.
//! - micro-slip: linear in the K_j and the elements' k_i on a log grid of 30 candidate slip
//!   deflections, so one non-negative least-squares solve (k_i ≥ 0) identifies it exactly. Of
//!   the candidates, those that never slip on a fitted sample are left out (within the data they
//!   are springs, their width not identified, and letting them slip beyond it would be a guess),
//!   and at most 16 of the others are kept (the joint's elements), those of largest k_i·d_i.
//!   In a fit of several runs where one starts at a standstill found in the data (not declared
//!   at rest), each element is [`START_STATES`] copies, so that the solve estimates that run's
//!   remanent start state; the model merges the copies.
//!
//! Every column c is taken where the model is evaluated: at θ_m, carried to the measured θ
//! along its slope, c(θ_m) + c′(θ_m)·(θ − θ_m), so the fitted model is exactly the one
//! `predict` runs. With a noise model, residuals are weighted by their total noise
//! 1/(σ_T² + σ_θ²·K²) with K the model's stiffness, refitted twice, as the loop fit does.
//!
//! **Subsamples.** Fed the monotone projection θ_m, both kinds' state after a sample depends
//! only on the turning points before it and on θ_m there, not on the samples between: a
//! subsample that keeps every turning point steps through exactly the states (and columns) of
//! the full run at the samples it keeps. So the searches run on a strided subsample with the
//! turning points kept (stepped, not counted), and only the final solve and the scores pass
//! over every sample, summing their normal equations as the samples come.
use super::spring::SpringBasis;
use super::{FitError, FitOptions, R_LIMIT};
use crate::gear::{step_offline, Projected, Projection, Reversals};
use crate::numeric::nnls::nnls_normal;
use crate::numeric::optimize::{brent, pso, PsoOptions};
use crate::prepare::NoiseModel;
use model_core::bouc_wen::{BoucWen, BoucWenMemory, BoucWenTerm};
use model_core::memory::{slip_grid, GeneticMemory, SlipElements};
use model_core::preisach::{self, CellMemory, Preisach, PreisachCells};
use model_core::{
    GearModel, Genetic, Hysteresis, Kind, Model, Params, SlipElement, Spring, SLIP_ELEMENTS, TURNING_POINTS,
};
use rayon::prelude::*;
use std::ops::Range;

mod kinks;
pub use kinks::{scan_kinks, Kink, KinkScan, KINK_PARAMETERS, MAX_KINKS, WIDE};

/// The swarm runs the genetic kind on a subsample of at most this many samples of the motion.
const SWARM_SAMPLES: usize = 4096;
/// The searches that only set weights or pick r (the genetic kind's polish, the micro-slip
/// kind's reweighting rounds before the last) run on at most this many samples.
const POLISH_SAMPLES: usize = 1 << 17;
/// The polish's tolerance in s = asinh(r).
const POLISH_TOLERANCE: f64 = 1e-8;
/// The polish's half-width in s around the r of a fit it starts from (`FitOptions::start`).
const START_HALF_WIDTH: f64 = 0.05;
/// Reweighting rounds for the total-noise weights.
const REWEIGHTINGS: usize = 2;
/// The smallest slip deflection of the micro-slip grid, in deflection-noise standard
/// deviations: elements that slip inside the noise cannot be told from it.
const SLIP_MIN_IN_NOISE_SIGMAS: f64 = 3.0;
/// Candidate slip deflections of the micro-slip fit, log-spaced over [`slip_range`]: finer than
/// the 16 elements the joint holds, so that the solve places them (`bench/real/FINDINGS.md` §3).
pub const SLIP_CANDIDATES: usize = 30;

/// What a sample counts for in a fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Run through (the model's state follows it) but neither fitted nor scored: before the
    /// motion's extremes wiped out an unknown start state.
    Unscored,
    /// In the least squares and the fit's RSS.
    Fitted,
    /// Scored apart (the held-out RMS), never fitted.
    HeldOut,
}

/// Consecutive scored samples of a run, fitted or held out.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Span {
    pub range: Range<usize>,
    pub held_out: bool,
}

/// One run of a fit: a recording's deflection and torque, its reversals, and which of its
/// samples are fitted, held out or not scored. The model starts at rest at its first sample, at
/// x = θ − `zero`; the model's torque is the measured one less `torque_offset`.
#[derive(Clone, Debug)]
pub struct Run<'a> {
    pub theta: &'a [f64],
    pub torque: &'a [f64],
    pub reversals: &'a Reversals,
    /// The scored samples: in order, not overlapping; samples in none are [`Role::Unscored`].
    pub spans: Vec<Span>,
    /// The run's θ0, rad.
    pub zero: f64,
    /// The torque sensor's offset in this run, N·m.
    pub torque_offset: f64,
    /// Each sample's total-noise weight, where fixed in advance ([`Motion::with_weights`]): the
    /// θ0 search weighs every θ0 it tries alike.
    pub weights: Option<&'a [f64]>,
    /// Whether the run starts at a standstill found in the data, not declared (`# start: rest`):
    /// the gear is still, but its elements may hold the remanence of the motion before the
    /// recording, so the micro-slip fit estimates their start state ([`START_STATES`]).
    pub remanent_start: bool,
}

impl<'a> Run<'a> {
    /// Every sample from `scored_from` on fitted; θ0 and the torque offset 0.
    pub fn fitted_from(theta: &'a [f64], torque: &'a [f64], reversals: &'a Reversals, scored_from: usize) -> Self {
        let spans = vec![Span { range: scored_from.min(theta.len())..theta.len(), held_out: false }];
        Run { theta, torque, reversals, spans, zero: 0.0, torque_offset: 0.0, weights: None, remanent_start: false }
    }

    /// The same run with θ0 `zero` (rad) and the torque sensor's offset `torque_offset` (N·m).
    pub fn with_origin(self, zero: f64, torque_offset: f64) -> Self {
        Run { zero, torque_offset, ..self }
    }

    /// The fitted samples, in order.
    fn fitted(&self) -> impl Iterator<Item = usize> + '_ {
        self.spans.iter().filter(|s| !s.held_out).flat_map(|s| s.range.clone())
    }

    /// How many samples are held out (`held_out`) or fitted.
    fn count(&self, held_out: bool) -> usize {
        self.spans.iter().filter(|s| s.held_out == held_out).map(|s| s.range.len()).sum()
    }

    /// Every sample in order with its projection and role.
    fn samples(&self) -> FullSamples<'_> {
        FullSamples {
            projection: self.reversals.project(self.theta),
            torque: self.torque,
            zero: self.zero,
            torque_offset: self.torque_offset,
            weights: self.weights,
            spans: &self.spans,
            span: 0,
            index: 0,
        }
    }
}

/// One or more runs sharing one parameter set, ready for the stateful fits.
#[derive(Clone, Debug)]
pub struct Motion<'a> {
    pub runs: Vec<Run<'a>>,
    pub noise: Option<NoiseModel>,
    /// The deflection's spread at rest, pooled over the runs' rest windows, rad (0 without):
    /// the knot rule's σθ where it exceeds the noise ([`super::spring`]).
    pub rest_jitter: f64,
}

/// A sample as a pass over a motion sees it.
#[derive(Clone, Copy, Debug)]
struct Sample {
    /// Index in its run.
    index: usize,
    /// x = θ − θ0 projected ([`Projected::theta_m`] is x_m).
    at: Projected,
    /// The measured torque less the run's offset, N·m.
    torque: f64,
    role: Role,
    /// The sample's total-noise weight where a subsample stored it, else 1.
    weight: f64,
}

/// The samples of a run, projected, with their roles.
struct FullSamples<'a> {
    projection: Projection<'a>,
    torque: &'a [f64],
    zero: f64,
    torque_offset: f64,
    weights: Option<&'a [f64]>,
    spans: &'a [Span],
    span: usize,
    index: usize,
}

impl Iterator for FullSamples<'_> {
    type Item = Sample;

    #[inline]
    fn next(&mut self) -> Option<Sample> {
        let at = self.projection.next()?;
        let at = Projected { theta_m: at.theta_m - self.zero, ..at };
        let index = self.index;
        self.index += 1;
        while self.spans.get(self.span).is_some_and(|s| s.range.end <= index) {
            self.span += 1;
        }
        let role = match self.spans.get(self.span) {
            Some(span) if span.range.start <= index => {
                if span.held_out {
                    Role::HeldOut
                } else {
                    Role::Fitted
                }
            }
            _ => Role::Unscored,
        };
        let weight = self.weights.and_then(|w| w.get(index).copied()).unwrap_or(1.0);
        Some(Sample { index, at, torque: *self.torque.get(index)? - self.torque_offset, role, weight })
    }
}

/// A run's samples in order: every one, or a stored subsample.
enum RunSamples<'a> {
    Full(FullSamples<'a>),
    Stored(std::slice::Iter<'a, Sample>),
}

impl Iterator for RunSamples<'_> {
    type Item = Sample;

    #[inline]
    fn next(&mut self) -> Option<Sample> {
        match self {
            RunSamples::Full(samples) => samples.next(),
            RunSamples::Stored(samples) => samples.next().copied(),
        }
    }
}

/// A strided subsample of every run (turning points kept, stepped but not counted), each
/// sample with its weight ([`Subsample::reweigh`]).
#[derive(Clone)]
struct Subsample {
    runs: Vec<Vec<Sample>>,
    /// Whether it holds every sample.
    whole: bool,
}

impl Subsample {
    /// Stores each sample's weight by `weighting`, its model stepped along the subsample alone:
    /// at the samples kept, the same state as along every sample.
    fn reweigh(&mut self, weighting: Weighting<'_>) -> Result<(), FitError> {
        self.runs.par_iter_mut().try_for_each(|run| -> Result<(), FitError> {
            let mut weigher = weighting.start()?;
            for sample in run.iter_mut() {
                sample.weight = weigher.weight(sample)?;
            }
            Ok(())
        })
    }
}

/// The samples a pass steps through.
#[derive(Clone, Copy)]
enum Source<'m> {
    Full(&'m Motion<'m>),
    Stored(&'m Subsample),
}

impl Source<'_> {
    /// `pass` over each run's samples (with the run's index in the motion), the runs in
    /// parallel; the results in run order.
    fn map_runs<A: Send>(&self, pass: impl Fn(usize, RunSamples<'_>) -> A + Sync) -> Vec<A> {
        match self {
            Source::Full(motion) => {
                motion.runs.par_iter().enumerate().map(|(k, run)| pass(k, RunSamples::Full(run.samples()))).collect()
            }
            Source::Stored(sub) => {
                sub.runs.par_iter().enumerate().map(|(k, run)| pass(k, RunSamples::Stored(run.iter()))).collect()
            }
        }
    }
}

/// How the fitted samples are weighted.
#[derive(Clone, Copy)]
enum Weighting<'a> {
    /// By the weight the sample carries (1, or what a subsample stored).
    Carried,
    /// By the total noise 1/(σ_T² + σ_θ²·K²), K the stiffness of `model` run along the motion.
    Model(&'a GearModel<f64>, NoiseModel),
    /// By the given weight of each sample of a one-run motion, by its index.
    Given(&'a [f64]),
}

/// The weight of each sample of one run, in order.
enum Weigher<'a> {
    Carried,
    Given(&'a [f64]),
    Model { evaluator: Box<model_core::Evaluator<f64>>, noise: NoiseModel },
}

impl<'a> Weighting<'a> {
    fn start(&self) -> Result<Weigher<'a>, FitError> {
        Ok(match *self {
            Weighting::Carried => Weigher::Carried,
            Weighting::Given(weights) => Weigher::Given(weights),
            Weighting::Model(model, noise) => Weigher::Model { evaluator: Box::new(model.evaluator(0.0)?), noise },
        })
    }
}

impl Weigher<'_> {
    /// The next sample's weight (the model's evaluator steps on every sample).
    #[inline]
    fn weight(&mut self, sample: &Sample) -> Result<f64, FitError> {
        match self {
            Weigher::Carried => Ok(sample.weight),
            Weigher::Given(weights) => Ok(weights.get(sample.index).copied().unwrap_or(0.0)),
            Weigher::Model { evaluator, noise } => {
                Ok(noise.weight(step_offline(evaluator.as_mut(), sample.at)?.stiffness))
            }
        }
    }
}

/// The normal equations of a solve: the Gram matrix, the right-hand side and Σ w·T² (the
/// weights' mean 1).
struct Equations {
    gram: Vec<f64>,
    rhs: Vec<f64>,
    tt: f64,
}

/// Weighted normal equations of the fitted samples: Σ w·x·xᵀ (upper triangle while summing),
/// Σ w·x·T, Σ w·T², and Σ w over how many samples.
#[derive(Clone)]
struct Normal {
    n: usize,
    gram: Vec<f64>,
    rhs: Vec<f64>,
    tt: f64,
    weight: f64,
    count: usize,
}

impl Normal {
    fn new(n: usize) -> Normal {
        Normal { n, gram: vec![0.0; n * n], rhs: vec![0.0; n], tt: 0.0, weight: 0.0, count: 0 }
    }

    #[inline]
    fn add(&mut self, x: &[f64], torque: f64, w: f64) {
        let n = self.n;
        // Row a of the upper triangle as slices, so that the products are summed in vector
        // registers (the same sums, element by element).
        for (a, (rhs, row)) in self.rhs.iter_mut().zip(self.gram.chunks_exact_mut(n)).enumerate() {
            let wa = w * x[a];
            *rhs += wa * torque;
            for (g, &xb) in row[a..].iter_mut().zip(&x[a..n]) {
                *g += wa * xb;
            }
        }
        self.tt += w * torque * torque;
        self.weight += w;
        self.count += 1;
    }

    fn merge(mut self, other: Normal) -> Normal {
        self.gram.iter_mut().zip(&other.gram).for_each(|(a, b)| *a += b);
        self.rhs.iter_mut().zip(&other.rhs).for_each(|(a, b)| *a += b);
        self.tt += other.tt;
        self.weight += other.weight;
        self.count += other.count;
        self
    }

    /// The symmetric Gram matrix, right-hand side and Σ w·T², with the weights normalised to a
    /// mean of 1 over the fitted samples.
    fn finish(mut self) -> Equations {
        let n = self.n;
        for a in 0..n {
            for b in 0..a {
                self.gram[a * n + b] = self.gram[b * n + a];
            }
        }
        let mean = if self.weight > 0.0 { self.weight / self.count as f64 } else { 1.0 };
        self.gram.iter_mut().for_each(|g| *g /= mean);
        self.rhs.iter_mut().for_each(|r| *r /= mean);
        Equations { gram: self.gram, rhs: self.rhs, tt: self.tt / mean }
    }
}

/// The fitted samples' normal equations over `source`, weighted by `weighting`, with the rows
/// that `make_row` gives: one row builder per run (by its index), called on every sample in
/// order (the columns' state follows the motion) to fill `x`.
fn normal_equations<R>(
    source: Source<'_>,
    n: usize,
    weighting: Weighting<'_>,
    make_row: impl Fn(usize) -> Result<R, FitError> + Sync,
) -> Result<Equations, FitError>
where
    R: FnMut(&Sample, &mut [f64]) -> Result<(), FitError>,
{
    let per_run = source.map_runs(|k, samples| -> Result<Normal, FitError> {
        let mut row = make_row(k)?;
        let mut weigher = weighting.start()?;
        let mut normal = Normal::new(n);
        let mut x = vec![0.0; n];
        for sample in samples {
            let w = weigher.weight(&sample)?;
            row(&sample, &mut x)?;
            if sample.role == Role::Fitted {
                normal.add(&x, sample.torque, w);
            }
        }
        Ok(normal)
    });
    let normal = per_run.into_iter().try_fold(Normal::new(n), |sum, run| run.map(|run| sum.merge(run)))?;
    Ok(normal.finish())
}

/// A stored subsample's fitted samples with the spring's columns fixed, for a search whose
/// every point changes one column only (the genetic kind's r, the Bouc–Wen shape): the spring's
/// rows, weighted, and the part of the normal equations without that column are made once, and
/// each point steps the column along the samples and sums its products with them. The same
/// equations, to the last bit, as [`normal_equations`] over the subsample with its carried
/// weights.
struct SearchRows {
    /// The columns: the spring's, then the one searched.
    n: usize,
    runs: Vec<SearchRun>,
}

struct SearchRun {
    /// Every sample's projection, in order: the searched column steps through them all.
    at: Vec<Projected>,
    /// The indices (in `at`) of the fitted samples, increasing.
    fitted: Vec<usize>,
    /// Per fitted sample, w·x_a for each spring column a.
    weighted: Vec<f64>,
    /// Per fitted sample, its weight and torque.
    weight: Vec<f64>,
    torque: Vec<f64>,
    /// The normal equations' sums without the searched column (its entries 0).
    fixed: Normal,
}

impl SearchRows {
    /// The rows of `sub` for `columns` (the spring's and one own column, no extras).
    fn new(sub: &Subsample, columns: &Columns) -> Result<SearchRows, FitError> {
        if columns.own.len() != 1 || !columns.extra.is_empty() {
            return Err(FitError::Degenerate);
        }
        let n = columns.len();
        let springs = columns.spring.len();
        let runs = sub
            .runs
            .par_iter()
            .map(|samples| {
                let fitted_count = samples.iter().filter(|s| s.role == Role::Fitted).count();
                let mut run = SearchRun {
                    at: Vec::with_capacity(samples.len()),
                    fitted: Vec::with_capacity(fitted_count),
                    weighted: Vec::with_capacity(fitted_count * springs),
                    weight: Vec::with_capacity(fitted_count),
                    torque: Vec::with_capacity(fitted_count),
                    fixed: Normal::new(n),
                };
                let mut x = vec![0.0; n];
                for (i, sample) in samples.iter().enumerate() {
                    run.at.push(sample.at);
                    if sample.role != Role::Fitted {
                        continue;
                    }
                    let w = sample.weight;
                    columns.row(sample, |own| own.fill(0.0), &mut x);
                    run.fixed.add(&x, sample.torque, w);
                    run.fitted.push(i);
                    run.weighted.extend(x.iter().take(springs).map(|&value| w * value));
                    run.weight.push(w);
                    run.torque.push(sample.torque);
                }
                run
            })
            .collect();
        Ok(SearchRows { n, runs })
    }

    /// The normal equations with the searched column that `column` gives: one column stepper per
    /// run, called on every sample in order.
    fn equations<C>(&self, column: impl Fn() -> Result<C, FitError> + Sync) -> Result<Equations, FitError>
    where
        C: FnMut(Projected) -> Result<f64, FitError>,
    {
        let n = self.n;
        let own = n - 1;
        let per_run: Vec<Result<Normal, FitError>> = self
            .runs
            .par_iter()
            .map(|run| {
                let mut step = column()?;
                let mut cross = vec![0.0; own];
                let (mut square, mut with_torque) = (0.0, 0.0);
                let mut next =
                    run.fitted.iter().copied().zip(run.weight.iter().zip(&run.torque)).enumerate().peekable();
                for (i, &at) in run.at.iter().enumerate() {
                    let h = step(at)?;
                    let Some((k, (_, (&w, &torque)))) = next.next_if(|(_, (index, _))| *index == i) else { continue };
                    let weighted = run.weighted.get(k * own..(k + 1) * own).ok_or(FitError::Degenerate)?;
                    for (sum, wx) in cross.iter_mut().zip(weighted) {
                        *sum += wx * h;
                    }
                    let wh = w * h;
                    with_torque += wh * torque;
                    square += wh * h;
                }
                let mut normal = run.fixed.clone();
                for (a, sum) in cross.into_iter().enumerate() {
                    normal.gram[a * n + own] = sum;
                }
                normal.gram[own * n + own] = square;
                normal.rhs[own] = with_torque;
                Ok(normal)
            })
            .collect();
        let normal = per_run.into_iter().try_fold(Normal::new(n), |sum, run| run.map(|run| sum.merge(run)))?;
        Ok(normal.finish())
    }
}

/// A stateful model fitted to a motion, with its errors.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionFit {
    pub model: GearModel<f64>,
    /// How many parameters the fit identified.
    pub parameters: usize,
    /// The samples fitted.
    pub n: usize,
    /// Unweighted RSS over the fitted samples, (N·m)².
    pub rss: f64,
    /// The weighted RSS the last solve minimised (weights of mean 1 over the fitted samples),
    /// (N·m)²: what a search over a parameter outside the solve (θ0) compares.
    pub misfit: f64,
    /// Unweighted RMS over the fitted samples, N·m.
    pub rms: f64,
    /// The held-out samples (none when every scored sample was fitted).
    pub held_out_samples: usize,
    /// RMS over the held-out samples, N·m.
    pub held_out_rms: Option<f64>,
    /// RSS of each held-out span (a run's contiguous held-out samples: a cycle, a leg or a
    /// whole run), (N·m)², runs in order: the pieces `auto` compares kinds on, pairwise.
    pub held_out_pieces: Vec<f64>,
    /// Evaluations of the model along the motion or a subsample of it (swarm and polish).
    pub evaluations: usize,
}

impl<'a> Motion<'a> {
    /// One run whose first `training` samples are fitted and the rest held out.
    pub fn training_prefix(
        theta: &'a [f64],
        torque: &'a [f64],
        reversals: &'a Reversals,
        training: usize,
        noise: Option<NoiseModel>,
    ) -> Self {
        let training = training.min(theta.len());
        let mut spans = vec![Span { range: 0..training, held_out: false }];
        if training < theta.len() {
            spans.push(Span { range: training..theta.len(), held_out: true });
        }
        Motion::with_spans(theta, torque, reversals, spans, noise)
    }

    /// One run whose samples are fitted or held out as `spans` say (`diagnose`'s interleaved
    /// cycles, [`super::held_out`]).
    pub fn with_spans(
        theta: &'a [f64],
        torque: &'a [f64],
        reversals: &'a Reversals,
        spans: Vec<Span>,
        noise: Option<NoiseModel>,
    ) -> Self {
        Motion {
            runs: vec![Run {
                theta,
                torque,
                reversals,
                spans,
                zero: 0.0,
                torque_offset: 0.0,
                weights: None,
                remanent_start: false,
            }],
            noise,
            rest_jitter: 0.0,
        }
    }

    /// The same runs with every scored sample fitted: the refit on all the data.
    pub fn all_fitted(&self) -> Motion<'a> {
        let mut all = self.clone();
        for run in &mut all.runs {
            run.spans.iter_mut().for_each(|span| span.held_out = false);
        }
        all
    }

    /// `fit`, solved on another motion (a strided copy of this one), scored on this one.
    pub fn rescore(&self, fit: MotionFit) -> Result<MotionFit, FitError> {
        self.score(fit.model, fit.parameters, fit.evaluations, fit.misfit)
    }

    /// Each run's total-noise weights 1/(σ_T² + σ_θ²·K²) along it, K the stiffness of `model`
    /// (on x) run from rest; none without a noise model.
    pub fn noise_weights(&self, model: &GearModel<f64>) -> Result<Option<Vec<Vec<f64>>>, FitError> {
        let Some(noise) = self.noise else { return Ok(None) };
        let weighting = Weighting::Model(model, noise);
        let per_run = Source::Full(self).map_runs(|_, samples| -> Result<Vec<f64>, FitError> {
            let mut weigher = weighting.start()?;
            samples.map(|sample| weigher.weight(&sample)).collect()
        });
        per_run.into_iter().collect::<Result<Vec<_>, _>>().map(Some)
    }

    /// The same runs with each sample's weight fixed to `weights` (one vector per run).
    pub fn with_weights<'w>(&self, weights: &'w [Vec<f64>]) -> Motion<'w>
    where
        'a: 'w,
    {
        let mut weighted = self.clone();
        for (run, weights) in weighted.runs.iter_mut().zip(weights) {
            run.weights = Some(weights);
        }
        weighted
    }

    /// The weighting of a fit that holds its start's nonlinear parameters: the weights the runs
    /// carry where fixed in advance, else those of the start `model` (on x).
    fn held_weighting<'m>(&self, model: &'m GearModel<f64>) -> Weighting<'m> {
        if self.runs.iter().all(|run| run.weights.is_some()) {
            Weighting::Carried
        } else {
            self.weighting(Some(model))
        }
    }

    /// Whether the searches of a fit run on a subsample of it ([`POLISH_SAMPLES`]): a refit of a
    /// kind fitted to most of its samples gains nothing from searching its nonlinear
    /// parameters again.
    pub fn is_long(&self) -> bool {
        self.runs.iter().map(|run| run.theta.len()).sum::<usize>() > POLISH_SAMPLES
    }

    /// Samples fitted, over every run.
    pub fn fitted(&self) -> usize {
        self.runs.iter().map(|run| run.count(false)).sum()
    }

    /// Samples held out, over every run.
    pub fn held_out(&self) -> usize {
        self.runs.iter().map(|run| run.count(true)).sum()
    }

    /// The fitted deflections from each run's θ0, x = θ − θ0, in order.
    fn fitted_x(&self) -> impl Iterator<Item = f64> + '_ {
        self.runs.iter().flat_map(|run| run.fitted().map(|i| run.theta[i] - run.zero))
    }

    /// The range of the fitted x, [lo, hi] rad, holding 0 (every run starts at x = 0 or passes
    /// it).
    pub fn fitted_range(&self) -> [f64; 2] {
        let (lo, hi) = self.fitted_x().fold((0.0f64, 0.0f64), |(lo, hi), x| (lo.min(x), hi.max(x)));
        [lo, hi]
    }

    /// The spring's columns of a fit to this motion: knots by the knot rule over the fitted range.
    pub fn spring_basis(&self) -> SpringBasis {
        SpringBasis::new(self.fitted_range(), self.knot_noise())
    }

    /// The σθ the knot rule spaces knots by: the deflection noise or the spread at rest.
    fn knot_noise(&self) -> f64 {
        self.noise.map_or(0.0, |n| n.deflection_rad).max(self.rest_jitter)
    }

    fn check(&self) -> Result<(), FitError> {
        let n = self.fitted();
        if n < super::MIN_POINTS {
            return Err(FitError::TooFewPoints { n, need: super::MIN_POINTS });
        }
        if self.fitted_x().all(|x| x == 0.0) {
            return Err(FitError::NoDeflection);
        }
        Ok(())
    }

    /// The largest |x| over the fitted samples: the columns' scale (each column in rad is divided
    /// by it, so that the normal equations are well conditioned).
    fn scale(&self) -> f64 {
        self.fitted_x().fold(0.0, |m, x| x.abs().max(m))
    }

    /// Every `stride`-th sample of each run from its first (fitted or held out as it is), and
    /// the turning points between them (stepped, not counted), of weight 1; every sample when
    /// the motion has at most `most`.
    fn subsample(&self, most: usize) -> Subsample {
        let total: usize = self.runs.iter().map(|run| run.theta.len()).sum();
        let stride = total.div_ceil(most.max(1)).max(1);
        let runs = self
            .runs
            .par_iter()
            .map(|run| {
                let mut turns = run.reversals.indices.iter().copied().peekable();
                let mut kept = Vec::with_capacity(run.theta.len().div_ceil(stride));
                for mut sample in run.samples() {
                    let on_grid = sample.index % stride == 0;
                    let turning = turns.next_if_eq(&sample.index).is_some();
                    if on_grid || turning {
                        if !on_grid {
                            sample.role = Role::Unscored;
                        }
                        kept.push(sample);
                    }
                }
                kept
            })
            .collect();
        Subsample { runs, whole: stride == 1 }
    }

    /// Every `stride`-th sample of each run and its turning points, as owned runs whose
    /// samples keep their roles (a sample kept only as a turning point is not scored), so that
    /// at most about `most` samples remain; none when the motion has at most `most`. A search
    /// that fits many times (θ0's) runs on it: the model's states at the samples kept are those
    /// of the full motion, up to the projection's running extreme over the samples dropped.
    pub fn strided(&self, most: usize) -> Option<StridedRuns> {
        let total: usize = self.runs.iter().map(|run| run.theta.len()).sum();
        let stride = total.div_ceil(most.max(1));
        if stride <= 1 {
            return None;
        }
        let runs = self
            .runs
            .iter()
            .map(|run| {
                let mut turns = run.reversals.indices.iter().copied().peekable();
                let mut strided = StridedRun {
                    theta: Vec::with_capacity(run.theta.len().div_ceil(stride)),
                    torque: Vec::with_capacity(run.theta.len().div_ceil(stride)),
                    reversals: Reversals { indices: Vec::new(), rising_first: run.reversals.rising_first },
                    spans: Vec::new(),
                };
                let mut roles = run.samples().map(|sample| sample.role);
                for (index, (&theta, &torque)) in run.theta.iter().zip(run.torque).enumerate() {
                    let role = roles.next().unwrap_or(Role::Unscored);
                    let on_grid = index % stride == 0;
                    let turning = turns.next_if_eq(&index).is_some();
                    if !(on_grid || turning) {
                        continue;
                    }
                    let at = strided.theta.len();
                    if turning {
                        strided.reversals.indices.push(at);
                    }
                    strided.push(theta, torque, if on_grid { role } else { Role::Unscored });
                }
                strided
            })
            .collect();
        Some(StridedRuns { runs })
    }

    /// Windows of whole legs (turning point to turning point) of the runs, about `travel` ranges
    /// of deflection in all, each run's windows one after the other and strided to about `most`
    /// samples in all (turning points kept): a search's copy of a motion whose path is longer,
    /// [`WINDOWS`] windows spread evenly along it. None when the motion's path is at most twice
    /// `travel` ranges (the range: the widest run's). See [`BOUC_WEN_TRAVEL`] for why.
    ///
    /// Between two windows the copy steps from the first's last turning point to the next's first
    /// in one step, and the samples of the next window's first [`LEAD_IN`] ranges of travel are
    /// run through but not scored: the state the model carries over the gap is not the one the
    /// motion left, and the lead-in forgets the difference (a window that starts at its run's
    /// first sample starts from the run's own start and keeps its roles).
    pub fn windowed(&self, most: usize, travel: f64) -> Option<StridedRuns> {
        let range = self
            .runs
            .iter()
            .map(|run| {
                let (lo, hi) =
                    run.theta.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| (l.min(t), h.max(t)));
                hi - lo
            })
            .fold(0.0, f64::max);
        if !(range > 0.0) {
            return None;
        }
        // Each run's legs: (first sample, last sample), the first a turning point or the run's
        // start, the last a turning point or the run's end. Leg k runs the way of the first leg
        // when k is even, the other way when odd.
        let legs: Vec<Vec<(usize, usize)>> = self
            .runs
            .iter()
            .map(|run| {
                let ends = run.reversals.indices.iter().copied().chain(run.theta.len().checked_sub(1));
                let mut start = 0;
                ends.filter_map(|end| {
                    let leg = (start < end).then_some((start, end));
                    start = start.max(end);
                    leg
                })
                .collect()
            })
            .collect();
        let moved =
            |r: usize, (start, end): (usize, usize)| (self.runs[r].theta[end] - self.runs[r].theta[start]).abs();
        let total: f64 = legs.iter().enumerate().flat_map(|(r, run)| run.iter().map(move |&leg| moved(r, leg))).sum();
        // Windows of a path up to twice `travel` would save little, and the copy's own path (its
        // windows and the steps between them) is never windowed again.
        if total <= 2.0 * travel * range {
            return None;
        }
        // The windows, as (run, first leg, legs), in order: each starts at the first leg that
        // begins at or after its share of the path and takes legs until it has travelled its
        // share of `travel` (or its run ends). After a window in the same run, the next starts
        // where the copy can turn from the first's last leg into it: a leg of the other
        // direction, starting beyond where the first ended (a maximum above, a minimum below).
        let per_window = travel * range / WINDOWS as f64;
        let mut windows: Vec<(usize, usize, usize)> = Vec::with_capacity(WINDOWS);
        let mut along = 0.0;
        for (r, run) in legs.iter().enumerate() {
            let theta = self.runs[r].theta;
            let mut last: Option<usize> = None;
            let mut k = 0;
            while k < run.len() && windows.len() < WINDOWS {
                let target = windows.len() as f64 * total / WINDOWS as f64;
                let joins = last.is_none_or(|j| {
                    let (end, start) = (run[j].1, run[k].0);
                    let rising = (j + 1) % 2 == 0;
                    (k - j) % 2 == 0 && if rising { theta[start] >= theta[end] } else { theta[start] <= theta[end] }
                });
                if along + 1e-12 * total < target || !joins {
                    along += moved(r, run[k]);
                    k += 1;
                    continue;
                }
                let (first, mut window) = (k, 0.0);
                while k < run.len() && window < per_window {
                    window += moved(r, run[k]);
                    k += 1;
                }
                along += window;
                windows.push((r, first, k - first));
                last = Some(k - 1);
            }
        }
        let kept: usize =
            windows.iter().map(|&(r, first, count)| legs[r][first + count - 1].1 + 1 - legs[r][first].0).sum();
        let stride = kept.div_ceil(most.max(1)).max(1);
        let lead = LEAD_IN * range;
        let runs = self
            .runs
            .iter()
            .enumerate()
            .map(|(r, run)| {
                let roles: Vec<Role> = run.samples().map(|sample| sample.role).collect();
                let mut copy = StridedRun {
                    theta: Vec::new(),
                    torque: Vec::new(),
                    reversals: Reversals { indices: Vec::new(), rising_first: run.reversals.rising_first },
                    spans: Vec::new(),
                };
                for &(_, first, count) in windows.iter().filter(|w| w.0 == r) {
                    let (start, end) = (legs[r][first].0, legs[r][first + count - 1].1);
                    // Where the lead-in ends: after whole legs of at least `lead` of travel.
                    let mut scored_from = start;
                    if start > 0 {
                        let mut lead_in = 0.0;
                        for &leg in &legs[r][first..first + count] {
                            if lead_in >= lead {
                                break;
                            }
                            lead_in += moved(r, leg);
                            scored_from = leg.1 + 1;
                        }
                    }
                    for index in start..=end {
                        let turning = index > start && run.reversals.indices.binary_search(&index).is_ok();
                        let on_grid = (index - start) % stride == 0;
                        if !(on_grid || turning || index == start) {
                            continue;
                        }
                        let at = copy.theta.len();
                        if index == start && at == 0 {
                            // The copy's first leg is the window's.
                            copy.reversals.rising_first = run.reversals.rising_first ^ (first % 2 == 1);
                        } else if turning || index == start {
                            copy.reversals.indices.push(at);
                        }
                        let role = roles.get(index).copied().unwrap_or(Role::Unscored);
                        let role = if on_grid && index >= scored_from { role } else { Role::Unscored };
                        copy.push(run.theta[index], run.torque[index], role);
                    }
                }
                copy
            })
            .collect();
        Some(StridedRuns { runs })
    }

    /// Errors of `model` (θ0 = 0: it runs on x) run along every run from rest, summed as the
    /// evaluator steps.
    fn score(
        &self,
        model: GearModel<f64>,
        parameters: usize,
        evaluations: usize,
        misfit: f64,
    ) -> Result<MotionFit, FitError> {
        let per_run = Source::Full(self).map_runs(|_, samples| -> Result<(f64, Vec<f64>), FitError> {
            let mut evaluator = model.evaluator(0.0)?;
            let (mut rss, mut held) = (0.0, Vec::new());
            let mut in_held_span = false;
            for sample in samples {
                let predicted = step_offline(&mut evaluator, sample.at)?.torque;
                let square = (sample.torque - predicted).powi(2);
                match sample.role {
                    Role::Fitted => rss += square,
                    Role::HeldOut => match held.last_mut() {
                        Some(piece) if in_held_span => *piece += square,
                        _ => held.push(square),
                    },
                    Role::Unscored => {}
                }
                in_held_span = sample.role == Role::HeldOut;
            }
            Ok((rss, held))
        });
        let (mut rss, mut held_out_pieces) = (0.0, Vec::new());
        for run in per_run {
            let (run_rss, run_held) = run?;
            rss += run_rss;
            held_out_pieces.extend(run_held);
        }
        let held: f64 = held_out_pieces.iter().sum();
        let (n, held_out_samples) = (self.fitted(), self.held_out());
        Ok(MotionFit {
            model,
            parameters,
            n,
            rss,
            misfit,
            rms: (rss / n.max(1) as f64).sqrt(),
            held_out_samples,
            held_out_rms: (held_out_samples > 0).then(|| (held / held_out_samples as f64).sqrt()),
            held_out_pieces,
            evaluations,
        })
    }

    /// The weighting of the reweighting round after `model`: by its total noise, when the
    /// motion has a noise model.
    fn weighting<'m>(&self, model: Option<&'m GearModel<f64>>) -> Weighting<'m> {
        match (model, self.noise) {
            (Some(model), Some(noise)) => Weighting::Model(model, noise),
            _ => Weighting::Carried,
        }
    }
}

/// A strided copy of a motion's runs ([`Motion::strided`]): owned samples, turning points kept.
pub struct StridedRuns {
    runs: Vec<StridedRun>,
}

struct StridedRun {
    theta: Vec<f64>,
    torque: Vec<f64>,
    reversals: Reversals,
    spans: Vec<Span>,
}

impl StridedRun {
    /// Appends a sample in `role`: a scored one joins the last span when that ends there and is
    /// held out alike.
    fn push(&mut self, theta: f64, torque: f64, role: Role) {
        let at = self.theta.len();
        self.theta.push(theta);
        self.torque.push(torque);
        if role == Role::Unscored {
            return;
        }
        let held_out = role == Role::HeldOut;
        match self.spans.last_mut() {
            Some(span) if span.range.end == at && span.held_out == held_out => span.range.end = at + 1,
            _ => self.spans.push(Span { range: at..at + 1, held_out }),
        }
    }
}

impl StridedRuns {
    /// The strided runs as a motion with `like`'s noise, θ0s and torque offsets.
    pub fn motion<'s>(&'s self, like: &Motion) -> Motion<'s> {
        let runs = self
            .runs
            .iter()
            .zip(&like.runs)
            .map(|(strided, run)| Run {
                theta: &strided.theta,
                torque: &strided.torque,
                reversals: &strided.reversals,
                spans: strided.spans.clone(),
                zero: run.zero,
                torque_offset: run.torque_offset,
                weights: None,
                remanent_start: run.remanent_start,
            })
            .collect();
        Motion { runs, noise: like.noise, rest_jitter: like.rest_jitter }
    }
}

/// The genetic model with k = 1 and no spring at decay ratio r, at rest: its hysteretic part
/// along the motion is the fit's column beside the spring's.
fn unit_hysteresis(r: f64) -> Result<GeneticMemory<f64, TURNING_POINTS>, FitError> {
    let unit = Params { c1: 0.0, c2: 0.0, c3: 0.0, alpha: 1.0 + r * r, beta: r, omega: 1.0 };
    Ok(GeneticMemory::new(Model::new(unit)?, 0.0))
}

/// The linear part of a fit: the spring's columns (K_j ≥ 0), the kind's own (`own`, with which
/// of them are ≥ 0) and the diagnosis' `extra` free columns.
struct Columns<'a> {
    spring: &'a SpringBasis,
    own: Vec<bool>,
    extra: &'a [&'a [f64]],
    scale: f64,
}

/// What one solve found: its coefficients (on the columns' scales) and weighted RSS.
struct Solved {
    coef: Vec<f64>,
    rss: f64,
}

impl Columns<'_> {
    fn len(&self) -> usize {
        self.spring.len() + self.own.len() + self.extra.len()
    }

    /// The columns of sample `sample` into `x`, the kind's own given by `own`: the spring's at
    /// x_m carried to x along their slopes, the kind's, the extras.
    #[inline]
    fn row(&self, sample: &Sample, own: impl FnOnce(&mut [f64]), x: &mut [f64]) {
        let (spring, rest) = x.split_at_mut(self.spring.len());
        self.spring.row(sample.at, self.scale, spring);
        let (kind, rest) = rest.split_at_mut(self.own.len());
        own(kind);
        for (value, column) in rest.iter_mut().zip(self.extra) {
            *value = column.get(sample.index).copied().unwrap_or(0.0);
        }
    }

    /// Solves `equations` with K_j ≥ 0 and the kind's bounds.
    fn solve(&self, equations: &Equations) -> Result<Solved, FitError> {
        let spring = self.spring.len();
        let nonnegative: Vec<bool> =
            (0..self.len()).map(|j| j < spring || self.own.get(j - spring).copied().unwrap_or(false)).collect();
        self.solve_bounded(equations, &nonnegative)
    }

    /// Solves `equations` with the coefficients `nonnegative` flags ≥ 0, the others free.
    fn solve_bounded(&self, equations: &Equations, nonnegative: &[bool]) -> Result<Solved, FitError> {
        equations.solve(nonnegative)
    }

    /// The spring of a solve's coefficients.
    fn spring(&self, coef: &[f64]) -> Result<Spring<f64>, FitError> {
        let stiffness: Vec<f64> = coef.iter().take(self.spring.len()).map(|c| c / self.scale).collect();
        Ok(self.spring.spring(&stiffness)?)
    }

    /// The kind's own coefficients of a solve.
    fn own<'c>(&self, coef: &'c [f64]) -> &'c [f64] {
        coef.get(self.spring.len()..self.spring.len() + self.own.len()).unwrap_or(&[])
    }
}

/// The exact least-squares genetic coefficients at r over `source` (spring, k) and
/// their weighted RSS.
fn genetic_at(source: Source<'_>, weighting: Weighting<'_>, columns: &Columns, r: f64) -> Result<Solved, FitError> {
    let equations = normal_equations(source, columns.len(), weighting, |_| {
        let mut hysteresis = unit_hysteresis(r)?;
        Ok(move |sample: &Sample, x: &mut [f64]| {
            let h = step_offline(&mut hysteresis, sample.at)?.torque;
            columns.row(sample, |own| own.fill(h), x);
            Ok(())
        })
    })?;
    columns.solve(&equations)
}

/// [`genetic_at`] on a subsample's search rows, with its carried weights.
fn genetic_on(rows: &SearchRows, columns: &Columns, r: f64) -> Result<Solved, FitError> {
    let equations = rows.equations(|| {
        let mut hysteresis = unit_hysteresis(r)?;
        Ok(move |at: Projected| Ok(step_offline(&mut hysteresis, at)?.torque))
    })?;
    columns.solve(&equations)
}

/// The genetic model (θ0 = 0) of a solve at r: canonical point ω = 1 at A = 1, α = k·(1 + r²),
/// so h = k per rad of half-width.
fn genetic_model(columns: &Columns, solved: &Solved, r: f64) -> Result<GearModel<f64>, FitError> {
    solved_model(columns, solved, |k| Hysteresis::Genetic(Genetic { alpha: k * (1.0 + r * r), beta: r, omega: 1.0 }))
}

/// The model (θ0 = 0) of a solve whose one own column is the hysteresis scaled by its
/// coefficient k: the spring of the solve and the hysteresis `of(k)`, validated.
fn solved_model(
    columns: &Columns,
    solved: &Solved,
    of: impl FnOnce(f64) -> Hysteresis<f64>,
) -> Result<GearModel<f64>, FitError> {
    let k = columns.own(&solved.coef).first().copied().ok_or(FitError::Degenerate)?;
    let model = GearModel { zero: 0.0, spring: columns.spring(&solved.coef)?, hysteresis: of(k) };
    model.validate()?;
    Ok(model)
}

/// Fits the genetic kind with Madelung's rules to `motion`: r by the swarm, or near the r of
/// `options.start` (a refit), then polished.
pub fn fit_genetic(motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    motion.check()?;
    let spring = motion.spring_basis();
    let columns = Columns { spring: &spring, own: vec![false], extra: &[], scale: motion.scale() };
    let s_limit = R_LIMIT.asinh();
    let objective =
        |rows: &SearchRows, s: f64| genetic_on(rows, &columns, s.sinh()).map_or(f64::INFINITY, |fit| fit.rss);
    let start = options.start.as_ref().and_then(|model| model.identifiable(1.0)).map(|id| id.r.asinh());
    if let (Some(s), Some(start), true) = (start, &options.start, options.hold_start) {
        let weighed_by = GearModel { zero: 0.0, ..*start };
        let solved = genetic_at(Source::Full(motion), motion.held_weighting(&weighed_by), &columns, s.sinh())?;
        let model = genetic_model(&columns, &solved, s.sinh())?;
        return motion.score(model, spring.len() + 2, 0, solved.rss);
    }
    let (mut s, mut half_width, mut evaluations) = match start {
        Some(s) => (s, START_HALF_WIDTH, 0),
        None => {
            // The swarm on a strided subsample: the same states at the samples it keeps.
            let coarse = SearchRows::new(&motion.subsample(SWARM_SAMPLES), &columns)?;
            let swarm = pso(
                |x| objective(&coarse, x[0]),
                &[(-s_limit, s_limit)],
                &PsoOptions {
                    particles: options.particles,
                    max_iterations: options.max_iterations,
                    stall_iterations: 12,
                    seed: options.seed,
                },
                |_, _| {},
            );
            (swarm.best[0], (3.0 * swarm.spread[0]).clamp(0.02, 0.1), swarm.evaluations)
        }
    };
    let rounds = if motion.noise.is_some() { 1 + REWEIGHTINGS } else { 1 };
    let mut polish = motion.subsample(POLISH_SAMPLES);
    // The model whose weights the last round used, and that round's model and constant.
    let mut weighed_by: Option<GearModel<f64>> = None;
    let mut fitted: Option<(GearModel<f64>, f64)> = None;
    for _ in 0..rounds {
        let previous = fitted.map(|(model, _)| model);
        polish.reweigh(motion.weighting(previous.as_ref()))?;
        let rows = SearchRows::new(&polish, &columns)?;
        let (lo, hi) = ((s - half_width).max(-s_limit), (s + half_width).min(s_limit));
        let (polished, _, used) = brent(|s| objective(&rows, s), lo, hi, POLISH_TOLERANCE);
        evaluations += used;
        s = polished;
        half_width = 0.05;
        let solved = genetic_on(&rows, &columns, s.sinh())?;
        fitted = Some((genetic_model(&columns, &solved, s.sinh())?, solved.rss));
        weighed_by = previous;
    }
    let (mut model, mut misfit) = fitted.ok_or(FitError::Degenerate)?;
    if !polish.whole {
        // The linear parameters at the polished r on every sample, with the same weights.
        let solved = genetic_at(Source::Full(motion), motion.weighting(weighed_by.as_ref()), &columns, s.sinh())?;
        (model, misfit) = (genetic_model(&columns, &solved, s.sinh())?, solved.rss);
    }
    // The knots. stiffnesses, h and r.
    motion.score(model, spring.len() + 2, evaluations, misfit)
}

/// The Bouc–Wen shape searched: ln z_max (rad), ρ = (β − γ)/(β + γ) and n, with A = 1 (only
/// k_h·z is identifiable: z scaled by s is A·s, β and γ by s^(1−n), with k_h/s).
const BOUC_WEN_RHO: f64 = 0.95;
/// The largest z_max searched, in half ranges of the fitted deflections: z must saturate within
/// each leg (from −z_max to z_max takes a travel of 2·z_max, half the range at most), so that the
/// stiffness at the range's edges is the spring's, which continues beyond it. With z_max up to the
/// half range, a 1 A run of the measured spring (a line within its noise) was fitted with z
/// unsaturated to the tips (n = 6, k_h·z standing in for a spring whose + side was left at 0),
/// and predicted its 2 A runs 9.4–10.8× worse than a straight line; at half of it, 0.94–0.96×
/// (`bash bench/real.sh`, table 3). At 0.625 and 0.75, 1-5 still blew up (1.9×, 3.9×).
const BOUC_WEN_Z_MAX_IN_HALF_RANGE: f64 = 0.5;
/// The sharpest transition to yield searched: OpenSees' default BoucWen uses n = 1 to 2; beyond
/// 6 the branch is elastic-perfectly-plastic to within the noise.
const BOUC_WEN_N_MAX: f64 = 6.0;
/// The path a Bouc–Wen search steps along, in ranges of deflection ([`Motion::windowed`]): a
/// long recording's windows. A candidate's cost is its sub-steps, one per z_max/16 of travel until
/// z settles (up to ≈ 600/n a leg), whatever the subsample's stride: the search over every leg of
/// a 2 M-sample recording of bench/scale.sh (2000 legs) took 20 s where 20 k samples (20 legs)
/// took 0.4 s. 32 ranges: 16 cycles of the widest run, 12 of them scored, 3 times the 4 cycles
/// the prediction corpus fits on.
pub const BOUC_WEN_TRAVEL: f64 = 32.0;
/// The path of a long motion the last round of the Bouc–Wen polish steps along, in ranges of
/// deflection: 4 times [`BOUC_WEN_TRAVEL`]. The shape is known to what its samples tell; on the
/// windows alone the fits of 2 M samples of simulate's bouc-wen gear (n = 1 and 2, random motion)
/// predicted up to 1.6 % worse than when the polish ran over every leg.
const BOUC_WEN_LAST_TRAVEL: f64 = 128.0;
/// Windows of [`Motion::windowed`], spread evenly along the motion.
const WINDOWS: usize = 4;
/// The travel, in ranges of deflection, that a window not at its run's start runs through before
/// it scores: z forgets a difference over a few z_max/A of travel (a factor e^(−n·u/u*) near its
/// bound), and z_max is at most a quarter of the range in the search.
const LEAD_IN: f64 = 2.0;
/// Coordinate passes of the polish over (ln z_max, ρ, n).
const BOUC_WEN_PASSES: usize = 2;
/// The Bouc–Wen polish's tolerance on each coordinate, as a fraction of its search range: 5·10⁻⁴
/// in ln z_max (0.05 % of z_max), 2·10⁻⁴ in ρ, 5·10⁻⁴ in n. Brent to [`POLISH_TOLERANCE`], 10⁻⁸,
/// took 35 evaluations a coordinate, 14 here, and the predictions of the fitted models moved by
/// at most 10⁻⁴ N·m (simulate's five gears fitted on the sine and the random motion, each
/// predicting five motions).
const BOUC_WEN_TOLERANCE: f64 = 1e-4;

/// The Bouc–Wen shape at a point of the search.
fn bouc_wen_shape(x: &[f64]) -> Option<BoucWen<f64>> {
    let [ln_z_max, rho, n] = x else { return None };
    let sum = ln_z_max.exp().powf(-*n);
    let shape = BoucWen { a: 1.0, beta: 0.5 * (1.0 + rho) * sum, gamma: 0.5 * (1.0 - rho) * sum, n: *n };
    shape.check().ok().map(|()| shape)
}

/// The exact least-squares Bouc–Wen coefficients (spring, k_h ≥ 0) for `shape` over `source`.
fn bouc_wen_at(
    source: Source<'_>,
    weighting: Weighting<'_>,
    columns: &Columns,
    shape: BoucWen<f64>,
) -> Result<Solved, FitError> {
    let equations = normal_equations(source, columns.len(), weighting, |_| {
        let mut z = BoucWenMemory::new(BoucWenTerm { stiffness: 1.0, shape })?;
        Ok(move |sample: &Sample, x: &mut [f64]| {
            let h = step_offline(&mut z, sample.at)?.torque / columns.scale;
            columns.row(sample, |own| own.fill(h), x);
            Ok(())
        })
    })?;
    columns.solve(&equations)
}

/// [`bouc_wen_at`] on a subsample's search rows, with its carried weights.
fn bouc_wen_on(rows: &SearchRows, columns: &Columns, shape: BoucWen<f64>) -> Result<Solved, FitError> {
    let equations = rows.equations(|| {
        let mut z = BoucWenMemory::new(BoucWenTerm { stiffness: 1.0, shape })?;
        Ok(move |at: Projected| Ok(step_offline(&mut z, at)?.torque / columns.scale))
    })?;
    columns.solve(&equations)
}

/// The Bouc–Wen model (θ0 = 0) of a solve.
fn bouc_wen_model(columns: &Columns, solved: &Solved, shape: BoucWen<f64>) -> Result<GearModel<f64>, FitError> {
    solved_model(columns, solved, |k| Hysteresis::BoucWen(BoucWenTerm { stiffness: k / columns.scale, shape }))
}

/// Fits the Bouc–Wen kind to `motion`: its shape (z_max, ρ, n) by the swarm on a strided
/// subsample, or that of `options.start` (a refit), polished coordinate by coordinate by Brent;
/// the spring and k_h ≥ 0 solved exactly at each point, as the genetic kind's are at each r.
pub fn fit_bouc_wen(motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    motion.check()?;
    let spring = motion.spring_basis();
    let columns = Columns { spring: &spring, own: vec![true], extra: &[], scale: motion.scale() };
    let parameters = spring.len() + 4;
    let objective = |rows: &SearchRows, x: &[f64]| {
        bouc_wen_shape(x).and_then(|shape| bouc_wen_on(rows, &columns, shape).ok()).map_or(f64::INFINITY, |fit| fit.rss)
    };
    let start = options.start.as_ref().and_then(|model| match model.hysteresis {
        Hysteresis::BoucWen(term) => {
            let sum = term.shape.beta + term.shape.gamma;
            Some(vec![term.shape.z_max().ln(), (term.shape.beta - term.shape.gamma) / sum, term.shape.n])
        }
        _ => None,
    });
    if let (Some(x), Some(start), true) = (&start, &options.start, options.hold_start) {
        let shape = bouc_wen_shape(x).ok_or(FitError::Degenerate)?;
        let weighed_by = GearModel { zero: 0.0, ..*start };
        let solved = bouc_wen_at(Source::Full(motion), motion.held_weighting(&weighed_by), &columns, shape)?;
        return motion.score(bouc_wen_model(&columns, &solved, shape)?, parameters, 0, solved.rss);
    }
    let (slip_min, half_range) = slip_range(motion);
    // Never below the smallest: a motion within a few σθ of noise keeps a search range.
    let z_max_max = (BOUC_WEN_Z_MAX_IN_HALF_RANGE * half_range).max(slip_min);
    let bounds = [(slip_min.ln(), z_max_max.ln()), (-BOUC_WEN_RHO, BOUC_WEN_RHO), (1.0, BOUC_WEN_N_MAX)];
    // A long motion is searched on windows of it ([`BOUC_WEN_TRAVEL`]), the linear parameters
    // then solved on every sample.
    let windows = motion.windowed(POLISH_SAMPLES, BOUC_WEN_TRAVEL);
    let windowed = windows.as_ref().map(|windows| windows.motion(motion));
    let search = windowed.as_ref().unwrap_or(motion);
    let (mut x, mut evaluations) = match start {
        Some(x) => (x, 0),
        None => {
            let coarse = SearchRows::new(&search.subsample(SWARM_SAMPLES), &columns)?;
            let swarm = pso(
                |x| objective(&coarse, x),
                &bounds,
                &PsoOptions {
                    particles: options.particles,
                    max_iterations: options.max_iterations,
                    stall_iterations: 12,
                    seed: options.seed,
                },
                |_, _| {},
            );
            (swarm.best, swarm.evaluations)
        }
    };
    // The last round, whose shape the fit keeps, polishes on more of a long motion: wider
    // windows, or all of it ([`BOUC_WEN_LAST_TRAVEL`]).
    let wide = windows.as_ref().and_then(|_| motion.windowed(POLISH_SAMPLES, BOUC_WEN_LAST_TRAVEL));
    let wide = wide.as_ref().map(|wide| wide.motion(motion));
    let last = match (&windowed, &wide) {
        (Some(_), Some(wide)) => wide,
        (Some(_), None) => motion,
        (None, _) => search,
    };
    let rounds = if motion.noise.is_some() { 1 + REWEIGHTINGS } else { 1 };
    let mut polish = search.subsample(POLISH_SAMPLES);
    let mut weighed_by: Option<GearModel<f64>> = None;
    let mut fitted: Option<(GearModel<f64>, f64)> = None;
    for round in 1..=rounds {
        let previous = fitted.map(|(model, _)| model);
        let on = if round == rounds { last } else { search };
        if round == rounds && windowed.is_some() {
            polish = on.subsample(POLISH_SAMPLES);
        }
        polish.reweigh(on.weighting(previous.as_ref()))?;
        let rows = SearchRows::new(&polish, &columns)?;
        for _ in 0..BOUC_WEN_PASSES {
            for (axis, &(lo, hi)) in bounds.iter().enumerate() {
                let half_width = 0.1 * (hi - lo);
                let centre = x.get(axis).copied().ok_or(FitError::Degenerate)?;
                let mut trial = x.clone();
                let (best, _, used) = brent(
                    |value| {
                        if let Some(slot) = trial.get_mut(axis) {
                            *slot = value;
                        }
                        objective(&rows, &trial)
                    },
                    (centre - half_width).max(lo),
                    (centre + half_width).min(hi),
                    BOUC_WEN_TOLERANCE * (hi - lo),
                );
                evaluations += used;
                if let Some(slot) = x.get_mut(axis) {
                    *slot = best;
                }
            }
        }
        let shape = bouc_wen_shape(&x).ok_or(FitError::Degenerate)?;
        let solved = bouc_wen_on(&rows, &columns, shape)?;
        fitted = Some((bouc_wen_model(&columns, &solved, shape)?, solved.rss));
        weighed_by = previous;
    }
    let (mut model, mut misfit) = fitted.ok_or(FitError::Degenerate)?;
    if windows.is_some() || !polish.whole {
        let shape = bouc_wen_shape(&x).ok_or(FitError::Degenerate)?;
        let solved = bouc_wen_at(Source::Full(motion), motion.weighting(weighed_by.as_ref()), &columns, shape)?;
        (model, misfit) = (bouc_wen_model(&columns, &solved, shape)?, solved.rss);
    }
    // The knots' stiffnesses, k_h, z_max, ρ and n.
    motion.score(model, parameters, evaluations, misfit)
}

/// The range of the candidate slip deflections for `motion`: from 3σ of the deflection noise
/// (at least 10⁻³ of the range) to half the range of the fitted deflections, rad.
pub fn slip_range(motion: &Motion) -> (f64, f64) {
    let [lo, hi] = motion.fitted_range();
    let half_range = (hi - lo) / 2.0;
    let noise = motion.noise.map_or(0.0, |n| n.deflection_rad);
    ((SLIP_MIN_IN_NOISE_SIGMAS * noise).max(1e-3 * half_range), half_range)
}

/// The start states a micro-slip element may hold at the first sample of a run with a
/// remanent start ([`Run::remanent_start`]), as fractions of its slip deflection d: in the fit,
/// each element is one copy per start state, and the solve spreads its k over the copies, an
/// estimate of the run's unknown start state linear in the k's (issue 16 item 3, "estimate it";
/// `bench/real/FINDINGS.md` §3: the measured runs start at the remanence of the run before).
/// The model merges the copies: k = Σ copies, one element from rest, as `predict` runs it.
pub const START_STATES: [f64; 5] = [-1.0, -0.5, 0.0, 0.5, 1.0];
/// Ridge on the copies' columns, relative to their Gram diagonal (unit-norm columns): the
/// copies of a width that the fitted runs cannot tell apart share their k by it, not by
/// round-off. The prototype's (`bench/real/FINDINGS.md` §3: 1e-9·Σy² on these runs' 1.3e5
/// (N·m)²). The held-out runs move with it (`bench/real.sh`, 4-4: 1.24 at 1e-5, 1.20 at 1e-4,
/// 1.04 at 3e-4; 2-4: 0.11, 0.13, 0.17).
const COPY_RIDGE: f64 = 1e-4;

/// The micro-slip fit's elements: the candidate grid, which of the candidates are columns, and
/// how many start-state copies each has.
#[derive(Clone, Debug)]
struct Elements {
    grid: [f64; SLIP_CANDIDATES],
    /// Indices into `grid`, increasing.
    kept: Vec<usize>,
    /// Per run of the motion: whether its start state is estimated ([`Run::remanent_start`]).
    remanent: Vec<bool>,
    /// Columns per kept element: [`START_STATES`]`.len()` where a run's start state is
    /// estimated (several runs, one of them remanent), else 1 (copies that all start at rest
    /// would be one column repeated).
    copies: usize,
}

/// Unit-stiffness elasto-slip elements that may start away from rest: copy c of element i
/// starts at e = s0 (the column e − s0 is 0 there, like every other column at rest) and
/// steps as [`SlipElements::step`] does.
struct StartedElements {
    slip: Vec<f64>,
    start: Vec<f64>,
    elastic: Vec<f64>,
    theta: f64,
}

impl StartedElements {
    /// The copies of the kept elements of `elements` for run `run`, at x = 0.
    fn new(elements: &Elements, run: usize) -> StartedElements {
        // One column per element (no run's start state estimated) is the element from rest.
        let remanent = elements.copies > 1 && elements.remanent.get(run).copied().unwrap_or(false);
        let (mut slip, mut start) = (Vec::new(), Vec::new());
        for &i in &elements.kept {
            let d = elements.grid[i];
            for fraction in START_STATES.iter().take(elements.copies) {
                slip.push(d);
                start.push(if remanent { fraction * d } else { 0.0 });
            }
        }
        StartedElements { elastic: start.clone(), slip, start, theta: 0.0 }
    }

    /// Moves to x (rad): e ← clamp(e + Δx, −d, d).
    fn step(&mut self, theta: f64) -> Result<(), FitError> {
        if !theta.is_finite() {
            return Err(model_core::Error::NonFiniteDeflection.into());
        }
        let delta = theta - self.theta;
        for (e, &d) in self.elastic.iter_mut().zip(&self.slip) {
            let moved = *e + delta;
            *e = if moved >= d {
                d
            } else if moved <= -d {
                -d
            } else {
                moved
            };
        }
        self.theta = theta;
        Ok(())
    }

    /// Each copy's column at x_m carried `carried` along its slope (1 sticking, 0 slipping).
    fn columns(&self, carried: f64, scale: f64, into: &mut [f64]) {
        for (value, ((&e, &s0), &d)) in into.iter_mut().zip(self.elastic.iter().zip(&self.start).zip(&self.slip)) {
            *value = (e - s0 + if e.abs() < d { carried } else { 0.0 }) / scale;
        }
    }
}

impl Elements {
    /// The candidates that slip on a fitted sample of `motion` (a candidate that never slips
    /// there is a spring within the data, its width not identified).
    fn slipping(motion: &Motion) -> Result<Elements, FitError> {
        let (slip_min, slip_max) = slip_range(motion);
        let grid = slip_grid::<f64, SLIP_CANDIDATES>(slip_min, slip_max)?;
        let per_run = Source::Full(motion).map_runs(|_, samples| -> Result<[bool; SLIP_CANDIDATES], FitError> {
            let mut elements = SlipElements::new(grid)?;
            let mut slipped = [false; SLIP_CANDIDATES];
            for sample in samples {
                elements.step(sample.at.theta_m)?;
                if sample.role == Role::Fitted {
                    for (s, sticks) in slipped.iter_mut().zip(elements.sticking()) {
                        *s |= !sticks;
                    }
                }
            }
            Ok(slipped)
        });
        let mut slipped = [false; SLIP_CANDIDATES];
        for run in per_run {
            slipped.iter_mut().zip(run?).for_each(|(s, r)| *s |= r);
        }
        let remanent: Vec<bool> = motion.runs.iter().map(|run| run.remanent_start).collect();
        // One run alone (one cycle here) leaves its start state and its elements confounded:
        // fitted alone with copies, each measured run predicted its repeats worse (3–5 A mean
        // 0.24–0.58 → 0.34–1.00 N·m, `bench/real.sh` section 2); other runs pin the elements.
        let copies = if motion.runs.len() > 1 && remanent.contains(&true) { START_STATES.len() } else { 1 };
        Ok(Elements { grid, kept: (0..SLIP_CANDIDATES).filter(|&i| slipped[i]).collect(), remanent, copies })
    }

    /// The fit's columns of these elements: `copies` per kept element.
    fn columns(&self) -> usize {
        self.kept.len() * self.copies
    }

    /// Each kept element's k from its copies' (`per_copy`, one per column): their sum.
    fn merged(&self, per_copy: &[f64]) -> Vec<f64> {
        per_copy.chunks(self.copies).map(|copies| copies.iter().sum()).collect()
    }

    /// At most the joint's [`SLIP_ELEMENTS`] of the kept candidates: those of largest k_i·d_i
    /// (the torque each adds once it slips) among those a solve gave k_i > 0, or all of them;
    /// `stiffness` has one k per column (copies merged here).
    fn strongest(&self, stiffness: &[f64]) -> Elements {
        let merged = self.merged(stiffness);
        let mut active: Vec<(usize, f64)> =
            self.kept.iter().zip(&merged).filter(|(_, &k)| k > 0.0).map(|(&i, &k)| (i, k * self.grid[i])).collect();
        if active.len() > SLIP_ELEMENTS {
            active.sort_by(|a, b| b.1.total_cmp(&a.1));
            active.truncate(SLIP_ELEMENTS);
        }
        let mut kept: Vec<usize> = active.into_iter().map(|(i, _)| i).collect();
        kept.sort_unstable();
        Elements { kept, ..self.clone() }
    }

    /// The kept elements with stiffnesses `stiffness` (N·m/rad, one per column, the copies
    /// merged), k = 0 left out.
    fn model_elements(&self, stiffness: &[f64]) -> Vec<SlipElement<f64>> {
        self.kept
            .iter()
            .zip(self.merged(stiffness))
            .filter(|(_, k)| *k > 0.0)
            .map(|(&i, k)| SlipElement { slip: self.grid[i], stiffness: k })
            .collect()
    }
}

/// The micro-slip coefficients (spring, k_i ≥ 0 of the kept `elements`, the extras, the
/// offset) by one weighted non-negative least-squares solve on the fitted samples of `source`.
fn slip_solve(
    source: Source<'_>,
    weighting: Weighting<'_>,
    columns: &Columns,
    elements: &Elements,
) -> Result<Solved, FitError> {
    let mut equations = slip_equations(source, weighting, columns, elements)?;
    if elements.copies > 1 {
        let n = columns.len();
        let ridge = 1.0 + COPY_RIDGE;
        for j in columns.spring.len()..columns.spring.len() + columns.own.len() {
            equations.gram[j * n + j] *= ridge;
        }
    }
    columns.solve(&equations)
}

/// The weighted normal equations of [`slip_solve`].
fn slip_equations(
    source: Source<'_>,
    weighting: Weighting<'_>,
    columns: &Columns,
    elements: &Elements,
) -> Result<Equations, FitError> {
    normal_equations(source, columns.len(), weighting, |run| {
        let mut all = StartedElements::new(elements, run);
        Ok(move |sample: &Sample, x: &mut [f64]| {
            all.step(sample.at.theta_m)?;
            // e_i at x_m carried to x along its slope: 1 sticking, 0 slipping.
            columns.row(sample, |own| all.columns(sample.at.offset, columns.scale, own), x);
            Ok(())
        })
    })
}

/// The micro-slip model (θ0 = 0) of a solve.
fn slip_model(columns: &Columns, elements: &Elements, solved: &Solved) -> Result<GearModel<f64>, FitError> {
    let stiffness: Vec<f64> = columns.own(&solved.coef).iter().map(|c| c / columns.scale).collect();
    Ok(GearModel::micro_slip(0.0, columns.spring(&solved.coef)?, &elements.model_elements(&stiffness))?)
}

/// The micro-slip fit's columns and elements on `motion` with `extra` free columns: the
/// candidates that slip, solved once on `source`, then the strongest 16 of those the solve kept.
fn slip_columns<'a>(
    motion: &Motion,
    spring: &'a SpringBasis,
    extra: &'a [&'a [f64]],
    source: Source<'_>,
    weighting: Weighting<'_>,
) -> Result<(Columns<'a>, Elements), FitError> {
    let candidates = Elements::slipping(motion)?;
    let columns =
        |elements: &Elements| Columns { spring, own: vec![true; elements.columns()], extra, scale: motion.scale() };
    let first = columns(&candidates);
    let solved = slip_solve(source, weighting, &first, &candidates)?;
    let elements = candidates.strongest(first.own(&solved.coef));
    Ok((columns(&elements), elements))
}

/// The spring a [`micro_slip_with_columns`] solve may take.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpringShape {
    /// The knot rule's spring, its two sides free ([`Motion::spring_basis`]).
    Free,
    /// Knots mirrored about x = 0 over the larger side's extent, each side free
    /// ([`SpringBasis::mirrored_knots`]).
    MirroredFree,
    /// The same knots, forced point-symmetric: S(−x) = −S(x).
    MirroredSymmetric,
}

/// What [`micro_slip_with_columns`] found.
#[derive(Clone, Debug)]
pub struct ColumnsFit {
    /// The torque at each sample, N·m.
    pub predicted: Vec<f64>,
    /// The weighted residual sum of squares.
    pub chi2: f64,
    /// The fitted micro-slip model (without the extra columns).
    pub model: GearModel<f64>,
    /// Columns solved for: the spring's, the slip elements' and the extras.
    pub parameters: usize,
    /// The extra columns' coefficients, in their order.
    pub extra: Vec<f64>,
}

/// The micro-slip form with further free columns beside it (the diagnosis' torque effects), in
/// one least-squares solve with the given weights on every sample of one recording, following
/// its `reversals`, on a spring of the given `shape`. `weights` and the `extra` columns have a
/// value per sample; a sample of weight 0 is followed, not fitted.
pub fn micro_slip_with_columns(
    theta: &[f64],
    torque: &[f64],
    reversals: &Reversals,
    noise: Option<NoiseModel>,
    weights: &[f64],
    extra: &[&[f64]],
    shape: SpringShape,
) -> Result<ColumnsFit, FitError> {
    let motion = Motion::training_prefix(theta, torque, reversals, theta.len(), noise);
    motion.check()?;
    let spring = match shape {
        SpringShape::Free => motion.spring_basis(),
        SpringShape::MirroredFree => SpringBasis::mirrored_knots(motion.fitted_range(), motion.knot_noise(), false),
        SpringShape::MirroredSymmetric => SpringBasis::mirrored_knots(motion.fitted_range(), motion.knot_noise(), true),
    };
    let weighting = Weighting::Given(weights);
    let (columns, elements) = slip_columns(&motion, &spring, extra, Source::Full(&motion), weighting)?;
    let solved = slip_solve(Source::Full(&motion), weighting, &columns, &elements)?;
    let model = slip_model(&columns, &elements, &solved)?;
    let free: Vec<f64> = solved.coef.iter().skip(spring.len() + elements.columns()).copied().collect();
    let mut evaluator = model.evaluator(0.0)?;
    let mut chi2 = 0.0;
    let mut predicted = Vec::with_capacity(theta.len());
    for run in &motion.runs {
        for sample in run.samples() {
            let extras: f64 = extra.iter().zip(&free).map(|(column, c)| column[sample.index] * c).sum();
            let p = step_offline(&mut evaluator, sample.at)?.torque + extras;
            chi2 += weights.get(sample.index).copied().unwrap_or(0.0) * (sample.torque - p).powi(2);
            predicted.push(p);
        }
    }
    Ok(ColumnsFit { predicted, chi2, model, parameters: columns.len(), extra: free })
}

/// A form of the test of Masing's rule ([`masing_forms_with_columns`]).
#[derive(Clone, Debug)]
pub struct FormFit {
    /// The torque at each sample, N·m.
    pub predicted: Vec<f64>,
    /// The weighted residual sum of squares.
    pub chi2: f64,
    /// Columns solved for: the spring's, the hysteresis' and the extras.
    pub parameters: usize,
    /// The extra columns' coefficients, in their order.
    pub extra: Vec<f64>,
}

/// Relative ridge on the diagonal of the spring's and hysteresis' columns of
/// [`masing_forms_with_columns`], all of them free: the Preisach cells of one relay width
/// together are a slip element, an element wider than the motion is a spring, and the normal
/// equations' Cholesky factor needs such collinear columns told apart.
const FORM_RIDGE: f64 = 1e-9;

/// The two nested forms that test Masing's rule, each with further free columns beside it (the
/// diagnosis' torque effects), by one least-squares solve with the given weights on every sample
/// of one recording, following its `reversals`, on the knot rule's spring: `[Masing's, free]`.
/// Every coefficient is free of sign, the spring's too: these forms test Masing's rule, not
/// whether a gear dissipates or its spring stiffens.
///
/// - **Masing's:** every slip element of the micro-slip kind's candidate grid that slips on the
///   data, its stiffness of either sign. On a branch from a reversal an element of half-width d
///   adds k·min(u, d), u half the travel, so the branches are any curve 2f(u) with breakpoints
///   on the grid: with both signs this is every model that follows Masing's rule, not only the
///   dissipative ones (the micro-slip kind, k ≥ 0).
/// - **Free:** those elements and the Preisach kind's cells beside them, weights of either
///   sign (the kind's smoothness asked of the cells): relays that switch at places on the loop,
///   not at a travel from the last reversal, which Masing's rule cannot make.
///
/// Test forms, not gears: no model of them is evaluated, their torque is their columns' sum.
pub fn masing_forms_with_columns(
    theta: &[f64],
    torque: &[f64],
    reversals: &Reversals,
    noise: Option<NoiseModel>,
    weights: &[f64],
    extra: &[&[f64]],
) -> Result<[FormFit; 2], FitError> {
    let run = FormRun { theta, torque, reversals, weights, extra: extra.to_vec(), remanent_start: false };
    masing_forms_of_runs(&[run], noise)
}

/// One run of [`masing_forms_of_runs`]: its deflection (from its zero) and torque, its
/// reversals, each sample's weight, the free columns' values at its samples, and whether it
/// starts at a standstill found in the data ([`Run::remanent_start`]: among several runs, its
/// start state is estimated), else from rest.
pub struct FormRun<'a> {
    pub theta: &'a [f64],
    pub torque: &'a [f64],
    pub reversals: &'a Reversals,
    pub weights: &'a [f64],
    pub extra: Vec<&'a [f64]>,
    pub remanent_start: bool,
}

/// [`masing_forms_with_columns`] on several runs, sharing one spring and one set of elements
/// and cells; each run brings its own values of the free columns (as many for every run). Each
/// run starts from rest, or, where it starts at a standstill found in the data, at a start
/// state the slip elements' copies estimate ([`START_STATES`], as the micro-slip fit of several
/// runs does): the measured runs start at the remanence of the run before, and from rest
/// Masing's form missed their first legs by what the free form then fitted (`bench/real/`
/// `FINDINGS.md` §10). The forms' torque runs through the runs in turn.
pub fn masing_forms_of_runs(runs: &[FormRun], noise: Option<NoiseModel>) -> Result<[FormFit; 2], FitError> {
    let setting = FormSetting::of(runs, noise)?;
    let cells = Cells::moving(&setting.motion)?;
    let (masing, free) = rayon::join(|| setting.form(runs, None), || setting.form(runs, Some(&cells)));
    Ok([masing?, free?])
}

/// Masing's form of [`masing_forms_of_runs`] alone: a rate-independent hysteresis of any
/// Masing shape, the runs' own columns beside it (a rate effect tested across runs).
pub fn masing_form_of_runs(runs: &[FormRun], noise: Option<NoiseModel>) -> Result<FormFit, FitError> {
    FormSetting::of(runs, noise)?.form(runs, None)
}

/// What the forms of several runs share: the runs as one motion, the spring and the elements.
struct FormSetting<'a> {
    motion: Motion<'a>,
    spring: SpringBasis,
    elements: Elements,
    extras: usize,
}

impl<'a> FormSetting<'a> {
    fn of(runs: &[FormRun<'a>], noise: Option<NoiseModel>) -> Result<Self, FitError> {
        let extras = runs.first().map_or(0, |run| run.extra.len());
        if runs.iter().any(|run| run.extra.len() != extras) {
            return Err(FitError::Degenerate);
        }
        let motion = Motion {
            runs: runs
                .iter()
                .map(|run| Run {
                    weights: Some(run.weights),
                    remanent_start: run.remanent_start,
                    ..Run::fitted_from(run.theta, run.torque, run.reversals, 0)
                })
                .collect(),
            noise,
            rest_jitter: 0.0,
        };
        motion.check()?;
        let spring = motion.spring_basis();
        let elements = Elements::slipping(&motion)?;
        Ok(FormSetting { motion, spring, elements, extras })
    }

    /// The form with `cells` beside the elements (the free form) or without (Masing's).
    fn form(&self, runs: &[FormRun], cells: Option<&Cells>) -> Result<FormFit, FitError> {
        let (spring, elements, scale) = (&self.spring, &self.elements, self.motion.scale());
        let own = FormRows::width(elements, cells);
        // One set of columns per run: the same spring and hysteresis, the run's own extras.
        let of_run: Vec<Columns> =
            runs.iter().map(|run| Columns { spring, own: vec![false; own], extra: &run.extra, scale }).collect();
        let n = spring.len() + own + self.extras;
        let of_run_ref = &of_run;
        let mut equations = normal_equations(Source::Full(&self.motion), n, Weighting::Carried, |k| {
            let mut rows = FormRows::new(elements, cells, k)?;
            Ok(move |sample: &Sample, x: &mut [f64]| rows.fill(sample, &of_run_ref[k], x))
        })?;
        if let Some(cells) = cells {
            smooth_density(&mut equations, n, spring.len() + elements.columns(), cells);
        }
        for j in 0..spring.len() + own {
            equations.gram[j * n + j] *= 1.0 + FORM_RIDGE;
        }
        let solved = of_run.first().ok_or(FitError::Degenerate)?.solve_bounded(&equations, &vec![false; n])?;
        let mut predicted = Vec::with_capacity(runs.iter().map(|run| run.theta.len()).sum());
        let mut chi2 = 0.0;
        let mut x = vec![0.0; n];
        for (k, run) in self.motion.runs.iter().enumerate() {
            let mut rows = FormRows::new(elements, cells, k)?;
            for sample in run.samples() {
                rows.fill(&sample, &of_run[k], &mut x)?;
                let p: f64 = x.iter().zip(&solved.coef).map(|(a, b)| a * b).sum();
                chi2 += sample.weight * (sample.torque - p).powi(2);
                predicted.push(p);
            }
        }
        let extra = solved.coef[spring.len() + own..].to_vec();
        Ok(FormFit { predicted, chi2, parameters: n, extra })
    }
}

/// The hysteresis columns of a form of [`masing_forms_with_columns`] along one run: the slip
/// elements', then the Preisach cell groups' when there are cells.
struct FormRows<'c> {
    elements: StartedElements,
    cells: Option<(&'c Cells, CellMemory<f64, TURNING_POINTS>)>,
}

impl<'c> FormRows<'c> {
    fn new(elements: &Elements, cells: Option<&'c Cells>, run: usize) -> Result<Self, FitError> {
        let cells = match cells {
            Some(cells) => Some((cells, CellMemory::new(PreisachCells::new(cells.reach)?, 0.0))),
            None => None,
        };
        Ok(FormRows { elements: StartedElements::new(elements, run), cells })
    }

    /// The hysteresis columns a form of these rows has.
    fn width(elements: &Elements, cells: Option<&Cells>) -> usize {
        elements.columns() + cells.map_or(0, |c| c.groups.len())
    }

    /// Steps to `sample` and writes its row.
    fn fill(&mut self, sample: &Sample, columns: &Columns, x: &mut [f64]) -> Result<(), FitError> {
        self.elements.step(sample.at.theta_m)?;
        let switched = match &mut self.cells {
            Some((cells, memory)) => Some((*cells, memory.columns(sample.at.theta_m)?)),
            None => None,
        };
        let elements = &self.elements;
        columns.row(
            sample,
            |own| {
                let (slips, relays) = own.split_at_mut(elements.slip.len());
                elements.columns(sample.at.offset, columns.scale, slips);
                if let Some((cells, all)) = &switched {
                    for (value, group) in relays.iter_mut().zip(&cells.groups) {
                        *value = group.iter().map(|&c| all.value[c] + all.slope[c] * sample.at.offset).sum();
                    }
                }
            },
            x,
        );
        Ok(())
    }
}

/// The Preisach fit's cells: the grid's reach and the groups of cells that share one weight.
///
/// The grid spans the fitted x's larger side, R = max(−lo, hi). On the shorter side the data
/// reach only part of it: a cell with thresholds beyond the data has relays that never switch
/// (or switch over a sliver of the cell), and its weight, fitted on that sliver, came out at
/// 14 N·m beside its neighbours' 0.05 (`simulate`'s micro-slip gear, random motion: the sine to
/// the longer side's extent then predicted at 5.0 N·m RMS against micro-slip's 0.16). Such a cell
/// takes the weight of the nearest covered cell along the diagonal: relays of the same width,
/// their centres moved towards the data, as the spring continues with its edge's stiffness.
/// (The point mirror (α, β) → (−β, −α), a point-symmetric gear's, was tried first: on the
/// Preisach gear that grips harder on the + side, trained on the random motion, it predicted
/// the sine at 1.66× the floor, the shift at 1.08×.)
#[derive(Clone, Debug)]
struct Cells {
    reach: f64,
    /// Each fitted weight's cells ([`preisach::cell`]): one cell, or a covered cell and its
    /// uncovered mirror. Groups whose column never moves on a fitted sample are left out.
    groups: Vec<Vec<usize>>,
}

impl Cells {
    /// The grid over the fitted x's larger side and the groups whose column moves on a fitted
    /// sample of `motion`.
    fn moving(motion: &Motion) -> Result<Cells, FitError> {
        let covering = Cells::covering(motion)?;
        let grid = PreisachCells::new(covering.reach)?;
        let per_run = Source::Full(motion).map_runs(|_, samples| -> Result<[bool; preisach::CELLS], FitError> {
            let mut cells = CellMemory::<f64, TURNING_POINTS>::new(grid, 0.0);
            let mut moved = [false; preisach::CELLS];
            for sample in samples {
                let columns = cells.columns(sample.at.theta_m)?;
                if sample.role == Role::Fitted {
                    for (m, value) in moved.iter_mut().zip(&columns.value) {
                        *m |= *value != 0.0;
                    }
                }
            }
            Ok(moved)
        });
        let mut moved = [false; preisach::CELLS];
        for run in per_run {
            moved.iter_mut().zip(run?).for_each(|(m, r)| *m |= r);
        }
        Ok(covering.moved(&moved))
    }

    /// These groups less those whose cells never moved (`moved`, by cell).
    fn moved(mut self, moved: &[bool; preisach::CELLS]) -> Cells {
        self.groups.retain(|group| group.iter().any(|&c| moved[c]));
        self
    }

    /// The grid over the fitted x's larger side and every group of its cells.
    fn covering(motion: &Motion) -> Result<Cells, FitError> {
        let [lo, hi] = motion.fitted_range();
        let reach = hi.max(-lo);
        let n = preisach::INTERVALS;
        let h = 2.0 * reach / n as f64;
        // A cell is covered when the data span both its threshold intervals (to rounding).
        let slack = 1e-9 * reach;
        let covered =
            |i: usize, j: usize| -reach + (i + 1) as f64 * h <= hi + slack && -reach + j as f64 * h >= lo - slack;
        let mut groups: Vec<Vec<usize>> = Vec::new();
        // The covered cell an uncovered one takes its weight from, if any: along the diagonal,
        // towards the data, the same relay widths at the nearest centres.
        let source = |i: usize, j: usize| -> Option<(usize, usize)> {
            if covered(i, j) {
                return None;
            }
            let (mut a, mut b) = (i as isize, j as isize);
            let step: isize = if -reach + (i + 1) as f64 * h > hi + slack { -1 } else { 1 };
            loop {
                a += step;
                b += step;
                if a < 0 || b < 0 || a >= n as isize || b > a {
                    return None;
                }
                if covered(a as usize, b as usize) {
                    return Some((a as usize, b as usize));
                }
            }
        };
        for i in 0..n {
            for j in 0..=i {
                if source(i, j).is_none() {
                    groups.push(vec![preisach::cell(i, j)]);
                }
            }
        }
        for i in 0..n {
            for j in 0..=i {
                if let Some((si, sj)) = source(i, j) {
                    let from = preisach::cell(si, sj);
                    if let Some(group) = groups.iter_mut().find(|g| g[0] == from) {
                        group.push(preisach::cell(i, j));
                    }
                }
            }
        }
        Ok(Cells { reach, groups })
    }

    /// The density of a solve's own coefficients (one per group), N·m.
    fn density(&self, own: &[f64]) -> Preisach<f64> {
        let mut weights = [0.0; preisach::CELLS];
        for (group, &w) in self.groups.iter().zip(own) {
            for &c in group {
                weights[c] = w;
            }
        }
        Preisach { reach: self.reach, weights }
    }
}

/// The Preisach coefficients (spring, the kept cells' w ≥ 0) by one weighted non-negative
/// least-squares solve on the fitted samples of `source`: every cell's column along the motion
/// by Madelung's rules (model-core's [`CellMemory`], the evaluator's rules), at x_m carried to x
/// along its slope.
fn preisach_solve(
    source: Source<'_>,
    weighting: Weighting<'_>,
    columns: &Columns,
    cells: &Cells,
) -> Result<Solved, FitError> {
    let (mut equations, _) = preisach_equations(source, weighting, columns, cells)?;
    smooth_density(&mut equations, columns.len(), columns.spring.len(), cells);
    columns.solve(&equations)
}

/// The normal equations of [`preisach_solve`] without the smoothness, and which cells moved on a
/// fitted sample.
fn preisach_equations(
    source: Source<'_>,
    weighting: Weighting<'_>,
    columns: &Columns,
    cells: &Cells,
) -> Result<(Equations, [bool; preisach::CELLS]), FitError> {
    let grid = PreisachCells::new(cells.reach)?;
    let moved: [std::sync::atomic::AtomicBool; preisach::CELLS] = std::array::from_fn(|_| Default::default());
    let equations = normal_equations(source, columns.len(), weighting, |_| {
        let mut memory = CellMemory::<f64, TURNING_POINTS>::new(grid, 0.0);
        let mut seen = [false; preisach::CELLS];
        let moved = &moved;
        Ok(move |sample: &Sample, x: &mut [f64]| {
            let all = memory.columns(sample.at.theta_m)?;
            if sample.role == Role::Fitted {
                for ((seen, moved), value) in seen.iter_mut().zip(moved).zip(&all.value) {
                    if !*seen && *value != 0.0 {
                        *seen = true;
                        moved.store(true, std::sync::atomic::Ordering::Relaxed);
                    }
                }
            }
            columns.row(
                sample,
                |own| {
                    for (value, group) in own.iter_mut().zip(&cells.groups) {
                        *value = group.iter().map(|&c| all.value[c] + all.slope[c] * sample.at.offset).sum();
                    }
                },
                x,
            );
            Ok(())
        })
    })?;
    Ok((equations, moved.map(|m| m.into_inner())))
}

/// The smoothness asked of the Preisach density, relative to its columns' mean Gram diagonal:
/// Σ λ·(w_c/a_c − w_c'/a_c')² over cells c, c' that share an edge (a_c the cell's area in
/// squares, ½ on the diagonal). A motion identifies the density only along the triangles it
/// sweeps (a sine: the major loop's edges), and the least-squares density is anything in the
/// rest; with the penalty it is the smoothest that fits. On the prediction corpus' Preisach
/// fits (`bench/prediction.sh`), worst over the motions predicted, trained on the sine with
/// λ = 0 / 10⁻⁴ / 10⁻³ / 10⁻²: micro-slip gear 1.45 / 1.12 / 1.05 / 1.04× the floor, Preisach
/// gear 1.22 / 1.09 / 1.06 / 1.06×; trained on the random motion 1.07 / 1.07 / 1.06 / 1.05× and
/// 1.15 / 1.13 / 1.14 / 1.19×.
const DENSITY_SMOOTHING: f64 = 1e-3;

/// Adds [`DENSITY_SMOOTHING`]'s penalty to the equations of a solve of `n` columns whose
/// cells' groups start at column `first`.
fn smooth_density(equations: &mut Equations, n: usize, first: usize, cells: &Cells) {
    let own = cells.groups.len();
    let mean = (first..first + own).map(|j| equations.gram[j * n + j]).sum::<f64>() / own.max(1) as f64;
    let lambda = DENSITY_SMOOTHING * mean;
    // Each cell's group and area (a diagonal cell is half a square).
    let mut group_of = vec![None; preisach::CELLS];
    for (g, group) in cells.groups.iter().enumerate() {
        for &c in group {
            group_of[c] = Some(g);
        }
    }
    let m = preisach::INTERVALS;
    let area = |i: usize, j: usize| if i == j { 0.5 } else { 1.0 };
    for i in 0..m {
        for j in 0..=i {
            for (a, b) in [(i + 1, j), (i, j + 1)] {
                if a >= m || b > a {
                    continue;
                }
                let (Some(g1), Some(g2)) = (group_of[preisach::cell(i, j)], group_of[preisach::cell(a, b)]) else {
                    continue;
                };
                let (c1, c2) = (1.0 / area(i, j), -1.0 / area(a, b));
                let (k1, k2) = (first + g1, first + g2);
                equations.gram[k1 * n + k1] += lambda * c1 * c1;
                equations.gram[k2 * n + k2] += lambda * c2 * c2;
                equations.gram[k1 * n + k2] += lambda * c1 * c2;
                equations.gram[k2 * n + k1] += lambda * c1 * c2;
            }
        }
    }
}

/// The Preisach model (θ0 = 0) of a solve, validated.
fn preisach_model(columns: &Columns, cells: &Cells, solved: &Solved) -> Result<GearModel<f64>, FitError> {
    let model = GearModel {
        zero: 0.0,
        spring: columns.spring(&solved.coef)?,
        hysteresis: Hysteresis::Preisach(cells.density(columns.own(&solved.coef))),
    };
    model.validate()?;
    Ok(model)
}

/// Fits the Preisach kind to `motion`: the spring's stiffnesses and the density's weights on a
/// grid over the fitted range, linear in both, by one non-negative least-squares solve a round
/// (the swarm's options are not used); the rounds whose model only sets the next round's
/// weights run on a subsample, the last on every sample.
pub fn fit_preisach(motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    motion.check()?;
    let spring = motion.spring_basis();
    let scale = motion.scale();
    // The knots' stiffnesses and the weights a solve left above 0.
    let parameters = |model: &GearModel<f64>| match &model.hysteresis {
        Hysteresis::Preisach(density) => spring.len() + density.weights.iter().filter(|w| **w > 0.0).count(),
        _ => spring.len(),
    };
    if let (Some(start), true) = (&options.start, options.hold_start) {
        // One pass: the equations of every group of cells, and which cells moved; those of the
        // groups that never moved are then left out (their sums are the ones a pass without
        // them makes).
        let weighed_by = GearModel { zero: 0.0, ..*start };
        let covering = Cells::covering(motion)?;
        let all = Columns { spring: &spring, own: vec![true; covering.groups.len()], extra: &[], scale };
        let (equations, moved) =
            preisach_equations(Source::Full(motion), motion.held_weighting(&weighed_by), &all, &covering)?;
        let keep: Vec<usize> = (0..spring.len())
            .chain(
                covering
                    .groups
                    .iter()
                    .enumerate()
                    .filter(|(_, g)| g.iter().any(|&c| moved[c]))
                    .map(|(k, _)| spring.len() + k),
            )
            .collect();
        let cells = covering.moved(&moved);
        let columns = Columns { spring: &spring, own: vec![true; cells.groups.len()], extra: &[], scale };
        let mut equations = equations.selected(&keep);
        smooth_density(&mut equations, columns.len(), columns.spring.len(), &cells);
        let solved = columns.solve(&equations)?;
        let model = preisach_model(&columns, &cells, &solved)?;
        return motion.score(model, parameters(&model), 1, solved.rss);
    }
    let cells = Cells::moving(motion)?;
    let columns = Columns { spring: &spring, own: vec![true; cells.groups.len()], extra: &[], scale };
    let rounds = if motion.noise.is_some() { 1 + REWEIGHTINGS } else { 1 };
    let mut sub = motion.subsample(POLISH_SAMPLES);
    let mut fitted: Option<(GearModel<f64>, f64)> = None;
    for round in 1..=rounds {
        let weighting = motion.weighting(fitted.as_ref().map(|(model, _)| model));
        let solved = if round == rounds {
            preisach_solve(Source::Full(motion), weighting, &columns, &cells)?
        } else {
            sub.reweigh(weighting)?;
            preisach_solve(Source::Stored(&sub), Weighting::Carried, &columns, &cells)?
        };
        fitted = Some((preisach_model(&columns, &cells, &solved)?, solved.rss));
    }
    let (model, misfit) = fitted.ok_or(FitError::Degenerate)?;
    motion.score(model, parameters(&model), rounds, misfit)
}

/// A kind's fit to a motion.
type KindFit = fn(&Motion, &FitOptions) -> Result<MotionFit, FitError>;

/// How each kind is fitted to a motion: the one table of the kinds' fits.
const KIND_FITS: [(Kind, KindFit); 4] = [
    (Kind::Genetic, fit_genetic),
    (Kind::MicroSlip, fit_micro_slip),
    (Kind::BoucWen, fit_bouc_wen),
    (Kind::Preisach, fit_preisach),
];

/// Fits the model of kind `kind` to `motion`.
pub fn fit_kind(kind: Kind, motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    let (_, fit) = KIND_FITS.iter().find(|(each, _)| *each == kind).ok_or(FitError::Degenerate)?;
    fit(motion, options)
}

/// Fits the micro-slip kind to `motion` (one solve a round: the swarm's options are not used).
/// The candidates are chosen and the rounds whose model only sets the next round's weights run
/// on a subsample; the last round solves on every sample.
pub fn fit_micro_slip(motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    motion.check()?;
    let spring = if options.free_knots {
        placed_knots(motion, &motion.subsample(KNOT_SAMPLES), motion.spring_basis())?
    } else {
        motion.spring_basis()
    };
    let mut sub = motion.subsample(POLISH_SAMPLES);
    let (columns, elements) = slip_columns(motion, &spring, &[], Source::Stored(&sub), Weighting::Carried)?;
    if let (Some(start), true) = (&options.start, options.hold_start) {
        let weighed_by = GearModel { zero: 0.0, ..*start };
        let solved = slip_solve(Source::Full(motion), motion.held_weighting(&weighed_by), &columns, &elements)?;
        let model = slip_model(&columns, &elements, &solved)?;
        let parameters = spring.len() + 2 * model.slip_elements().len();
        return motion.score(model, parameters, 1, solved.rss);
    }
    let rounds = if motion.noise.is_some() { 1 + REWEIGHTINGS } else { 1 };
    let mut fitted: Option<(GearModel<f64>, f64)> = None;
    for round in 1..=rounds {
        let weighting = motion.weighting(fitted.as_ref().map(|(model, _)| model));
        let solved = if round == rounds {
            slip_solve(Source::Full(motion), weighting, &columns, &elements)?
        } else {
            sub.reweigh(weighting)?;
            slip_solve(Source::Stored(&sub), Weighting::Carried, &columns, &elements)?
        };
        fitted = Some((slip_model(&columns, &elements, &solved)?, solved.rss));
    }
    let (model, misfit) = fitted.ok_or(FitError::Degenerate)?;
    // The knots' stiffnesses and each element's k and d.
    let parameters = spring.len() + 2 * model.slip_elements().len();
    motion.score(model, parameters, rounds, misfit)
}

/// Points a side's knots may move to: the side's extent in this many steps.
const KNOT_GRID: usize = 64;
/// Passes over the knots.
const KNOT_PASSES: usize = 2;
/// Samples the knots are placed on (a subsample: the shape needs no more).
const KNOT_SAMPLES: usize = 1 << 13;
/// The shortest segment at an edge, as a fraction of the knot rule's there. Its stiffness is the
/// one the spring extrapolates with; fitted on a shorter stretch it followed the last samples'
/// noise and curvature (micro-slip gear trained on the random motion, sine predicted: the whole
/// segment 1.04× the floor, half of it 1.04×, free 2.46×; the catalogue gear, whose step at
/// 0.96 mrad lies in the + side's last segment there: 3.66×, 1.21×, 2.34×).
const EDGE_SEGMENT: f64 = 0.5;

/// The knot rule's knots, each interior one (not x = 0, not the range's edges) moved in turn to
/// the point of a fine grid between its neighbours (at least 10σθ from them) where
/// the micro-slip solve on the subsample has the least RSS: free knots, so that a stiffness that
/// steps (a catalogue gear's kinks) gets a pair of knots close around each step.
///
/// One pass over the subsample: its normal equations on the fine grid's knots (every point a
/// knot may sit at) and the slipping candidates. A spring on knots that are grid points is a
/// spring on the grid (its stiffness is piecewise linear between grid points too), so each
/// trial's equations are the fine ones mapped onto its knots, Mᵀ·G·M with M the trial's hats at
/// the grid points: a solve of ≤ 47 unknowns, not a pass over the samples.
fn placed_knots(motion: &Motion, sub: &Subsample, rule: SpringBasis) -> Result<SpringBasis, FitError> {
    let fine = fine_grid(&rule, KNOT_GRID);
    let fine_basis = rule.with_knots(fine.clone());
    let elements = Elements::slipping(motion)?;
    fn columns<'a>(spring: &'a SpringBasis, motion: &Motion, elements: &Elements) -> Columns<'a> {
        Columns { spring, own: vec![true; elements.columns()], extra: &[], scale: motion.scale() }
    }
    let fine_columns = columns(&fine_basis, motion, &elements);
    let equations = slip_equations(Source::Stored(sub), Weighting::Carried, &fine_columns, &elements)?;
    let rss = |knots: &[f64]| -> Result<f64, FitError> {
        let trial = rule.with_knots(knots.to_vec());
        let mapped = equations.mapped(&fine, knots, fine_columns.len());
        columns(&trial, motion, &elements).solve(&mapped).map(|solved| solved.rss)
    };
    let gap = super::spring::PLACED_KNOT_GAP_IN_NOISE * motion.noise.map_or(0.0, |n| n.deflection_rad);
    let mut knots = rule.knots().to_vec();
    let mut best = rss(&knots)?;
    for _ in 0..KNOT_PASSES {
        for j in 1..knots.len().saturating_sub(1) {
            if knots[j] == 0.0 {
                continue;
            }
            // The edge's segment gives the stiffness the spring extrapolates with: at least
            // EDGE_SEGMENT of the rule's.
            let (mut left, mut right) = (knots[j - 1] + gap, knots[j + 1] - gap);
            if j == 1 {
                left = left.max(knots[0] + EDGE_SEGMENT * (rule.knots()[1] - knots[0]));
            }
            if j + 2 == knots.len() {
                right = right.min(knots[j + 1] - EDGE_SEGMENT * (knots[j + 1] - rule.knots()[j]));
            }
            for &candidate in fine.iter().filter(|&&x| x > left && x < right && x != 0.0) {
                if candidate == knots[j] {
                    continue;
                }
                let mut trial = knots.clone();
                trial[j] = candidate;
                let trial_rss = rss(&trial)?;
                if trial_rss < best {
                    (best, knots) = (trial_rss, trial);
                }
            }
        }
    }
    Ok(rule.with_knots(knots))
}

/// The knots of `rule` and the points of a grid of `steps` a side over its range, increasing.
fn fine_grid(rule: &SpringBasis, steps: usize) -> Vec<f64> {
    let mut fine: Vec<f64> = rule.knots().to_vec();
    for step in 1..=steps {
        for extent in rule.range() {
            if extent != 0.0 {
                fine.push(extent * step as f64 / steps as f64);
            }
        }
    }
    fine.sort_by(f64::total_cmp);
    fine.dedup();
    fine
}

impl Equations {
    /// The least-squares coefficients, those `nonnegative` flags ≥ 0 and the others free, and
    /// their weighted RSS.
    fn solve(&self, nonnegative: &[bool]) -> Result<Solved, FitError> {
        let Equations { gram, rhs, tt } = self;
        let n = rhs.len();
        let coef = nnls_normal(gram, rhs, nonnegative).ok_or(FitError::Degenerate)?;
        if !coef.iter().all(|c| c.is_finite()) {
            return Err(FitError::Degenerate);
        }
        // ‖Ac − y‖² = yᵀy − 2cᵀAᵀy + cᵀAᵀAc, which holds at a bound as well.
        let quadratic: f64 = (0..n).map(|a| coef[a] * (0..n).map(|b| gram[a * n + b] * coef[b]).sum::<f64>()).sum();
        let linear: f64 = coef.iter().zip(rhs).map(|(c, r)| c * r).sum();
        let rss = (tt - 2.0 * linear + quadratic).max(0.0);
        Ok(Solved { rss, coef })
    }

    /// These equations on the columns `keep` (indices, increasing) alone.
    fn selected(&self, keep: &[usize]) -> Equations {
        let n = self.rhs.len();
        let gram = keep.iter().flat_map(|&a| keep.iter().map(move |&b| self.gram[a * n + b])).collect();
        Equations { gram, rhs: keep.iter().map(|&a| self.rhs[a]).collect(), tt: self.tt }
    }

    /// These equations, on columns whose first `fine.len()` are a spring's on the knots `fine`,
    /// mapped onto the spring on `knots` (each a point of `fine`): column c of the new spring is
    /// Σ_f h_c(fine_f)·column f; the columns after the spring's (of `n` in all) are kept.
    fn mapped(&self, fine: &[f64], knots: &[f64], n: usize) -> Equations {
        let (springs, coarse) = (fine.len(), knots.len());
        let m = coarse + n - springs;
        // M as (fine column, new column, weight): each grid point lies on at most two hats.
        let mut map: Vec<(usize, usize, f64)> = Vec::with_capacity(2 * springs + n);
        for (f, &x) in fine.iter().enumerate() {
            let right = knots.partition_point(|&k| k < x).min(coarse - 1);
            if knots[right] == x || right == 0 {
                map.push((f, right, 1.0));
            } else if x > knots[coarse - 1] {
                map.push((f, coarse - 1, 1.0));
            } else {
                let left = right - 1;
                let t = (x - knots[left]) / (knots[right] - knots[left]);
                map.push((f, left, 1.0 - t));
                map.push((f, right, t));
            }
        }
        map.extend((springs..n).map(|f| (f, f - springs + coarse, 1.0)));
        // G·M (n × m), then Mᵀ·(G·M) (m × m) and Mᵀ·r.
        let mut gm = vec![0.0; n * m];
        for &(f, c, w) in &map {
            for a in 0..n {
                gm[a * m + c] += self.gram[a * n + f] * w;
            }
        }
        let (mut gram, mut rhs) = (vec![0.0; m * m], vec![0.0; m]);
        for &(f, c, w) in &map {
            for b in 0..m {
                gram[c * m + b] += w * gm[f * m + b];
            }
            rhs[c] += w * self.rhs[f];
        }
        Equations { gram, rhs, tt: self.tt }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gear::run_offline;

    /// A motion of nested reversals from rest: a big sine with a smaller, faster one on top.
    fn nested(n: usize, amplitude: f64) -> Vec<f64> {
        (0..n)
            .map(|i| {
                let phase = std::f64::consts::TAU * 3.0 * i as f64 / n as f64;
                amplitude * (0.75 * phase.sin() + 0.25 * (9.0 * phase).sin())
            })
            .collect()
    }

    fn torque_of(model: &GearModel<f64>, theta: &[f64], reversals: &Reversals) -> Vec<f64> {
        run_offline(model, theta, reversals).unwrap().iter().map(|e| e.torque).collect()
    }

    /// An asymmetric spring on the knots the fit of `theta` places: softer on the + side, with a
    /// kink.
    fn asymmetric_spring(theta: &[f64]) -> Spring<f64> {
        let range = theta.iter().fold([0.0f64, 0.0f64], |[lo, hi], &t| [lo.min(t), hi.max(t)]);
        let knots: Vec<model_core::Knot<f64>> = super::super::spring::knot_rule(range[0], range[1], 0.0)
            .into_iter()
            .map(|x| model_core::Knot { x, stiffness: if x > 0.0 { 6000.0 + 4.0e6 * x } else { 9000.0 } })
            .collect();
        Spring::of_knots(&knots, range).unwrap()
    }

    /// Elements on every third candidate of the grid a fit of `theta` tries.
    fn elements_on_grid(theta: &[f64], reversals: &Reversals) -> Vec<SlipElement<f64>> {
        let noise = NoiseModel { torque_nm: 0.0, deflection_rad: 0.0 };
        let probe = Motion::training_prefix(theta, &[], reversals, theta.len(), Some(noise));
        let (slip_min, slip_max) = slip_range(&probe);
        let grid = slip_grid::<f64, SLIP_CANDIDATES>(slip_min, slip_max).unwrap();
        grid.iter()
            .step_by(3)
            .enumerate()
            .map(|(i, &slip)| SlipElement { slip, stiffness: 400.0 + 50.0 * i as f64 })
            .collect()
    }

    /// A nested motion and the torque of a micro-slip gear with an asymmetric spring along it.
    fn asymmetric_micro_slip_gear_on_nested_motion() -> (Vec<f64>, Reversals, Vec<f64>) {
        let theta = nested(6000, 1.2e-3);
        let reversals = crate::prepare::reversals(&theta);
        let truth =
            GearModel::micro_slip(0.0, asymmetric_spring(&theta), &elements_on_grid(&theta, &reversals)).unwrap();
        let torque = torque_of(&truth, &theta, &reversals);
        (theta, reversals, torque)
    }

    #[test]
    fn micro_slip_recovers_its_own_asymmetric_gear_exactly() {
        let (theta, reversals, torque) = asymmetric_micro_slip_gear_on_nested_motion();
        let motion = Motion::training_prefix(&theta, &torque, &reversals, theta.len(), None);
        let fitted = fit_micro_slip(&motion, &FitOptions::default()).unwrap();
        let scale = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(fitted.rms < 1e-6 * scale, "RMS {} of a peak {scale}: {:?}", fitted.model, fitted.rms);
        // The spring's two sides differ as the truth's do (the split of a constant stiffness
        // between the spring and elements that slip only at the extremes is not identified).
        let mut spring = fitted.model.spring.prepare().unwrap();
        let (plus, minus) = (spring.evaluate(1.0e-3).stiffness, spring.evaluate(-1.0e-3).stiffness);
        assert!((plus - minus - 1000.0).abs() < 1.0, "{plus} / {minus}");
    }

    /// The knot placement's shortcut: the normal equations on the fine grid mapped onto knots
    /// that are grid points are the normal equations on those knots.
    #[test]
    fn equations_on_the_fine_grid_map_exactly_onto_knots_among_its_points() {
        let (theta, reversals, torque) = asymmetric_micro_slip_gear_on_nested_motion();
        let motion = Motion::training_prefix(&theta, &torque, &reversals, theta.len(), None);
        let rule = motion.spring_basis();
        let [lo, hi] = rule.range();
        let grid = KNOT_GRID as i32;
        let mut fine: Vec<f64> =
            (-grid..=grid).map(|s| if s < 0 { -lo * s as f64 } else { hi * s as f64 } / KNOT_GRID as f64).collect();
        fine.sort_by(f64::total_cmp);
        // Knots among the grid's points, unevenly spaced.
        let knots: Vec<f64> = [0, 5, 30, 64, 70, 71, 100, 128].iter().map(|&f| fine[f]).collect();
        let elements = Elements::slipping(&motion).unwrap();
        let columns =
            |spring| Columns { spring, own: vec![true; elements.columns()], extra: &[], scale: motion.scale() };
        let (fine_basis, coarse) = (rule.with_knots(fine.clone()), rule.with_knots(knots.clone()));
        let on_fine = slip_equations(Source::Full(&motion), Weighting::Carried, &columns(&fine_basis), &elements);
        let mapped = on_fine.unwrap().mapped(&fine, &knots, columns(&fine_basis).len());
        let direct = slip_equations(Source::Full(&motion), Weighting::Carried, &columns(&coarse), &elements).unwrap();
        let largest = direct.gram.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        for (a, b) in mapped.gram.iter().zip(&direct.gram).chain(mapped.rhs.iter().zip(&direct.rhs)) {
            assert!((a - b).abs() <= 1e-9 * largest, "{a} vs {b}");
        }
        assert_eq!((mapped.gram.len(), mapped.rhs.len()), (direct.gram.len(), direct.rhs.len()));
    }

    /// Two runs, each from rest: the first ends loaded at its minimum, the second is a small
    /// motion about zero. Fitted together, each run from its own start, the micro-slip gear is
    /// recovered exactly; carried over from the first, the second run's state would be far off.
    #[test]
    fn each_run_starts_from_rest() {
        let first: Vec<f64> = (0..3001).map(|i| 1.2e-3 * (std::f64::consts::TAU * i as f64 / 4000.0).sin()).collect();
        let second = nested(4000, 0.3e-3);
        let reversals = [crate::prepare::reversals(&first), crate::prepare::reversals(&second)];
        let truth =
            GearModel::micro_slip(0.0, asymmetric_spring(&first), &elements_on_grid(&first, &reversals[0])).unwrap();
        let torque = [torque_of(&truth, &first, &reversals[0]), torque_of(&truth, &second, &reversals[1])];
        let motion = Motion {
            runs: vec![
                Run::fitted_from(&first, &torque[0], &reversals[0], 0),
                Run::fitted_from(&second, &torque[1], &reversals[1], 0),
            ],
            noise: None,
            rest_jitter: 0.0,
        };
        let fitted = fit_micro_slip(&motion, &FitOptions::default()).unwrap();
        assert_eq!(fitted.n, first.len() + second.len());
        assert!(fitted.rms < 1e-6 * 30.0, "RMS {}: {:?}", fitted.rms, fitted.model);
    }

    #[test]
    fn a_remanent_start_is_estimated_by_the_start_state_copies() {
        // The gear is run to +A, −A and back to 0 before the recording: at its first sample
        // (x = 0, standing still) every element of d ≤ A/2 holds +d, the remanence. The torque
        // sensor is zeroed there.
        let amplitude = 1.2e-3;
        let recorded: Vec<f64> =
            (0..4001).map(|i| amplitude * (std::f64::consts::TAU * i as f64 / 2000.0).sin()).collect();
        let reversals = crate::prepare::reversals(&recorded);
        let probe = Motion::training_prefix(&recorded, &[], &reversals, recorded.len(), None);
        let (slip_min, slip_max) = slip_range(&probe);
        let grid = slip_grid::<f64, SLIP_CANDIDATES>(slip_min, slip_max).unwrap();
        let elements: Vec<SlipElement<f64>> = grid
            .iter()
            .filter(|&&d| d <= amplitude / 2.0)
            .step_by(4)
            .enumerate()
            .map(|(i, &slip)| SlipElement { slip, stiffness: 400.0 + 50.0 * i as f64 })
            .collect();
        let truth = GearModel::micro_slip(0.0, asymmetric_spring(&recorded), &elements).unwrap();
        let history: Vec<f64> =
            (0..4001).map(|i| amplitude * (std::f64::consts::TAU * i as f64 / 4000.0).sin()).collect();
        let whole: Vec<f64> = history.iter().chain(&recorded[1..]).copied().collect();
        let along = torque_of(&truth, &whole, &crate::prepare::reversals(&whole));
        let torque = &along[history.len() - 1..];
        // Fitted jointly with a run from rest (one run alone leaves start and elements confounded).
        let virgin = nested(4000, amplitude);
        let virgin_reversals = crate::prepare::reversals(&virgin);
        let virgin_torque = torque_of(&truth, &virgin, &virgin_reversals);
        let fit = |remanent_start: bool| {
            let run = Run { remanent_start, ..Run::fitted_from(&recorded, torque, &reversals, 0) };
            let runs =
                vec![run.with_origin(0.0, torque[0]), Run::fitted_from(&virgin, &virgin_torque, &virgin_reversals, 0)];
            fit_micro_slip(&Motion { runs, noise: None, rest_jitter: 0.0 }, &FitOptions::default()).unwrap()
        };
        let (estimated, from_rest) = (fit(true), fit(false));
        let misfit_rms = |f: &MotionFit| (f.misfit / f.n as f64).sqrt();
        let peak = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(misfit_rms(&estimated) < 1e-3 * peak, "{} of {peak}", misfit_rms(&estimated));
        assert!(misfit_rms(&from_rest) > 10.0 * misfit_rms(&estimated), "{} of {peak}", misfit_rms(&from_rest));
        // The copies merged, from rest along the history and the recording: the truth's torque.
        let merged = torque_of(&estimated.model, &whole, &crate::prepare::reversals(&whole));
        let rms = (merged.iter().zip(&along).map(|(m, t)| (m - t).powi(2)).sum::<f64>() / whole.len() as f64).sqrt();
        assert!(rms < 1e-3 * peak, "merged RMS {rms} of {peak}");
    }

    #[test]
    fn masings_form_follows_runs_that_start_at_the_remanence_of_the_run_before() {
        // A Masing gear (micro-slip) recorded in three runs at three amplitudes, one after the
        // other, as the measured spring was: each run starts at x = 0, still, at the remanence
        // of the one before. Run from rest, Masing's form misses each first leg, and the
        // Preisach cells, which can switch anywhere, take that up: Masing's rule "broken" by a
        // gear that follows it.
        let amplitude = 1.2e-3;
        let sine = |a: f64, n: usize| -> Vec<f64> {
            (0..=n).map(|i| a * (std::f64::consts::TAU * i as f64 / n as f64).sin()).collect()
        };
        let runs: Vec<Vec<f64>> = [0.4, 1.0, 0.7].iter().map(|&a| sine(a * amplitude, 2000)).collect();
        let whole: Vec<f64> = runs.iter().flat_map(|run| run[1..].iter().copied()).collect();
        let theta: Vec<f64> = std::iter::once(0.0).chain(whole).collect();
        let elements = elements_on_grid(&theta, &crate::prepare::reversals(&theta));
        let truth = GearModel::micro_slip(0.0, asymmetric_spring(&theta), &elements).unwrap();
        // Before the first run, a loop larger than any of them.
        let history = sine(1.1 * amplitude, 2000);
        let along_all: Vec<f64> = history.iter().chain(&theta[1..]).copied().collect();
        let along = torque_of(&truth, &along_all, &crate::prepare::reversals(&along_all));
        let mut torque: Vec<Vec<f64>> = Vec::new();
        let mut at = history.len() - 1;
        for run in &runs {
            torque.push(along[at..at + run.len()].to_vec());
            at += run.len() - 1;
        }
        let reversals: Vec<Reversals> = runs.iter().map(|run| crate::prepare::reversals(run)).collect();
        let weights: Vec<Vec<f64>> = runs.iter().map(|run| vec![1.0; run.len()]).collect();
        // Each run's own torque offset (its sensor zeroed as it starts), zero on the others.
        let ones: Vec<Vec<f64>> = runs.iter().map(|run| vec![1.0; run.len()]).collect();
        let forms = |remanent_start: bool| {
            let form_runs: Vec<FormRun> = (0..runs.len())
                .map(|k| FormRun {
                    theta: &runs[k],
                    torque: &torque[k],
                    reversals: &reversals[k],
                    weights: &weights[k],
                    extra: (0..runs.len()).map(|j| if j == k { ones[k].as_slice() } else { &[][..] }).collect(),
                    remanent_start,
                })
                .collect();
            masing_forms_of_runs(&form_runs, None).unwrap()
        };
        let samples = weights.iter().map(Vec::len).sum::<usize>() as f64;
        let rms = |form: &FormFit| (form.chi2 / samples).sqrt();
        let peak = along.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        let [masing, free] = forms(true);
        assert!(rms(&masing) < 3e-3 * peak, "Masing's form from the remanence: RMS {} of {peak}", rms(&masing));
        assert!(rms(&free) > 0.9 * rms(&masing), "the cells fit {} against {}", rms(&free), rms(&masing));
        let [masing, free] = forms(false);
        assert!(rms(&masing) > 5e-3 * peak, "Masing's form from rest: RMS {} of {peak}", rms(&masing));
        assert!(rms(&free) < 0.7 * rms(&masing), "the cells fit {} against {}", rms(&free), rms(&masing));
    }

    #[test]
    fn genetic_recovers_its_own_asymmetric_gear_on_nested_motion() {
        let theta = nested(6000, 1.2e-3);
        let reversals = crate::prepare::reversals(&theta);
        let truth = GearModel {
            zero: 0.0,
            spring: asymmetric_spring(&theta),
            hysteresis: Hysteresis::Genetic(Genetic { alpha: 1.5 * (1.0 + 1.2 * 1.2), beta: 1.2, omega: 1.0 }),
        };
        let torque = torque_of(&truth, &theta, &reversals);
        let motion = Motion::training_prefix(&theta, &torque, &reversals, theta.len(), None);
        let fitted = fit_genetic(&motion, &FitOptions::default()).unwrap();
        let scale = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(fitted.rms < 1e-6 * scale, "RMS {} of a peak {scale}: {:?}", fitted.rms, fitted.model);
    }

    /// The Bouc–Wen gear of the recovery tests (n = 1.5, sub-steps, with z_max = 0.4 mrad and fat
    /// loops, ρ = 0.5) along `theta`, fitted: its torque, n, z_max and k_h recovered.
    fn bouc_wen_recovered(theta: &[f64]) {
        let reversals = crate::prepare::reversals(theta);
        let (z_max, rho, n) = (0.4e-3f64, 0.5, 1.5);
        let sum = z_max.powf(-n);
        let shape = BoucWen { a: 1.0, beta: 0.5 * (1.0 + rho) * sum, gamma: 0.5 * (1.0 - rho) * sum, n };
        let truth = GearModel {
            zero: 0.0,
            spring: asymmetric_spring(theta),
            hysteresis: Hysteresis::BoucWen(BoucWenTerm { stiffness: 1500.0, shape }),
        };
        let torque = torque_of(&truth, theta, &reversals);
        let motion = Motion::training_prefix(theta, &torque, &reversals, theta.len(), None);
        let fitted = fit_bouc_wen(&motion, &FitOptions::default()).unwrap();
        let scale = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(fitted.rms < 1e-3 * scale, "RMS {} of a peak {scale}: {:?}", fitted.rms, fitted.model);
        let Hysteresis::BoucWen(found) = fitted.model.hysteresis else { panic!("{:?}", fitted.model) };
        assert!((found.shape.n - n).abs() < 0.05, "{found:?}");
        assert!((found.shape.z_max() / z_max - 1.0).abs() < 0.02, "{found:?}");
        assert!((found.stiffness / 1500.0 - 1.0).abs() < 0.02, "{found:?}");
    }

    #[test]
    fn bouc_wen_recovers_its_own_asymmetric_gear_on_nested_motion() {
        bouc_wen_recovered(&nested(6000, 1.2e-3));
    }

    /// Twelve times the nested motion: searched on windows of it (`Motion::windowed`), the gear
    /// is recovered as from one.
    #[test]
    fn bouc_wen_recovers_its_own_gear_from_windows_of_a_long_motion() {
        let once = nested(6000, 1.2e-3);
        let theta: Vec<f64> = once.iter().cycle().take(12 * once.len()).copied().collect();
        let reversals = crate::prepare::reversals(&theta);
        let motion = Motion::training_prefix(&theta, &theta, &reversals, theta.len(), None);
        assert!(motion.windowed(POLISH_SAMPLES, BOUC_WEN_TRAVEL).is_some());
        bouc_wen_recovered(&theta);
    }

    /// Windows of a long motion: whole legs whose turning points still alternate, a window after
    /// a gap scored only after its lead-in, the roles of the samples kept otherwise; none of a
    /// short motion.
    #[test]
    fn windows_keep_whole_legs_and_score_after_their_lead_in() {
        let once = nested(6000, 1.2e-3);
        let reversals = crate::prepare::reversals(&once);
        let short = Motion::training_prefix(&once, &once, &reversals, once.len(), None);
        assert!(short.windowed(1000, BOUC_WEN_TRAVEL).is_none());
        let theta: Vec<f64> = once.iter().cycle().take(12 * once.len()).copied().collect();
        let reversals = crate::prepare::reversals(&theta);
        // Every fourth block of 1500 samples held out, as `auto` holds out cycles.
        let mut motion = Motion::training_prefix(&theta, &theta, &reversals, theta.len(), None);
        motion.runs[0].spans =
            (0..theta.len() / 1500).map(|b| Span { range: b * 1500..(b + 1) * 1500, held_out: b % 4 == 1 }).collect();
        let windows = motion.windowed(4000, BOUC_WEN_TRAVEL).unwrap();
        let copy = windows.motion(&motion);
        let run = &copy.runs[0];
        assert!(run.theta.len() < 4000 + reversals.indices.len(), "{}", run.theta.len());
        // Along the copy's legs θ rises to each maximum and falls to each minimum.
        let mut rising = run.reversals.rising_first;
        let mut from = run.theta[0];
        for &turn in &run.reversals.indices {
            let to = run.theta[turn];
            assert!(if rising { to >= from } else { to <= from }, "turn {turn}: {from} → {to}");
            (from, rising) = (to, !rising);
        }
        // The path it steps is about the budget's (the range here 2.4 mrad).
        let mut path = 0.0;
        let mut last = run.theta[0];
        for &turn in run.reversals.indices.iter().chain(Some(&(run.theta.len() - 1))) {
            path += (run.theta[turn] - last).abs();
            last = run.theta[turn];
        }
        let range = 2.0 * theta.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(path > 0.8 * BOUC_WEN_TRAVEL * range && path < 1.5 * BOUC_WEN_TRAVEL * range, "{path} of {range}");
        // Fitted and held-out samples both kept; some samples run through unscored (lead-ins).
        assert!(run.count(false) > 0 && run.count(true) > 0);
        assert!(run.count(false) + run.count(true) < run.theta.len());
    }

    /// A gear of the Preisach kind's own form (a smooth density that is not Masing: it grows with
    /// the relays' centre, on the grid a fit of the motion places) is recovered from a nested
    /// motion to within what the smoothness asked of the density costs, and predicts a biased
    /// one.
    #[test]
    fn preisach_recovers_its_own_gear_and_predicts_a_biased_motion() {
        let theta = nested(6000, 1.2e-3);
        let reversals = crate::prepare::reversals(&theta);
        let reach = theta.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        let mut weights = [0.0; preisach::CELLS];
        for i in 0..preisach::INTERVALS {
            for j in 0..=i {
                let area = if i == j { 0.5 } else { 1.0 };
                weights[preisach::cell(i, j)] = area * 0.05 * (1.0 + (i + j) as f64 / 8.0);
            }
        }
        let truth = GearModel {
            zero: 0.0,
            spring: asymmetric_spring(&theta),
            hysteresis: Hysteresis::Preisach(Preisach { reach, weights }),
        };
        let torque = torque_of(&truth, &theta, &reversals);
        let motion = Motion::training_prefix(&theta, &torque, &reversals, theta.len(), None);
        let fitted = fit_preisach(&motion, &FitOptions::default()).unwrap();
        let scale = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(fitted.rms < 2e-5 * scale, "RMS {} of a peak {scale}: {:?}", fitted.rms, fitted.model);
        // Oscillations about 0.4 mrad after a ramp: relays the nested motion switched, in loops
        // it never ran.
        let biased: Vec<f64> = (0..4000)
            .map(|i| {
                let t = i as f64 / 4000.0;
                let ramp = 0.4e-3 * (t / 0.2).min(1.0);
                ramp + if t > 0.2 { 0.3e-3 * (std::f64::consts::TAU * 4.0 * (t - 0.2)).sin() } else { 0.0 }
            })
            .collect();
        let turns = crate::prepare::reversals(&biased);
        let (want, got) = (torque_of(&truth, &biased, &turns), torque_of(&fitted.model, &biased, &turns));
        let error = want.iter().zip(&got).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        println!(
            "Preisach gear recovered: RMS {:.2e} N·m, biased motion worst {error:.2e} N·m, peak {scale:.2} N·m",
            fitted.rms
        );
        assert!(error < 1e-5 * scale, "biased motion: worst {error} N·m of a peak {scale}");
    }

    /// Each run's θ0 and torque offset place its samples: a gear recorded with its encoder zero
    /// at −8 mrad and its torque sensor reading +0.3 N·m is the same gear once placed.
    #[test]
    fn a_run_is_fitted_from_its_own_zero_and_offset() {
        let x = nested(6000, 1.2e-3);
        let reversals = crate::prepare::reversals(&x);
        let truth = GearModel::micro_slip(0.0, asymmetric_spring(&x), &elements_on_grid(&x, &reversals)).unwrap();
        let torque: Vec<f64> = torque_of(&truth, &x, &reversals).iter().map(|t| t + 0.3).collect();
        let theta: Vec<f64> = x.iter().map(|x| x - 8.0e-3).collect();
        let placed = Motion::training_prefix(&theta, &torque, &reversals, theta.len(), None);
        let mut placed_runs = placed.clone();
        placed_runs.runs[0] = placed_runs.runs[0].clone().with_origin(-8.0e-3, 0.3);
        let fitted = fit_micro_slip(&placed_runs, &FitOptions::default()).unwrap();
        assert!(fitted.rms < 1e-6 * 30.0, "RMS {}", fitted.rms);
        // Without them, the symmetric-about-0 spring of knots cannot follow.
        let unplaced = fit_micro_slip(&placed, &FitOptions::default()).unwrap();
        assert!(unplaced.rms > 1e3 * fitted.rms.max(1e-9), "{} vs {}", unplaced.rms, fitted.rms);
    }
}
