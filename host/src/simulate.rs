//! Synthetic bench recordings from the model: a sinusoidal deflection, the model's torque
//! plus sensor noise, and quantised input/output encoders, with the physical effects of
//! [`crate::diagnose::effects`] added on request.
use crate::diagnose::effects::{backlash, kinematic_error, Effect, EffectValue};
use crate::input::{deflection, Angles, Recording};
use model_core::{Direction, Model, Params};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::f64::consts::TAU;

#[derive(Clone, Debug, PartialEq)]
pub struct Simulation {
    pub params: Params<f64>,
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
        let width = self.effect(Effect::Backlash);
        check(
            "backlash",
            width,
            (0.0..2.0 * self.amplitude_rad).contains(&width),
            "from 0 to below twice the amplitude",
        )?;
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

/// The recording the simulation describes.
pub fn simulate(sim: &Simulation) -> Result<Recording, SimulateError> {
    sim.validate()?;
    let width = sim.effect(Effect::Backlash);
    // Behind the dead band the elastic loop is narrower by half its width.
    let model = Model::new(sim.params)?.at_amplitude(sim.amplitude_rad - width / 2.0)?;
    let duration: f64 = sim.frequencies_hz.iter().map(|f| sim.cycles as f64 / f).sum();
    let samples = (duration * sim.sample_rate_hz).floor();
    if samples > MAX_SAMPLES {
        return Err(SimulateError::TooLong(samples));
    }
    let n = samples as usize + 1;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(sim.seed);
    // Phases from their own stream, so that adding an effect leaves the noise unchanged.
    let mut phase_rng = rand_chacha::ChaCha8Rng::seed_from_u64(sim.seed ^ 0x6b69_6e65_6d61_7469);
    let kinematic_phases = (phase_rng.random_range(0.0..TAU), phase_rng.random_range(0.0..TAU));
    let (friction, damping, offset) =
        (sim.effect(Effect::CoulombFriction), sim.effect(Effect::ViscousDamping), sim.effect(Effect::TorqueOffset));
    let (kinematic, thermal) = (sim.effect(Effect::KinematicError), sim.effect(Effect::ThermalDrift));
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
    // Start time of each frequency's block.
    let mut blocks = Vec::new();
    let mut start = 0.0;
    for &f in &sim.frequencies_hz {
        blocks.push((start, f));
        start += sim.cycles as f64 / f;
    }

    let mut rec = Recording {
        ratio: sim.ratio,
        metadata: vec![
            ("source".into(), "swg-host simulate".into()),
            ("amplitude_rad".into(), sim.amplitude_rad.to_string()),
            ("frequencies_hz".into(), sim.frequencies_hz.iter().map(f64::to_string).collect::<Vec<_>>().join(" ")),
            ("seed".into(), sim.seed.to_string()),
        ],
        angles: Some(Angles { input: Vec::with_capacity(n), output: Vec::with_capacity(n) }),
        temperature: sim.temperature.map(|_| Vec::with_capacity(n)),
        ..Recording::default()
    };
    for i in 0..n {
        let t = i as f64 / sim.sample_rate_hz;
        let &(block_start, f) = blocks.iter().rev().find(|(s, _)| *s <= t).unwrap_or(&blocks[0]);
        let phase = TAU * f * (t - block_start);
        // The bench drives the gear's deflection x; the encoders see x minus the kinematic
        // error, the teeth see x behind the backlash dead band.
        let x = sim.amplitude_rad * phase.sin();
        let rate = sim.amplitude_rad * TAU * f * phase.cos();
        let direction = if rate >= 0.0 { Direction::Rising } else { Direction::Falling };
        let theta_in = sim.input_speed_rad_s * t;
        let elastic = backlash(x, width);
        let temperature = sim.temperature.map(|(start, rise)| (start + rise * t, rise * t));
        let warming = temperature.map_or(0.0, |(_, delta)| delta);
        let torque = model.torque(elastic, direction)?
            + sim.params.c1 * thermal * warming * elastic
            + friction * rate.signum()
            + damping * rate
            + offset
            + torque_noise.sample(&mut rng);
        let measured = x - kinematic_error(kinematic, kinematic_phases, theta_in);
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
    Ok(rec)
}
