//! The prediction corpus shared by the benchmark (`prediction_bench.rs`, every case, figures)
//! and the system test (`prediction.rs`, the goals on a few cases): gears of five truth
//! physics recorded under five motions, the models of every kind (and `fit --model auto`'s
//! choice) fitted on one motion, run along another.
//!
//! Two stiffness errors, where the truth has a tangent (micro-slip, catalogue):
//! - **K err** ([`centre_stiffness_error`]), the goal's: K is the slope of the loop's centre
//!   curve (the mean of the rising and falling branch) on the bench sine, the spring the
//!   firmware schedules its gain on. The model and the truth are run along the same exact sine
//!   from rest; RMS over |θ| ≤ 0.95 A of the model's K minus the truth's, over the truth's RMS.
//! - **tangent err** ([`Case::stiffness_error`]): the model's dT/dθ along the measured angles (as
//!   `predict` writes it) against the truth's tangent along the true deflection, RMS over the
//!   tangent's RMS, as `bench/opensees/score.py` scores OpenSees' `getTangent`. Dominated by the
//!   few samples at the reversals (which branch's stiffness a turning point has: the elements
//!   that slip there, whose split from the spring a fit does not identify) and at the kinks (a
//!   sample off in the quantised deflection): the truth on the measured angles is 1.9 % off its
//!   own tangent on the catalogue gear's nested motion.
// The benchmark and the test each use their own part of it.
#![allow(dead_code)]
use model_core::{GearModel, Identifiable, Kind, Model, Params};
use swg_host::fit::{fit, fit_input, FitInput, FitOptions, ModelChoice};
use swg_host::input::Recording;
use swg_host::predict::{predict, Zeroing};
use swg_host::prepare::{from_recording, OfflineRun};
use swg_host::simulate::{simulate_experiment, Experiment, Motion, Physics, Simulation, Trajectory};

pub const MOTIONS: [&str; 5] = ["sine", "biased", "nested", "random", "hold"];
pub const TRAINING: [&str; 2] = ["sine", "random"];
pub const SEED: u64 = 11;

/// A genetic gear with decaying memory (r > 0) whose loop runs the passive way (h < 0).
pub fn genetic_gear() -> Params<f64> {
    Params::from_identifiable(2.2e4, 4.0e9, 0.0, Identifiable { h: -1.5, r: 1.2 }, 1.2e-3).expect("valid gear")
}

pub fn motion(name: &str) -> Motion {
    match name {
        "sine" => Motion::Sine,
        "biased" => Motion::Biased { bias_rad: None },
        "nested" => Motion::Nested,
        "random" => Motion::Random,
        "hold" => Motion::Hold { load_rad: None },
        other => panic!("no motion {other}"),
    }
}

pub fn simulation(noisy: bool) -> Simulation {
    Simulation {
        params: GearModel::paper(genetic_gear()),
        amplitude_rad: 1.168e-3,
        frequencies_hz: vec![0.5],
        cycles: 4,
        sample_rate_hz: 1000.0,
        ratio: 50.0,
        input_speed_rad_s: 0.0,
        input_bits: noisy.then_some(20),
        output_bits: noisy.then_some(20),
        torque_noise_nm: if noisy { 0.05 } else { 0.0 },
        temperature: None,
        effects: Vec::new(),
        seed: SEED,
    }
}

pub fn record(physics: &Physics, motion: Motion, noisy: bool) -> Recording {
    simulate_experiment(&Experiment {
        simulation: simulation(noisy),
        motion,
        physics: physics.clone(),
        deflection_zero_rad: 0.0,
    })
    .expect("simulation runs")
}

pub fn rms(a: &[f64], b: &[f64]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
}

pub fn max_step(t: &[f64]) -> f64 {
    t.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0, f64::max)
}

/// The models fitted to one training recording.
pub struct Fitted {
    pub symmetric: Params<f64>,
    /// The kinds fitted as `fit --model KIND` fits them, in the order asked.
    pub kinds: Vec<GearModel<f64>>,
    /// What `fit --model auto` chose, where asked.
    pub auto: Option<GearModel<f64>>,
}

impl Fitted {
    /// The model of kind `kind`.
    pub fn of(&self, kind: Kind) -> &GearModel<f64> {
        self.kinds.iter().find(|m| m.kind() == kind).expect("the kind was fitted")
    }
}

/// The symmetric rule, every kind and auto's choice, fitted to `recording`.
pub fn fit_all(recording: &Recording) -> Fitted {
    fit_some(recording, &Kind::ALL, true)
}

/// The symmetric rule, `kinds` and, where `auto`, auto's choice, fitted to `recording`.
pub fn fit_some(recording: &Recording, kinds: &[Kind], auto: bool) -> Fitted {
    let prepared = from_recording(recording).expect("segmentation");
    let options = FitOptions { noise: prepared.noise, ..FitOptions::default() };
    let symmetric = fit(&prepared.data, &options, |_| {}).expect("symmetric fit").params;
    let stateful = |choice: ModelChoice| {
        let input = FitInput::Recordings(std::slice::from_ref(recording));
        fit_input(input, choice, &[], options.seed, |_| {}).expect("fit").identified.model()
    };
    let kinds = kinds.iter().map(|&kind| stateful(ModelChoice::Kind(kind))).collect();
    Fitted { symmetric, kinds, auto: auto.then(|| stateful(ModelChoice::Auto)) }
}

