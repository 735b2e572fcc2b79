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
use crate::linalg::Cholesky;
use crate::optimize::{brent, pso, PsoOptions};
use model_core::{Direction, Identifiable, Model, Params};

/// Deflection samples with what the model needs to evaluate them.
#[derive(Clone, Debug, Default)]
pub struct FitData {
    pub theta: Vec<f64>,
    pub torque: Vec<f64>,
    pub direction: Vec<Direction>,
    pub amplitude: Vec<f64>,
}

/// Standard deviations of the measurement noise.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct NoiseModel {
    /// Torque sensor noise, N·m.
    pub torque_nm: f64,
    /// Deflection noise (encoders), rad.
    pub deflection_rad: f64,
}

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
    Swarm { iteration: usize, of: usize },
    Polish { round: usize, of: usize },
}

/// Per-sample quantities that do not depend on r.
pub(crate) struct Basis {
    /// θ/S for S the largest amplitude: u, u³, u⁵.
    poly: Vec<[f64; 3]>,
    phase: Vec<f64>,
    /// sin φ = θ/A (clamped).
    sin: Vec<f64>,
    cos: Vec<f64>,
    /// A·|cos φ|.
    amp_abs_cos: Vec<f64>,
    torque: Vec<f64>,
    weight: Vec<f64>,
    phase_range: (f64, f64),
    scale: f64,
    /// Further linear columns (the diagnosis' effects), one value per sample each.
    extra: Vec<Vec<f64>>,
    /// The normal equations' entries that do not involve the hysteresis column, which alone
    /// depends on r: computed once per set of weights, so each r costs one exp and a row.
    fixed: FixedSums,
}

#[derive(Clone, Debug, Default)]
struct FixedSums {
    /// XᵀWX, row-major, zero in the hysteresis row and column.
    gram: Vec<f64>,
    /// XᵀWT, zero for the hysteresis column.
    rhs: Vec<f64>,
    /// TᵀWT.
    tt: f64,
}

/// Column of the hysteresis term in the normal equations.
const HYSTERESIS: usize = 3;
/// Below this many samples one thread accumulates faster than several.
const PARALLEL_SAMPLES: usize = 16_384;

/// The weighted least-squares answer at one r.
pub(crate) struct Solution {
    /// c1·S, c2·S³, c3·S⁵, k·e^shift, then one coefficient per extra column.
    pub(crate) coef: Vec<f64>,
    /// The hysteresis column was divided by e^shift to stay finite.
    shift: f64,
    /// Σ w·residual², with the basis' weights.
    pub(crate) weighted_rss: f64,
    /// Factor of the normal equations, for the coefficients' variances.
    pub(crate) factor: Cholesky,
}

impl Basis {
    pub(crate) fn new(data: &FitData, indices: impl Iterator<Item = usize>, scale: f64) -> Basis {
        let mut b = Basis {
            poly: Vec::new(),
            phase: Vec::new(),
            sin: Vec::new(),
            cos: Vec::new(),
            amp_abs_cos: Vec::new(),
            torque: Vec::new(),
            weight: Vec::new(),
            phase_range: (f64::INFINITY, f64::NEG_INFINITY),
            scale,
            extra: Vec::new(),
            fixed: FixedSums::default(),
        };
        for i in indices {
            let (theta, amplitude) = (data.theta[i], data.amplitude[i]);
            let u = theta / scale;
            b.poly.push([u, u * u * u, u * u * u * u * u]);
            let x = (theta / amplitude).clamp(-1.0, 1.0);
            let abs_cos = ((1.0 - x) * (1.0 + x)).sqrt();
            let (phase, cos) = match data.direction[i] {
                Direction::Rising => (x.asin(), abs_cos),
                Direction::Falling => (std::f64::consts::PI - x.asin(), -abs_cos),
            };
            b.phase_range = (b.phase_range.0.min(phase), b.phase_range.1.max(phase));
            b.phase.push(phase);
            b.sin.push(x);
            b.cos.push(cos);
            b.amp_abs_cos.push(amplitude * abs_cos);
            b.torque.push(data.torque[i]);
            b.weight.push(1.0);
        }
        b.refresh_fixed();
        b
    }

    /// The value of column `column` (not the hysteresis one) at sample `i`.
    fn column(&self, column: usize, i: usize) -> f64 {
        match column {
            0..=2 => self.poly[i][column],
            _ => self.extra[column - 4][i],
        }
    }

