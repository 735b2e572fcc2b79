//! Bouc–Wen hysteresis: the hysteretic deflection z of
//!
//! ```text
//! dz = dθ·(A − |z|ⁿ·(β·sign(dθ·z) + γ)),   z = 0 at rest
//! ```
//!
//! Rate-independent (z follows the path of θ, not time) and smooth along a branch. Minor loops
//! do not close where they started: a held load with dither drifts (ratcheting), which is this
//! physics, not an error of the integration. |z| never exceeds (A/(β + γ))^(1/n).
//!
//! Along a step of one direction, with w = sign(dθ)·z and u = |θ − θ_start|, the equation is
//! autonomous: dw/du = A − |w|ⁿ·(β·sign(w) + γ).
//! - **n = 1: integrated exactly.** For a fixed sign of w it is linear, dw/du = A − c·w with
//!   c = β + γ where w ≥ 0 and β − γ where w < 0. A step is split where z crosses 0 (at most
//!   once: w only rises) and each piece is solved in closed form, so the state after a step is
//!   the same whether θ got there in one step or in many (to rounding), on the host as on the
//!   joint.
//! - **Any other n ≥ 1: classical Runge–Kutta (RK4)** in sub-steps of at most u*/[`SUB_STEPS_PER_SCALE`]
//!   of deflection, u* = z_max/A the deflection over which z saturates. Its error against the
//!   same step taken in 10,000 pieces: below 2·10⁻⁵·z_max per u* travelled, the largest on a
//!   half-u* step across z = 0, where |w|ⁿ is not smooth (8.6·10⁻⁶ just above n = 1, 8.6·10⁻⁷
//!   at n = 1.5: `cargo test -p model-core for_n_other_than_one -- --nocapture`). A joint's tick
//!   moves θ by a small fraction of u*: one sub-step, a few |w|ⁿ.
//!
//! One copy: the simulator's Bouc–Wen gear steps it too.
use crate::{Error, Real};

/// Sub-steps per u* = z_max/A of deflection for n ≠ 1 (see the module's documentation).
pub const SUB_STEPS_PER_SCALE: u32 = 32;
/// Most sub-steps a step of n ≠ 1 takes: beyond 64·u* z sits at its bound to rounding, and a
/// step's cost stays bounded whatever the deflection asked.
const MAX_SUB_STEPS: u32 = 64 * SUB_STEPS_PER_SCALE;

/// The parameters of Bouc–Wen hysteresis: A (dimensionless), β and γ (rad⁻ⁿ), n.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoucWen<F> {
    /// A, > 0: dz/dθ at z = 0.
    pub a: F,
    /// β, > 0, rad⁻ⁿ.
    pub beta: F,
    /// γ, > −β, rad⁻ⁿ.
    pub gamma: F,
    /// n, ≥ 1: the sharpness of the transition to yield (1: exact integration).
    pub n: F,
}

impl<F: Real> BoucWen<F> {
    /// Whether A > 0, β > 0, γ > −β and n ≥ 1, all finite (else z would not stay bounded, or
    /// the step would not be smooth at z = 0).
    pub fn check(&self) -> Result<(), Error> {
        let finite = self.a.is_finite() && self.beta.is_finite() && self.gamma.is_finite() && self.n.is_finite();
        if finite && self.a > F::zero() && self.beta > F::zero() && self.gamma > -self.beta && self.n >= F::one() {
            Ok(())
        } else {
            Err(Error::InvalidBoucWen)
        }
    }

    /// The largest |z|, (A/(β + γ))^(1/n), rad.
    pub fn z_max(&self) -> F {
        let ratio = self.a / (self.beta + self.gamma);
        if self.n == F::one() {
            ratio
        } else {
            ratio.powf(self.n.recip())
        }
    }

