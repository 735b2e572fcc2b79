//! Running a gear's model (model-core's [`GearModel`], of any kind) along a motion from rest:
//! offline, following the turning points found over the whole recording ([`step_offline`],
//! what `fit` and `predict` do), or causally with a reversal band, as the joint does ([`run`]).
use model_core::{Direction, Evaluation, GearModel, Hysteretic};

/// Torque and stiffness of `model` along `deflection` from rest, reversing causally once θ is
/// `band` rad back from its extreme (as the joint does); the index of the first sample that
/// cannot be evaluated is the error's.
pub fn run(
    model: &GearModel<f64>,
    deflection: &[f64],
    band: f64,
) -> Result<Vec<Evaluation<f64>>, (usize, model_core::Error)> {
    let mut evaluator = model.evaluator(band).map_err(|e| (0, e))?;
    // Sized up front: collected through a `Result`, the vector would grow by doubling.
    let mut evaluations = Vec::with_capacity(deflection.len());
    for (i, &theta) in deflection.iter().enumerate() {
        evaluations.push(evaluator.step(theta).map_err(|e| (i, e))?);
    }
    Ok(evaluations)
}

/// Where a run's deflection reverses, found offline over the whole run (`prepare`'s
/// segmentation): the sample index of each turning point, in order, maxima and minima
/// alternating.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Reversals {
    /// Sample index of each turning point, increasing.
    pub indices: Vec<usize>,
    /// Whether the motion rises before the first turning point (which is then a maximum); with
    /// no turning point, whether it rises at all.
    pub rising_first: bool,
}

impl Reversals {
    /// Each sample of `theta` (the run these reversals were found on) as the offline model
    /// follows it: [`Projected`], in order.
    pub fn project<'a>(&'a self, theta: &'a [f64]) -> Projection<'a> {
        Projection { theta, turns: &self.indices, next_turn: 0, index: 0, rising: self.rising_first, level: 0.0 }
    }

    /// The direction of the leg each sample lies on (a turning point ends its leg), for a run of
    /// `len` samples.
    pub fn directions(&self, len: usize) -> impl Iterator<Item = Direction> + '_ {
        let mut rising = self.rising_first;
        let mut turns = self.indices.iter().copied().peekable();
        (0..len).map(move |i| {
            let direction = if rising { Direction::Rising } else { Direction::Falling };
            if turns.next_if_eq(&i).is_some() {
                rising = !rising;
            }
            direction
        })
    }

    /// The indices of the maxima among the turning points, in order.
    pub fn maxima(&self) -> impl Iterator<Item = usize> + '_ {
        // The first turning point is a maximum when the motion rises before it; they alternate.
        let first = usize::from(!self.rising_first);
        self.indices.iter().skip(first).step_by(2).copied()
    }
}

/// A sample as the offline model follows it: the monotone projection θ_m of the deflection
/// between turning points (its running maximum on a rising leg, minimum on a falling one) and
/// what the measured deflection adds to it, θ − θ_m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projected {
    /// θ_m, rad: what the evaluator is fed (band 0: it reverses exactly at the turning points).
    pub theta_m: f64,
    /// θ − θ_m, rad (≤ 0 rising, ≥ 0 falling; 0 on a clean monotone leg).
    pub offset: f64,
}

/// The iterator of [`Reversals::project`].
#[derive(Clone, Debug)]
pub struct Projection<'a> {
    theta: &'a [f64],
    turns: &'a [usize],
    next_turn: usize,
    index: usize,
    rising: bool,
    level: f64,
}

impl Iterator for Projection<'_> {
    type Item = Projected;

    #[inline]
    fn next(&mut self) -> Option<Projected> {
        let theta = *self.theta.get(self.index)?;
        self.level = match (self.index, self.rising) {
            (0, _) => theta,
            (_, true) => self.level.max(theta),
            (_, false) => self.level.min(theta),
        };
        // A turning point ends its leg and starts the next from the extreme.
        if self.turns.get(self.next_turn) == Some(&self.index) {
            self.next_turn += 1;
            self.rising = !self.rising;
        }
        self.index += 1;
        Some(Projected { theta_m: self.level, offset: theta - self.level })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.theta.len().saturating_sub(self.index);
        (left, Some(left))
    }
}

/// One sample of the offline model: `evaluator` stepped to θ_m, its torque carried to the
/// measured deflection along its stiffness, T(θ_m) + K(θ_m)·(θ − θ_m). The one rule by which
/// `fit` (its columns and its scores) and `predict` follow a recording's reversals.
#[inline]
pub fn step_offline<E: Hysteretic<f64>>(
    evaluator: &mut E,
    sample: Projected,
) -> Result<Evaluation<f64>, model_core::Error> {
    let at = evaluator.step(sample.theta_m)?;
    Ok(Evaluation { torque: at.torque + at.stiffness * sample.offset, stiffness: at.stiffness })
}

/// Torque and stiffness of `model` along `deflection` from rest, following `reversals` offline
/// ([`step_offline`]); the index of the first sample that cannot be evaluated is the error's.
pub fn run_offline(
    model: &GearModel<f64>,
    deflection: &[f64],
    reversals: &Reversals,
) -> Result<Vec<Evaluation<f64>>, (usize, model_core::Error)> {
    let mut evaluator = model.evaluator(0.0).map_err(|e| (0, e))?;
    let mut evaluations = Vec::with_capacity(deflection.len());
    for (i, sample) in reversals.project(deflection).enumerate() {
        evaluations.push(step_offline(&mut evaluator, sample).map_err(|e| (i, e))?);
    }
    Ok(evaluations)
}
