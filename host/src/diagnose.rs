//! Where the fitted model and a recording disagree, which physics the model leaves out, and
//! how much better the model gets with it.
//!
//! Every effect of [`Effect`] enters the fit as extra linear columns beside the model's own:
//! torque effects directly (friction ±1 by direction, damping the deflection rate, drift the
//! warming times θ, an offset 1), deflection effects (backlash, kinematic error) as
//! Gauss–Newton columns K·∂θ_elastic/∂magnitude, iterated to convergence. So an effect costs
//! a few weighted least-squares solves, and a greedy search can try each one.
//!
//! An effect is accepted only on strong evidence: the Bayesian information criterion must
//! drop by more than 10 (Kass & Raftery's "very strong"), the effect must explain at least
//! 5 % of the remaining weighted residual (a concealed effect at half the noise explains
//! 20 %: smaller gains are what model mismatch and noise structure produce), and the two
//! independent halves of the recording, fitted alone, must each show it clearly (|z| > 3)
//! with magnitudes within ±25 % of their mean.
use crate::effects::{backlash, Effect};
use crate::fit::{median, total_noise_weights, Basis, FitData, NoiseModel, R_LIMIT};
use crate::input::{Dataset, Recording};
use crate::prepare::Prepared;
use model_core::{Direction, Model, Params};
use rayon::prelude::*;
use serde::Serialize;

/// ΔBIC an effect must reach.
pub const MIN_BIC_DROP: f64 = 10.0;
/// Share of the weighted residual an effect must explain.
pub const MIN_EXPLAINED: f64 = 0.05;
/// Significance each half must show.
pub const MIN_HALF_Z: f64 = 3.0;
/// Largest difference of the halves' magnitudes, relative to their mean.
pub const MAX_HALF_SPREAD: f64 = 0.5;
const GAUSS_NEWTON_ITERATIONS: usize = 10;

/// What the recording offers the diagnosis, sample by sample.
#[derive(Clone, Debug)]
pub struct Observed {
    pub data: FitData,
    pub noise: Option<NoiseModel>,
    pub time: Option<Vec<f64>>,
    /// Deflection rate, rad/s (local slope).
    pub rate: Option<Vec<f64>>,
    /// Input (wave generator) angle, rad, when the input turns at least once.
    pub input_angle: Option<Vec<f64>>,
    /// Temperature minus the temperature at the start, K, when it changes.
    pub warming: Option<Vec<f64>>,
    /// Two independent parts of the data, for the consistency check.
    pub parts: [Vec<usize>; 2],
    /// Fit on `training`, judge on `held_out`.
    pub training: Vec<usize>,
    pub held_out: Vec<usize>,
    /// Effects this data cannot reveal, with why.
    pub cannot_reveal: Vec<(Effect, String)>,
    /// For each sample of a recording, the two ends of its leg as (deflection, sample index):
    /// the kinematic error moves the elastic turning points, and with them the amplitude.
    leg_ends: Option<Vec<[(f64, usize); 2]>>,
}

