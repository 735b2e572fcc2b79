//! The direct path's elementary functions ([`DirectMath`]): libm's, bit for bit, as model-core's
//! [`Libm`] evaluates with them, but without double precision. On the Cortex-M4F (an FPU of
//! single precision only) libm's `asinf` computes its result for 0.5 ≤ |x| < 1 in f64 — a square
//! root, a product, a sum and a difference, each rounded to 53 bits, then the result to 24 —
//! which linked the compiler's software f64 helpers (2 KiB of flash) and took hundreds of
//! instructions per tick. [`asin`] makes the same roundings of the same exact values in integer
//! arithmetic (model-core's [`binary64`](model_core::binary64)); its square root starts from the
//! FPU's `vsqrt`, which is also the direct path's √ (correctly rounded, as libm's `sqrtf`). The
//! tests compare [`asin`] with libm's on every f32 from 0.5 to 1 of either sign, and its 53-bit
//! square root with the host's f64 one on every argument it gets.
use crate::fast;
use model_core::binary64::Double;
use model_core::{Elementary, Libm};

/// model-core's [`Libm`] functions, bit for bit, with √ by the FPU and [`asin`] without f64:
/// what the compensator's direct path ([`swg_protocol::EvalPath::Direct`]) evaluates with.
#[derive(Clone, Copy, Debug)]
pub struct DirectMath;

impl Elementary<f32> for DirectMath {
    /// The FPU's `vsqrt` ([`fast::sqrt`]): correctly rounded, as libm's `sqrtf`.
    #[inline(always)]
    fn sqrt(v: f32) -> f32 {
        fast::sqrt(v)
    }
    #[inline(always)]
    fn asin(x: f32) -> f32 {
        asin(x)
    }
    #[inline(always)]
    fn exp(y: f32) -> f32 {
        <Libm as Elementary<f32>>::exp(y)
    }
    #[inline(always)]
    fn ln(v: f32) -> f32 {
        <Libm as Elementary<f32>>::ln(v)
    }
    #[inline(always)]
    fn exp_m1(y: f32) -> f32 {
        <Libm as Elementary<f32>>::exp_m1(y)
    }
    #[inline(always)]
    fn ln_1p(v: f32) -> f32 {
        <Libm as Elementary<f32>>::ln_1p(v)
    }
    // `pow`, `DIRECT_DECAY` and `exp_direct`: the trait's defaults, as `Libm`'s.
}

// libm's asinf (FreeBSD's e_asinf.c): its rational approximation R(z) of (asin x − x)/x³, z = x².
const P_S0: f32 = 1.666_658_7e-1;
const P_S1: f32 = -4.274_342_2e-2;
const P_S2: f32 = -8.656_363e-3;
const Q_S1: f32 = -7.066_296_3e-1;

#[inline(always)]
fn r(z: f32) -> f32 {
    let p = z * (P_S0 + z * (P_S1 + z * P_S2));
    let q = 1.0 + z * Q_S1;
    p / q
}

/// asin x exactly as libm's `asinf`; NaN for |x| > 1.
#[inline(never)]
pub fn asin(x: f32) -> f32 {
    let hx = x.to_bits();
    let ix = hx & 0x7fff_ffff;
    if ix >= 0x3f80_0000 {
        if ix == 0x3f80_0000 {
            // libm's x·π/2 + 2⁻¹²⁰ in f64, rounded to f32: ±π/2.
            return f32::from_bits(core::f32::consts::FRAC_PI_2.to_bits() | (hx & 0x8000_0000));
        }
        // libm's NaN for |x| > 1 (and x itself when NaN), exactly as it forms it.
        #[allow(clippy::eq_op)]
        return 0.0 / (x - x);
    }
    if ix < 0x3f00_0000 {
        // |x| < 0.5: libm's f32 code as it is.
        if (0x0080_0000..0x3980_0000).contains(&ix) {
            return x;
        }
        return x + x * r(x * x);
    }
    // 0.5 ≤ |x| < 1: π/2 − 2·(s + s·R(z)) with z = (1 − |x|)/2 and s = √z, in f64 in libm.
    let z = (1.0 - x.abs()) * 0.5;
    let angle = half_pi_minus_twice(sqrt53(z), r(z));
    if hx >> 31 != 0 {
        -angle
    } else {
        angle
    }
}

