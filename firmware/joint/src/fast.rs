//! The per-tick evaluation of T(θ) and dT/dθ with polynomial elementary functions.
//!
//! model-core's f32 path calls libm's `asinf`/`expf` (on the joint, libm's results bit for bit
//! without its f64 steps: [`crate::direct`]), hundreds of instructions per tick
//! (`bench/firmware.sh` measures both paths). This path runs
//! model-core's own formula with [`FastMath`]: a polynomial arcsine (Abramowitz–Stegun
//! 4.4.46), a range-reduced polynomial exponential and the FPU's `vsqrt`, and h·e^(−rφ) formed
//! directly ([`Elementary::DIRECT_DECAY`]), which needs |r| ≤ [`MAX_ABS_R`]. The constants that
//! depend only on the parameters (k = α/(ω(1 + r²)), r = β/ω) are prepared once when a set is
//! installed. Error against the f64 model: see the tests (`fast_path_error_bound`).
use core::f32::consts::{FRAC_PI_2, LN_2, LOG2_E, SQRT_2};
use model_core::{Direction, Elementary, Evaluation, Model, Params};

/// Largest |r| = |β/ω| of the fast path: model-core's bound for the direct form of
/// h·e^(−rφ), where e^(−rφ), φ ∈ [−π/2, 3π/2], stays well inside f32; real gears have |r| ≈ 2
/// (paper: 1.87, seed fit: 2.30).
pub const MAX_ABS_R: f32 = model_core::MAX_DIRECT_DECAY_R;

/// Why a parameter set has no fast path (the direct path still works).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FastPathError {
    /// The parameters are not finite or ω = 0.
    Invalid,
    /// |β/ω| > [`MAX_ABS_R`].
    DecayOutOfRange,
    /// k = α/(ω(1 + r²)), or the spring's slope factors, do not fit in f32.
    Overflow,
}

impl core::fmt::Display for FastPathError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FastPathError::Invalid => f.write_str("parameters not finite or omega is zero"),
            FastPathError::DecayOutOfRange => write!(f, "|beta/omega| exceeds {MAX_ABS_R}"),
            FastPathError::Overflow => f.write_str("alpha/(omega(1 + r^2)) overflows f32"),
        }
    }
}

/// A parameter set that the fast path evaluates: model-core's [`Model`] with h·e^(−rφ) in the
/// direct form ([`Model::has_direct_decay`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastModel {
    model: Model<f32>,
}

impl FastModel {
    pub fn new(params: &Params<f32>) -> Result<Self, FastPathError> {
        params.validate().map_err(|_| FastPathError::Invalid)?;
        let model = Model::new(*params).map_err(|_| FastPathError::Overflow)?;
        if model.r().abs() > MAX_ABS_R {
            return Err(FastPathError::DecayOutOfRange);
        }
        if !model.has_direct_decay() {
            return Err(FastPathError::Overflow);
        }
        Ok(FastModel { model })
    }

    /// T(θ) and dT/dθ on a loop of amplitude `amplitude`: [`model_core::Loop::evaluate`] with
    /// [`FastMath`]. Returns `None` when the inputs are not finite, A ≤ 0 or the result
    /// overflows.
    #[inline]
    pub fn evaluate(&self, theta: f32, direction: Direction, amplitude: f32) -> Option<Evaluation<f32>> {
        self.model
            .at_amplitude_with::<FastMath>(amplitude)
            .and_then(|lp| lp.evaluate_with::<FastMath>(theta, direction))
            .ok()
    }
}

/// The fast path's elementary functions: the FPU's square root, polynomial arcsine,
/// exponential and logarithm, and h·e^(−rφ) formed directly. model-core's formulas run with
/// them: [`FastModel::evaluate`] (one symmetric loop), and on the joint the stateful genetic
/// model (`GeneticMemory::step_with::<FastMath>`) and the Bouc–Wen kind's step (e^y − 1 in its
/// closed form for n = 1, |z|ⁿ = e^(n·ln|z|) otherwise).
#[derive(Clone, Copy, Debug)]
pub struct FastMath;

