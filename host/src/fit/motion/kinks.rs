//! The scan behind `diagnose`'s `stiffness_kinks`: where the micro-slip form's spring steps in
//! stiffness faster than the knot rule's spring can follow.
//!
//! The rule's spring is continuous and piecewise linear in stiffness, its knots at least 20σθ
//! apart (`fit::spring`): a step (a catalogue gear's kink at T1 and T2) is smeared over a
//! segment. A kink at x_k is one column more beside the rule's spring: the torque of a unit step
//! of stiffness outwards of x_k, (x − x_k) beyond it and 0 inside, its coefficient the step, of
//! either sign. (Pairs of knots close together were tried first: they can make a local bump of
//! stiffness as well as a step, and named softening steps on the simulator's catalogue gear
//! where its stiffening kink lay a little away, at A = 1.1 and 2.2 mrad.) The steps are tried at
//! every point of a grid of [`KINK_GRID`] a side (one pass over a subsample for the normal
//! equations of them all, each trial a selection of its columns), and the best few by their fit
//! are tried in turn for one that drops the information criterion and is a kink, not something
//! else a step can take up:
//! - **not a gradual change:** it fits better than the same change of stiffness spread linearly
//!   over [`WIDE`] times the scan's resolution around it (curvature that the rule's segments
//!   miss fits as well spread; on the measured spring's 4 and 5 A runs the best steps do not);
//! - **the same on both branches:** a step of its own on the rising branch alone does not fit
//!   better. A spring's step is at one deflection on every branch; a misfit of the hysteresis,
//!   or the deflection error of coarse encoders, is not (the slip elements' stiffness changes at
//!   fixed distances from each reversal).
use super::*;

/// Points a side's kinks may sit at: the side's extent in this many steps.
const KINK_GRID: usize = 32;
/// Samples the scan runs on, spread over the recording (the spring's shape needs no more: on
/// the OpenSees catalogue gear its kinks at 8192 samples drop the criterion by thousands).
const KINK_SAMPLES: usize = 1 << 13;
/// The most kinks searched for: two a side, the catalogue's three segments.
pub const MAX_KINKS: usize = 4;
/// Candidates tried a round, best first, for one that is a kink.
const TRIED_PER_ROUND: usize = 8;
/// What a kink costs the information criterion: its step and where it is.
pub const KINK_PARAMETERS: usize = 2;
/// How much wider than the scan's resolution the gradual change a kink is tested against is:
/// a step must fit better sharp than spread over four times that.
pub const WIDE: f64 = 4.0;

/// A step of the spring's stiffness at one deflection.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Kink {
    /// Where it is, x = θ − θ0, rad.
    pub at_rad: f64,
    /// The spring's stiffness just inside it (towards x = 0), N·m/rad.
    pub inner_nm_per_rad: f64,
    /// The spring's stiffness just outside it, N·m/rad.
    pub outer_nm_per_rad: f64,
    /// The drop of the information criterion when it was added to the kinks before it.
    pub delta_bic: f64,
    /// How much better it fits than the same change spread over [`WIDE`] times the scan's
    /// resolution in its place: the drop of χ² in units of the residual's variance, at the same
    /// count of parameters. `None` where the spread change does not fit inside the range.
    pub sharpness: Option<f64>,
    /// How much better the step fits when it may differ between the rising and the falling
    /// branches (χ² in units of the residual's variance, one parameter more): a spring's step is
    /// the same on both, a misfit of the hysteresis is not. `None` where that fit fails.
    pub branches: Option<f64>,
    /// How much the spring's stiffness changes across it, outwards, from a spread width inside
    /// to one outside (N·m/rad): a kink's step is that change, not a wiggle that the rule's
    /// neighbouring segments undo.
    pub across_nm_per_rad: f64,
}

impl Kink {
    /// The step of stiffness outwards, outer − inner, N·m/rad: above 0 where the spring
    /// stiffens past the kink. (The stiffness on each side is the spring's share: slip elements
    /// wider than the motion stand in for a spring, so the share is not identified, the step is.)
    pub fn step_nm_per_rad(&self) -> f64 {
        self.outer_nm_per_rad - self.inner_nm_per_rad
    }

