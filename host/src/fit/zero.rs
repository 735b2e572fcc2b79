//! The deflection's zero θ0 and the torque sensor's offset of each run of a fit.
//!
//! - **A run that starts at rest** (its rest window, [`crate::prepare::RestWindow`]): θ0 is the
//!   deflection it reads there and the offset the torque it reads there (the model's torque at
//!   rest is 0). Each such run has its own: a gear's rest point moves with the loops it went
//!   through (remanence), and each run is fitted from its own rest.
//! - **A run that does not**: θ0 and a torque offset cannot both be told from the data where the
//!   spring is nearly linear (k·(θ − θ0) + c). The offset is taken as 0 and θ0, shared by every
//!   such run, is fitted: starting from the encoder's zero or the middle of the runs' deflection
//!   range, whichever fits better, the kind is fitted with a free
//!   constant c, θ0 moves to where the fitted spring's torque plus c is zero, and the kind is
//!   fitted there without c; that repeats while the move is significant and lowers the misfit.
use super::motion::{fit_kind, FreeOffset, Motion, MotionFit};
use super::{FitError, FitOptions};
pub use crate::prepare::{OriginSource, RunOrigin};
use model_core::{GearModel, Kind};

/// Rounds of the θ0 iteration at most.
const ZERO_ROUNDS: usize = 4;
/// The iteration stops once θ0 would move less than this fraction of the deflection noise…
const ZERO_TOLERANCE_IN_NOISE: f64 = 0.05;
/// …or less than this many of its standard errors.
const SIGNIFICANT_IN_SE: f64 = 2.0;

/// Fits `kind` to `motion`, whose runs without a rest window (`fitted_zero[i]`) share a fitted
/// θ0; the others keep theirs. Returns the fit (of x = θ − θ0, its model's θ0 still 0) and each
/// run's origin.
pub fn fit_with_zero(
    kind: Kind,
    motion: &Motion,
    origins: &[Option<RunOrigin>],
    options: &FitOptions,
) -> Result<(MotionFit, Vec<RunOrigin>), FitError> {
    let requested = options;
    let placed = |zero: f64| -> Motion {
        let mut placed = motion.clone();
        for (run, origin) in placed.runs.iter_mut().zip(origins) {
            let (zero, offset) = origin.map_or((zero, 0.0), |o| (o.zero_rad, o.torque_offset_nm));
            run.zero = zero;
            run.torque_offset = offset;
        }
        placed
    };
    let resolved = |zero: f64, se: Option<f64>| -> Vec<RunOrigin> {
        origins
            .iter()
            .map(|origin| {
                origin.unwrap_or(RunOrigin {
                    zero_rad: zero,
                    zero_se_rad: se,
                    torque_offset_nm: 0.0,
                    source: OriginSource::Fitted,
                })
            })
            .collect()
    };
    if origins.iter().all(Option::is_some) {
        let fit = fit_kind(kind, &placed(0.0), options)?;
        return Ok((fit, resolved(0.0, None)));
    }
    let tolerance = ZERO_TOLERANCE_IN_NOISE * motion.noise.map_or(0.0, |n| n.deflection_rad);
    // The candidates are compared on the knot rule's knots: placed freely, the knots of a spring
    // zeroed off its data (all of it on one side of the encoder's zero) leave the empty stretch
    // for the data, and that θ0 wins (the measured runs without their rest: 4 of 15 fell back to
    // the encoder's zero, θ0 off by 127–188 % of the range). The found θ0 is refitted with them.
    let mut options = FitOptions { free_knots: false, ..options.clone() };
    // θ0 starts at the better of the encoder's zero and the centre of the runs' deflection
    // range (a Masing loop's centre, where its virgin curve starts; the free constant alone does
    // not find it from afar: 0.5 A off, it moved θ0 the wrong way), and moves only while a
    // move is significant and lowers the misfit: a Masing loop is infinitely stiff at its
    // tips, so a θ0 a few nrad off a symmetric recording's centre changes the fit more than
    // the constant can tell.
    let mut se = None;
    let (mut zero, mut best) = (0.0, fit_kind(kind, &placed(0.0), &options)?);
    let centre = range_centre(motion, origins);
    // Within the deflection noise of the encoder's zero, the rounds below find it as well.
    if centre.abs() > motion.noise.map_or(0.0, |n| n.deflection_rad) {
        let centred = fit_kind(kind, &placed(centre), &options)?;
        if centred.rss < best.rss {
            (zero, best) = (centre, centred);
        }
    }
    for _ in 0..ZERO_ROUNDS {
        options.start = Some(best.model);
        let free = fit_kind(kind, &Motion { free_offset: true, ..placed(zero) }, &options)?;
        let Some(FreeOffset { nm, se_nm }) = free.offset else { break };
        let (shift, stiffness) = spring_zero(&free.model, nm)?;
        let shift_se = se_nm.map(|se| se / stiffness.abs());
        se = shift_se;
        if shift.abs() <= tolerance.max(SIGNIFICANT_IN_SE * shift_se.unwrap_or(0.0)) {
            break;
        }
        options.start = Some(free.model);
        let moved = fit_kind(kind, &placed(zero + shift), &options)?;
        if moved.rss >= best.rss {
            break;
        }
        (zero, best) = (zero + shift, moved);
    }
    if options.free_knots != requested.free_knots {
        best = fit_kind(kind, &placed(zero), &FitOptions { start: Some(best.model), ..requested.clone() })?;
    }
    Ok((best, resolved(zero, se)))
}

/// The middle of the scored deflections of the runs without a rest window, rad.
fn range_centre(motion: &Motion, origins: &[Option<RunOrigin>]) -> f64 {
    let scored = motion.runs.iter().zip(origins).filter(|(_, origin)| origin.is_none()).flat_map(|(run, _)| {
        run.spans.iter().flat_map(|span| span.range.clone().filter_map(|i| run.theta.get(i).copied()))
    });
    let (lo, hi) = scored.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), theta| (lo.min(theta), hi.max(theta)));
    if lo <= hi {
        0.5 * (lo + hi)
    } else {
        0.0
    }
}

/// Where the spring of `model` plus `offset` (N·m) has zero torque, as a shift of x from 0, and
/// the spring's stiffness there (its mean over the range where the tangent is 0): bisection on
/// the monotone spring within its range, its edge's line beyond.
fn spring_zero(model: &GearModel<f64>, offset: f64) -> Result<(f64, f64), FitError> {
    let mut spring = model.spring.prepare()?;
    let [lo, hi] = model.spring.range;
    let mut torque = |x: f64| spring.evaluate(x).torque + offset;
    let (at_lo, at_hi) = (torque(lo), torque(hi));
    let mean = (at_hi - at_lo) / (hi - lo);
    if !(mean.is_finite() && mean > 0.0) {
        return Err(FitError::Degenerate);
    }
    let x = if at_lo >= 0.0 {
        lo - at_lo / mean
    } else if at_hi <= 0.0 {
        hi - at_hi / mean
    } else {
        let (mut a, mut b) = (lo, hi);
        for _ in 0..100 {
            let mid = 0.5 * (a + b);
            if torque(mid) < 0.0 {
                a = mid;
            } else {
                b = mid;
            }
        }
        0.5 * (a + b)
    };
    let tangent = spring.evaluate(x).stiffness;
    Ok((x, if tangent > 0.0 { tangent } else { mean }))
}
