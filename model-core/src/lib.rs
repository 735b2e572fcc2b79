//! The genetic hysteresis stiffness model of a strain wave gear (harmonic drive),
//! as in "Hysteresis Stiffness Modeling in Strain Wave Gearing: A Genetic Characteristic
//! Approach" (`shared/seed/`):
//!
//! ```text
//! T(θ) = c1·θ + c2·θ³ + c3·θ⁵ + z(θ)
//! z    = A·α·(ω·e^(−β·t) + β·sin ωt − ω·cos ωt) / (β² + ω²) · |cos ωt|
//! ωt   = asin(θ/A)          while θ rises  (forward loading, reverse unloading)
//! ωt   = π − asin(θ/A)      while θ falls  (forward unloading, reverse loading)
//! ```
//!
//! θ is the torsional deflection in rad, T the torque in N·m and A the amplitude of the
//! current loop in rad. θ/A is clamped to [−1, 1].
//!
//! # Identifiability
//! z depends on (α, β, ω) only through `r = β/ω` and `h = A·α / (ω·(1 + r²))` (N·m):
//! `z = h·(e^(−r·ωt) + r·sin ωt − cos ωt)·|cos ωt|`. Every (s·α, s·β, s·ω), s ≠ 0, gives the
//! same torque, so a fit can only determine (c1, c2, c3, h, r). [`Params::from_identifiable`]
//! picks the canonical point ω = 1 of that line.
//!
//! # Never panics
//! Every entry point returns a [`Result`]: non-finite inputs, A ≤ 0, ω = 0 and results that
//! would overflow are reported as [`Error`] values. Evaluation works in the log domain
//! (`A·k·e^(−rφ)` as `exp(ln|A·k| − rφ)`), so a large `r` with a small `α` stays finite;
//! elementary functions that ask for it form it directly where |r| ≤ [`MAX_DIRECT_DECAY_R`]
//! ([`Elementary::DIRECT_DECAY`]: the firmware's fast path, which then takes no ln or exp of h).
#![no_std]

use core::fmt;
use num_traits::{Float, FloatConst};

/// Name of the model in files and on the wire.
pub const MODEL_NAME: &str = "genetic-hysteresis";
/// Version of the model's equations; bumped when T(θ) changes meaning. Version 2: the deflection's
/// zero θ0 and the free-form spring of every kind ([`GearModel`]), the micro-slip kind's
/// elements each with its own slip deflection; version 1's sets load through [`legacy`].
pub const MODEL_VERSION: u16 = 2;

/// The float types the model runs on: `f32` on the microcontroller, `f64` on the host.
pub trait Real: Float + FloatConst + Default + fmt::Debug + private::Sealed {
    /// Cap on the singular factor 1/|cos ωt| in the stiffness, see [`Loop::stiffness`].
    const MIN_COS: Self;
    /// 3, used by dT/dθ of the polynomial.
    const THREE: Self;
    /// 5, used by dT/dθ of the polynomial.
    const FIVE: Self;
    /// α/(ω(1 + r²)) formed in f64 and rounded to `Self` once (ω ≠ 0, all three finite).
    fn decay_factor(alpha: Self, omega: Self, r: Self) -> Self;
}

impl Real for f32 {
    const MIN_COS: Self = 0.01;
    const THREE: Self = 3.0;
    const FIVE: Self = 5.0;
    /// In [`binary64`]'s integer arithmetic, rounded as f64's: the same bits, without the
    /// software f64 helpers on an FPU of single precision.
    fn decay_factor(alpha: f32, omega: f32, r: f32) -> f32 {
        use binary64::Double;
        // 1 + r² > 0, so the sign is α's times ω's; α = ±0 gives ±0.
        let negative = alpha.is_sign_negative() != omega.is_sign_negative();
        let magnitude = match (Double::from_f32(alpha), Double::from_f32(omega)) {
            (Some(alpha), Some(omega)) => {
                // r² is exact in f64 (48 bits).
                let one_plus_r2 = Double::from_f32(r).map_or(Double::ONE, |r| {
                    let (m, e) = (r.significand >> 29, r.exponent + 29);
                    Double::ONE.plus(Double::exact(m * m, 2 * e))
                });
                let (m, e) = (omega.significand >> 29, omega.exponent + 29);
                alpha.over(one_plus_r2.times(m as u32, e)).to_f32()
            }
            _ => 0.0,
        };
        if negative {
            -magnitude
        } else {
            magnitude
        }
    }
}

impl Real for f64 {
    const MIN_COS: Self = 0.01;
    const THREE: Self = 3.0;
    const FIVE: Self = 5.0;
    fn decay_factor(alpha: f64, omega: f64, r: f64) -> f64 {
        alpha / (omega * (1.0 + r * r))
    }
}

