//! Whether a gear's model can be evaluated over the whole range a joint will see: every
//! deflection |θ| ≤ D (so |x| = |θ − θ0| ≤ D + |θ0| ≤ 2·D: θ0 itself must lie within ±D), every loop amplitude and branch half-width
//! up to 2·(D + |θ0|) that the stateful evaluators can produce, in the float type `F` the joint
//! runs (f32), on the direct path and on the firmware's fast path.
//!
//! The check bounds each term of T and dT/dθ analytically and asks that the bound of the sum
//! stay below `F::MAX / MARGIN`, so that no intermediate of the evaluation (5·c3·x⁴, h·e^(−rφ),
//! r·h·e^(−rφ), the capped 1/|cos φ|, …) nor the rounding of the fast path's approximations can
//! reach infinity. The bounds are computed in `F` itself (no soft-float f64 on the joint): every
//! term is a sum of non-negative parts, so a part that overflows `F` makes the sum exceed the
//! limit, which is the answer; k·E is formed as e^(ln k + ln E), as the evaluation forms h·e^(−rφ),
//! so that a large E with a tiny k is not refused for E alone.
//!
//! - the spring's polynomial: |T| ≤ |c1|·d + |c2|·d³ + |c3|·d⁵, |K| ≤ |c1| + 3|c2|·d² + 5|c3|·d⁴,
//!   and the slope factors 3|c2| and 5|c3| themselves (beyond its range the spring is the line
//!   of its edge, which these bound too);
//! - the spring's knots: the stiffness between them interpolates theirs, so |K| ≤ max K_j and
//!   |P| ≤ max K_j·d; the stiffness's slope between two knots is bounded too;
//! - genetic z on a loop of half-width w ≤ 2·d, h = w·k, k = α/(ω(1 + r²)), r = β/ω, phase
//!   φ ∈ [−π/2, 3π/2]: with E = max e^(−rφ) = e^(max(rπ/2, −3rπ/2)),
//!   |z| ≤ |h|·(E + |r| + 1) and |dz/dθ| ≤ |k|·((|r| + 100)·E + 101·(|r| + 1));
//!   the memory's hysteretic part H adds at most one such z per stored turning point
//!   (`depth` + 2 of them); r and k themselves are bounded too;
//! - micro-slip: |T| adds Σ k_i·min(d_i, 2·d) (an element's elastic deflection never exceeds
//!   its slip deflection nor the travel 2·d), |K| adds Σ k_i.
//!
//! One more rule for the micro-slip kind: its slip deflections must lie within the travel
//! 2·d; an element that could only slip beyond it is a parameter set fitted to (or typed for)
//! some other range, not this joint.
//!
//! What it does not bound: the straight part of a genetic branch between two turning points
//! closer together than f32 resolves; the evaluator refuses such a sample by itself (the
//! tick is off, the memory untouched).
use crate::gear::{GearModel, Hysteresis, TURNING_POINTS};
use crate::{Model, ParamName, Params, Real};
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

/// Bounds of |T| and |K| of the polynomial c1·x + c2·x³ + c3·x⁵ for |x| ≤ d.
fn polynomial_bound<F: Real>(c: [F; 3], d: F) -> (F, F) {
    let [c1, c2, c3] = c.map(F::abs);
    let d2 = d * d;
    // The slope factors 3·c2 and 5·c3 are formed before x² multiplies them.
    let (c2x3, c3x5) = (F::THREE * c2, F::FIVE * c3);
    let stiffness = (c1 + d2 * (c2x3 + c3x5 * d2)).max(c2x3).max(c3x5);
    (d * (c1 + d2 * (c2 + d2 * c3)), stiffness)
}

