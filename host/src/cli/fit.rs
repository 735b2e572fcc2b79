//! `swg-host fit`: identify the model from a loop table or a recording.
use super::InputOptions;
use anyhow::{bail, Context, Result};
use clap::builder::PossibleValue;
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use model_core::{Kind, Model};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use swg_host::fit::{fit_input, FitDatasetError, FitInput, Identified, ModelChoice, Stage};
use swg_host::gear::run_offline;
use swg_host::input::{Dataset, LoopTable, Recording};
use swg_host::report::finite::to_json;
use swg_host::report::fit::{ComparedReport, FitReport, InputSummary, RunReport};
use swg_host::report::output::Outputs;
use swg_host::report::params::read_model;
use swg_host::report::plot::{loop_svg, motion_svg, LoopPlot, MotionSeries};

#[derive(Args)]
pub struct FitArgs {
    /// Bench recordings (`# swg-recording v1`), each a run from its own start, that share one
    /// parameter set; or one loop table (branch,torque_nm,deflection_rad), alone.
    #[arg(required = true, value_name = "INPUT")]
    inputs: Vec<PathBuf>,
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
    /// The model to identify. `auto` fits every kind once per fold without its held-out samples
    /// (three or more runs: each run held out once, whole but the largest, which holds out its
    /// cycles; else every fourth cycle of each run), keeps the one with the lowest error on them
    /// pooled, or one of fewer parameters within a standard error of it, and refits it on every
    /// sample. Default: `auto` on recordings, `genetic` on a loop table (one loop: nothing to
    /// spare).
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
            ModelChoice::Auto => PossibleValue::new("auto")
                .help("Every kind; the lowest error on held-out runs or cycles wins (fewer parameters on a tie), refitted on every sample"),
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
    let inputs = args.inputs.iter().chain(&args.compare).map(PathBuf::as_path);
    let mut outputs = Outputs::new(inputs);
    outputs.refuse_inputs(args.out.iter().chain(&args.plot).map(PathBuf::as_path))?;
    let mut datasets = Vec::with_capacity(args.inputs.len());
    for path in &args.inputs {
        let mut dataset = args.input_options.read_to_fit(path)?;
        // The fit reads a recording's time, deflection and torque only: the angles (once the
        // deflection is formed) and the temperature need not stay in memory beside its columns.
        if let Dataset::Recording(recording) = &mut dataset {
            recording.angles = None;
            recording.temperature = None;
        }
        if matches!(dataset, Dataset::LoopTable(_)) && args.inputs.len() > 1 {
            bail!("{}: a loop table is one loop: fit it alone, not with other inputs", path.display());
        }
        datasets.push(dataset);
    }
    let (table, recordings): (Option<LoopTable>, Vec<Recording>) = match datasets.pop() {
        Some(Dataset::LoopTable(table)) => (Some(table), Vec::new()),
        Some(Dataset::Recording(last)) => {
            let mut recordings: Vec<Recording> = datasets
                .into_iter()
                .filter_map(|d| match d {
                    Dataset::Recording(r) => Some(r),
                    Dataset::LoopTable(_) => None,
                })
                .collect();
            recordings.push(last);
            (None, recordings)
        }
        None => bail!("no input to fit"),
    };
    let input = match &table {
        Some(table) => FitInput::LoopTable(table),
        None => FitInput::Recordings(&recordings),
    };
    let compare = args.compare.iter().map(|path| read_model(path)).collect::<Result<Vec<_>, _>>()?;
    let choice = args.model.map_or(ModelChoice::Auto, |arg| arg.0);
    let paths = args.inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ");

    let progress = DelayedProgress::new();
    let outcome =
        fit_input(input, choice, &compare, args.seed, |stage| progress.update(stage)).map_err(|error| match error {
            FitDatasetError::Compared { index, source } => anyhow::Error::new(source)
                .context(format!("{}: cannot evaluate on {paths}", args.compare[index].display())),
            FitDatasetError::Run { index, source } => {
                anyhow::Error::new(source).context(args.inputs[index].display().to_string())
            }
            other => anyhow::Error::new(other).context(paths.clone()),
        })?;
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
    let runs: Vec<RunReport> = args
        .inputs
        .iter()
        .zip(&outcome.runs)
        .map(|(path, run)| RunReport::new(path.display().to_string(), run))
        .collect();
    let summary = InputSummary {
        path: paths.clone(),
        kind: if table.is_some() { "loop_table" } else { "recording" },
        turning_points: (!runs.is_empty()).then(|| runs.iter().map(|r| r.turning_points).sum()),
    };
    let report = FitReport::new(
        summary,
        runs,
        &outcome.identified,
        outcome.lines.clone(),
        outcome.three_segment.clone(),
        compared,
    );
    let json = to_json("fit", &report).with_context(|| paths.clone())?;

    // Render everything before writing anything.
    let name = args.inputs.iter().map(|p| file_name(p)).collect::<Vec<_>>().join(", ");
    let svg = match (&args.plot, &outcome.identified, &outcome.prepared) {
        (None, _, _) => None,
        (Some(_), Identified::Loop(fitted), Some(prepared)) => {
            let model = Model::new(fitted.params)?;
            let title = format!("{name} — genetic hysteresis fit, RMS {:.3} N·m", fitted.rms);
            Some(loop_svg(&LoopPlot {
                title: &title,
                data: &prepared.data,
                branch: &prepared.branch,
                model: &model,
                amplitude: fitted.reference_amplitude,
                lines: &outcome.lines,
                three_segment: outcome.three_segment.as_ref(),
            })?)
        }
        (Some(_), identified, _) => {
            let chosen = identified.model();
            // The runs one after the other, each from rest along its reversals.
            let (mut time, mut theta, mut torque, mut model) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for (recording, run) in recordings.iter().zip(&outcome.runs) {
                let first = recording.time.first().copied().unwrap_or(0.0);
                let step = recording.time.get(1).map_or(0.0, |t| t - first);
                let offset = time.last().map_or(0.0, |&end: &f64| end + step - first);
                time.extend(recording.time.iter().map(|t| t + offset));
                theta.extend_from_slice(&recording.deflection);
                torque.extend_from_slice(&recording.torque);
                let evaluations = run_offline(&chosen, &recording.deflection, &run.offline.reversals)
                    .map_err(|(_, e)| e)
                    .context("the fitted model along the recording")?;
                model.extend(evaluations.iter().map(|e| e.torque));
            }
            let label = format!("{} (fitted, run from rest)", chosen.kind().name());
            let title = format!("{name} — {} fit, RMS {:.3} N·m", chosen.kind().name(), report.rms);
            Some(motion_svg(&title, &time, &theta, &torque, &[MotionSeries { label: &label, torque: &model }])?)
        }
    };
    // Every output at the end, or none.
    if let Some(out) = &args.out {
        outputs.stage(out, format!("{json}\n").as_bytes())?;
    }
    if let (Some(path), Some(svg)) = (&args.plot, svg) {
        outputs.stage(path, svg.as_bytes())?;
    }
    let text = if args.json {
        format!("{json}\n")
    } else {
        let mut text = report.human();
        for written in args.out.iter().chain(&args.plot) {
            text.push_str(&format!("wrote {}\n", written.display()));
        }
        text
    };
    super::print_then_commit(&text, outputs)
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
            Stage::Refit { kind } => (1, 1, format!("refitting the {} model on every sample", kind.name())),
        };
        self.bar.set_length(total as u64);
        self.bar.set_position(done as u64);
        self.bar.set_message(message);
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
