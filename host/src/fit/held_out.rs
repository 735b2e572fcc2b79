//! Which samples `fit --model auto` holds out of the fits that choose the kind. Never the last
//! quarter in time: a gear warms and a sensor drifts over a recording, so the last quarter
//! would judge the kinds on how they extrapolate the drift, not on how well they model the gear.
//!
//! - **Several runs** (three or more): whole runs. The runs sorted by amplitude (half the
//!   range of their scored deflection; ties in the order given), about a quarter of them —
//!   round(R/4), at least one — are held out at evenly spread interior ranks, never the largest
//!   or the smallest amplitude: the fit must span the amplitudes it is judged on.
//! - **One or two runs**: interleaved cycles. Each run's cycles run from one maximum (turning
//!   point) to the next; every fourth cycle, the 2nd, 6th, 10th, …, is held out, so the held-out
//!   samples are spread over the whole run. A run of fewer than two whole cycles holds out its
//!   legs (turning point to turning point) by the same rule; a run of one cycle (two turning
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
    /// These runs (indices in the order given), whole.
    Runs(Vec<usize>),
    /// Every [`CYCLE_PERIOD`]th cycle between consecutive maxima of each run.
    Cycles,
}

impl HeldOutRule {
    /// The rule in words, for reports.
    pub fn describe(&self) -> String {
        match self {
            HeldOutRule::Runs(_) => "whole runs: about a quarter of them by amplitude, never the largest or the \
                                     smallest"
                .to_string(),
            HeldOutRule::Cycles => format!(
                "interleaved cycles: the {} of every {CYCLE_PERIOD} between consecutive maxima of each run, or of \
                 its legs in a run of fewer than two cycles",
                ["1st", "2nd", "3rd", "4th"][CYCLE_HELD_OUT]
            ),
        }
    }
}

