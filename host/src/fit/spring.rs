//! The spring's part of a fit: where its knots go, the columns they give the linear solves, and
//! the spring a solve's weights make.
//!
//! **The knot rule.** Per side of x = θ − θ0, E = that side's largest |x| in the fitted samples,
//! n = min(8, ⌊E / (20·σθ)⌋) knots at E·j/n (j = 1 … n), plus one at x = 0: up to 17 knots, the
//! outermost ones at the range's edges. (`bench/real/FINDINGS.md` §3 places ⌊E/10σθ⌋ − 1 at
//! E·j/(n + 1), the stiffness constant over the last segment: on the simulator's stiffening
//! springs that lost their last ninth, 0.12 % of peak on the seed gear's loop.) σθ is the larger of the deflection noise and the
//! deflection's spread at rest (the runs' rest windows, pooled): on the measured spring the
//! second differences see a fraction of the 0.030 mrad the encoder jitters by at rest. Why:
//! - The stiffness beyond the range is the outermost segment's (model-core's edge rule), so that
//!   segment extrapolates. Its samples' deflections carry the encoder's noise σθ, which biases
//!   the segment's stiffness towards 0 (errors in x, regression dilution): by the factor
//!   L²/(L² + 12σθ²) for samples spread evenly over a segment of length L, 0.89 at L = 10σθ,
//!   0.97 at 20σθ, and more where the samples bunch at a hold (the measured runs hold the
//!   torque at each tip for ≈ 5 s, a third of their samples, jittering by σθ about one true
//!   deflection). Without a limit a fit on the measured 1 A run predicts the 2 A runs at 1 N·m
//!   RMS against a straight line's 0.08 (`bench/real/FINDINGS.md` §3, §6); at 10σθ the 1 A run's
//!   − edge (0.30 mrad of travel, most of it the hold) came out at 1158 N·m/rad on a spring of
//!   ≈ 2600, and its fits predicted 2 A at 0.26–0.46 N·m. At 20σθ a 1 A run gets one segment a
//!   side or none (E ≈ 0.5–0.7 mrad, σθ = 0.030 mrad) and predicts 2 A at 0.078–0.092 N·m by
//!   the micro-slip kind (the line: 0.081–0.086); `bash bench/real.sh`, section 3, 28 → 12 of
//!   54 cases worse than the line (15σθ: 24, 25σθ: 19, 30σθ: 21). A gear recorded with a fine
//!   encoder keeps its 8 knots a side (the simulator's 20-bit encoders: 20σθ = 0.035 mrad).
//! - Uniform, because the variants tried on the measured runs (quantiles of |x|, denser near 0,
//!   4/8/12 knots) were second order there and uniform is the simplest to state.
//! - 8 a side: the seed gear's quintic spring is then within 0.006 % of its peak torque.
//! - **Then placed (the micro-slip kind, `fit::motion::placed_knots`)**: each interior knot is
//!   moved in turn, twice over, to the point of a 64-step grid of its side where the kind's
//!   solve on an 8192-sample subsample has the least RSS, still ≥ 10σθ from its neighbours (a
//!   step in stiffness asks for a knot close on each side; 20σθ there cost the measured joint
//!   fit a run: `bench/real.sh` section 1, 2-4 0.157 → 0.161 N·m against a goal of 0.16), and
//!   the segment at an edge at least half the rule's (its stiffness is the one the spring
//!   extrapolates with: see `EDGE_SEGMENT` there). Free knots: a catalogue gear's stiffness steps
//!   at two torques, uniform knots E/8 apart smear each step over a segment (fitted on the sine:
//!   nested motion 1.47× the floor, centre-curve K 5.5 % off), a pair of knots around each step
//!   follows it (1.04×, 2.5 %). Each trial is the fine grid's normal equations mapped onto the
//!   trial's knots (exact: a spring on grid points is one on the grid), one pass over the
//!   subsample in all.
//! - Separate sides: the spring's asymmetry. K ≥ 0 at every knot (the solves ask it) keeps the
//!   spring monotone, as the physics asks.
//!
//! **The shorter side, continued.** Where one side's extent falls short of the other's by more
//! than 20σθ, that side gets one knot fewer of its own and one at the mirror of the longer
//! side's edge, beyond its samples, so that the spring's range is symmetric: there its stiffness
//! is its own edge's plus what the longer side's stiffness gains over the same stretch,
//! K(−e_l) = K(e_s) + K(e_l) − K(−e_s) (e_s, e_l the shorter and longer side's edges; ≥ 0). No
//! sample identifies it (no column in the solves); it carries the shape a gear's two sides share
//! (stiffening or softening) rather than the edge's straight line. Why: a recording rarely
//! reaches the same extent on both sides (`simulate`'s random motion: −1.1685, +1.0007 mrad), a
//! gear's stiffness curve is much alike on its two sides, and a motion that reaches the longer
//! side's extent on both is the next one a user records. The micro-slip gear (k3 = 1.2·10¹⁰
//! N·m/rad³) fitted on the random motion predicted the sine 5.05× and the nested motion 3.28× the
//! floor with the edge's line (1.01× within the fitted range), 1.04× and 1.03× continued. The odd
//! polynomial of model version 1 had that shape by construction. Beyond the longer side's extent
//! both sides continue with their edge's stiffness, as before.
use crate::gear::Projected;
use model_core::spring::MAX_KNOTS;
use model_core::{Knot, Spring};

