//! What a recording offers the diagnosis, sample by sample: rate, input angle, warming, the
//! parts for the consistency check and the held-out samples, and what it cannot reveal.
use super::effects::Effect;
use super::extended::{kinematic_of, EffectState};
use crate::fit::held_out::{hold_out, RunShape};
use crate::fit::motion::Span;
use crate::input::{Dataset, Recording};
use crate::prepare::rest::within_rest_band;
use crate::prepare::{FitData, NoiseModel, Prepared};
use model_core::Direction;
use std::borrow::Cow;

/// What the recording offers the diagnosis, sample by sample.
#[derive(Clone, Debug)]
pub struct Observed {
    pub data: FitData,
    pub noise: Option<NoiseModel>,
    pub time: Option<Vec<f64>>,
    /// Deflection rate, rad/s (local slope).
    pub rate: Option<Vec<f64>>,
    /// Half the window of the local slope that forms `rate`, samples.
    rate_window: usize,
    /// Input (wave generator) angle, rad, when the input turns at least once.
    pub input_angle: Option<Vec<f64>>,
    /// cos 2ψ and sin 2ψ of the input angle ψ, with [`Observed::input_angle`]: the kinematic
    /// error's harmonics, formed for every sample of every Gauss–Newton step of every trial
    /// where it is active, where their sine and cosine were 12 % of `diagnose`'s time (perf,
    /// 60 k samples of `bench/diagnose.sh`). Kept in f32, 8 bytes a sample as the angle is:
    /// their rounding, 6·10⁻⁸, moves a kinematic error of micro-radians by 10⁻¹³ rad.
    input_harmonics: Option<Vec<[f32; 2]>>,
    /// Temperature minus the temperature at the start, K, when it changes.
    pub warming: Option<Vec<f64>>,
    /// Two independent parts of the data, for the consistency check: alternate cycles
    /// (pairs of legs) of a recording, so that each part spans the whole recording and every
    /// variable's range (time, temperature, rate, input angle); alternate points of a table.
    pub parts: [Vec<usize>; 2],
    /// The samples moving slower and faster than the median instantaneous frequency, when the
    /// recording has a second rate: a rate effect must have one magnitude in both.
    pub rate_parts: Option<[Vec<usize>; 2]>,
    /// Ratio of the 90th to the 10th percentile of the motion's instantaneous frequency.
    pub rate_spread: Option<f64>,
    /// The median of the motion's instantaneous frequency, rad/s: the rate a run of one rate is
    /// recorded at, beside the other runs.
    pub frequency: Option<f64>,
    /// Every sample, in order: the subset the whole-data fits run on.
    samples: Vec<usize>,
    /// Fit on [`Observed::training`], judge on [`Observed::held_out`].
    split: HeldOut,
    /// Effects this data cannot reveal, with why.
    pub cannot_reveal: Vec<(Effect, String)>,
    /// The torque read at rest before the motion and its standard error, N·m: a torque
    /// sensor's offset reads there as it does everywhere.
    pub rest_torque: Option<(f64, f64)>,
    /// The first sample whose hysteresis state is known (0 from rest): the samples before it,
    /// of a recording that starts mid-motion, carry no weight in any fit and count in no figure
    /// ([`Observed::scored`]).
    pub known_state_from: usize,
    /// The ends of a recording's legs as (deflection, sample index): the first sample, every
    /// turning point, the last sample. Leg k (from end k to end k + 1) holds the samples after
    /// turning point k − 1 up to turning point k. The kinematic error moves the elastic turning
    /// points, and with them the amplitude.
    leg_ends: Option<Vec<LegEnd>>,
}

/// One end of a leg ([`Observed::leg_ends`]).
#[derive(Clone, Copy, Debug)]
struct LegEnd {
    /// The measured deflection there, rad.
    deflection: f64,
    /// The kinematic error's harmonics of the input angle there, formed once: the amplitude of
    /// every sample looks up its leg's two ends on every pass.
    harmonics: [f64; 4],
    /// Its sample.
    index: usize,
}

/// Which samples a model is fitted on and which it is judged on: a recording's interleaved
/// cycles (`fit`'s rule for one run, [`crate::fit::held_out`]), a table's alternate points of
/// each branch. Never the last quarter in time: a gear warms and a sensor drifts over a
/// recording, so the last quarter would judge a real effect beside a drift on how the model
/// extrapolates the drift (a kinematic error beside a thermal drift was dropped that way).
///
/// A recording keeps its spans only, and its lists of samples are formed when asked for: two
/// lists of every sample are 16 MB at 2 M samples, which took `diagnose` to 205 MB there
/// (`bash bench/scale.sh 2000000`).
#[derive(Clone, Debug)]
enum HeldOut {
    /// A recording's samples in order as spans, each fitted or held out.
    Spans(Vec<Span>),
    /// A table's alternate points of each branch.
    Apart { training: Vec<usize>, held_out: Vec<usize> },
}

