//! The spring's part of a fit: where its knots go, the columns they give the linear solves, the
//! spring a solve's weights make; and the deflection's zero θ0 with the torque sensor's offset,
//! read from a recording's rest window.
//!
//! **The knot rule.** Per side of x = θ − θ0, E = that side's largest |x| in the fitted samples,
//! n = min(8, ⌊E / (10·σθ)⌋) knots at E·j/n (j = 1 … n), plus one at x = 0: up to 17 knots, the
//! outermost ones at the range's edges. Why:
//! - The stiffness beyond the range is the outermost knot's (model-core's edge rule), so the last
//!   segment is the one that extrapolates. Fitted on a cluster of samples whose spread is
//!   deflection noise, its slope is biased towards 0 (errors in x); at least 10σθ between knots
//!   keeps it fitted on real travel. Without that limit a fit on the measured 1 A run predicts the
//!   2 A runs at 1 N·m RMS against a straight line's 0.08 (`bench/real/FINDINGS.md` §3, §6).
//! - Uniform, because the variants tried on the measured runs (quantiles of |x|, denser near 0,
//!   4/8/12 knots) were second order there and uniform is the simplest to state.
//! - 8 a side: the seed gear's quintic spring is then within 0.006 % of its peak torque.
//! - Separate sides: the spring's asymmetry. K ≥ 0 at every knot (the solves ask it) keeps the
//!   spring monotone, as the physics asks.
use crate::numeric::mean;
use model_core::spring::MAX_KNOTS;
use model_core::{Knot, Spring};

/// Most knots a side of x = 0 gets (model-core's 17 = 8 + 8 + the one at 0).
pub const KNOTS_PER_SIDE: usize = (MAX_KNOTS - 1) / 2;
/// Knots lie at least this many deflection-noise σ apart.
pub const KNOT_SPACING_IN_NOISE: f64 = 10.0;

/// The knots of a spring fitted on x within `[lo, hi]` (lo ≤ 0 ≤ hi), the deflection noise σθ
/// being `noise`: see the module's documentation.
pub fn knot_rule(lo: f64, hi: f64, noise: f64) -> Vec<f64> {
    let per_side = |extent: f64| -> usize {
        if !(extent > 0.0) {
            return 0;
        }
        let limit = if noise > 0.0 { (extent / (KNOT_SPACING_IN_NOISE * noise)).floor() } else { f64::INFINITY };
        (limit.max(0.0) as usize).min(KNOTS_PER_SIDE)
    };
    let (minus, plus) = (per_side(-lo), per_side(hi));
    let mut knots: Vec<f64> = (1..=minus).rev().map(|j| lo * j as f64 / minus as f64).collect();
    knots.push(0.0);
    knots.extend((1..=plus).map(|j| hi * j as f64 / plus as f64));
    knots
}

/// The spring's columns for a fit: one per knot, its stiffness K_j ≥ 0.
#[derive(Clone, Debug, PartialEq)]
pub struct SpringBasis {
    knots: Vec<f64>,
    range: [f64; 2],
}

impl SpringBasis {
    /// The knots of [`knot_rule`] over the fitted range `[lo, hi]` of x.
    pub fn new(range: [f64; 2], noise: f64) -> Self {
        let [lo, hi] = [range[0].min(0.0), range[1].max(0.0)];
        SpringBasis { knots: knot_rule(lo, hi, noise), range: [lo, hi] }
    }

    /// Columns: one per knot.
    pub fn len(&self) -> usize {
        self.knots.len()
    }

    /// Never empty: the knot at x = 0 is always there.
    pub fn is_empty(&self) -> bool {
        self.knots.is_empty()
    }

    /// The knots, x rad.
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// The columns' torque B_j(x) into `torque` (its first [`len`](Self::len) entries).
    pub fn torque_row(&self, x: f64, torque: &mut [f64]) {
        let mut stiffness = [0.0; MAX_KNOTS];
        model_core::spring::basis(&self.knots, x, torque, &mut stiffness);
    }

    /// The spring of the knots' stiffnesses `weights` (N·m/rad, one per knot), over the fitted
    /// range. A weight that the solve left a hair below 0 is 0.
    pub fn spring(&self, weights: &[f64]) -> Result<Spring<f64>, model_core::Error> {
        let knots: Vec<Knot<f64>> =
            self.knots.iter().zip(weights).map(|(&x, &k)| Knot { x, stiffness: k.max(0.0) }).collect();
        Spring::of_knots(&knots, self.range)
    }
}