    fn dimension(&self) -> usize {
        4 + self.extra.len()
    }

    fn refresh_fixed(&mut self) {
        let dim = self.dimension();
        let mut fixed = FixedSums { gram: vec![0.0; dim * dim], rhs: vec![0.0; dim], tt: 0.0 };
        let columns: Vec<usize> = (0..dim).filter(|&c| c != HYSTERESIS).collect();
        for i in 0..self.torque.len() {
            let (w, t) = (self.weight[i], self.torque[i]);
            for &a in &columns {
                let wa = w * self.column(a, i);
                fixed.rhs[a] += wa * t;
                for &b in columns.iter().filter(|&&b| b >= a) {
                    fixed.gram[a * dim + b] += wa * self.column(b, i);
                }
            }
            fixed.tt += w * t * t;
        }
        for a in 0..dim {
            for b in 0..a {
                fixed.gram[a * dim + b] = fixed.gram[b * dim + a];
            }
        }
        self.fixed = fixed;
    }

    /// Σ w·b·x_a for every column a (the hysteresis column b itself included) and Σ w·b·T,
    /// over samples `range`, with b the hysteresis column at r.
    fn hysteresis_sums(&self, range: std::ops::Range<usize>, r: f64, shift: f64) -> (Vec<f64>, f64) {
        let dim = self.dimension();
        let e_shift = (-shift).exp();
        let mut cross = vec![0.0; dim];
        let mut bt = 0.0;
        for i in range {
            let p = (-r * self.phase[i] - shift).exp() + (r * self.sin[i] - self.cos[i]) * e_shift;
            let wb = self.weight[i] * self.amp_abs_cos[i] * p;
            let poly = &self.poly[i];
            cross[0] += wb * poly[0];
            cross[1] += wb * poly[1];
            cross[2] += wb * poly[2];
            cross[HYSTERESIS] += wb * self.amp_abs_cos[i] * p;
            for (sum, column) in cross[4..].iter_mut().zip(&self.extra) {
                *sum += wb * column[i];
            }
            bt += wb * self.torque[i];
        }
        (cross, bt)
    }

    /// Weighted least squares at `r` over the model's four columns and the extra ones.
    pub(crate) fn solve(&self, r: f64) -> Option<Solution> {
        use rayon::prelude::*;
        // Largest exponent −rφ over the data: dividing by e^shift keeps e^(−rφ) ≤ 1.
        let shift = (-r * self.phase_range.0).max(-r * self.phase_range.1);
        let n = self.torque.len();
        let (cross, bt) = if n < PARALLEL_SAMPLES {
            self.hysteresis_sums(0..n, r, shift)
        } else {
            let chunk = n.div_ceil(rayon::current_num_threads().max(1));
            (0..n)
                .step_by(chunk)
                .collect::<Vec<_>>()
                .into_par_iter()
                .map(|start| self.hysteresis_sums(start..(start + chunk).min(n), r, shift))
                .reduce_with(|(mut a, x), (b, y)| {
                    a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
                    (a, x + y)
                })?
        };
        let dim = self.dimension();
        let mut m = self.fixed.gram.clone();
        for (a, value) in cross.iter().enumerate() {
            m[a * dim + HYSTERESIS] = *value;
            m[HYSTERESIS * dim + a] = *value;
        }
        let mut rhs = self.fixed.rhs.clone();
        rhs[HYSTERESIS] = bt;
        let factor = Cholesky::new(dim, &m)?;
        let coef = factor.solve(&rhs);
        if !coef.iter().all(|c| c.is_finite()) {
            return None;
        }
        let explained: f64 = coef.iter().zip(&rhs).map(|(c, r)| c * r).sum();
        Some(Solution { coef, shift, weighted_rss: (self.fixed.tt - explained).max(0.0), factor })
    }

    /// Uses these weights (one per sample) instead of 1.
    pub(crate) fn with_weights(mut self, weights: Vec<f64>) -> Basis {
        self.weight = weights;
        self.refresh_fixed();
        self
    }

    /// Adds linear columns (one value per sample each) beside the model's own.
    pub(crate) fn with_extra(mut self, columns: Vec<Vec<f64>>) -> Basis {
        self.extra = columns;
        self.refresh_fixed();
        self
    }

    pub(crate) fn objective(&self, s: f64) -> f64 {
        self.solve(s.sinh()).map_or(f64::INFINITY, |sol| sol.weighted_rss)
    }

