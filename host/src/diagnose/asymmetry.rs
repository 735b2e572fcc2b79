//! A finding of form: whether the spring's two sides differ (`asymmetry`).
//!
//! The micro-slip form (the kind with the free-form spring and rate-independent hysteresis)
//! is fitted twice with the accepted torque effects beside it, on knots mirrored about the
//! deflection's zero: with its spring's two sides free, and forced point-symmetric (each pair of
//! knots ±x sharing one stiffness). The asymmetry is named on the tests an effect must pass:
//! the information criterion drops by more than [`MIN_BIC_DROP`] for the free side's extra
//! columns, the free side explains at least [`MIN_EXPLAINED`] of the symmetric spring's weighted
//! residual, and the two independent parts of the recording, each fitted alone, show it with the
//! same sign and magnitudes within [`MAX_HALF_SPREAD`] of their mean; and it is at least
//! [`MIN_ASYMMETRY`] and more than a zero off by 3σ of its reading would make. Only where the
//! form describes the loop: its weighted residual within [`STRUCTURE_FACTOR`] of the noise (on
//! the default genetic gear's nested motion the form left 38× the noise and read +31 % on a
//! symmetric gear).
//!
//! Its magnitude is the free fit's loop between ±a, a the extent both sides of the motion reach:
//! the secant from the origin to each tip, T(+a)/a against T(−a)/(−a). (The spring's own secants
//! would not do: the slip elements carry much of the stiffness, and how the fit shares it between
//! them and the spring is not identified. The elements are symmetric, so T(+a) + T(−a) =
//! S(+a) + S(−a): the tips' asymmetry is the spring's.)
//!
//! Only about a known zero: the deflection measured from a zero read at rest. A zero off the
//! gear's centre makes a symmetric spring that stiffens look asymmetric, so without a rest
//! window the asymmetry is not tested.
use super::effects::Effect;
use super::form::STRUCTURE_FACTOR;
use super::form::{columns_of, torque_column};
use super::observed::Observed;
use super::{share_below, weights_on, MAX_HALF_SPREAD, MIN_BIC_DROP, MIN_EXPLAINED};
use crate::fit::motion::{micro_slip_with_columns, ColumnsFit, SpringShape};
use crate::gear::run_offline;
use crate::prepare::reversals;
use rayon::prelude::*;
use serde::Serialize;

/// The smallest asymmetry named, (k₊ − k₋) over their mean. Below it a wrong hysteresis form
/// passes the tests: the peak-oriented OpenSees material under the random motion (+1.00, −1.17
/// mrad) read +0.7 % with ΔBIC 564, both parts of one sign (`bench/opensees/run.sh`). A 2 %
/// difference of stiffness is also below what a feed-forward notices beside a gear's spread.
pub const MIN_ASYMMETRY: f64 = 0.02;

/// The spring's two sides, measured and tested.
#[derive(Clone, Debug, Serialize)]
pub struct Asymmetry {
    /// The extent a both sides of the motion reach, rad: the secants are taken at ±a.
    pub extent_rad: f64,
    /// The free fit's secant stiffness to the loop's + tip, T(a)/a, N·m/rad.
    pub plus_nm_per_rad: f64,
    /// The free fit's secant stiffness to the loop's − tip, T(−a)/(−a), N·m/rad.
    pub minus_nm_per_rad: f64,
    /// (k₊ − k₋) over their mean: below 0 when the + side is the softer.
    pub magnitude: f64,
    /// The magnitude fitted on each independent part alone.
    pub halves: Option<[f64; 2]>,
    /// Drop of the information criterion from the symmetric spring to the free one.
    pub delta_bic: f64,
    /// Share of the symmetric spring's weighted residual that the free one explains.
    pub explained: f64,
    /// The free fit's weighted residual against the noise's (1: the noise alone).
    pub form_to_noise: f64,
    /// Every test on the whole recording passes: it is named unless its parts disagree or
    /// cannot be checked (a run of one cycle, whose parts are legs of one side each).
    pub whole_passes: bool,
    /// Why it is not named; `None` when it is.
    pub rejected: Option<String>,
}

/// Whether the asymmetry was tested, and what it showed.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "tested", rename_all = "snake_case")]
pub enum AsymmetryCheck {
    /// Tested: named when `rejected` is `None`.
    Yes(Asymmetry),
    /// Not tested, and why.
    No { why: String },
}

impl AsymmetryCheck {
    /// The asymmetry, when it was tested and named.
    pub fn named(&self) -> Option<&Asymmetry> {
        match self {
            AsymmetryCheck::Yes(asymmetry) if asymmetry.rejected.is_none() => Some(asymmetry),
            _ => None,
        }
    }
}

