//! `swg-host predict`: run fitted parameters along a recording from rest, following its
//! reversals as `fit` does.
use super::InputOptions;
use anyhow::{Context, Result};
use clap::Args;
use std::fmt::Write as _;
use std::path::PathBuf;
use swg_host::input::read_recording;
use swg_host::predict::{predict, Zeroing};
use swg_host::report::finite::{ensure_finite, to_json};
use swg_host::report::output::Outputs;
use swg_host::report::params::read_model;
use swg_host::report::predict::prediction_csv;

#[derive(Args)]
pub struct PredictArgs {
    /// Parameter file, as `swg-host fit --out` writes it.
    params: PathBuf,
    /// Bench recording (`# swg-recording v1`) whose deflection the model follows.
    recording: PathBuf,
    /// Write the prediction (time_s,deflection_rad,torque_nm,stiffness_nm_per_rad,scored) to this
    /// CSV file; `scored` is 0 before the motion's extremes wiped out an unknown start state.
    #[arg(long, value_name = "PRED.csv")]
    out: Option<PathBuf>,
    /// Print the summary (n, start_state_samples, rss, rms, max_step_nm, reversals) as JSON.
    #[arg(long)]
    json: bool,
    /// Follow the reversals causally, taking those smaller than RAD for noise, as the joint
    /// does (default: the turning points found offline over the whole recording, as `fit`).
    #[arg(long, value_name = "RAD")]
    band: Option<f64>,
    /// Run with the params file's θ0 and no torque offset, as the joint does (default: a
    /// recording that starts at rest is zeroed on its rest window, as `fit` zeroes each run).
    #[arg(long)]
    keep_zero: bool,
    #[command(flatten)]
    input_options: InputOptions,
}

pub fn run(args: PredictArgs) -> Result<()> {
    let mut outputs = Outputs::new([args.params.as_path(), args.recording.as_path()]);
    outputs.refuse_inputs(args.out.as_deref()).context("--out")?;
    let model = read_model(&args.params)?;
    let recording = read_recording(&args.recording, args.input_options.ratio)?;
    let zeroing = if args.keep_zero { Zeroing::Model } else { Zeroing::RestWindow };
    let prediction =
        predict(&model, &recording, args.band, zeroing).with_context(|| args.recording.display().to_string())?;
    let summary = prediction.summary(&recording.torque);
    let name = || args.recording.display().to_string();
    let json = to_json("prediction", &summary).with_context(name)?;
    if let Some(out) = &args.out {
        ensure_finite("prediction", &prediction.torque).with_context(name)?;
        ensure_finite("prediction", &prediction.stiffness).with_context(name)?;
        outputs.stage(out, &prediction_csv(&prediction)?)?;
    }
    let mut text = String::new();
    if args.json {
        let _ = writeln!(text, "{json}");
    } else {
        let reversals = match summary.band_rad {
            Some(band) => format!("reversals followed causally, band {band:.3e} rad"),
            None => "reversals found offline over the whole recording".to_string(),
        };
        let _ = writeln!(
            text,
            "{}: {} samples predicted from rest with {} ({reversals})",
            args.recording.display(),
            summary.n,
            args.params.display(),
        );
        let _ = match &summary.origin {
            Some(origin) => writeln!(
                text,
                "  zeroed on the recording's rest window: θ0 = {:.4} mrad (params file {:.4} mrad), torque offset {:+.4} N·m",
                origin.zero_rad * 1e3,
                model.zero * 1e3,
                origin.torque_offset_nm
            ),
            None => writeln!(text, "  θ0 = {:.4} mrad from the params file, no torque offset", model.zero * 1e3),
        };
        if summary.start_state_samples > 0 {
            let _ = writeln!(
                text,
                "  {} samples before the motion's extremes wiped out the unknown start state between them: run through, not scored \
                 (the recording does not say `# start: rest`)",
                summary.start_state_samples
            );
        }
        let _ = writeln!(
            text,
            "  against the recorded torque ({} samples): RSS {:.5} (N·m)², RMS {:.4} N·m",
            summary.n - summary.start_state_samples,
            summary.rss,
            summary.rms
        );
        let _ =
            writeln!(text, "  largest change of the predicted torque between samples: {:.4} N·m", summary.max_step_nm);
        if summary.beyond_range_samples > 0 {
            let _ = writeln!(
                text,
                "  {} samples beyond the spring's identified range (θ {:.4} … {:.4} mrad), by up to {:.4} mrad: there \
                 it continues with its edge's stiffness",
                summary.beyond_range_samples,
                prediction.range[0] * 1e3,
                prediction.range[1] * 1e3,
                summary.max_excess_rad * 1e3
            );
            if let Some(rms) = summary.within_range_rms {
                let _ = writeln!(text, "  RMS over the scored samples within the range: {rms:.4} N·m");
            }
        }
        if let Some(out) = &args.out {
            let _ = writeln!(text, "wrote {}", out.display());
        }
    }
    super::print_then_commit(&text, outputs)
}