/// The symmetric rule along a recording: each sample on the loop of its leg.
pub fn symmetric_prediction(params: &Params<f64>, recording: &Recording) -> Predicted {
    let prepared = from_recording(recording).expect("segmentation");
    let model = Model::new(*params).expect("valid");
    let d = &prepared.data;
    let (torque, stiffness) = (0..d.theta.len())
        .map(|i| {
            let (theta, direction, amplitude) = (d.theta[i], d.direction[i], d.amplitude[i]);
            let torque = model.torque(theta, direction, amplitude).unwrap_or(0.0);
            (torque, model.stiffness(theta, direction, amplitude).unwrap_or(0.0))
        })
        .unzip();
    Predicted { torque, stiffness }
}

/// One motion of one gear: measured, the noise-free truth, and the truth on the measured angles.
pub struct Case {
    pub motion: &'static str,
    pub measured: Recording,
    pub truth: Vec<f64>,
    pub floor: Vec<f64>,
    /// The truth's tangent stiffness along the true deflection, N·m/rad, where it has one.
    pub tangent: Option<Vec<f64>>,
    /// The first sample scored: `predict`'s start rule (the sine of the genetic gear starts on
    /// its loop, not at rest).
    pub scored_from: usize,
}

impl Case {
    /// RMS of a − b over the scored samples.
    pub fn rms(&self, a: &[f64], b: &[f64]) -> f64 {
        rms(&a[self.scored_from..], &b[self.scored_from..])
    }

    /// The stiffness error of `stiffness` (N·m/rad, one a sample): RMS of it minus the truth's
    /// tangent over the tangent's RMS, on the scored samples; `None` without a tangent.
    pub fn stiffness_error(&self, stiffness: &[f64]) -> Option<f64> {
        let tangent = &self.tangent.as_ref()?[self.scored_from..];
        let zero = vec![0.0; tangent.len()];
        Some(rms(&stiffness[self.scored_from..], tangent) / rms(tangent, &zero))
    }
}

pub fn case(physics: &Physics, name: &'static str) -> Case {
    let measured = record(physics, motion(name), true);
    let exact = record(physics, motion(name), false);
    let tangent = physics.tangent_along(&exact.deflection).expect("valid physics");
    let truth = exact.torque;
    let trajectory =
        Trajectory::new("measured angles", measured.time.clone(), measured.deflection.clone()).expect("a trajectory");
    let floor = record(physics, Motion::File(trajectory), false).torque;
    let scored_from = OfflineRun::of(&measured).scored_from;
    Case { motion: name, measured, truth, floor, tangent, scored_from }
}

/// A model's torque and stiffness along a recording.
pub struct Predicted {
    pub torque: Vec<f64>,
    pub stiffness: Vec<f64>,
}

/// `model` along `case`'s measured angles, as `predict` runs it.
pub fn prediction(model: &GearModel<f64>, case: &Case) -> Predicted {
    let prediction = predict(model, &case.measured, None, Zeroing::RestWindow).expect("runs");
    Predicted { torque: prediction.torque, stiffness: prediction.stiffness }
}

/// Along `case`: the symmetric rule, then each kind fitted in its order, then auto's choice.
pub fn predictions(fitted: &Fitted, case: &Case) -> Vec<Predicted> {
    std::iter::once(symmetric_prediction(&fitted.symmetric, &case.measured))
        .chain(fitted.kinds.iter().chain(&fitted.auto).map(|model| prediction(model, case)))
        .collect()
}

/// Points on the loop's centre-curve grid: |θ| ≤ 0.95 A in steps of A/50.
const CENTRE_GRID: usize = 95;

/// The slope of the centre curve of the last cycle of a sine recording (deflection `theta`,
/// torque `torque`, `per_cycle` samples a cycle) at the midpoints of the grid: see [`CENTRE_GRID`].
pub fn centre_slope(theta: &[f64], torque: &[f64], per_cycle: usize, amplitude: f64) -> Vec<f64> {
    let start = theta.len() - per_cycle;
    let (mut rising, mut falling) = (Vec::new(), Vec::new());
    for i in start..theta.len() - 1 {
        let point = (theta[i], torque[i]);
        if theta[i + 1] > theta[i] {
            rising.push(point);
        } else if theta[i + 1] < theta[i] {
            falling.push(point);
        }
    }
    let at = |branch: &mut Vec<(f64, f64)>, x: f64| -> f64 {
        branch.sort_by(|a, b| a.0.total_cmp(&b.0));
        let j = branch.partition_point(|p| p.0 < x).clamp(1, branch.len() - 1);
        let ((x0, t0), (x1, t1)) = (branch[j - 1], branch[j]);
        t0 + (t1 - t0) * (x - x0) / (x1 - x0)
    };
    let step = amplitude / 50.0;
    let centre: Vec<f64> = (0..=CENTRE_GRID)
        .map(|j| {
            let x = -0.95 * amplitude + j as f64 * step;
            0.5 * (at(&mut rising, x) + at(&mut falling, x))
        })
        .collect();
    centre.windows(2).map(|w| (w[1] - w[0]) / step).collect()
}

/// K err: the model's centre-curve slope on the bench sine against the truth's, RMS of the
/// difference over the truth's RMS (see the module's documentation); `None` for a physics
/// without a tangent.
pub fn centre_stiffness_error(physics: &Physics, model: &GearModel<f64>) -> Option<f64> {
    physics.tangent_along(&[0.0]).expect("valid physics")?;
    let sim = simulation(false);
    let exact = record(physics, Motion::Sine, false);
    let per_cycle = (sim.sample_rate_hz / sim.frequencies_hz[0]).round() as usize;
    let modelled = predict(model, &exact, None, Zeroing::RestWindow).expect("runs").torque;
    let truth = centre_slope(&exact.deflection, &exact.torque, per_cycle, sim.amplitude_rad);
    let fitted = centre_slope(&exact.deflection, &modelled, per_cycle, sim.amplitude_rad);
    let zero = vec![0.0; truth.len()];
    Some(rms(&fitted, &truth) / rms(&truth, &zero))
}