/// Bounds of |H| and |dH/dθ| of the genetic memory with [`TURNING_POINTS`] turning points on
/// branches of half-width up to `width`; ∞ where the hysteresis cannot be evaluated at all.
fn genetic_bound<F: Real>(alpha: F, beta: F, omega: F, width: F) -> (F, F) {
    if alpha == F::zero() {
        return (F::zero(), F::zero());
    }
    let zero = F::zero();
    let params = Params { c1: zero, c2: zero, c3: zero, alpha, beta, omega };
    // r = β/ω and ln k, k = α/(ω(1 + r²)), formed as the evaluation forms them.
    let Ok(model) = Model::new(params) else { return (F::infinity(), F::infinity()) };
    let r = model.r();
    let half_pi = F::FRAC_PI_2();
    // ln E = max(rπ/2, −3rπ/2), E the largest e^(−rφ) over φ ∈ [−π/2, 3π/2].
    let ln_e = (r * half_pi).max(-F::THREE * r * half_pi);
    let (k, k_e) = (model.ln_abs_k.exp(), (model.ln_abs_k + ln_e).exp());
    let r = r.abs();
    let z_t = width * (k_e + k * (r + F::one()));
    // r, k and h = A·k at A = 1 (what the fast path forms) must be finite too.
    let hundred = F::from(100.0).unwrap_or_else(F::infinity);
    let z_k = (k_e * (r + hundred) + k * (hundred + F::one()) * (r + F::one())).max(k).max(r);
    let copies = F::from(TURNING_POINTS + 2).unwrap_or_else(F::infinity);
    (copies * z_t, copies * z_k)
}

/// Bounds of |T| and |K| over |θ| ≤ `max_deflection`, with the parameter `neutral` set to its
/// neutral value (0; |β| or 1 for ω).
fn bound<F: Real>(model: &GearModel<F>, max_deflection: F, neutral: Option<ParamName>) -> (F, F) {
    let value = |name: ParamName, actual: F| if neutral == Some(name) { F::zero() } else { actual };
    let spring = &model.spring;
    let d = max_deflection + value(ParamName::Zero, model.zero).abs();
    // The spring is evaluated at the range's ends too (the edges' values and stiffness,
    // continued beyond them).
    let [lo, hi] = spring.range;
    let ends = value(ParamName::RangeMin, lo).abs().max(value(ParamName::RangeMax, hi).abs());
    let d_spring = d.max(ends);
    let c = [value(ParamName::C1, spring.c1), value(ParamName::C2, spring.c2), value(ParamName::C3, spring.c3)];
    let (mut torque, mut stiffness) = polynomial_bound(c, d_spring);
    // Horner's rule forms x² whatever the coefficients.
    stiffness = stiffness.max(d_spring * d_spring);
    let knot_stiffness = |i: usize, k: F| value(ParamName::KnotStiffness(i as u8), k.abs());
    let knots = spring.knots();
    let largest = (0..).zip(knots).fold(F::zero(), |largest, (i, knot)| largest.max(knot_stiffness(i, knot.stiffness)));
    torque = torque + largest * d_spring;
    stiffness = stiffness + largest;
    // The stiffness's slope between knots, which the prepared spring keeps per segment.
    for (i, pair) in (0..).zip(knots.windows(2)) {
        if let [a, b] = pair {
            let slope = (knot_stiffness(i + 1, b.stiffness) - knot_stiffness(i, a.stiffness)) / (b.x - a.x);
            stiffness = stiffness.max(slope.abs());
        }
    }
    let width = (F::one() + F::one()) * d;
    let (t, k) = match &model.hysteresis {
        Hysteresis::Genetic(g) => {
            let omega = match neutral {
                Some(ParamName::Omega) if g.beta == F::zero() => F::one(),
                Some(ParamName::Omega) => g.beta.abs(),
                _ => g.omega,
            };
            genetic_bound(value(ParamName::Alpha, g.alpha), value(ParamName::Beta, g.beta), omega, width)
        }
        Hysteresis::MicroSlip(_) => (0..).zip(model.slip_elements()).fold((F::zero(), F::zero()), |(t, k), (i, e)| {
            let stiffness = value(ParamName::SlipStiffness(i), e.stiffness).abs();
            (t + stiffness * e.slip.min(width), k + stiffness)
        }),
        Hysteresis::BoucWen(term) => {
            // |z| ≤ z_max (and ≤ A·travel from rest); 0 ≤ dz/dx ≤ A·max(1, 2β/(β + γ)).
            let stiffness = value(ParamName::HysteresisStiffness, term.stiffness).abs();
            let shape = &term.shape;
            let two = F::one() + F::one();
            let slope = shape.a * F::one().max(two * shape.beta / (shape.beta + shape.gamma));
            (stiffness * shape.z_max().min(shape.a * width), stiffness * slope)
        }
        // |H| ≤ Σ w (P moves within ±Σ w of rest); a cell's share moves at most 2 per interval
        // of h = 2R/INTERVALS, so |dH/dx| ≤ Σ w·INTERVALS/R. A neutral R is a wide one.
        Hysteresis::Preisach(preisach) => {
            let total = (0..)
                .zip(&preisach.weights)
                .fold(F::zero(), |sum, (i, w)| sum + value(ParamName::PreisachWeight(i), *w).abs());
            let per_reach = if neutral == Some(ParamName::PreisachReach) { F::zero() } else { preisach.reach.recip() };
            let intervals = F::from(crate::preisach::INTERVALS).unwrap_or_else(F::one);
            (total, total * intervals * per_reach)
        }
    };
    // A NaN (∞·0, ∞ − ∞) counts as ∞.
    let nan_inf = |v: F| if v.is_nan() { F::infinity() } else { v };
    (nan_inf(torque + t), nan_inf(stiffness + k))
}

