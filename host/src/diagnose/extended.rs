//! The model with a set of effects, fitted by Gauss–Newton on the effects' magnitudes and r.
use super::effects::{backlash, Effect};
use super::observed::Observed;
use crate::fit::basis::{self, NormalEquations};
use crate::fit::R_LIMIT;
use crate::numeric::median;
use model_core::{Direction, Libm, Model, Params, Phase};

const GAUSS_NEWTON_ITERATIONS: usize = 10;
/// Relative change of χ² between two iterations below which a fit with the kinematic error has
/// settled. Its steps creep by about 1 % an iteration, χ² rising by 10⁻⁴ each, up to the
/// iteration limit; stopping once it settles cuts the diagnosis of `bench/out/diagnose-60k.csv`
/// (`bash bench/diagnose.sh`) from 232 to 161 iterations, 12.0 to 8.0 M sample-iterations, and
/// leaves the corpus' verdicts as they were.
const CHI2_SETTLED: f64 = 1e-4;

/// Magnitudes of the effects in a model, in the fit's own terms.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EffectState {
    /// Dead band width w, rad.
    pub backlash: f64,
    /// e(θ_in) = a·cos 2θ_in + b·sin 2θ_in + c·cos 4θ_in + d·sin 4θ_in, rad.
    pub kinematic: [f64; 4],
    pub coulomb: f64,
    pub viscous: f64,
    /// c1·k, N·m/(rad·K).
    pub thermal_gain: f64,
    pub offset: f64,
    /// Torque channel delay τ, s.
    pub delay: f64,
}

/// The model with a set of effects, fitted.
#[derive(Clone, Debug)]
pub struct ExtendedFit {
    pub params: Params<f64>,
    pub r: f64,
    pub state: EffectState,
    pub active: Vec<Effect>,
    /// Σ w·residual² with the diagnosis' fixed weights.
    pub chi2: f64,
    pub n: usize,
    /// Standard error of each extra column's coefficient.
    column_errors: Vec<f64>,
}

/// Why [`fit_extended`] could not fit.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ExtendedFitError {
    #[error("the data do not determine the model and the effects' columns (they are collinear)")]
    Degenerate,
    #[error(transparent)]
    Model(#[from] model_core::Error),
    #[error("the data have no variable that could show {0}")]
    Unrevealable(Effect),
}

impl From<crate::fit::FitError> for ExtendedFitError {
    fn from(error: crate::fit::FitError) -> Self {
        match error {
            crate::fit::FitError::Model(e) => ExtendedFitError::Model(e),
            _ => ExtendedFitError::Degenerate,
        }
    }
}

/// Coefficients an effect adds to the fit.
pub(super) fn columns(effect: Effect) -> usize {
    if effect == Effect::KinematicError {
        4
    } else {
        1
    }
}

impl ExtendedFit {
    /// The baseline model, no effects, not yet fitted: where [`fit_extended`] starts.
    pub fn start(params: Params<f64>, r: f64, n: usize) -> ExtendedFit {
        ExtendedFit {
            params,
            r,
            state: EffectState::default(),
            active: Vec::new(),
            chi2: f64::INFINITY,
            n,
            column_errors: Vec::new(),
        }
    }

    /// Free parameters: c1, c2, c3, h, r and the effects' columns.
    pub fn degrees_of_freedom(&self) -> usize {
        5 + self.active.iter().map(|&e| columns(e)).sum::<usize>()
    }

    /// The effect's magnitude in SI units (see [`Effect::unit`]).
    pub fn magnitude(&self, effect: Effect) -> f64 {
        let s = &self.state;
        match effect {
            Effect::Backlash => s.backlash,
            Effect::CoulombFriction => s.coulomb,
            Effect::ViscousDamping => s.viscous,
            Effect::KinematicError => s.kinematic[0].hypot(s.kinematic[1]),
            Effect::ThermalDrift => s.thermal_gain / self.params.c1,
            Effect::TorqueOffset => s.offset,
            Effect::ChannelDelay => s.delay,
        }
    }

