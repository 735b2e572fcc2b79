//! Synthetic bench recordings: a deflection motion (today's sine, or one of [`Motion`]'s)
//! played through a gear's truth physics (the params file's genetic model, or one of
//! [`Physics`]'s that the model is not), plus sensor noise, quantised input/output encoders,
//! and the physical effects of [`crate::diagnose::effects`] on request.
//!
//! [`simulate`] plays [`Simulation`] as it always has (sine, genetic); [`simulate_experiment`]
//! plays an [`Experiment`], a simulation with its motion and physics.
pub mod motion;
pub mod physics;

use crate::diagnose::effects::{backlash, kinematic_error, Effect, EffectValue};
use crate::input::{deflection, Angles, InputError, Recording, MAX_DEFLECTION_RAD, MAX_TORQUE_NM};
use model_core::{Direction, Evaluator, GearModel, Hysteretic, Model};
pub use motion::{read_trajectory, Motion, Trajectory};
use motion::{PlayError, Played, Timing};
use physics::Gear;
pub use physics::{read_physics_params, BoucWen, Catalogue, MicroSlip, Physics, PhysicsParamError, Preisach};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::f64::consts::TAU;

#[derive(Clone, Debug, PartialEq)]
pub struct Simulation {
    /// The gear's model, the truth of [`Physics::Model`].
    pub params: GearModel<f64>,
    /// Deflection amplitude A, rad.
    pub amplitude_rad: f64,
    /// Excitation frequencies, played one after the other, Hz.
    pub frequencies_hz: Vec<f64>,
    /// Whole cycles at each frequency.
    pub cycles: u32,
    pub sample_rate_hz: f64,
    /// Gear reduction ratio N.
    pub ratio: f64,
    /// Input (wave generator) speed, rad/s; 0 for a locked input.
    pub input_speed_rad_s: f64,
    /// Encoder resolutions, bits per revolution; `None` for exact angles.
    pub input_bits: Option<u32>,
    pub output_bits: Option<u32>,
    /// Standard deviation of the torque sensor's noise, N·m.
    pub torque_noise_nm: f64,
    /// Temperature at the start, °C, and its rise, K/s; `None` for no temperature column.
    pub temperature: Option<(f64, f64)>,
    /// Physics the model leaves out, added to what is written.
    pub effects: Vec<EffectValue>,
    pub seed: u64,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimulateError {
    #[error("invalid parameters: {0}")]
    Params(#[from] model_core::Error),
    #[error("{name} must be {expected}, got {value}")]
    OutOfRange { name: &'static str, expected: &'static str, value: f64 },
    #[error("thermal_drift needs a temperature column: add --temperature (and --temperature-rise)")]
    NeedsTemperature,
    #[error("the recording would have {0} samples; at most {MAX_SAMPLES} are written")]
    TooLong(f64),
    #[error(
        "the simulated torque reaches {torque:e} N·m at t = {time} s, beyond any gear (|T| ≤ 10⁶ N·m, what the readers \
         accept): an effect or parameter is far too large"
    )]
    TorqueBeyondAnyGear { torque: f64, time: f64 },
    #[error(transparent)]
    PhysicsParam(#[from] PhysicsParamError),
    #[error(transparent)]
    Plan(InputError),
    #[error(
        "{plan}: the gear's torque reaches {torque:.4} N·m at t = {time} s, beyond the plan's limit of {limit} N·m: the \
         joint would stop the experiment there; lower the plan's deflection or raise its torque limit"
    )]
    PlanTorqueLimit { plan: String, torque: f64, time: f64, limit: f32 },
}

/// A simulation with the motion it plays, the gear's truth physics and where the encoders were
/// zeroed: what `swg-host simulate` runs. From a [`Simulation`] alone: today's sine through the
/// genetic model, encoders zeroed at the gear's true zero.
#[derive(Clone, Debug, PartialEq)]
pub struct Experiment {
    pub simulation: Simulation,
    pub motion: Motion,
    pub physics: Physics,
    /// The deflection's zero θ0, rad: the encoders were zeroed off the gear's true zero, so
    /// every recorded deflection is the true one + θ0 (the output encoder reads θ0 less).
    pub deflection_zero_rad: f64,
}

