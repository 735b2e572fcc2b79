//! The fit's linear algebra at one r: the model's columns (c1·θ, c2·θ³, c3·θ⁵ and the
//! hysteresis term) and their weighted least-squares solve, either over samples kept for many
//! r ([`Basis`]) or summed as the samples come at one r, with further columns the diagnosis
//! adds ([`NormalEquations`]).
use super::FitError;
use crate::numeric::linalg::Cholesky;
use crate::prepare::FitData;
use model_core::{Direction, Identifiable, Libm, Params, Phase};
use std::borrow::Cow;
use std::f64::consts::FRAC_PI_2;

/// The samples and their weights, and the normal equations' sums that do not depend on r.
///
/// The columns are formed where they are summed, sample by sample, from the samples
/// themselves (θ, T, direction, A): kept per sample (u, φ, sin φ, cos φ, A·|cos φ|, T, w) they
/// were 56 bytes a sample, over 500 MB at 10 M samples, for a solve that holds only its sums.
/// Each r then costs an asin and a square root per sample beside its exp.
pub struct Basis<'a> {
    /// Borrowed from the fit's data, or owned for a subsample ([`Basis::sampled`]).
    data: Cow<'a, FitData>,
    /// One weight per sample; `None` while every weight is 1 (an unweighted fit, or weights
    /// still to come with [`Basis::set_weights`]): no vector of ones beside the data.
    weight: Option<Vec<f64>>,
    phase_range: (f64, f64),
    scale: f64,
    /// The normal equations' entries that do not involve the hysteresis column, which alone
    /// depends on r: computed once per set of weights, so each r costs one phase, one exp and a
    /// row of sums per sample.
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

/// The model's own columns: the three polynomial ones, then the hysteresis one.
const MODEL_COLUMNS: usize = 4;
/// Column of the hysteresis term in the normal equations.
const HYSTERESIS: usize = 3;
/// Below this many samples one thread accumulates faster than several.
const PARALLEL_SAMPLES: usize = 16_384;
/// Every phase φ a sample can have: asin(θ/A) rising, π − asin(θ/A) falling.
const PHASES: (f64, f64) = (-FRAC_PI_2, 3.0 * FRAC_PI_2);

/// The largest exponent −rφ for φ in `phase_range`: the hysteresis column divided by
/// e^shift keeps e^(−rφ) ≤ 1, finite for any r.
fn hysteresis_shift(r: f64, phase_range: (f64, f64)) -> f64 {
    (-r * phase_range.0).max(-r * phase_range.1)
}

/// One sample's model columns at r: the polynomial ones and the two factors of the
/// hysteresis one, A·|cos φ| and p(φ)/e^shift, each caller multiplying them in its own order.
struct Row {
    poly: [f64; 3],
    amp_abs_cos: f64,
    shape: f64,
}

impl Row {
    /// `e_shift` = e^(−shift), see [`hysteresis_shift`].
    #[inline(always)]
    fn new(theta: f64, direction: Direction, amplitude: f64, scale: f64, r: f64, shift: f64, e_shift: f64) -> Row {
        Row::at_phase(theta, &Phase::new::<Libm>(theta / amplitude, direction), amplitude, scale, r, shift, e_shift)
    }

    /// [`Row::new`] with the sample's phase at θ/A already formed.
    #[inline(always)]
    fn at_phase(theta: f64, phase: &Phase<f64>, amplitude: f64, scale: f64, r: f64, shift: f64, e_shift: f64) -> Row {
        Row {
            poly: powers(theta / scale),
            amp_abs_cos: amplitude * phase.abs_cos,
            shape: phase.shape(r, (-r * phase.angle - shift).exp(), e_shift),
        }
    }
}

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

impl Solution {
    /// Solves the `dim`×`dim` normal equations `gram`·x = `rhs` (both triangles filled), `tt`
    /// = TᵀWT, the hysteresis column divided by e^`shift`.
    fn new(dim: usize, gram: &[f64], rhs: &[f64], tt: f64, shift: f64) -> Option<Solution> {
        let factor = Cholesky::new(dim, gram)?;
        let coef = factor.solve(rhs);
        if !coef.iter().all(|c| c.is_finite()) {
            return None;
        }
        let explained: f64 = coef.iter().zip(rhs).map(|(c, r)| c * r).sum();
        Some(Solution { coef, shift, weighted_rss: (tt - explained).max(0.0), factor })
    }
}