mod private {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// Which way the deflection θ is moving, i.e. which inverse branch of θ = A·sin ωt applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// θ increasing: forward loading or reverse unloading; ωt = asin(θ/A).
    Rising,
    /// θ decreasing: forward unloading or reverse loading; ωt = π − asin(θ/A).
    Falling,
}

/// A parameter of a [`GearModel`] of any kind, named in errors, files and the wire's error
/// replies: the genetic kind's six, then the micro-slip kind's own (its c1, c2, c3 are `C1`,
/// `C2`, `C3`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamName {
    C1,
    C2,
    C3,
    Alpha,
    Beta,
    Omega,
    /// k_i of micro-slip element i.
    SlipStiffness(u8),
    /// d_i, the slip deflection of micro-slip element i.
    Slip(u8),
    /// θ0, the deflection's zero.
    Zero,
    /// The x of the spring's knot i.
    Knot(u8),
    /// The stiffness at the spring's knot i.
    KnotStiffness(u8),
    /// The low end of the spring's identified range.
    RangeMin,
    /// The high end of the spring's identified range.
    RangeMax,
    /// k_h, the Bouc–Wen kind's torque per rad of z.
    HysteresisStiffness,
    /// The Bouc–Wen kind's A.
    BoucWenA,
    /// The Bouc–Wen kind's β.
    BoucWenBeta,
    /// The Bouc–Wen kind's γ.
    BoucWenGamma,
    /// The Bouc–Wen kind's n.
    BoucWenN,
    /// R, the reach of the Preisach kind's grid of thresholds.
    PreisachReach,
    /// w of the Preisach kind's cell i ([`preisach::cell`]).
    PreisachWeight(u8),
}

impl ParamName {
    /// The genetic kind's parameters, in the order of [`Params`]' fields (and of files and the
    /// wire).
    pub const GENETIC: [ParamName; 6] =
        [ParamName::C1, ParamName::C2, ParamName::C3, ParamName::Alpha, ParamName::Beta, ParamName::Omega];

    /// The parameter's name as written in files (an element's stiffness without its index; see
    /// the `Display` form for that).
    pub const fn as_str(self) -> &'static str {
        match self {
            ParamName::C1 => "c1",
            ParamName::C2 => "c2",
            ParamName::C3 => "c3",
            ParamName::Alpha => "alpha",
            ParamName::Beta => "beta",
            ParamName::Omega => "omega",
            ParamName::SlipStiffness(_) => "stiffness",
            ParamName::Slip(_) => "slip",
            ParamName::Zero => "zero",
            ParamName::Knot(_) => "knot",
            ParamName::KnotStiffness(_) => "knot_stiffness",
            ParamName::RangeMin => "range_min",
            ParamName::RangeMax => "range_max",
            ParamName::HysteresisStiffness => "stiffness",
            ParamName::BoucWenA => "a",
            ParamName::BoucWenBeta => "beta",
            ParamName::BoucWenGamma => "gamma",
            ParamName::BoucWenN => "n",
            ParamName::PreisachReach => "reach",
            ParamName::PreisachWeight(_) => "weight",
        }
    }

    /// What the parameter's range is, for an error.
    pub const fn range(self) -> &'static str {
        match self {
            ParamName::Omega => "it must not be zero (the model divides by it)",
            ParamName::Slip(_) => "slip deflections must be > 0 rad and increasing",
            ParamName::SlipStiffness(_) | ParamName::KnotStiffness(_) => "a stiffness must be >= 0 N·m/rad",
            ParamName::Knot(_) => "knots must be increasing and within the spring's range",
            ParamName::RangeMin => "the range's low end must be <= 0 rad",
            ParamName::RangeMax => "the range's high end must be >= 0 rad and above its low end",
            ParamName::Zero => "the deflection's zero must lie within the joint's deflection range",
            ParamName::C1
            | ParamName::C2
            | ParamName::C3
            | ParamName::Alpha
            | ParamName::Beta
            | ParamName::HysteresisStiffness => "the model overflows the float type with it",
            ParamName::BoucWenA => "A must be > 0",
            ParamName::BoucWenBeta => "beta must be > 0",
            ParamName::BoucWenGamma => "gamma must be > -beta",
            ParamName::BoucWenN => "n must be from 1 to 32",
            ParamName::PreisachReach => "the grid's reach must be > 0 rad",
            ParamName::PreisachWeight(_) => "a cell's weight must be >= 0 N·m",
        }
    }

    /// The parameter's unit, for reports.
    pub const fn unit(self) -> &'static str {
        match self {
            ParamName::C1
            | ParamName::SlipStiffness(_)
            | ParamName::KnotStiffness(_)
            | ParamName::HysteresisStiffness => "N·m/rad",
            ParamName::BoucWenA | ParamName::BoucWenN => "1",
            ParamName::BoucWenBeta | ParamName::BoucWenGamma => "rad⁻ⁿ",
            ParamName::PreisachWeight(_) => "N·m",
            ParamName::C2 => "N·m/rad³",
            ParamName::C3 => "N·m/rad⁵",
            ParamName::Alpha => "N·m/rad per unit of ω",
            ParamName::Beta | ParamName::Omega => "1/s",
            ParamName::Slip(_)
            | ParamName::Zero
            | ParamName::Knot(_)
            | ParamName::RangeMin
            | ParamName::RangeMax
            | ParamName::PreisachReach => "rad",
        }
    }
}