/// N − U² for N = `n_high`·2⁶⁴ and U < 2⁶³ in three parts (h, x, y) of 64 bits, without a
/// 128-bit product: N − U² = h·2⁶⁴ − x·2³² − y.
fn residual(n_high: u64, u: u64) -> (i64, u64, u64) {
    let (high, low) = (u >> 32, u & 0xffff_ffff);
    (n_high as i64 - (high * high) as i64, 2 * high * low, low * low)
}

/// √z rounded to 53 bits, ties to even (f64's `sqrt` of z), for a normal f32 z > 0.
///
/// With z = M·2^E, E even and M ∈ [2²⁴, 2²⁶), √z = √N·2^(E/2 − 50) for N = M·2¹⁰⁰, and
/// √N ∈ [2⁶², 2⁶³). The FPU's √M gives U within 2³⁹ of √N; two Newton steps U + (N − U²)/(2U),
/// the residual N − U² exact and the quotient in f32, bring it within 1.1; the rounding to 53
/// bits (10 bits off U) then holds unless U is that close to a midpoint, where the midpoint's
/// exact square against N decides (√N is never a midpoint: a midpoint's square is an odd number
/// times 2²⁰, N is M·2¹⁰⁰).
fn sqrt53(z: f32) -> Double {
    let bits = z.to_bits();
    let (m, e) = (u64::from((bits & 0x007f_ffff) | 0x0080_0000), ((bits >> 23) & 0xff) as i32 - 150);
    let (m, e) = if e & 1 != 0 { (m << 1, e - 1) } else { (m << 2, e - 2) };
    let n_high = m << 36;
    // M is exact in f32 (24 significant bits); a ∈ [2¹², 2¹³], U = a·2⁵⁰ ≤ 2⁶³.
    let a = fast::sqrt(m as u32 as f32);
    let a_bits = a.to_bits();
    let mut u = u64::from((a_bits & 0x007f_ffff) | 0x0080_0000) << (((a_bits >> 23) & 0xff) - 100);
    // 1/(2U) = y·2⁻⁵⁰.
    let y = 0.5 / a;
    // |N − U²| < 2¹⁰³: its bits from 2⁷³ up (within 2), and the step (< 2³⁹) in units of 2⁹.
    let (h, x, _) = residual(n_high, u);
    let top = (h >> 9) - (x >> 41) as i64;
    u = u.wrapping_add_signed(i64::from((top as i32 as f32 * y * 16_384.0) as i32) << 9);
    // Within 2¹⁸ of √N: |N − U²| < 2⁸², its bits from 2⁵¹ up, the step < 2¹⁸.
    let (h, x, low) = residual(n_high, u);
    let top = (h << 13) - (x >> 19) as i64 - (low >> 51) as i64;
    let step = (top as i32 as f32 * y * 2.0) as i32;
    let u = u.wrapping_add_signed(i64::from(step)).clamp(1 << 62, (1 << 63) - 1);
    let rounded = if (u & 0x3ff).abs_diff(0x200) <= 4 {
        // N > midpoint² exactly: h − x/2³² − (carry of the rest) ≥ 1.
        let (h, x, low) = residual(n_high, (u & !0x3ff) | 0x200);
        let carry = ((x & 0xffff_ffff) << 32).overflowing_add(low).1;
        (u >> 10) + u64::from(h - (x >> 32) as i64 - i64::from(carry) >= 1)
    } else {
        (u + 0x200) >> 10
    };
    let e = e / 2 - 40;
    if rounded >> 53 != 0 {
        Double { significand: rounded >> 1, exponent: e + 1 }
    } else {
        Double { significand: rounded, exponent: e }
    }
}

