//! The scan behind `diagnose`'s `stiffness_kinks`: where the micro-slip form's spring steps in
//! stiffness faster than the knot rule's spring can follow.
//!
//! The rule's spring is continuous and piecewise linear in stiffness, its knots at least 20σθ
//! apart (`fit::spring`): a step (a catalogue gear's kink at T1 and T2) is smeared over a
//! segment. A kink is a pair of knots 10σθ apart (or one grid step, whichever is wider) added to
//! the rule's, whose stiffness may differ by anything. The pairs are tried at every point of a
//! grid of [`KINK_GRID`] steps a side, as [`placed_knots`] places knots (one pass over a
//! subsample for the normal equations on the grid's knots, each trial mapped onto its own
//! knots), and the best that drops the information criterion and is a kink is added (the best
//! few by their fit are tried in turn), not something else a pair can take up:
//! - **not a gradual change:** it fits better than the best pair [`WIDE`] times as far apart
//!   around it (the curvature of a stiffening spring that the rule's segments miss fits as well
//!   spread);
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
/// What a kink costs the information criterion: the stiffness at its two knots, and where it is.
pub const KINK_PARAMETERS: usize = 3;
/// A kink's knots against a gradual change's, how many times as far apart: the step must fit
/// better sharp than spread over four times the stretch around it (the OpenSees catalogue
/// gear's kinks by 21–141 times the residual's variance; on the simulator's micro-slip gear,
/// whose cubic spring stiffens from 9000 to 60000 N·m/rad at 1.24 mrad, a step there fits worse
/// sharp by 15).
pub const WIDE: f64 = 4.0;

/// A step of the spring's stiffness between two knots close together.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Kink {
    /// Where it is: the middle of its two knots, x = θ − θ0, rad.
    pub at_rad: f64,
    /// Its knots, the one nearer x = 0 first, rad.
    pub knots_rad: [f64; 2],
    /// The spring's stiffness at the knot nearer x = 0, N·m/rad.
    pub inner_nm_per_rad: f64,
    /// The spring's stiffness at the other knot, N·m/rad.
    pub outer_nm_per_rad: f64,
    /// The drop of the information criterion when it was added to the kinks before it.
    pub delta_bic: f64,
    /// How much better it fits than the best pair [`WIDE`] times as far apart around it, added
    /// in its place: the drop of χ² in units of the residual's variance, at the same count of
    /// parameters. A kink fits better than a gradual change; curvature, or a misfit of the slip
    /// elements that a change of stiffness can take up, fits as well or better gradually. `None`
    /// where no such pair fits beside it.
    pub sharpness: Option<f64>,
    /// How much better the step fits when it may differ between the rising and the falling
    /// branches (χ² in units of the residual's variance, one parameter more): a spring's step is
    /// the same on both, a misfit of the hysteresis is not. `None` where that fit fails.
    pub branches: Option<f64>,
}

impl Kink {
    /// The step of stiffness outwards, outer − inner, N·m/rad: above 0 where the spring
    /// stiffens past the kink. (The stiffness on each side is the spring's share: slip elements
    /// wider than the motion stand in for a spring, so the share is not identified, the step is.)
    pub fn step_nm_per_rad(&self) -> f64 {
        self.outer_nm_per_rad - self.inner_nm_per_rad
    }
}

/// What [`scan_kinks`] found.
#[derive(Clone, Debug)]
pub struct KinkScan {
    /// The kinks added, in order, the stiffnesses those of the fit with all of them.
    pub kinks: Vec<Kink>,
    /// The best kink the criterion refused after them (none where no pair could be tried).
    pub refused: Option<Kink>,
    /// The subsample's fitted samples (weight > 0).
    pub samples: usize,
    /// The weighted residual sum of squares on the subsample, the rule's spring alone and with
    /// the kinks (the weights as given).
    pub chi2: [f64; 2],
    /// Columns solved for, without and with the kinks.
    pub parameters: [usize; 2],
    /// Each part's steps at the kinks' knots (N·m/rad), fitted on that part alone; `None` where a
    /// part cannot be fitted alone.
    pub parts: Vec<Option<Vec<f64>>>,
}