/// Most knots a side of x = 0 gets (model-core's 17 = 8 + 8 + the one at 0).
pub const KNOTS_PER_SIDE: usize = (MAX_KNOTS - 1) / 2;
/// The knot rule spaces knots at least this many deflection-noise σ apart.
pub const KNOT_SPACING_IN_NOISE: f64 = 20.0;
/// Placed knots (`fit::motion::placed_knots`) stay at least this many deflection-noise σ apart.
pub const PLACED_KNOT_GAP_IN_NOISE: f64 = 10.0;

/// The knots of a spring fitted on x within `[lo, hi]` (lo ≤ 0 ≤ hi), the deflection noise σθ
/// being `noise`: see the module's documentation.
pub fn knot_rule(lo: f64, hi: f64, noise: f64) -> Vec<f64> {
    knots_within(lo, hi, noise, [KNOTS_PER_SIDE; 2])
}

/// [`knot_rule`] with at most `most` = [− side, + side] knots a side.
fn knots_within(lo: f64, hi: f64, noise: f64, most: [usize; 2]) -> Vec<f64> {
    let per_side = |extent: f64, most: usize| -> usize {
        if !(extent > 0.0) {
            return 0;
        }
        let limit = if noise > 0.0 { (extent / (KNOT_SPACING_IN_NOISE * noise)).floor() } else { f64::INFINITY };
        (limit.max(0.0) as usize).min(most)
    };
    let (minus, plus) = (per_side(-lo, most[0]), per_side(hi, most[1]));
    // The outermost knot is the edge itself: E·n/n can round past it, out of the spring's range.
    let at = |extent: f64, j: usize, n: usize| if j == n { extent } else { extent * j as f64 / n as f64 };
    let mut knots: Vec<f64> = (1..=minus).rev().map(|j| at(lo, j, minus)).collect();
    knots.push(0.0);
    knots.extend((1..=plus).map(|j| at(hi, j, plus)));
    knots
}

/// The shorter side's continuation out to the longer side's extent: a knot at the mirror of
/// the longer side's edge, whose stiffness the shorter side's edge gets plus what the longer
/// side's stiffness gains over the same stretch (see the module's documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Mirrored {
    /// The shorter side's edge (the fitted range's), x rad.
    short_edge: f64,
    /// The longer side's edge, x rad (the other sign).
    long_edge: f64,
}

/// The spring's columns for a fit: one per knot, its stiffness K_j ≥ 0.
#[derive(Clone, Debug, PartialEq)]
pub struct SpringBasis {
    knots: Vec<f64>,
    /// Each knot's column integral to x = 0 ([`model_core::spring::basis_origin`]).
    at_zero: Vec<f64>,
    range: [f64; 2],
    mirrored: Option<Mirrored>,
    /// Each knot at −x shares the stiffness of its mirror at +x: one column per pair.
    paired: bool,
}