/// The scored spans of each run, fitted or held out, and the rule that chose them.
pub fn hold_out(runs: &[RunShape<'_>]) -> (Vec<Vec<Span>>, HeldOutRule) {
    if runs.len() >= MIN_RUNS_TO_HOLD_OUT {
        let held = held_out_runs(runs);
        let spans = runs
            .iter()
            .enumerate()
            .map(|(k, run)| vec![Span { range: run.scored_from..run.theta.len(), held_out: held.contains(&k) }])
            .collect();
        (spans, HeldOutRule::Runs(held))
    } else {
        (runs.iter().map(held_out_cycles).collect(), HeldOutRule::Cycles)
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

/// The runs held out (indices, increasing): round(R/4) of them, at least one, at evenly spread
/// interior ranks by amplitude.
fn held_out_runs(runs: &[RunShape<'_>]) -> Vec<usize> {
    let count = runs.len();
    let mut by_amplitude: Vec<usize> = (0..count).collect();
    by_amplitude.sort_by(|&a, &b| amplitude(&runs[a]).total_cmp(&amplitude(&runs[b])));
    let interior = count - 2;
    let held = (count as f64 / 4.0).round().max(1.0) as usize;
    let mut chosen: Vec<usize> = (0..held).map(|j| by_amplitude[1 + (2 * j + 1) * interior / (2 * held)]).collect();
    chosen.sort_unstable();
    chosen
}

/// A run's scored samples split at its maxima, every [`CYCLE_PERIOD`]th cycle held out; split
/// at every turning point (legs) when that holds out nothing, and at its start and end too
/// when that still holds out nothing.
fn held_out_cycles(run: &RunShape<'_>) -> Vec<Span> {
    let maxima: Vec<usize> = run.reversals.maxima().collect();
    let turns = &run.reversals.indices;
    let ends: Vec<usize> =
        std::iter::once(0).chain(turns.iter().copied()).chain(std::iter::once(run.theta.len())).collect();
    let spans = [maxima.as_slice(), turns, &ends]
        .into_iter()
        .map(|bounds| every_fourth(run, bounds))
        .find(|spans| spans.iter().any(|s| s.held_out))
        .unwrap_or_else(|| every_fourth(run, &maxima));
    spans
}

/// A run's scored samples split at `bounds` (increasing), every [`CYCLE_PERIOD`]th piece
/// between two of them held out.
fn every_fourth(run: &RunShape<'_>, bounds: &[usize]) -> Vec<Span> {
    let n = run.theta.len();
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
        push(pair[0]..pair[1], k % CYCLE_PERIOD == CYCLE_HELD_OUT);
    }
    push(bounds.last().copied().unwrap_or(n)..n, false);
    spans
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
        let (spans, rule) = hold_out(&[shape(&theta, &reversals)]);
        assert_eq!(rule, HeldOutRule::Cycles);
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
    fn samples_before_the_scored_start_are_in_no_span() {
        let theta = sine(8, 1e-3);
        let reversals = crate::prepare::reversals(&theta);
        let run = RunShape { theta: &theta, reversals: &reversals, scored_from: 1500 };
        let (spans, _) = hold_out(&[run]);
        assert_eq!(spans[0][0].range.start, 1500);
        assert!(spans[0].iter().all(|s| s.range.start >= 1500));
    }

    #[test]
    fn several_runs_hold_out_interior_amplitudes_never_the_largest_or_smallest() {
        for count in 3..=12 {
            // Amplitudes given out of order: 1, 12, 2, 11, 3, 10, … mrad.
            let amplitudes: Vec<f64> =
                (0..count).map(|k| if k % 2 == 0 { 1 + k / 2 } else { count - k / 2 } as f64 * 1e-3).collect();
            let thetas: Vec<Vec<f64>> = amplitudes.iter().map(|&a| sine(3, a)).collect();
            let reversals: Vec<Reversals> = thetas.iter().map(|t| crate::prepare::reversals(t)).collect();
            let shapes: Vec<RunShape> = thetas.iter().zip(&reversals).map(|(t, r)| shape(t, r)).collect();
            let (spans, rule) = hold_out(&shapes);
            let HeldOutRule::Runs(held) = rule else { panic!("{count} runs: whole runs") };
            assert_eq!(held.len(), ((count as f64 / 4.0).round() as usize).max(1), "{count} runs");
            let (smallest, largest) = (0, amplitudes.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap().0);
            assert!(!held.contains(&smallest) && !held.contains(&largest), "{count} runs: {held:?}");
            for (k, run) in spans.iter().enumerate() {
                assert_eq!(run.len(), 1);
                assert_eq!(run[0].held_out, held.contains(&k));
            }
        }
    }

    #[test]
    fn a_run_of_fewer_than_two_cycles_holds_out_a_leg() {
        // 1.5 cycles: maxima at 250 and 1250, one whole cycle between them.
        let theta: Vec<f64> = (0..1500).map(|i| (std::f64::consts::TAU * i as f64 / 1000.0).sin()).collect();
        let reversals = crate::prepare::reversals(&theta);
        let (spans, _) = hold_out(&[shape(&theta, &reversals)]);
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
        let (spans, _) = hold_out(&[shape(&theta, &reversals)]);
        let held: Vec<&Span> = spans[0].iter().filter(|s| s.held_out).collect();
        assert_eq!(held.len(), 1, "{spans:?}");
        assert_eq!(held[0].range, 250..750);
    }

    #[test]
    fn two_runs_hold_out_cycles_of_each() {
        let (a, b) = (sine(6, 1e-3), sine(6, 2e-3));
        let (ra, rb) = (crate::prepare::reversals(&a), crate::prepare::reversals(&b));
        let (spans, rule) = hold_out(&[shape(&a, &ra), shape(&b, &rb)]);
        assert_eq!(rule, HeldOutRule::Cycles);
        assert!(spans.iter().all(|run| run.iter().any(|s| s.held_out) && run.iter().any(|s| !s.held_out)));
    }
}
