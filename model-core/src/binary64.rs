//! Binary64 (f64) arithmetic on positive finite values in 64-bit integers: each operation's
//! exact result rounded to 53 significant bits, ties to even, as IEEE 754's f64 operations round
//! it (the exponent is not limited: no value here overflows or underflows f64's range).
//!
//! For f32 code that must give the same bits as a computation in f64 — [`Model`]'s direct-form
//! k, the firmware's libm-exact arcsine — on a target whose FPU has single precision only (the
//! Cortex-M4F): there the compiler's software f64 helpers were 3 KiB of the joint's 48 KiB of
//! flash. Only what those two need: products with an f32's significand, sums,
//! differences, quotients, the rounding to f32. The tests compare each with the host's f64.
//!
//! The operations keep 10 bits below a significand's last and fold whatever is shifted out
//! beyond them into the lowest ("sticky") bit: the rounding sees whether the exact value lies
//! below, at or above a midpoint, as it would with every bit.
//!
//! [`Model`]: crate::Model

/// A positive binary64 value, `significand`·2^`exponent` with `significand` ∈ [2⁵², 2⁵³).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Double {
    pub significand: u64,
    pub exponent: i32,
}

/// Bits kept below a significand's last one while an operation's result is formed.
const GUARD: u32 = 10;

impl Double {
    /// 1.
    pub const ONE: Double = Double { significand: 1 << 52, exponent: -52 };

    /// v·2^e exactly, for 0 < v < 2⁵³.
    pub fn exact(v: u64, e: i32) -> Double {
        let shift = v.leading_zeros() - 11;
        Double { significand: v << shift, exponent: e - shift as i32 }
    }

    /// |v| exactly, for a finite v ≠ 0 (subnormals included); `None` for 0, ∞ and NaN.
    pub fn from_f32(v: f32) -> Option<Double> {
        let bits = v.to_bits() & 0x7fff_ffff;
        let (field, fraction) = (bits >> 23, u64::from(bits & 0x007f_ffff));
        match field {
            0 if fraction == 0 => None,
            0 => Some(Double::exact(fraction, -149)),
            0xff => None,
            _ => Some(Double::exact(fraction | 1 << 23, field as i32 - 150)),
        }
    }

    /// self·m·2^e rounded, for 0 < m < 2²⁴ (an f32's significand).
    #[inline(never)]
    pub fn times(self, m: u32, e: i32) -> Double {
        let shift = m.leading_zeros() - 8;
        let m = u64::from(m << shift);
        let (high, low) = ((self.significand >> 32) * m, (self.significand & 0xffff_ffff) * m);
        // The product high·2³² + low ∈ [2⁷⁵, 2⁷⁷): its bits from 2²⁰ up, and whether any below.
        let product = ((high << 12) + (low >> 20)) | u64::from(low & 0xf_ffff != 0);
        round(product, self.exponent + e - shift as i32 + 20)
    }

    /// self + other rounded.
    #[inline(never)]
    pub fn plus(self, other: Double) -> Double {
        let (big, small) = if self.exponent >= other.exponent { (self, other) } else { (other, self) };
        let sum = (big.significand << GUARD) + aligned(small, big.exponent);
        round(sum, big.exponent - GUARD as i32)
    }

    /// self − other rounded, for self > other.
    pub fn minus(self, other: Double) -> Double {
        let difference = (self.significand << GUARD) - aligned(other, self.exponent);
        // Less than 2⁵⁵ only when `other` lost no bits in its alignment (its exponent is within
        // one of self's): exact, shifted back up.
        let (difference, e) = normalized(difference, self.exponent - GUARD as i32);
        round(difference, e)
    }

    /// self/other rounded: 56 quotient bits by long division, the remainder's sign as the
    /// sticky bit.
    pub fn over(self, other: Double) -> Double {
        let (mut remainder, divisor) = (self.significand, other.significand);
        let mut exponent = self.exponent - other.exponent;
        // The quotient's first bit is 1: remainder/divisor ∈ [1, 2).
        if remainder < divisor {
            remainder <<= 1;
            exponent -= 1;
        }
        let mut quotient = 0u64;
        // Until its first bit reaches 2⁵⁵ (a bound the compiler does not unroll).
        while quotient >> 55 == 0 {
            quotient <<= 1;
            if remainder >= divisor {
                remainder -= divisor;
                quotient |= 1;
            }
            remainder <<= 1;
        }
        round(quotient | u64::from(remainder != 0), exponent - 55)
    }

    /// The value rounded to f32 (ties to even; subnormal where it is that small, ∞ beyond
    /// f32's range), as `as f32` rounds an f64.
    #[inline(never)]
    pub fn to_f32(self) -> f32 {
        // The value lies in [2^k, 2^(k+1)); f32's last significand bit there is worth 2^(k − 23),
        // or 2⁻¹⁴⁹ for a subnormal.
        let k = self.exponent + 52;
        if k > 127 {
            return f32::INFINITY;
        }
        let last_bit = (k - 23).max(-149);
        // ≥ 29.
        let drop = (last_bit - self.exponent) as u32;
        if drop >= 64 {
            // Below half the smallest subnormal.
            return 0.0;
        }
        let m = rounded_off(self.significand, drop);
        // m·2^last_bit. A normal's m ∈ [2²³, 2²⁴] has the bits (biased exponent − 1)·2²³ + m,
        // which carry into the exponent when m = 2²⁴ (into ∞ beyond the largest finite); a
        // subnormal's m ≤ 2²³ is its bits (2²³: the smallest normal's).
        let bits = if last_bit == -149 { m as u32 } else { ((k + 126) as u32) * (1 << 23) + m as u32 };
        f32::from_bits(bits)
    }
}

/// `v` shifted right by `drop` (1 ≤ `drop` < 64) with the bits shifted out rounded in, ties to
/// even.
fn rounded_off(v: u64, drop: u32) -> u64 {
    let kept = v >> drop;
    let rest = v & ((1 << drop) - 1);
    let half = 1 << (drop - 1);
    kept + u64::from(rest > half || (rest == half && kept & 1 == 1))
}

/// `d`'s significand with [`GUARD`] bits more, shifted to the exponent `to` (≥ d's), the bits
/// shifted out folded into the lowest.
fn aligned(d: Double, to: i32) -> u64 {
    let wide = d.significand << GUARD;
    match (to - d.exponent) as u32 {
        shift @ 0..=63 => wide >> shift | u64::from(wide & ((1 << shift) - 1) != 0),
        _ => 1,
    }
}

/// v·2^e with v shifted up to at least 2⁵⁵ (v > 0).
fn normalized(v: u64, e: i32) -> (u64, i32) {
    let shift = v.leading_zeros().saturating_sub(8);
    (v << shift, e - shift as i32)
}

/// v·2^e rounded to 53 bits, for 2⁵⁵ ≤ v < 2⁶⁴ whose lowest bit is set where anything lay
/// below it (at least three bits go: the rounding bit, one more, and that one).
#[inline(never)]
fn round(v: u64, e: i32) -> Double {
    let drop = 11 - v.leading_zeros();
    let m = rounded_off(v, drop);
    let e = e + drop as i32;
    if m >> 53 != 0 {
        Double { significand: m >> 1, exponent: e + 1 }
    } else {
        Double { significand: m, exponent: e }
    }
}

#[cfg(test)]
mod tests;