    /// w after u along [`BoucWen::rate`]: one classical Runge–Kutta step.
    fn rk4(&self, w: F, u: F) -> F {
        let half = F::from(0.5).unwrap_or(F::zero());
        let two = F::one() + F::one();
        let six = two + two + two;
        let k1 = self.rate(w);
        let k2 = self.rate(w + half * u * k1);
        let k3 = self.rate(w + half * u * k2);
        let k4 = self.rate(w + u * k3);
        w + u / six * (k1 + two * (k2 + k3) + k4)
    }

    /// dw/du = A − |w|ⁿ·(β·sign(w) + γ), w = sign(dθ)·z.
    fn rate(&self, w: F) -> F {
        let c = if w >= F::zero() { self.beta + self.gamma } else { self.gamma - self.beta };
        self.a - w.abs().powf(self.n) * c
    }
}

/// Bouc–Wen hysteresis and its state: z, and the deflection it was last stepped to.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoucWenState<F> {
    params: BoucWen<F>,
    theta: F,
    z: F,
}

impl<F: Real> BoucWenState<F> {
    /// At rest at θ = 0 (z = 0), once the parameters pass [`BoucWen::check`].
    pub fn new(params: BoucWen<F>) -> Result<Self, Error> {
        params.check()?;
        Ok(BoucWenState { params, theta: F::zero(), z: F::zero() })
    }

    /// The hysteretic deflection z, rad.
    pub fn z(&self) -> F {
        self.z
    }

    /// The deflection last stepped to, rad.
    pub fn theta(&self) -> F {
        self.theta
    }

    /// Moves to deflection `theta` (rad) and returns z there.
    pub fn step(&mut self, theta: F) -> Result<F, Error> {
        if !theta.is_finite() {
            return Err(Error::NonFiniteDeflection);
        }
        let delta = theta - self.theta;
        if delta != F::zero() && self.params.n != F::one() {
            let p = &self.params;
            let direction = delta.signum();
            let scale = p.z_max() / p.a;
            let per_scale = F::from(SUB_STEPS_PER_SCALE).unwrap_or(F::one());
            let most = F::from(MAX_SUB_STEPS).unwrap_or(F::one());
            let steps = (delta.abs() / scale * per_scale).ceil().max(F::one()).min(most);
            let h = delta.abs().min(most / per_scale * scale) / steps;
            let mut w = direction * self.z;
            let mut step = F::zero();
            while step < steps {
                w = p.rk4(w, h);
                step = step + F::one();
            }
            let z_max = p.z_max();
            self.z = (direction * w).max(-z_max).min(z_max);
            self.theta = theta;
        } else if delta != F::zero() {
            let p = &self.params;
            let direction = delta.signum();
            let (mut w, mut u) = (direction * self.z, delta.abs());
            if w < F::zero() {
                // dw/du = A − (β − γ)·w > 0 here: w rises towards 0, maybe past it.
                let c = p.beta - p.gamma;
                let to_zero = if c == F::zero() { -w / p.a } else { -(w / (p.a / c - w)).ln_1p() / c };
                if to_zero < u {
                    (w, u) = (F::zero(), u - to_zero);
                } else {
                    (w, u) = (relax(w, u, p.a, c).min(F::zero()), F::zero());
                }
            }
            if u > F::zero() {
                w = relax(w, u, p.a, p.beta + p.gamma);
            }
            // Rounding (f32 on the joint) may carry w a hair past its bound.
            let z_max = p.z_max();
            self.z = (direction * w).max(-z_max).min(z_max);
            self.theta = theta;
        }
        Ok(self.z)
    }

    /// dz/dθ at the present state for motion in the direction of `rising`.
    pub fn slope(&self, rising: bool) -> F {
        self.params.rate(if rising { self.z } else { -self.z })
    }
}

/// w after moving u ≥ 0 along dw/du = a − c·w (closed form).
fn relax<F: Real>(w: F, u: F, a: F, c: F) -> F {
    if c == F::zero() {
        w + a * u
    } else {
        w + (w - a / c) * (-c * u).exp_m1()
    }
}

#[cfg(test)]
mod tests;
