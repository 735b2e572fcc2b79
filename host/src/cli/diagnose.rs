//! `swg-host diagnose`: where the model and a recording disagree, and which physics is missing;
//! of several runs, each alone and then what they show together.
use super::InputOptions;
use anyhow::{Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use swg_host::diagnose::asymmetry::AsymmetryCheck;
use swg_host::diagnose::runs::diagnose_runs;
use swg_host::diagnose::{diagnose_dataset, DiagnoseOutcome};
use swg_host::input::{Dataset, Recording};
use swg_host::report::diagnose::DiagnoseReport;
use swg_host::report::diagnose_runs::RunsReport;
use swg_host::report::finite::to_json;
use swg_host::report::output::{same_file, Outputs};
use swg_host::report::params::read_params;
use swg_host::report::plot::{diagnosis_loop_svg, drift_svg, masing_svg, residuals_svg};

#[derive(Args)]
pub struct DiagnoseArgs {
    /// Bench recording (`# swg-recording v1`) or loop table; several recordings of one gear are
    /// diagnosed each alone, from its own start, then together (the runs as independent parts).
    #[arg(required = true, num_args = 1..)]
    inputs: Vec<PathBuf>,
    /// Start from these parameters instead of fitting the baseline (of every run).
    #[arg(long, value_name = "PARAMS.json")]
    params: Option<PathBuf>,
    /// Print the result as JSON instead of the report.
    #[arg(long)]
    json: bool,
    /// Write residuals.svg, loop.svg, masing.svg and drift.svg into this directory (of several
    /// runs: into run-K/ within it, K = 1, 2, … in the order given).
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Seed of the baseline fit's particle swarm.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    input_options: InputOptions,
}

/// The pictures of a diagnosis, and where they go.
const PICTURES: [&str; 4] = ["residuals.svg", "loop.svg", "masing.svg", "drift.svg"];

pub fn run(args: DiagnoseArgs) -> Result<()> {
    let mut outputs = Outputs::new(args.inputs.iter().map(PathBuf::as_path).chain(args.params.as_deref()));
    let several = args.inputs.len() > 1;
    // Each run's pictures' directory.
    let picture_dirs: Vec<PathBuf> = match &args.plot {
        None => Vec::new(),
        Some(dir) if several => (1..=args.inputs.len()).map(|k| dir.join(format!("run-{k}"))).collect(),
        Some(dir) => vec![dir.clone()],
    };
    // Checked before the diagnosis, which takes seconds a run: the pictures could not be written.
    if let Some(dir) = args.plot.as_deref().filter(|dir| dir.exists() && !dir.is_dir()) {
        anyhow::bail!("{}: --plot takes a directory to write the pictures into, and this is a file", dir.display());
    }
    let pictures: Vec<PathBuf> = picture_dirs.iter().flat_map(|dir| PICTURES.map(|name| dir.join(name))).collect();
    outputs.refuse_inputs(pictures.iter().map(PathBuf::as_path))?;
    // A run given twice, by its path or as a copy, would agree with itself and weigh twice in what
    // the runs show together. Only files of one size are read to compare.
    let sizes: Vec<Option<u64>> = args.inputs.iter().map(|p| std::fs::metadata(p).ok().map(|m| m.len())).collect();
    for (k, path) in args.inputs.iter().enumerate() {
        for (first, other) in args.inputs[..k].iter().enumerate() {
            if same_file(path, other) {
                anyhow::bail!("{}: given twice (runs {} and {}): give each run once", path.display(), first + 1, k + 1);
            }
            if sizes[first].is_some() && sizes[first] == sizes[k] && same_bytes(other, path) {
                anyhow::bail!(
                    "{}: the same recording as {} (runs {} and {}): give each run once",
                    path.display(),
                    other.display(),
                    first + 1,
                    k + 1
                );
            }
        }
    }
    let mut datasets = Vec::with_capacity(args.inputs.len());
    for path in &args.inputs {
        let dataset = read(&args.input_options, path)?;
        if several && matches!(dataset, Dataset::LoopTable(_)) {
            anyhow::bail!("{}: a loop table is one loop: diagnose it alone, not with other runs", path.display());
        }
        datasets.push(dataset);
    }
    let baseline = args.params.as_deref().map(read_params).transpose()?;
    let kinds: Vec<&'static str> = datasets.iter().map(Dataset::kind).collect();
    let names: Vec<String> = args.inputs.iter().map(|p| p.display().to_string()).collect();

    let (outcomes, json, text) = if several {
        let bar = ProgressBar::new(datasets.len() as u64);
        bar.set_style(
            ProgressStyle::with_template("{spinner} diagnose [{elapsed}] {bar:30} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let outcome = diagnose_runs(datasets, baseline, args.seed, |index, of| {
            bar.set_position(index as u64);
            bar.set_message(format!("run {} of {of}: {}", index + 1, names[index]));
        })
        .map_err(|error| anyhow::Error::new(error.source).context(names[error.index].clone()))?;
        bar.finish_and_clear();
        let runs = outcome.runs.iter().enumerate().map(|(k, o)| DiagnoseReport::new(names[k].clone(), kinds[k], o));
        let report = RunsReport { runs: runs.collect(), across: outcome.across };
        let json = to_json("diagnosis", &report).map_err(|error| {
            let causes: Vec<String> =
                report.runs.iter().map(|r| format!("{}: {}", r.input, r.non_finite_cause())).collect();
            anyhow::anyhow!("{error}: {}", causes.join("; "))
        })?;
        (outcome.runs, json, report.human())
    } else {
        let dataset = datasets.pop().context("no input to diagnose")?;
        let outcome = diagnose_dataset(dataset, baseline, args.seed).with_context(|| names[0].clone())?;
        let report = DiagnoseReport::new(names[0].clone(), kinds[0], &outcome);
        // The text is made of the same figures: a report that is not finite is printed in neither form.
        let json = to_json("diagnosis", &report)
            .map_err(|error| anyhow::anyhow!("{error}: {}", report.non_finite_cause()))
            .with_context(|| names[0].clone())?;
        (vec![outcome], json, report.human())
    };

    for (outcome, dir) in outcomes.iter().zip(&picture_dirs) {
        stage_pictures(&mut outputs, outcome, dir)?;
    }
    let report = if args.json {
        format!("{json}\n")
    } else {
        let mut report = text;
        if let Some(dir) = &args.plot {
            let within = if several { format!("{}/run-K", dir.display()) } else { dir.display().to_string() };
            let each: Vec<String> = PICTURES.iter().map(|name| format!("{within}/{name}")).collect();
            report.push_str(&format!("pictures: {}\n", each.join(", ")));
        }
        report
    };
    super::print_then_commit(&report, outputs)?;
    Ok(())
}

/// Whether two files hold the same bytes, compared a block at a time (a recording may be larger
/// than memory would like twice); false where either cannot be read.
fn same_bytes(a: &Path, b: &Path) -> bool {
    use std::io::Read;
    let (Ok(a), Ok(b)) = (std::fs::File::open(a), std::fs::File::open(b)) else { return false };
    let (mut a, mut b) = (std::io::BufReader::new(a), std::io::BufReader::new(b));
    let (mut block_a, mut block_b) = (vec![0u8; 1 << 16], vec![0u8; 1 << 16]);
    loop {
        let Ok(n) = a.read(&mut block_a) else { return false };
        if n == 0 {
            // The first has ended: the same only if the second has too.
            return b.read(&mut block_b[..1]).is_ok_and(|m| m == 0);
        }
        if b.read_exact(&mut block_b[..n]).is_err() || block_a[..n] != block_b[..n] {
            return false;
        }
    }
}

/// Reads one run. The diagnosis reads a recording's input angle (the kinematic error) but not
/// its output angle once the deflection is formed: it need not stay in memory beside the columns.
fn read(options: &InputOptions, path: &Path) -> Result<Dataset> {
    let mut dataset = options.read_to_fit(path)?;
    if let Dataset::Recording(Recording { angles: Some(angles), .. }) = &mut dataset {
        angles.output = Vec::new();
    }
    Ok(dataset)
}

/// Stages the pictures of one diagnosis in `dir`.
fn stage_pictures(outputs: &mut Outputs, outcome: &DiagnoseOutcome, dir: &Path) -> Result<()> {
    let residual_svg = residuals_svg(&outcome.observed, &outcome.before, &outcome.after)?;
    let mirrored = matches!(outcome.asymmetry, AsymmetryCheck::Yes(_));
    let kinks: Vec<f64> =
        outcome.kinks.named().map_or(Vec::new(), |k| k.kinks.iter().map(|kink| kink.at_rad).collect());
    let loop_svg = diagnosis_loop_svg(&outcome.observed, &outcome.diagnosis, mirrored, &kinks)?;
    outputs.create_dir(dir)?;
    let [residuals, loops, masing, drift] = PICTURES.map(|name| dir.join(name));
    outputs.stage(&residuals, residual_svg.as_bytes())?;
    outputs.stage(&loops, loop_svg.as_bytes())?;
    outputs.stage(&masing, masing_svg(&outcome.observed, &outcome.non_masing)?.as_bytes())?;
    outputs.stage(&drift, drift_svg(&outcome.ratcheting)?.as_bytes())?;
    Ok(())
}