/// libm's π/2 in f64.
const HALF_PI: Double = Double { significand: 0x0019_21fb_5444_2d18, exponent: -52 };

/// π/2 − 2·(s + s·w) rounded to f32 after libm's f64 steps: s·w, the sum and the difference each
/// rounded to 53 bits.
fn half_pi_minus_twice(s: Double, w: f32) -> f32 {
    // w = R(z) > 0 and normal: R(z) ≈ z/6, z ≥ 2⁻²⁵.
    let bits = w.to_bits();
    let sum = s.plus(s.times((bits & 0x007f_ffff) | 0x0080_0000, ((bits >> 23) & 0xff) as i32 - 150));
    HALF_PI.minus(Double { exponent: sum.exponent + 1, ..sum }).to_f32()
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn asin_is_libm_s_on_every_f32_from_one_half_to_one() {
        for bits in 0x3f00_0000u32..=0x3f80_0000 {
            for x in [f32::from_bits(bits), -f32::from_bits(bits)] {
                assert_eq!(asin(x).to_bits(), libm::asinf(x).to_bits(), "asin({x:e})");
            }
        }
    }

    /// Every 997th bit pattern, NaN and infinity included, and the edges.
    #[test]
    fn asin_is_libm_s_everywhere_else() {
        for bits in (0..=u32::MAX).step_by(997) {
            let x = f32::from_bits(bits);
            let (got, want) = (asin(x), libm::asinf(x));
            assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()), "asin({x:e})");
        }
        for x in [0.0, -0.0, 1.0, -1.0, 0.5, -0.5, f32::MIN_POSITIVE, 1.0e-40, f32::from_bits(0x3f7f_ffff)] {
            assert_eq!(asin(x).to_bits(), libm::asinf(x).to_bits(), "asin({x:e})");
        }
    }

    /// The square root of every z that `asin` takes, (1 − |x|)/2 for 0.5 ≤ |x| < 1, against
    /// the host's f64 one.
    #[test]
    fn sqrt53_is_f64_s_on_every_argument_it_gets() {
        for bits in 0x3f00_0000u32..0x3f80_0000 {
            let z = (1.0 - f32::from_bits(bits)) * 0.5;
            let Double { significand, exponent } = sqrt53(z);
            assert!((1u64 << 52..1 << 53).contains(&significand));
            assert_eq!(significand as f64 * 2f64.powi(exponent), f64::from(z).sqrt(), "sqrt({z:e})");
        }
    }

    /// The other functions are [`Libm`]'s own; √ is libm's on the host (the FPU's `vsqrt` on the
    /// Cortex-M4F, checked there by `model-core-checks`).
    #[test]
    fn the_other_functions_are_libm_s() {
        for bits in (0x0000_0000u32..0x7f80_0000).step_by(7919) {
            let v = f32::from_bits(bits);
            assert_eq!(DirectMath::sqrt(v).to_bits(), <Libm as Elementary<f32>>::sqrt(v).to_bits());
            for y in [v.min(80.0), -v.min(80.0)] {
                assert_eq!(DirectMath::exp(y).to_bits(), <Libm as Elementary<f32>>::exp(y).to_bits());
                assert_eq!(DirectMath::exp_m1(y).to_bits(), <Libm as Elementary<f32>>::exp_m1(y).to_bits());
            }
            assert_eq!(DirectMath::ln(v).to_bits(), <Libm as Elementary<f32>>::ln(v).to_bits());
            assert_eq!(DirectMath::ln_1p(v).to_bits(), <Libm as Elementary<f32>>::ln_1p(v).to_bits());
            let pow = <DirectMath as Elementary<f32>>::pow(v, 1.5);
            assert_eq!(pow.to_bits(), <Libm as Elementary<f32>>::pow(v, 1.5).to_bits());
        }
    }
}
