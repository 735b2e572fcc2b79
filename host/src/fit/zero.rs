//! The deflection's zero θ0 and the torque sensor's offset of each run of a fit.
//!
//! - **A run that starts at rest** (its rest window, [`crate::prepare::RestWindow`]): θ0 is the
//!   deflection it reads there and the offset the torque it reads there (the model's torque at
//!   rest is 0). Each such run has its own: a gear's rest point moves with the loops it went
//!   through (remanence), and each run is fitted from its own rest.
//! - **A run that does not**: θ0 and a torque offset cannot both be told from the data where the
//!   spring is nearly linear (k·(θ − θ0) + c). The offset is taken as 0 and θ0, shared by every
//!   such run, is searched over the runs' deflection range by the fit's weighted misfit (its
//!   profile): a grid, then golden-section search around the grid's best, each point one linear
//!   solve with the nonlinear parameters (genetic r) of a first fit at the range's middle, on a
//!   strided copy of the motion (the turning points kept); then the kind is fitted at the θ0
//!   found (r polished on the copy, the linear parameters on every sample; `auto`'s candidates
//!   keep the copy's and are scored on every sample, the chosen kind refitted). The middle of the
//!   range (a Masing loop's centre) or the encoder's zero is kept unless the best is
//!   significantly better. The uncertainty spans the θ0s whose misfit is within 10 % of the
//!   best: on a one-cycle run fitted after its extremes (one branch) the profile is flat over
//!   milliradians of θ0 on one side, and the report says so.
use super::motion::{fit_kind, Motion, MotionFit, BOUC_WEN_TRAVEL};
use super::{FitError, FitOptions};
pub use crate::prepare::{OriginSource, RunOrigin};
use model_core::{GearModel, Kind};
use rayon::prelude::*;

/// The θ0 search fits on a strided copy of the motion of about this many samples at most.
const SEARCH_SAMPLES: usize = 1 << 13;
/// Intervals of the search's grid over the deflection range.
const GRID_INTERVALS: usize = 16;
/// The golden-section search ends at this fraction of the deflection range.
const REFINE_TOLERANCE: f64 = 1e-4;
/// A simpler θ0 (the range's middle, the encoder's zero) is kept unless the best misfit is lower
/// by more than this many σ² (σ² = the best's RSS per fitted sample): a likelihood-ratio test of
/// one parameter at 2σ.
const SIGNIFICANT_IN_VARIANCE: f64 = 4.0;
/// θ0's uncertainty spans the θ0s whose misfit is within this fraction of the best: apart from
/// θ0, the knots' placement moves with it and changes the misfit by a few % on the measured
/// runs (bench/real/FINDINGS.md §9), so a sharper bound would claim more than the fit knows.
const PROFILE_TOLERANCE: f64 = 0.1;

/// `motion` with the runs of unknown origin at θ0 `zero` (torque offset 0), the others at theirs.
fn placed<'a>(motion: &Motion<'a>, origins: &[Option<RunOrigin>], zero: f64) -> Motion<'a> {
    let mut placed = motion.clone();
    for (run, origin) in placed.runs.iter_mut().zip(origins) {
        let (zero, offset) = origin.map_or((zero, 0.0), |o| (o.zero_rad, o.torque_offset_nm));
        run.zero = zero;
        run.torque_offset = offset;
    }
    placed
}

/// Where the linear parameters of a fit at the θ0 found are solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FinalSolve {
    /// On every sample: the parameters written.
    EverySample,
    /// On the strided copy the search ran on, where the motion is long, then scored on every
    /// sample: `auto`'s candidates, judged by their held-out RMS; the chosen kind is refitted
    /// on every sample.
    Strided,
}