impl Observed {
    pub fn new(dataset: &Dataset, prepared: &Prepared) -> Observed {
        let data = prepared.data.clone();
        let n = data.theta.len();
        let mut observed = Observed {
            noise: prepared.noise,
            time: None,
            rate: None,
            input_angle: None,
            warming: None,
            parts: [Vec::new(), Vec::new()],
            training: Vec::new(),
            held_out: Vec::new(),
            cannot_reveal: Vec::new(),
            leg_ends: None,
            data,
        };
        match dataset {
            Dataset::Recording(recording) => observed.add_recording(recording, prepared),
            Dataset::LoopTable(_) => {
                // Alternate points of each branch: both parts see every branch.
                let mut seen = std::collections::HashMap::new();
                for i in 0..n {
                    let k: &mut usize = seen.entry(prepared.branch[i]).or_default();
                    observed.parts[*k % 2].push(i);
                    if *k % 4 == 3 {
                        observed.held_out.push(i)
                    } else {
                        observed.training.push(i)
                    }
                    *k += 1;
                }
                for (effect, why) in [
                    (Effect::ViscousDamping, "a loop table has no time, so no deflection rate"),
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

    fn add_recording(&mut self, recording: &Recording, prepared: &Prepared) {
        let n = recording.time.len();
        self.parts = [(0..n / 2).collect(), (n / 2..n).collect()];
        let split = n * 3 / 4;
        self.training = (0..split).collect();
        self.held_out = (split..n).collect();
        let legs = prepared.segmentation.as_ref().map_or(n, |s| n / (s.turning_points.len() + 1).max(1));
        self.rate = Some(local_slope(&recording.time, &recording.deflection, (legs / 50).max(2)));
        self.time = Some(recording.time.clone());
        if let Some(segmentation) = &prepared.segmentation {
            let theta = &recording.deflection;
            let mut ends = Vec::with_capacity(n);
            let mut start = (theta[0], 0);
            for tp in &segmentation.turning_points {
                ends.resize(tp.index + 1, [start, (tp.deflection, tp.index)]);
                start = (tp.deflection, tp.index);
            }
            ends.resize(n, [start, (theta[n - 1], n - 1)]);
            self.leg_ends = Some(ends);
        }
        match &recording.angles {
            Some(angles) => {
                let (lo, hi) = min_max(&angles.input);
                if hi - lo >= std::f64::consts::TAU {
                    self.input_angle = Some(angles.input.clone());
                } else {
                    self.cannot_reveal.push((
                        Effect::KinematicError,
                        format!("the input turned {:.2} rad, less than one revolution", hi - lo),
                    ));
                }
            }
            None => self.cannot_reveal.push((Effect::KinematicError, "the recording has no input angle".into())),
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
    fn elastic_amplitude(&self, state: &EffectState, i: usize) -> f64 {
        let measured = match &self.leg_ends {
            Some(ends) if state.kinematic != [0.0; 4] => {
                ends[i].iter().map(|&(theta, j)| (theta + kinematic_at(state, self, j)).abs()).fold(0.0, f64::max)
            }
            _ => self.data.amplitude[i],
        };
        (measured - state.backlash / 2.0).max(f64::MIN_POSITIVE)
    }
}

fn min_max(values: &[f64]) -> (f64, f64) {
    values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)))
}

/// Slope of a least-squares line through the `half` samples either side of each sample, in
/// O(n) from running sums: the deflection rate without the encoder's quantisation steps.
pub fn local_slope(time: &[f64], x: &[f64], half: usize) -> Vec<f64> {
    let n = x.len();
    let prefix = |f: &dyn Fn(usize) -> f64| {
        let mut p = Vec::with_capacity(n + 1);
        p.push(0.0);
        for i in 0..n {
            p.push(p[i] + f(i));
        }
        p
    };
    // Times relative to the first sample keep the sums well conditioned.
    let t = |i: usize| time[i] - time[0];
    let (st, sx, stt, stx) = (prefix(&|i| t(i)), prefix(&|i| x[i]), prefix(&|i| t(i) * t(i)), prefix(&|i| t(i) * x[i]));
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
            let m = (b - a) as f64;
            let (mt, mx) = ((st[b] - st[a]) / m, (sx[b] - sx[a]) / m);
            let var = (stt[b] - stt[a]) / m - mt * mt;
            let cov = (stx[b] - stx[a]) / m - mt * mx;
            if var > 0.0 {
                cov / var
            } else {
                0.0
            }
        })
        .collect()
}

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

fn columns(effect: Effect) -> usize {
    if effect == Effect::KinematicError {
        4
    } else {
        1
    }
}

impl ExtendedFit {
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
    fn kinematic_vector(&self) -> (f64, f64) {
        (self.state.kinematic[0], self.state.kinematic[1])
    }

    /// Torque the extended model predicts for sample `i`.
    pub fn predict(&self, observed: &Observed, model: &Model<f64>, i: usize) -> Option<f64> {
        let d = &observed.data;
        let s = &self.state;
        let x = d.theta[i] + kinematic_at(s, observed, i);
        let elastic = backlash(x, s.backlash);
        let amplitude = observed.elastic_amplitude(s, i);
        let sign = direction_sign(d.direction[i]);
        let rate = observed.rate.as_ref().map_or(0.0, |r| r[i]);
        let warming = observed.warming.as_ref().map_or(0.0, |w| w[i]);
        Some(
            model.torque(elastic, d.direction[i], amplitude).ok()?
                + s.coulomb * sign
                + s.viscous * rate
                + s.thermal_gain * warming * elastic
                + s.offset,
        )
    }