impl Elementary<f32> for FastMath {
    #[inline(always)]
    fn sqrt(v: f32) -> f32 {
        sqrt(v)
    }
    #[inline(always)]
    fn asin(x: f32) -> f32 {
        asin(x)
    }
    /// [`exp`] with y held to ±87 (e^y of a y beyond stays finite, as the trait allows).
    #[inline(always)]
    fn exp(y: f32) -> f32 {
        exp(within_exp_range(y))
    }
    #[inline(always)]
    fn ln(v: f32) -> f32 {
        ln(v)
    }
    #[inline(always)]
    fn exp_m1(y: f32) -> f32 {
        exp_m1(y)
    }
    #[inline(always)]
    fn pow(v: f32, n: f32) -> f32 {
        pow(v, n)
    }
    /// libm's (the joint links it anyway): once per zero crossing of Bouc–Wen's z, not on the
    /// usual tick.
    fn ln_1p(v: f32) -> f32 {
        libm::log1pf(v)
    }
    // h·e^(−rφ) as h times exp(−rφ): no ln and exp of h when a branch begins.
    const DIRECT_DECAY: bool = true;
    #[inline(always)]
    fn exp_direct(y: f32) -> f32 {
        exp(y)
    }
}

/// The |y| within which [`exp`] puts 2^n into the exponent bits.
const EXP_RANGE: f32 = 87.0;

/// y held to ±[`EXP_RANGE`] (NaN stays NaN) by comparisons: `f32::max` and `min` are calls
/// into libm on the Cortex-M4F, and `f32::clamp` asserts that its bounds are ordered.
#[allow(clippy::manual_clamp)]
#[inline(always)]
fn within_exp_range(y: f32) -> f32 {
    if y < -EXP_RANGE {
        -EXP_RANGE
    } else if y > EXP_RANGE {
        EXP_RANGE
    } else {
        y
    }
}

/// √v with the FPU's `vsqrt.f32` on the Cortex-M4F; libm (also correctly rounded) elsewhere.
///
/// Inline, not a call: a call lets the tick keep values only in the 16 callee-saved FPU
/// registers across it, and the ticks that change branch then spilled a dozen of them to the
/// stack and back (`bench/firmware.sh`).
#[inline(always)]
pub fn sqrt(v: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        // Inline `asm!` cannot take an f32 operand in a single-precision register on this
        // target (its `sreg` class demands the double-precision `vfp2`), but it may clobber
        // one: the value goes in and out through a core register, s0 as the scratch.
        let mut bits = v.to_bits();
        // SAFETY: the three instructions read and write only `bits` (a core register) and s0,
        // which is declared clobbered; no memory, no stack.
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "vmov s0, {bits}",
                "vsqrt.f32 s0, s0",
                "vmov {bits}, s0",
                bits = inout(reg) bits,
                out("s0") _,
                options(pure, nomem, nostack),
            );
        }
        f32::from_bits(bits)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(v)
    }
}

/// asin x for x ∈ [−1, 1]: π/2 − √(1 − |x|)·P7(|x|), |error| ≤ 2·10⁻⁸ before f32 rounding
/// (Abramowitz & Stegun 4.4.46).
#[inline(always)]
pub fn asin(x: f32) -> f32 {
    let a = x.abs();
    // A&S's leading coefficient 1.5707963050 rounds to the same f32 as π/2.
    let p = FRAC_PI_2
        + a * (-0.214_598_8
            + a * (0.088_978_99
                + a * (-0.050_174_3
                    + a * (0.030_891_88 + a * (-0.017_088_126 + a * (0.006_670_09 - a * 0.001_262_491))))));
    let angle = FRAC_PI_2 - sqrt(1.0 - a) * p;
    if x < 0.0 {
        -angle
    } else {
        angle
    }
}

/// e^y for |y| ≤ 87 (beyond, 2^n does not fit the exponent bits; the direct form's exponents
/// stay within ±76): y = n·ln 2 + f with |f| ≤ ln 2 / 2, e^f by its Taylor polynomial of
/// degree 6 (relative error ≤ 1.3·10⁻⁷), 2^n put into the exponent bits.
#[inline(always)]
pub fn exp(y: f32) -> f32 {
    // n = y·log2(e) rounded to the nearest integer by adding and taking away 1.5·2²³, which
    // leaves no fraction bits (|y·log2(e)| < 2²²): fewer instructions than adding ±0.5 by the
    // sign bit and truncating.
    const ROUND: f32 = 12_582_912.0;
    let whole = (y * LOG2_E + ROUND) - ROUND;
    let n = whole as i32;
    // ln 2 split in a part exact in f32 times n and a correction (Cody–Waite).
    const LN_2_HIGH: f32 = 0.693_359_4;
    const LN_2_LOW: f32 = LN_2 - LN_2_HIGH;
    let f = (y - whole * LN_2_HIGH) - whole * LN_2_LOW;
    let poly = 1.0 + f * (1.0 + f * (0.5 + f * (1.0 / 6.0 + f * (1.0 / 24.0 + f * (1.0 / 120.0 + f * (1.0 / 720.0))))));
    let scale = f32::from_bits(((n + 127) as u32) << 23);
    poly * scale
}

