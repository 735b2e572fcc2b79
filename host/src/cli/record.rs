//! `swg-host record`: the joint plays an identification plan and streams the recording.
use super::hil::PhysicsArg;
use super::push::PortOptions;
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use swg_host::hil::GearTruth;
use swg_host::input::plan::read_plan;
use swg_host::link::push::{joint_params, JointSettings};
use swg_host::record::{default_plan, record, PlanRequest, Progress, RecordOptions, SimulatedJoint};
use swg_host::report::output::Outputs;
use swg_host::report::params::{parse_model, read_model};

#[derive(Args)]
pub struct RecordArgs {
    #[command(flatten)]
    port: PortOptions,
    /// The recording written (format v1, `# start: rest`), once the whole plan has played.
    #[arg(long, value_name = "REC.csv")]
    out: PathBuf,
    /// A plan file (README, "Plan"), with its own limits. Default: the default plan (a rest,
    /// sines at A/4, A/2 and A each at --frequency and 4× it, a dithered hold at 0.6·A, back to
    /// rest) in deflection.
    #[arg(long, value_name = "PLAN.json")]
    plan: Option<PathBuf>,
    /// A parameter file written to the joint first (not stored): the joint needs a set for its
    /// gear ratio and its deflection. Its identified range sets the default plan's amplitude and
    /// limits. Without it, the joint's own set is used.
    #[arg(long, value_name = "PARAMS.json")]
    params: Option<PathBuf>,
    /// Gear reduction ratio N of the set written with --params.
    #[arg(long, value_name = "N")]
    ratio: Option<f64>,
    /// Ticks a second the plan plays at: the board's tick rate (in lockstep, any).
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    rate: f64,
    /// The default plan's largest deflection amplitude A, rad. Default: 80 % of the --params
    /// set's identified range.
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    amplitude: Option<f64>,
    /// The default plan's slow frequency, Hz (it plays 4× this too, and dithers at 10×).
    #[arg(long, default_value_t = 0.5, value_name = "HZ")]
    frequency: f64,
    /// The default plan's torque limit, N·m. Default: 1.5× the --params model's largest torque
    /// within ±1.5·A.
    #[arg(long, value_name = "NM", allow_negative_numbers = true)]
    torque_limit: Option<f64>,
    /// The default plan's deflection limit, rad. Default: 1.5·A.
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    deflection_limit: Option<f64>,
    /// Write the recording even when samples were lost, with the gaps listed in its metadata.
    #[arg(long)]
    allow_gaps: bool,
    /// The board ticks in lockstep (QEMU): swg-host simulates the joint it drives, with this
    /// truth physics, its output clamped, a torque sensor with --sensor-offset and
    /// --sensor-noise, and a temperature that rises with the motor's losses.
    #[arg(long, value_enum, value_name = "PHYSICS")]
    simulated_joint: Option<PhysicsArg>,
    /// The simulated torque sensor's offset, N·m.
    #[arg(long, default_value_t = 0.3, value_name = "NM", allow_negative_numbers = true)]
    sensor_offset: f64,
    /// The simulated torque sensor's noise (standard deviation), N·m.
    #[arg(long, default_value_t = 0.05, value_name = "NM", allow_negative_numbers = true)]
    sensor_noise: f64,
}

pub fn run(args: RecordArgs) -> Result<()> {
    let mut outputs = Outputs::new(args.plan.iter().chain(&args.params).map(PathBuf::as_path));
    outputs.refuse_inputs([args.out.as_path()])?;
    let model = args.params.as_deref().map(read_model).transpose()?;
    let params = match (&model, args.ratio) {
        (Some(model), Some(ratio)) => {
            let settings = JointSettings { gear_ratio: ratio, torque_limit: 60.0, direction_band: 2.0e-6 };
            Some(joint_params(model, &settings).context("--params")?)
        }
        (Some(_), None) => bail!("--params needs --ratio: the joint's gear ratio N"),
        (None, _) => None,
    };
    let spec = match &args.plan {
        Some(path) => read_plan(path).context("--plan")?,
        None => {
            let asked = PlanRequest {
                amplitude: args.amplitude,
                frequency_hz: args.frequency,
                torque_limit: args.torque_limit,
                deflection_limit: args.deflection_limit,
            };
            default_plan(&asked, model.as_ref())?
        }
    };
    let plan = spec.at_rate(args.rate)?;
    let simulated = match args.simulated_joint {
        Some(physics) => {
            let seed = parse_model("data/seed/lht-20-50-fit.json (bundled)".as_ref(), super::simulate::SEED_FIT)?;
            let truth = GearTruth::Physics { physics: physics.physics(), model: seed };
            Some(SimulatedJoint {
                torque_offset_nm: args.sensor_offset,
                torque_noise_nm: args.sensor_noise,
                ..SimulatedJoint::new(truth)
            })
        }
        None => None,
    };
    let options = RecordOptions {
        plan,
        plan_text: spec.describe(),
        plan_source: spec.source().to_owned(),
        params,
        simulated,
        allow_gaps: args.allow_gaps,
    };
    if let Some(simulated) = &options.simulated {
        simulated.validate()?;
    }
    let mut link = args.port.open()?;
    let bar = ProgressBar::new(u64::from(plan.ticks()));
    bar.set_style(
        ProgressStyle::with_template("{spinner} record [{elapsed}] {bar:30} {pos}/{len} ticks {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let segments = plan.segments();
    let mut show = |progress: Progress| {
        bar.set_position(progress.recorded);
        let name = segments.get(usize::from(progress.segment)).map_or("", |s| s.name());
        bar.set_message(format!("segment {} of {} ({name})", progress.segment + 1, segments.len()));
    };
    let recorded = record(&mut link, &options, &mut show);
    bar.finish_and_clear();
    let recorded = recorded.with_context(|| format!("record on {} failed", args.port.port))?;
    let mut csv = Vec::new();
    recorded.recording.write(&mut csv).context("cannot format the recording")?;
    outputs.stage(&args.out, &csv)?;
    let samples = recorded.recording.time.len();
    let lost = match recorded.gaps.len() {
        0 => "0 samples lost".to_owned(),
        n => format!("{n} gap(s), {} samples dropped by the joint: listed in its metadata", recorded.dropped),
    };
    let text = format!(
        "recorded {samples} samples ({:.1} s at {} Hz) from firmware {} (protocol {}); {lost}\n\
         link: {} batches ({} empty), {:.0} samples/s over {:.1} s; the joint's queue held {} ticks at most\n\
         plan: {}\n\
         wrote {}\n",
        samples as f64 / args.rate,
        args.rate,
        recorded.device.firmware_version,
        recorded.device.protocol_version,
        recorded.batches,
        recorded.empty_batches,
        recorded.samples_per_second(),
        recorded.wall.as_secs_f64(),
        recorded.high_water,
        options.plan_text,
        args.out.display(),
    );
    super::print_then_commit(&text, outputs)?;
    Ok(())
}