    /// Standard error of [`Self::magnitude`].
    pub fn magnitude_error(&self, effect: Effect) -> f64 {
        let mut column = 0;
        for &e in &self.active {
            if e == effect {
                let se = |k: usize| self.column_errors.get(column + k).copied().unwrap_or(f64::INFINITY);
                return match effect {
                    Effect::KinematicError => {
                        let [a, b, ..] = self.state.kinematic;
                        let m = a.hypot(b).max(f64::MIN_POSITIVE);
                        ((a * se(0)).powi(2) + (b * se(1)).powi(2)).sqrt() / m
                    }
                    Effect::ThermalDrift => se(0) / self.params.c1.abs(),
                    _ => se(0),
                };
            }
            column += columns(e);
        }
        f64::INFINITY
    }

    /// The 2nd-order kinematic error as a vector, for comparing halves by phase too.
    pub(super) fn kinematic_vector(&self) -> (f64, f64) {
        (self.state.kinematic[0], self.state.kinematic[1])
    }

    /// What predicts this fit's torque sample by sample ([`Prediction::at`]).
    pub(super) fn prediction<'a>(&'a self, observed: &'a Observed) -> Result<Prediction<'a>, model_core::Error> {
        let model = Model::new(self.params)?;
        let torque_rate = if self.state.delay == 0.0 { None } else { torque_rate(observed, &model, &self.state) };
        Ok(Prediction { fit: self, observed, model, torque_rate })
    }

    /// dT/dθ of the model at sample `i`, spring plus hysteresis as in the Gauss–Newton columns.
    pub(super) fn stiffness(
        &self,
        observed: &Observed,
        model: &Model<f64>,
        i: usize,
    ) -> Result<f64, model_core::Error> {
        let d = &observed.data;
        let elastic = backlash(d.theta[i] + kinematic_at(&self.state, observed, i), self.state.backlash);
        let amplitude = observed.elastic_amplitude(&self.state, i);
        let (spring, hysteresis) = model.at_amplitude(amplitude)?.evaluate_parts(elastic, d.direction[i])?;
        Ok(spring.stiffness + hysteresis.stiffness)
    }

    /// Measured minus predicted torque on `subset`.
    pub fn residuals(&self, observed: &Observed, subset: &[usize]) -> Result<Vec<f64>, model_core::Error> {
        let prediction = self.prediction(observed)?;
        // Sized up front: collected through a `Result` the vector does not know its length and
        // grows by doubling, 134 MB instead of 80 for 10 M samples.
        let mut residuals = Vec::with_capacity(subset.len());
        for &i in subset {
            residuals.push(observed.data.torque[i] - prediction.at(i)?);
        }
        Ok(residuals)
    }
}

/// An [`ExtendedFit`]'s model, formed once for the samples it predicts.
pub(super) struct Prediction<'a> {
    fit: &'a ExtendedFit,
    observed: &'a Observed,
    model: Model<f64>,
    /// [`torque_rate`] along the recording, when the fit has a channel delay.
    torque_rate: Option<Vec<f64>>,
}

impl Prediction<'_> {
    /// Torque the extended model predicts for sample `i`.
    pub(super) fn at(&self, i: usize) -> Result<f64, model_core::Error> {
        let (observed, s) = (self.observed, &self.fit.state);
        let d = &observed.data;
        let x = d.theta[i] + kinematic_at(s, observed, i);
        let elastic = backlash(x, s.backlash);
        let amplitude = observed.elastic_amplitude(s, i);
        let sign = direction_sign(d.direction[i]);
        let rate = observed.rate.as_ref().map_or(0.0, |r| r[i]);
        let warming = observed.warming.as_ref().map_or(0.0, |w| w[i]);
        let delayed = self.torque_rate.as_ref().map_or(0.0, |torque_rate| s.delay * torque_rate[i]);
        Ok(self.model.torque(elastic, d.direction[i], amplitude)?
            + s.coulomb * sign
            + s.viscous * rate
            + s.thermal_gain * warming * elastic
            + s.offset
            - delayed)
    }
}