/// v = m·2^e with m ∈ [√½, √2) for a finite v > 0, from its bits (a subnormal v read as a
/// normal one of the smallest exponent): [`ln`]'s and [`pow`]'s first step.
#[inline(always)]
fn split(v: f32) -> (f32, i32) {
    let bits = v.to_bits();
    let mut exponent = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    if m > SQRT_2 {
        m *= 0.5;
        exponent += 1;
    }
    (m, exponent)
}

/// ln v for a finite v > 0: v = m·2^e with m ∈ [√½, √2), ln m = 2·atanh s with
/// s = (m − 1)/(m + 1), |s| ≤ 0.172, by its series to s⁹ (error ≤ 10⁻⁹ before f32 rounding).
/// A subnormal v is read as a normal one of the smallest exponent: its logarithm is then too
/// large by at most 87, and nothing on the joint takes a logarithm of one except |z|ⁿ next to
/// z = 0, where e^(n·ln|z|) < 10⁻³⁷ either way.
#[inline(always)]
pub fn ln(v: f32) -> f32 {
    let (m, exponent) = split(v);
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = 2.0 * s * (1.0 + s2 * (1.0 / 3.0 + s2 * (1.0 / 5.0 + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0)))));
    exponent as f32 * LN_2 + series
}

/// vⁿ for a finite v > 0, as 2^(n·log2 v): log2 of v's mantissa m ∈ [√½, √2) by a polynomial
/// of degree 6 in m − 1 (absolute error ≤ 2.2·10⁻⁶, near-minimax, fitted by iteratively
/// reweighted least squares), 2^f for |f| ≤ ½ by one of degree 5 (relative error ≤ 8·10⁻⁸):
/// a relative error of vⁿ within 1.6·10⁻⁶·n, plus 10⁻⁷·|n·log2 v| as log2 v and n·log2 v
/// round to f32 (|z|ⁿ of a gear: 10⁻⁵ at most). Bouc–Wen's |z|ⁿ takes it once a sub-step, and
/// e^(n·ln v) by [`ln`] and [`exp`] was 30 instructions more each time (`bench/firmware.sh`).
/// Below f32's normal range (2⁻¹²⁶) vⁿ is 0, above 2¹²⁷ it is 2¹²⁷: a |z|ⁿ rounded up to
/// 2⁻¹²⁶ where it is smaller made dz/dθ negative for a set with β + γ near f32's largest.
///
/// Never inlined: a leaf call keeps its constants out of the caller's registers, where two
/// inlined copies in a sub-step left the compiler 50 register moves (`bench/firmware.sh`).
#[inline(never)]
pub fn pow(v: f32, n: f32) -> f32 {
    let (m, exponent) = split(v);
    let t = m - 1.0;
    let log2 = exponent as f32
        + t * (1.442_713_5
            + t * (-0.721_131_8 + t * (0.479_348_2 + t * (-0.367_490_95 + t * (0.322_152_97 + t * -0.206_585_11)))));
    let y = n * log2;
    if y < -126.0 {
        return 0.0;
    }
    let y = if y > 127.0 { 127.0 } else { y };
    // The nearest integer by adding and taking away 1.5·2²³, as in [`exp`].
    const ROUND: f32 = 12_582_912.0;
    let whole = (y + ROUND) - ROUND;
    let f = y - whole;
    let poly = 1.000_000_1
        + f * (core::f32::consts::LN_2
            + f * (0.240_221_07 + f * (0.055_502_974 + f * (0.009_676_036 + f * 0.001_340_999))));
    poly * f32::from_bits(((whole as i32 + 127) as u32) << 23)
}

/// e^y − 1: its Taylor polynomial of degree 7 for |y| < 1/4 (relative error ≤ 2·10⁻⁹ before
/// f32 rounding), where e^y − 1 would lose the small increments of a tick; [`exp`] − 1
/// beyond, y held to ±87.
#[inline(always)]
pub fn exp_m1(y: f32) -> f32 {
    if y.abs() < 0.25 {
        y * (1.0
            + y * (1.0 / 2.0
                + y * (1.0 / 6.0 + y * (1.0 / 24.0 + y * (1.0 / 120.0 + y * (1.0 / 720.0 + y * (1.0 / 5040.0)))))))
    } else {
        exp(within_exp_range(y)) - 1.0
    }
}

pub mod verify;

#[cfg(test)]
mod tests;