impl From<Simulation> for Experiment {
    fn from(simulation: Simulation) -> Self {
        Experiment { simulation, motion: Motion::Sine, physics: Physics::Model, deflection_zero_rad: 0.0 }
    }
}

pub const MAX_SAMPLES: f64 = 50e6;

fn check(name: &'static str, value: f64, ok: bool, expected: &'static str) -> Result<(), SimulateError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(SimulateError::OutOfRange { name, expected, value })
    }
}

impl Simulation {
    fn validate(&self) -> Result<(), SimulateError> {
        check("amplitude", self.amplitude_rad, self.amplitude_rad > 0.0, "> 0 rad")?;
        check("sample rate", self.sample_rate_hz, self.sample_rate_hz > 0.0, "> 0 Hz")?;
        check("ratio", self.ratio, self.ratio > 0.0, "> 0")?;
        check("input speed", self.input_speed_rad_s, true, "finite")?;
        check("torque noise", self.torque_noise_nm, self.torque_noise_nm >= 0.0, ">= 0 N·m")?;
        check("cycles", self.cycles as f64, self.cycles > 0, "at least 1")?;
        if self.frequencies_hz.is_empty() {
            return Err(SimulateError::OutOfRange { name: "frequencies", expected: "at least one", value: 0.0 });
        }
        for &f in &self.frequencies_hz {
            check("frequency", f, f > 0.0, "> 0 Hz")?;
        }
        for bits in [self.input_bits, self.output_bits].into_iter().flatten() {
            check("encoder resolution", bits as f64, (1..=48).contains(&bits), "1 to 48 bits")?;
        }
        if let Some((start, rise)) = self.temperature {
            check("temperature", start, true, "finite")?;
            check("temperature rise", rise, true, "finite")?;
        }
        for e in &self.effects {
            check("effect value", e.value, true, "finite")?;
        }
        let delay = self.effect(Effect::ChannelDelay);
        check("channel delay", delay, delay.abs() <= 1.0, "within ±1 s")?;
        if self.effect(Effect::ThermalDrift) != 0.0 && self.temperature.is_none() {
            return Err(SimulateError::NeedsTemperature);
        }
        Ok(())
    }

    /// The magnitude of `effect` (summed if given twice), 0 when absent.
    pub fn effect(&self, effect: Effect) -> f64 {
        self.effects.iter().filter(|e| e.effect == effect).map(|e| e.value).sum()
    }
}

/// The recording the simulation describes: today's sine through the params' genetic model.
pub fn simulate(sim: &Simulation) -> Result<Recording, SimulateError> {
    simulate_experiment(&sim.clone().into())
}

/// The recording of `experiment`: its motion through its physics, read by encoders zeroed at
/// its deflection zero.
pub fn simulate_experiment(experiment: &Experiment) -> Result<Recording, SimulateError> {
    run(experiment)
}

/// The gear the torque comes from, with its state.
enum Truth {
    /// The model on the sine's loop, where its kind has a stateless one: the direction picks
    /// the branch.
    Loop(model_core::Loop<f64>),
    /// The model with its memory, stepped along the deflection's path from rest.
    Memory(Box<Evaluator<f64>>),
    /// A host physics with memory, stepped along the deflection's path from rest.
    Path(Box<dyn Gear>),
}

impl Truth {
    /// Whether the gear starts unstressed at θ = 0 (all but the loop, which starts on it).
    fn starts_at_rest(&self) -> bool {
        !matches!(self, Truth::Loop(_))
    }
}

/// A motion whose first deflection is within this of 0 begins at the truth's rest (a motion file's
/// rounding; far below any encoder's step, 2π/2²⁴ = 0.37 µrad).
const AT_ZERO_RAD: f64 = 1e-9;