impl fmt::Display for ParamName {
    /// The name as in files; an element's stiffness with its index, `stiffness[3]`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamName::SlipStiffness(i)
            | ParamName::Slip(i)
            | ParamName::Knot(i)
            | ParamName::KnotStiffness(i)
            | ParamName::PreisachWeight(i) => {
                write!(f, "{}[{i}]", self.as_str())
            }
            name => f.write_str(name.as_str()),
        }
    }
}

/// Why a parameter set or an evaluation was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// A parameter is NaN or infinite.
    NonFiniteParameter(ParamName),
    /// ω = 0: the hysteresis term divides by ω.
    ZeroOmega,
    /// The loop amplitude A is not a finite number > 0.
    InvalidAmplitude,
    /// The deflection θ is NaN or infinite.
    NonFiniteDeflection,
    /// The result does not fit in the float type (parameters far outside any real gear).
    Overflow,
    /// A micro-slip element's stiffness k_i (its index i) is negative or not finite.
    InvalidSlipStiffness(usize),
    /// The micro-slip deflections need 0 < d_min < d_max, both finite.
    InvalidSlipRange,
    /// A spring's knots are not finite and increasing with stiffnesses ≥ 0, or its range does
    /// not hold x = 0.
    InvalidSpring,
    /// A parameter of a gear's model is not finite or out of its range ([`GearModel::check`]).
    InvalidParameter(ParamName, ParamFault),
    /// Bouc–Wen hysteresis needs A > 0, β > 0 and γ > −β, all finite ([`bouc_wen::BoucWen`]).
    InvalidBoucWen,
    /// A Preisach density needs a grid reach R > 0 and weights >= 0, all finite
    /// ([`preisach::Preisach`]).
    InvalidPreisach,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::NonFiniteParameter(name) => {
                write!(f, "parameter {} is not a finite number", name.as_str())
            }
            Error::ZeroOmega => f.write_str("parameter omega is zero; the model divides by it"),
            Error::InvalidAmplitude => f.write_str("loop amplitude A must be a finite deflection > 0 rad"),
            Error::NonFiniteDeflection => f.write_str("deflection is not a finite number"),
            Error::Overflow => f.write_str("model result overflows the float type"),
            Error::InvalidSlipStiffness(index) => {
                write!(f, "micro-slip element {index}: stiffness must be a finite number >= 0 N·m/rad")
            }
            Error::InvalidSlipRange => {
                f.write_str("micro-slip deflections must satisfy 0 < d_min < d_max, both finite rad")
            }
            Error::InvalidParameter(name, ParamFault::NotFinite) => {
                write!(f, "parameter {name} is not a finite number")
            }
            Error::InvalidParameter(name, ParamFault::OutOfRange) => {
                write!(f, "parameter {name} is out of range: {}", name.range())
            }
            Error::InvalidSpring => f.write_str(
                "spring knots must be finite and increasing with stiffness >= 0 N·m/rad, its range must hold x = 0",
            ),
            Error::InvalidBoucWen => f.write_str(
                "Bouc–Wen needs A > 0, beta > 0 1/rad^n, gamma > -beta 1/rad^n and 1 <= n <= 32, all finite",
            ),
            Error::InvalidPreisach => {
                f.write_str("a Preisach density needs a reach R > 0 rad and cell weights >= 0 N·m, all finite")
            }
        }
    }
}

impl core::error::Error for Error {}

/// The six parameters of the paper. Units: c1 N·m/rad, c2 N·m/rad³, c3 N·m/rad⁵,
/// α N·m/rad (per unit of ω), β and ω 1/s.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Params<F> {
    pub c1: F,
    pub c2: F,
    pub c3: F,
    pub alpha: F,
    pub beta: F,
    pub omega: F,
}

/// The identifiable part of (α, β, ω) at a loop amplitude A.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Identifiable<F> {
    /// Hysteresis torque scale h = A·α/(ω·(1 + r²)), N·m.
    pub h: F,
    /// Decay ratio r = β/ω, dimensionless.
    pub r: F,
}

