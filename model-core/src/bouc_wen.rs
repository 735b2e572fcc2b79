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
//! - **Any other n (1 < n ≤ [`MAX_N`]): the Taylor polynomial of degree 2** in w, in sub-steps
//!   along which w moves by at most z_max/[`SUB_STEPS_PER_SCALE`] (u*/16 of deflection,
//!   u* = z_max/A the deflection over which z saturates, or less where γ < β makes dw/du up to
//!   A·2β/(β + γ)). f′ = df/dw = −c·n·|w|ⁿ/w comes from the |w|ⁿ kept with z, so a sub-step
//!   takes one |w|ⁿ, its end's, which is also the slope K needs and the next sub-step's f.
//!   Its error against the same step taken in 10,000 pieces: below 5·10⁻³·z_max per u*
//!   travelled for n up to 6 (the fit's range), from narrow loops to wide ones (γ from −0.95β
//!   to 49β); the largest, 4.4·10⁻³, at n = 6 with γ = 49β starting at −0.99·z_max
//!   (`cargo test -p model-core for_n_other_than_one -- --nocapture` prints it). z forgets its
//!   past over a few u*, so the error does not grow with the length of a motion; in torque it
//!   is below k_h·z_max·5·10⁻³, 0.5 % of the hysteresis' own amplitude.
//! - **A tick's cost for n ≠ 1** grows with the deflection it moves: one sub-step (one |w|ⁿ)
//!   per z_max/16 of z. At a gear's speeds on a 20 kHz tick that is one sub-step
//!   (`bench/firmware.sh` measures its motions at 0.22 rad/s of deflection). A longer step
//!   takes more, up to [`MAX_SUB_STEPS`], then longer ones; beyond [`SATURATING_SCALES`]·u*
//!   z is at its bound and the step costs nothing. (Heun's method takes two |w|ⁿ a sub-step:
//!   442 instructions a tick against the budget of 400 in `bench/firmware.sh` when it was
//!   tried; RK4 takes four.)
//!
//! One copy: the simulator's Bouc–Wen gear steps it too.
use crate::gear::Memory;
use crate::memory::{Alone, Finish, Hysteretic};
use crate::{Direction, Elementary, Error, Evaluation, Libm, Real};

/// Sub-steps per u* = z_max/A of deflection for n ≠ 1 (see the module's documentation).
pub const SUB_STEPS_PER_SCALE: u32 = 16;
/// The travel, in u*, beyond which z is at its bound to rounding, from anywhere (n ≠ 1): z
/// escapes −z_max over ln(1/ε)·u*/n where dw/du there is ε·A, then relaxes to z_max over u*/n.
pub const SATURATING_SCALES: u32 = 64;
/// Most sub-steps a step of n ≠ 1 takes, so that its cost stays bounded whatever the deflection
/// asked: a longer step takes longer sub-steps.
pub const MAX_SUB_STEPS: u32 = 64 * SUB_STEPS_PER_SCALE;

/// The sharpest transition to yield accepted: a sub-step's Taylor gain 1 + h·f′/2 stays within
/// [1 − n/32, 1 + n/32] ⊂ [0, 2] up to it; beyond, the branch is elastic–perfectly-plastic to
/// f32's precision anyway.
pub const MAX_N: u32 = 32;

/// The parameters of Bouc–Wen hysteresis: A (dimensionless), β and γ (rad⁻ⁿ), n.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoucWen<F> {
    /// A, > 0: dz/dθ at z = 0.
    pub a: F,
    /// β, > 0, rad⁻ⁿ.
    pub beta: F,
    /// γ, > −β, rad⁻ⁿ.
    pub gamma: F,
    /// n, from 1 to [`MAX_N`]: the sharpness of the transition to yield (1: exact integration).
    pub n: F,
}

impl<F: Real> BoucWen<F> {
    /// Whether A > 0, β > 0, γ > −β and 1 ≤ n ≤ [`MAX_N`], all finite (else z would not stay
    /// bounded, or the step would not be smooth at z = 0).
    pub fn check(&self) -> Result<(), Error> {
        let finite = self.a.is_finite() && self.beta.is_finite() && self.gamma.is_finite() && self.n.is_finite();
        if finite
            && self.a > F::zero()
            && self.beta > F::zero()
            && self.gamma > -self.beta
            && self.n >= F::one()
            && self.n <= F::from(MAX_N).unwrap_or(F::one())
        {
            Ok(())
        } else {
            Err(Error::InvalidBoucWen)
        }
    }

