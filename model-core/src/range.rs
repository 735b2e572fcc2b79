//! Whether a parameter set can be evaluated over the whole range a joint will see: every
//! deflection |θ| ≤ D, every loop amplitude and branch half-width up to 2·D that the stateful
//! evaluators can produce, in the float type `F` the joint runs (f32), on the direct path and
//! on the firmware's fast path.
//!
//! The check bounds each term of T and dT/dθ analytically (in f64, whatever `F` is) and asks
//! that the bound of the sum stay below `F::MAX / MARGIN`, so that no intermediate of the
//! evaluation (5·c3·θ⁴, h·e^(−rφ), r·h·e^(−rφ), the capped 1/|cos φ|, …) nor the rounding of
//! the fast path's approximations can reach infinity:
//!
//! - polynomial: |T| ≤ |c1|·D + |c2|·D³ + |c3|·D⁵, |K| ≤ |c1| + 3|c2|·D² + 5|c3|·D⁴, and the
//!   slope factors 3|c2| and 5|c3| themselves;
//! - genetic z on a loop of half-width w ≤ 2·D, h = w·k, k = α/(ω(1 + r²)), r = β/ω, phase
//!   φ ∈ [−π/2, 3π/2]: with E = max e^(−rφ) = e^(max(rπ/2, −3rπ/2)),
//!   |z| ≤ |h|·(E + |r| + 1) and |dz/dθ| ≤ |k|·((|r| + 100)·E + 101·(|r| + 1));
//!   the memory's hysteretic part H adds at most one such z per stored turning point
//!   (`depth` + 2 of them); r and k themselves are bounded too;
//! - micro-slip: |T| adds Σ k_i·min(d_i, 2·D) (an element's elastic deflection never exceeds
//!   its slip deflection nor the travel 2·D), |K| adds Σ k_i.
//!
//! One more rule for the micro-slip kind: its slip deflections must lie within the travel
//! 2·D; an element that could only slip beyond it is a parameter set fitted to (or typed for)
//! some other range, not this joint.
//!
//! What it does not bound: the straight part of a genetic branch between two turning points
//! closer together than f32 resolves; the evaluator refuses such a sample by itself (the
//! tick is off, the memory untouched).
use crate::memory::SlipParams;
use crate::{ParamName, Params, Real};
use core::cmp::Ordering;
#[allow(unused_imports)]
use num_traits::Float;

/// The factor between `F::MAX` and the largest bound accepted.
pub const MARGIN: f64 = 16.0;

/// The parameter that makes a set unevaluable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Culprit {
    /// This one parameter.
    Param(ParamName),
    /// No single parameter: several together.
    Several,
}

fn f64_of<F: Real>(value: F) -> f64 {
    value.to_f64().unwrap_or(f64::INFINITY)
}

fn limit<F: Real>() -> f64 {
    f64_of(F::max_value()) / MARGIN
}

/// Bounds of |T| and |K| of the polynomial spring for |θ| ≤ d.
fn polynomial_bound(c1: f64, c2: f64, c3: f64, d: f64) -> (f64, f64) {
    let (c1, c2, c3) = (c1.abs(), c2.abs(), c3.abs());
    let d2 = d * d;
    // The slope factors 3·c2 and 5·c3 are formed before θ² multiplies them.
    let stiffness = (c1 + d2 * (3.0 * c2 + 5.0 * c3 * d2)).max(3.0 * c2).max(5.0 * c3);
    (d * (c1 + d2 * (c2 + d2 * c3)), stiffness)
}

/// Bounds of |T| and |K| of the genetic memory for |θ| ≤ d, with `depth` turning points.
fn genetic_bound(p: &Params<f64>, d: f64, depth: usize) -> (f64, f64) {
    let (spring_t, spring_k) = polynomial_bound(p.c1, p.c2, p.c3, d);
    if p.alpha == 0.0 {
        return (spring_t, spring_k);
    }
    let r = p.beta / p.omega;
    let k = p.alpha.abs() / (p.omega.abs() * (1.0 + r * r));
    let half_pi = core::f64::consts::FRAC_PI_2;
    let e = (r * half_pi).max(-3.0 * r * half_pi).exp();
    let r = r.abs();
    let width = 2.0 * d;
    let z_t = k * width * (e + r + 1.0);
    // r, k and h = A·k at A = 1 (what the firmware's stage forms) must be finite too.
    let z_k = (k * ((r + 100.0) * e + 101.0 * (r + 1.0))).max(k).max(r);
    // A NaN (∞·0) counts as ∞.
    let nan_inf = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
    let copies = (depth + 2) as f64;
    (nan_inf(spring_t + copies * z_t), nan_inf(spring_k + copies * z_k))
}

fn fits<F: Real>((torque, stiffness): (f64, f64)) -> bool {
    torque <= limit::<F>() && stiffness <= limit::<F>()
}

