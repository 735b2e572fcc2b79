//! Whether a gear's model can be evaluated over the whole range a joint will see: every
//! deflection |θ| ≤ D (so |x| = |θ − θ0| ≤ D + |θ0| ≤ 2·D: θ0 itself must lie within ±D), every loop amplitude and branch half-width
//! up to 2·(D + |θ0|) that the stateful evaluators can produce, in the float type `F` the joint
//! runs (f32), on the direct path and on the firmware's fast path.
//!
//! The check bounds each term of T and dT/dθ analytically (in f64, whatever `F` is) and asks
//! that the bound of the sum stay below `F::MAX / MARGIN`, so that no intermediate of the
//! evaluation (5·c3·x⁴, h·e^(−rφ), r·h·e^(−rφ), the capped 1/|cos φ|, …) nor the rounding of
//! the fast path's approximations can reach infinity:
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
use crate::{ParamName, Real};
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

/// Bounds of |T| and |K| of the polynomial c1·x + c2·x³ + c3·x⁵ for |x| ≤ d.
fn polynomial_bound(c: [f64; 3], d: f64) -> (f64, f64) {
    let [c1, c2, c3] = c.map(f64::abs);
    let d2 = d * d;
    // The slope factors 3·c2 and 5·c3 are formed before x² multiplies them.
    let stiffness = (c1 + d2 * (3.0 * c2 + 5.0 * c3 * d2)).max(3.0 * c2).max(5.0 * c3);
    (d * (c1 + d2 * (c2 + d2 * c3)), stiffness)
}

/// The model's parameters in f64, in the order of [`GearModel::map`], with their names.
struct Wide {
    values: [(ParamName, f64); 2 * crate::spring::MAX_KNOTS + 3 * crate::gear::SLIP_ELEMENTS + 8],
    count: usize,
    kind: crate::Kind,
}

impl Wide {
    fn of<F: Real>(model: &GearModel<F>) -> Wide {
        let mut wide = Wide {
            values: [(ParamName::Zero, 0.0); 2 * crate::spring::MAX_KNOTS + 3 * crate::gear::SLIP_ELEMENTS + 8],
            count: 0,
            kind: model.kind(),
        };
        model.map(|name, value| {
            if let Some(slot) = wide.values.get_mut(wide.count) {
                *slot = (name, f64_of(value));
                wide.count += 1;
            }
            value
        });
        wide
    }

    fn all(&self) -> &[(ParamName, f64)] {
        self.values.get(..self.count).unwrap_or(&[])
    }

    fn get(&self, name: ParamName) -> f64 {
        self.all().iter().find(|(n, _)| *n == name).map_or(0.0, |(_, v)| *v)
    }

    /// Bounds of |T| and |K| over |θ| ≤ `max_deflection`, the parameter `neutral` set to its
    /// neutral value (0; |β| or 1 for ω).
    fn bound(&self, max_deflection: f64, neutral: Option<ParamName>) -> (f64, f64) {
        let value = |name: ParamName| match neutral {
            Some(n) if n == name && name == ParamName::Omega => {
                let beta = self.get(ParamName::Beta);
                if beta == 0.0 {
                    1.0
                } else {
                    beta.abs()
                }
            }
            Some(n) if n == name => 0.0,
            _ => self.get(name),
        };
        let d = max_deflection + value(ParamName::Zero).abs();
        // The spring is evaluated at the range's ends too (the edges' values and stiffness,
        // continued beyond them).
        let ends = value(ParamName::RangeMin).abs().max(value(ParamName::RangeMax).abs());
        let d_spring = d.max(ends);
        let (mut torque, mut stiffness) =
            polynomial_bound([value(ParamName::C1), value(ParamName::C2), value(ParamName::C3)], d_spring);
        // Horner's rule forms x² whatever the coefficients.
        stiffness = stiffness.max(d_spring * d_spring);
        let knots_k = self
            .all()
            .iter()
            .filter(|(name, _)| matches!(name, ParamName::KnotStiffness(_)))
            .map(|(name, _)| value(*name).abs())
            .fold(0.0, f64::max);
        torque += knots_k * d_spring;
        stiffness += knots_k;
        // The stiffness's slope between knots, which the prepared spring keeps per segment.
        let knots: [(f64, f64); crate::spring::MAX_KNOTS] = core::array::from_fn(|j| {
            let j = u8::try_from(j).unwrap_or(u8::MAX);
            (value(ParamName::Knot(j)), value(ParamName::KnotStiffness(j)))
        });
        let count = self.all().iter().filter(|(name, _)| matches!(name, ParamName::Knot(_))).count();
        for pair in knots.get(..count).unwrap_or(&[]).windows(2) {
            if let [(x0, k0), (x1, k1)] = pair {
                stiffness = stiffness.max(((k1 - k0) / (x1 - x0)).abs());
            }
        }
        let width = 2.0 * d;
        let (t, k) = match self.kind {
            crate::Kind::Genetic => {
                genetic_bound(value(ParamName::Alpha), value(ParamName::Beta), value(ParamName::Omega), width)
            }
            crate::Kind::MicroSlip => {
                let mut bound = (0.0, 0.0);
                for (name, _) in self.all() {
                    if let ParamName::SlipStiffness(i) = name {
                        let k = value(*name).abs();
                        bound.0 += k * self.get(ParamName::Slip(*i)).min(width);
                        bound.1 += k;
                    }
                }
                bound
            }
        };
        // A NaN (∞·0) counts as ∞.
        let nan_inf = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
        (nan_inf(torque + t), nan_inf(stiffness + k))
    }
}