    /// The largest |z|, (A/(β + γ))^(1/n), rad.
    pub fn z_max(&self) -> F {
        self.z_max_with::<Libm>()
    }

    /// [`BoucWen::z_max`] with the elementary functions of `E`.
    pub fn z_max_with<E: Elementary<F>>(&self) -> F {
        pow::<F, E>(self.a / (self.beta + self.gamma), self.n.recip())
    }

    /// w and |w|ⁿ after `steps` sub-steps of `h` from w (whose |w|ⁿ is `w_pow`), w held to
    /// `w_max` = z_max (it only rises, towards z_max): the Taylor polynomial of degree 2,
    /// w + h·f·(1 + h·f′/2) with f = dw/du and f′ = df/dw = −c·n·|w|ⁿ/w, so that a sub-step
    /// takes one |w|ⁿ, its end's, which is also the slope K needs and the next sub-step's f.
    fn taylor<E: Elementary<F>>(&self, mut w: F, mut w_pow: F, h: F, steps: u32, w_max: F) -> (F, F) {
        let half_h = F::from(0.5).unwrap_or(F::zero()) * h;
        // A float count: with an integer one the compiler unrolled the loop eight times, 600 B
        // of the joint's flash for a loop that runs once a tick (`bench/firmware.sh`).
        let mut left = F::from(steps).unwrap_or(F::one());
        while left > F::zero() {
            left = left - F::one();
            #[cfg(feature = "use-std")]
            let before = (w, w_pow);
            let c = self.coefficient(w);
            let rate = self.a - w_pow * c;
            // f′ is 0 at w = 0 (n > 1). The gain is within 1 ± n/32 on sub-steps of at most
            // `BoucWenState`'s length; on the longer ones of a step capped at MAX_SUB_STEPS it is
            // kept ≥ 0, so that w never falls, as in the equation.
            let curvature = if w == F::zero() { F::zero() } else { -(c * w_pow / w) * self.n };
            let mut gain = F::one() + half_h * curvature;
            if gain < F::zero() {
                gain = F::zero();
            }
            w = w + h * rate * gain;
            // A comparison, not `min`: on the joint that is a call into libm, every sub-step.
            if w > w_max {
                w = w_max;
            }
            w_pow = pow::<F, E>(w.abs(), self.n);
            // A sub-step that left w and |w|ⁿ as they were leaves them so again (the same h): z
            // has settled to its bound, to the last bit, and the sub-steps left are skipped, the
            // same result. On the host only, where a fit strides along a motion many sub-steps
            // a step (`fit::motion`); on the joint a tick is one sub-step and the test would only
            // cost flash and cycles.
            #[cfg(feature = "use-std")]
            if (w, w_pow) == before && w != F::zero() {
                break;
            }
        }
        (w, w_pow)
    }

    /// β + γ where w ≥ 0, γ − β where w < 0: dw/du = A − c·|w|ⁿ.
    #[inline(always)]
    fn coefficient(&self, w: F) -> F {
        if w >= F::zero() {
            self.beta + self.gamma
        } else {
            self.gamma - self.beta
        }
    }

    /// dw/du = A − |w|ⁿ·(β·sign(w) + γ), w = sign(dθ)·z, from w and its |w|ⁿ.
    #[inline(always)]
    fn rate(&self, w: F, w_pow: F) -> F {
        self.a - w_pow * self.coefficient(w)
    }
}

/// vⁿ for v ≥ 0 with `E`'s functions (exactly v where n = 1): on the joint these are the
/// tick's own fast ones, where libm's `powf` would be 1.6 KiB of flash and software double
/// precision.
#[inline(always)]
fn pow<F: Real, E: Elementary<F>>(v: F, n: F) -> F {
    if n == F::one() {
        v
    } else if v > F::zero() {
        E::pow(v, n)
    } else {
        F::zero()
    }
}