/// The model's torque (spring and hysteresis at the elastic deflection of `state`) differentiated
/// in time along the recording, N·m/s: a channel delay τ shows the torque of τ earlier, T − τ·dT/dt
/// to first order, so −dT/dt is its column. Not −K·dθ/dt with K the tangent stiffness: the
/// genetic loop's K is infinite at its tips, where the measured rate is small but not zero, and
/// there that column ran far beyond the torque it stood for (diagnosis corpus, seed 2054: a
/// delay of 2.76 ms fitted 2.46 and raised the unweighted RSS 612 → 1056 N·m², so it was
/// refused and an offset named). A sample the model cannot evaluate counts no torque, as in the
/// Gauss–Newton columns. `None` without time.
pub(super) fn torque_rate(observed: &Observed, model: &Model<f64>, state: &EffectState) -> Option<Vec<f64>> {
    let d = &observed.data;
    let mut amplitudes = observed.elastic_amplitudes(state);
    // A leg's samples share one loop, formed once (a logarithm and an exponential), as in the
    // Gauss–Newton pass.
    let mut on_loop: Option<(f64, Option<model_core::Loop<f64>>)> = None;
    let torque: Vec<f64> = (0..d.theta.len())
        .map(|i| {
            let elastic = backlash(d.theta[i] + kinematic_at(state, observed, i), state.backlash);
            let amplitude = amplitudes.at(i);
            let at_amplitude = match on_loop {
                Some((of, at)) if of.to_bits() == amplitude.to_bits() => at,
                _ => on_loop.insert((amplitude, model.at_amplitude(amplitude).ok())).1,
            };
            at_amplitude.and_then(|l| l.torque(elastic, d.direction[i]).ok()).unwrap_or_default()
        })
        .collect();
    observed.time_derivative(&torque)
}

/// +1 while the deflection rises, −1 while it falls: friction's column.
pub(super) fn direction_sign(direction: Direction) -> f64 {
    match direction {
        Direction::Rising => 1.0,
        Direction::Falling => -1.0,
    }
}

pub(super) fn kinematic_at(state: &EffectState, observed: &Observed, i: usize) -> f64 {
    if state.kinematic == [0.0; 4] {
        return 0.0;
    }
    observed.input_harmonics(i).map_or(0.0, |harmonics| kinematic_of(state, harmonics))
}

/// The kinematic error at an input angle of `harmonics` ([`Observed::input_harmonics`]).
pub(super) fn kinematic_of(state: &EffectState, harmonics: [f64; 4]) -> f64 {
    let [a, b, c, d] = state.kinematic;
    let [cos2, sin2, cos4, sin4] = harmonics;
    a * cos2 + b * sin2 + c * cos4 + d * sin4
}