/// Whether `model` (checked: [`GearModel::check`]) can be evaluated in `F` for |θ| ≤
/// `max_deflection`; else the parameter whose neutral value would make it so (0 for the spring's
/// and the elements' stiffnesses, its range's ends, θ0, α, β; |β| or 1 for ω), or the micro-slip
/// element whose slip deflection lies beyond the travel.
pub fn gear<F: Real>(model: &GearModel<F>, max_deflection: F) -> Result<(), Culprit> {
    let limit = F::max_value() / F::from(MARGIN).unwrap_or_else(F::one);
    let d = max_deflection;
    // θ0 is a deflection the encoders read: within the joint's plausible range (so that x stays
    // within twice it, where the evaluators are bounded). NaN counts as beyond.
    let within = |value: F, limit: F| matches!(value.partial_cmp(&limit), Some(Ordering::Less | Ordering::Equal));
    if !within(model.zero.abs(), d) {
        return Err(Culprit::Param(ParamName::Zero));
    }
    let travel = (F::one() + F::one()) * (d + model.zero.abs());
    if let Some(i) = (0u8..).zip(model.slip_elements()).find_map(|(i, e)| (!within(e.slip, travel)).then_some(i)) {
        return Err(Culprit::Param(ParamName::Slip(i)));
    }
    let fits = |(torque, stiffness): (F, F)| torque <= limit && stiffness <= limit;
    if fits(bound(model, d, None)) {
        return Ok(());
    }
    // β and ω before α: α = 0 switches the whole hysteresis term off, whatever overflows in it,
    // as Bouc–Wen's k_h = 0 does (its A, which scales z with k_h, has no neutral value).
    let genetic = matches!(model.hysteresis, Hysteresis::Genetic(_));
    let bouc_wen = matches!(model.hysteresis, Hysteresis::BoucWen(_));
    let preisach = match &model.hysteresis {
        Hysteresis::Preisach(p) => p.weights.len(),
        _ => 0,
    };
    let first =
        [ParamName::C1, ParamName::C2, ParamName::C3, ParamName::RangeMin, ParamName::RangeMax, ParamName::Zero]
            .into_iter()
            .chain(genetic.then_some([ParamName::Beta, ParamName::Omega]).into_iter().flatten());
    let knots = (0..model.spring.knots().len()).map(|i| ParamName::KnotStiffness(i as u8));
    let elements = (0..model.slip_elements().len()).map(|i| ParamName::SlipStiffness(i as u8));
    first
        .chain(knots)
        .chain(elements)
        .chain(genetic.then_some(ParamName::Alpha))
        .chain(bouc_wen.then_some(ParamName::HysteresisStiffness))
        .chain((preisach > 0).then_some(ParamName::PreisachReach))
        .chain((0..preisach).map(|i| ParamName::PreisachWeight(i as u8)))
        .find(|&name| fits(bound(model, d, Some(name))))
        .map_or(Err(Culprit::Several), |name| Err(Culprit::Param(name)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::{bouc_wen_set, micro_slip_set, preisach_set, PAPER_TABLE_2, SEED_TABLE_FIT};

    const D: f32 = 0.1;

    #[test]
    fn the_reference_sets_fit() {
        for p in [PAPER_TABLE_2, SEED_TABLE_FIT] {
            let model = GearModel::paper(p);
            assert_eq!(gear(&model.map(|_, v| v as f32), D), Ok(()));
            assert_eq!(gear(&model, 0.1f64), Ok(()));
        }
        assert_eq!(gear(&micro_slip_set().unwrap().map(|_, v| v as f32), D), Ok(()));
    }

    #[test]
    fn each_huge_parameter_is_named() {
        let genetic = GearModel::paper(PAPER_TABLE_2).map(|_, v| v as f32);
        for name in ParamName::GENETIC {
            let value = if name == ParamName::Omega { 1.0e-38 } else { 1.0e38 };
            assert_eq!(gear(&genetic.with(name, value), D), Err(Culprit::Param(name)), "{name:?}");
        }
        let slip = micro_slip_set().unwrap().map(|_, v| v as f32);
        for name in [ParamName::C1, ParamName::C2, ParamName::C3] {
            assert_eq!(gear(&slip.with(name, 1.0e38), D), Err(Culprit::Param(name)));
        }
        for i in 0..16 {
            let name = ParamName::SlipStiffness(i);
            assert_eq!(gear(&slip.with(name, 1.0e38), D), Err(Culprit::Param(name)));
        }
        assert_eq!(gear(&slip.with(ParamName::Slip(15), 1.0), D), Err(Culprit::Param(ParamName::Slip(15))));
        assert_eq!(gear(&slip.with(ParamName::Zero, 1.0e38), D), Err(Culprit::Param(ParamName::Zero)));
        assert_eq!(gear(&slip.with(ParamName::Zero, 0.2), D), Err(Culprit::Param(ParamName::Zero)));
        assert_eq!(gear(&slip.with(ParamName::Zero, -0.05), D), Ok(()));
        let bouc_wen = bouc_wen_set().map(|_, v| v as f32);
        assert_eq!(gear(&bouc_wen, D), Ok(()));
        for name in [ParamName::C1, ParamName::C2, ParamName::HysteresisStiffness] {
            assert_eq!(gear(&bouc_wen.with(name, 1.0e38), D), Err(Culprit::Param(name)), "{name:?}");
        }
        // A scales z_max = A/(β + γ) with k_h: k_h, whose 0 switches the hysteresis off, is named.
        let hysteresis = Err(Culprit::Param(ParamName::HysteresisStiffness));
        assert_eq!(gear(&bouc_wen.with(ParamName::BoucWenA, 1.0e38), D), hysteresis);
        // A larger β, γ or n only narrows z: nothing overflows.
        for name in [ParamName::BoucWenBeta, ParamName::BoucWenGamma, ParamName::BoucWenN] {
            assert_eq!(gear(&bouc_wen.with(name, 1.0e38), D), Ok(()), "{name:?}");
        }
        let preisach = preisach_set().map(|_, v| v as f32);
        assert_eq!(gear(&preisach, D), Ok(()));
        for i in [0, 17, 35] {
            let name = ParamName::PreisachWeight(i);
            assert_eq!(gear(&preisach.with(name, 1.0e38), D), Err(Culprit::Param(name)), "{name:?}");
        }
        // A reach so small that the relays switch within it: the stiffness bound overflows.
        let tiny = Err(Culprit::Param(ParamName::PreisachReach));
        assert_eq!(gear(&preisach.with(ParamName::PreisachReach, 1.0e-38), D), tiny);
    }
}
