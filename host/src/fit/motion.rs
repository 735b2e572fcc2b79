//! Fits of the stateful models to recordings of any motion: the genetic kind with Madelung's
//! rules and the micro-slip kind. A fit takes one or more runs (recordings) that share one
//! parameter set; the model runs along each run from rest at its first sample, following the
//! run's reversals offline ([`crate::gear::step_offline`]), as `predict` runs it, and the least
//! squares count only the samples fitted ([`Role::Fitted`]).
//!
//! - genetic: for a fixed r the model is linear in c1, c2, c3 and k (h = w·k on every branch
//!   of half-width w), so each r is an exact 4-unknown solve on the columns θ, θ³, θ⁵ and the
//!   hysteretic part run with k = 1; r is searched by the swarm and polished by Brent on strided
//!   subsamples of the motion, then the linear parameters are solved on every sample.
//! - micro-slip: linear in (c1, c2, c3, k_1 … k_M) on a fixed log grid of slip deflections, so
//!   one non-negative least-squares solve (k_i ≥ 0) identifies it exactly.
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
use super::{FitError, FitOptions, R_LIMIT};
use crate::gear::{step_offline, Projected, Projection, Reversals};
use crate::numeric::linalg::Cholesky;
use crate::numeric::nnls::nnls_normal;
use crate::numeric::optimize::{brent, pso, PsoOptions};
use crate::prepare::NoiseModel;
use model_core::memory::{slip_grid, GeneticMemory, SlipElements, SlipParams};
use model_core::{GearModel, Identifiable, Kind, Model, Params, SLIP_ELEMENTS, TURNING_POINTS};
use rayon::prelude::*;
use std::ops::Range;

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
/// samples are fitted, held out or not scored. The model starts at rest at its first sample.
#[derive(Clone, Debug)]
pub struct Run<'a> {
    pub theta: &'a [f64],
    pub torque: &'a [f64],
    pub reversals: &'a Reversals,
    /// The scored samples: in order, not overlapping; samples in none are [`Role::Unscored`].
    pub spans: Vec<Span>,
}

impl<'a> Run<'a> {
    /// Every sample from `scored_from` on fitted.
    pub fn fitted_from(theta: &'a [f64], torque: &'a [f64], reversals: &'a Reversals, scored_from: usize) -> Self {
        let spans = vec![Span { range: scored_from.min(theta.len())..theta.len(), held_out: false }];
        Run { theta, torque, reversals, spans }
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
}

/// A sample as a pass over a motion sees it.
#[derive(Clone, Copy, Debug)]
struct Sample {
    /// Index in its run.
    index: usize,
    at: Projected,
    torque: f64,
    role: Role,
    /// The sample's total-noise weight where a subsample stored it, else 1.
    weight: f64,
}

/// The samples of a run, projected, with their roles.
struct FullSamples<'a> {
    projection: Projection<'a>,
    torque: &'a [f64],
    spans: &'a [Span],
    span: usize,
    index: usize,
}