impl HeldOut {
    /// The samples fitted (`held_out` false) or held out (true).
    fn samples(&self, held_out: bool) -> Cow<'_, [usize]> {
        match self {
            HeldOut::Spans(spans) => {
                spans.iter().filter(|s| s.held_out == held_out).flat_map(|s| s.range.clone()).collect::<Vec<_>>().into()
            }
            HeldOut::Apart { training, held_out: held } => if held_out { held } else { training }.as_slice().into(),
        }
    }
}

impl Observed {
    /// The samples whose hysteresis state is known, from [`Observed::known_state_from`]: the
    /// ones every fit weighs and every figure counts.
    pub fn scored(&self) -> std::ops::Range<usize> {
        let n = self.data.theta.len();
        self.known_state_from.min(n)..n
    }

    /// How many samples [`Observed::scored`] holds.
    pub fn scored_count(&self) -> usize {
        self.scored().len()
    }

    /// `weights` with the samples before the known state at 0: weighed by nothing.
    pub fn unweigh_unknown(&self, weights: &mut [f64]) {
        weights.iter_mut().take(self.known_state_from).for_each(|w| *w = 0.0);
    }

    /// Σ (torque − predicted)² over the scored samples, (N·m)².
    pub fn rss(&self, predicted: &[f64]) -> f64 {
        let scored = self.scored();
        let torque = self.data.torque.get(scored.clone()).unwrap_or(&[]);
        torque.iter().zip(predicted.get(scored).unwrap_or(&[])).map(|(t, p)| (t - p).powi(2)).sum()
    }

    /// Every sample, in order.
    pub fn samples(&self) -> &[usize] {
        &self.samples
    }