/// Scans the micro-slip form (its slip elements, and the free `extra` columns beside it, with a
/// torque offset too where `with_offset`) on the samples of one recording for kinks of its
/// spring, with the given weights on every sample (0: followed, not fitted); refits the kinks on
/// each of `parts` (sample indices, increasing) alone. A kink is added while it drops the criterion by more
/// than `min_bic_drop`, among those that step by at least `min_step` N·m/rad.
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
    let extra = extra.as_slice();
    let (fitted, mean_weight) = sub
        .runs
        .iter()
        .flatten()
        .filter(|s| s.role == Role::Fitted)
        .fold((0usize, 0.0), |(n, w), s| (n + usize::from(s.weight > 0.0), w + s.weight));
    let count = sub.runs.iter().flatten().filter(|s| s.role == Role::Fitted).count();
    // The solves' RSS are in units of the weights' mean (`Normal::finish`).
    let unit = if count > 0 { mean_weight / count as f64 } else { 0.0 };
    let (_, elements) = slip_columns(&motion, &rule, extra, Source::Stored(&sub), Weighting::Carried)?;
    let fine = fine_grid(&rule, KINK_GRID);
    let fine_basis = rule.with_knots(fine.clone());
    fn columns<'a>(
        spring: &'a SpringBasis,
        motion: &Motion,
        elements: &Elements,
        extra: &'a [&'a [f64]],
    ) -> Columns<'a> {
        Columns { spring, own: vec![true; elements.columns()], extra, scale: motion.scale() }
    }
    let stiffness_at = |knots: &[f64], solved: &Solved, x: f64| {
        knots.iter().position(|&k| k == x).map_or(f64::NAN, |j| solved.coef[j] / motion.scale())
    };
    let n = fitted as f64;
    let variance = |rss: f64, parameters: usize| rss / (n - parameters as f64).max(1.0);
    // Pairs: a point of the grid and the first one at least the gap further out, on one side,
    // clear of x = 0 and of the edge's segment (its stiffness is the one the spring extrapolates
    // with, as `placed_knots` keeps it).
    let gap =
        (super::super::spring::PLACED_KNOT_GAP_IN_NOISE * motion.knot_noise()).max(lo.abs().max(hi) / KINK_GRID as f64);
    let knots = rule.knots();
    let edge_lo = knots.get(1).map_or(lo, |&k1| knots[0] + EDGE_SEGMENT * (k1 - knots[0]));
    let edge_hi = knots.len().checked_sub(2).map_or(hi, |j| knots[j + 1] - EDGE_SEGMENT * (knots[j + 1] - knots[j]));
    // Nor in the rule's first segment either side of x = 0: a step there is the two sides'
    // difference, which `diagnose` tests as the asymmetry, about a zero read at rest (on the
    // OpenSees asymmetric spring, whose stiffness steps at 0 by −24 %, a pair 0.04–0.07 mrad
    // from 0 stood in for it with a step of the other sign).
    let zero = knots.iter().position(|&k| k == 0.0);
    let near_lo = zero.and_then(|z| z.checked_sub(1)).map_or(0.0, |j| knots[j]);
    let near_hi = zero.and_then(|z| knots.get(z + 1)).copied().unwrap_or(0.0);
    let pairs_apart = |spacing: f64| -> Vec<[f64; 2]> {
        let mut pairs = Vec::new();
        for &inner in fine.iter().filter(|&&x| x != 0.0 && (x <= near_lo || x >= near_hi)) {
            let outward = inner.signum();
            let outer = fine
                .iter()
                .copied()
                .filter(|&x| x * outward >= inner.abs() + spacing * (1.0 - 1e-12))
                .min_by(|a, b| a.abs().total_cmp(&b.abs()));
            if let Some(outer) = outer.filter(|&x| x > edge_lo && x < edge_hi && x.signum() == outward) {
                pairs.push([inner, outer]);
            }
        }
        pairs
    };
    let (pairs, wide_pairs) = (pairs_apart(gap), pairs_apart(WIDE * gap));
    let fine_columns = columns(&fine_basis, &motion, &elements, extra);
    let equations = slip_equations(Source::Stored(&sub), Weighting::Carried, &fine_columns, &elements)?;
    let solve = |knots: &[f64]| -> Result<Solved, FitError> {
        let trial = rule.with_knots(knots.to_vec());
        columns(&trial, &motion, &elements, extra).solve(&equations.mapped(&fine, knots, fine_columns.len()))
    };
    // The drop of χ², in units of the variance, when the step at `at` on the knots `knots` may
    // differ between the rising and the falling branches (a further column: a step of stiffness
    // outwards of `at` on the rising samples alone). A spring's step is the same on both.
    let branches_differ = |knots: &[f64], at: f64, parameters: usize| -> Result<f64, FitError> {
        let trial = rule.with_knots(knots.to_vec());
        let kinked = columns(&trial, &motion, &elements, extra);
        let scale = motion.scale();
        let split = normal_equations(Source::Stored(&sub), kinked.len() + 1, Weighting::Carried, |run| {
            let mut all = StartedElements::new(&elements, run);
            let (mut last, mut rising) = (f64::NAN, true);
            let kinked = &kinked;
            Ok(move |sample: &Sample, x: &mut [f64]| {
                all.step(sample.at.theta_m)?;
                let m = sample.at.theta_m;
                if m > last {
                    rising = true;
                } else if m < last {
                    rising = false;
                }
                last = m;
                let (kind, step) = x.split_at_mut(kinked.len());
                kinked.row(sample, |own| all.columns(sample.at.offset, scale, own), kind);
                let beyond = (m - at) * at.signum() > 0.0;
                step[0] = if rising && beyond { (m - at + sample.at.offset) / scale } else { 0.0 };
                Ok(())
            })
        })?;
        let bounded = knots.len() + elements.columns();
        let nonnegative: Vec<bool> = (0..kinked.len() + 1).map(|j| j < bounded).collect();
        let alike = split.selected(&(0..kinked.len()).collect::<Vec<_>>()).solve(&nonnegative[..kinked.len()])?;
        let apart = split.solve(&nonnegative)?;
        Ok((alike.rss - apart.rss) / variance(apart.rss, parameters + 1))
    };
    let mut current: Vec<f64> = knots.to_vec();
    let rule_solved = solve(&current)?;
    let parameters_rule = current.len() + elements.columns() + extra.len();
    let mut rss = rule_solved.rss;
    // Each kink added, with the tests of the round that added it.
    let mut kinks: Vec<Kink> = Vec::new();
    let mut refused = None;
    while kinks.len() < MAX_KINKS {
        let free = |p: &&[f64; 2]| !kinks.iter().any(|k| overlaps(&k.knots_rad, p));
        let trial_of = |pair: &[f64; 2]| -> Option<(Vec<f64>, Solved)> {
            let mut trial = current.clone();
            trial.extend_from_slice(pair);
            trial.sort_by(f64::total_cmp);
            trial.dedup();
            solve(&trial).ok().map(|solved| (trial, solved))
        };
        let wide: Vec<([f64; 2], f64)> =
            wide_pairs.iter().filter(free).filter_map(|p| trial_of(p).map(|(_, solved)| (*p, solved.rss))).collect();
        let mut candidates: Vec<([f64; 2], Vec<f64>, Solved)> = pairs
            .iter()
            .filter(free)
            .filter_map(|p| trial_of(p).map(|(trial, solved)| (*p, trial, solved)))
            .filter(|(p, trial, solved)| {
                (stiffness_at(trial, solved, p[1]) - stiffness_at(trial, solved, p[0])).abs() >= min_step
            })
            .collect();
        candidates.sort_by(|a, b| a.2.rss.total_cmp(&b.2.rss));
        // The best candidates in turn, until one is a kink or they no longer drop the criterion:
        // the best by RSS may be a gradual change or a misfit, and a kink elsewhere still be found.
        let mut added = None;
        for (pair, trial, solved) in candidates.into_iter().take(TRIED_PER_ROUND) {
            let parameters = trial.len() + elements.columns() + extra.len();
            let trial_rss = solved.rss;
            let delta_bic = (rss - trial_rss) / variance(trial_rss, parameters) - KINK_PARAMETERS as f64 * n.ln();
            let at = 0.5 * (pair[0] + pair[1]);
            // Against the same change spread over the wide pairs around it; None where no wide
            // pair fits there (a short side): then it cannot be told from a gradual change.
            let spread =
                wide.iter().filter(|(w, _)| overlaps(w, &pair)).map(|(_, rss)| *rss).fold(f64::INFINITY, f64::min);
            let sharpness = spread.is_finite().then(|| (spread - trial_rss) / variance(trial_rss, parameters));
            let branches = branches_differ(&trial, at, parameters).ok();
            let kink = Kink {
                at_rad: at,
                knots_rad: pair,
                inner_nm_per_rad: stiffness_at(&trial, &solved, pair[0]),
                outer_nm_per_rad: stiffness_at(&trial, &solved, pair[1]),
                delta_bic,
                sharpness,
                branches,
            };
            if !(delta_bic > min_bic_drop) {
                refused = refused.or(Some(kink));
                break;
            }
            let sharp = sharpness.is_some_and(|s| s > min_bic_drop);
            let alike = branches.is_some_and(|b| b <= min_bic_drop);
            if sharp && alike {
                added = Some((kink, trial, trial_rss));
                break;
            }
            refused = refused.or(Some(kink));
        }
        let Some((kink, trial, trial_rss)) = added else { break };
        kinks.push(kink);
        refused = None;
        current = trial;
        rss = trial_rss;
    }
    // The stiffnesses of the fit with every kink.
    let final_solved = solve(&current)?;
    let final_basis = rule.with_knots(current.clone());
    let found: Vec<Kink> = kinks
        .iter()
        .map(|kink| Kink {
            inner_nm_per_rad: stiffness_at(&current, &final_solved, kink.knots_rad[0]),
            outer_nm_per_rad: stiffness_at(&current, &final_solved, kink.knots_rad[1]),
            ..*kink
        })
        .collect();
    let parameters_kinked = current.len() + elements.columns() + extra.len();
    let parts = if kinks.is_empty() {
        Vec::new()
    } else {
        let kinked_columns = columns(&final_basis, &motion, &elements, extra);
        parts
            .iter()
            .map(|part| {
                let mut alone = sub.clone();
                for (sample, i) in alone.runs.iter_mut().flatten().zip(&picked) {
                    if part.binary_search(i).is_err() {
                        sample.weight = 0.0;
                    }
                }
                let equations =
                    slip_equations(Source::Stored(&alone), Weighting::Carried, &kinked_columns, &elements).ok()?;
                let solved = kinked_columns.solve(&equations).ok()?;
                Some(
                    kinks
                        .iter()
                        .map(|k| {
                            stiffness_at(&current, &solved, k.knots_rad[1])
                                - stiffness_at(&current, &solved, k.knots_rad[0])
                        })
                        .collect(),
                )
            })
            .collect()
    };
    Ok(KinkScan {
        kinks: found,
        refused,
        samples: fitted,
        chi2: [unit * rule_solved.rss, unit * final_solved.rss],
        parameters: [parameters_rule, parameters_kinked],
        parts,
    })
}

/// Whether two pairs of knots share a stretch.
fn overlaps(a: &[f64; 2], b: &[f64; 2]) -> bool {
    let span = |p: &[f64; 2]| (p[0].min(p[1]), p[0].max(p[1]));
    let ((a0, a1), (b0, b1)) = (span(a), span(b));
    a0 <= b1 && b0 <= a1
}