/// The samples at a recording's start during which the gear stands still, and what they read.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RestWindow {
    /// Samples from the first.
    pub samples: usize,
    /// How long it lasts, s.
    pub seconds: f64,
    /// The mean deflection, rad: θ0 for a gear at rest.
    pub deflection_rad: f64,
    /// Its standard error, rad: the deflection noise over √samples.
    pub deflection_se_rad: f64,
    /// The mean torque, N·m: the torque sensor's offset for a gear at rest.
    pub torque_nm: f64,
}

/// Band around the first sample's deflection within which the gear counts as still, in σθ:
/// wider than noise ever spans at these sample counts, and wider than one encoder step
/// (σθ ≥ step/√12).
const REST_BAND_IN_NOISE: f64 = 4.0;
/// Fewest samples of a rest window the recording does not declare (`# start: rest`): fewer say
/// nothing about θ0 that the fit would not see better.
const MIN_UNDECLARED_REST: usize = 20;
/// An undeclared rest window's torque is at most this fraction of the recording's torque range:
/// a gear held still under load is not at rest.
const REST_TORQUE_FRACTION: f64 = 0.05;

/// The leading samples whose deflection stays within 4σθ of the first's, when they make a rest
/// window: any number when the recording says it starts at rest (`declared`), otherwise at
/// least 20 at a torque within 5 % of the recording's torque range.
pub fn rest_window(time: &[f64], deflection: &[f64], torque: &[f64], noise: f64, declared: bool) -> Option<RestWindow> {
    let first = *deflection.first()?;
    let band = REST_BAND_IN_NOISE * noise;
    let samples = deflection.iter().take_while(|&&theta| (theta - first).abs() <= band).count();
    let still = deflection.get(..samples)?;
    let torque_still = torque.get(..samples)?;
    let window = RestWindow {
        samples,
        seconds: time.get(samples - 1).zip(time.first()).map_or(0.0, |(end, start)| end - start),
        deflection_rad: mean(still),
        deflection_se_rad: noise / (samples as f64).sqrt(),
        torque_nm: mean(torque_still),
    };
    if declared {
        return Some(window);
    }
    let (lo, hi) = torque.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| (l.min(t), h.max(t)));
    let at_rest = window.torque_nm.abs() <= REST_TORQUE_FRACTION * (hi - lo);
    (samples >= MIN_UNDECLARED_REST && at_rest).then_some(window)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_knot_rule_spaces_knots_by_ten_noise_sigmas_and_caps_each_side_at_eight() {
        // Wide sides: 8 each, the outermost at the edges, x = 0 always.
        let knots = knot_rule(-2.0e-3, 4.0e-3, 1.0e-6);
        assert_eq!(knots.len(), 17);
        assert_eq!((knots[0], knots[8], knots[16]), (-2.0e-3, 0.0, 4.0e-3));
        assert!(knots.windows(2).all(|w| w[1] > w[0]));
        // A short side gets ⌊E / 10σ⌋ knots, none below 10σ.
        assert_eq!(knot_rule(-3.5e-4, 1.0e-3, 3.0e-5), [-3.5e-4, 0.0, 1.0e-3 / 3.0, 2.0e-3 / 3.0, 1.0e-3]);
        assert_eq!(knot_rule(-2.9e-4, 0.0, 3.0e-5), [0.0]);
        // Without noise (a loop table) the cap alone.
        assert_eq!(knot_rule(-1.0, 1.0, 0.0).len(), 17);
    }

    #[test]
    fn a_fitted_spring_is_its_knots_with_the_range_as_given() {
        let basis = SpringBasis::new([-1.0e-3, 2.0e-3], 1.0e-6);
        let weights: Vec<f64> = (0..basis.len()).map(|j| 1000.0 + 10.0 * j as f64).collect();
        let spring = basis.spring(&weights).unwrap();
        assert_eq!(spring.range, [-1.0e-3, 2.0e-3]);
        // The spring evaluates to the columns' weighted sum.
        let mut prepared = spring.prepare().unwrap();
        let mut row = vec![0.0; basis.len()];
        for x in [-9.0e-4, -1.0e-4, 0.0, 3.0e-4, 1.9e-3] {
            basis.torque_row(x, &mut row);
            let sum: f64 = row.iter().zip(&weights).map(|(b, k)| b * k).sum();
            let torque = prepared.evaluate(x).torque;
            assert!((torque - sum).abs() <= 1e-12 * sum.abs().max(1.0), "{x}: {torque} vs {sum}");
        }
        // A solve's −0 or −1e-18 is 0, not a refused negative stiffness.
        let mut tiny = weights.clone();
        tiny[3] = -1.0e-18;
        assert_eq!(basis.spring(&tiny).unwrap().knots()[3].stiffness, 0.0);
    }
}