/// The model's parameters from a solution at `r`, θ having been scaled by `scale`.
pub fn params(scale: f64, r: f64, solution: &Solution, reference_amplitude: f64) -> Result<Params<f64>, FitError> {
    let [a1, a3, a5, ak] = [solution.coef[0], solution.coef[1], solution.coef[2], solution.coef[3]];
    let k = ak * (-solution.shift).exp();
    let s = scale;
    let params = Params::from_identifiable(
        a1 / s,
        a3 / s.powi(3),
        a5 / s.powi(5),
        Identifiable { h: k * reference_amplitude, r },
        reference_amplitude,
    )?;
    Ok(params)
}

impl<'a> Basis<'a> {
    /// The model's columns on every sample of `data`, unit weights, θ scaled by `scale`.
    pub fn new(data: &'a FitData, scale: f64) -> Basis<'a> {
        Basis::from_data(Cow::Borrowed(data), scale)
    }

    /// The model's columns at the samples `indices` of `data` (a copy of those samples), unit
    /// weights, θ scaled by `scale`.
    pub fn sampled(data: &FitData, indices: impl Iterator<Item = usize>, scale: f64) -> Basis<'static> {
        let capacity = indices.size_hint().0;
        let mut sample = FitData {
            theta: Vec::with_capacity(capacity),
            torque: Vec::with_capacity(capacity),
            direction: Vec::with_capacity(capacity),
            amplitude: Vec::with_capacity(capacity),
        };
        for i in indices {
            sample.theta.push(data.theta[i]);
            sample.torque.push(data.torque[i]);
            sample.direction.push(data.direction[i]);
            sample.amplitude.push(data.amplitude[i]);
        }
        Basis::from_data(Cow::Owned(sample), scale)
    }

    fn from_data(data: Cow<'a, FitData>, scale: f64) -> Basis<'a> {
        let phase_range = data.theta.iter().zip(&data.direction).zip(&data.amplitude).fold(
            (f64::INFINITY, f64::NEG_INFINITY),
            |(lo, hi), ((&theta, &direction), &amplitude)| {
                let angle = Phase::new::<Libm>(theta / amplitude, direction).angle;
                (lo.min(angle), hi.max(angle))
            },
        );
        let mut b = Basis { data, weight: None, phase_range, scale, fixed: FixedSums::default() };
        b.refresh_fixed();
        b
    }

    #[inline(always)]
    fn weight(&self, i: usize) -> f64 {
        self.weight.as_ref().map_or(1.0, |w| w[i])
    }

    fn refresh_fixed(&mut self) {
        const DIM: usize = MODEL_COLUMNS;
        let mut fixed = FixedSums { gram: vec![0.0; DIM * DIM], rhs: vec![0.0; DIM], tt: 0.0 };
        for i in 0..self.len() {
            let (w, t) = (self.weight(i), self.data.torque[i]);
            let poly = powers(self.data.theta[i] / self.scale);
            for a in 0..HYSTERESIS {
                let wa = w * poly[a];
                fixed.rhs[a] += wa * t;
                for b in a..HYSTERESIS {
                    fixed.gram[a * DIM + b] += wa * poly[b];
                }
            }
            fixed.tt += w * t * t;
        }
        for a in 0..DIM {
            for b in 0..a {
                fixed.gram[a * DIM + b] = fixed.gram[b * DIM + a];
            }
        }
        self.fixed = fixed;
    }

    /// Σ w·b·x_a for every column a (the hysteresis column b itself included) and Σ w·b·T,
    /// over samples `range`, with b the hysteresis column at r.
    fn hysteresis_sums(&self, range: std::ops::Range<usize>, r: f64, shift: f64) -> ([f64; MODEL_COLUMNS], f64) {
        let e_shift = (-shift).exp();
        let mut cross = [0.0; MODEL_COLUMNS];
        let mut bt = 0.0;
        let d = &*self.data;
        for i in range {
            let row = Row::new(d.theta[i], d.direction[i], d.amplitude[i], self.scale, r, shift, e_shift);
            let wb = self.weight(i) * row.amp_abs_cos * row.shape;
            cross[0] += wb * row.poly[0];
            cross[1] += wb * row.poly[1];
            cross[2] += wb * row.poly[2];
            cross[HYSTERESIS] += wb * row.amp_abs_cos * row.shape;
            bt += wb * d.torque[i];
        }
        (cross, bt)
    }

    /// Weighted least squares at `r` over the model's four columns.
    pub fn solve(&self, r: f64) -> Option<Solution> {
        use rayon::prelude::*;
        // Over the data's own phases: the tightest shift.
        let shift = hysteresis_shift(r, self.phase_range);
        let n = self.len();
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
        const DIM: usize = MODEL_COLUMNS;
        let mut m = self.fixed.gram.clone();
        for (a, value) in cross.iter().enumerate() {
            m[a * DIM + HYSTERESIS] = *value;
            m[HYSTERESIS * DIM + a] = *value;
        }
        let mut rhs = self.fixed.rhs.clone();
        rhs[HYSTERESIS] = bt;
        Solution::new(DIM, &m, &rhs, self.fixed.tt, shift)
    }

    /// The weights, leaving none: a buffer to fill and give back with [`Basis::set_weights`].
    pub fn take_weights(&mut self) -> Vec<f64> {
        self.weight.take().unwrap_or_default()
    }

    /// Replaces the weights (one per sample).
    pub fn set_weights(&mut self, weights: Vec<f64>) {
        self.weight = Some(weights);
        self.refresh_fixed();
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.data.torque.len()
    }

    pub fn is_empty(&self) -> bool {
        self.data.torque.is_empty()
    }

    pub fn objective(&self, s: f64) -> f64 {
        self.solve(s.sinh()).map_or(f64::INFINITY, |sol| sol.weighted_rss)
    }

    pub fn params(&self, r: f64, solution: &Solution, reference_amplitude: f64) -> Result<Params<f64>, FitError> {
        params(self.scale, r, solution, reference_amplitude)
    }
}

/// The normal equations at one r over the model's columns and `extra_columns` more, summed as
/// the samples come: the diagnosis' Gauss–Newton iterations each form their columns once, and
/// keeping them per sample (the samples, the extra columns and the weights again) was ≥ 49
/// bytes a sample, half a gigabyte at 10 M samples, for a solve that holds only these sums.
pub struct NormalEquations {
    scale: f64,
    r: f64,
    /// Over every phase a sample can have ([`PHASES`]): the data's own are not known before
    /// the sums start. The Cholesky equilibrates the columns, so this costs no accuracy.
    shift: f64,
    e_shift: f64,
    dim: usize,
    /// XᵀWX, row-major, the upper triangle while summing.
    gram: Vec<f64>,
    /// XᵀWT.
    rhs: Vec<f64>,
    /// TᵀWT.
    tt: f64,
    /// The row being added.
    row: Vec<f64>,
}

impl NormalEquations {
    /// No samples yet: θ scaled by `scale`, the hysteresis column at `r`, then `extra_columns`.
    pub fn new(scale: f64, r: f64, extra_columns: usize) -> NormalEquations {
        let dim = MODEL_COLUMNS + extra_columns;
        let shift = hysteresis_shift(r, PHASES);
        NormalEquations {
            scale,
            r,
            shift,
            e_shift: (-shift).exp(),
            dim,
            gram: vec![0.0; dim * dim],
            rhs: vec![0.0; dim],
            tt: 0.0,
            row: vec![0.0; dim],
        }
    }