    /// The samples the held-out check fits on.
    pub fn training(&self) -> Cow<'_, [usize]> {
        self.split.samples(false)
    }

    /// The samples the held-out check judges on.
    pub fn held_out(&self) -> Cow<'_, [usize]> {
        self.split.samples(true)
    }

    /// How many samples are held out.
    pub fn held_out_count(&self) -> usize {
        match &self.split {
            HeldOut::Spans(spans) => spans.iter().filter(|s| s.held_out).map(|s| s.range.len()).sum(),
            HeldOut::Apart { held_out, .. } => held_out.len(),
        }
    }

    /// cos 2ψ, sin 2ψ, cos 4ψ and sin 4ψ of the input angle ψ at sample `i` (the 4th from the
    /// 2nd by the double angle), when the input turns.
    pub(super) fn input_harmonics(&self, i: usize) -> Option<[f64; 4]> {
        let [cos2, sin2] = self.input_harmonics.as_ref()?[i].map(f64::from);
        Some([cos2, sin2, (cos2 - sin2) * (cos2 + sin2), 2.0 * sin2 * cos2])
    }

    /// The time derivative of `values` (one per sample) by the local slope that forms the
    /// deflection rate; `None` without time.
    pub(super) fn time_derivative(&self, values: &[f64]) -> Option<Vec<f64>> {
        Some(local_slope(self.time.as_ref()?, values, self.rate_window))
    }

    /// A recording's samples in order as spans, each fitted or held out (empty for a table).
    pub fn held_out_spans(&self) -> &[Span] {
        match &self.split {
            HeldOut::Spans(spans) => spans,
            HeldOut::Apart { .. } => &[],
        }
    }

    /// What `dataset` offers the diagnosis, with `data`, its prepared samples (moved out of
    /// `prepared`: the diagnosis holds them once). A recording's time and input angle are
    /// moved in, and its other columns dropped.
    /// `known_state_from`: the first sample whose hysteresis state is known (0 from rest).
    pub fn with_data(dataset: Dataset, prepared: &Prepared, data: FitData, known_state_from: usize) -> Observed {
        let n = data.theta.len();
        let mut observed = Observed {
            noise: prepared.noise,
            time: None,
            rate: None,
            rate_window: 0,
            input_angle: None,
            input_harmonics: None,
            warming: None,
            parts: [Vec::new(), Vec::new()],
            rate_parts: None,
            rate_spread: None,
            frequency: None,
            samples: (0..n).collect(),
            split: HeldOut::Spans(Vec::new()),
            cannot_reveal: Vec::new(),
            rest_torque: None,
            known_state_from,
            leg_ends: None,
            data,
        };
        match dataset {
            Dataset::Recording(recording) => observed.add_recording(recording, prepared),
            Dataset::LoopTable(_) => {
                // Alternate points of each branch: both parts see every branch.
                let mut seen = std::collections::HashMap::new();
                let (mut training, mut held_out) = (Vec::new(), Vec::new());
                for i in 0..n {
                    let k: &mut usize = seen.entry(prepared.branch[i]).or_default();
                    observed.parts[*k % 2].push(i);
                    if *k % 4 == 3 {
                        held_out.push(i)
                    } else {
                        training.push(i)
                    }
                    *k += 1;
                }
                observed.split = HeldOut::Apart { training, held_out };
                for (effect, why) in [
                    (Effect::ViscousDamping, "a loop table has no time, so no deflection rate"),
                    (Effect::ChannelDelay, "a loop table has no time, so no deflection rate"),
                    (Effect::KinematicError, "a loop table has no input angle"),
                    (Effect::ThermalDrift, "a loop table has no temperature"),
                ] {
                    observed.cannot_reveal.push((effect, why.into()));
                }
            }
        }
        observed.check_coverage();
        observed
    }

    fn add_recording(&mut self, recording: Recording, prepared: &Prepared) {
        let n = recording.time.len();
        self.parts = interleaved_cycles(n, prepared.segmentation.as_ref().map_or(&[][..], |s| &s.turning_points));
        if let Some(segmentation) = &prepared.segmentation {
            let reversals = segmentation.reversals();
            // Neither fitted nor judged before the state is known.
            let run = RunShape { theta: &self.data.theta, reversals: &reversals, scored_from: self.known_state_from };
            let (folds, _) = hold_out(&[run]);
            if let Some(spans) = folds.into_iter().next().and_then(|fold| fold.into_iter().next()) {
                self.split = HeldOut::Spans(spans);
            }
        }
        let legs = prepared.segmentation.as_ref().map_or(n, |s| n / (s.turning_points.len() + 1).max(1));
        self.rate_window = (legs / 50).max(2);
        let rate = local_slope(&recording.time, &recording.deflection, self.rate_window);
        let noise = prepared.noise.map_or(0.0, |n| n.deflection_rad);
        let (spread, median, rate_parts) = rate_spread(&self.data, &rate, moving(&self.data.theta, noise));
        self.rate_spread = Some(spread);
        self.frequency = median;
        if spread < MIN_RATE_SPREAD {
            let why = format!(
                "rate-dependent and rate-independent hysteresis cannot be told apart from this data: the \
                 motion passes each place on the loop at one rate (its frequencies spread {spread:.2}×, \
                 {MIN_RATE_SPREAD}× needed), so friction, damping, a channel delay and hysteresis open the loop \
                 alike; record the same loop at a second rate (e.g. half and twice the frequency) to tell damping \
                 and a delay (an opening that grows with the rate) from friction and hysteresis, and at a \
                 second amplitude to tell Coulomb friction (the same opening at every amplitude) from \
                 hysteresis (an opening that grows with the amplitude). The loop's opening is taken for \
                 hysteresis shape"
            );
            // Friction's torque follows the rate's sign: at one rate, damping or a delay that the
            // hysteresis' shape leaves over would be named as friction (seen on the corpus).
            for effect in Effect::ALL.into_iter().filter(|e| e.is_rate_dependent()) {
                self.cannot_reveal.push((effect, why.clone()));
            }
        } else {
            self.rate_parts = Some(rate_parts);
        }
        self.rate = Some(rate);
        match recording.angles {
            Some(angles) => {
                let (lo, hi) = min_max(&angles.input);
                if hi - lo >= std::f64::consts::TAU {
                    self.input_harmonics = Some(
                        angles
                            .input
                            .iter()
                            .map(|psi| {
                                let (sin2, cos2) = (2.0 * psi).sin_cos();
                                [cos2 as f32, sin2 as f32]
                            })
                            .collect(),
                    );
                    self.input_angle = Some(angles.input);
                } else {
                    self.cannot_reveal.push((
                        Effect::KinematicError,
                        format!("the input turned {:.2} rad, less than one revolution", hi - lo),
                    ));
                }
            }
            None => self.cannot_reveal.push((Effect::KinematicError, "the recording has no input angle".into())),
        }
        if let Some(segmentation) = &prepared.segmentation {
            let theta = &recording.deflection;
            let end = |deflection: f64, index: usize| LegEnd {
                deflection,
                harmonics: self.input_harmonics(index).unwrap_or([0.0; 4]),
                index,
            };
            let mut ends = Vec::with_capacity(segmentation.turning_points.len() + 2);
            ends.push(end(theta[0], 0));
            ends.extend(segmentation.turning_points.iter().map(|tp| end(tp.deflection, tp.index)));
            ends.push(end(theta[n - 1], n - 1));
            self.leg_ends = Some(ends);
        }
        match &recording.temperature {
            Some(temps) => {
                let (lo, hi) = min_max(temps);
                if hi - lo >= 0.5 {
                    self.warming = Some(temps.iter().map(|t| t - temps[0]).collect());
                } else {
                    self.cannot_reveal
                        .push((Effect::ThermalDrift, format!("the temperature changed by only {:.2} K", hi - lo)));
                }
            }
            None => self.cannot_reveal.push((Effect::ThermalDrift, "the recording has no temperature column".into())),
        }
        self.time = Some(recording.time);
    }

    /// Effects whose signature the data cannot show at all.
    fn check_coverage(&mut self) {
        let rising = self.data.direction.iter().filter(|d| **d == Direction::Rising).count();
        if rising == 0 || rising == self.data.direction.len() {
            self.cannot_reveal.push((Effect::CoulombFriction, "the deflection moves in one direction only".into()));
        }
        let closest = self.data.theta.iter().map(|t| t.abs()).fold(f64::INFINITY, f64::min);
        let amplitude = self.data.amplitude.iter().copied().fold(0.0, f64::max);
        if closest > 0.25 * amplitude {
            self.cannot_reveal
                .push((Effect::Backlash, format!("the deflection never comes near zero (closest {closest:.3e} rad)")));
        }
    }

    /// The effects this data can reveal.
    pub fn revealable(&self) -> Vec<Effect> {
        Effect::ALL.into_iter().filter(|e| self.cannot_reveal.iter().all(|(c, _)| c != e)).collect()
    }
}

