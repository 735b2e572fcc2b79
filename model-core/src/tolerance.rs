//! How closely an f32 evaluation (the firmware's) can match the f64 model, point by point.
//!
//! The allowed error is [`RELATIVE_TOLERANCE`] of the loop's scale (max |T| and max |K| over
//! |θ| ≤ 0.99·A) plus how far the exact model itself moves when θ or A move by 2⁻²²
//! relative, the rounding of θ/A in f32: near the turning points |θ| = A the model is steep
//! in θ/A, and no f32 evaluation can do better than that.
use crate::gear::{Hysteresis, HysteresisState};
use crate::memory::{branch, SlipElement, TurningPoint};
use crate::{Direction, Evaluation, Evaluator, GearModel, Model};
#[allow(unused_imports)]
use num_traits::Float;

/// Allowed error as a fraction of the loop's torque and stiffness scale.
pub const RELATIVE_TOLERANCE: f64 = 2.0e-5;

/// The loop's scale: max |T| and max |K| of `model` over |θ| ≤ 0.99·A (401 points a branch).
pub fn loop_scales(model: &Model<f64>, amplitude: f64) -> Result<(f64, f64), crate::Error> {
    let on_loop = model.at_amplitude(amplitude)?;
    let mut torque: f64 = 0.0;
    let mut stiffness: f64 = 0.0;
    for i in 0..=400 {
        let theta = 0.99 * amplitude * (f64::from(i) / 200.0 - 1.0);
        for direction in [Direction::Rising, Direction::Falling] {
            let e = on_loop.evaluate(theta, direction)?;
            torque = torque.max(e.torque.abs());
            stiffness = stiffness.max(e.stiffness.abs());
        }
    }
    Ok((torque, stiffness))
}

/// The exact value at (θ, A) and the allowed torque and stiffness errors of an f32
/// evaluation there, given the loop's scales from [`loop_scales`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    pub exact: Evaluation<f64>,
    pub torque: f64,
    pub stiffness: f64,
}

impl Bound {
    pub fn at(
        model: &Model<f64>,
        theta: f64,
        direction: Direction,
        amplitude: f64,
        scales: (f64, f64),
    ) -> Result<Self, crate::Error> {
        let eval = |t: f64, a: f64| model.at_amplitude(a).and_then(|lp| lp.evaluate(t, direction));
        let exact = eval(theta, amplitude)?;
        let eps = 1.0 / 4_194_304.0; // 2⁻²²
        let mut torque_spread: f64 = 0.0;
        let mut stiffness_spread: f64 = 0.0;
        for (dt, da) in [(eps, 0.0), (-eps, 0.0), (0.0, eps), (0.0, -eps)] {
            let moved = eval(theta * (1.0 + dt), amplitude * (1.0 + da))?;
            torque_spread = torque_spread.max((moved.torque - exact.torque).abs());
            stiffness_spread = stiffness_spread.max((moved.stiffness - exact.stiffness).abs());
        }
        Ok(Bound {
            exact,
            torque: RELATIVE_TOLERANCE * scales.0 + torque_spread,
            stiffness: RELATIVE_TOLERANCE * scales.1 + stiffness_spread,
        })
    }

    /// Whether an f32 evaluation is within the bound.
    pub fn admits(&self, torque: f64, stiffness: f64) -> bool {
        (torque - self.exact.torque).abs() <= self.torque && (stiffness - self.exact.stiffness).abs() <= self.stiffness
    }
}

/// How far an f32 Bouc–Wen state's z may drift from the f64 one's, as a fraction of z's bound.
pub const BOUC_WEN_DRIFT: f64 = 1e-4;

/// 2⁻²²: the relative rounding of an f32 quantity after a few operations.
const ROUNDING: f64 = 1.0 / 4_194_304.0;