impl<F: Real> Params<F> {
    /// Checks that the set can be evaluated: all finite, ω ≠ 0.
    pub fn validate(&self) -> Result<(), Error> {
        if let Some((name, _)) = self.fields().into_iter().find(|(_, value)| !value.is_finite()) {
            return Err(Error::NonFiniteParameter(name));
        }
        if self.omega == F::zero() {
            return Err(Error::ZeroOmega);
        }
        Ok(())
    }

    /// The identifiable pair (h, r) at loop amplitude `amplitude`.
    pub fn identifiable(&self, amplitude: F) -> Result<Identifiable<F>, Error> {
        let model = Model::new(*self)?;
        check_amplitude(amplitude)?;
        let h = model.sign_k * (model.ln_abs_k + amplitude.ln()).exp();
        if !h.is_finite() {
            return Err(Error::Overflow);
        }
        Ok(Identifiable { h, r: model.r })
    }

    /// The canonical parameters for an identifiable pair: ω = 1, β = r, α = h·(1 + r²)/A.
    pub fn from_identifiable(c1: F, c2: F, c3: F, hysteresis: Identifiable<F>, amplitude: F) -> Result<Self, Error> {
        check_amplitude(amplitude)?;
        let Identifiable { h, r } = hysteresis;
        let params = Params { c1, c2, c3, alpha: h * (F::one() + r * r) / amplitude, beta: r, omega: F::one() };
        params.validate()?;
        Ok(params)
    }
}

impl<F: Copy> Params<F> {
    /// Every parameter with its name, in [`ParamName::GENETIC`] order: the one list of the
    /// parameters that validation goes through.
    pub fn fields(&self) -> [(ParamName, F); 6] {
        [
            (ParamName::C1, self.c1),
            (ParamName::C2, self.c2),
            (ParamName::C3, self.c3),
            (ParamName::Alpha, self.alpha),
            (ParamName::Beta, self.beta),
            (ParamName::Omega, self.omega),
        ]
    }

    /// Each parameter converted by `convert`, which may refuse one (the first refusal wins).
    pub fn try_map<G, E>(&self, mut convert: impl FnMut(ParamName, F) -> Result<G, E>) -> Result<Params<G>, E> {
        Ok(Params {
            c1: convert(ParamName::C1, self.c1)?,
            c2: convert(ParamName::C2, self.c2)?,
            c3: convert(ParamName::C3, self.c3)?,
            alpha: convert(ParamName::Alpha, self.alpha)?,
            beta: convert(ParamName::Beta, self.beta)?,
            omega: convert(ParamName::Omega, self.omega)?,
        })
    }
}

impl Params<f64> {
    /// The set rounded to f32, as the microcontroller holds it.
    pub fn to_f32(&self) -> Params<f32> {
        let rounded: Result<Params<f32>, core::convert::Infallible> = self.try_map(|_, value| Ok(value as f32));
        match rounded {
            Ok(params) => params,
            Err(never) => match never {},
        }
    }
}

/// Largest |r| = |β/ω| for which elementary functions that ask for it
/// ([`Elementary::DIRECT_DECAY`]) form h·e^(−rφ) as h times e^(−rφ): with φ ∈ [−π/2, 3π/2],
/// e^(−rφ) ≤ e^(16·3π/2) ≈ 6·10³², well inside f32. Real gears have |r| ≈ 2 (paper: 1.87,
/// seed fit: 2.30).
pub const MAX_DIRECT_DECAY_R: f32 = 16.0;

/// A validated parameter set, with the amplitude-independent constants precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Model<F> {
    polynomial: Polynomial<F>,
    r: F,
    /// ln|k| with k = α/(ω(1 + r²)), so that h = A·k.
    ln_abs_k: F,
    /// sign of k, or 0 when α = 0 (no hysteresis).
    sign_k: F,
    /// k itself, rounded once (formed in f64), where the direct form h·e^(−rφ) applies:
    /// |r| ≤ [`MAX_DIRECT_DECAY_R`] and k finite; `None` elsewhere.
    direct_k: Option<F>,
    /// Whether the polynomial spring is there (not c1 = c2 = c3 = 0).
    has_spring: bool,
}

