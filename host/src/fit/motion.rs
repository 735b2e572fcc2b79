//! Fits of the stateful models to a recording of any motion: the genetic kind with Madelung's
//! rules and the micro-slip kind. Both are run along the whole recording from rest, as
//! `predict` and the joint run them; the least squares count only the training samples.
//!
//! - genetic: for a fixed r the model is linear in c1, c2, c3 and k (h = w·k on every branch
//!   of half-width w), so each r is an exact 4-unknown solve on the columns θ, θ³, θ⁵ and the
//!   hysteretic part run with k = 1; r is searched by the swarm on a strided copy of the motion
//!   and polished by Brent on all of it.
//! - micro-slip: linear in (c1, c2, c3, k_1 … k_M) on a fixed log grid of slip deflections, so
//!   one non-negative least-squares solve (k_i ≥ 0) identifies it exactly.
//!
//! With a noise model, residuals are weighted by their total noise 1/(σ_T² + σ_θ²·K²) with K
//! the model's stiffness, refitted twice, as the loop fit does.
use super::{FitError, FitOptions, R_LIMIT};
use crate::numeric::linalg::Cholesky;
use crate::numeric::nnls::nnls_normal;
use crate::numeric::optimize::{brent, pso, PsoOptions};
use crate::prepare::NoiseModel;
use model_core::memory::{slip_grid, GeneticMemory, Hysteretic, SlipElements};
use model_core::{GearModel, Identifiable, Kind, Model, Params, SlipElement, Spring, SLIP_ELEMENTS, TURNING_POINTS};

/// The swarm runs the genetic kind on at most this many samples of the motion.
const SWARM_SAMPLES: usize = 4096;
/// Reweighting rounds for the total-noise weights.
const REWEIGHTINGS: usize = 2;
/// The smallest slip deflection of the micro-slip grid, in deflection-noise standard
/// deviations: elements that slip inside the noise cannot be told from it.
const SLIP_MIN_IN_NOISE_SIGMAS: f64 = 3.0;

/// A recording's motion and torque, ready for the stateful fits.
#[derive(Clone, Debug)]
pub struct Motion<'a> {
    pub theta: &'a [f64],
    pub torque: &'a [f64],
    /// The samples the least squares count: the first `training` of them.
    pub training: usize,
    pub noise: Option<NoiseModel>,
    /// The smallest reversal the genetic kind follows, rad.
    pub band: f64,
}

/// A stateful model fitted to a motion, with its errors.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionFit {
    pub model: GearModel<f64>,
    /// The samples fitted (the training ones).
    pub n: usize,
    /// Unweighted RSS over the training samples, (N·m)².
    pub rss: f64,
    /// Unweighted RMS over the training samples, N·m.
    pub rms: f64,
    /// RMS over the samples after the training ones, N·m (none when all were trained on).
    pub held_out_rms: Option<f64>,
    /// Evaluations of the model along the whole motion (swarm and polish).
    pub evaluations: usize,
    /// The model's torque along the whole motion from rest, N·m.
    pub torque: Vec<f64>,
}