impl GearModel<f64> {
    /// The motion's scale for [`RELATIVE_TOLERANCE`]: max |T| and max |K| over |θ| ≤
    /// `envelope`: the spring's over those θ plus the hysteresis' (the genetic kind: the largest
    /// loop's, [`loop_scales`] at the half-width the envelope allows; the micro-slip kind:
    /// Σ k_i·min(d_i, that half-width) and Σ k_i).
    pub fn scales(&self, envelope: f64) -> Result<(f64, f64), crate::Error> {
        let mut spring = self.spring.prepare()?;
        let (mut torque, mut stiffness) = (0.0f64, 0.0f64);
        for i in 0..=400 {
            let theta = envelope * (f64::from(i) / 200.0 - 1.0);
            let e = spring.evaluate(theta - self.zero);
            torque = torque.max(e.torque.abs());
            stiffness = stiffness.max(e.stiffness.abs());
        }
        let width = envelope + self.zero.abs();
        let hysteresis = match &self.hysteresis {
            Hysteresis::Genetic(g) => {
                let model = Model::new(crate::Params {
                    c1: 0.0,
                    c2: 0.0,
                    c3: 0.0,
                    alpha: g.alpha,
                    beta: g.beta,
                    omega: g.omega,
                })?;
                loop_scales(&model, width / 0.99)?
            }
            Hysteresis::MicroSlip(_) => {
                let elements = self.slip_elements();
                let t: f64 = elements.iter().map(|e| e.stiffness * e.slip.min(width)).sum();
                (t, elements.iter().map(|e| e.stiffness).sum())
            }
            Hysteresis::BoucWen(term) => {
                let shape = &term.shape;
                let slope = shape.a * 1f64.max(2.0 * shape.beta / (shape.beta + shape.gamma));
                (term.stiffness.abs() * shape.z_max().min(shape.a * width), term.stiffness.abs() * slope)
            }
            Hysteresis::Preisach(preisach) => {
                let total = preisach.total();
                (total, total * crate::preisach::INTERVALS as f64 / preisach.reach)
            }
        };
        Ok((torque + hysteresis.0, stiffness + hysteresis.1))
    }
}

/// How far an f32 evaluation of the joint may be from an f64 evaluator's step, beyond
/// [`RELATIVE_TOLERANCE`] of the motion's scale: what the exact model itself moves when the f32
/// quantities it depends on move by their rounding.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rounding {
    /// N·m.
    pub torque: f64,
    /// N·m/rad.
    pub stiffness: f64,
    /// By how much the f32 evaluator's memory depth may differ (elements at the margin of their
    /// slip limit, where f32 and f64 may disagree on sticking).
    pub memory: usize,
}

impl Evaluator<f64> {
    /// [`Rounding`] at θ (rad), the deflection this evaluator has just stepped to, where it gave
    /// `exact`:
    ///
    /// - x = θ − θ0 rounds in f32 by 2⁻²²·(|θ| + |θ0|): K times that on T;
    /// - genetic: the current branch (from its start, the top turning point, to its target) is
    ///   re-evaluated with x and each end's x moved by ±2⁻²² of the largest of them — the f32
    ///   rounding of x − c and of the half-width w, which near a branch's ends, where the model
    ///   is steep in (x − c)/w, no f32 evaluation can do better than (the analogue of
    ///   [`Bound::at`] on one loop, at the branch's own half-width); the memory must match
    ///   exactly (its turning points are the samples themselves, exact in both);
    /// - micro-slip: for each element within 10⁻⁵·d_i + 2⁻²¹·(|x| + d_i) of its slip limit its
    ///   k_i on K, k_i·that margin on T, and one on the memory.
    pub fn rounding(&self, theta: f64, exact: &Evaluation<f64>) -> Result<Rounding, crate::Error> {
        let x = theta - self.zero();
        let mut rounding = Rounding {
            torque: exact.stiffness.abs() * ROUNDING * (theta.abs() + self.zero().abs()),
            stiffness: 0.0,
            memory: 0,
        };
        match self.hysteresis() {
            HysteresisState::Genetic(memory) => {
                let (torque, stiffness) = branch_spread(memory.model(), memory.turning_points(), x)?;
                rounding.torque += torque;
                rounding.stiffness += stiffness;
            }
            HysteresisState::MicroSlip(slip) => {
                for (&SlipElement { slip: d, stiffness: k }, e) in slip.elements().iter().zip(slip.elastic()) {
                    let margin = 1.0e-5 * d + 2.0 * ROUNDING * (x.abs() + d);
                    if d - e.abs() <= margin {
                        rounding.memory += 1;
                        rounding.stiffness += k;
                        rounding.torque += k * margin;
                    }
                }
            }
            HysteresisState::BoucWen(bouc_wen) => {
                // The f32 state integrates the same equation with its own rounding at every
                // step; the equation contracts (dz/dx falls as |z| grows), so the difference
                // stays within BOUC_WEN_DRIFT of z's bound (measured 2.8e-6 at n = 1, 1.3e-5 at
                // n = 1.5 over 200,000 ticks: model-core's `f32_tracks_f64_along_a_long_random_motion`).
                let term = bouc_wen.term();
                let z_max = term.shape.z_max();
                rounding.torque += term.stiffness.abs() * BOUC_WEN_DRIFT * z_max;
                // dz/dx moves with z: by |n·z^(n−1)·(β + |γ|)| per unit of z, at most n·A/z_max.
                let slope_per_z = term.shape.n * term.shape.a / z_max * 2.0;
                rounding.stiffness += term.stiffness.abs() * slope_per_z * BOUC_WEN_DRIFT * z_max;
            }
            HysteresisState::Preisach(memory) => {
                // Each stored H and each table entry rounds by 2⁻²⁴ of Σ w; x and the branch's
                // start round in the grid's coordinates, where E moves by at most
                // Σ w·INTERVALS/R per rad. Within that rounding of a node, f32 and f64 may read
                // neighbouring intervals, whose slopes differ by up to that much again.
                let shape = memory.shape();
                let (total, reach) = (shape.total(), shape.reach());
                let slope = total * crate::preisach::INTERVALS as f64 / reach;
                let margin = 4.0 * ROUNDING * (x.abs() + reach);
                rounding.torque += slope * margin + (memory.depth() as f64 + 2.0) * ROUNDING * total;
                let h = 2.0 * reach / crate::preisach::INTERVALS as f64;
                let from_node = ((x + reach) / h - ((x + reach) / h).round()).abs() * h;
                if from_node <= margin {
                    rounding.stiffness += slope;
                }
            }
        }
        Ok(rounding)
    }
}