impl SpringBasis {
    /// The knots of [`knot_rule`] over the fitted range `[lo, hi]` of x, the shorter side with
    /// one knot fewer where it is continued to the longer side's extent.
    pub fn new(range: [f64; 2], noise: f64) -> Self {
        let [lo, hi] = [range[0].min(0.0), range[1].max(0.0)];
        // Continued where the sides differ by more than the knots' least spacing (and the shorter
        // side has knots of its own to continue from).
        let spacing = KNOT_SPACING_IN_NOISE * noise;
        let mirrored = if -lo - hi > spacing && hi > spacing {
            Some(Mirrored { short_edge: hi, long_edge: lo })
        } else if hi + lo > spacing && -lo > spacing {
            Some(Mirrored { short_edge: lo, long_edge: hi })
        } else {
            None
        };
        let most = match mirrored {
            Some(m) if m.short_edge > 0.0 => [KNOTS_PER_SIDE, KNOTS_PER_SIDE - 1],
            Some(_) => [KNOTS_PER_SIDE - 1, KNOTS_PER_SIDE],
            None => [KNOTS_PER_SIDE; 2],
        };
        SpringBasis::of(knots_within(lo, hi, noise, most), [lo, hi], mirrored)
    }

    fn of(knots: Vec<f64>, range: [f64; 2], mirrored: Option<Mirrored>) -> Self {
        let mut at_zero = vec![0.0; knots.len()];
        model_core::spring::basis_origin(&knots, &mut at_zero);
        SpringBasis { knots, at_zero, range, mirrored, paired: false }
    }

    /// The knot rule's knots over the larger side's extent on both sides, mirrored about x = 0;
    /// with `shared`, each pair ±x shares one stiffness (one column per pair, the knot at 0
    /// first): the spring forced point-symmetric, S(−x) = −S(x). `diagnose` tests a spring's
    /// asymmetry by the two, which differ only in that constraint.
    pub fn mirrored_knots(range: [f64; 2], noise: f64, shared: bool) -> Self {
        let extent = (-range[0]).max(range[1]).max(0.0);
        let basis = SpringBasis::of(knot_rule(-extent, extent, noise), [-extent, extent], None);
        SpringBasis { paired: shared, ..basis }
    }

    /// The middle knot's index (x = 0) of a paired basis.
    fn middle(&self) -> usize {
        self.knots.len() / 2
    }

    /// Values per knot folded onto the pairs: the middle knot's, then each pair's sum.
    fn fold(&self, per_knot: &[f64], out: &mut [f64]) {
        let middle = self.middle();
        for (j, value) in out.iter_mut().enumerate().take(self.len()) {
            *value = if j == 0 { per_knot[middle] } else { per_knot[middle - j] + per_knot[middle + j] };
        }
    }

    /// The same range with other knots (increasing, holding x = 0 and the range's edges).
    pub fn with_knots(&self, knots: Vec<f64>) -> Self {
        SpringBasis::of(knots, self.range, self.mirrored)
    }

    /// The fitted range, [lo, hi] of x: the samples' (the spring's own may reach further, see
    /// [`SpringBasis::spring`]).
    pub fn range(&self) -> [f64; 2] {
        self.range
    }

    /// Columns: one per knot, or per pair of mirrored knots.
    pub fn len(&self) -> usize {
        if self.paired {
            self.middle() + 1
        } else {
            self.knots.len()
        }
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
        let (mut per_knot, mut stiffness) = ([0.0; MAX_KNOTS], [0.0; MAX_KNOTS]);
        model_core::spring::basis(&self.knots, x, &mut per_knot, &mut stiffness);
        if self.paired {
            self.fold(&per_knot, torque);
        } else {
            torque[..self.knots.len()].copy_from_slice(&per_knot[..self.knots.len()]);
        }
    }