impl Motion<'_> {
    fn check(&self) -> Result<(), FitError> {
        if self.training < super::MIN_POINTS {
            return Err(FitError::TooFewPoints { n: self.training, need: super::MIN_POINTS });
        }
        if self.theta[..self.training].iter().all(|&t| t == 0.0) {
            return Err(FitError::NoDeflection);
        }
        Ok(())
    }

    /// The largest |θ| over the training samples: the scale of the polynomial's columns.
    fn scale(&self) -> f64 {
        self.theta[..self.training].iter().fold(0.0, |m, t| t.abs().max(m))
    }

    /// Errors of `model` run along the whole motion, summed as the evaluator steps: the
    /// predicted torque is the one vector kept (the evaluations and their squared errors beside
    /// it were 40 bytes a sample more, the peak of `diagnose` at 10 M samples).
    fn score(&self, model: GearModel<f64>, evaluations: usize) -> Result<MotionFit, FitError> {
        let mut evaluator = model.evaluator(self.band).map_err(FitError::Model)?;
        let mut torque = Vec::with_capacity(self.theta.len());
        let (mut rss, mut held) = (0.0, 0.0);
        for (i, (&theta, &measured)) in self.theta.iter().zip(self.torque).enumerate() {
            let predicted = evaluator.step(theta).map_err(FitError::Model)?.torque;
            let square = (measured - predicted).powi(2);
            if i < self.training {
                rss += square;
            } else {
                held += square;
            }
            torque.push(predicted);
        }
        let held_samples = self.theta.len() - self.training;
        Ok(MotionFit {
            model,
            n: self.training,
            rss,
            rms: (rss / self.training as f64).sqrt(),
            held_out_rms: (held_samples > 0).then(|| (held / held_samples as f64).sqrt()),
            evaluations,
            torque,
        })
    }

    /// Total-noise weights of `model` on the training samples, normalised to a mean of 1.
    fn weights(&self, model: &GearModel<f64>, noise: &NoiseModel) -> Result<Vec<f64>, FitError> {
        let mut evaluator = model.evaluator(self.band).map_err(FitError::Model)?;
        let (var_t, var_theta) = (noise.torque_nm.powi(2), noise.deflection_rad.powi(2));
        let mut weights = Vec::with_capacity(self.training);
        for &theta in &self.theta[..self.training] {
            let stiffness = evaluator.step(theta).map_err(FitError::Model)?.stiffness;
            weights.push(1.0 / (var_t + var_theta * stiffness * stiffness).max(f64::MIN_POSITIVE));
        }
        let mean = weights.iter().sum::<f64>() / weights.len() as f64;
        weights.iter_mut().for_each(|w| *w /= mean);
        Ok(weights)
    }
}

/// Normal equations Σ w·x·xᵀ and Σ w·x·T of rows `columns(i)` over the training samples.
fn normal_equations(
    n: usize,
    training: usize,
    weights: Option<&[f64]>,
    torque: &[f64],
    mut row: impl FnMut(usize, &mut [f64]),
) -> (Vec<f64>, Vec<f64>) {
    let mut gram = vec![0.0; n * n];
    let mut rhs = vec![0.0; n];
    let mut x = vec![0.0; n];
    for i in 0..training {
        row(i, &mut x);
        let w = weights.map_or(1.0, |w| w[i]);
        for a in 0..n {
            let wa = w * x[a];
            rhs[a] += wa * torque[i];
            for b in a..n {
                gram[a * n + b] += wa * x[b];
            }
        }
    }
    for a in 0..n {
        for b in 0..a {
            gram[a * n + b] = gram[b * n + a];
        }
    }
    (gram, rhs)
}

/// The genetic model with k = 1 and no spring at decay ratio r: its hysteretic part along
/// `theta` is the fit's fourth column.
fn unit_hysteresis(theta: &[f64], r: f64, band: f64) -> Result<Vec<f64>, FitError> {
    let unit = Params { c1: 0.0, c2: 0.0, c3: 0.0, alpha: 1.0 + r * r, beta: r, omega: 1.0 };
    let mut memory = GeneticMemory::<f64, TURNING_POINTS>::new(Model::new(unit)?, band);
    theta.iter().map(|&t| memory.step(t).map(|e| e.torque).map_err(FitError::Model)).collect()
}