/// How far the genetic hysteresis H and dH/dx at x move when x and the current branch's two ends
/// move by ±2⁻²² of the largest of them (their f32 rounding). The branch runs from the top turning
/// point to the one below it, or to its mirror (−x, −H) when it is alone; at rest (no turning
/// points) H = 0.
fn branch_spread(model: &Model<f64>, points: &[TurningPoint<f64>], theta: f64) -> Result<(f64, f64), crate::Error> {
    let polynomial = model.polynomial();
    let evaluate =
        |ends: Option<(TurningPoint<f64>, TurningPoint<f64>)>, t: f64| -> Result<Evaluation<f64>, crate::Error> {
            let spring = polynomial.evaluate(t);
            Ok(match ends {
                None => spring,
                Some((a, b)) => spring.plus(branch(model, a, b, t)?),
            })
        };
    let ends = match points {
        [] => None,
        [.., below, top] => Some((*top, *below)),
        [top] => Some((*top, TurningPoint { theta: -top.theta, hysteresis: -top.hysteresis })),
    };
    let exact = evaluate(ends, theta)?;
    let size = ends.map_or(theta.abs(), |(a, b)| theta.abs().max(a.theta.abs()).max(b.theta.abs()));
    let delta = ROUNDING * size;
    let moved = |dt: f64, da: f64, db: f64| {
        let ends =
            ends.map(|(a, b)| (TurningPoint { theta: a.theta + da, ..a }, TurningPoint { theta: b.theta + db, ..b }));
        evaluate(ends, theta + dt)
    };
    let mut spread = (0.0f64, 0.0f64);
    for (dt, da, db) in [
        (delta, 0.0, 0.0),
        (-delta, 0.0, 0.0),
        (0.0, delta, 0.0),
        (0.0, -delta, 0.0),
        (0.0, 0.0, delta),
        (0.0, 0.0, -delta),
    ] {
        if ends.is_none() && dt == 0.0 {
            continue;
        }
        let e = moved(dt, da, db)?;
        spread.0 = spread.0.max((e.torque - exact.torque).abs());
        spread.1 = spread.1.max((e.stiffness - exact.stiffness).abs());
    }
    Ok(spread)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::{PAPER_TABLE_2, SEED_AMPLITUDE};

    #[test]
    fn the_bound_widens_where_the_model_is_steep_in_theta_over_a() {
        let model = Model::new(PAPER_TABLE_2).unwrap();
        let a = SEED_AMPLITUDE;
        let scales = loop_scales(&model, a).unwrap();
        let middle = Bound::at(&model, 0.0, Direction::Rising, a, scales).unwrap();
        // Just inside the cap of 1/|cos ωt| (|θ| ≤ 0.99995·A), where K is steepest.
        let edge = Bound::at(&model, 0.9999 * a, Direction::Rising, a, scales).unwrap();
        assert!(edge.stiffness > 10.0 * middle.stiffness, "{edge:?} vs {middle:?}");
        assert!(middle.torque >= RELATIVE_TOLERANCE * scales.0);
        let e = middle.exact;
        assert!(middle.admits(e.torque + 0.9 * middle.torque, e.stiffness - 0.9 * middle.stiffness));
        assert!(!middle.admits(e.torque + 1.1 * middle.torque, e.stiffness));
        assert!(!middle.admits(e.torque, f64::NAN));
    }
}
