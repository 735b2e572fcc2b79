//! The per-tick evaluation of T(θ) and dT/dθ in a few dozen FPU instructions.
//!
//! model-core's f32 path calls libm's `asinf`/`expf`, which on the Cortex-M4F go through
//! software double-precision helpers (716.5 instructions per T_ff + K evaluation, measured by
//! `bench/firmware.sh`). This path runs model-core's own formula ([`Phase`], [`Polynomial`])
//! with a polynomial arcsine (Abramowitz–Stegun 4.4.46), a range-reduced polynomial
//! exponential and the FPU's `vsqrt` (191 instructions); the constants that depend only on
//! the parameters (k = α/(ω(1 + r²)), r = β/ω) are prepared once when a set is installed.
//! Error against the f64 model: see the tests (`fast_path_error_bound`).
use crate::limit;
use core::f32::consts::{FRAC_PI_2, LN_2, LOG2_E};
use model_core::{Direction, Elementary, Evaluation, Params, Phase, Polynomial};

/// Largest |r| = |β/ω| for which e^(−rφ), φ ∈ [−π/2, 3π/2], stays well inside f32;
/// real gears have |r| ≈ 2 (paper: 1.87, seed fit: 2.30).
pub const MAX_ABS_R: f32 = 16.0;

/// Why a parameter set has no fast path (the direct path still works).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FastPathError {
    /// The parameters are not finite or ω = 0.
    Invalid,
    /// |β/ω| > [`MAX_ABS_R`].
    DecayOutOfRange,
    /// k = α/(ω(1 + r²)) does not fit in f32.
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

/// The constants of one parameter set, ready for [`FastModel::evaluate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastModel {
    polynomial: Polynomial<f32>,
    r: f32,
    /// k = α/(ω(1 + r²)), so that h = A·k.
    k: f32,
}

impl FastModel {
    pub fn new(params: &Params<f32>) -> Result<Self, FastPathError> {
        params.validate().map_err(|_| FastPathError::Invalid)?;
        // Prepared in f64: runs once per push, and keeps k exact to f32 rounding.
        let r = f64::from(params.beta) / f64::from(params.omega);
        // Finite operands and ω ≠ 0 leave r finite or ±∞, never NaN.
        if r.abs() > f64::from(MAX_ABS_R) {
            return Err(FastPathError::DecayOutOfRange);
        }
        let k = f64::from(params.alpha) / (f64::from(params.omega) * (1.0 + r * r));
        let k = k as f32;
        let polynomial = Polynomial::new(params.c1, params.c2, params.c3).map_err(|_| FastPathError::Overflow)?;
        if !k.is_finite() {
            return Err(FastPathError::Overflow);
        }
        Ok(FastModel { polynomial, r: r as f32, k })
    }

    /// T(θ) and dT/dθ on a loop of amplitude `amplitude`: model-core's own formula
    /// ([`Phase`], [`Polynomial`], as in [`model_core::Loop::evaluate`]) with the elementary
    /// functions below and h·e^(−rφ) formed directly (|r| ≤ [`MAX_ABS_R`] keeps it in range).
    /// Returns `None` when the inputs are not finite, A ≤ 0 or the result overflows.
    #[inline]
    pub fn evaluate(&self, theta: f32, direction: Direction, amplitude: f32) -> Option<Evaluation<f32>> {
        if !(amplitude > 0.0 && theta.is_finite() && amplitude.is_finite()) {
            return None;
        }
        let inv_amplitude = 1.0 / amplitude;
        let phase = Phase::new::<FastMath>(theta * inv_amplitude, direction);
        let h = amplitude * self.k;
        let z = phase.hysteresis(self.r, h, h * exp(-self.r * phase.angle), inv_amplitude);
        let evaluation = self.polynomial.evaluate(theta).plus(z);
        (evaluation.torque.is_finite() && evaluation.stiffness.is_finite()).then_some(evaluation)
    }
}