/// Tests the spring's asymmetry on `observed`, its deflection measured from a zero read at rest
/// to within `zero_se` (rad; `None` where the zero is not known), the accepted effects `active`
/// beside the form, with the search's `weights` (1/σ² of each sample's noise).
pub fn check(observed: &Observed, weights: &[f64], active: &[Effect], zero_se: Option<f64>) -> AsymmetryCheck {
    let untested = |why: &str| AsymmetryCheck::No { why: why.to_string() };
    let Some(zero_se) = zero_se else {
        return untested(if observed.time.is_none() {
            "a loop table holds no reading at rest, so its deflection's zero is not known: a zero off the gear's \
             centre makes a symmetric spring that stiffens look asymmetric"
        } else {
            "the deflection's zero is not known (no rest window before the motion): a zero off the gear's centre \
             makes a symmetric spring that stiffens look asymmetric"
        });
    };
    let Some(noise) = observed.noise else { return untested("the data give no noise estimate to judge it by") };
    let data = &observed.data;
    let (lo, hi) = data.theta.iter().fold((0.0f64, 0.0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    let extent = (-lo).min(hi);
    // Both sides need a stretch of their own beyond the noise, as the knot rule asks of a segment.
    let needed = crate::fit::spring::KNOT_SPACING_IN_NOISE * noise.deflection_rad;
    if !(extent > needed) {
        // The measured spring's 1 A runs reach −0.72 and +0.53 mrad, with 20σθ = 0.59 mrad.
        let reach = if extent > 0.0 {
            format!("the motion's shorter side reaches {:.3} mrad from the zero", 1e3 * extent)
        } else {
            format!("the motion stays on one side of the zero ({:+.3} … {:+.3} mrad)", 1e3 * lo, 1e3 * hi)
        };
        return AsymmetryCheck::No {
            why: format!(
                "{reach}, not beyond the {:.3} mrad ({} times the deflection's noise) a side needs for a stiffness \
                 of its own: record a larger amplitude",
                1e3 * needed,
                crate::fit::spring::KNOT_SPACING_IN_NOISE
            ),
        };
    }
    let reversals = reversals(&data.theta);
    let mut columns: Vec<Vec<f64>> =
        columns_of(observed, &reversals, noise, weights, active).into_iter().map(|(_, c)| c).collect();
    // A torque offset beside both springs always, as beside the kinks' scan: the form cannot tell
    // one from its misfit without the torque read at rest, and an offset c moves the tips'
    // secants by ±c/a (a symmetric micro-slip gear with 0.3 N·m read +2.5 %, a new user's trial).
    if !active.contains(&Effect::TorqueOffset) {
        columns.extend(torque_column(observed, Effect::TorqueOffset));
    }
    let extra: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
    // The torque along the recording is not needed here: dropped at once (16 MB at 2 M samples).
    let fit = |weights: &[f64], shape: SpringShape| {
        micro_slip_with_columns(&data.theta, &data.torque, &reversals, Some(noise), weights, &extra, shape)
            .ok()
            .map(|fit| ColumnsFit { predicted: Vec::new(), ..fit })
    };
    // Side by side: four solves along the recording, a fifth of `diagnose`'s time at 60 k samples.
    let (free, symmetric) =
        rayon::join(|| fit(weights, SpringShape::MirroredFree), || fit(weights, SpringShape::MirroredSymmetric));
    let (Some(free), Some(symmetric)) = (free, symmetric) else {
        return untested("the micro-slip form cannot be fitted to this data");
    };
    let Some((plus, minus)) = secants(&free, extent) else {
        return untested(
            "the micro-slip form's loop has no positive secant stiffness to both tips (a loop that does not \
             rise through the origin): the form does not describe this gear",
        );
    };
    let fitted = weights.iter().filter(|&&w| w > 0.0).count() as f64;
    let variance = free.chi2 / (fitted - free.parameters as f64).max(1.0);
    let extra_parameters = free.parameters.saturating_sub(symmetric.parameters) as f64;
    let drop = symmetric.chi2 - free.chi2;
    let delta_bic = drop / variance - extra_parameters * fitted.ln();
    let explained = drop / symmetric.chi2;
    let magnitude = relative(plus, minus);
    // Each part fitted alone (the other part's samples followed at weight 0), where each part
    // reaches both sides: the parts of a one-cycle recording are its legs, one side each.
    let reaches_both = |part: &[usize]| {
        let (lo, hi) =
            part.iter().fold((0.0f64, 0.0f64), |(lo, hi), &i| (lo.min(data.theta[i]), hi.max(data.theta[i])));
        -lo >= 0.5 * extent && hi >= 0.5 * extent
    };
    let both_sides = observed.parts.iter().all(|part| reaches_both(part));
    let halves = observed
        .parts
        .par_iter()
        .filter(|_| both_sides)
        .map(|part| {
            fit(&weights_on(weights, part.iter().copied()), SpringShape::MirroredFree)
                .and_then(|half| secants(&half, extent))
                .map(|(p, m)| relative(p, m))
        })
        .collect::<Option<Vec<f64>>>()
        .and_then(|h| <[f64; 2]>::try_from(h).ok());
    // A zero off by δ moves the origin the secants start from: an apparent asymmetry of 2δ/a.
    let from_zero = 3.0 * 2.0 * zero_se / extent;
    let on_the_whole = if !(variance <= STRUCTURE_FACTOR * STRUCTURE_FACTOR) {
        Some(format!(
            "the micro-slip form leaves {:.1}× the noise, so a difference between the sides may be its misfit of \
             the loop's shape",
            variance.sqrt()
        ))
    } else if !(magnitude.abs() >= MIN_ASYMMETRY) {
        Some(format!(
            "{:.1} % is below the {:.0} % named (a wrong hysteresis form leaves as much)",
            100.0 * magnitude.abs(),
            100.0 * MIN_ASYMMETRY
        ))
    } else if !(magnitude.abs() > from_zero) {
        Some(format!(
            "{:.1} % is within the {:.1} % that a zero off by 3σ (σ = {:.4} mrad, the rest reading's) makes of a \
             symmetric gear",
            100.0 * magnitude.abs(),
            100.0 * from_zero,
            1e3 * zero_se
        ))
    } else if !(delta_bic > MIN_BIC_DROP) {
        Some(format!("the information criterion drops by {delta_bic:.1} (it must drop by more than {MIN_BIC_DROP})"))
    } else if explained < MIN_EXPLAINED {
        Some(format!(
            "explains {} % of the symmetric spring's residual, less than {:.0} %",
            share_below(explained, MIN_EXPLAINED),
            100.0 * MIN_EXPLAINED
        ))
    } else {
        None
    };
    let whole_passes = on_the_whole.is_none();
    let rejected = on_the_whole.or_else(|| match halves {
        None if !both_sides => Some(
            "its two parts (alternate cycles) do not each reach both sides, so whether they agree cannot be \
                 checked: record several cycles"
                .to_string(),
        ),
        None => Some("the two parts of the recording cannot each be fitted alone".to_string()),
        Some([a, b]) if a.signum() != magnitude.signum() || b.signum() != magnitude.signum() => Some(format!(
            "the two parts disagree on which side is the softer: {:+.1} % and {:+.1} %",
            100.0 * a,
            100.0 * b
        )),
        Some([a, b]) if (a - b).abs() > MAX_HALF_SPREAD * (0.5 * (a + b)).abs() => {
            Some(format!("the two parts disagree: {:+.1} % and {:+.1} %", 100.0 * a, 100.0 * b))
        }
        Some(_) => None,
    });
    AsymmetryCheck::Yes(Asymmetry {
        extent_rad: extent,
        plus_nm_per_rad: plus,
        minus_nm_per_rad: minus,
        magnitude,
        halves,
        delta_bic,
        explained,
        form_to_noise: variance.sqrt(),
        whole_passes,
        rejected,
    })
}

/// The difference of two stiffnesses over their mean.
fn relative(plus: f64, minus: f64) -> f64 {
    2.0 * (plus - minus) / (plus + minus)
}

/// The fitted model's secant stiffness to the tips of its loop between ±a (from rest to +a, to
/// −a, to +a; each steady tip), N·m/rad, where both are finite and > 0.
fn secants(fit: &ColumnsFit, a: f64) -> Option<(f64, f64)> {
    const STEPS: usize = 200;
    let leg = |from: f64, to: f64| (1..=STEPS).map(move |k| from + (to - from) * k as f64 / STEPS as f64);
    let path: Vec<f64> = std::iter::once(0.0).chain(leg(0.0, a)).chain(leg(a, -a)).chain(leg(-a, a)).collect();
    let torque = run_offline(&fit.model, &path, &reversals(&path)).ok()?;
    let (plus, minus) = (torque.last()?.torque / a, torque.get(2 * STEPS)?.torque / -a);
    (plus.is_finite() && minus.is_finite() && plus > 0.0 && minus > 0.0).then_some((plus, minus))
}