    /// Whether the stiffness across it changes the way its step does, by at least half of it.
    /// (On the simulator's catalogue gear a softening step at one of the rule's knots, the
    /// segment before it rising steeply, fitted as well as the stiffening kink between the
    /// knots; across both the stiffness rises by the catalogue's step.)
    pub fn steps_across(&self) -> bool {
        let step = self.step_nm_per_rad();
        self.across_nm_per_rad * step.signum() >= 0.5 * step.abs()
    }
}

/// What [`scan_kinks`] found.
#[derive(Clone, Debug)]
pub struct KinkScan {
    /// The kinks added, in order, the stiffnesses those of the fit with all of them.
    pub kinks: Vec<Kink>,
    /// The best kink the tests refused after them (none where no step could be tried).
    pub refused: Option<Kink>,
    /// The scan's resolution: the grid's step, or 10σθ where wider, rad.
    pub resolution_rad: f64,
    /// The subsample's fitted samples (weight > 0).
    pub samples: usize,
    /// The weighted residual sum of squares on the subsample, the rule's spring alone and with
    /// the kinks (the weights as given).
    pub chi2: [f64; 2],
    /// Columns solved for, without and with the kinks.
    pub parameters: [usize; 2],
    /// Each part's steps at the kinks (N·m/rad), fitted on that part alone; `None` where a part
    /// cannot be fitted alone.
    pub parts: Vec<Option<Vec<f64>>>,
}

/// A column of stiffness changing outwards of x_k (by 1 N·m/rad per unit coefficient).
#[derive(Clone, Copy, Debug)]
enum Step {
    /// A step at x_k.
    Sharp(f64),
    /// The step spread linearly over a stretch of this width centred on x_k.
    Spread(f64, f64),
    /// A step at x_k on the rising branch only.
    Rising(f64),
}

impl Step {
    /// The column's torque at x_m carried `offset` along its slope, as the spring's rows are.
    fn value(self, at: Projected, rising: bool) -> f64 {
        let (x_k, width) = match self {
            Step::Sharp(x_k) => (x_k, 0.0),
            Step::Spread(x_k, width) => (x_k, width),
            Step::Rising(x_k) if rising => (x_k, 0.0),
            Step::Rising(_) => return 0.0,
        };
        // Distance outwards from x_k, so that both sides' steps are outwards.
        let (side, u) = (x_k.signum(), (at.theta_m - x_k) * x_k.signum());
        let half = 0.5 * width;
        let (torque, slope) = if u >= half {
            (u, 1.0)
        } else if u > -half {
            ((u + half).powi(2) / (2.0 * width), (u + half) / width)
        } else {
            (0.0, 0.0)
        };
        side * torque + slope * at.offset
    }
}