impl<F: Real> Model<F> {
    /// Validates `params` and precomputes what every evaluation needs.
    pub fn new(params: Params<F>) -> Result<Self, Error> {
        params.validate()?;
        let r = params.beta / params.omega;
        if !r.is_finite() {
            return Err(Error::Overflow);
        }
        // ln(1 + r²) without forming r², which overflows first.
        let abs_r = r.abs();
        let ln_one_plus_r2 = if abs_r > F::one() {
            let two = F::one() + F::one();
            two * abs_r.ln() + (abs_r * abs_r).recip().ln_1p()
        } else {
            (abs_r * abs_r).ln_1p()
        };
        let ln_abs_k = params.alpha.abs().ln() - params.omega.abs().ln() - ln_one_plus_r2;
        let sign = |v: F| if v > F::zero() { F::one() } else { -F::one() };
        let sign_k = if params.alpha == F::zero() { F::zero() } else { sign(params.alpha) * sign(params.omega) };
        let polynomial = Polynomial::new(params.c1, params.c2, params.c3)?;
        let direct_k = Self::direct_k(&params, r);
        let has_spring = [params.c1, params.c2, params.c3].iter().any(|c| *c != F::zero());
        Ok(Model { polynomial, r, ln_abs_k, sign_k, direct_k, has_spring })
    }

    /// k = α/(ω(1 + r²)) in f64, rounded to F once, where the direct form applies.
    fn direct_k(params: &Params<F>, r: F) -> Option<F> {
        let max_r = F::from(MAX_DIRECT_DECAY_R)?;
        // r is finite (Model::new checked).
        if r.abs() > max_r {
            return None;
        }
        let k = F::decay_factor(params.alpha, params.omega, r);
        k.is_finite().then_some(k)
    }

    /// The polynomial spring c1·θ + c2·θ³ + c3·θ⁵.
    pub fn polynomial(&self) -> &Polynomial<F> {
        &self.polynomial
    }

    /// Whether the polynomial spring is there (not c1 = c2 = c3 = 0).
    #[inline(always)]
    pub fn has_spring(&self) -> bool {
        self.has_spring
    }

    /// r = β/ω.
    pub fn r(&self) -> F {
        self.r
    }

    /// k = α/(ω(1 + r²)), so that h = A·k (infinite where it overflows the float type).
    pub fn k(&self) -> F {
        self.sign_k * self.ln_abs_k.exp()
    }

    /// Whether elementary functions that ask for it ([`Elementary::DIRECT_DECAY`]) form
    /// h·e^(−rφ) directly: |r| ≤ [`MAX_DIRECT_DECAY_R`] and k fits the float type.
    pub fn has_direct_decay(&self) -> bool {
        self.direct_k.is_some()
    }

    /// The model on a loop of amplitude `amplitude` (rad), ready for per-sample evaluation.
    pub fn at_amplitude(&self, amplitude: F) -> Result<Loop<F>, Error> {
        self.at_amplitude_with::<Libm>(amplitude)
    }

    /// [`Model::at_amplitude`] with the elementary functions of `E` (ln and exp of h).
    #[inline(always)]
    pub fn at_amplitude_with<E: Elementary<F>>(&self, amplitude: F) -> Result<Loop<F>, Error> {
        Ok(Loop { model: *self, amplitude, scale: self.scale_with::<E>(amplitude)? })
    }

    /// What the amplitude A fixes of a loop ([`Scale`]), with the elementary functions of `E`:
    /// h = A·k, in the form `E` asks for ([`Elementary::DIRECT_DECAY`]) where the model allows
    /// it, else through ln|h| = ln|k| + ln A (so that a huge k with a tiny A stays finite).
    #[inline(always)]
    pub fn scale_with<E: Elementary<F>>(&self, amplitude: F) -> Result<Scale<F>, Error> {
        check_amplitude(amplitude)?;
        let scale = self.scale_of::<E>(amplitude, amplitude.recip());
        if !scale.h.is_finite() {
            return Err(Error::Overflow);
        }
        Ok(scale)
    }

    /// [`Model::scale_with`] of an amplitude known to be finite and > 0, given with its
    /// reciprocal, and h not checked: where it is not finite, neither is any z made with it.
    #[inline(always)]
    pub(crate) fn scale_of<E: Elementary<F>>(&self, amplitude: F, inv_amplitude: F) -> Scale<F> {
        let (h, decay) = match self.direct_k {
            Some(k) if E::DIRECT_DECAY => (k * amplitude, Decay::Direct),
            _ => {
                let ln_abs_h = self.ln_abs_k + E::ln(amplitude);
                (self.sign_k * E::exp(ln_abs_h), Decay::Log { ln_abs_h })
            }
        };
        Scale { inv_amplitude, h, decay }
    }

    /// The hysteresis term z and dz/dθ alone at `theta` on the loop of `scale`, moving in
    /// `direction`, with the elementary functions of `E`: [`Phase`] and h·e^(−rφ) in the form
    /// `scale` was made for. Not checked for finiteness (callers check their sums).
    #[inline(always)]
    pub fn hysteresis_with<E: Elementary<F>>(&self, scale: &Scale<F>, theta: F, direction: Direction) -> Evaluation<F> {
        let phase = Phase::new::<E>(theta * scale.inv_amplitude, direction);
        let h_decay = match scale.decay {
            // h = 0 when α = 0, so no special case.
            Decay::Direct => scale.h * E::exp_direct(-self.r * phase.angle),
            // h·e^(−rφ) in the log domain, so that huge r with tiny α stays finite.
            Decay::Log { ln_abs_h } => {
                if self.sign_k == F::zero() {
                    F::zero()
                } else {
                    self.sign_k * E::exp(ln_abs_h - self.r * phase.angle)
                }
            }
        };
        phase.hysteresis(self.r, scale.h, h_decay, scale.inv_amplitude)
    }

