//! `swg-host simulate`: write a recording (format v1) from the model.
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use swg_host::diagnose::effects::EffectValue;
use swg_host::report::output::write_atomically;
use swg_host::report::params::{parse_params, read_params};
use swg_host::simulate::{simulate, Simulation};

/// The fit of the paper's table that ships with the tool (`data/seed/lht-20-50-fit.json`).
pub const SEED_FIT: &str = include_str!("../../../data/seed/lht-20-50-fit.json");

#[derive(Args)]
pub struct SimulateArgs {
    /// Recording to write.
    #[arg(long, short, value_name = "FILE")]
    out: PathBuf,
    /// Model parameters (JSON with a `params` field); default: the bundled fit of the seed table.
    #[arg(long, value_name = "PARAMS.json")]
    params: Option<PathBuf>,
    /// Deflection amplitude A of the loops, rad.
    #[arg(long, default_value_t = 1.168e-3, value_name = "RAD")]
    amplitude: f64,
    /// Excitation frequency, Hz; several (comma-separated or repeated) are played in turn.
    #[arg(long = "frequency", value_delimiter = ',', default_value = "0.5", value_name = "HZ")]
    frequencies: Vec<f64>,
    /// Whole cycles at each frequency.
    #[arg(long, default_value_t = 4)]
    cycles: u32,
    /// Sample rate, Hz.
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    rate: f64,
    /// Gear reduction ratio N.
    #[arg(long, default_value_t = 50.0, value_name = "N")]
    ratio: f64,
    /// Input (wave generator) speed, rad/s; 0 keeps the input locked.
    #[arg(long, default_value_t = 0.0, value_name = "RAD_S")]
    input_speed: f64,
    /// Input encoder resolution, bits per revolution (default: exact angles).
    #[arg(long, value_name = "BITS")]
    input_bits: Option<u32>,
    /// Output encoder resolution, bits per revolution (default: exact angles).
    #[arg(long, value_name = "BITS")]
    output_bits: Option<u32>,
    /// Torque sensor noise, standard deviation, N·m.
    #[arg(long, default_value_t = 0.05, value_name = "NM")]
    torque_noise: f64,
    /// Add a temperature column starting at this temperature, °C.
    #[arg(long, value_name = "CELSIUS")]
    temperature: Option<f64>,
    /// Temperature rise over time, K/s (with --temperature).
    #[arg(long, default_value_t = 0.0, value_name = "K_PER_S", requires = "temperature")]
    temperature_rise: f64,
    /// Add a physical effect the model leaves out, NAME=VALUE in SI units (repeatable):
    /// backlash=WIDTH_RAD, coulomb_friction=NM, viscous_damping=NM_S_PER_RAD,
    /// kinematic_error=RAD (2nd-order amplitude), thermal_drift=PER_K, torque_offset=NM.
    #[arg(long = "effect", value_name = "NAME=VALUE")]
    effects: Vec<EffectValue>,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

pub fn run(args: SimulateArgs) -> Result<()> {
    let params = match &args.params {
        Some(path) => read_params(path)?,
        None => parse_params("data/seed/lht-20-50-fit.json (bundled)".as_ref(), SEED_FIT)?,
    };
    let simulation = Simulation {
        params,
        amplitude_rad: args.amplitude,
        frequencies_hz: args.frequencies,
        cycles: args.cycles,
        sample_rate_hz: args.rate,
        ratio: args.ratio,
        input_speed_rad_s: args.input_speed,
        input_bits: args.input_bits,
        output_bits: args.output_bits,
        torque_noise_nm: args.torque_noise,
        temperature: args.temperature.map(|start| (start, args.temperature_rise)),
        effects: args.effects,
        seed: args.seed,
    };
    let recording = simulate(&simulation)?;
    let mut text = Vec::new();
    recording.write(&mut text)?;
    write_atomically(&args.out, &text).with_context(|| format!("writing {}", args.out.display()))?;
    let duration = recording.time.last().copied().unwrap_or(0.0);
    println!("wrote {}: {} samples, {duration} s", args.out.display(), recording.time.len());
    Ok(())
}