fn truth(sim: &Simulation, motion: &Motion, physics: &Physics, width: f64) -> Result<Truth, SimulateError> {
    if let Some(gear) = physics.gear()? {
        return Ok(Truth::Path(gear));
    }
    Ok(match (motion, sim.params.paper_params().map(Model::new).transpose()?) {
        (Motion::Sine, Some(model)) => {
            check(
                "backlash",
                width,
                (0.0..2.0 * sim.amplitude_rad).contains(&width),
                "from 0 to below twice the amplitude",
            )?;
            // Behind the dead band the elastic loop is narrower by half its width.
            Truth::Loop(model.at_amplitude(sim.amplitude_rad - width / 2.0)?)
        }
        _ => Truth::Memory(Box::new(sim.params.evaluator(0.0)?)),
    })
}

/// sign(v), 0 at 0.
fn sign(v: f64) -> f64 {
    if v == 0.0 {
        0.0
    } else {
        v.signum()
    }
}

fn run(experiment: &Experiment) -> Result<Recording, SimulateError> {
    let Experiment { simulation: sim, motion, physics, deflection_zero_rad: zero } = experiment;
    sim.validate()?;
    check("deflection zero", *zero, zero.abs() <= MAX_DEFLECTION_RAD, "within ±1 rad")?;
    let width = sim.effect(Effect::Backlash);
    let mut truth = truth(sim, motion, physics, width)?;
    if !matches!(truth, Truth::Loop(_)) {
        check("backlash", width, width >= 0.0, ">= 0 rad")?;
    }
    if let Motion::Biased { bias_rad: Some(level) } | Motion::Hold { load_rad: Some(level) } = motion {
        check("bias", *level, true, "a finite deflection, rad")?;
    }
    let timing = Timing {
        amplitude: sim.amplitude_rad,
        frequencies_hz: &sim.frequencies_hz,
        cycles: sim.cycles,
        sample_rate_hz: sim.sample_rate_hz,
        seed: sim.seed,
    };
    let played = Played::new(motion, &timing, MAX_SAMPLES).map_err(|e| match e {
        PlayError::TooLong(samples) => SimulateError::TooLong(samples),
        PlayError::Plan(error) => SimulateError::Plan(error),
    })?;
    let n = played.len;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(sim.seed);
    // Phases from their own stream, so that adding an effect leaves the noise unchanged.
    let mut phase_rng = rand_chacha::ChaCha8Rng::seed_from_u64(sim.seed ^ 0x6b69_6e65_6d61_7469);
    let kinematic_phases = (phase_rng.random_range(0.0..TAU), phase_rng.random_range(0.0..TAU));
    let (friction, damping, offset) =
        (sim.effect(Effect::CoulombFriction), sim.effect(Effect::ViscousDamping), sim.effect(Effect::TorqueOffset));
    let (kinematic, thermal) = (sim.effect(Effect::KinematicError), sim.effect(Effect::ThermalDrift));
    let delay = sim.effect(Effect::ChannelDelay);
    let torque_noise = Normal::new(0.0, sim.torque_noise_nm).map_err(|_| SimulateError::OutOfRange {
        name: "torque noise",
        expected: ">= 0 N·m",
        value: sim.torque_noise_nm,
    })?;
    let quantise = |angle: f64, bits: Option<u32>| match bits {
        Some(bits) => {
            let step = TAU / (1u64 << bits) as f64;
            (angle / step).round() * step
        }
        None => angle,
    };

    let mut metadata = vec![("source".to_string(), "swg-host simulate".to_string())];
    match motion {
        Motion::File(trajectory) => {
            let peak = trajectory.deflection().iter().fold(0.0, |m: f64, x| m.max(x.abs()));
            metadata.push(("amplitude_rad".into(), peak.to_string()));
        }
        Motion::Plan(spec) => {
            // The plan's own peak, in the plan's numbers (f32, as the wire carries them).
            let peak = spec.at_rate(sim.sample_rate_hz).map_err(SimulateError::Plan)?.peak();
            metadata.push(("amplitude_rad".into(), peak.to_string()));
        }
        _ => {
            metadata.push(("amplitude_rad".into(), sim.amplitude_rad.to_string()));
            metadata.push((
                "frequencies_hz".into(),
                sim.frequencies_hz.iter().map(f64::to_string).collect::<Vec<_>>().join(" "),
            ));
        }
    }
    metadata.push(("seed".into(), sim.seed.to_string()));
    if !sim.effects.is_empty() {
        let effects: Vec<String> = sim.effects.iter().map(|e| format!("{}={}", e.effect, e.value)).collect();
        metadata.push(("effects".into(), effects.join(" ")));
    }
    match motion {
        Motion::Sine => {}
        Motion::File(trajectory) => metadata.push(("motion".into(), format!("file {}", trajectory.name()))),
        Motion::Plan(spec) => {
            metadata.push(("motion".into(), format!("plan: {}", spec.source())));
            metadata.push(("plan".into(), spec.describe()));
        }
        _ => metadata.push(("motion".into(), motion.name().into())),
    }
    if !matches!(physics, Physics::Model) {
        metadata.push(("physics".into(), physics.name().into()));
    }
    // The truth starts unstressed at θ = 0; the recording begins at rest only where the motion
    // does too. (A motion file that begins at 0.83 mrad was written `# start: rest`, and
    // `diagnose` read its first deflection as the gear's zero.)
    let begins_at_zero = n > 0 && played.sample(0).x.abs() <= AT_ZERO_RAD;
    if truth.starts_at_rest() && begins_at_zero {
        metadata.push(("start".into(), "rest".into()));
    }
    if *zero != 0.0 {
        metadata.push(("deflection_zero_rad".into(), zero.to_string()));
    }
    let mut rec = Recording {
        ratio: sim.ratio,
        metadata,
        angles: Some(Angles { input: Vec::with_capacity(n), output: Vec::with_capacity(n) }),
        temperature: sim.temperature.map(|_| Vec::with_capacity(n)),
        ..Recording::default()
    };
    let linear_stiffness = match &truth {
        Truth::Loop(_) | Truth::Memory(_) => sim.params.linear_stiffness(),
        Truth::Path(gear) => gear.linear_stiffness(),
    };
    for i in 0..n {
        let motion::Sample { t, x, rate } = played.sample(i);
        // The bench drives the gear's deflection x; the encoders see x minus the kinematic
        // error, off by the zero they were set to, the teeth see x behind the backlash dead band.
        let direction = if rate >= 0.0 { Direction::Rising } else { Direction::Falling };
        let theta_in = sim.input_speed_rad_s * t;
        let elastic = backlash(x, width);
        let temperature = sim.temperature.map(|(start, rise)| (start + rise * t, rise * t));
        let warming = temperature.map_or(0.0, |(_, delta)| delta);
        let gear_torque = match &mut truth {
            Truth::Loop(model) => model.torque(elastic, direction)?,
            Truth::Memory(memory) => memory.step(elastic)?.torque,
            Truth::Path(gear) => gear.step(elastic),
        };
        // What the gear transmits; the sensor's offset and noise are added once it is sampled.
        let torque =
            gear_torque + linear_stiffness * thermal * warming * elastic + friction * sign(rate) + damping * rate;
        let measured = x - kinematic_error(kinematic, kinematic_phases, theta_in) + zero;
        let theta_out = theta_in / sim.ratio - measured;
        let (measured_in, measured_out) = (quantise(theta_in, sim.input_bits), quantise(theta_out, sim.output_bits));
        rec.time.push(t);
        if let Some(angles) = rec.angles.as_mut() {
            angles.input.push(measured_in);
            angles.output.push(measured_out);
        }
        rec.deflection.push(deflection(measured_in, measured_out, sim.ratio));
        rec.torque.push(torque);
        if let (Some((celsius, _)), Some(temps)) = (temperature, rec.temperature.as_mut()) {
            temps.push((celsius * 100.0).round() / 100.0);
        }
    }
    if delay != 0.0 {
        rec.torque = delayed(&rec.time, &rec.torque, delay);
    }
    // A plan's torque limit, on what the joint's torque sensor reads: beyond it the joint stops.
    let plan_limit = match motion {
        Motion::Plan(spec) => Some((spec.source(), spec.limits.torque_nm)),
        _ => None,
    };
    for (torque, &time) in rec.torque.iter_mut().zip(&rec.time) {
        *torque = *torque + offset + torque_noise.sample(&mut rng);
        // A recording the readers would refuse is not written.
        if !(torque.abs() <= MAX_TORQUE_NM) {
            return Err(SimulateError::TorqueBeyondAnyGear { torque: *torque, time });
        }
        if let Some((source, limit)) = plan_limit {
            if torque.abs() > f64::from(limit) {
                return Err(SimulateError::PlanTorqueLimit { plan: source.to_owned(), torque: *torque, time, limit });
            }
        }
    }
    Ok(rec)
}