/// Scans the micro-slip form (its slip elements, and the free `extra` columns beside it, with a
/// torque offset too where `with_offset`) on the samples of one recording for kinks of its
/// spring, with the given weights on every sample (0: followed, not fitted); refits the kinks on
/// each of `parts` (sample indices, increasing) alone. A kink is added while it drops the
/// criterion by more than `min_bic_drop`, among those that step by at least `min_step` N·m/rad.
#[allow(clippy::too_many_arguments)]
pub fn scan_kinks(
    theta: &[f64],
    torque: &[f64],
    reversals: &Reversals,
    noise: NoiseModel,
    weights: &[f64],
    extra: &[&[f64]],
    with_offset: bool,
    parts: &[Vec<usize>],
    min_bic_drop: f64,
    min_step: f64,
) -> Result<KinkScan, FitError> {
    let motion = Motion::training_prefix(theta, torque, reversals, theta.len(), Some(noise));
    motion.check()?;
    let rule = motion.spring_basis();
    let [lo, hi] = rule.range();
    let mut sub = motion.subsample(KINK_SAMPLES);
    sub.reweigh(Weighting::Given(weights))?;
    // The extra columns gathered at the subsample's samples, numbered anew: the scan never
    // reads a column elsewhere, and a torque offset's column of ones along a recording of 2 M
    // samples would be 16 MB.
    let picked: Vec<usize> = sub.runs.iter().flatten().map(|sample| sample.index).collect();
    let mut gathered: Vec<Vec<f64>> =
        extra.iter().map(|column| picked.iter().map(|&i| column.get(i).copied().unwrap_or(0.0)).collect()).collect();
    if with_offset {
        gathered.push(vec![1.0; picked.len()]);
    }
    sub.runs.iter_mut().flatten().enumerate().for_each(|(k, sample)| sample.index = k);
    let extra: Vec<&[f64]> = gathered.iter().map(Vec::as_slice).collect();
    let (fitted, mean_weight) = sub
        .runs
        .iter()
        .flatten()
        .filter(|s| s.role == Role::Fitted)
        .fold((0usize, 0.0), |(n, w), s| (n + usize::from(s.weight > 0.0), w + s.weight));
    let count = sub.runs.iter().flatten().filter(|s| s.role == Role::Fitted).count();
    // The solves' RSS are in units of the weights' mean (`Normal::finish`).
    let unit = if count > 0 { mean_weight / count as f64 } else { 0.0 };
    let (columns, elements) = slip_columns(&motion, &rule, &extra, Source::Stored(&sub), Weighting::Carried)?;
    let scale = motion.scale();
    let n = fitted as f64;
    let variance = |rss: f64, parameters: usize| rss / (n - parameters as f64).max(1.0);
    // The candidates: the grid's points, clear of x = 0's first segment either side (a step
    // there is the two sides' difference, which `diagnose` tests as the asymmetry about a zero
    // read at rest; on the OpenSees asymmetric spring, whose stiffness steps at 0 by −24 %, a
    // step 0.04–0.07 mrad from 0 stood in for it with the other sign) and a resolution short of
    // the range's edges (a step needs samples beyond it).
    let resolution =
        (super::super::spring::PLACED_KNOT_GAP_IN_NOISE * motion.knot_noise()).max((-lo).max(hi) / KINK_GRID as f64);
    let knots = rule.knots();
    let zero = knots.iter().position(|&k| k == 0.0);
    let near_lo = zero.and_then(|z| z.checked_sub(1)).map_or(0.0, |j| knots[j]);
    let near_hi = zero.and_then(|z| knots.get(z + 1)).copied().unwrap_or(0.0);
    let places: Vec<f64> = fine_grid(&rule, KINK_GRID)
        .into_iter()
        .filter(|&x| x != 0.0 && (x <= near_lo || x >= near_hi) && x > lo + resolution && x < hi - resolution)
        .collect();
    let width = WIDE * resolution;
    let steps: Vec<Step> = places.iter().map(|&x| Step::Sharp(x)).collect();
    let base = columns.len();
    // The normal equations of the form's columns and the given steps beside them, on a
    // subsample (the direction of travel from the projected x_m, which is monotone on a leg).
    let equations_with = |sample_set: &Subsample, steps: &[Step]| -> Result<Equations, FitError> {
        normal_equations(Source::Stored(sample_set), base + steps.len(), Weighting::Carried, |run| {
            let mut all = StartedElements::new(&elements, run);
            let (mut last, mut rising) = (f64::NAN, true);
            let columns = &columns;
            Ok(move |sample: &Sample, x: &mut [f64]| {
                all.step(sample.at.theta_m)?;
                let m = sample.at.theta_m;
                if m > last {
                    rising = true;
                } else if m < last {
                    rising = false;
                }
                last = m;
                let (kind, stepped) = x.split_at_mut(base);
                columns.row(sample, |own| all.columns(sample.at.offset, scale, own), kind);
                for (value, step) in stepped.iter_mut().zip(steps) {
                    *value = step.value(sample.at, rising) / scale;
                }
                Ok(())
            })
        })
    };
    let bounded = rule.len() + elements.columns();
    let solve = |equations: &Equations, keep: &[usize]| -> Result<Solved, FitError> {
        let nonnegative: Vec<bool> = keep.iter().map(|&j| j < bounded).collect();
        equations.selected(keep).solve(&nonnegative)
    };
    let equations = equations_with(&sub, &steps)?;
    let sharp_column = |k: usize| base + k;
    // The spring's stiffness at x, with the steps at `positions` (in the solve's order after the
    // base columns) that lie inside x on its side.
    let stiffness_with = |solved: &Solved, positions: &[f64], x: f64| -> f64 {
        let (mut per_knot, mut stiffness) = (vec![0.0; knots.len()], vec![0.0; knots.len()]);
        model_core::spring::basis(knots, x, &mut per_knot, &mut stiffness);
        let spring: f64 = stiffness.iter().zip(&solved.coef).map(|(h, c)| h * c).sum::<f64>() / scale;
        let stepped: f64 = positions
            .iter()
            .enumerate()
            .filter(|&(_, &p)| p.signum() == x.signum() && x.abs() > p.abs())
            .map(|(j, _)| solved.coef[base + j] / scale)
            .sum();
        spring + stepped
    };
    let stiffness_inside = |solved: &Solved, kept: &[usize], x: f64| {
        stiffness_with(solved, &kept.iter().map(|&k| places[k]).collect::<Vec<_>>(), x)
    };
    // A kink found at a point of the grid, placed to a quarter of a grid step about it beside
    // the kinks `placed` before it (one pass over the subsample for the few places).
    let refined = |k: usize, placed: &[f64]| -> Result<f64, FitError> {
        let grid_step = if places[k] > 0.0 { hi } else { -lo } / KINK_GRID as f64;
        let trials: Vec<f64> = (-3..=3)
            .map(|j| places[k] + 0.25 * j as f64 * grid_step)
            .filter(|&x| x > lo + resolution && x < hi - resolution && x.signum() == places[k].signum())
            .collect();
        let steps: Vec<Step> = placed.iter().chain(&trials).map(|&x| Step::Sharp(x)).collect();
        let equations = equations_with(&sub, &steps)?;
        let fixed: Vec<usize> = (0..base + placed.len()).collect();
        let rss_at = |t: usize| {
            let keep: Vec<usize> = fixed.iter().copied().chain([base + placed.len() + t]).collect();
            solve(&equations, &keep).map_or(f64::INFINITY, |solved| solved.rss)
        };
        let best = (0..trials.len()).min_by(|&a, &b| rss_at(a).total_cmp(&rss_at(b)));
        Ok(best.map_or(places[k], |t| trials[t]))
    };
    let base_columns: Vec<usize> = (0..base).collect();
    let rule_solved = solve(&equations, &base_columns)?;
    let mut rss = rule_solved.rss;
    let mut kept: Vec<usize> = Vec::new();
    // Where each kink kept is placed, finer than the grid.
    let mut positions: Vec<f64> = Vec::new();
    let mut found: Vec<Kink> = Vec::new();
    let mut refused = None;
    while kept.len() < MAX_KINKS {
        let with = |extra_column: usize| -> Vec<usize> {
            base_columns.iter().copied().chain(kept.iter().map(|&k| sharp_column(k))).chain([extra_column]).collect()
        };
        let clear = |k: usize| kept.iter().all(|&j| (places[j] - places[k]).abs() > width);
        let mut candidates: Vec<(usize, Solved)> = (0..places.len())
            .filter(|&k| clear(k))
            .filter_map(|k| solve(&equations, &with(sharp_column(k))).ok().map(|solved| (k, solved)))
            .filter(|(_, solved)| (solved.coef.last().copied().unwrap_or(0.0) / scale).abs() >= min_step)
            .collect();
        candidates.sort_by(|a, b| a.1.rss.total_cmp(&b.1.rss));
        // The best candidates in turn, until one is a kink or they no longer drop the criterion:
        // the best by RSS may be a gradual change or a misfit, and a kink elsewhere still be found.
        let mut added = None;
        for (k, solved) in candidates.into_iter().take(TRIED_PER_ROUND) {
            let parameters = base + kept.len() + 1;
            let delta_bic = (rss - solved.rss) / variance(solved.rss, parameters) - KINK_PARAMETERS as f64 * n.ln();
            let x_k = places[k];
            let inner = stiffness_inside(&solved, &kept, x_k);
            // Against the same change spread over the wide stretch in its place (where that fits
            // inside the range), and with the step free to differ on the rising branch: one pass.
            let fits_inside = x_k.abs() - 0.5 * width > 0.0 && x_k + 0.5 * width < hi && x_k - 0.5 * width > lo;
            let mut trial: Vec<Step> = kept.iter().map(|&j| Step::Sharp(places[j])).collect();
            trial.extend([Step::Sharp(x_k), Step::Rising(x_k), Step::Spread(x_k, width)]);
            let (sharpness, branches) = match equations_with(&sub, &trial) {
                Ok(trial_equations) => {
                    let first = base + kept.len();
                    let with =
                        |columns: &[usize]| -> Vec<usize> { (0..first).chain(columns.iter().copied()).collect() };
                    let rss_of =
                        |columns: &[usize]| solve(&trial_equations, &with(columns)).ok().map(|solved| solved.rss);
                    let sharp = rss_of(&[first]);
                    let apart = rss_of(&[first, first + 1]);
                    let spread = if fits_inside { rss_of(&[first + 2]) } else { None };
                    let sharpness =
                        sharp.zip(spread).map(|(sharp, spread)| (spread - sharp) / variance(sharp, parameters));
                    let branches =
                        sharp.zip(apart).map(|(sharp, apart)| (sharp - apart) / variance(apart, parameters + 1));
                    (sharpness, branches)
                }
                Err(_) => (None, None),
            };
            // The spring's stiffness across it, a spread width either side, every step included.
            let with_it: Vec<usize> = kept.iter().copied().chain([k]).collect();
            let outwards = x_k.signum();
            let across = stiffness_inside(&solved, &with_it, x_k + outwards * width)
                - stiffness_inside(&solved, &with_it, x_k - outwards * width);
            let kink = Kink {
                at_rad: x_k,
                inner_nm_per_rad: inner,
                outer_nm_per_rad: inner + solved.coef.last().copied().unwrap_or(0.0) / scale,
                delta_bic,
                sharpness,
                branches,
                across_nm_per_rad: across,
            };
            if !(delta_bic > min_bic_drop) {
                refused = refused.or(Some(kink));
                break;
            }
            let sharp = sharpness.is_some_and(|s| s > min_bic_drop);
            let alike = branches.is_some_and(|b| b <= min_bic_drop);
            if sharp && alike && kink.steps_across() {
                added = Some((k, kink, solved.rss));
                break;
            }
            refused = refused.or(Some(kink));
        }
        let Some((k, kink, trial_rss)) = added else { break };
        positions.push(refined(k, &positions)?);
        kept.push(k);
        found.push(kink);
        refused = None;
        rss = trial_rss;
    }
    // The fit with every kink where it was placed, and the stiffnesses each side.
    let kinked: Vec<Step> = positions.iter().map(|&x| Step::Sharp(x)).collect();
    let final_equations = equations_with(&sub, &kinked)?;
    let final_solved = solve(&final_equations, &(0..base + kinked.len()).collect::<Vec<_>>())?;
    let step_of = |solved: &Solved, j: usize| solved.coef[base + j] / scale;
    let kinks: Vec<Kink> = found
        .iter()
        .zip(&positions)
        .enumerate()
        .map(|(j, (kink, &at_rad))| {
            let inner = stiffness_with(&final_solved, &positions, at_rad);
            Kink { at_rad, inner_nm_per_rad: inner, outer_nm_per_rad: inner + step_of(&final_solved, j), ..*kink }
        })
        .collect();
    let parts = if kept.is_empty() {
        Vec::new()
    } else {
        parts
            .iter()
            .map(|part| {
                let mut alone = sub.clone();
                for (sample, i) in alone.runs.iter_mut().flatten().zip(&picked) {
                    if part.binary_search(i).is_err() {
                        sample.weight = 0.0;
                    }
                }
                let equations = equations_with(&alone, &kinked).ok()?;
                let all: Vec<usize> = (0..base + kinked.len()).collect();
                let solved = solve(&equations, &all).ok()?;
                Some((0..kinked.len()).map(|j| step_of(&solved, j)).collect())
            })
            .collect()
    };
    Ok(KinkScan {
        kinks,
        refused,
        resolution_rad: resolution,
        samples: fitted,
        chi2: [unit * rule_solved.rss, unit * final_solved.rss],
        parameters: [base, base + kept.len()],
        parts,
    })
}