/// The Bouc–Wen kind's hysteresis: H = k_h·z.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoucWenTerm<F> {
    /// k_h, N·m/rad: the torque per rad of z.
    pub stiffness: F,
    pub shape: BoucWen<F>,
}

/// Bouc–Wen hysteresis and its state: z, the deflection it was last stepped to, and which way
/// it last moved.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoucWenState<F> {
    params: BoucWen<F>,
    /// z_max, the longest sub-step (z moves by z_max/[`SUB_STEPS_PER_SCALE`] at most) and the
    /// travel that saturates z, once.
    z_max: F,
    sub_step: F,
    saturating: F,
    theta: F,
    z: F,
    /// |z|ⁿ, made by the step that made z: the next step's first slope, and this one's K.
    z_pow: F,
    rising: bool,
}

impl<F: Real> BoucWenState<F> {
    /// At rest at θ = 0 (z = 0), once the parameters pass [`BoucWen::check`].
    pub fn new(params: BoucWen<F>) -> Result<Self, Error> {
        Self::new_with::<Libm>(params)
    }

    /// [`BoucWenState::new`] with the elementary functions of `E` for z_max.
    pub fn new_with<E: Elementary<F>>(params: BoucWen<F>) -> Result<Self, Error> {
        params.check()?;
        let z_max = params.z_max_with::<E>();
        if !z_max.is_finite() {
            return Err(Error::InvalidBoucWen);
        }
        let zero = F::zero();
        // dw/du is at most A, or A·2β/(β + γ) (at w = −z_max) where γ < β: a sub-step moves z
        // by at most z_max/16.
        let two = F::one() + F::one();
        let widening = two * params.beta / (params.beta + params.gamma);
        let peak_rate = if widening > F::one() { params.a * widening } else { params.a };
        let sub_step = z_max / peak_rate / F::from(SUB_STEPS_PER_SCALE).unwrap_or(F::one());
        let saturating = z_max / params.a * F::from(SATURATING_SCALES).unwrap_or(F::one());
        Ok(BoucWenState { params, z_max, sub_step, saturating, theta: zero, z: zero, z_pow: zero, rising: true })
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
        self.step_with::<Libm>(theta)
    }

    /// [`BoucWenState::step`] with the elementary functions of `E`.
    ///
    /// Never inlined: the joint's tick calls it, and an inlined copy cost it 1.6 KiB of its
    /// 48 KiB of flash (`bench/firmware.sh`).
    #[inline(never)]
    pub fn step_with<E: Elementary<F>>(&mut self, theta: F) -> Result<F, Error> {
        if !theta.is_finite() {
            return Err(Error::NonFiniteDeflection);
        }
        let delta = theta - self.theta;
        let z_max = self.z_max;
        if delta != F::zero() && self.params.n != F::one() {
            let p = &self.params;
            let direction = delta.signum();
            // Comparisons, not `max` and `min` (calls into libm on the joint); a tick's step is
            // one sub-step, without the division.
            let travel = delta.abs();
            let (w, w_pow) = if travel <= self.sub_step {
                p.taylor::<E>(direction * self.z, self.z_pow, travel, 1, z_max)
            } else if travel < self.saturating {
                // One more than the whole sub-steps in the travel, not `ceil` (a call into libm
                // on the joint).
                let steps = (travel / self.sub_step).to_u32().map_or(MAX_SUB_STEPS, |whole| whole.saturating_add(1));
                let steps = if steps > MAX_SUB_STEPS { MAX_SUB_STEPS } else { steps };
                let h = travel / F::from(steps).unwrap_or(F::one());
                p.taylor::<E>(direction * self.z, self.z_pow, h, steps, z_max)
            } else {
                // z_maxⁿ = A/(β + γ).
                (z_max, p.a / (p.beta + p.gamma))
            };
            (self.z, self.z_pow) = (direction * w, w_pow);
            self.theta = theta;
            self.rising = delta > F::zero();
        } else if delta != F::zero() {
            let p = &self.params;
            let direction = delta.signum();
            let (mut w, mut u) = (direction * self.z, delta.abs());
            if w < F::zero() {
                // dw/du = A − (β − γ)·w > 0 here: w rises towards 0, maybe past it.
                let c = p.beta - p.gamma;
                let to_zero = if c == F::zero() { -w / p.a } else { -E::ln_1p(w / (p.a / c - w)) / c };
                if to_zero < u {
                    (w, u) = (F::zero(), u - to_zero);
                } else {
                    (w, u) = (relax::<F, E>(w, u, p.a, c).min(F::zero()), F::zero());
                }
            }
            if u > F::zero() {
                w = relax::<F, E>(w, u, p.a, p.beta + p.gamma);
            }
            // Rounding (f32 on the joint) may carry w a hair past its bound (it only rises);
            // a comparison, not `min`, which is a call into libm on the joint.
            if w > z_max {
                w = z_max;
            }
            self.z = direction * w;
            self.z_pow = self.z.abs();
            self.theta = theta;
            self.rising = delta > F::zero();
        }
        Ok(self.z)
    }