    /// Torque T(θ) in N·m at deflection `theta` (rad) moving in `direction` on a loop of
    /// amplitude `amplitude` (rad).
    pub fn torque(&self, theta: F, direction: Direction, amplitude: F) -> Result<F, Error> {
        self.at_amplitude(amplitude)?.torque(theta, direction)
    }

    /// Stiffness dT/dθ in N·m/rad; see [`Loop::stiffness`] for the turning points.
    pub fn stiffness(&self, theta: F, direction: Direction, amplitude: F) -> Result<F, Error> {
        self.at_amplitude(amplitude)?.stiffness(theta, direction)
    }
}

fn check_amplitude<F: Real>(amplitude: F) -> Result<(), Error> {
    if amplitude.is_finite() && amplitude > F::zero() {
        Ok(())
    } else {
        Err(Error::InvalidAmplitude)
    }
}

/// Torque and stiffness at one deflection.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Evaluation<F> {
    /// T(θ), N·m.
    pub torque: F,
    /// dT/dθ, N·m/rad.
    pub stiffness: F,
}

/// What the amplitude A fixes of a loop: 1/A and h = A·k, with the form h·e^(−rφ) takes
/// ([`Model::scale_with`]). A stateful evaluator keeps its current branch's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale<F> {
    inv_amplitude: F,
    h: F,
    decay: Decay<F>,
}

/// How h·e^(−rφ) is formed.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Decay<F> {
    /// h times e^(−rφ) (|r| ≤ [`MAX_DIRECT_DECAY_R`]).
    Direct,
    /// ±e^(ln|h| − rφ).
    Log { ln_abs_h: F },
}

impl<F: Real> Scale<F> {
    /// h = A·k, N·m.
    pub fn h(&self) -> F {
        self.h
    }
}

/// The model on one loop amplitude A: what a controller evaluates every tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Loop<F> {
    model: Model<F>,
    amplitude: F,
    scale: Scale<F>,
}

impl<F: Real> Loop<F> {
    /// The loop amplitude A, rad.
    pub fn amplitude(&self) -> F {
        self.amplitude
    }

    /// h = A·α/(ω(1 + r²)), N·m.
    pub fn h(&self) -> F {
        self.scale.h
    }

    /// Torque T(θ), N·m.
    pub fn torque(&self, theta: F, direction: Direction) -> Result<F, Error> {
        self.evaluate(theta, direction).map(|e| e.torque)
    }

    /// Stiffness dT/dθ, N·m/rad, computed analytically.
    ///
    /// At the turning points |θ| = A the slope of asin, and with it dz/dθ, is infinite. The
    /// singular factor 1/|cos ωt| is therefore capped at 1/[`Real::MIN_COS`] = 100: the
    /// value is exact for |θ| ≤ A·√(1 − 0.01²) ≈ 0.99995·A, and at and beyond ±A it is the
    /// finite, steep slope of that edge (the stiff start of the return branch), never ±∞.
    pub fn stiffness(&self, theta: F, direction: Direction) -> Result<F, Error> {
        self.evaluate(theta, direction).map(|e| e.stiffness)
    }

    /// Torque and stiffness together, sharing the transcendental functions.
    #[inline]
    pub fn evaluate(&self, theta: F, direction: Direction) -> Result<Evaluation<F>, Error> {
        self.evaluate_with::<Libm>(theta, direction)
    }

    /// [`Loop::evaluate`] with the elementary functions of `E`.
    #[inline(always)]
    pub fn evaluate_with<E: Elementary<F>>(&self, theta: F, direction: Direction) -> Result<Evaluation<F>, Error> {
        let (spring, hysteresis) = self.evaluate_parts_with::<E>(theta, direction)?;
        let evaluation = spring.plus(hysteresis);
        if evaluation.torque.is_finite() && evaluation.stiffness.is_finite() {
            Ok(evaluation)
        } else {
            Err(Error::Overflow)
        }
    }

    /// The polynomial spring's and the hysteresis term z's torque and stiffness, apart; their
    /// sum is [`Loop::evaluate`]. Each part is finite where that is.
    #[inline]
    pub fn evaluate_parts(&self, theta: F, direction: Direction) -> Result<(Evaluation<F>, Evaluation<F>), Error> {
        self.evaluate_parts_with::<Libm>(theta, direction)
    }

