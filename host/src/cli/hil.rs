//! `swg-host hil`: the joint firmware controls a simulated joint in lockstep; the true torque
//! is scored against the reference for each scenario and controller mode.
use super::push::PortOptions;
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use model_core::GearModel;
use std::path::PathBuf;
use swg_host::hil::output::picture_name;
use swg_host::hil::{self, GearTruth, HilOptions, Scenario};
use swg_host::report::output::Outputs;
use swg_host::report::params::{parse_model, read_model};
use swg_host::simulate::{BoucWen, MicroSlip, Physics};
use swg_protocol::ControlMode;

#[derive(Args)]
pub struct HilArgs {
    /// The parameter file pushed to the joint (either model kind, as `fit --out` writes).
    #[arg(value_name = "PARAMS.json")]
    params: PathBuf,
    #[command(flatten)]
    port: PortOptions,
    /// The gear's truth: any parameter file the project reads (either kind), run from rest;
    /// overrides --physics.
    #[arg(long, value_name = "GEAR.json")]
    gear: Option<PathBuf>,
    /// The gear's truth physics, with the simulator's defaults (genetic: the bundled seed fit).
    #[arg(long, value_enum, default_value_t = PhysicsArg::MicroSlip)]
    physics: PhysicsArg,
    /// What the joint is asked to do.
    #[arg(long, value_enum, default_value_t = ScenarioArg::All)]
    scenario: ScenarioArg,
    /// The controller's mode.
    #[arg(long, value_enum, default_value_t = ModeArg::All)]
    mode: ModeArg,
    /// Simulated seconds per run.
    #[arg(long, default_value_t = Scenario::DEFAULT_SECONDS, value_name = "S", allow_negative_numbers = true)]
    seconds: f64,
    /// Control rate, Hz.
    #[arg(long, default_value_t = 1000.0, value_name = "HZ", allow_negative_numbers = true)]
    rate: f64,
    /// Print the result as JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// Write one picture per scenario (hil-SCENARIO-PHYSICS.svg) into this directory.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub(super) enum PhysicsArg {
    /// The genetic model of the bundled seed fit (the simulator's default).
    Genetic,
    /// The simulator's Maxwell-slip/Iwan gear (300 elements).
    MicroSlip,
    /// The simulator's Bouc–Wen gear.
    BoucWen,
}

impl PhysicsArg {
    /// The simulator's physics with its defaults.
    pub(super) fn physics(self) -> Physics {
        match self {
            PhysicsArg::Genetic => Physics::Model,
            PhysicsArg::MicroSlip => Physics::MicroSlip(MicroSlip::default()),
            PhysicsArg::BoucWen => Physics::BoucWen(BoucWen::default()),
        }
    }
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ScenarioArg {
    /// 10 N·m at 1 Hz + 5 N·m at 3.7 Hz against a compliant environment.
    TorqueSine,
    /// Steps 6, −4, 12, 2 N·m against the same environment.
    TorqueSteps,
    /// Into a stiff wall, pressed with 8 N·m ± 5 N·m at 2 Hz, held at 8 N·m.
    Contact,
    /// A pendulum link raised to 40° and held.
    GravityHold,
    All,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ModeArg {
    /// Current feed-forward only.
    OpenLoop,
    /// The torque loop on one stiffness from the fit.
    Linear,
    /// The torque loop on the stateful model.
    Model,
    All,
}

pub fn run(args: HilArgs) -> Result<()> {
    let mut outputs = Outputs::new(std::iter::once(args.params.as_path()).chain(args.gear.as_deref()));
    let model = read_model(&args.params)?;
    let truth = match &args.gear {
        Some(path) => {
            let gear = read_model(path)?;
            GearTruth::Model { name: gear_name(path, &gear), model: gear }
        }
        None => {
            let seed = parse_model("data/seed/lht-20-50-fit.json (bundled)".as_ref(), super::simulate::SEED_FIT)?;
            GearTruth::Physics { physics: args.physics.physics(), model: seed }
        }
    };
    let scenarios = match args.scenario {
        ScenarioArg::TorqueSine => vec![Scenario::TorqueSine],
        ScenarioArg::TorqueSteps => vec![Scenario::TorqueSteps],
        ScenarioArg::Contact => vec![Scenario::Contact],
        ScenarioArg::GravityHold => vec![Scenario::GravityHold],
        ScenarioArg::All => Scenario::ALL.to_vec(),
    };
    let modes = match args.mode {
        ModeArg::OpenLoop => vec![ControlMode::OpenLoop],
        ModeArg::Linear => vec![ControlMode::Linear],
        ModeArg::Model => vec![ControlMode::Model],
        ModeArg::All => hil::MODES.to_vec(),
    };
    let options = HilOptions { scenarios, modes, seconds: args.seconds, rate_hz: args.rate, ..HilOptions::new(truth) };
    // Every picture's name is known before the runs: refuse one that names an input first.
    let pictures: Vec<PathBuf> = match &args.plot {
        Some(dir) => options.scenarios.iter().map(|&s| dir.join(picture_name(s, &options.truth.name()))).collect(),
        None => Vec::new(),
    };
    outputs.refuse_inputs(pictures.iter().map(PathBuf::as_path))?;
    options.validate()?;
    let mut link = args.port.open()?;
    let report = hil::run(&mut link, &model, &options).with_context(|| format!("hil on {} failed", args.port.port))?;
    let json = report.to_json()?;
    if let Some(dir) = &args.plot {
        let drawn = report.pictures()?;
        outputs.create_dir(dir)?;
        for (file, svg) in &drawn {
            outputs.stage(&dir.join(file), svg.as_bytes())?;
        }
    }
    let text = if args.json {
        format!("{json}\n")
    } else {
        let mut text = format!("{}\n", report.human());
        if !pictures.is_empty() {
            let each: Vec<String> = pictures.iter().map(|p| p.display().to_string()).collect();
            text.push_str(&format!("pictures: {}\n", each.join(", ")));
        }
        text
    };
    super::print_then_commit(&text, outputs)?;
    Ok(())
}

/// The truth's name in reports for a params file: its kind and file name, `genetic:gear`.
fn gear_name(path: &std::path::Path, model: &GearModel<f64>) -> String {
    let file = path.file_stem().map_or_else(|| "gear".to_owned(), |s| s.to_string_lossy().into_owned());
    format!("{}:{file}", model.kind().label())
}