impl Observed {
    /// Amplitude of the elastic loop through sample `i`: the larger magnitude of its leg's
    /// ends after the kinematic error, less half the backlash.
    pub(super) fn elastic_amplitude(&self, state: &EffectState, i: usize) -> f64 {
        self.elastic_amplitudes(state).at(i)
    }

    /// [`Observed::elastic_amplitude`] of many samples: asked in increasing order, each finds
    /// its leg from the last one's.
    pub(super) fn elastic_amplitudes<'a>(&'a self, state: &'a EffectState) -> ElasticAmplitudes<'a> {
        ElasticAmplitudes { observed: self, state, leg: 0 }
    }
}

/// [`Observed::elastic_amplitudes`].
pub(super) struct ElasticAmplitudes<'a> {
    observed: &'a Observed,
    state: &'a EffectState,
    /// The leg of the last sample asked for.
    leg: usize,
}

impl ElasticAmplitudes<'_> {
    /// The elastic amplitude at sample `i`.
    pub(super) fn at(&mut self, i: usize) -> f64 {
        let state = self.state;
        let measured = match &self.observed.leg_ends {
            Some(ends) if state.kinematic != [0.0; 4] => {
                // The leg of sample i ends at the first turning point at or after it: found by
                // walking on from the last sample's leg (a whole-data pass asks in order; a
                // search per sample was 3.5 % of `diagnose`'s time), or by bisection backwards.
                let turning = &ends[1..ends.len() - 1];
                if self.leg > 0 && turning[self.leg - 1].index >= i {
                    self.leg = turning.partition_point(|end| end.index < i);
                }
                while self.leg < turning.len() && turning[self.leg].index < i {
                    self.leg += 1;
                }
                ends[self.leg..self.leg + 2]
                    .iter()
                    .map(|end| (end.deflection + kinematic_of(state, end.harmonics)).abs())
                    .fold(0.0, f64::max)
            }
            _ => self.observed.data.amplitude[i],
        };
        (measured - state.backlash / 2.0).max(f64::MIN_POSITIVE)
    }
}

/// A rate effect needs a second rate at the same place on the loop: the instantaneous
/// frequencies of the motion (below) must spread by at least this ratio between their 10th and
/// 90th percentiles. One excitation frequency gives about 1.1 (noise); two an octave apart, 2.
pub const MIN_RATE_SPREAD: f64 = 1.5;

/// Alternate cycles (two legs each) of a recording; time halves when it has fewer than four
/// cycles.
fn interleaved_cycles(n: usize, turning_points: &[crate::prepare::TurningPoint]) -> [Vec<usize>; 2] {
    if turning_points.len() < 8 {
        return [(0..n / 2).collect(), (n / 2..n).collect()];
    }
    let mut parts = [Vec::with_capacity(n / 2 + 1), Vec::with_capacity(n / 2 + 1)];
    let mut leg = 0;
    for i in 0..n {
        while leg < turning_points.len() && i > turning_points[leg].index {
            leg += 1;
        }
        parts[(leg / 2) % 2].push(i);
    }
    parts
}

