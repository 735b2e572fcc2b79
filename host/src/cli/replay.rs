//! `swg-host replay`: stream a recording's encoder samples through the joint firmware and
//! compare its T_ff and K with the host's f64 model.
use super::push::PortOptions;
use anyhow::{bail, Result};
use clap::{Args, ValueEnum};
use std::path::PathBuf;
use swg_host::input::read_recording;
use swg_host::link::replay::{device_model, device_params, replay, samples};
use swg_host::report::params::read_model;
use swg_protocol::{endpoint, EvalPath};

#[derive(Args)]
pub struct ReplayArgs {
    /// Bench recording (format v1).
    #[arg(value_name = "RECORDING")]
    recording: PathBuf,
    #[command(flatten)]
    port: PortOptions,
    /// Compare with this parameter file (either model kind) instead of the device's own set.
    #[arg(long, value_name = "PARAMS.json")]
    params: Option<PathBuf>,
    /// The firmware's evaluation to exercise.
    #[arg(long, value_enum, default_value_t = Path::Fast)]
    path: Path,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Path {
    /// model-core's f32 evaluation.
    Direct,
    /// The per-tick fast path.
    Fast,
}

pub fn run(args: ReplayArgs) -> Result<()> {
    let recording = read_recording(&args.recording, None)?;
    let mut link = args.port.open()?;
    let joint = device_params(&mut link)?;
    let model = match &args.params {
        Some(path) => read_model(path)?,
        None => device_model(&joint),
    };
    // The comparison runs both models from rest: writing the device's own set back resets its
    // memory (at its next tick), so the replay starts where the host's model does.
    link.call::<endpoint::WriteParams>(&joint)?;
    let samples = samples(&recording, joint.gear_ratio)?;
    let path = match args.path {
        Path::Direct => EvalPath::Direct,
        Path::Fast => EvalPath::Fast,
    };
    let report = replay(&mut link, &joint, &model, &samples, path)?;
    super::print_report(&format!(
        "replayed {} through the firmware's {:?} path on {}\n{report}\n",
        args.recording.display(),
        path,
        args.port.port
    ))?;
    if !report.passed() {
        bail!("the firmware's feed-forward differs from the host model beyond the f32 tolerance");
    }
    Ok(())
}