/// Fits `kind` to `motion`, whose runs without a rest window (`origins[i]` none) share a fitted
/// θ0; the others keep theirs. Returns the fit (of x = θ − θ0, its model's θ0 still 0) and each
/// run's origin.
pub fn fit_with_zero(
    kind: Kind,
    motion: &Motion,
    origins: &[Option<RunOrigin>],
    options: &FitOptions,
    solve: FinalSolve,
) -> Result<(MotionFit, Vec<RunOrigin>), FitError> {
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
        let fit = fit_kind(kind, &placed(motion, origins, 0.0), options)?;
        return Ok((fit, resolved(0.0, None)));
    }
    let strided = match kind {
        // Its candidates' cost is the path they step along, not the samples: windows of a long
        // motion (`motion::BOUC_WEN_TRAVEL`).
        Kind::BoucWen => motion.windowed(SEARCH_SAMPLES, BOUC_WEN_TRAVEL).or_else(|| motion.strided(SEARCH_SAMPLES)),
        _ => motion.strided(SEARCH_SAMPLES),
    };
    let search = strided.as_ref().map(|strided| strided.motion(motion));
    let search = search.as_ref().unwrap_or(motion);
    let [lo, hi] = deflection_range(motion, origins);
    let centre = 0.5 * (lo + hi);
    // The candidates are compared on the knot rule's knots: placed freely, the knots of a spring
    // zeroed off its data (all of it on one side of the encoder's zero) leave the empty stretch
    // for the data, and that θ0 wins (the measured runs without their rest: 4 of 15 fell back to
    // the encoder's zero, θ0 off by 127–188 % of the range). The fit at the θ0 found places them
    // as `options` asks.
    let searching = FitOptions { free_knots: false, ..options.clone() };
    // The first fit searches the kind's nonlinear parameters globally; the others start there.
    let first = fit_kind(kind, &placed(search, origins, centre), &searching);
    let start = match &first {
        Ok(fit) => fit.model,
        // The middle may be degenerate (one branch, collinear columns): the first grid point
        // that fits starts the others.
        Err(_) => {
            grid(lo, hi)
                .find_map(|zero| fit_kind(kind, &placed(search, origins, zero), &searching).ok())
                .ok_or(FitError::Degenerate)?
                .model
        }
    };
    // The profile's points keep the first fit's nonlinear parameters, each one linear solve, and
    // its weights at each sample: every θ0 is weighed alike.
    let weights = placed(search, origins, centre).noise_weights(&GearModel { zero: 0.0, ..start })?;
    let held = FitOptions { start: Some(start), hold_start: true, ..searching };
    let misfit = |zero: f64| -> (f64, f64) {
        let at = placed(search, origins, zero);
        let at = match &weights {
            Some(weights) => at.with_weights(weights),
            None => at,
        };
        (zero, fit_kind(kind, &at, &held).map_or(f64::INFINITY, |fit| fit.misfit))
    };
    let mut profile: Vec<(f64, f64)> = grid(lo, hi).collect::<Vec<_>>().into_par_iter().map(misfit).collect();
    profile.push(misfit(centre));
    if lo <= 0.0 && 0.0 <= hi {
        profile.push(misfit(0.0));
    }
    let (grid_best, _) = lowest(&profile).ok_or(FitError::Degenerate)?;
    let step = (hi - lo) / GRID_INTERVALS as f64;
    golden(&mut profile, &misfit, (grid_best - step).max(lo), (grid_best + step).min(hi), REFINE_TOLERANCE * (hi - lo));
    let (best, best_rss) = lowest(&profile).ok_or(FitError::Degenerate)?;
    let samples = search.fitted().max(1) as f64;
    let variance = best_rss / samples;
    let simpler = profile
        .iter()
        .filter(|(zero, _)| *zero == centre || *zero == 0.0)
        .filter(|(_, rss)| *rss <= best_rss + SIGNIFICANT_IN_VARIANCE * variance)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|&(zero, _)| zero);
    let zero = simpler.unwrap_or(best);
    // The θ0s the fit does not tell apart: those within PROFILE_TOLERANCE of the best misfit.
    let spread = profile
        .iter()
        .filter(|(_, rss)| *rss <= (1.0 + PROFILE_TOLERANCE) * best_rss)
        .fold(0.0f64, |m, (z, _)| m.max((z - zero).abs()));
    let se = spread.max(REFINE_TOLERANCE * (hi - lo));
    // The nonlinear parameters polished at the θ0 found on the strided copy, the linear ones then
    // solved on every sample (or kept from the copy, `FinalSolve::Strided`); a short motion is
    // its own copy.
    let polish = FitOptions { start: Some(start), hold_start: false, ..options.clone() };
    let fit = match &strided {
        Some(_) => {
            let polished = fit_kind(kind, &placed(search, origins, zero), &polish)?;
            let every = placed(motion, origins, zero);
            match solve {
                FinalSolve::Strided => every.rescore(polished)?,
                FinalSolve::EverySample => {
                    let held = FitOptions { start: Some(polished.model), hold_start: true, ..options.clone() };
                    fit_kind(kind, &every, &held)?
                }
            }
        }
        None => fit_kind(kind, &placed(motion, origins, zero), &polish)?,
    };
    Ok((fit, resolved(zero, Some(se))))
}

/// The grid's θ0s over [lo, hi], its ends included.
fn grid(lo: f64, hi: f64) -> impl Iterator<Item = f64> {
    (0..=GRID_INTERVALS).map(move |k| lo + (hi - lo) * k as f64 / GRID_INTERVALS as f64)
}

/// The θ0 of least misfit of those evaluated, and its misfit.
fn lowest(profile: &[(f64, f64)]) -> Option<(f64, f64)> {
    profile.iter().copied().filter(|(_, rss)| rss.is_finite()).min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Golden-section search of `misfit` on [a, b] down to `tolerance`, every evaluation added to
/// `profile`.
fn golden(
    profile: &mut Vec<(f64, f64)>,
    misfit: &(impl Fn(f64) -> (f64, f64) + Sync),
    mut a: f64,
    mut b: f64,
    tolerance: f64,
) {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - ratio * (b - a), a + ratio * (b - a));
    let (mut fc, mut fd) = (misfit(c), misfit(d));
    profile.extend([fc, fd]);
    while b - a > tolerance {
        if fc.1 <= fd.1 {
            (b, d, fd) = (d, c, fc);
            c = b - ratio * (b - a);
            fc = misfit(c);
            profile.push(fc);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + ratio * (b - a);
            fd = misfit(d);
            profile.push(fd);
        }
    }
}

/// The range of every deflection of the runs without a rest window, [lo, hi] rad: where the
/// spring's zero torque lies for a run whose torque changes sign.
fn deflection_range(motion: &Motion, origins: &[Option<RunOrigin>]) -> [f64; 2] {
    let unknown = motion.runs.iter().zip(origins).filter(|(_, origin)| origin.is_none());
    let (lo, hi) = unknown
        .flat_map(|(run, _)| run.theta.iter().copied())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), theta| (lo.min(theta), hi.max(theta)));
    if lo <= hi {
        [lo, hi]
    } else {
        [0.0, 0.0]
    }
}