/// The samples between the rests at either end (each the readings within the rest band of the
/// end's reading, [`within_rest_band`]; `noise` is σθ): the motion.
fn moving(theta: &[f64], noise: f64) -> std::ops::Range<usize> {
    let start = within_rest_band(theta.iter(), noise);
    let end = theta.len() - within_rest_band(theta.iter().rev(), noise);
    start..end.max(start)
}

/// How far the motion's rates at the same place on the loop spread, their median (rad/s), and
/// the samples slower and faster than the median. At θ = A·sin φ on a leg of amplitude A the rate is
/// A·ω·cos φ, so ω = |rate|/(A·|cos φ|) is the motion's instantaneous frequency: one value for
/// a single-frequency excitation whatever the amplitude, many for several frequencies or a
/// random motion. Samples with |θ/A| > 0.8 (rate near zero, ω ill-defined) are left out, and
/// so are those outside `moving`: a rest at either end is no rate of the loop (counted, a rest
/// before a one-frequency sine made its "slow half" and let a channel delay of 38 ms be named
/// on a gear that has none).
fn rate_spread(data: &FitData, rate: &[f64], moving: std::ops::Range<usize>) -> (f64, Option<f64>, [Vec<usize>; 2]) {
    // Formed three times, to count, to sort and to split, rather than kept with its index (16
    // bytes a sample).
    let frequency = |i: usize| {
        if !moving.contains(&i) {
            return None;
        }
        let x = data.theta[i] / data.amplitude[i];
        (x.abs() <= 0.8).then(|| rate[i].abs() / (data.amplitude[i] * (1.0 - x * x).sqrt())).filter(|w| w.is_finite())
    };
    // Counted first: collected, the vector grew by doubling to 1.7× its room.
    let mut sorted = Vec::with_capacity((0..rate.len()).filter(|&i| frequency(i).is_some()).count());
    sorted.extend((0..rate.len()).filter_map(frequency));
    if sorted.len() < 20 {
        return (1.0, None, [Vec::new(), Vec::new()]);
    }
    // Equal under total_cmp is equal bit for bit: the unstable sort's order is the stable one's.
    sorted.sort_unstable_by(f64::total_cmp);
    let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q) as usize];
    let spread = at(0.9) / at(0.1).max(f64::MIN_POSITIVE);
    let median = at(0.5);
    // The parts sized exactly and the sorted frequencies let go before they fill: both together,
    // and the parts grown by doubling, made `diagnose`'s peak at 2 M samples (`bash
    // bench/scale.sh 2000000`).
    let slower = sorted.partition_point(|&w| w <= median);
    let mut parts = [Vec::with_capacity(slower), Vec::with_capacity(sorted.len() - slower)];
    drop(sorted);
    for i in 0..rate.len() {
        if let Some(w) = frequency(i) {
            parts[usize::from(w > median)].push(i);
        }
    }
    (spread, Some(median), parts)
}

fn min_max(values: &[f64]) -> (f64, f64) {
    values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)))
}

/// Slope of a least-squares line through the `half` samples either side of each sample, in
/// O(n) from running sums: the deflection rate without the encoder's quantisation steps.
pub fn local_slope(time: &[f64], x: &[f64], half: usize) -> Vec<f64> {
    let n = x.len();
    // (t, x, t², t·x) of sample i; times relative to the first sample keep the sums well
    // conditioned.
    let terms = |i: usize| {
        let t = time[i] - time[0];
        [t, x[i], t * t, t * x[i]]
    };
    // Running sums over samples 0..a and 0..b, the window a..b their difference: two cursors
    // instead of four prefix arrays (32 bytes a sample), the same additions in the same order.
    let advance = |(at, sums): &mut (usize, [f64; 4]), to: usize| {
        while *at < to {
            sums.iter_mut().zip(terms(*at)).for_each(|(sum, term)| *sum += term);
            *at += 1;
        }
    };
    let (mut trail, mut lead) = ((0, [0.0; 4]), (0, [0.0; 4]));
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
            advance(&mut trail, a);
            advance(&mut lead, b);
            let [st, sx, stt, stx]: [f64; 4] = std::array::from_fn(|k| lead.1[k] - trail.1[k]);
            let m = (b - a) as f64;
            let (mt, mx) = (st / m, sx / m);
            let var = stt / m - mt * mt;
            let cov = stx / m - mt * mx;
            if var > 0.0 {
                cov / var
            } else {
                0.0
            }
        })
        .collect()
}
