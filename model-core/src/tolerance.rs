//! How closely an f32 evaluation (the firmware's) can match the f64 model, point by point.
//!
//! The allowed error is [`RELATIVE_TOLERANCE`] of the loop's scale (max |T| and max |K| over
//! |θ| ≤ 0.99·A) plus how far the exact model itself moves when θ or A move by 2⁻²²
//! relative, the rounding of θ/A in f32: near the turning points |θ| = A the model is steep
//! in θ/A, and no f32 evaluation can do better than that.
use crate::{Direction, Evaluation, Model};

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
