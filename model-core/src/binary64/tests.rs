extern crate std;
use super::*;

/// xorshift64: reproducible cases without a dependency.
struct Cases(u64);

impl Cases {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// A positive normal f64 with an exponent in [−range, range] and random significand bits,
    /// often with long runs of zeros or ones (ties and carries).
    fn f64(&mut self, range: i32) -> f64 {
        let exponent = (self.next() % (2 * range as u64 + 1)) as i32 - range;
        let mut fraction = self.next() & ((1 << 52) - 1);
        match self.next() % 4 {
            0 => fraction &= !((1 << (self.next() % 52)) - 1),
            1 => fraction |= (1 << (self.next() % 52)) - 1,
            _ => {}
        }
        f64::from_bits(((exponent + 1023) as u64) << 52 | fraction)
    }

    /// A finite f32 ≠ 0 of any sign, subnormals included.
    fn f32(&mut self) -> f32 {
        loop {
            let v = f32::from_bits(self.next() as u32);
            if v.is_finite() && v != 0.0 {
                return v;
            }
        }
    }
}

fn double(v: f64) -> Double {
    let bits = v.to_bits();
    Double { significand: bits & ((1 << 52) - 1) | 1 << 52, exponent: (bits >> 52) as i32 - 1075 }
}

fn value(d: Double) -> f64 {
    assert!((1 << 52..1 << 53).contains(&d.significand), "{d:?}");
    f64::from_bits(((d.exponent + 1075) as u64) << 52 | (d.significand & ((1 << 52) - 1)))
}

#[test]
fn f32_values_convert_exactly() {
    let mut cases = Cases(0x5eed_0001);
    for _ in 0..200_000 {
        let v = cases.f32();
        assert_eq!(Double::from_f32(v).map(value), Some(f64::from(v.abs())), "{v:e}");
    }
    for v in [f32::from_bits(1), f32::MIN_POSITIVE, f32::MAX, 1.0, -0.5] {
        assert_eq!(Double::from_f32(v).map(value), Some(f64::from(v.abs())), "{v:e}");
    }
    assert_eq!(Double::from_f32(0.0), None);
    assert_eq!(Double::from_f32(f32::INFINITY), None);
    assert_eq!(Double::from_f32(f32::NAN), None);
    assert_eq!(Double::from_f32(1.0), Some(Double::ONE));
}

/// Across f32's whole range and beyond it both ways, ties included.
#[test]
fn rounding_to_f32_is_as_f32_s() {
    let mut cases = Cases(0x5eed_0002);
    for _ in 0..1_000_000 {
        let v = cases.f64(160);
        assert_eq!(double(v).to_f32().to_bits(), (v as f32).to_bits(), "{v:e}");
    }
    for bits in [0x3ff0_0000_1000_0000u64, 0x3ff0_0000_3000_0000, 0x47ef_ffff_f000_0000, 0x47ef_ffff_efff_ffff] {
        let v = f64::from_bits(bits);
        assert_eq!(double(v).to_f32().to_bits(), (v as f32).to_bits(), "{v:e}");
    }
    // Ties at every subnormal position, and around the smallest ones.
    for shift in 0..30 {
        for v in [f64::from(f32::MIN_POSITIVE) / f64::from(1u32 << shift) * 1.5, 2f64.powi(-150), 2f64.powi(-151) * 3.0]
        {
            assert_eq!(double(v).to_f32().to_bits(), (v as f32).to_bits(), "{v:e}");
        }
    }
}

#[test]
fn operations_round_as_f64_s() {
    let mut cases = Cases(0x5eed_0003);
    for _ in 0..1_000_000 {
        let (a, b) = (cases.f64(300), cases.f64(300));
        let (x, y) = (double(a), double(b));
        let m = cases.f32().abs();
        let Some(Double { significand, exponent }) = Double::from_f32(m) else { unreachable!() };
        let product = x.times((significand >> 29) as u32, exponent + 29);
        assert_eq!(value(product), a * f64::from(m), "{a:e}·{m:e}");
        let small = (cases.next() % (1 << 24)) as u32 | 1;
        assert_eq!(value(x.times(small, -7)), a * f64::from(small) / 128.0, "{a:e}·{small}/128");
        assert_eq!(value(x.over(y)), a / b, "{a:e}/{b:e}");
        assert_eq!(value(x.plus(y)), a + b, "{a:e} + {b:e}");
        if a > b {
            assert_eq!(value(x.minus(y)), a - b, "{a:e} − {b:e}");
        }
        // Close operands: cancellation, and sums that carry.
        let c = a * (1.0 + (cases.next() % 1024) as f64 * f64::EPSILON);
        if c > a {
            assert_eq!(value(double(c).minus(x)), c - a, "{c:e} − {a:e}");
        }
        assert_eq!(value(double(c).plus(x)), c + a, "{c:e} + {a:e}");
    }
}

#[test]
fn rounding_ties_go_to_even() {
    assert_eq!(
        [0b1011, 0b1001, 0b1101, 0b1111, 0b1100].map(|v| rounded_off(v, 1)),
        [0b110, 0b100, 0b110, 0b1000, 0b110]
    );
    let tie = |low: u64| round((1 << 63) | low, 0);
    assert_eq!(tie(1 << 10), Double { significand: 1 << 52, exponent: 11 });
    assert_eq!(tie(3 << 10), Double { significand: (1 << 52) + 2, exponent: 11 });
    assert_eq!(tie((1 << 10) + 1), Double { significand: (1 << 52) + 1, exponent: 11 });
    assert_eq!(round(u64::MAX, 0), Double { significand: 1 << 52, exponent: 12 });
}

/// [`Real::decay_factor`] of f32 against the same formula in f64, rounded once: every sign,
/// magnitudes from subnormal to the largest, results that overflow or underflow f32.
#[test]
fn the_decay_factor_of_f32_is_f64_s_rounded_once() {
    use crate::Real;
    let reference = |alpha: f32, omega: f32, r: f32| {
        let (alpha, omega, r) = (f64::from(alpha), f64::from(omega), f64::from(r));
        (alpha / (omega * (1.0 + r * r))) as f32
    };
    let mut cases = Cases(0x5eed_0004);
    for case in 0..2_000_000 {
        let (alpha, omega) = (cases.f32(), cases.f32());
        let r = match case % 3 {
            0 => cases.f32(),
            // |r| ≤ 16, where the model uses it.
            _ => (cases.next() % 3_200_001) as f32 / 100_000.0 - 16.0,
        };
        let r = if case % 7 == 0 { 0.0 } else { r };
        let alpha = if case % 11 == 0 { 0.0 * alpha.signum() } else { alpha };
        let (got, want) = (f32::decay_factor(alpha, omega, r), reference(alpha, omega, r));
        assert_eq!(got.to_bits(), want.to_bits(), "alpha {alpha:e}, omega {omega:e}, r {r:e}");
    }
    // The paper's set (α = 68, β = −2.298, ω = 1) and the seed fit's scale.
    for (alpha, omega, r) in [(68.0f32, 1.0f32, -2.298f32), (-3.1e4, 0.7, 2.3), (1.0e-30, -3.0e30, 16.0)] {
        assert_eq!(f32::decay_factor(alpha, omega, r).to_bits(), reference(alpha, omega, r).to_bits());
    }
}