    /// [`Loop::evaluate_parts`] with the elementary functions of `E`: the firmware's fast path
    /// runs this same formula with its polynomial approximations.
    #[inline(always)]
    pub fn evaluate_parts_with<E: Elementary<F>>(
        &self,
        theta: F,
        direction: Direction,
    ) -> Result<(Evaluation<F>, Evaluation<F>), Error> {
        if !theta.is_finite() {
            return Err(Error::NonFiniteDeflection);
        }
        let hysteresis = self.model.hysteresis_with::<E>(&self.scale, theta, direction);
        let spring = self.model.polynomial.evaluate(theta);
        let finite = |e: &Evaluation<F>| e.torque.is_finite() && e.stiffness.is_finite();
        if finite(&spring) && finite(&hysteresis) {
            Ok((spring, hysteresis))
        } else {
            Err(Error::Overflow)
        }
    }
}

/// The elementary functions the evaluation needs besides arithmetic. model-core uses libm
/// ([`Libm`]); the firmware's per-tick path supplies polynomial approximations, so that both
/// run the same formula ([`Phase`], [`Polynomial`]) and differ only in these.
pub trait Elementary<F> {
    /// √v for v ≥ 0.
    fn sqrt(v: F) -> F;
    /// asin x for x ∈ [−1, 1].
    fn asin(x: F) -> F;
    /// e^y; e^y of a y that overflows may be large and finite instead of ∞ (the callers
    /// check their results' range).
    fn exp(y: F) -> F;
    /// ln v for a finite v > 0.
    fn ln(v: F) -> F;
    /// e^y − 1, to a relative error as small near y = 0 as elsewhere (Bouc–Wen's closed-form
    /// step: a tick's increment of z is this times a constant, and e^y − 1 would lose it).
    fn exp_m1(y: F) -> F;
    /// ln(1 + v) for a finite v > −1.
    fn ln_1p(v: F) -> F;
    /// vⁿ for a finite v > 0: e^(n·ln v) unless the implementation has a cheaper way.
    #[inline(always)]
    fn pow(v: F, n: F) -> F
    where
        F: Real,
    {
        Self::exp(n * Self::ln(v))
    }
    /// Whether h·e^(−rφ) is formed as h times [`Elementary::exp`]`(−rφ)` where the model
    /// allows it (|r| ≤ [`MAX_DIRECT_DECAY_R`]): no ln and exp of h when a loop's amplitude
    /// changes. Otherwise (the default, and [`Libm`]'s choice) as ±exp(ln|h| − rφ), which stays
    /// finite for any r.
    const DIRECT_DECAY: bool = false;
    /// e^y for the direct form's exponents, |y| ≤ [`MAX_DIRECT_DECAY_R`]·3π/2 (< 76): what
    /// may skip the range handling that [`Elementary::exp`] needs for any y.
    #[inline(always)]
    fn exp_direct(y: F) -> F {
        Self::exp(y)
    }
}

/// The elementary functions of libm (through `num_traits::Float`).
#[derive(Clone, Copy, Debug)]
pub struct Libm;

impl<F: Real> Elementary<F> for Libm {
    #[inline(always)]
    fn sqrt(v: F) -> F {
        v.sqrt()
    }
    #[inline(always)]
    fn asin(x: F) -> F {
        x.asin()
    }
    #[inline(always)]
    fn exp(y: F) -> F {
        y.exp()
    }
    #[inline(always)]
    fn ln(v: F) -> F {
        v.ln()
    }
    #[inline(always)]
    fn exp_m1(y: F) -> F {
        y.exp_m1()
    }
    #[inline(always)]
    fn ln_1p(v: F) -> F {
        v.ln_1p()
    }
}

/// The polynomial spring c1·θ + c2·θ³ + c3·θ⁵, with 3·c2 and 5·c3 kept for its slope.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Polynomial<F> {
    c1: F,
    c2: F,
    c3: F,
    c2x3: F,
    c3x5: F,
}

impl<F: Real> Polynomial<F> {
    /// Refuses coefficients whose slope factors 3·c2 or 5·c3 overflow the float type.
    pub fn new(c1: F, c2: F, c3: F) -> Result<Self, Error> {
        let (c2x3, c3x5) = (F::THREE * c2, F::FIVE * c3);
        if !(c2x3.is_finite() && c3x5.is_finite()) {
            return Err(Error::Overflow);
        }
        Ok(Polynomial { c1, c2, c3, c2x3, c3x5 })
    }

    /// T and dT/dθ of the polynomial at `theta`, by Horner's rule.
    #[inline(always)]
    pub fn evaluate(&self, theta: F) -> Evaluation<F> {
        let theta2 = theta * theta;
        Evaluation {
            torque: theta * (self.c1 + theta2 * (self.c2 + theta2 * self.c3)),
            stiffness: self.c1 + theta2 * (self.c2x3 + self.c3x5 * theta2),
        }
    }
}