/// The torque channel sampled `delay` seconds late (early when negative): the value at t − τ,
/// interpolated linearly between samples and held at the recording's ends.
fn delayed(time: &[f64], torque: &[f64], delay: f64) -> Vec<f64> {
    time.iter()
        .map(|&t| {
            let at = t - delay;
            let after = time.partition_point(|&s| s < at);
            match after {
                0 => torque[0],
                n if n == time.len() => torque[n - 1],
                k => {
                    let w = (at - time[k - 1]) / (time[k] - time[k - 1]);
                    torque[k - 1] + w * (torque[k] - torque[k - 1])
                }
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    use model_core::checks::SEED_TABLE_FIT as SEED_FIT;

    fn base() -> Simulation {
        Simulation {
            params: GearModel::paper(SEED_FIT),
            amplitude_rad: 1.168e-3,
            frequencies_hz: vec![0.5],
            cycles: 2,
            sample_rate_hz: 1000.0,
            ratio: 50.0,
            input_speed_rad_s: 0.0,
            input_bits: None,
            output_bits: None,
            torque_noise_nm: 0.0,
            temperature: None,
            effects: Vec::new(),
            seed: 1,
        }
    }

    #[test]
    fn the_memory_model_on_the_loop_is_todays_loop_where_the_peaks_are_sampled() {
        // At 0.5 Hz and 1 kHz the samples hit ±A exactly: GeneticMemory started on the loop
        // gives today's torque bit for bit. (Where the samples straddle the peak it reverses at
        // the sampled extreme instead of ±A, and differs; so `sine` keeps the symmetric rule.)
        let sim = base();
        let model = model_core::Model::new(SEED_FIT).unwrap();
        let mut memory: model_core::GeneticMemory<f64, 64> =
            model_core::GeneticMemory::on_loop(model, 0.0, sim.amplitude_rad, Direction::Rising).unwrap();
        let rec = simulate(&sim).unwrap();
        for i in 0..rec.time.len() {
            let x = sim.amplitude_rad * (std::f64::consts::TAU * 0.5 * rec.time[i]).sin();
            assert_eq!(memory.step(x).unwrap().torque, rec.torque[i], "sample {i}");
        }
    }

    #[test]
    fn an_experiment_from_a_simulation_is_the_simulation() {
        let sim = Simulation { torque_noise_nm: 0.1, input_bits: Some(18), ..base() };
        assert_eq!(simulate_experiment(&sim.clone().into()).unwrap(), simulate(&sim).unwrap());
    }

    fn motions() -> Vec<Motion> {
        let trajectory = Trajectory::new("t", (0..500).map(|i| i as f64 * 0.01).collect(), {
            (0..500).map(|i| 1e-3 * (i as f64 * 0.05).sin() * (i as f64 * 0.013).cos()).collect()
        })
        .unwrap();
        vec![
            Motion::Sine,
            Motion::Biased { bias_rad: None },
            Motion::Nested,
            Motion::Random,
            Motion::Hold { load_rad: Some(-0.5e-3) },
            Motion::File(trajectory),
        ]
    }

    fn physics() -> [Physics; 5] {
        [
            Physics::Model,
            Physics::BoucWen(BoucWen::default()),
            Physics::MicroSlip(MicroSlip::default()),
            Physics::Catalogue(Catalogue::default()),
            Physics::Preisach(physics::Preisach::default()),
        ]
    }

    #[test]
    fn every_motion_runs_through_every_physics_with_every_effect() {
        let effects = ["backlash=1e-4", "coulomb_friction=0.2", "viscous_damping=0.3", "kinematic_error=2e-6"]
            .into_iter()
            .chain(["thermal_drift=0.01", "torque_offset=0.1", "channel_delay=2e-3"])
            .map(|e| e.parse().unwrap())
            .collect();
        let sim = Simulation {
            input_speed_rad_s: 3.0,
            input_bits: Some(20),
            output_bits: Some(20),
            torque_noise_nm: 0.05,
            temperature: Some((25.0, 0.2)),
            effects,
            ..base()
        };
        for motion in motions() {
            for physics in physics() {
                let experiment =
                    Experiment { simulation: sim.clone(), motion: motion.clone(), physics, deflection_zero_rad: 0.0 };
                let rec = simulate_experiment(&experiment).unwrap();
                let expected = if let Motion::File(t) = &motion { t.time().len() } else { rec.time.len() };
                assert_eq!(rec.time.len(), expected);
                assert!(rec.torque.iter().chain(&rec.deflection).all(|v| v.is_finite()), "{experiment:?}");
                let peak = rec.torque.iter().fold(0.0, |m: f64, t| m.max(t.abs()));
                // (The seed fit's genetic branches overshoot far more than a gear's: r < 0.)
                assert!(peak > 2.0 && peak < 200.0, "{} {}: peak {peak}", motion.name(), experiment.physics.name());
            }
        }
    }

    #[test]
    fn a_channel_delay_shows_the_torque_of_tau_earlier() {
        let quiet = Simulation { frequencies_hz: vec![1.0], ..base() };
        let delayed = |delay: f64| {
            let effects = vec![EffectValue { effect: Effect::ChannelDelay, value: delay }];
            simulate(&Simulation { effects, ..quiet.clone() }).unwrap().torque
        };
        let (now, late, early) = (delayed(0.0), delayed(2.5e-3), delayed(-1e-3));
        // 2.5 samples late: halfway between the torques 2 and 3 samples before; held at the start.
        for i in 3..now.len() {
            assert!((late[i] - (now[i - 2] + now[i - 3]) / 2.0).abs() <= 1e-9 * now[i].abs().max(1.0), "sample {i}");
        }
        assert_eq!(&late[..3], &[now[0]; 3]);
        // One sample early; held at the end.
        for i in 0..now.len() - 1 {
            assert!((early[i] - now[i + 1]).abs() <= 1e-9 * now[i + 1].abs().max(1.0), "sample {i}");
        }
        assert_eq!(early[now.len() - 1], now[now.len() - 1]);
        let out_of_range = vec![EffectValue { effect: Effect::ChannelDelay, value: 2.0 }];
        let error = simulate(&Simulation { effects: out_of_range, ..quiet }).unwrap_err();
        assert!(error.to_string().contains("channel delay"), "{error}");
    }

    /// ∮T dθ over samples `from..to` (trapezoids), of the exact motion's deflection.
    fn work(rec: &Recording, from: usize, to: usize) -> f64 {
        (from..to)
            .map(|i| 0.5 * (rec.torque[i] + rec.torque[i + 1]) * (rec.deflection[i + 1] - rec.deflection[i]))
            .sum()
    }

    #[test]
    fn the_truth_physics_are_passive_on_the_closed_cycles_of_every_periodic_motion() {
        // 0.5 Hz at 1 kHz: a cycle is 2000 samples; the last cycle (after the ramp) is closed.
        for motion in [Motion::Sine, Motion::Biased { bias_rad: None }, Motion::Nested, Motion::Hold { load_rad: None }]
        {
            // Not the seed fit's genetic model: its own loop is not passive (README: r < 0).
            for physics in physics().into_iter().skip(1) {
                let experiment =
                    Experiment { simulation: base(), motion: motion.clone(), physics, deflection_zero_rad: 0.0 };
                let rec = simulate_experiment(&experiment).unwrap();
                let end = rec.time.len() - 1;
                assert!((rec.deflection[end - 2000] - rec.deflection[end]).abs() < 1e-15);
                let dissipated = work(&rec, end - 2000, end);
                assert!(dissipated > 0.0, "{} {}: ∮T dθ = {dissipated}", motion.name(), experiment.physics.name());
            }
        }
    }

    #[test]
    fn the_genetic_model_starts_at_rest_off_the_sine() {
        let experiment = Experiment {
            simulation: base(),
            motion: Motion::Nested,
            physics: Physics::Model,
            deflection_zero_rad: 0.0,
        };
        let rec = simulate_experiment(&experiment).unwrap();
        assert_eq!(rec.torque[0], 0.0);
        assert_eq!(rec.metadata.iter().find(|(k, _)| k == "motion").unwrap().1, "nested");
    }

    fn meta<'a>(rec: &'a Recording, key: &str) -> Option<&'a str> {
        rec.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    #[test]
    fn every_truth_but_the_sines_loop_writes_start_rest() {
        let slip_model = Simulation { params: model_core::checks::micro_slip_set().unwrap(), ..base() };
        for simulation in [base(), slip_model] {
            // The micro-slip kind has no stateless loop: its memory runs from rest under the sine too.
            let has_loop = simulation.params.paper_params().is_some();
            for motion in motions() {
                for physics in physics() {
                    let on_loop = has_loop && motion == Motion::Sine && physics == Physics::Model;
                    let experiment = Experiment {
                        simulation: simulation.clone(),
                        motion: motion.clone(),
                        physics,
                        deflection_zero_rad: 0.0,
                    };
                    let rec = simulate_experiment(&experiment).unwrap();
                    let what =
                        format!("{} {} {:?}", motion.name(), experiment.physics.name(), simulation.params.kind());
                    assert_eq!(rec.starts_at_rest(), !on_loop, "{what}");
                    assert_eq!(meta(&rec, "start"), (!on_loop).then_some("rest"), "{what}");
                }
            }
        }
        // A motion file that begins away from θ = 0 does not begin at rest.
        for (first, at_rest) in [(0.0, true), (8.3e-4, false)] {
            let time: Vec<f64> = (0..2000).map(|k| f64::from(k) / 1000.0).collect();
            let deflection: Vec<f64> = time.iter().map(|t| first + 1e-4 * (TAU * t).sin()).collect();
            let trajectory = motion::Trajectory::new("file", time, deflection).unwrap();
            let experiment = Experiment {
                simulation: base(),
                motion: Motion::File(trajectory),
                physics: Physics::Model,
                deflection_zero_rad: 0.0,
            };
            assert_eq!(simulate_experiment(&experiment).unwrap().starts_at_rest(), at_rest, "from {first}");
        }
        // The genetic seed fit has its loop: the default recording is as it was.
        assert!(base().params.paper_params().is_some());
        assert!(!simulate(&base()).unwrap().metadata.iter().any(|(k, _)| k == "start"));
    }

    #[test]
    fn a_deflection_zero_moves_the_recorded_deflection_and_nothing_else() {
        let step = TAU / (1u64 << 20) as f64;
        let effects = ["backlash=1e-4", "kinematic_error=2e-6", "thermal_drift=0.01"]
            .into_iter()
            .map(|e| e.parse().unwrap())
            .collect();
        let simulation = Simulation {
            input_speed_rad_s: 3.0,
            input_bits: Some(20),
            output_bits: Some(20),
            torque_noise_nm: 0.05,
            temperature: Some((25.0, 0.2)),
            effects,
            ..base()
        };
        for (motion, physics) in [
            (Motion::Sine, Physics::Model),
            (Motion::Nested, Physics::Catalogue(Catalogue::default())),
            (Motion::Random, Physics::BoucWen(BoucWen::default())),
        ] {
            let run = |zero: f64| {
                let experiment = Experiment {
                    simulation: simulation.clone(),
                    motion: motion.clone(),
                    physics: physics.clone(),
                    deflection_zero_rad: zero,
                };
                simulate_experiment(&experiment).unwrap()
            };
            let (zeroed, offset) = (run(0.0), run(-0.5e-3));
            assert_eq!(meta(&zeroed, "deflection_zero_rad"), None);
            assert_eq!(meta(&offset, "deflection_zero_rad"), Some("-0.0005"));
            // Within one encoder step of the true deflection + θ0 (each reading is within half a step).
            for (i, (a, b)) in zeroed.deflection.iter().zip(&offset.deflection).enumerate() {
                assert!((b - a + 0.5e-3).abs() <= step, "{} sample {i}: {a} {b}", motion.name());
            }
            assert_ne!(zeroed.deflection, offset.deflection);
            assert_eq!(zeroed.torque, offset.torque);
            assert_eq!(zeroed.time, offset.time);
            assert_eq!(zeroed.temperature, offset.temperature);
            assert_eq!(zeroed.angles.as_ref().unwrap().input, offset.angles.as_ref().unwrap().input);
            let mut metadata = offset.metadata.clone();
            metadata.retain(|(k, _)| k != "deflection_zero_rad");
            assert_eq!(metadata, zeroed.metadata);
        }
        // The encoders read 0 at the true zero + θ0: off by θ0 before any motion.
        let exact = Experiment { deflection_zero_rad: 2e-4, ..Experiment::from(base()) };
        assert_eq!(simulate_experiment(&exact).unwrap().deflection[0], 2e-4);
        let bad = Experiment { deflection_zero_rad: f64::INFINITY, ..Experiment::from(base()) };
        assert_eq!(
            simulate_experiment(&bad).unwrap_err().to_string(),
            "deflection zero must be within ±1 rad, got inf"
        );
    }

    #[test]
    fn bad_values_are_named() {
        let biased = Experiment {
            simulation: base(),
            motion: Motion::Biased { bias_rad: Some(f64::NAN) },
            physics: Physics::BoucWen(BoucWen::default()),
            deflection_zero_rad: 0.0,
        };
        assert_eq!(
            simulate_experiment(&biased).unwrap_err().to_string(),
            "bias must be a finite deflection, rad, got NaN"
        );
        let bad = Experiment {
            simulation: base(),
            motion: Motion::Sine,
            physics: Physics::MicroSlip(MicroSlip { max_slip_rad: -1.0, ..MicroSlip::default() }),
            deflection_zero_rad: 0.0,
        };
        let message = simulate_experiment(&bad).unwrap_err().to_string();
        assert_eq!(message, "micro-slip parameter max_slip_rad must be > min_slip_rad, got -1");
        let too_long = Experiment {
            simulation: Simulation { sample_rate_hz: 1e9, ..base() },
            motion: Motion::Random,
            physics: Physics::BoucWen(BoucWen::default()),
            deflection_zero_rad: 0.0,
        };
        assert!(matches!(simulate_experiment(&too_long), Err(SimulateError::TooLong(_))));
    }
}
