//! A finding of form: whether loops run over and over drift (`ratcheting`).
//!
//! With return-point memory (Madelung's rules: the micro-slip, genetic and Preisach kinds), a
//! loop that returns to the same turning points returns to the same torque there: after its
//! first cycle it closes and stays put. A Bouc–Wen gear's loops drift instead, cycle after
//! cycle, under a held load with dither most of all (issue 17: its peak torque fell by 0.4 N·m
//! over a hold). No kind of `fit` follows a drift of the loops, so it is named, not modelled.
//!
//! **The drift's sign.** Each run's residual is taken along the sign of the torque it holds
//! (a loop about zero: as measured), so that loops relaxing towards zero torque under a + and
//! a − load add up instead of cancelling (a Bouc–Wen gear held at +A/2 and at −A/2 drifted by
//! −5.8·10⁻³ and +6.4·10⁻³ N·m per cycle, pooled +1.2·10⁻³, unnamed), while a torque sensor's
//! offset drifting in time, the same sign under both loads, cancels.
//!
//! **Repeated loops** are runs of at least [`MIN_CYCLES`] consecutive cycles whose maxima lie
//! within a tolerance of one deflection, and their minima too: [`REPEAT_TOLERANCE`] of the
//! loops' own span, and at least 4σθ; and run at one pace (each fall within [`SAME_PACE`] of
//! the first's duration). The first cycle of each run is left out (it may be the
//! loop's first closing). **The drift** is the slope, N·m per cycle, of the final model's
//! residual at the turning points against the cycle's index, one slope for every run and both
//! ends (each run and end keeps its own level): the final model has no memory of the cycles, so
//! at a repeated turning point it predicts one torque, and the accepted effects (a thermal
//! drift, a kinematic error, an offset) are taken out with it.
//!
//! It is named on an effect's tests: the information criterion drops by more than
//! [`MIN_BIC_DROP`] for the slope, it explains at least [`MIN_EXPLAINED`] of the turning points'
//! scatter about their levels, and the maxima and the minima, fitted alone, drift the same way
//! within [`MAX_HALF_SPREAD`] of their mean (the whole loop moves, not one end of it). A torque
//! sensor whose offset drifts with time reads the same, and is told apart only by a recording
//! that holds still as long.
use super::{share_below, MAX_HALF_SPREAD, MIN_BIC_DROP, MIN_EXPLAINED};
use crate::gear::Reversals;
use serde::Serialize;

/// The fewest consecutive cycles of one loop tested for a drift.
pub const MIN_CYCLES: usize = 6;
/// Turning points of one repeated loop lie within this share of its span of one another.
pub const REPEAT_TOLERANCE: f64 = 0.1;
/// A run of repeated loops holds a torque when the mean of its turning points' torques is at
/// least this share of the loop's torque span from zero.
pub const HELD_SHARE: f64 = 0.5;
/// The falls (maximum to minimum) of one repeated loop last within this share of one another.
pub const SAME_PACE: f64 = 0.25;

/// The drift of repeated loops, measured and tested.
#[derive(Clone, Debug, Serialize)]
pub struct Ratcheting {
    /// The runs of repeated loops and the cycles they hold, all told.
    pub runs: usize,
    pub cycles: usize,
    /// The torque's drift at the turning points, N·m per cycle, along the sign of the torque each
    /// run holds (below 0: the loops relax towards zero torque), and its standard error.
    pub drift_nm_per_cycle: f64,
    pub drift_se: f64,
    /// The drift fitted on the maxima alone and on the minima alone, N·m per cycle.
    pub ends: [f64; 2],
    /// Drop of the information criterion for the slope.
    pub delta_bic: f64,
    /// Share of the turning points' scatter about their levels that the slope explains.
    pub explained: f64,
    /// Why it is not named; `None` when it is.
    pub rejected: Option<String>,
    /// Each tested turning point as (cycle index in its run, residual N·m, a maximum), for the
    /// picture.
    #[serde(skip)]
    pub points: Vec<(usize, f64, bool)>,
}

/// Whether repeated loops were tested for a drift, and what they showed.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "tested", rename_all = "snake_case")]
pub enum RatchetingCheck {
    /// Tested: named when `rejected` is `None`.
    Yes(Ratcheting),
    /// Not tested, and why.
    No { why: String },
}