    pub(crate) fn params(
        &self,
        r: f64,
        solution: &Solution,
        reference_amplitude: f64,
    ) -> Result<Params<f64>, FitError> {
        let [a1, a3, a5, ak] = [solution.coef[0], solution.coef[1], solution.coef[2], solution.coef[3]];
        let k = ak * (-solution.shift).exp();
        let s = self.scale;
        let params = Params::from_identifiable(
            a1 / s,
            a3 / s.powi(3),
            a5 / s.powi(5),
            Identifiable { h: k * reference_amplitude, r },
            reference_amplitude,
        )?;
        Ok(params)
    }
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
    let sample = Basis::new(data, (0..n).step_by(stride), scale);
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

    let mut full = Basis::new(data, 0..n, scale);
    let rounds = if options.noise.is_some() { 1 + REWEIGHTINGS } else { 1 };
    let mut s = swarm.best[0];
    // The bracket widens by itself when the minimum lies on its edge.
    let mut half_width = (3.0 * swarm.spread[0]).clamp(0.02, 0.1);
    let mut params = None;
    for round in 0..rounds {
        progress(Stage::Polish { round: round + 1, of: rounds });
        if round > 0 {
            let noise = options.noise.as_ref().ok_or(FitError::Degenerate)?;
            let model = Model::new(params.ok_or(FitError::Degenerate)?)?;
            reweight(&mut full, data, &model, noise)?;
        }
        // With weights to come, the swarm's point is close enough to set them: polishing the
        // unweighted fit first would cost a third of a 20k-sample fit and change nothing.
        if round > 0 || rounds == 1 {
            let (polished, polish_evaluations) = polish(&full, s, half_width, s_limit);
            evaluations += polish_evaluations;
            s = polished;
            half_width = 0.05;
        }
        let r = s.sinh();
        let solution = full.solve(r).ok_or(FitError::Degenerate)?;
        params = Some(full.params(r, &solution, reference_amplitude)?);
    }
    let params = params.ok_or(FitError::Degenerate)?;
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
            pso_samples: sample.torque.len(),
            evaluations,
            reweightings: rounds - 1,
        },
    })
}

/// Brent on s = asinh(r) around `s`, widening the bracket while the minimum sits on its edge.
pub(crate) fn polish(basis: &Basis, s: f64, half_width: f64, s_limit: f64) -> (f64, usize) {
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
fn reweight(basis: &mut Basis, data: &FitData, model: &Model<f64>, noise: &NoiseModel) -> Result<(), FitError> {
    basis.weight = total_noise_weights(data, model, noise)?;
    let mean = basis.weight.iter().sum::<f64>() / basis.weight.len() as f64;
    basis.weight.iter_mut().for_each(|w| *w /= mean);
    basis.refresh_fixed();
    Ok(())
}

/// 1/(σ_T² + σ_θ²·K²) for every sample, K the model's stiffness there: the inverse variance
/// of a torque residual when both torque and deflection are noisy.
pub fn total_noise_weights(
    data: &FitData,
    model: &Model<f64>,
    noise: &NoiseModel,
) -> Result<Vec<f64>, model_core::Error> {
    let (var_t, var_theta) = (noise.torque_nm.powi(2), noise.deflection_rad.powi(2));
    (0..data.theta.len())
        .map(|i| {
            let stiffness = model.stiffness(data.theta[i], data.direction[i], data.amplitude[i])?;
            Ok(1.0 / (var_t + var_theta * stiffness * stiffness).max(f64::MIN_POSITIVE))
        })
        .collect()
}

/// Unweighted residual sum of squares of `model` on `data`, (N·m)².
pub fn rss(model: &Model<f64>, data: &FitData) -> Result<f64, model_core::Error> {
    residuals(model, data).map(|r| r.iter().map(|e| e * e).sum())
}

/// Measured minus modelled torque for every sample, N·m.
pub fn residuals(model: &Model<f64>, data: &FitData) -> Result<Vec<f64>, model_core::Error> {
    (0..data.theta.len())
        .map(|i| Ok(data.torque[i] - model.torque(data.theta[i], data.direction[i], data.amplitude[i])?))
        .collect()
}

pub fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut sorted = values.to_vec();
    let mid = sorted.len() / 2;
    *sorted.select_nth_unstable_by(mid, f64::total_cmp).1
}