/// Whether the genetic set `params` (validated: finite, ω ≠ 0) can be evaluated in `F` for
/// |θ| ≤ `max_deflection` by a memory of `depth` turning points; else the parameter whose
/// neutral value (0 for c1, c2, c3, α, β; |β| or 1 for ω) would make it so.
pub fn genetic<F: Real>(params: &Params<F>, max_deflection: F, depth: usize) -> Result<(), Culprit> {
    let wide = params.try_map(|_, v| Ok::<f64, ()>(f64_of(v))).map_err(|()| Culprit::Several)?;
    let d = f64_of(max_deflection);
    if fits::<F>(genetic_bound(&wide, d, depth)) {
        return Ok(());
    }
    let neutral = |name: ParamName| {
        let mut p = wide;
        match name {
            ParamName::C1 => p.c1 = 0.0,
            ParamName::C2 => p.c2 = 0.0,
            ParamName::C3 => p.c3 = 0.0,
            ParamName::Alpha => p.alpha = 0.0,
            ParamName::Beta => p.beta = 0.0,
            // r = ±1: the neutral ω for this β.
            ParamName::Omega => p.omega = if p.beta == 0.0 { 1.0 } else { p.beta.abs() },
            // Not the genetic kind's: never named here.
            _ => {}
        }
        p
    };
    // β and ω before α: α = 0 switches the whole hysteresis term off, whatever overflows in it.
    let order = [ParamName::C1, ParamName::C2, ParamName::C3, ParamName::Beta, ParamName::Omega, ParamName::Alpha];
    order
        .into_iter()
        .find(|&name| fits::<F>(genetic_bound(&neutral(name), d, depth)))
        .map_or(Err(Culprit::Several), |name| Err(Culprit::Param(name)))
}

/// Whether the micro-slip set `params` (validated) can be evaluated in `F` for |θ| ≤
/// `max_deflection`, with its slip deflections inside the travel 2·`max_deflection`; else
/// the parameter at fault.
pub fn micro_slip<F: Real, const M: usize>(params: &SlipParams<F, M>, max_deflection: F) -> Result<(), Culprit> {
    let d = f64_of(max_deflection);
    let travel = 2.0 * d;
    // NaN counts as beyond.
    let within = |v: F| matches!(f64_of(v).partial_cmp(&travel), Some(Ordering::Less | Ordering::Equal));
    if !within(params.slip_min) {
        return Err(Culprit::Param(ParamName::SlipMin));
    }
    if !within(params.slip_max) {
        return Err(Culprit::Param(ParamName::SlipMax));
    }
    let stiffness = params.stiffness.map(|k| f64_of(k).abs());
    let bound = |c: [f64; 3], stiffness: &[f64; M]| {
        let (mut t, mut k) = polynomial_bound(c[0], c[1], c[2], d);
        // d_i ≤ d_max ≤ travel: the elastic deflection is bounded by d_max.
        let elastic = f64_of(params.slip_max);
        for ki in stiffness {
            t += ki * elastic;
            k += ki;
        }
        (t, k)
    };
    let spring = [f64_of(params.c1), f64_of(params.c2), f64_of(params.c3)];
    if fits::<F>(bound(spring, &stiffness)) {
        return Ok(());
    }
    for (i, name) in [ParamName::C1, ParamName::C2, ParamName::C3].into_iter().enumerate() {
        let mut c = spring;
        if let Some(v) = c.get_mut(i) {
            *v = 0.0;
        }
        if fits::<F>(bound(c, &stiffness)) {
            return Err(Culprit::Param(name));
        }
    }
    for i in 0..M {
        let mut s = stiffness;
        if let Some(v) = s.get_mut(i) {
            *v = 0.0;
        }
        if fits::<F>(bound(spring, &s)) {
            return Err(Culprit::Param(ParamName::SlipStiffness(u8::try_from(i).unwrap_or(u8::MAX))));
        }
    }
    Err(Culprit::Several)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::{MICRO_SLIP_SET, PAPER_TABLE_2, SEED_TABLE_FIT};
    use crate::GearModel;

    const D: f32 = 0.1;

    #[test]
    fn the_reference_sets_fit() {
        for p in [PAPER_TABLE_2, SEED_TABLE_FIT] {
            assert_eq!(genetic(&p.to_f32(), D, 16), Ok(()));
            assert_eq!(genetic(&p, 0.1f64, 16), Ok(()));
        }
        assert_eq!(micro_slip(&MICRO_SLIP_SET.to_f32(), D), Ok(()));
    }

    #[test]
    fn each_huge_parameter_is_named() {
        for name in ParamName::GENETIC {
            let value = if name == ParamName::Omega { 1.0e-38 } else { 1.0e38 };
            let GearModel::Genetic(p) = GearModel::Genetic(PAPER_TABLE_2.to_f32()).with(name, value) else {
                unreachable!()
            };
            assert_eq!(genetic(&p, D, 16), Err(Culprit::Param(name)), "{name:?}");
        }
        let slip = MICRO_SLIP_SET.to_f32();
        for (i, c) in [ParamName::C1, ParamName::C2, ParamName::C3].into_iter().enumerate() {
            let mut p = slip;
            match i {
                0 => p.c1 = 1.0e38,
                1 => p.c2 = 1.0e38,
                _ => p.c3 = 1.0e38,
            }
            assert_eq!(micro_slip(&p, D), Err(Culprit::Param(c)));
        }
        for i in 0..16 {
            let mut p = slip;
            p.stiffness[i] = 1.0e38;
            assert_eq!(micro_slip(&p, D), Err(Culprit::Param(ParamName::SlipStiffness(i as u8))));
        }
        let p = SlipParams { slip_max: 1.0e38, ..slip };
        assert_eq!(micro_slip(&p, D), Err(Culprit::Param(ParamName::SlipMax)));
        let p = SlipParams { slip_min: 1.0e37, slip_max: 1.0e38, ..slip };
        assert_eq!(micro_slip(&p, D), Err(Culprit::Param(ParamName::SlipMin)));
    }
}