    /// Measured minus predicted torque on `subset`.
    pub fn residuals(&self, observed: &Observed, subset: &[usize]) -> Option<Vec<f64>> {
        let model = Model::new(self.params).ok()?;
        subset.iter().map(|&i| Some(observed.data.torque[i] - self.predict(observed, &model, i)?)).collect()
    }
}

fn direction_sign(direction: Direction) -> f64 {
    match direction {
        Direction::Rising => 1.0,
        Direction::Falling => -1.0,
    }
}

fn kinematic_at(state: &EffectState, observed: &Observed, i: usize) -> f64 {
    match &observed.input_angle {
        Some(angle) => {
            let [a, b, c, d] = state.kinematic;
            let psi = angle[i];
            a * (2.0 * psi).cos() + b * (2.0 * psi).sin() + c * (4.0 * psi).cos() + d * (4.0 * psi).sin()
        }
        None => 0.0,
    }
}

/// Fits the model with the `active` effects on `subset` by Gauss–Newton on the nonlinear
/// magnitudes and r, starting from `start`.
pub fn fit_extended(
    observed: &Observed,
    subset: &[usize],
    weights: &[f64],
    active: &[Effect],
    start: &ExtendedFit,
) -> Option<ExtendedFit> {
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
    let mut result = None;
    for _ in 0..GAUSS_NEWTON_ITERATIONS {
        let model = Model::new(params).ok()?;
        let r_of_params = params.beta / params.omega;
        let k = params.alpha / (params.omega * (1.0 + r_of_params * r_of_params));
        let mut sub = FitData {
            theta: Vec::with_capacity(m),
            torque: Vec::with_capacity(m),
            direction: Vec::with_capacity(m),
            amplitude: Vec::with_capacity(m),
        };
        let mut extra = vec![Vec::with_capacity(m); width];
        for &i in subset {
            let x = d.theta[i] + kinematic_at(&state, observed, i);
            let elastic = backlash(x, state.backlash);
            let amplitude = observed.elastic_amplitude(&state, i);
            let (torque, stiffness) = model
                .at_amplitude(amplitude)
                .and_then(|l| l.evaluate(elastic, d.direction[i]))
                .map_or((0.0, 0.0), |e| (e.torque, e.stiffness));
            sub.theta.push(elastic);
            sub.torque.push(d.torque[i]);
            sub.direction.push(d.direction[i]);
            sub.amplitude.push(amplitude);
            let mut column = extra.iter_mut();
            for &effect in active {
                match effect {
                    Effect::Backlash => {
                        // w shifts the elastic deflection by ∓w/2 and narrows the loop by w/2:
                        // ∂T/∂A at fixed θ is z/A − (θ/A)·dz/dθ, z the hysteresis term.
                        let (c1, c2, c3) = (params.c1, params.c2, params.c3);
                        let e2 = elastic * elastic;
                        let z = torque - elastic * (c1 + e2 * (c2 + e2 * c3));
                        let dz = stiffness - (c1 + e2 * (3.0 * c2 + 5.0 * c3 * e2));
                        let by_amplitude = z / amplitude - elastic / amplitude * dz;
                        let inside = x.abs() <= state.backlash / 2.0;
                        let shift = if inside { 0.0 } else { -stiffness * x.signum() / 2.0 };
                        column.next()?.push(shift - by_amplitude / 2.0);
                    }
                    Effect::KinematicError => {
                        let psi = observed.input_angle.as_ref()?[i];
                        for value in [(2.0 * psi).cos(), (2.0 * psi).sin(), (4.0 * psi).cos(), (4.0 * psi).sin()] {
                            column.next()?.push(stiffness * value);
                        }
                    }
                    Effect::CoulombFriction => column.next()?.push(direction_sign(d.direction[i])),
                    Effect::ViscousDamping => column.next()?.push(observed.rate.as_ref()?[i]),
                    Effect::ThermalDrift => column.next()?.push(observed.warming.as_ref()?[i] * elastic),
                    Effect::TorqueOffset => column.next()?.push(1.0),
                }
            }
            // ∂T/∂r = k·A·|cos φ|·(sin φ − φ·e^(−rφ)).
            let x = (elastic / amplitude).clamp(-1.0, 1.0);
            let phase = match d.direction[i] {
                Direction::Rising => x.asin(),
                Direction::Falling => std::f64::consts::PI - x.asin(),
            };
            let abs_cos = ((1.0 - x) * (1.0 + x)).sqrt();
            column.next()?.push(k * amplitude * abs_cos * (x - phase * (-r * phase).exp()));
        }
        let sub_weights = subset.iter().map(|&i| weights[i]).collect();
        let basis = Basis::new(&sub, 0..m, scale).with_weights(sub_weights).with_extra(extra);
        let solution = basis.solve(r)?;
        params = basis.params(r, &solution, reference_amplitude).ok()?;
        let dof = (m as f64 - (4 + width) as f64).max(1.0);
        let variance = solution.weighted_rss / dof;
        let column_errors: Vec<f64> =
            (0..width).map(|k| (variance * solution.factor.inverse_diagonal(4 + k)).max(0.0).sqrt()).collect();
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
            }
            k += columns(effect);
        }
        let step = solution.coef[k];
        converged &= step.abs() <= 1e-6 * (1.0 + r.abs());
        let fitted_r = r;
        r = (r + step).clamp(-R_LIMIT, R_LIMIT);
        result = Some(ExtendedFit {
            params,
            r: fitted_r,
            state: state.clone(),
            active: active.to_vec(),
            chi2: solution.weighted_rss,
            n: m,
            column_errors,
        });
        if converged {
            break;
        }
    }
    result
}