/// The exact least-squares genetic parameters at r, and their weighted RSS.
fn genetic_at(
    theta: &[f64],
    torque: &[f64],
    training: usize,
    weights: Option<&[f64]>,
    scale: f64,
    r: f64,
    band: f64,
) -> Result<(Params<f64>, f64), FitError> {
    let hysteresis = unit_hysteresis(theta, r, band)?;
    let (gram, rhs) = normal_equations(4, training.min(theta.len()), weights, torque, |i, x| {
        let u = theta[i] / scale;
        x.copy_from_slice(&[u, u * u * u, u * u * u * u * u, hysteresis[i]]);
    });
    let coef = Cholesky::new(4, &gram).ok_or(FitError::Degenerate)?.solve(&rhs);
    if !coef.iter().all(|c| c.is_finite()) {
        return Err(FitError::Degenerate);
    }
    let tt: f64 = (0..training.min(theta.len())).map(|i| weights.map_or(1.0, |w| w[i]) * torque[i] * torque[i]).sum();
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

/// Fits the genetic kind with Madelung's rules to `motion`.
pub fn fit_genetic(motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    motion.check()?;
    let scale = motion.scale();
    let s_limit = R_LIMIT.asinh();
    // The swarm on a strided copy: a coarser motion with the same reversals, to within a stride.
    let stride = motion.training.div_ceil(SWARM_SAMPLES).max(1);
    let coarse_theta: Vec<f64> = motion.theta[..motion.training].iter().step_by(stride).copied().collect();
    let coarse_torque: Vec<f64> = motion.torque[..motion.training].iter().step_by(stride).copied().collect();
    let coarse = |s: f64| {
        genetic_at(&coarse_theta, &coarse_torque, coarse_theta.len(), None, scale, s.sinh(), motion.band)
            .map_or(f64::INFINITY, |(_, rss)| rss)
    };
    let swarm = pso(
        |x| coarse(x[0]),
        &[(-s_limit, s_limit)],
        &PsoOptions {
            particles: options.particles,
            max_iterations: options.max_iterations,
            stall_iterations: 12,
            seed: options.seed,
        },
        |_, _| {},
    );
    let mut evaluations = swarm.evaluations;
    let mut s = swarm.best[0];
    let mut half_width = (3.0 * swarm.spread[0]).clamp(0.02, 0.1);
    let mut weights: Option<Vec<f64>> = None;
    let rounds = if motion.noise.is_some() { 1 + REWEIGHTINGS } else { 1 };
    let mut params = None;
    for _ in 0..rounds {
        if let (Some(noise), Some(params)) = (&motion.noise, params) {
            weights = Some(motion.weights(&GearModel::paper(params), noise)?);
        }
        let objective = |s: f64| {
            genetic_at(motion.theta, motion.torque, motion.training, weights.as_deref(), scale, s.sinh(), motion.band)
                .map_or(f64::INFINITY, |(_, rss)| rss)
        };
        let (lo, hi) = ((s - half_width).max(-s_limit), (s + half_width).min(s_limit));
        let (polished, _, used) = brent(objective, lo, hi, 1e-8);
        evaluations += used;
        s = polished;
        half_width = 0.05;
        params = Some(
            genetic_at(motion.theta, motion.torque, motion.training, weights.as_deref(), scale, s.sinh(), motion.band)?
                .0,
        );
    }
    let params = params.ok_or(FitError::Degenerate)?;
    motion.score(GearModel::paper(params), evaluations)
}

/// The slip grid for `motion`: from 3σ of the deflection noise (at least 10⁻³ of the range) to
/// half the range of the deflection, rad.
pub fn slip_range(motion: &Motion) -> (f64, f64) {
    let theta = &motion.theta[..motion.training];
    let (lo, hi) = theta.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    let half_range = (hi - lo) / 2.0;
    let noise = motion.noise.map_or(0.0, |n| n.deflection_rad);
    ((SLIP_MIN_IN_NOISE_SIGMAS * noise).max(1e-3 * half_range), half_range)
}

/// Each element's unit-stiffness torque e_i along the training samples, the columns of the
/// k_i, formed sample by sample for a pass over the samples in order: kept as a matrix, they
/// would be 16 values a sample. Each pass starts from the elements at rest ([`Self::pass`]).
#[derive(Clone, Copy)]
struct ElementRun {
    at_rest: SlipElements<f64, SLIP_ELEMENTS>,
}

/// One pass of an [`ElementRun`]: call [`ElementPass::step`] on samples 0, 1, 2, … in order,
/// then [`ElementPass::finish`] for the first error, if any.
struct ElementPass {
    elements: SlipElements<f64, SLIP_ELEMENTS>,
    error: Option<model_core::Error>,
}

impl ElementRun {
    fn new(slip_min: f64, slip_max: f64) -> Result<ElementRun, FitError> {
        Ok(ElementRun { at_rest: SlipElements::new(slip_grid(slip_min, slip_max)?)? })
    }

    fn pass(&self) -> ElementPass {
        ElementPass { elements: self.at_rest, error: None }
    }
}

impl ElementPass {
    /// The elements' e_i after the deflection `theta`, the next sample's.
    fn step(&mut self, theta: f64) -> [f64; SLIP_ELEMENTS] {
        if self.error.is_none() {
            if let Err(error) = self.elements.step(theta) {
                self.error = Some(error);
            }
        }
        *self.elements.elastic()
    }

    fn finish(self) -> Result<(), FitError> {
        self.error.map_or(Ok(()), |error| Err(error.into()))
    }
}

/// Sample i's row of the micro-slip form, in order (`pass` steps the elements): θ/S, (θ/S)³,
/// (θ/S)⁵, each element's e_i/S (on the scale of the polynomial's columns), then `extra`.
fn slip_row(motion: &Motion, scale: f64, extra: &[&[f64]], pass: &mut ElementPass, i: usize, x: &mut [f64]) {
    let u = motion.theta[i] / scale;
    x[..3].copy_from_slice(&[u, u * u * u, u * u * u * u * u]);
    for (value, e) in x[3..3 + SLIP_ELEMENTS].iter_mut().zip(&pass.step(motion.theta[i])) {
        *value = e / scale;
    }
    for (value, column) in x[3 + SLIP_ELEMENTS..].iter_mut().zip(extra) {
        *value = column[i];
    }
}

/// The coefficients of the micro-slip form (k_i ≥ 0) and of `extra` free columns beside it,
/// by one weighted non-negative least-squares solve on the training samples.
fn slip_coefficients(
    motion: &Motion,
    scale: f64,
    run: &ElementRun,
    weights: Option<&[f64]>,
    extra: &[&[f64]],
) -> Result<Vec<f64>, FitError> {
    let n = 3 + SLIP_ELEMENTS + extra.len();
    let nonnegative: Vec<bool> = (0..n).map(|j| (3..3 + SLIP_ELEMENTS).contains(&j)).collect();
    let mut pass = run.pass();
    let (gram, rhs) = normal_equations(n, motion.training, weights, motion.torque, |i, x| {
        slip_row(motion, scale, extra, &mut pass, i, x)
    });
    pass.finish()?;
    nnls_normal(&gram, &rhs, &nonnegative).ok_or(FitError::Degenerate)
}

/// The micro-slip form with further free columns beside it (the diagnosis' torque effects),
/// in one least-squares solve with the given weights on the training samples: its torque at
/// each of them and the weighted residual sum of squares.
pub fn micro_slip_with_columns(
    motion: &Motion,
    weights: &[f64],
    extra: &[&[f64]],
) -> Result<(Vec<f64>, f64), FitError> {
    motion.check()?;
    let scale = motion.scale();
    let (slip_min, slip_max) = slip_range(motion);
    let run = ElementRun::new(slip_min, slip_max)?;
    let coef = slip_coefficients(motion, scale, &run, Some(weights), extra)?;
    let mut x = vec![0.0; coef.len()];
    let mut chi2 = 0.0;
    let mut pass = run.pass();
    let predicted = (0..motion.training)
        .map(|i| {
            slip_row(motion, scale, extra, &mut pass, i, &mut x);
            let p: f64 = x.iter().zip(&coef).map(|(a, b)| a * b).sum();
            chi2 += weights[i] * (motion.torque[i] - p).powi(2);
            p
        })
        .collect();
    pass.finish()?;
    Ok((predicted, chi2))
}

/// A kind's fit to a recording.
type KindFit = fn(&Motion, &FitOptions) -> Result<MotionFit, FitError>;

/// How each kind is fitted to a recording: the one table of the kinds' fits.
const KIND_FITS: [(Kind, KindFit); 2] = [(Kind::Genetic, fit_genetic), (Kind::MicroSlip, fit_micro_slip)];

/// Fits the model of kind `kind` to `motion`.
pub fn fit_kind(kind: Kind, motion: &Motion, options: &FitOptions) -> Result<MotionFit, FitError> {
    let (_, fit) = KIND_FITS.iter().find(|(each, _)| *each == kind).ok_or(FitError::Degenerate)?;
    fit(motion, options)
}

/// Fits the micro-slip kind to `motion` (one solve: the swarm's options are not used).
pub fn fit_micro_slip(motion: &Motion, _options: &FitOptions) -> Result<MotionFit, FitError> {
    motion.check()?;
    let scale = motion.scale();
    let (slip_min, slip_max) = slip_range(motion);
    let run = ElementRun::new(slip_min, slip_max)?;
    let grid = slip_grid::<f64, SLIP_ELEMENTS>(slip_min, slip_max)?;
    let solve = |weights: Option<&[f64]>| -> Result<GearModel<f64>, FitError> {
        let coef = slip_coefficients(motion, scale, &run, weights, &[])?;
        let mut elements = [SlipElement::default(); SLIP_ELEMENTS];
        for ((element, c), slip) in elements.iter_mut().zip(&coef[3..]).zip(grid) {
            *element = SlipElement { slip, stiffness: c / scale };
        }
        let spring = Spring::polynomial(coef[0] / scale, coef[1] / scale.powi(3), coef[2] / scale.powi(5));
        Ok(GearModel::micro_slip(0.0, spring, &elements)?)
    };
    let mut model = solve(None)?;
    if let Some(noise) = &motion.noise {
        for _ in 0..REWEIGHTINGS {
            let weights = motion.weights(&model, noise)?;
            model = solve(Some(&weights))?;
        }
    }
    motion.score(model, 1 + REWEIGHTINGS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gear::run;

    /// A motion of nested reversals from rest: a big sine with a smaller, faster one on top.
    fn nested(n: usize, amplitude: f64) -> Vec<f64> {
        (0..n)
            .map(|i| {
                let phase = std::f64::consts::TAU * 3.0 * i as f64 / n as f64;
                amplitude * (0.75 * phase.sin() + 0.25 * (9.0 * phase).sin())
            })
            .collect()
    }

    #[test]
    fn micro_slip_recovers_its_own_gear_exactly() {
        let theta = nested(6000, 1.2e-3);
        let motion_noise = NoiseModel { torque_nm: 0.0, deflection_rad: 0.0 };
        let probe = Motion { theta: &theta, torque: &[], training: theta.len(), noise: Some(motion_noise), band: 0.0 };
        let (slip_min, slip_max) = slip_range(&probe);
        let mut stiffness = [0.0; SLIP_ELEMENTS];
        for (i, k) in stiffness.iter_mut().enumerate() {
            *k = if i % 3 == 0 { 400.0 + 50.0 * i as f64 } else { 0.0 };
        }
        let grid = slip_grid::<f64, SLIP_ELEMENTS>(slip_min, slip_max).unwrap();
        let elements: Vec<SlipElement<f64>> =
            grid.iter().zip(stiffness).map(|(&slip, stiffness)| SlipElement { slip, stiffness }).collect();
        let truth = GearModel::micro_slip(0.0, Spring::polynomial(8000.0, 1.0e10, 0.0), &elements).unwrap();
        let torque: Vec<f64> = run(&truth, &theta, 0.0).unwrap().iter().map(|e| e.torque).collect();
        let motion = Motion { theta: &theta, torque: &torque, training: theta.len(), noise: None, band: 0.0 };
        let fitted = fit_micro_slip(&motion, &FitOptions::default()).unwrap();
        let scale = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(fitted.rms < 1e-6 * scale, "RMS {} of a peak {scale}: {:?}", fitted.rms, fitted.model);
    }

    #[test]
    fn genetic_recovers_its_own_gear_on_nested_motion() {
        let theta = nested(6000, 1.2e-3);
        let truth = Params::from_identifiable(2.2e4, 4.0e9, 0.0, Identifiable { h: 1.5, r: 1.2 }, 1.2e-3).unwrap();
        let torque: Vec<f64> = run(&GearModel::paper(truth), &theta, 0.0).unwrap().iter().map(|e| e.torque).collect();
        let motion = Motion { theta: &theta, torque: &torque, training: theta.len(), noise: None, band: 0.0 };
        let fitted = fit_genetic(&motion, &FitOptions::default()).unwrap();
        let scale = torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        assert!(fitted.rms < 1e-6 * scale, "RMS {} of a peak {scale}: {:?}", fitted.rms, fitted.model);
    }
}