impl RatchetingCheck {
    /// The drift, when it was tested and named.
    pub fn named(&self) -> Option<&Ratcheting> {
        match self {
            RatchetingCheck::Yes(found) if found.rejected.is_none() => Some(found),
            _ => None,
        }
    }
}

/// A line fitted to points (x, y) grouped by level: one slope, a level per group.
#[derive(Default)]
struct Trend {
    /// Σ (x − x̄_g)², Σ (x − x̄_g)(y − ȳ_g), Σ (y − ȳ_g)² within the groups.
    xx: f64,
    xy: f64,
    yy: f64,
    points: usize,
    groups: usize,
}

impl Trend {
    /// Adds one group of points (cycle index, residual).
    fn add(&mut self, points: &[(f64, f64)]) {
        if points.len() < 2 {
            return;
        }
        let n = points.len() as f64;
        let (mx, my) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
        for (x, y) in points {
            self.xx += (x - mx).powi(2);
            self.xy += (x - mx) * (y - my);
            self.yy += (y - my).powi(2);
        }
        self.points += points.len();
        self.groups += 1;
    }

    fn slope(&self) -> f64 {
        self.xy / self.xx
    }

    /// The scatter the slope leaves, per degree of freedom.
    fn variance(&self) -> f64 {
        (self.yy - self.slope() * self.xy) / (self.points as f64 - self.groups as f64 - 1.0).max(1.0)
    }
}

/// Tests the loops of a recording (`time`, s, deflection `theta`, turning points `reversals`)
/// for a drift, from the final model's residual `after` at every sample and the deflection noise
/// `noise_theta`, rad.
pub fn check(
    time: &[f64],
    theta: &[f64],
    torque: &[f64],
    reversals: &Reversals,
    after: &[f64],
    noise_theta: f64,
) -> RatchetingCheck {
    let repeated = repeated_loops(time, theta, reversals, noise_theta);
    if repeated.is_empty() {
        return RatchetingCheck::No {
            why: format!(
                "no loop runs {MIN_CYCLES} times over between the same turning points: hold a load with a dither, or \
                 run one loop over and over"
            ),
        };
    }
    // Per run, the maxima and the minima after the first cycle, each a group of its own.
    let mut both = Trend::default();
    let mut ends = [Trend::default(), Trend::default()];
    let mut cycles = 0;
    let mut shown = Vec::new();
    for run in &repeated {
        cycles += run.len();
        let along = held_sign(torque, run);
        for (end, trend) in ends.iter_mut().enumerate() {
            let points: Vec<(f64, f64)> =
                run.iter().enumerate().skip(1).map(|(k, turns)| (k as f64, along * after[turns[end]])).collect();
            trend.add(&points);
            both.add(&points);
            shown.extend(points.iter().map(|&(k, r)| (k as usize, r, end == 0)));
        }
    }
    let drift = both.slope();
    let variance = both.variance();
    // The same residual at every turning point (a torque clipped at its tips reads one value
    // there) leaves no scatter to judge a drift by, and the criterion would be 0/0.
    if !(variance > 0.0 && both.xx > 0.0 && (drift * both.xy / variance).is_finite()) {
        return RatchetingCheck::No {
            why: "the final model's residual is the same at every turning point (a torque clipped or held at the \
                  tips?): no scatter to judge a drift by"
                .to_string(),
        };
    }
    let drift_se = (variance / both.xx).sqrt();
    let drop = drift * both.xy;
    let delta_bic = drop / variance - (both.points as f64).ln();
    let explained = drop / both.yy;
    let [maxima, minima] = [ends[0].slope(), ends[1].slope()];
    let rejected = if !(delta_bic > MIN_BIC_DROP) {
        Some(format!("the information criterion drops by {delta_bic:.1} (it must drop by more than {MIN_BIC_DROP})"))
    } else if explained < MIN_EXPLAINED {
        Some(format!(
            "explains {} % of the turning points' scatter, less than {:.0} %",
            share_below(explained, MIN_EXPLAINED),
            100.0 * MIN_EXPLAINED
        ))
    } else if maxima.signum() != drift.signum() || minima.signum() != drift.signum() {
        Some(format!(
            "the maxima and the minima drift apart ({maxima:+.2e} and {minima:+.2e} N·m per cycle): the loop changes \
             its shape, it does not move"
        ))
    } else if (maxima - minima).abs() > MAX_HALF_SPREAD * (0.5 * (maxima + minima)).abs() {
        Some(format!("the maxima and the minima disagree: {maxima:+.2e} and {minima:+.2e} N·m per cycle"))
    } else {
        None
    };
    RatchetingCheck::Yes(Ratcheting {
        runs: repeated.len(),
        cycles,
        drift_nm_per_cycle: drift,
        drift_se,
        ends: [maxima, minima],
        delta_bic,
        explained,
        rejected,
        points: shown,
    })
}