/// The fast path's elementary functions: the FPU's square root and polynomial arcsine,
/// exponential and logarithm. model-core's formulas run with them: [`FastModel::evaluate`]
/// (one symmetric loop) and the stateful genetic model on the joint
/// (`GeneticMemory::step_with::<FastMath>`, each branch through `memory::branch_with`).
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
    #[inline(always)]
    fn exp(y: f32) -> f32 {
        exp(y)
    }
    #[inline(always)]
    fn ln(v: f32) -> f32 {
        ln(v)
    }
    // h·e^(−rφ) as h times exp(−rφ): no ln and exp of h when a branch begins.
    const DIRECT_DECAY: bool = true;
    #[inline(always)]
    fn exp_direct(y: f32) -> f32 {
        exp_within_range(y)
    }
}

/// √v with the FPU's `vsqrt.f32` on the Cortex-M4F; libm (also correctly rounded) elsewhere.
#[inline(always)]
pub fn sqrt(v: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        // SAFETY: `swg_vsqrtf` below follows the AAPCS-VFP calling convention of `extern "C"`
        // on this target (argument and result in s0) and touches nothing else.
        #[allow(unsafe_code)]
        unsafe {
            swg_vsqrtf(v)
        }
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(v)
    }
}

// Rust has no stable `f32::sqrt` without std, and inline `asm!` cannot name single-precision
// registers on this target (its `sreg` class demands the double-precision `vfp2`), so the
// one instruction lives in a two-instruction function.
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[allow(unsafe_code)]
mod vsqrt {
    core::arch::global_asm!(
        ".section .text.swg_vsqrtf,\"ax\",%progbits",
        ".global swg_vsqrtf",
        ".type swg_vsqrtf,%function",
        ".fpu fpv4-sp-d16",
        ".thumb_func",
        "swg_vsqrtf:",
        "vsqrt.f32 s0, s0",
        "bx lr",
    );

    extern "C" {
        pub fn swg_vsqrtf(v: f32) -> f32;
    }
}
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
use vsqrt::swg_vsqrtf;

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

/// e^y for |y| ≤ 87: y = n·ln 2 + f with |f| ≤ ln 2 / 2, e^f by its Taylor polynomial of
/// degree 6 (relative error ≤ 1.3·10⁻⁷), 2^n put into the exponent bits.
#[inline(always)]
pub fn exp(y: f32) -> f32 {
    // The usual |y| ≤ 87 in one comparison, where the clamp takes two; beyond it (and NaN)
    // the clamp as before.
    exp_within_range(if y.abs() <= 87.0 { y } else { limit(y, -87.0, 87.0) })
}

/// [`exp`] of a y known to lie within ±87 (beyond, 2^n does not fit the exponent bits).
#[inline(always)]
fn exp_within_range(y: f32) -> f32 {
    // n = y·log2(e) rounded to the nearest integer by adding and taking away 1.5·2²³, which
    // leaves no fraction bits (|y·log2(e)| < 2²²): three FPU instructions, where rounding by
    // ±0.5 and a conversion took eleven.
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

/// ln v for a finite v > 0: v = 2^e·m with m ∈ [√½, √2), ln m = 2·atanh s with
/// s = (m − 1)/(m + 1), |s| ≤ 0.172, by its odd Taylor polynomial to s⁹ (|error| ≤ 2·s¹¹/11
/// ≈ 7·10⁻¹⁰), e·ln 2 split as in [`exp`]. Zero, subnormal, negative and non-finite v go to
/// libm (not on the fast path's inputs: the genetic model takes ln of a branch's half-width,
/// whose reciprocal must be finite).
#[inline(always)]
pub fn ln(v: f32) -> f32 {
    let bits = v.to_bits();
    // v ∈ [MIN_POSITIVE, MAX] (positive, normal, finite) as one unsigned comparison of its bits.
    if bits.wrapping_sub(f32::MIN_POSITIVE.to_bits()) > f32::MAX.to_bits() - f32::MIN_POSITIVE.to_bits() {
        return libm::logf(v);
    }
    let mut e = ((bits >> 23) & 0xFF) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007F_FFFF) | 0x3F80_0000);
    if m > core::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let atanh = s + s * s2 * (1.0 / 3.0 + s2 * (0.2 + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0))));
    const LN_2_HIGH: f32 = 0.693_359_4;
    const LN_2_LOW: f32 = LN_2 - LN_2_HIGH;
    let e = e as f32;
    e * LN_2_HIGH + (e * LN_2_LOW + 2.0 * atanh)
}

pub mod verify;

#[cfg(test)]
mod tests;