    /// Adds one sample (deflection θ, torque, its phase on the loop of amplitude A, which the
    /// caller forms once for its own columns too) with `weight`, and its values of the extra
    /// columns (`extra_columns` of them).
    pub fn add(&mut self, theta: f64, torque: f64, phase: &Phase<f64>, amplitude: f64, weight: f64, extra: &[f64]) {
        let Row { poly, amp_abs_cos, shape } =
            Row::at_phase(theta, phase, amplitude, self.scale, self.r, self.shift, self.e_shift);
        self.row[..HYSTERESIS].copy_from_slice(&poly);
        self.row[HYSTERESIS] = amp_abs_cos * shape;
        self.row[MODEL_COLUMNS..].copy_from_slice(extra);
        // The upper triangle, row by row over slices (no index checks in the inner loop: this
        // sum was a fifth of `diagnose`'s time, perf on bench/diagnose.sh's 60 k samples).
        for ((a, &value), rhs) in self.row.iter().enumerate().zip(self.rhs.iter_mut()) {
            let wa = weight * value;
            *rhs += wa * torque;
            let gram = &mut self.gram[a * self.dim + a..(a + 1) * self.dim];
            for (entry, &other) in gram.iter_mut().zip(&self.row[a..]) {
                *entry += wa * other;
            }
        }
        self.tt += weight * torque * torque;
    }

    /// Weighted least squares over every sample added.
    pub fn solve(mut self) -> Option<Solution> {
        let dim = self.dim;
        for a in 0..dim {
            for b in 0..a {
                self.gram[a * dim + b] = self.gram[b * dim + a];
            }
        }
        Solution::new(dim, &self.gram, &self.rhs, self.tt, self.shift)
    }
}
