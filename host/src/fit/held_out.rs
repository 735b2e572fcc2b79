//! Which samples `fit --model auto` holds out of the fits that choose the kind. Never the last
//! quarter in time: a gear warms and a sensor drifts over a recording, so the last quarter
//! would judge the kinds on how they extrapolate the drift, not on how well they model the gear.
//!
//! - **Several runs** (three or more): every run held out once. The run of the largest
//!   amplitude (half the range of its scored deflection) by its interleaved cycles, as one run
//!   alone (below), in a fold of its own that fits every other run whole: held out whole, it
//!   would lie beyond the range the fit spans and judge the kinds on their extrapolation, which
//!   the model refitted on every run is never asked for (micro-slip runs at 0.4–1.2 mrad: the
//!   largest held out whole made the held-out RMS 16× the training RMS and chose the genetic
//!   kind). The others whole: sorted by amplitude (ties in the order given), dealt into
//!   min(R − 1, [`MAX_RUN_FOLDS`]) folds, fold j holding out ranks j, j + F, j + 2F, …. Every
//!   kind is fitted once per fold and judged on the held-out errors of all folds pooled.
//!   The smallest amplitude is held out too: a kind that stands in for the spring with its
//!   hysteresis, or that is not Masing where the gear is, loses there. (One interior run held
//!   out ranked the kinds on the measured spring unlike the other runs: `bash bench/real.sh`,
//!   table 5.)
//! - **One or two runs**: one fold of interleaved cycles. Each run's cycles run from one maximum
//!   (turning point) to the next; every fourth cycle, the 2nd, 6th, 10th, …, is held out, so the
//!   held-out samples are spread over the whole run, except a cycle inside which the run reaches
//!   its largest or smallest deflection beyond the rest of it (the fit must span the range it is
//!   judged on). A run of fewer than two whole cycles holds out its legs (turning point to
//!   turning point) by the same rule; a run of one cycle (two turning
//!   points: up, down, back, as a bench's ramp cycle from rest) counts its first rise and its
//!   return as legs too, and holds out its middle leg.
use super::motion::Span;
use crate::gear::Reversals;

/// Every how many cycles one is held out of a run.
pub const CYCLE_PERIOD: usize = 4;
/// Which cycle of each period is held out (0-based): the second, so that a short recording's
/// held-out cycle is neither its first nor its last.
pub const CYCLE_HELD_OUT: usize = 1;
/// Runs from which whole runs are held out; fewer hold out cycles.
pub const MIN_RUNS_TO_HOLD_OUT: usize = 3;
/// The most folds of whole runs: each fold costs one fit of every kind.
pub const MAX_RUN_FOLDS: usize = 4;

/// What a run looks like to the rule.
#[derive(Clone, Copy, Debug)]
pub struct RunShape<'a> {
    pub theta: &'a [f64],
    pub reversals: &'a Reversals,
    /// The first sample scored.
    pub scored_from: usize,
}

/// How the held-out samples were chosen.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum HeldOutRule {
    /// Whole runs, each but the largest held out in one of these folds (each fold: run indices
    /// in the order given, increasing); the largest run (its index) holds out its cycles in
    /// one more fold.
    Runs { whole: Vec<Vec<usize>>, largest: usize },
    /// Every [`CYCLE_PERIOD`]th cycle between consecutive maxima of each run.
    Cycles,
}

impl HeldOutRule {
    /// The rule in words, for reports.
    pub fn describe(&self) -> String {
        match self {
            HeldOutRule::Runs { whole, .. } => format!(
                "every run once: all but the largest whole, in {} folds dealt by amplitude, and the largest by its \
                 interleaved cycles in one more; every kind fitted once per fold and judged on all folds pooled",
                whole.len()
            ),
            HeldOutRule::Cycles => format!(
                "interleaved cycles: the {} of every {CYCLE_PERIOD} between consecutive maxima of each run, or of \
                 its legs in a run of fewer than two cycles",
                ["1st", "2nd", "3rd", "4th"][CYCLE_HELD_OUT]
            ),
        }
    }
}

