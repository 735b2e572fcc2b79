//! The fit's linear algebra at one r: the model's columns (c1·θ, c2·θ³, c3·θ⁵, the hysteresis
//! term, and any extra columns the diagnosis adds) and their weighted least-squares solve.
use super::FitError;
use crate::numeric::linalg::Cholesky;
use crate::prepare::FitData;
use model_core::{shape, Direction, Identifiable, Libm, Params, Phase};

/// Per-sample quantities that do not depend on r.
pub struct Basis {
    /// θ/S for S the largest amplitude: u (u³ and u⁵ are formed where they are needed).
    poly: Vec<f64>,
    /// Each sample's place on its loop (model-core's [`Phase`]): φ, sin φ, cos φ, in arrays of
    /// their own because the search over r streams through them once per r.
    phase: Vec<f64>,
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

/// u, u³, u⁵: the polynomial columns at u = θ/S, formed the same way every time.
#[inline(always)]
fn powers(u: f64) -> [f64; 3] {
    [u, u * u * u, u * u * u * u * u]
}

/// Column of the hysteresis term in the normal equations.
const HYSTERESIS: usize = 3;
/// Below this many samples one thread accumulates faster than several.
const PARALLEL_SAMPLES: usize = 16_384;

/// The weighted least-squares answer at one r.
pub struct Solution {
    /// c1·S, c2·S³, c3·S⁵, k·e^shift, then one coefficient per extra column.
    pub coef: Vec<f64>,
    /// The hysteresis column was divided by e^shift to stay finite.
    shift: f64,
    /// Σ w·residual², with the basis' weights.
    pub weighted_rss: f64,
    /// Factor of the normal equations, for the coefficients' variances.
    pub factor: Cholesky,
}

impl Basis {
    /// The model's columns at the samples `indices` of `data`, unit weights, θ scaled by `scale`.
    pub fn new(data: &FitData, indices: impl Iterator<Item = usize>, scale: f64) -> Basis {
        let mut b = Basis::unsummed(data, indices, scale);
        b.refresh_fixed();
        b
    }

    /// [`Basis::new`] on every sample of `data`, with `weights` (one per sample) and further
    /// linear columns `extra` (one value per sample each) beside the model's own. The sums are
    /// formed once, for these weights and columns: they are a quarter of a diagnosis.
    pub fn weighted(data: &FitData, scale: f64, weights: Vec<f64>, extra: Vec<Vec<f64>>) -> Basis {
        Basis::unsummed(data, 0..data.theta.len(), scale).with_weights(weights, extra)
    }

    fn unsummed(data: &FitData, indices: impl Iterator<Item = usize>, scale: f64) -> Basis {
        let mut b = Basis::empty(scale, indices.size_hint().0);
        for i in indices {
            b.push(data.theta[i], data.torque[i], data.direction[i], data.amplitude[i]);
        }
        b
    }

    /// No samples yet, room for `capacity`: fill with [`Basis::push`], then
    /// [`Basis::with_weights`]. Lets a caller build the columns without a [`FitData`] of them.
    pub fn empty(scale: f64, capacity: usize) -> Basis {
        Basis {
            poly: Vec::with_capacity(capacity),
            phase: Vec::with_capacity(capacity),
            sin: Vec::with_capacity(capacity),
            cos: Vec::with_capacity(capacity),
            amp_abs_cos: Vec::with_capacity(capacity),
            torque: Vec::with_capacity(capacity),
            weight: Vec::with_capacity(capacity),
            phase_range: (f64::INFINITY, f64::NEG_INFINITY),
            scale,
            extra: Vec::new(),
            fixed: FixedSums::default(),
        }
    }

    /// Adds one sample (deflection θ, torque, direction, amplitude A), weight 1.
    pub fn push(&mut self, theta: f64, torque: f64, direction: Direction, amplitude: f64) {
        self.poly.push(theta / self.scale);
        let phase = Phase::new::<Libm>(theta / amplitude, direction);
        self.phase_range = (self.phase_range.0.min(phase.angle), self.phase_range.1.max(phase.angle));
        self.phase.push(phase.angle);
        self.sin.push(phase.sin);
        self.cos.push(phase.cos);
        self.amp_abs_cos.push(amplitude * phase.abs_cos);
        self.torque.push(torque);
        self.weight.push(1.0);
    }

    /// The pushed samples with `weights` (one per sample) and further linear columns `extra`,
    /// as [`Basis::weighted`] makes them.
    pub fn with_weights(mut self, weights: Vec<f64>, extra: Vec<Vec<f64>>) -> Basis {
        self.weight = weights;
        self.extra = extra;
        self.refresh_fixed();
        self
    }

    /// The value of column `column` (not the hysteresis one) at sample `i`.
    #[inline(always)]
    fn column(&self, column: usize, i: usize) -> f64 {
        match column {
            0..=2 => powers(self.poly[i])[column],
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
            let p = shape(r, self.sin[i], self.cos[i], (-r * self.phase[i] - shift).exp(), e_shift);
            let wb = self.weight[i] * self.amp_abs_cos[i] * p;
            let poly = powers(self.poly[i]);
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
    pub fn solve(&self, r: f64) -> Option<Solution> {
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

    /// The weights and extra columns back, for the next [`Basis::with_weights`] to reuse.
    pub fn into_weights(self) -> (Vec<f64>, Vec<Vec<f64>>) {
        (self.weight, self.extra)
    }

    /// The weights, leaving none: a buffer to fill and give back with [`Basis::set_weights`].
    pub fn take_weights(&mut self) -> Vec<f64> {
        std::mem::take(&mut self.weight)
    }

    /// Replaces the weights (one per sample).
    pub fn set_weights(&mut self, weights: Vec<f64>) {
        self.weight = weights;
        self.refresh_fixed();
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.torque.len()
    }

    pub fn is_empty(&self) -> bool {
        self.torque.is_empty()
    }

    pub fn objective(&self, s: f64) -> f64 {
        self.solve(s.sinh()).map_or(f64::INFINITY, |sol| sol.weighted_rss)
    }

    pub fn params(&self, r: f64, solution: &Solution, reference_amplitude: f64) -> Result<Params<f64>, FitError> {
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
