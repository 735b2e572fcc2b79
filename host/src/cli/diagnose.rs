//! `swg-host diagnose`: where the model and a recording disagree, and which physics is missing.
use super::InputOptions;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use swg_host::diagnose::diagnose_dataset;
use swg_host::report::diagnose::DiagnoseReport;
use swg_host::report::output::write_atomically;
use swg_host::report::params::read_params;
use swg_host::report::plot::{diagnosis_loop_svg, residuals_svg};

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
    /// Write residuals.svg and loop.svg into this directory.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Seed of the baseline fit's particle swarm.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    input_options: InputOptions,
}

pub fn run(args: DiagnoseArgs) -> Result<()> {
    let dataset = args.input_options.read_to_fit(&args.input)?;
    let baseline = args.params.as_deref().map(read_params).transpose()?;
    let outcome = diagnose_dataset(&dataset, baseline, args.seed).with_context(|| args.input.display().to_string())?;
    let report = DiagnoseReport::new(args.input.display().to_string(), dataset.kind(), &outcome);

    if let Some(dir) = &args.plot {
        let residual_svg = residuals_svg(&outcome.observed, &outcome.before, &outcome.after)?;
        let loop_svg = diagnosis_loop_svg(&outcome.observed, &outcome.diagnosis)?;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (name, svg) in [("residuals.svg", residual_svg), ("loop.svg", loop_svg)] {
            let path = dir.join(name);
            write_atomically(&path, svg.as_bytes()).with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", report.human());
        if let Some(dir) = &args.plot {
            println!("pictures: {}/residuals.svg, {}/loop.svg", dir.display(), dir.display());
        }
    }
    Ok(())
}
