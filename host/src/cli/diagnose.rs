//! `swg-host diagnose`: where the model and a recording disagree, and which physics is missing.
use super::InputOptions;
use anyhow::{Context, Result};
use clap::Args;
use model_core::Params;
use serde::Serialize;
use std::fmt::Write;
use std::path::PathBuf;
use swg_host::diagnose::{
    diagnose_dataset, locate, ExtendedFit, Finding, Observation, Observed, Rejection, MAX_HALF_SPREAD, MIN_BIC_DROP,
    MIN_EXPLAINED, MIN_HALF_Z,
};
use swg_host::fit::NoiseModel;
use swg_host::input::Dataset;
use swg_host::output::write_atomically;
use swg_host::paramsfile::read_params;
use swg_host::plot::{diagnosis_loop_svg, residuals_svg};

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

#[derive(Serialize)]
struct Report {
    input: String,
    kind: &'static str,
    baseline: ModelSummary,
    noise: Option<NoiseModel>,
    locate: Vec<Observation>,
    revealable: Vec<&'static str>,
    not_revealable: Vec<NotRevealable>,
    findings: Vec<Finding>,
    rejected: Vec<Rejection>,
    #[serde(rename = "final")]
    final_model: ModelSummary,
    held_out: Option<HeldOut>,
    criteria: Criteria,
}

#[derive(Serialize)]
struct ModelSummary {
    rss: f64,
    rms: f64,
    n: usize,
    params: Params<f64>,
    effects: Vec<&'static str>,
}

#[derive(Serialize)]
struct NotRevealable {
    effect: &'static str,
    why: String,
}

#[derive(Serialize)]
struct HeldOut {
    /// RMS residual, N·m, on the held-out samples of the baseline and of the final model, each
    /// refitted without them.
    rms_before: f64,
    rms_after: f64,
    samples: usize,
}

#[derive(Serialize)]
struct Criteria {
    min_bic_drop: f64,
    min_explained: f64,
    min_half_z: f64,
    max_half_spread: f64,
}

fn summary(observed: &Observed, fit: &ExtendedFit) -> Result<ModelSummary> {
    let all: Vec<usize> = (0..observed.data.theta.len()).collect();
    let residuals = fit.residuals(observed, &all).context("the model cannot be evaluated on the data")?;
    let rss: f64 = residuals.iter().map(|r| r * r).sum();
    Ok(ModelSummary {
        rss,
        rms: (rss / residuals.len() as f64).sqrt(),
        n: residuals.len(),
        params: fit.params,
        effects: fit.active.iter().map(|e| e.name()).collect(),
    })
}

pub fn run(args: DiagnoseArgs) -> Result<()> {
    let dataset = args.input_options.read_to_fit(&args.input)?;
    let baseline = args.params.as_deref().map(read_params).transpose()?;
    let (observed, diagnosis) =
        diagnose_dataset(&dataset, baseline, args.seed).with_context(|| args.input.display().to_string())?;
    let all: Vec<usize> = (0..dataset.len()).collect();
    let before = diagnosis.baseline.residuals(&observed, &all).context("baseline residuals")?;
    let after = diagnosis.final_fit.residuals(&observed, &all).context("final residuals")?;

    let report = Report {
        input: args.input.display().to_string(),
        kind: match dataset {
            Dataset::LoopTable(_) => "loop_table",
            Dataset::Recording(_) => "recording",
        },
        baseline: summary(&observed, &diagnosis.baseline)?,
        noise: observed.noise,
        locate: locate(&observed, &before),
        revealable: observed.revealable().iter().map(|e| e.name()).collect(),
        not_revealable: observed
            .cannot_reveal
            .iter()
            .map(|(e, why)| NotRevealable { effect: e.name(), why: why.clone() })
            .collect(),
        findings: diagnosis.findings.clone(),
        rejected: diagnosis.rejected.clone(),
        final_model: summary(&observed, &diagnosis.final_fit)?,
        held_out: diagnosis.held_out_rms.map(|(rms_before, rms_after)| HeldOut {
            rms_before,
            rms_after,
            samples: observed.held_out.len(),
        }),
        criteria: Criteria {
            min_bic_drop: MIN_BIC_DROP,
            min_explained: MIN_EXPLAINED,
            min_half_z: MIN_HALF_Z,
            max_half_spread: MAX_HALF_SPREAD,
        },
    };

    if let Some(dir) = &args.plot {
        let residual_svg = residuals_svg(&observed, &before, &after).map_err(anyhow::Error::msg)?;
        let loop_svg = diagnosis_loop_svg(&observed, &diagnosis).map_err(anyhow::Error::msg)?;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (name, svg) in [("residuals.svg", residual_svg), ("loop.svg", loop_svg)] {
            let path = dir.join(name);
            write_atomically(&path, svg.as_bytes()).with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", human(&report));
        if let Some(dir) = &args.plot {
            println!("pictures: {}/residuals.svg, {}/loop.svg", dir.display(), dir.display());
        }
    }
    Ok(())
}

fn human(report: &Report) -> String {
    let mut s = String::new();
    let b = &report.baseline;
    let _ = writeln!(s, "{} ({}, {} samples)", report.input, report.kind.replace('_', " "), b.n);
    if let Some(noise) = &report.noise {
        let _ = writeln!(
            s,
            "measurement noise: torque {:.3e} N·m, deflection {:.3e} rad",
            noise.torque_nm, noise.deflection_rad
        );
    }
    let _ = writeln!(s, "baseline model: RSS {:.5} (N·m)², RMS {:.4} N·m", b.rss, b.rms);
    let _ = writeln!(s, "\nwhere the residual concentrates");
    for o in &report.locate {
        let _ = writeln!(s, "  - {}", o.words);
    }
    if report.findings.is_empty() {
        let _ = writeln!(s, "\nno missing physics found: no effect passed the evidence tests");
    } else {
        let _ = writeln!(s, "\nmissing physics, most important first");
        for (k, f) in report.findings.iter().enumerate() {
            let _ = writeln!(s, "  {}. {}: {:.4e} {} ({})", k + 1, f.effect, f.magnitude, f.unit, f.meaning);
            let _ = writeln!(s, "     where: {}", f.location);
            let halves = f.evidence.halves.map_or(String::new(), |[a, b]| format!(", halves {a:.4e} / {b:.4e}"));
            let _ = writeln!(
                s,
                "     RSS {:.5} → {:.5} (N·m)²; ΔBIC {:.0}, explains {:.0} % of the residual{halves}",
                f.rss_before,
                f.rss_after,
                f.evidence.delta_bic,
                100.0 * f.evidence.explained
            );
        }
    }
    let fm = &report.final_model;
    let effects = if fm.effects.is_empty() { "no effects".to_string() } else { fm.effects.join(" + ") };
    let _ = writeln!(s, "\nfinal model (baseline + {effects}): RSS {:.5} (N·m)², RMS {:.4} N·m", fm.rss, fm.rms);
    if let Some(h) = &report.held_out {
        let _ = writeln!(
            s,
            "held-out error ({} samples not used in the fit): RMS {:.4} → {:.4} N·m",
            h.samples, h.rms_before, h.rms_after
        );
    }
    if !report.rejected.is_empty() {
        let _ = writeln!(s, "\nnot accepted");
        for r in &report.rejected {
            let _ = writeln!(s, "  - {}: {}", r.effect, r.reason);
        }
    }
    if !report.not_revealable.is_empty() {
        let _ = writeln!(s, "\ncannot be told from this data");
        for r in &report.not_revealable {
            let _ = writeln!(s, "  - {}: {}", r.effect, r.why);
        }
    }
    s
}
