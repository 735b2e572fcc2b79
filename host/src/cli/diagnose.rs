//! `swg-host diagnose`: where the model and a recording disagree, and which physics is missing.
use super::InputOptions;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use swg_host::diagnose::asymmetry::AsymmetryCheck;
use swg_host::diagnose::diagnose_dataset;
use swg_host::input::{Dataset, Recording};
use swg_host::report::diagnose::DiagnoseReport;
use swg_host::report::finite::to_json;
use swg_host::report::output::Outputs;
use swg_host::report::params::read_params;
use swg_host::report::plot::{diagnosis_loop_svg, drift_svg, masing_svg, residuals_svg};

#[derive(Args)]
pub struct DiagnoseArgs {
    /// Bench recording (`# swg-recording v1`) or loop table.
    input: PathBuf,
    /// Start from these parameters instead of fitting the baseline.
    #[arg(long, value_name = "PARAMS.json")]
    params: Option<PathBuf>,
    /// Print the result as JSON instead of the report.
    #[arg(long)]
    json: bool,
    /// Write residuals.svg, loop.svg, masing.svg and drift.svg into this directory.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Seed of the baseline fit's particle swarm.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    input_options: InputOptions,
}

pub fn run(args: DiagnoseArgs) -> Result<()> {
    let mut outputs = Outputs::new(std::iter::once(args.input.as_path()).chain(args.params.as_deref()));
    let pictures = args
        .plot
        .as_ref()
        .map(|dir| [dir.join("residuals.svg"), dir.join("loop.svg"), dir.join("masing.svg"), dir.join("drift.svg")]);
    outputs.refuse_inputs(pictures.iter().flatten().map(PathBuf::as_path))?;
    let mut dataset = args.input_options.read_to_fit(&args.input)?;
    // The diagnosis reads a recording's input angle (the kinematic error) but not its output
    // angle once the deflection is formed: it need not stay in memory beside the columns.
    if let Dataset::Recording(Recording { angles: Some(angles), .. }) = &mut dataset {
        angles.output = Vec::new();
    }
    let baseline = args.params.as_deref().map(read_params).transpose()?;
    let kind = dataset.kind();
    let outcome = diagnose_dataset(dataset, baseline, args.seed).with_context(|| args.input.display().to_string())?;
    let report = DiagnoseReport::new(args.input.display().to_string(), kind, &outcome);
    // The text is made of the same figures: a report that is not finite is printed in neither form.
    let json = to_json("diagnosis", &report)
        .map_err(|error| anyhow::anyhow!("{error}: {}", report.non_finite_cause()))
        .with_context(|| args.input.display().to_string())?;

    if let (Some(dir), Some([residuals_path, loop_path, masing_path, drift_path])) = (&args.plot, &pictures) {
        let residual_svg = residuals_svg(&outcome.observed, &outcome.before, &outcome.after)?;
        let mirrored = matches!(outcome.asymmetry, AsymmetryCheck::Yes(_));
        let loop_svg = diagnosis_loop_svg(&outcome.observed, &outcome.diagnosis, mirrored)?;
        outputs.create_dir(dir)?;
        outputs.stage(residuals_path, residual_svg.as_bytes())?;
        outputs.stage(loop_path, loop_svg.as_bytes())?;
        outputs.stage(masing_path, masing_svg(&outcome.observed, &outcome.non_masing)?.as_bytes())?;
        outputs.stage(drift_path, drift_svg(&outcome.ratcheting)?.as_bytes())?;
    }
    outputs.commit()?;
    if args.json {
        println!("{json}");
    } else {
        print!("{}", report.human());
        if let Some(dir) = &args.plot {
            println!("pictures: {0}/residuals.svg, {0}/loop.svg, {0}/masing.svg, {0}/drift.svg", dir.display());
        }
    }
    Ok(())
}