/// The sign of the torque a run of repeated loops holds, by which its drift is measured: the
/// mean of the measured torque at its turning points where that is at least
/// [`HELD_SHARE`] of the loop's torque span from zero, else +1 (a loop about zero holds none).
fn held_sign(torque: &[f64], run: &[[usize; 2]]) -> f64 {
    let n = run.len() as f64;
    let mean = run.iter().map(|[t, b]| 0.5 * (torque[*t] + torque[*b])).sum::<f64>() / n;
    let span = run.iter().map(|[t, b]| torque[*t] - torque[*b]).sum::<f64>() / n;
    if mean.abs() >= HELD_SHARE * span.abs() {
        mean.signum()
    } else {
        1.0
    }
}

/// The runs of at least [`MIN_CYCLES`] consecutive cycles of one loop: per run, each cycle's
/// [maximum, minimum] sample (the minimum after the maximum).
fn repeated_loops(time: &[f64], theta: &[f64], reversals: &Reversals, noise_theta: f64) -> Vec<Vec<[usize; 2]>> {
    let maxima: Vec<usize> = reversals.maxima().collect();
    let cycles: Vec<[usize; 2]> = maxima
        .iter()
        .filter_map(|&top| reversals.indices.iter().find(|&&i| i > top).map(|&bottom| [top, bottom]))
        .collect();
    let mut runs = Vec::new();
    let mut start = 0;
    while start < cycles.len() {
        let [top, bottom] = cycles[start];
        let span = theta[top] - theta[bottom];
        let tolerance = (REPEAT_TOLERANCE * span).max(4.0 * noise_theta);
        let duration = time[bottom] - time[top];
        // One loop at one pace: a change of frequency steps a rate effect's residual, which the
        // slope would take for a drift (a channel delay on the corpus' micro-slip gear at 0.2
        // then 0.6 Hz).
        let same = |[t, b]: [usize; 2]| {
            (theta[t] - theta[top]).abs() <= tolerance
                && (theta[b] - theta[bottom]).abs() <= tolerance
                && ((time[b] - time[t]) - duration).abs() <= SAME_PACE * duration
        };
        let end = (start..cycles.len()).find(|&k| !same(cycles[k])).unwrap_or(cycles.len());
        if end - start >= MIN_CYCLES && span > 0.0 {
            runs.push(cycles[start..end].to_vec());
        }
        start = end.max(start + 1);
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ramp to a load, ten cycles of one loop there, then a larger excursion: one run of the
    /// ten cycles.
    #[test]
    fn a_held_dither_is_one_run_of_repeated_loops() {
        let mut theta = vec![0.0];
        let mut corners = vec![1.0];
        for _ in 0..10 {
            corners.extend([0.8, 1.0]);
        }
        corners.extend([-1.0, 2.0]);
        let mut turns = Vec::new();
        for (k, &c) in corners.iter().enumerate() {
            let from = *theta.last().unwrap();
            theta.extend((1..=10).map(|s| from + (c - from) * f64::from(s) / 10.0));
            if k + 1 < corners.len() {
                turns.push(theta.len() - 1);
            }
        }
        let reversals = Reversals { indices: turns, rising_first: true };
        let time: Vec<f64> = (0..theta.len()).map(|i| i as f64).collect();
        let runs = repeated_loops(&time, &theta, &reversals, 0.0);
        assert_eq!(runs.len(), 1, "{runs:?}");
        assert_eq!(runs[0].len(), 10, "{runs:?}");
        assert!(runs[0].iter().all(|[t, b]| theta[*t] == 1.0 && theta[*b] == 0.8));
        // The same loops at twice the pace from the sixth cycle on: five cycles and five, each
        // too few.
        let paced: Vec<f64> =
            (0..theta.len()).map(|i| if i <= 110 { i as f64 } else { 110.0 + 0.5 * (i - 110) as f64 }).collect();
        assert!(repeated_loops(&paced, &theta, &reversals, 0.0).is_empty());
    }
}