/// One fit's scored spans of each run, fitted or held out.
pub type Fold = Vec<Vec<Span>>;

/// The folds (every held-out sample is held out in exactly one), and the rule that chose them.
pub fn hold_out(runs: &[RunShape<'_>]) -> (Vec<Fold>, HeldOutRule) {
    if runs.len() >= MIN_RUNS_TO_HOLD_OUT {
        let (whole, largest) = run_folds(runs);
        let whole_run =
            |run: &RunShape<'_>, held_out: bool| vec![Span { range: run.scored_from..run.theta.len(), held_out }];
        let mut folds: Vec<Fold> = whole
            .iter()
            .map(|held| runs.iter().enumerate().map(|(k, run)| whole_run(run, held.contains(&k))).collect())
            .collect();
        folds.push(
            runs.iter()
                .enumerate()
                .map(|(k, run)| if k == largest { held_out_cycles(run) } else { whole_run(run, false) })
                .collect(),
        );
        (folds, HeldOutRule::Runs { whole, largest })
    } else {
        (vec![runs.iter().map(held_out_cycles).collect()], HeldOutRule::Cycles)
    }
}

/// Half the range of a run's scored deflection, rad.
fn amplitude(run: &RunShape<'_>) -> f64 {
    let scored = run.theta.get(run.scored_from..).unwrap_or(&[]);
    let (lo, hi) = scored.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    if hi >= lo {
        (hi - lo) / 2.0
    } else {
        0.0
    }
}

/// The runs each fold holds out whole (indices, increasing): the runs by amplitude but the
/// largest, dealt into min(R − 1, [`MAX_RUN_FOLDS`]) folds so that each fold spans the
/// amplitudes; and the largest run.
fn run_folds(runs: &[RunShape<'_>]) -> (Vec<Vec<usize>>, usize) {
    let mut by_amplitude: Vec<usize> = (0..runs.len()).collect();
    by_amplitude.sort_by(|&a, &b| amplitude(&runs[a]).total_cmp(&amplitude(&runs[b])));
    let largest = by_amplitude.pop().unwrap_or(0);
    let count = by_amplitude.len().min(MAX_RUN_FOLDS);
    let whole = (0..count)
        .map(|fold| {
            let mut held: Vec<usize> = by_amplitude.iter().copied().skip(fold).step_by(count).collect();
            held.sort_unstable();
            held
        })
        .collect();
    (whole, largest)
}

/// A run's scored samples split at its maxima, every [`CYCLE_PERIOD`]th cycle held out; split
/// at every turning point (legs) when that holds out nothing, and at its start and end too
/// when that still holds out nothing.
fn held_out_cycles(run: &RunShape<'_>) -> Vec<Span> {
    let maxima: Vec<usize> = run.reversals.maxima().collect();
    let turns = &run.reversals.indices;
    let ends: Vec<usize> =
        std::iter::once(0).chain(turns.iter().copied()).chain(std::iter::once(run.theta.len())).collect();
    let extremes = Extremes::of(run);
    let spans = [maxima.as_slice(), turns, &ends]
        .into_iter()
        .map(|bounds| every_fourth(run, bounds, extremes.as_ref()))
        .find(|spans| spans.iter().any(|s| s.held_out))
        .unwrap_or_else(|| every_fourth(run, &maxima, extremes.as_ref()));
    spans
}

/// A run's scored samples split at `bounds` (increasing), every [`CYCLE_PERIOD`]th piece
/// between two of them held out, unless it holds one of the run's `extremes` beyond the rest of
/// the run ([`Extremes::held_by`]): the fit must span the range it is judged on. (A random motion's widest cycle,
/// held out, judges the kinds on their extrapolation: with `diagnose`'s form check held out
/// this way, micro-slip's held-out error on a micro-slip gear came out worse than the genetic
/// form's, 0.65 against 0.45 N·m, corpus seed 1000, case 1039.)
fn every_fourth(run: &RunShape<'_>, bounds: &[usize], extremes: Option<&Extremes>) -> Vec<Span> {
    let n = run.theta.len();
    let spans_an_extreme = |start: usize, end: usize| extremes.is_some_and(|e| e.held_by(run, start, end));
    let mut spans = Vec::new();
    let mut push = |range: std::ops::Range<usize>, held_out: bool| {
        let range = range.start.max(run.scored_from)..range.end;
        if range.is_empty() {
            return;
        }
        match spans.last_mut() {
            Some(Span { range: last, held_out: same }) if *same == held_out && last.end == range.start => {
                last.end = range.end;
            }
            _ => spans.push(Span { range, held_out }),
        }
    };
    push(0..bounds.first().copied().unwrap_or(n), false);
    for (k, pair) in bounds.windows(2).enumerate() {
        push(pair[0]..pair[1], k % CYCLE_PERIOD == CYCLE_HELD_OUT && !spans_an_extreme(pair[0], pair[1]));
    }
    push(bounds.last().copied().unwrap_or(n)..n, false);
    spans
}

/// Whether a piece reaches beyond the rest of the run's scored deflection by more than this
/// share of its range: noise at a rest end is no extreme to protect.
const EXTREME_MARGIN: f64 = 0.01;

/// A run's smallest and largest scored deflection, (index, rad) each, and its range, rad.
struct Extremes {
    lowest: (usize, f64),
    highest: (usize, f64),
    range: f64,
}

impl Extremes {
    /// None when nothing is scored.
    fn of(run: &RunShape<'_>) -> Option<Extremes> {
        let scored = run.theta.get(run.scored_from..).unwrap_or(&[]);
        let arg = |better: fn(f64, f64) -> bool| {
            scored.iter().enumerate().fold(None, |best: Option<(usize, f64)>, (i, &t)| match best {
                Some((_, b)) if !better(t, b) => best,
                _ => Some((run.scored_from + i, t)),
            })
        };
        let (lowest, highest) = (arg(|t, b| t < b)?, arg(|t, b| t > b)?);
        Some(Extremes { lowest, highest, range: highest.1 - lowest.1 })
    }

    /// Whether the piece `start..end` holds an extreme strictly inside (not at a turning point
    /// that bounds it) that the rest of the run falls short of by more than [`EXTREME_MARGIN`]
    /// of the range.
    fn held_by(&self, run: &RunShape<'_>, start: usize, end: usize) -> bool {
        let rest = |pick: fn(f64, f64) -> f64| {
            let before = run.theta.get(run.scored_from..start).unwrap_or(&[]);
            before.iter().chain(run.theta.get(end..).unwrap_or(&[])).copied().reduce(pick)
        };
        let margin = EXTREME_MARGIN * self.range;
        let inside = |(i, _): (usize, f64)| start < i && i < end;
        (inside(self.lowest) && rest(f64::min).is_none_or(|r| self.lowest.1 < r - margin))
            || (inside(self.highest) && rest(f64::max).is_none_or(|r| self.highest.1 > r + margin))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(cycles: usize, amplitude: f64) -> Vec<f64> {
        (0..cycles * 1000).map(|i| amplitude * (std::f64::consts::TAU * i as f64 / 1000.0).sin()).collect()
    }

    fn shape<'a>(theta: &'a [f64], reversals: &'a Reversals) -> RunShape<'a> {
        RunShape { theta, reversals, scored_from: 0 }
    }

    #[test]
    fn one_run_holds_out_every_fourth_cycle_spread_over_the_run_not_its_last_quarter() {
        let theta = sine(12, 1e-3);
        let reversals = crate::prepare::reversals(&theta);
        let (folds, rule) = hold_out(&[shape(&theta, &reversals)]);
        assert_eq!(rule, HeldOutRule::Cycles);
        let spans = &folds[0];
        let held: Vec<&Span> = spans[0].iter().filter(|s| s.held_out).collect();
        // Maxima at 250, 1250, …, 11250: cycles 1, 5, 9 of the 11 between them.
        assert_eq!(held.len(), 3, "{spans:?}");
        assert_eq!(held[0].range, 1250..2250);
        let held_samples: usize = held.iter().map(|s| s.range.len()).sum();
        let in_last_quarter: usize = held.iter().map(|s| s.range.end.saturating_sub(s.range.start.max(9000))).sum();
        assert!(in_last_quarter < held_samples / 2, "{held:?}");
        // Every sample is in exactly one span, in order.
        assert_eq!(spans[0].first().unwrap().range.start, 0);
        assert_eq!(spans[0].last().unwrap().range.end, theta.len());
        assert!(spans[0].windows(2).all(|w| w[0].range.end == w[1].range.start && w[0].held_out != w[1].held_out));
    }

    #[test]
    fn the_cycle_that_reaches_the_widest_deflection_is_fitted_not_held_out() {
        // Cycle 1 (between the 2nd and 3rd maxima), the one a run holds out first, dips to
        // −2 mrad where every other cycle turns at −1: held out, the fit would not span it.
        let mut theta = sine(12, 1e-3);
        theta[1250..2250].iter_mut().for_each(|t| *t = t.min(0.0) * 2.0 + t.max(0.0));
        let reversals = crate::prepare::reversals(&theta);
        let spans = held_out_cycles(&shape(&theta, &reversals));
        let held: Vec<&Span> = spans.iter().filter(|s| s.held_out).collect();
        assert!(held.iter().all(|s| !s.range.contains(&1750)), "{spans:?}");
        // Cycles 5 and 9 still held out.
        assert_eq!(held.iter().map(|s| s.range.clone()).collect::<Vec<_>>(), [5250..6250, 9250..10250]);
    }

    #[test]
    fn a_return_to_rest_whose_noise_dips_below_the_start_is_still_held_out() {
        // Up to 1 mrad and back to rest, the last sample 10⁻⁹ rad below the first: the return
        // leg holds the run's smallest deflection, by noise, not by reaching beyond the rest.
        let mut theta: Vec<f64> = (0..=2000).map(|i| 1e-3 * (std::f64::consts::PI * i as f64 / 2000.0).sin()).collect();
        *theta.last_mut().unwrap() = -1e-9;
        let reversals = crate::prepare::reversals(&theta);
        let spans = held_out_cycles(&shape(&theta, &reversals));
        let held: Vec<&Span> = spans.iter().filter(|s| s.held_out).collect();
        assert_eq!(held.len(), 1, "{spans:?}");
        assert_eq!(held[0].range.end, theta.len());
    }

    #[test]
    fn samples_before_the_scored_start_are_in_no_span() {
        let theta = sine(8, 1e-3);
        let reversals = crate::prepare::reversals(&theta);
        let run = RunShape { theta: &theta, reversals: &reversals, scored_from: 1500 };
        let spans = &hold_out(&[run]).0[0];
        assert_eq!(spans[0][0].range.start, 1500);
        assert!(spans[0].iter().all(|s| s.range.start >= 1500));
    }

    #[test]
    fn several_runs_are_each_held_out_once_whole_in_folds_dealt_by_amplitude_the_largest_by_its_cycles() {
        for count in 3..=12 {
            // Amplitudes given out of order: 1, 12, 2, 11, 3, 10, … mrad.
            let amplitudes: Vec<f64> =
                (0..count).map(|k| if k % 2 == 0 { 1 + k / 2 } else { count - k / 2 } as f64 * 1e-3).collect();
            let thetas: Vec<Vec<f64>> = amplitudes.iter().map(|&a| sine(3, a)).collect();
            let reversals: Vec<Reversals> = thetas.iter().map(|t| crate::prepare::reversals(t)).collect();
            let shapes: Vec<RunShape> = thetas.iter().zip(&reversals).map(|(t, r)| shape(t, r)).collect();
            let (folds, rule) = hold_out(&shapes);
            let HeldOutRule::Runs { whole: held, largest } = rule else { panic!("{count} runs: whole runs") };
            assert_eq!(held.len(), (count - 1).min(MAX_RUN_FOLDS), "{count} runs");
            assert_eq!(folds.len(), held.len() + 1);
            let mut by_amplitude: Vec<usize> = (0..count).collect();
            by_amplitude.sort_by(|&a, &b| amplitudes[a].total_cmp(&amplitudes[b]));
            assert_eq!(by_amplitude.pop(), Some(largest));
            // Each run but the largest held out whole in exactly one fold, fitted in the others.
            for k in (0..count).filter(|&k| k != largest) {
                let holding = (0..folds.len()).filter(|&f| folds[f][k][0].held_out).count();
                assert_eq!(holding, 1, "{count} runs, run {k}: {held:?}");
                assert!(folds.iter().all(|fold| fold[k].len() == 1 && fold[k][0].range == (0..thetas[k].len())));
            }
            // Dealt by amplitude: fold j holds out the (j+1)-th smallest amplitude, and no fold
            // holds out two runs of neighbouring amplitude ranks.
            for (j, fold) in held.iter().enumerate() {
                assert!(fold.contains(&by_amplitude[j]), "{count} runs: {held:?}");
                assert!(by_amplitude.windows(2).all(|w| !(fold.contains(&w[0]) && fold.contains(&w[1]))));
                assert!(fold.iter().all(|&k| folds[j][k][0].held_out));
            }
            // The largest: its cycles, in the last fold, which fits every other run whole.
            let last = folds.last().unwrap();
            assert!(folds[..held.len()].iter().all(|fold| fold[largest].iter().all(|s| !s.held_out)));
            assert!(last[largest].iter().any(|s| s.held_out) && last[largest].iter().any(|s| !s.held_out));
            assert!((0..count).filter(|&k| k != largest).all(|k| !last[k][0].held_out));
        }
    }

    #[test]
    fn a_run_of_fewer_than_two_cycles_holds_out_a_leg() {
        // 1.5 cycles: maxima at 250 and 1250, one whole cycle between them.
        let theta: Vec<f64> = (0..1500).map(|i| (std::f64::consts::TAU * i as f64 / 1000.0).sin()).collect();
        let reversals = crate::prepare::reversals(&theta);
        let spans = &hold_out(&[shape(&theta, &reversals)]).0[0];
        let held: Vec<&Span> = spans[0].iter().filter(|s| s.held_out).collect();
        // Turning points at 250, 750, 1250: the second leg, 750..1250.
        assert_eq!(held.len(), 1, "{spans:?}");
        assert_eq!(held[0].range, 750..1250);
    }

    #[test]
    fn a_run_of_one_cycle_holds_out_its_middle_leg() {
        // Up to a maximum at 250, down to a minimum at 750, back: a bench's ramp cycle.
        let theta: Vec<f64> = (0..1000).map(|i| (std::f64::consts::TAU * i as f64 / 1000.0).sin()).collect();
        let reversals = crate::prepare::reversals(&theta);
        let spans = &hold_out(&[shape(&theta, &reversals)]).0[0];
        let held: Vec<&Span> = spans[0].iter().filter(|s| s.held_out).collect();
        assert_eq!(held.len(), 1, "{spans:?}");
        assert_eq!(held[0].range, 250..750);
    }

    #[test]
    fn two_runs_hold_out_cycles_of_each() {
        let (a, b) = (sine(6, 1e-3), sine(6, 2e-3));
        let (ra, rb) = (crate::prepare::reversals(&a), crate::prepare::reversals(&b));
        let (folds, rule) = hold_out(&[shape(&a, &ra), shape(&b, &rb)]);
        assert_eq!(rule, HeldOutRule::Cycles);
        assert_eq!(folds.len(), 1);
        let spans = &folds[0];
        assert!(spans.iter().all(|run| run.iter().any(|s| s.held_out) && run.iter().any(|s| !s.held_out)));
    }
}
