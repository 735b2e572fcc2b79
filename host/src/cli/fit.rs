//! `swg-host fit`: identify the model from a loop table or a recording.
use super::InputOptions;
use anyhow::{bail, Context, Result};
use clap::builder::PossibleValue;
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use model_core::{Kind, Model};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use swg_host::fit::{fit_dataset, FitDatasetError, Identified, ModelChoice, Stage};
use swg_host::report::finite::to_json;
use swg_host::report::fit::{ComparedReport, FitReport, InputSummary};
use swg_host::report::output::Outputs;
use swg_host::report::params::read_model;
use swg_host::report::plot::{loop_svg, motion_svg, LoopPlot, MotionSeries};

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
    /// The model to identify. `auto` fits every kind on the first three quarters of a
    /// recording and keeps the one with the lowest error on the last quarter. Default: `auto`
    /// on a recording, `genetic` on a loop table (one loop: no quarter to spare).
    #[arg(long, value_enum)]
    model: Option<ModelArg>,
    #[command(flatten)]
    input_options: InputOptions,
}

/// `--model`: a kind by its label, `auto` or `genetic-loop`.
#[derive(Clone, Copy, Debug)]
struct ModelArg(ModelChoice);

impl ValueEnum for ModelArg {
    fn value_variants<'a>() -> &'a [Self] {
        static VARIANTS: std::sync::OnceLock<Vec<ModelArg>> = std::sync::OnceLock::new();
        VARIANTS.get_or_init(|| {
            let kinds = Kind::ALL.into_iter().map(ModelChoice::Kind);
            kinds.chain([ModelChoice::Auto, ModelChoice::Loop]).map(ModelArg).collect()
        })
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(match self.0 {
            ModelChoice::Kind(kind) => PossibleValue::new(kind.label()).help(kind.description()),
            ModelChoice::Auto => {
                PossibleValue::new("auto").help("Every kind; the lowest error on the held-out last quarter wins")
            }
            ModelChoice::Loop => PossibleValue::new("genetic-loop").help(
                "The paper's symmetric-loop rule on each leg of a recording (the fit before the stateful models; for \
                 comparison only, it assumes symmetric loops)",
            ),
        })
    }
}

pub fn run(args: FitArgs) -> Result<()> {
    if let Some(plot) = &args.plot {
        if plot.extension().and_then(|e| e.to_str()) != Some("svg") {
            bail!("--plot {}: the picture is written as SVG; name the file *.svg", plot.display());
        }
    }
    let inputs = std::iter::once(args.input.as_path()).chain(args.compare.iter().map(PathBuf::as_path));
    let mut outputs = Outputs::new(inputs);
    outputs.refuse_inputs(args.out.iter().chain(&args.plot).map(PathBuf::as_path))?;
    let mut dataset = args.input_options.read_to_fit(&args.input)?;
    // The fit reads a recording's time, deflection and torque only: the angles (once the
    // deflection is formed) and the temperature need not stay in memory beside its columns.
    if let swg_host::input::Dataset::Recording(recording) = &mut dataset {
        recording.angles = None;
        recording.temperature = None;
    }
    let compare = args.compare.iter().map(|path| read_model(path)).collect::<Result<Vec<_>, _>>()?;
    let choice = args.model.map_or(ModelChoice::Auto, |arg| arg.0);

    let progress = DelayedProgress::new();
    let outcome = fit_dataset(&dataset, choice, &compare, args.seed, |stage| progress.update(stage)).map_err(
        |error| match error {
            FitDatasetError::Compared { index, source } => anyhow::Error::new(source).context(format!(
                "{}: cannot evaluate on {}",
                args.compare[index].display(),
                args.input.display()
            )),
            other => anyhow::Error::new(other).context(args.input.display().to_string()),
        },
    )?;
    progress.finish();

    let compared = args
        .compare
        .iter()
        .zip(&compare)
        .zip(&outcome.compared_rss)
        .map(|((path, model), &rss)| ComparedReport {
            path: path.display().to_string(),
            model: model.kind().name(),
            params: *model,
            rss,
        })
        .collect();
    let summary = InputSummary {
        path: args.input.display().to_string(),
        kind: dataset.kind(),
        turning_points: outcome.prepared.segmentation.as_ref().map(|s| s.turning_points.len()),
    };
    let report =
        FitReport::new(summary, &outcome.identified, outcome.lines.clone(), outcome.three_segment.clone(), compared);
    let json = to_json("fit", &report).with_context(|| args.input.display().to_string())?;

    // Render everything before writing anything.
    let svg = match (&args.plot, &outcome.identified) {
        (None, _) => None,
        (Some(_), Identified::Loop(fitted)) => {
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
        (Some(_), Identified::Motion(motion)) => {
            let data = &outcome.prepared.data;
            let chosen = motion.chosen.model;
            let torque = &motion.chosen.torque;
            let label = format!("{} (fitted, run from rest)", chosen.kind().name());
            let title = format!("{} — {} fit, RMS {:.3} N·m", file_name(&args.input), chosen.kind().name(), report.rms);
            let time = match &dataset {
                swg_host::input::Dataset::Recording(recording) => recording.time.clone(),
                swg_host::input::Dataset::LoopTable(_) => (0..data.theta.len()).map(|i| i as f64).collect(),
            };
            Some(motion_svg(&title, &time, &data.theta, &data.torque, &[MotionSeries { label: &label, torque }])?)
        }
    };
    // Every output at the end, or none.
    if let Some(out) = &args.out {
        outputs.stage(out, format!("{json}\n").as_bytes())?;
    }
    if let (Some(path), Some(svg)) = (&args.plot, svg) {
        outputs.stage(path, svg.as_bytes())?;
    }
    outputs.commit()?;
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
            Stage::Kind { kind, index, of } => (index, of, format!("fitting the {} model", kind.name())),
        };
        self.bar.set_length(total as u64);
        self.bar.set_position(done as u64);
        self.bar.set_message(message);
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