impl Iterator for FullSamples<'_> {
    type Item = Sample;

    #[inline]
    fn next(&mut self) -> Option<Sample> {
        let at = self.projection.next()?;
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
        Some(Sample { index, at, torque: *self.torque.get(index)?, role, weight: 1.0 })
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
    /// `pass` over each run's samples, the runs in parallel; the results in run order.
    fn map_runs<A: Send>(&self, pass: impl Fn(RunSamples<'_>) -> A + Sync) -> Vec<A> {
        match self {
            Source::Full(motion) => motion.runs.par_iter().map(|run| pass(RunSamples::Full(run.samples()))).collect(),
            Source::Stored(sub) => sub.runs.par_iter().map(|run| pass(RunSamples::Stored(run.iter()))).collect(),
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
    Model { evaluator: Box<model_core::Evaluator<f64>>, var_t: f64, var_theta: f64 },
}

impl<'a> Weighting<'a> {
    fn start(&self) -> Result<Weigher<'a>, FitError> {
        Ok(match *self {
            Weighting::Carried => Weigher::Carried,
            Weighting::Given(weights) => Weigher::Given(weights),
            Weighting::Model(model, noise) => Weigher::Model {
                evaluator: Box::new(model.evaluator(0.0)?),
                var_t: noise.torque_nm.powi(2),
                var_theta: noise.deflection_rad.powi(2),
            },
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
            Weigher::Model { evaluator, var_t, var_theta } => {
                let stiffness = step_offline(evaluator.as_mut(), sample.at)?.stiffness;
                Ok(1.0 / (*var_t + *var_theta * stiffness * stiffness).max(f64::MIN_POSITIVE))
            }
        }
    }
}

/// Weighted normal equations of the fitted samples: Σ w·x·xᵀ (upper triangle while summing),
/// Σ w·x·T, Σ w·T², and Σ w over how many samples.
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
        for a in 0..n {
            let wa = w * x[a];
            self.rhs[a] += wa * torque;
            for b in a..n {
                self.gram[a * n + b] += wa * x[b];
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
    fn finish(mut self) -> (Vec<f64>, Vec<f64>, f64) {
        let n = self.n;
        for a in 0..n {
            for b in 0..a {
                self.gram[a * n + b] = self.gram[b * n + a];
            }
        }
        let mean = if self.weight > 0.0 { self.weight / self.count as f64 } else { 1.0 };
        self.gram.iter_mut().for_each(|g| *g /= mean);
        self.rhs.iter_mut().for_each(|r| *r /= mean);
        (self.gram, self.rhs, self.tt / mean)
    }
}

/// The fitted samples' normal equations over `source`, weighted by `weighting`, with the rows
/// that `make_row` gives: one row builder per run, called on every sample in order (the
/// columns' state follows the motion) to fill `x`.
fn normal_equations<R>(
    source: Source<'_>,
    n: usize,
    weighting: Weighting<'_>,
    make_row: impl Fn() -> Result<R, FitError> + Sync,
) -> Result<(Vec<f64>, Vec<f64>, f64), FitError>
where
    R: FnMut(&Sample, &mut [f64]) -> Result<(), FitError>,
{
    let per_run = source.map_runs(|samples| -> Result<Normal, FitError> {
        let mut row = make_row()?;
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
    /// Unweighted RMS over the fitted samples, N·m.
    pub rms: f64,
    /// The held-out samples (none when every scored sample was fitted).
    pub held_out_samples: usize,
    /// RMS over the held-out samples, N·m.
    pub held_out_rms: Option<f64>,
    /// Evaluations of the model along the motion or a subsample of it (swarm and polish).
    pub evaluations: usize,
}

impl<'a> Motion<'a> {
    /// One run whose first `training` samples (from `scored_from` on) are fitted and the rest
    /// held out.
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
        Motion { runs: vec![Run { theta, torque, reversals, spans }], noise }
    }

    /// The same runs with every scored sample fitted: the refit on all the data.
    pub fn all_fitted(&self) -> Motion<'a> {
        let mut all = self.clone();
        for run in &mut all.runs {
            run.spans.iter_mut().for_each(|span| span.held_out = false);
        }
        all
    }

    /// Samples fitted, over every run.
    pub fn fitted(&self) -> usize {
        self.runs.iter().map(|run| run.count(false)).sum()
    }

    /// Samples held out, over every run.
    pub fn held_out(&self) -> usize {
        self.runs.iter().map(|run| run.count(true)).sum()
    }

    /// The fitted deflections, in order.
    fn fitted_theta(&self) -> impl Iterator<Item = f64> + '_ {
        self.runs.iter().flat_map(|run| run.fitted().map(|i| run.theta[i]))
    }

    fn check(&self) -> Result<(), FitError> {
        let n = self.fitted();
        if n < super::MIN_POINTS {
            return Err(FitError::TooFewPoints { n, need: super::MIN_POINTS });
        }
        if self.fitted_theta().all(|t| t == 0.0) {
            return Err(FitError::NoDeflection);
        }
        Ok(())
    }

    /// The largest |θ| over the fitted samples: the scale of the polynomial's columns.
    fn scale(&self) -> f64 {
        self.fitted_theta().fold(0.0, |m, t| t.abs().max(m))
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

    /// Errors of `model` run along every run from rest, summed as the evaluator steps.
    fn score(&self, model: GearModel<f64>, parameters: usize, evaluations: usize) -> Result<MotionFit, FitError> {
        let per_run = Source::Full(self).map_runs(|samples| -> Result<(f64, f64), FitError> {
            let mut evaluator = model.evaluator(0.0)?;
            let (mut rss, mut held) = (0.0, 0.0);
            for sample in samples {
                let predicted = step_offline(&mut evaluator, sample.at)?.torque;
                let square = (sample.torque - predicted).powi(2);
                match sample.role {
                    Role::Fitted => rss += square,
                    Role::HeldOut => held += square,
                    Role::Unscored => {}
                }
            }
            Ok((rss, held))
        });
        let (rss, held) =
            per_run.into_iter().try_fold((0.0, 0.0), |(a, b), run| run.map(|(rss, held)| (a + rss, b + held)))?;
        let (n, held_out_samples) = (self.fitted(), self.held_out());
        Ok(MotionFit {
            model,
            parameters,
            n,
            rss,
            rms: (rss / n.max(1) as f64).sqrt(),
            held_out_samples,
            held_out_rms: (held_out_samples > 0).then(|| (held / held_out_samples as f64).sqrt()),
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

/// The genetic model with k = 1 and no spring at decay ratio r, at rest: its hysteretic part
/// along the motion is the fit's fourth column.
fn unit_hysteresis(r: f64) -> Result<GeneticMemory<f64, TURNING_POINTS>, FitError> {
    let unit = Params { c1: 0.0, c2: 0.0, c3: 0.0, alpha: 1.0 + r * r, beta: r, omega: 1.0 };
    Ok(GeneticMemory::new(Model::new(unit)?, 0.0))
}

/// The exact least-squares genetic parameters at r over `source`, and their weighted RSS.
fn genetic_at(
    source: Source<'_>,
    weighting: Weighting<'_>,
    scale: f64,
    r: f64,
) -> Result<(Params<f64>, f64), FitError> {
    let (gram, rhs, tt) = normal_equations(source, 4, weighting, || {
        let mut hysteresis = unit_hysteresis(r)?;
        Ok(move |sample: &Sample, x: &mut [f64]| {
            let h = step_offline(&mut hysteresis, sample.at)?.torque;
            // θ, θ³, θ⁵ at θ_m, carried to θ along their slopes.
            let (u, d) = (sample.at.theta_m / scale, sample.at.offset / scale);
            let (u2, u4) = (u * u, u * u * u * u);
            x.copy_from_slice(&[u + d, u * u2 + 3.0 * u2 * d, u * u4 + 5.0 * u4 * d, h]);
            Ok(())
        })
    })?;
    let coef = Cholesky::new(4, &gram).ok_or(FitError::Degenerate)?.solve(&rhs);
    if !coef.iter().all(|c| c.is_finite()) {
        return Err(FitError::Degenerate);
    }
    let explained: f64 = coef.iter().zip(&rhs).map(|(c, r)| c * r).sum();
    // Canonical point ω = 1 at A = 1: α = k·(1 + r²), so h = k per rad of half-width.
    let params = Params::from_identifiable(
        coef[0] / scale,
        coef[1] / scale.powi(3),
        coef[2] / scale.powi(5),
        Identifiable { h: coef[3], r },
        1.0,
    )?;
    Ok((params, (tt - explained).max(0.0)))
}

/// The genetic kind's identifiable parameters: c1, c2, c3, h and r.
const GENETIC_PARAMETERS: usize = 5;

/// Fits the genetic kind with Madelung's rules to `motion`: r by the swarm, or near the r of
/// `options.start` (a refit), then polished.
pub fn fit_genetic(motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    motion.check()?;
    let scale = motion.scale();
    let s_limit = R_LIMIT.asinh();
    let objective = |sub: &Subsample, s: f64| {
        genetic_at(Source::Stored(sub), Weighting::Carried, scale, s.sinh()).map_or(f64::INFINITY, |(_, rss)| rss)
    };
    let start = options.start.as_ref().and_then(|model| model.identifiable(1.0)).map(|id| id.r.asinh());
    let (mut s, mut half_width, mut evaluations) = match start {
        Some(s) => (s, START_HALF_WIDTH, 0),
        None => {
            // The swarm on a strided subsample: the same states at the samples it keeps.
            let coarse = motion.subsample(SWARM_SAMPLES);
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
    // The model whose weights the last round used, and that round's parameters.
    let (mut weighed_by, mut params): (Option<GearModel<f64>>, Option<Params<f64>>) = (None, None);
    for _ in 0..rounds {
        let previous = params.map(GearModel::Genetic);
        polish.reweigh(motion.weighting(previous.as_ref()))?;
        let (lo, hi) = ((s - half_width).max(-s_limit), (s + half_width).min(s_limit));
        let (polished, _, used) = brent(|s| objective(&polish, s), lo, hi, POLISH_TOLERANCE);
        evaluations += used;
        s = polished;
        half_width = 0.05;
        params = Some(genetic_at(Source::Stored(&polish), Weighting::Carried, scale, s.sinh())?.0);
        weighed_by = previous;
    }
    let mut params = params.ok_or(FitError::Degenerate)?;
    if !polish.whole {
        // The linear parameters at the polished r on every sample, with the same weights.
        params = genetic_at(Source::Full(motion), motion.weighting(weighed_by.as_ref()), scale, s.sinh())?.0;
    }
    motion.score(GearModel::Genetic(params), GENETIC_PARAMETERS, evaluations)
}

/// The slip grid for `motion`: from 3σ of the deflection noise (at least 10⁻³ of the range) to
/// half the range of the fitted deflections, rad.
pub fn slip_range(motion: &Motion) -> (f64, f64) {
    let (lo, hi) = motion.fitted_theta().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| (lo.min(t), hi.max(t)));
    let half_range = (hi - lo) / 2.0;
    let noise = motion.noise.map_or(0.0, |n| n.deflection_rad);
    ((SLIP_MIN_IN_NOISE_SIGMAS * noise).max(1e-3 * half_range), half_range)
}

/// Sample i's row of the micro-slip form (`elements` follow the motion): θ/S, (θ/S)³, (θ/S)⁵,
/// each element's e_i/S (on the scale of the polynomial's columns), each at θ_m and carried to
/// θ along its slope (1 for an element that sticks, 0 for one that slips), then `extra`.
fn slip_row(
    elements: &mut SlipElements<f64, SLIP_ELEMENTS>,
    scale: f64,
    extra: &[&[f64]],
    sample: &Sample,
    x: &mut [f64],
) -> Result<(), FitError> {
    let (u, d) = (sample.at.theta_m / scale, sample.at.offset / scale);
    let (u2, u4) = (u * u, u * u * u * u);
    x[..3].copy_from_slice(&[u + d, u * u2 + 3.0 * u2 * d, u * u4 + 5.0 * u4 * d]);
    elements.step(sample.at.theta_m)?;
    let sticking = elements.sticking();
    for ((value, e), sticks) in x[3..3 + SLIP_ELEMENTS].iter_mut().zip(elements.elastic()).zip(sticking) {
        *value = e / scale + if sticks { d } else { 0.0 };
    }
    for (value, column) in x[3 + SLIP_ELEMENTS..].iter_mut().zip(extra) {
        *value = column.get(sample.index).copied().unwrap_or(0.0);
    }
    Ok(())
}

/// The coefficients of the micro-slip form (k_i ≥ 0) and of `extra` free columns beside it,
/// by one weighted non-negative least-squares solve on the fitted samples of `source`.
fn slip_coefficients(
    source: Source<'_>,
    scale: f64,
    grid: &[f64; SLIP_ELEMENTS],
    weighting: Weighting<'_>,
    extra: &[&[f64]],
) -> Result<Vec<f64>, FitError> {
    let n = 3 + SLIP_ELEMENTS + extra.len();
    let nonnegative: Vec<bool> = (0..n).map(|j| (3..3 + SLIP_ELEMENTS).contains(&j)).collect();
    let (gram, rhs, _) = normal_equations(source, n, weighting, || {
        let mut elements = SlipElements::new(*grid)?;
        Ok(move |sample: &Sample, x: &mut [f64]| slip_row(&mut elements, scale, extra, sample, x))
    })?;
    nnls_normal(&gram, &rhs, &nonnegative).ok_or(FitError::Degenerate)
}

/// The micro-slip form with further free columns beside it (the diagnosis' torque effects), in
/// one least-squares solve with the given weights on every sample of one recording, following
/// its `reversals`: its torque at each sample and the weighted residual sum of squares.
/// `weights` and the `extra` columns have a value per sample.
pub fn micro_slip_with_columns(
    theta: &[f64],
    torque: &[f64],
    reversals: &Reversals,
    noise: Option<NoiseModel>,
    weights: &[f64],
    extra: &[&[f64]],
) -> Result<(Vec<f64>, f64), FitError> {
    let motion = Motion::training_prefix(theta, torque, reversals, theta.len(), noise);
    motion.check()?;
    let scale = motion.scale();
    let (slip_min, slip_max) = slip_range(&motion);
    let grid = slip_grid(slip_min, slip_max)?;
    let coef = slip_coefficients(Source::Full(&motion), scale, &grid, Weighting::Given(weights), extra)?;
    let mut x = vec![0.0; coef.len()];
    let mut elements = SlipElements::new(grid)?;
    let mut chi2 = 0.0;
    let mut predicted = Vec::with_capacity(theta.len());
    for run in &motion.runs {
        for sample in run.samples() {
            slip_row(&mut elements, scale, extra, &sample, &mut x)?;
            let p: f64 = x.iter().zip(&coef).map(|(a, b)| a * b).sum();
            chi2 += weights.get(sample.index).copied().unwrap_or(0.0) * (sample.torque - p).powi(2);
            predicted.push(p);
        }
    }
    Ok((predicted, chi2))
}

/// A kind's fit to a motion.
type KindFit = fn(&Motion, &FitOptions) -> Result<MotionFit, FitError>;

/// How each kind is fitted to a motion: the one table of the kinds' fits.
const KIND_FITS: [(Kind, KindFit); 2] = [(Kind::Genetic, fit_genetic), (Kind::MicroSlip, fit_micro_slip)];

/// Fits the model of kind `kind` to `motion`.
pub fn fit_kind(kind: Kind, motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    let (_, fit) = KIND_FITS.iter().find(|(each, _)| *each == kind).ok_or(FitError::Degenerate)?;
    fit(motion, options)
}

/// Fits the micro-slip kind to `motion` (one solve a round: the swarm's options are not used).
/// The rounds whose model only sets the next round's weights run on a subsample.
pub fn fit_micro_slip(motion: &Motion, _options: &FitOptions) -> Result<MotionFit, FitError> {
    motion.check()?;
    let scale = motion.scale();
    let (slip_min, slip_max) = slip_range(motion);
    let grid = slip_grid(slip_min, slip_max)?;
    let params = |coef: Vec<f64>| {
        let mut stiffness = [0.0; SLIP_ELEMENTS];
        for (k, c) in stiffness.iter_mut().zip(&coef[3..]) {
            *k = c / scale;
        }
        GearModel::MicroSlip(SlipParams {
            c1: coef[0] / scale,
            c2: coef[1] / scale.powi(3),
            c3: coef[2] / scale.powi(5),
            stiffness,
            slip_min,
            slip_max,
        })
    };
    let rounds = if motion.noise.is_some() { 1 + REWEIGHTINGS } else { 1 };
    let mut sub = motion.subsample(POLISH_SAMPLES);
    let mut model: Option<GearModel<f64>> = None;
    for round in 1..=rounds {
        let weighting = motion.weighting(model.as_ref());
        let coef = if round == rounds {
            slip_coefficients(Source::Full(motion), scale, &grid, weighting, &[])?
        } else {
            sub.reweigh(weighting)?;
            slip_coefficients(Source::Stored(&sub), scale, &grid, Weighting::Carried, &[])?
        };
        model = Some(params(coef));
    }
    let model = model.ok_or(FitError::Degenerate)?;
    motion.score(model, 3 + SLIP_ELEMENTS, rounds)
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

    #[test]
    fn micro_slip_recovers_its_own_gear_exactly() {
        let theta = nested(6000, 1.2e-3);
        let reversals = crate::prepare::reversals(&theta);
        let motion_noise = NoiseModel { torque_nm: 0.0, deflection_rad: 0.0 };
        let probe = Motion::training_prefix(&theta, &[], &reversals, theta.len(), Some(motion_noise));
        let (slip_min, slip_max) = slip_range(&probe);
        let mut stiffness = [0.0; SLIP_ELEMENTS];
        for (i, k) in stiffness.iter_mut().enumerate() {
            *k = if i % 3 == 0 { 400.0 + 50.0 * i as f64 } else { 0.0 };
        }
        let truth = SlipParams { c1: 8000.0, c2: 1.0e10, c3: 0.0, stiffness, slip_min, slip_max };
        let torque = torque_of(&GearModel::MicroSlip(truth), &theta, &reversals);
        let motion = Motion::training_prefix(&theta, &torque, &reversals, theta.len(), None);
        let fitted = fit_micro_slip(&motion, &FitOptions::default()).unwrap();
        let scale = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(fitted.rms < 1e-6 * scale, "RMS {} of a peak {scale}: {:?}", fitted.rms, fitted.model);
    }

    /// Two runs, each from rest: the first ends loaded at its minimum, the second is a small
    /// motion about zero. Fitted together, each run from its own start, the micro-slip gear is
    /// recovered exactly; carried over from the first, the second run's state would be far off.
    #[test]
    fn each_run_starts_from_rest() {
        let first: Vec<f64> = (0..3001).map(|i| 1.2e-3 * (std::f64::consts::TAU * i as f64 / 4000.0).sin()).collect();
        let second = nested(4000, 0.3e-3);
        let reversals = [crate::prepare::reversals(&first), crate::prepare::reversals(&second)];
        let probe = Motion::training_prefix(&first, &[], &reversals[0], first.len(), None);
        let (slip_min, slip_max) = slip_range(&probe);
        let mut stiffness = [0.0; SLIP_ELEMENTS];
        for (i, k) in stiffness.iter_mut().enumerate() {
            *k = 300.0 + 40.0 * i as f64;
        }
        let truth = GearModel::MicroSlip(SlipParams { c1: 8000.0, c2: 1.0e10, c3: 0.0, stiffness, slip_min, slip_max });
        let torque = [torque_of(&truth, &first, &reversals[0]), torque_of(&truth, &second, &reversals[1])];
        let motion = Motion {
            runs: vec![
                Run::fitted_from(&first, &torque[0], &reversals[0], 0),
                Run::fitted_from(&second, &torque[1], &reversals[1], 0),
            ],
            noise: None,
        };
        let fitted = fit_micro_slip(&motion, &FitOptions::default()).unwrap();
        assert_eq!(fitted.n, first.len() + second.len());
        assert!(fitted.rms < 1e-6 * 30.0, "RMS {}: {:?}", fitted.rms, fitted.model);
    }

    #[test]
    fn genetic_recovers_its_own_gear_on_nested_motion() {
        let theta = nested(6000, 1.2e-3);
        let reversals = crate::prepare::reversals(&theta);
        let truth = Params::from_identifiable(2.2e4, 4.0e9, 0.0, Identifiable { h: 1.5, r: 1.2 }, 1.2e-3).unwrap();
        let torque = torque_of(&GearModel::Genetic(truth), &theta, &reversals);
        let motion = Motion::training_prefix(&theta, &torque, &reversals, theta.len(), None);
        let fitted = fit_genetic(&motion, &FitOptions::default()).unwrap();
        let scale = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(fitted.rms < 1e-6 * scale, "RMS {} of a peak {scale}: {:?}", fitted.rms, fitted.model);
    }
}