    /// The columns as the offline model takes them (`crate::gear::step_offline`): at x_m,
    /// carried to x along their slopes, B_j(x_m) + h_j(x_m)·(x − x_m), each divided by `scale`.
    #[inline]
    pub fn row(&self, at: Projected, scale: f64, out: &mut [f64]) {
        if self.knots.len() > MAX_KNOTS {
            // The fine grid knots are placed on (`fit::motion::placed_knots`), not a model's.
            let (mut torque, mut stiffness) = (vec![0.0; self.knots.len()], vec![0.0; self.knots.len()]);
            model_core::spring::basis_from(&self.knots, &self.at_zero, at.theta_m, &mut torque, &mut stiffness);
            for ((value, b), h) in out.iter_mut().zip(torque).zip(stiffness) {
                *value = (b + h * at.offset) / scale;
            }
            return;
        }
        let (mut torque, mut stiffness) = ([0.0; MAX_KNOTS], [0.0; MAX_KNOTS]);
        model_core::spring::basis_from(&self.knots, &self.at_zero, at.theta_m, &mut torque, &mut stiffness);
        if self.paired {
            let mut carried = [0.0; MAX_KNOTS];
            for ((value, b), h) in carried.iter_mut().zip(torque).zip(stiffness) {
                *value = (b + h * at.offset) / scale;
            }
            self.fold(&carried, out);
            return;
        }
        for ((value, b), h) in out.iter_mut().zip(torque).zip(stiffness) {
            *value = (b + h * at.offset) / scale;
        }
    }

