//! Bouc–Wen hysteresis with n = 1: the hysteretic deflection z of
//!
//! ```text
//! dz = dθ·(A − |z|·(β·sign(dθ·z) + γ)),   z = 0 at rest
//! ```
//!
//! Rate-independent (z follows the path of θ, not time) and smooth along a branch. Minor loops
//! do not close where they started: a held load with dither drifts (ratcheting), which is this
//! physics, not an error of the integration. |z| never exceeds A/(β + γ).
//!
//! **Integrated exactly.** For a fixed sign of z the equation is linear: with w = sign(dθ)·z and
//! u = |θ − θ_start|, dw/du = A − c·w, c = β + γ where w ≥ 0 and β − γ where w < 0. A step is
//! split where z crosses 0 (at most once: w only rises) and each piece is solved in closed form,
//! so the state after a step is the same whether θ got there in one step or in many (to
//! rounding), on the host as on the joint. One copy: the simulator's Bouc–Wen gear steps it too.
use crate::{Error, Real};

/// The parameters of Bouc–Wen hysteresis with n = 1: A (dimensionless), β and γ (1/rad).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoucWen<F> {
    /// A, > 0: dz/dθ at z = 0.
    pub a: F,
    /// β, > 0, 1/rad.
    pub beta: F,
    /// γ, > −β, 1/rad.
    pub gamma: F,
}

impl<F: Real> BoucWen<F> {
    /// Whether A > 0, β > 0 and γ > −β, all finite (else z would not stay bounded).
    pub fn check(&self) -> Result<(), Error> {
        let finite = self.a.is_finite() && self.beta.is_finite() && self.gamma.is_finite();
        if finite && self.a > F::zero() && self.beta > F::zero() && self.gamma > -self.beta {
            Ok(())
        } else {
            Err(Error::InvalidBoucWen)
        }
    }

    /// The largest |z|, A/(β + γ), rad.
    pub fn z_max(&self) -> F {
        self.a / (self.beta + self.gamma)
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
        if delta != F::zero() {
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
        let p = &self.params;
        let moving_with_z = (self.z >= F::zero()) == rising;
        let c = if moving_with_z { p.beta + p.gamma } else { p.beta - p.gamma };
        p.a - self.z.abs() * c
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