/// Fits the model with the `active` effects on `subset` by Gauss–Newton on the nonlinear
/// magnitudes and r, starting from `start`.
pub fn fit_extended(
    observed: &Observed,
    subset: &[usize],
    weights: &[f64],
    active: &[Effect],
    start: &ExtendedFit,
) -> Result<ExtendedFit, ExtendedFitError> {
    let d = &observed.data;
    let reference_amplitude = median(&d.amplitude);
    let scale = subset.iter().map(|&i| d.amplitude[i]).fold(0.0, f64::max);
    let (mut params, mut r, mut state) = (start.params, start.r, start.state.clone());
    for effect in Effect::ALL.iter().filter(|e| !active.contains(e)) {
        clear(&mut state, *effect);
    }
    // The effects' columns, then one for r: a Gauss–Newton step on r instead of a line search
    // keeps each trial a few solves, so r follows every effect tried.
    let width: usize = active.iter().map(|&e| columns(e)).sum::<usize>() + 1;
    let m = subset.len();
    for effect in active {
        let variable = match effect {
            Effect::KinematicError => observed.input_angle.is_some(),
            Effect::ViscousDamping | Effect::ChannelDelay => observed.rate.is_some(),
            Effect::ThermalDrift => observed.warming.is_some(),
            Effect::Backlash | Effect::CoulombFriction | Effect::TorqueOffset => true,
        };
        if !variable {
            return Err(ExtendedFitError::Unrevealable(*effect));
        }
    }
    // With no effect, the iteration of lowest χ² is kept: Gauss–Newton steps r undamped, and on
    // the measured spring's run 4-4 (its rest 2.9 mrad off its loop's centre) it ran from RMS 2.5
    // to 32 and 502 N·m, so that the final model of no effect fitted worse than the baseline it
    // started from. With effects, the last is kept: their nonlinear states (backlash, kinematic
    // error) have stepped past the solve of that iteration, and keeping the lowest turned the
    // diagnosis corpus's seed 1000 from 0 to 4 wrong physics.
    let mut best: Option<ExtendedFit> = None;
    let mut iteration = 0;
    let mut previous_chi2 = f64::INFINITY;
    // Only the kinematic error reads the input angle's harmonics (its state is cleared when it is
    // not active).
    let kinematic = observed.input_angle.is_some() && active.contains(&Effect::KinematicError);
    loop {
        iteration += 1;
        let model = Model::new(params)?;
        let k = model.k();
        // Normal equations summed as the samples come: the per-sample columns (the samples,
        // the effects' columns and the weights) were ≥ 49 bytes a sample at 10 M samples.
        let mut normal = NormalEquations::new(scale, r, width);
        let mut row = vec![0.0; width];
        let mut amplitudes = observed.elastic_amplitudes(&state);
        let delay_column = if active.contains(&Effect::ChannelDelay) {
            torque_rate(observed, &model, &state).ok_or(ExtendedFitError::Unrevealable(Effect::ChannelDelay))?
        } else {
            Vec::new()
        };
        // The loop of the last amplitude: a leg's samples share one, and forming it costs a
        // logarithm and an exponential.
        let mut on_loop: Option<(f64, Option<model_core::Loop<f64>>)> = None;
        for &i in subset {
            // Formed once a sample: the kinematic error's value and its columns use them both.
            let input_harmonics = if kinematic { observed.input_harmonics(i) } else { None };
            let x = d.theta[i] + input_harmonics.map_or(0.0, |h| kinematic_of(&state, h));
            let elastic = backlash(x, state.backlash);
            let amplitude = amplitudes.at(i);
            let at_amplitude = match on_loop {
                Some((of, at)) if of.to_bits() == amplitude.to_bits() => at,
                _ => {
                    let at = model.at_amplitude(amplitude).ok();
                    on_loop = Some((amplitude, at));
                    at
                }
            };
            let (spring, hysteresis) =
                at_amplitude.and_then(|l| l.evaluate_parts(elastic, d.direction[i]).ok()).unwrap_or_default();
            let stiffness = spring.stiffness + hysteresis.stiffness;
            // The effects' columns fill `row` in order; `width` counted them.
            let mut column = 0;
            let mut push = |value: f64| {
                row[column] = value;
                column += 1;
            };
            for &effect in active {
                match effect {
                    Effect::Backlash => {
                        // w shifts the elastic deflection by ∓w/2 and narrows the loop by w/2:
                        // ∂T/∂A at fixed θ is z/A − (θ/A)·dz/dθ, z the hysteresis term.
                        let by_amplitude = hysteresis.torque / amplitude - elastic / amplitude * hysteresis.stiffness;
                        let inside = x.abs() <= state.backlash / 2.0;
                        let shift = if inside { 0.0 } else { -stiffness * x.signum() / 2.0 };
                        push(shift - by_amplitude / 2.0);
                    }
                    Effect::KinematicError => {
                        for value in input_harmonics.unwrap_or([1.0, 0.0, 1.0, 0.0]) {
                            push(stiffness * value);
                        }
                    }
                    Effect::CoulombFriction => push(direction_sign(d.direction[i])),
                    Effect::ViscousDamping => push(observed.rate.as_ref().map_or(0.0, |rate| rate[i])),
                    Effect::ThermalDrift => push(observed.warming.as_ref().map_or(0.0, |w| w[i]) * elastic),
                    Effect::TorqueOffset => push(1.0),
                    Effect::ChannelDelay => push(-delay_column[i]),
                };
            }
            // ∂T/∂r = k·A·|cos φ|·∂p/∂r, ∂p/∂r = sin φ − φ·e^(−rφ).
            let phase = Phase::new::<Libm>(elastic / amplitude, d.direction[i]);
            push(k * amplitude * phase.abs_cos * (phase.sin - phase.angle * (-r * phase.angle).exp()));
            normal.add(elastic, d.torque[i], &phase, amplitude, weights[i], &row);
        }
        let solution = normal.solve().ok_or(ExtendedFitError::Degenerate)?;
        params = basis::params(scale, r, &solution, reference_amplitude)?;
        let dof = (m as f64 - (4 + width) as f64).max(1.0);
        let variance = solution.weighted_rss / dof;
        // A column the data cannot determine (a backlash wider than the motion leaves its column
        // zero) makes the normal matrix singular there, and rounding leaves its inverse diagonal
        // zero or negative: its error is unbounded, not zero.
        let column_errors: Vec<f64> = (0..width)
            .map(|k| match solution.factor.inverse_diagonal(4 + k) {
                inverse if inverse > 0.0 => (variance * inverse).sqrt(),
                _ => f64::INFINITY,
            })
            .collect();
        let mut converged = true;
        let mut k = 4;
        for &effect in active {
            let c = &solution.coef[k..k + columns(effect)];
            match effect {
                Effect::Backlash => {
                    let next = (state.backlash + c[0]).max(0.0);
                    converged &= (next - state.backlash).abs() <= 1e-4 * next + 1e-12;
                    state.backlash = next;
                }
                Effect::KinematicError => {
                    let step = c.iter().map(|v| v * v).sum::<f64>().sqrt();
                    let size = state.kinematic.iter().map(|v| v * v).sum::<f64>().sqrt();
                    for (value, delta) in state.kinematic.iter_mut().zip(c) {
                        *value += delta;
                    }
                    converged &= step <= 1e-4 * size + 1e-12;
                }
                Effect::CoulombFriction => state.coulomb = c[0],
                Effect::ViscousDamping => state.viscous = c[0],
                Effect::ThermalDrift => state.thermal_gain = c[0],
                Effect::TorqueOffset => state.offset = c[0],
                Effect::ChannelDelay => state.delay = c[0],
            }
            k += columns(effect);
        }
        let step = solution.coef[k];
        converged &= step.abs() <= 1e-6 * (1.0 + r.abs());
        let fitted = ExtendedFit {
            params,
            r,
            state: state.clone(),
            active: active.to_vec(),
            chi2: solution.weighted_rss,
            n: m,
            column_errors,
        };
        if !active.is_empty() || best.as_ref().is_none_or(|best: &ExtendedFit| fitted.chi2 < best.chi2) {
            best = Some(fitted);
        }
        r = (r + step).clamp(-R_LIMIT, R_LIMIT);
        // A kinematic error's steps creep on without settling (each moves the legs' amplitudes,
        // which its column leaves out), so its fit stops once χ² has settled instead.
        let settled =
            kinematic && (previous_chi2 - solution.weighted_rss).abs() <= CHI2_SETTLED * solution.weighted_rss;
        previous_chi2 = solution.weighted_rss;
        if converged || settled || iteration == GAUSS_NEWTON_ITERATIONS {
            return best.ok_or(ExtendedFitError::Degenerate);
        }
    }
}

fn clear(state: &mut EffectState, effect: Effect) {
    match effect {
        Effect::Backlash => state.backlash = 0.0,
        Effect::KinematicError => state.kinematic = [0.0; 4],
        Effect::CoulombFriction => state.coulomb = 0.0,
        Effect::ViscousDamping => state.viscous = 0.0,
        Effect::ThermalDrift => state.thermal_gain = 0.0,
        Effect::TorqueOffset => state.offset = 0.0,
        Effect::ChannelDelay => state.delay = 0.0,
    }
}