/// Where a deflection sits on its loop: the phase φ = ωt of θ = A·sin φ on the branch that
/// `direction` selects, φ = asin(θ/A) rising and π − asin(θ/A) falling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phase<F> {
    /// φ, rad.
    pub angle: F,
    /// sin φ = θ/A, clamped to [−1, 1].
    pub sin: F,
    /// cos φ: +|cos φ| rising, −|cos φ| falling.
    pub cos: F,
    /// |cos φ| = √((1 − sin φ)(1 + sin φ)).
    pub abs_cos: F,
    /// dφ/dθ·A·|cos φ|: +1 rising, −1 falling.
    turn: F,
}

impl<F: Real> Phase<F> {
    /// The phase of θ/A = `ratio` (clamped to [−1, 1]; finite or ±∞, never NaN) moving in
    /// `direction`. Comparisons rather than `max`/`min`: those are calls to `fmaxf` on the
    /// Cortex-M4F, and this runs every control tick.
    #[inline(always)]
    pub fn new<M: Elementary<F>>(ratio: F, direction: Direction) -> Self {
        let one = F::one();
        let sin = if ratio < -one {
            -one
        } else if ratio > one {
            one
        } else {
            ratio
        };
        // (1 − x)(1 + x) keeps precision near |x| = 1.
        let abs_cos = M::sqrt((one - sin) * (one + sin));
        let asin = M::asin(sin);
        let (angle, cos, turn) = match direction {
            Direction::Rising => (asin, abs_cos, one),
            Direction::Falling => (F::PI() - asin, -abs_cos, -one),
        };
        Phase { angle, sin, cos, abs_cos, turn }
    }

    /// The hysteresis shape at this phase, see [`shape`].
    #[inline(always)]
    pub fn shape(&self, r: F, decay: F, scale: F) -> F {
        shape(r, self.sin, self.cos, decay, scale)
    }

    /// z = h·p(φ)·|cos φ| and dz/dθ on a loop of 1/A = `inv_amplitude`, with `h_decay` =
    /// h·e^(−rφ). At the turning points dφ/dθ is infinite; the singular factor 1/|cos φ| is
    /// capped at 1/[`Real::MIN_COS`] (see [`Loop::stiffness`]).
    #[inline(always)]
    pub fn hysteresis(&self, r: F, h: F, h_decay: F, inv_amplitude: F) -> Evaluation<F> {
        let hp = self.shape(r, h_decay, h);
        // h·p'(φ).
        let hdp = -r * h_decay + h * (r * self.cos + self.sin);
        let capped_cos = if self.abs_cos > F::MIN_COS { self.abs_cos } else { F::MIN_COS };
        Evaluation {
            torque: hp * self.abs_cos,
            // dz/dθ = (±h·p' − h·p·sin φ/|cos φ|)/A.
            stiffness: (self.turn * hdp - hp * self.sin / capped_cos) * inv_amplitude,
        }
    }
}

/// The hysteresis shape p(φ) = e^(−rφ) + r·sin φ − cos φ, scaled: `decay` + `scale`·(r·sin φ
/// − cos φ), where the caller supplies `decay` = `scale`·e^(−rφ) in whatever form keeps it
/// finite (log domain, or a common factor taken out). A free function so that the fit, which
/// keeps sin φ and cos φ of many samples in arrays of their own, evaluates the same formula.
#[inline(always)]
pub fn shape<F: Real>(r: F, sin: F, cos: F, decay: F, scale: F) -> F {
    decay + scale * (r * sin - cos)
}

impl<F: Real> Evaluation<F> {
    /// The sum of two parts of the torque (the polynomial and the hysteresis).
    #[inline(always)]
    pub fn plus(self, other: Self) -> Self {
        Evaluation { torque: self.torque + other.torque, stiffness: self.stiffness + other.stiffness }
    }
}

pub mod binary64;
pub mod bouc_wen;
#[cfg(any(test, feature = "checks"))]
pub mod checks;
pub mod gear;
pub mod memory;
pub mod preisach;
pub mod range;
#[cfg(feature = "serde")]
mod serde_array;
pub mod spring;
pub use gear::{
    Evaluator, GearModel, Genetic, Hysteresis, HysteresisState, Kind, Memory, ParamFault, SLIP_ELEMENTS, TURNING_POINTS,
};
pub mod legacy;
pub use memory::{GeneticMemory, Hysteretic, MicroSlip, SlipElement, SlipElements, TurningPoint};
pub use spring::{Knot, Spring};
pub mod tolerance;

#[cfg(test)]
mod tests;
