//! `swg-host fit`: identify the model from a loop table or a recording.
use super::InputOptions;
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use model_core::Model;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use swg_host::fit::{fit_dataset, FitDatasetError, Stage};
use swg_host::report::fit::{ComparedReport, FitReport, InputSummary};
use swg_host::report::output::write_atomically;
use swg_host::report::params::read_params;
use swg_host::report::plot::{loop_svg, LoopPlot};

#[derive(Args)]
pub struct FitArgs {
    /// Loop table (branch,torque_nm,deflection_rad) or bench recording (`# swg-recording v1`).
    input: PathBuf,
    /// Write the result (parameters and figures, JSON) to this file, for `push` and `simulate`.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Print the result as JSON instead of the summary.
    #[arg(long)]
    json: bool,
    /// Seed of the particle swarm; the fit is deterministic for a seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Draw the loop, the fit, the baselines and the residuals into this SVG file.
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    /// Also evaluate this parameter file on the same data (repeatable).
    #[arg(long, value_name = "PARAMS.json")]
    compare: Vec<PathBuf>,
    #[command(flatten)]
    input_options: InputOptions,
}

pub fn run(args: FitArgs) -> Result<()> {
    if let Some(plot) = &args.plot {
        if plot.extension().and_then(|e| e.to_str()) != Some("svg") {
            bail!("--plot {}: the picture is written as SVG; name the file *.svg", plot.display());
        }
    }
    let dataset = args.input_options.read_to_fit(&args.input)?;
    let compare = args.compare.iter().map(|path| read_params(path)).collect::<Result<Vec<_>, _>>()?;

    let progress = DelayedProgress::new();
    let outcome =
        fit_dataset(&dataset, &compare, args.seed, |stage| progress.update(stage)).map_err(|error| match error {
            FitDatasetError::Compared { index, source } => anyhow::Error::new(source).context(format!(
                "{}: cannot evaluate on {}",
                args.compare[index].display(),
                args.input.display()
            )),
            other => anyhow::Error::new(other).context(args.input.display().to_string()),
        })?;
    progress.finish();

    let fitted = &outcome.fit;
    let compared = args
        .compare
        .iter()
        .zip(&compare)
        .zip(&outcome.compared_rss)
        .map(|((path, params), &rss)| ComparedReport { path: path.display().to_string(), params: *params, rss })
        .collect();
    let summary = InputSummary {
        path: args.input.display().to_string(),
        kind: dataset.kind(),
        turning_points: outcome.prepared.segmentation.as_ref().map(|s| s.turning_points.len()),
    };
    let report = FitReport::new(summary, fitted, outcome.lines.clone(), outcome.three_segment.clone(), compared);
    let json = serde_json::to_string_pretty(&report)?;

    // Render everything before writing anything.
    let svg = match &args.plot {
        Some(_) => {
            let model = Model::new(fitted.params)?;
            let title = format!("{} — genetic hysteresis fit, RMS {:.3} N·m", file_name(&args.input), fitted.rms);
            Some(loop_svg(&LoopPlot {
                title: &title,
                data: &outcome.prepared.data,
                branch: &outcome.prepared.branch,
                model: &model,
                amplitude: fitted.reference_amplitude,
                lines: &outcome.lines,
                three_segment: outcome.three_segment.as_ref(),
            })?)
        }
        None => None,
    };
    if let Some(out) = &args.out {
        write_atomically(out, format!("{json}\n").as_bytes()).with_context(|| format!("writing {}", out.display()))?;
    }
    if let (Some(path), Some(svg)) = (&args.plot, svg) {
        write_atomically(path, svg.as_bytes()).with_context(|| format!("writing {}", path.display()))?;
    }
    if args.json {
        println!("{json}");
    } else {
        print!("{}", report.human());
        if let Some(out) = &args.out {
            println!("wrote {}", out.display());
        }
        if let Some(plot) = &args.plot {
            println!("wrote {}", plot.display());
        }
    }
    Ok(())
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// A progress bar on stderr that appears only once the fit has run for a second.
struct DelayedProgress {
    bar: ProgressBar,
    start: Instant,
}

impl DelayedProgress {
    fn new() -> Self {
        let bar = ProgressBar::with_draw_target(Some(1), ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template("{spinner} fit [{elapsed}] {bar:30} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        DelayedProgress { bar, start: Instant::now() }
    }

    fn update(&self, stage: Stage) {
        if self.bar.is_hidden() && self.start.elapsed() > Duration::from_secs(1) {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
        }
        let (done, total, message) = match stage {
            Stage::Swarm { iteration, of } => (iteration, of, format!("particle swarm, iteration {iteration}")),
            Stage::Polish { round, of } => (round, of, format!("polish, round {round} of {of}")),
        };
        self.bar.set_length(total as u64);
        self.bar.set_position(done as u64);
        self.bar.set_message(message);
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