/// Bounds of |H| and |dH/dθ| of the genetic memory with [`TURNING_POINTS`] turning points on
/// branches of half-width up to `width`.
fn genetic_bound(alpha: f64, beta: f64, omega: f64, width: f64) -> (f64, f64) {
    if alpha == 0.0 {
        return (0.0, 0.0);
    }
    let r = beta / omega;
    let k = alpha.abs() / (omega.abs() * (1.0 + r * r));
    let half_pi = core::f64::consts::FRAC_PI_2;
    let e = (r * half_pi).max(-3.0 * r * half_pi).exp();
    let r = r.abs();
    let z_t = k * width * (e + r + 1.0);
    // r, k and h = A·k at A = 1 (what the fast path forms) must be finite too.
    let z_k = (k * ((r + 100.0) * e + 101.0 * (r + 1.0))).max(k).max(r);
    let copies = (TURNING_POINTS + 2) as f64;
    (copies * z_t, copies * z_k)
}

/// Whether `model` (checked: [`GearModel::check`]) can be evaluated in `F` for |θ| ≤
/// `max_deflection`; else the parameter whose neutral value would make it so (0 for the spring's
/// and the elements' stiffnesses, its range's ends, θ0, α, β; |β| or 1 for ω), or the micro-slip element whose
/// slip deflection lies beyond the travel.
pub fn gear<F: Real>(model: &GearModel<F>, max_deflection: F) -> Result<(), Culprit> {
    let limit = f64_of(F::max_value()) / MARGIN;
    let d = f64_of(max_deflection);
    let wide = Wide::of(model);
    // θ0 is a deflection the encoders read: within the joint's plausible range (so that x stays
    // within twice it, where the evaluators are bounded).
    if !matches!(wide.get(ParamName::Zero).abs().partial_cmp(&d), Some(Ordering::Less | Ordering::Equal)) {
        return Err(Culprit::Param(ParamName::Zero));
    }
    if let Hysteresis::MicroSlip(_) = model.hysteresis {
        let travel = 2.0 * (d + wide.get(ParamName::Zero).abs());
        for (name, value) in wide.all() {
            // NaN counts as beyond.
            let within = matches!(value.partial_cmp(&travel), Some(Ordering::Less | Ordering::Equal));
            if matches!(name, ParamName::Slip(_)) && !within {
                return Err(Culprit::Param(*name));
            }
        }
    }
    let fits = |(torque, stiffness): (f64, f64)| torque <= limit && stiffness <= limit;
    if fits(wide.bound(d, None)) {
        return Ok(());
    }
    // β and ω before α: α = 0 switches the whole hysteresis term off, whatever overflows in it.
    let first = [
        ParamName::C1,
        ParamName::C2,
        ParamName::C3,
        ParamName::RangeMin,
        ParamName::RangeMax,
        ParamName::Zero,
        ParamName::Beta,
        ParamName::Omega,
    ];
    let rest =
        wide.all().iter().map(|(name, _)| *name).filter(|name| {
            matches!(name, ParamName::KnotStiffness(_) | ParamName::SlipStiffness(_) | ParamName::Alpha)
        });
    first
        .into_iter()
        .chain(rest)
        .find(|&name| wide.all().iter().any(|(n, _)| *n == name) && fits(wide.bound(d, Some(name))))
        .map_or(Err(Culprit::Several), |name| Err(Culprit::Param(name)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::{micro_slip_set, PAPER_TABLE_2, SEED_TABLE_FIT};

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
    }
}