    /// The spring of the knots' stiffnesses `weights` (N·m/rad, one per knot), over the fitted
    /// range, or with the shorter side continued out to the longer side's extent. A weight that
    /// the solve left a hair below 0 is 0.
    pub fn spring(&self, weights: &[f64]) -> Result<Spring<f64>, model_core::Error> {
        let per_knot: Vec<f64> = if self.paired {
            let middle = self.middle();
            (0..self.knots.len()).map(|j| weights.get(j.abs_diff(middle)).copied().unwrap_or(0.0)).collect()
        } else {
            weights.to_vec()
        };
        let mut knots: Vec<Knot<f64>> =
            self.knots.iter().zip(&per_knot).map(|(&x, &k)| Knot { x, stiffness: k.max(0.0) }).collect();
        let Some(Mirrored { short_edge, long_edge }) = self.mirrored else {
            return Spring::of_knots(&knots, self.range);
        };
        // The stiffness at x, linear between the knots (the solve's knots hold both edges).
        let at = |x: f64| -> f64 {
            let right = knots.partition_point(|k| k.x < x).clamp(1, knots.len().saturating_sub(1).max(1));
            match (knots.get(right - 1), knots.get(right)) {
                (Some(a), Some(b)) if b.x > a.x => {
                    a.stiffness + (b.stiffness - a.stiffness) * ((x - a.x) / (b.x - a.x)).clamp(0.0, 1.0)
                }
                (Some(a), _) => a.stiffness,
                _ => 0.0,
            }
        };
        let gained = at(long_edge) - at(-short_edge);
        let continued = Knot { x: -long_edge, stiffness: (at(short_edge) + gained).max(0.0) };
        let range = if short_edge > 0.0 { [long_edge, -long_edge] } else { [-long_edge, long_edge] };
        if short_edge > 0.0 {
            knots.push(continued);
        } else {
            knots.insert(0, continued);
        }
        Spring::of_knots(&knots, range)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_knot_rule_spaces_knots_by_twenty_noise_sigmas_and_caps_each_side_at_eight() {
        // Wide sides: 8 each, the outermost at the edges, x = 0 always.
        let knots = knot_rule(-2.0e-3, 4.0e-3, 1.0e-6);
        assert_eq!(knots.len(), 17);
        assert_eq!((knots[0], knots[8], knots[16]), (-2.0e-3, 0.0, 4.0e-3));
        assert!(knots.windows(2).all(|w| w[1] > w[0]));
        // A short side gets ⌊E / 20σ⌋ knots, none below 20σ; the outermost exactly at the edge.
        assert_eq!(knot_rule(-3.5e-4, 1.0e-3, 1.5e-5), [-3.5e-4, 0.0, 1.0e-3 / 3.0, 2.0e-3 / 3.0, 1.0e-3]);
        assert_eq!(knot_rule(-2.9e-4, 0.0, 1.5e-5), [0.0]);
        let edge = -6.373218443481491e-3;
        // At 5 and 7 knots E·n/n rounds past this E.
        assert!((1..=8).all(|n| knot_rule(edge, 0.0, -edge / (20.0 * n as f64 + 1.0))[0] == edge));
        // Without noise (a loop table) the cap alone.
        assert_eq!(knot_rule(-1.0, 1.0, 0.0).len(), 17);
    }

    #[test]
    fn a_fitted_spring_is_its_knots_with_the_range_as_given() {
        let basis = SpringBasis::new([-2.0e-3, 2.0e-3], 1.0e-6);
        let weights: Vec<f64> = (0..basis.len()).map(|j| 1000.0 + 10.0 * j as f64).collect();
        let spring = basis.spring(&weights).unwrap();
        assert_eq!(spring.range, [-2.0e-3, 2.0e-3]);
        // The spring evaluates to the columns' weighted sum.
        let mut prepared = spring.prepare().unwrap();
        let mut row = vec![0.0; basis.len()];
        for x in [-1.9e-3, -1.0e-4, 0.0, 3.0e-4, 1.9e-3] {
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

    #[test]
    fn the_shorter_side_continues_with_the_longer_sides_gain_in_stiffness() {
        // + side to 1 mrad, − side to 2 mrad: 8 knots −, 7 knots +, one more at +2 mrad.
        let basis = SpringBasis::new([-2.0e-3, 1.0e-3], 1.0e-6);
        assert_eq!(basis.len(), 16);
        assert_eq!(basis.range(), [-2.0e-3, 1.0e-3]);
        // A stiffening spring, 1000 N·m/rad softer on the + side: K = 5000 + 4·10⁶·|x| (− side).
        let weights: Vec<f64> =
            basis.knots().iter().map(|&x| if x < 0.0 { 5000.0 - 4.0e6 * x } else { 4000.0 + 4.0e6 * x }).collect();
        let spring = basis.spring(&weights).unwrap();
        assert_eq!(spring.range, [-2.0e-3, 2.0e-3]);
        let last = *spring.knots().last().unwrap();
        assert_eq!(last.x, 2.0e-3);
        // K(1 mrad) + K(−2 mrad) − K(−1 mrad) = 8000 + 13000 − 9000.
        assert!((last.stiffness - 12_000.0).abs() < 1e-6, "{last:?}");
        // Within the samples' range the spring is the solve's.
        let mut prepared = spring.prepare().unwrap();
        let mut row = vec![0.0; basis.len()];
        for x in [-1.5e-3, 0.5e-3, 1.0e-3] {
            basis.torque_row(x, &mut row);
            let sum: f64 = row.iter().zip(&weights).map(|(b, k)| b * k).sum();
            assert!((prepared.evaluate(x).torque - sum).abs() <= 1e-12 * sum.abs().max(1.0));
        }
        // Sides within 20σθ of each other: no continuation.
        assert_eq!(
            SpringBasis::new([-1.0e-3, 0.995e-3], 1.0e-6).spring(&[1.0; 17]).unwrap().range,
            [-1.0e-3, 0.995e-3]
        );
    }

    #[test]
    fn a_symmetric_basis_gives_a_point_symmetric_spring_over_the_larger_side() {
        let basis = SpringBasis::mirrored_knots([-2.0e-3, 1.0e-3], 1.0e-6, true);
        // 17 knots over ±2 mrad, one column for x = 0 and one per pair.
        assert_eq!((basis.knots().len(), basis.len()), (17, 9));
        let weights: Vec<f64> = (0..basis.len()).map(|j| 1000.0 + 500.0 * j as f64).collect();
        let spring = basis.spring(&weights).unwrap();
        assert_eq!(spring.range, [-2.0e-3, 2.0e-3]);
        let mut prepared = spring.prepare().unwrap();
        let mut row = vec![0.0; basis.len()];
        for x in [-1.9e-3, -4.0e-4, 0.0, 7.0e-4, 1.5e-3] {
            let torque = prepared.evaluate(x).torque;
            assert!((torque + prepared.evaluate(-x).torque).abs() <= 1e-12 * torque.abs().max(1.0), "{x}");
            basis.torque_row(x, &mut row);
            let sum: f64 = row.iter().zip(&weights).map(|(b, k)| b * k).sum();
            assert!((torque - sum).abs() <= 1e-12 * sum.abs().max(1.0), "{x}: {torque} vs {sum}");
        }
    }
}