    /// Back to rest: θ = 0, z = 0.
    pub fn reset(&mut self) {
        (self.theta, self.z, self.z_pow, self.rising) = (F::zero(), F::zero(), F::zero(), true);
    }

    /// Whether it last moved up (at rest: up).
    pub fn rising(&self) -> bool {
        self.rising
    }

    /// dz/dθ at the present state for motion in the direction of `rising`.
    pub fn slope(&self, rising: bool) -> F {
        self.params.rate(if rising { self.z } else { -self.z }, self.z_pow)
    }
}

/// The Bouc–Wen kind's hysteresis with its state, in x = θ − θ0.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoucWenMemory<F> {
    term: BoucWenTerm<F>,
    state: BoucWenState<F>,
}

impl<F: Real> BoucWenMemory<F> {
    /// At rest, once the term's shape passes [`BoucWen::check`] and k_h is finite.
    pub fn new(term: BoucWenTerm<F>) -> Result<Self, Error> {
        if !term.stiffness.is_finite() {
            return Err(Error::InvalidBoucWen);
        }
        Ok(BoucWenMemory { term, state: BoucWenState::new(term.shape)? })
    }

    /// z and which way it last moved.
    pub fn state(&self) -> &BoucWenState<F> {
        &self.state
    }

    /// Its parameters.
    pub fn term(&self) -> &BoucWenTerm<F> {
        &self.term
    }

    /// What it remembers, as the joint reports it: the direction it last moved (none at rest);
    /// z is its one state whatever the motion (depth 0).
    pub fn memory(&self) -> Memory {
        let direction = if self.state.theta == F::zero() && self.state.z == F::zero() {
            None
        } else if self.state.rising {
            Some(Direction::Rising)
        } else {
            Some(Direction::Falling)
        };
        Memory { direction, depth: 0 }
    }

    /// H = k_h·z and dH/dx = k_h·dz/dx (in the direction of the step; at a standstill the last
    /// one's) at x, as `finish` makes of them; the state is committed only if that succeeds.
    #[inline(always)]
    pub(crate) fn step_finishing<E: Elementary<F>>(
        &mut self,
        x: F,
        finish: impl Finish<crate::Evaluation<F>>,
    ) -> Result<Evaluation<F>, Error> {
        let mut next = self.state;
        let z = next.step_with::<E>(x)?;
        let k = self.term.stiffness;
        let evaluation = Evaluation { torque: k * z, stiffness: k * next.slope(next.rising) };
        let finished = finish.finish(evaluation)?;
        self.state = next;
        Ok(finished)
    }
}

impl<F: Real> Hysteretic<F> for BoucWenMemory<F> {
    fn reset(&mut self) {
        self.state.reset();
    }

    fn step(&mut self, x: F) -> Result<Evaluation<F>, Error> {
        self.step_finishing::<Libm>(x, Alone)
    }
}

/// w after moving u ≥ 0 along dw/du = a − c·w (closed form). Not inlined: its two calls each
/// carried a copy of e^y − 1 (`bench/firmware.sh`'s flash).
#[inline(never)]
fn relax<F: Real, E: Elementary<F>>(w: F, u: F, a: F, c: F) -> F {
    if c == F::zero() {
        w + a * u
    } else {
        w + (w - a / c) * E::exp_m1(-c * u)
    }
}

#[cfg(test)]
mod tests;