fn clear(state: &mut EffectState, effect: Effect) {
    match effect {
        Effect::Backlash => state.backlash = 0.0,
        Effect::KinematicError => state.kinematic = [0.0; 4],
        Effect::CoulombFriction => state.coulomb = 0.0,
        Effect::ViscousDamping => state.viscous = 0.0,
        Effect::ThermalDrift => state.thermal_gain = 0.0,
        Effect::TorqueOffset => state.offset = 0.0,
    }
}

/// The numbers behind accepting or rejecting an effect.
#[derive(Clone, Debug, Serialize)]
pub struct Evidence {
    /// Drop of the Bayesian information criterion, Δχ²/s² − p·ln n.
    pub delta_bic: f64,
    /// Share of the weighted residual the effect explains.
    pub explained: f64,
    /// Magnitude over its standard error on the whole recording.
    pub z: f64,
    /// Magnitudes fitted on each independent half alone.
    pub halves: Option<[f64; 2]>,
    pub halves_z: Option<[f64; 2]>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Finding {
    pub effect: &'static str,
    pub magnitude: f64,
    pub unit: &'static str,
    pub meaning: &'static str,
    #[serde(rename = "where")]
    pub location: String,
    /// Unweighted RSS, (N·m)², before and after adding this effect.
    pub rss_before: f64,
    pub rss_after: f64,
    pub evidence: Evidence,
}

#[derive(Clone, Debug, Serialize)]
pub struct Rejection {
    pub effect: &'static str,
    pub reason: String,
    pub magnitude: f64,
    pub evidence: Evidence,
}

/// The result of [`diagnose`].
#[derive(Clone, Debug)]
pub struct Diagnosis {
    pub baseline: ExtendedFit,
    pub findings: Vec<Finding>,
    pub rejected: Vec<Rejection>,
    pub final_fit: ExtendedFit,
    pub weights: Vec<f64>,
    /// RMS on the held-out part, N·m, of the baseline and the final model fitted without it.
    pub held_out_rms: Option<(f64, f64)>,
}

#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    #[error(transparent)]
    Segment(#[from] crate::segment::SegmentError),
    #[error("baseline fit failed: {0}")]
    Fit(#[from] crate::fit::FitError),
    #[error("the model with effects could not be fitted to this data")]
    Unfittable,
}

/// Everything `swg-host diagnose` does short of printing: prepare the data, fit the baseline
/// (unless `baseline` is given), and search for missing physics.
pub fn diagnose_dataset(
    dataset: &Dataset,
    baseline: Option<Params<f64>>,
    seed: u64,
) -> Result<(Observed, Diagnosis), DiagnoseError> {
    let prepared = crate::prepare::prepare(dataset)?;
    let baseline = match baseline {
        Some(params) => params,
        None => {
            let options = crate::fit::FitOptions { seed, noise: prepared.noise, ..Default::default() };
            crate::fit::fit(&prepared.data, &options, |_| {})?.params
        }
    };
    let observed = Observed::new(dataset, &prepared);
    let diagnosis = diagnose(&observed, baseline).ok_or(DiagnoseError::Unfittable)?;
    Ok((observed, diagnosis))
}

/// Runs the greedy search for missing physics from the `baseline` parameters.
pub fn diagnose(observed: &Observed, baseline_params: Params<f64>) -> Option<Diagnosis> {
    let n = observed.data.theta.len();
    let all: Vec<usize> = (0..n).collect();
    let baseline_model = Model::new(baseline_params).ok()?;
    let weights = match &observed.noise {
        Some(noise) => total_noise_weights(&observed.data, &baseline_model, noise).ok()?,
        None => vec![1.0; n],
    };
    let r = baseline_model.r();
    let seed = ExtendedFit {
        params: baseline_params,
        r,
        state: EffectState::default(),
        active: Vec::new(),
        chi2: f64::INFINITY,
        n,
        column_errors: Vec::new(),
    };
    let baseline = fit_extended(observed, &all, &weights, &[], &seed)?;
    let mut current = baseline.clone();
    let mut findings = Vec::new();
    let mut rejected = Vec::new();
    let ln_n = (n as f64).ln();
    loop {
        let candidates: Vec<Effect> =
            observed.revealable().into_iter().filter(|e| !current.active.contains(e)).collect();
        let variance = current.chi2 / (n as f64 - current.degrees_of_freedom() as f64).max(1.0);
        let mut trials: Vec<(Effect, ExtendedFit, Evidence)> = candidates
            .par_iter()
            .filter_map(|&effect| {
                let mut active = current.active.clone();
                active.push(effect);
                let fit = fit_extended(observed, &all, &weights, &active, &current)?;
                let drop = (current.chi2 - fit.chi2).max(0.0);
                let evidence = Evidence {
                    delta_bic: drop / variance - columns(effect) as f64 * ln_n,
                    explained: drop / current.chi2,
                    z: fit.magnitude(effect) / fit.magnitude_error(effect),
                    halves: None,
                    halves_z: None,
                };
                Some((effect, fit, evidence))
            })
            .collect();
        trials.sort_by(|a, b| b.2.explained.total_cmp(&a.2.explained));
        let mut accepted = None;
        rejected.clear();
        for (effect, fit, mut evidence) in trials {
            let magnitude = fit.magnitude(effect);
            let reason = if evidence.delta_bic < MIN_BIC_DROP {
                Some(format!("information criterion drops by {:.1}, less than {MIN_BIC_DROP}", evidence.delta_bic))
            } else if evidence.explained < MIN_EXPLAINED {
                Some(format!(
                    "explains {:.1} % of the residual, less than {:.0} %",
                    100.0 * evidence.explained,
                    100.0 * MIN_EXPLAINED
                ))
            } else if accepted.is_some() {
                Some("weaker than the effect accepted in this round; tried again next round".into())
            } else {
                halves_check(observed, &weights, &current, &fit, effect, &mut evidence)
            };
            match reason {
                Some(reason) => rejected.push(Rejection { effect: effect.name(), reason, magnitude, evidence }),
                None => accepted = Some((effect, fit, evidence)),
            }
        }
        let Some((effect, fit, evidence)) = accepted else { break };
        let rss_before = unweighted_rss(observed, &current, &all)?;
        let rss_after = unweighted_rss(observed, &fit, &all)?;
        findings.push(Finding {
            effect: effect.name(),
            magnitude: fit.magnitude(effect),
            unit: effect.unit(),
            meaning: effect.magnitude_meaning(),
            location: location_words(effect, &fit),
            rss_before,
            rss_after,
            evidence,
        });
        current = fit;
    }
    let final_fit = fit_extended(observed, &all, &weights, &current.active.clone(), &current)?;
    for finding in &mut findings {
        if let Ok(effect) = finding.effect.parse::<Effect>() {
            finding.magnitude = final_fit.magnitude(effect);
        }
    }
    let held_out_rms = held_out(observed, &weights, &baseline, &final_fit);
    Some(Diagnosis { baseline, findings, rejected, final_fit, weights, held_out_rms })
}

/// Fits each half alone; `None` when both show the effect clearly and agree.
fn halves_check(
    observed: &Observed,
    weights: &[f64],
    current: &ExtendedFit,
    fit: &ExtendedFit,
    effect: Effect,
    evidence: &mut Evidence,
) -> Option<String> {
    let halves: Vec<Option<ExtendedFit>> =
        observed.parts.par_iter().map(|part| fit_extended(observed, part, weights, &fit.active, current)).collect();
    let (Some(a), Some(b)) = (&halves[0], &halves[1]) else {
        return Some("could not be fitted on each half alone".into());
    };
    let (ma, mb) = (a.magnitude(effect), b.magnitude(effect));
    let (za, zb) = (ma / a.magnitude_error(effect), mb / b.magnitude_error(effect));
    evidence.halves = Some([ma, mb]);
    evidence.halves_z = Some([za, zb]);
    let full = fit.magnitude(effect);
    let spread = if effect == Effect::KinematicError {
        let ((xa, ya), (xb, yb)) = (a.kinematic_vector(), b.kinematic_vector());
        (xa - xb).hypot(ya - yb)
    } else {
        (ma - mb).abs()
    };
    if effect == Effect::Backlash && full <= 0.0 {
        Some("the dead band width fits to zero".into())
    } else if za.abs() < MIN_HALF_Z || zb.abs() < MIN_HALF_Z {
        Some(format!("not clear in both halves alone (z = {za:.1} and {zb:.1})"))
    } else if ma.signum() != mb.signum() || spread > MAX_HALF_SPREAD * (ma + mb).abs() / 2.0 {
        Some(format!("the halves disagree: {ma:.4e} and {mb:.4e} {}", effect.unit()))
    } else {
        None
    }
}

fn unweighted_rss(observed: &Observed, fit: &ExtendedFit, subset: &[usize]) -> Option<f64> {
    Some(fit.residuals(observed, subset)?.iter().map(|r| r * r).sum())
}

/// RMS on the held-out samples of each model refitted on the training samples only.
fn held_out(
    observed: &Observed,
    weights: &[f64],
    baseline: &ExtendedFit,
    final_fit: &ExtendedFit,
) -> Option<(f64, f64)> {
    if observed.held_out.is_empty() || observed.training.len() < 10 {
        return None;
    }
    let rms = |fit: &ExtendedFit| {
        let trained = fit_extended(observed, &observed.training, weights, &fit.active, fit)?;
        let residuals = trained.residuals(observed, &observed.held_out)?;
        Some((residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len() as f64).sqrt())
    };
    Some((rms(baseline)?, rms(final_fit)?))
}

fn location_words(effect: Effect, fit: &ExtendedFit) -> String {
    let s = &fit.state;
    match effect {
        Effect::Backlash => format!(
            "around zero torque: the deflection jumps by {:.3e} rad while the torque crosses zero",
            s.backlash
        ),
        Effect::CoulombFriction => format!(
            "on both directions, the whole loop: the torque is {} N·m higher while the deflection rises than while it falls",
            torque(2.0 * s.coulomb)
        ),
        Effect::ViscousDamping => {
            "grows with the deflection rate: largest where the loop crosses zero deflection, zero at the turning points".into()
        }
        Effect::KinematicError => format!(
            "periodic in the input angle: 2 cycles per input revolution ({:.3e} rad), 4 per revolution {:.3e} rad",
            s.kinematic[0].hypot(s.kinematic[1]),
            s.kinematic[2].hypot(s.kinematic[3])
        ),
        Effect::ThermalDrift => {
            "drifts with temperature: the loop's slope changes as the gear warms".into()
        }
        Effect::TorqueOffset => "everywhere: the whole loop is shifted in torque".into(),
    }
}

/// One pattern in the baseline residuals, in numbers and words.
#[derive(Clone, Debug, Serialize)]
pub struct Observation {
    pub pattern: &'static str,
    pub value: f64,
    pub unit: &'static str,
    pub words: String,
}

/// Where the baseline residuals concentrate.
pub fn locate(observed: &Observed, residuals: &[f64]) -> Vec<Observation> {
    let d = &observed.data;
    let n = residuals.len();
    let rms_of = |keep: &dyn Fn(usize) -> bool| {
        let (sum, count) =
            (0..n).filter(|&i| keep(i)).fold((0.0, 0usize), |(s, c), i| (s + residuals[i] * residuals[i], c + 1));
        if count == 0 {
            f64::NAN
        } else {
            (sum / count as f64).sqrt()
        }
    };
    let mut out = Vec::new();

    let near = |i: usize| d.theta[i].abs() >= 0.9 * d.amplitude[i];
    let (near_rms, far_rms) = (rms_of(&near), rms_of(&|i| !near(i)));
    if near_rms.is_finite() && far_rms.is_finite() {
        out.push(Observation {
            pattern: "turning_points",
            value: near_rms / far_rms,
            unit: "ratio",
            words: format!(
                "near the turning points (|θ| ≥ 0.9·A) the residual RMS is {} N·m, {:.1}× the {} N·m elsewhere",
                torque(near_rms),
                near_rms / far_rms,
                torque(far_rms)
            ),
        });
    }

    let peak = d.torque.iter().map(|t| t.abs()).fold(0.0, f64::max);
    let low = |i: usize| d.torque[i].abs() < 0.1 * peak;
    let (low_rms, high_rms) = (rms_of(&low), rms_of(&|i| !low(i)));
    if low_rms.is_finite() && high_rms.is_finite() {
        out.push(Observation {
            pattern: "zero_torque",
            value: low_rms / high_rms,
            unit: "ratio",
            words: format!(
                "around zero torque (|T| < 10 % of the peak) the residual RMS is {} N·m, {:.1}× the {} N·m at load",
                torque(low_rms),
                low_rms / high_rms,
                torque(high_rms)
            ),
        });
    }

    let mean_of = |keep: &dyn Fn(usize) -> bool| {
        let (sum, count) = (0..n).filter(|&i| keep(i)).fold((0.0, 0usize), |(s, c), i| (s + residuals[i], c + 1));
        if count == 0 {
            0.0
        } else {
            sum / count as f64
        }
    };
    let gap = mean_of(&|i| d.direction[i] == Direction::Rising) - mean_of(&|i| d.direction[i] == Direction::Falling);
    out.push(Observation {
        pattern: "direction",
        value: gap,
        unit: "N·m",
        words: format!(
            "by direction: the residual averages {}{} N·m more while the deflection rises than while it falls",
            if gap >= 0.0 { "+" } else { "" },
            torque(gap)
        ),
    });

    if let Some(rate) = &observed.rate {
        let slope = regression_slope(rate, residuals);
        let peak_rate = rate.iter().map(|r| r.abs()).fold(0.0, f64::max);
        out.push(Observation {
            pattern: "rate",
            value: slope,
            unit: "N·m·s/rad",
            words: format!(
                "with rate: the residual grows by {slope:.4e} N·m per rad/s of deflection rate ({} N·m at the fastest {peak_rate:.3e} rad/s)",
                torque(slope * peak_rate)
            ),
        });
    }

    if let Some(angle) = &observed.input_angle {
        let (order, amplitude) = (1..=6)
            .map(|k| {
                let (mut c, mut s, mut cc, mut ss) = (0.0, 0.0, 0.0, 0.0);
                for i in 0..n {
                    let (cos, sin) = ((k as f64 * angle[i]).cos(), (k as f64 * angle[i]).sin());
                    c += cos * residuals[i];
                    s += sin * residuals[i];
                    cc += cos * cos;
                    ss += sin * sin;
                }
                (k, (c / cc).hypot(s / ss))
            })
            .fold((0, 0.0), |best, x| if x.1 > best.1 { x } else { best });
        out.push(Observation {
            pattern: "input_angle",
            value: amplitude,
            unit: "N·m",
            words: format!(
                "periodic in the input angle: strongest at {order} cycle{} per input revolution, {} N·m",
                if order == 1 { "" } else { "s" },
                torque(amplitude)
            ),
        });
    }

    if let Some(time) = &observed.time {
        let slope = regression_slope(time, residuals);
        let span = time.last().copied().unwrap_or(0.0) - time.first().copied().unwrap_or(0.0);
        out.push(Observation {
            pattern: "time",
            value: slope,
            unit: "N·m/s",
            words: format!(
                "over time: the residual drifts by {} N·m over the {span:.1} s recording",
                torque(slope * span)
            ),
        });
    }
    if let Some(warming) = &observed.warming {
        let load: Vec<f64> = (0..n).map(|i| warming[i] * d.theta[i]).collect();
        let slope = regression_slope(&load, residuals);
        out.push(Observation {
            pattern: "temperature",
            value: slope,
            unit: "N·m/(rad·K)",
            words: format!("with temperature: the loop's slope changes by {slope:.4e} N·m/rad per kelvin of warming"),
        });
    }
    out
}

/// A torque in N·m for the report: four decimals, or four significant digits when smaller
/// (a noise-free recording's residuals are micro-newton-metres, not 0.0000).
fn torque(value: f64) -> String {
    if value == 0.0 || value.abs() >= 0.01 {
        format!("{value:.4}")
    } else {
        format!("{value:.3e}")
    }
}

fn regression_slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
    }
    if sxx > 0.0 {
        sxy / sxx
    } else {
        0.0
    }
}
