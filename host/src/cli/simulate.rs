//! `swg-host simulate`: write a recording (format v1) from a motion through a gear's truth
//! physics (by default today's sine through the model).
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use std::path::PathBuf;
use swg_host::diagnose::effects::EffectValue;
use swg_host::input::plan::{read_plan, PlanSpec};
use swg_host::report::output::Outputs;
use swg_host::report::params::{parse_model, read_model};
use swg_host::simulate::{
    read_physics_params, read_trajectory, simulate_experiment, BoucWen, Catalogue, Experiment, MicroSlip, Motion,
    Physics, Preisach, Simulation,
};
use swg_protocol::plan::{Channel, Limits};

/// The fit of the paper's table that ships with the tool (`data/seed/lht-20-50-fit.json`).
pub const SEED_FIT: &str = include_str!("../../../data/seed/lht-20-50-fit.json");

/// The truth physics' equations and defaults, at the end of `--help`.
const PHYSICS_HELP: &str = "\
Truth physics (--physics), θ the elastic deflection (rad), T the torque (N·m), at rest θ = 0:
  genetic     the params file's model (--params): under --motion sine the symmetric loop of
              amplitude A, under the others model-core's GeneticMemory (Madelung's rules) from rest.
  bouc-wen    T = a·k·θ + k3·θ³ + (1 − a)·k·z,  dz = dθ·(A_bw − |z|ⁿ·(β_bw·sign(dθ·z) + γ_bw)),
              z = 0 at rest; for n = 1 integrated exactly (closed form between sign changes of
              z), else by RK4 within 2e-5 of z's bound per A_bw·z_max of travel (model-core).
              Defaults: k = 9000 N·m/rad, a = 0.85, k3 = 1.2e10 N·m/rad³, A_bw = 1,
              β_bw = γ_bw = 1250 1/rad, n = 1 (z saturates at 0.4 mrad). No exact return-point
              memory.
  micro-slip  T = k1·θ + k3·θ³ + Σ k_e·s_i,  s_i ← clamp(s_i + Δθ, −d_i, d_i), s_i = 0 at rest;
              M elements, k_e = K_slip/M, d_i the quantiles (i + ½)/M of p(d) ∝ d^p on
              [d_min, d_max]. Defaults: k1 = 6000 N·m/rad, k3 = 1.2e10 N·m/rad³, M = 300,
              K_slip = 3000 N·m/rad, d_min = 0, d_max = 2 mrad, p = 0 (uniform).
  catalogue   T = T_s(θ) + Σ k_e·s_i, the slip elements as micro-slip's and T_s a harmonic-drive
              catalogue's three segments: stiffness K1 for |T_s| < T1, K2 for T1 ≤ |T_s| < T2,
              K3 beyond (K1 < K2 < K3), each σ·K_j on the + side (σ = positive_scale). With
              K_j' = σ·K_j for θ > 0, K_j for θ < 0, θ1 = T1/K1', θ2 = θ1 + (T2 − T1)/K2':
              T_s = sign(θ)·K1'·|θ| for |θ| < θ1, sign(θ)·(T1 + K2'·(|θ| − θ1)) for |θ| < θ2,
              sign(θ)·(T2 + K3'·(|θ| − θ2)) beyond: kinks where T_s reaches ±T1, ±T2.
              Defaults: K1 = 14000, K2 = 26000, K3 = 36000 N·m/rad, T1 = 7, T2 = 19 N·m, σ = 1,
              M = 300, K_slip = 2000 N·m/rad, d_min = 0, d_max = 2 mrad, p = 0.
  preisach    T = k1·θ + k3·θ³ + Σ (k_e·θ − Φ(p_i)),  p_i ← clamp(p_i, θ − d_i, θ + d_i), p_i = 0
              at rest, Φ(p) = k_e·(p + skew·w·ln cosh(p/w)): micro-slip's elements, each gripping
              1 + skew·tanh(p_i/w) times as hard where its play p_i sits (a Preisach density over
              relay centres that is not uniform: loops depend on where they sit, not Masing).
              Defaults: micro-slip's, and skew = 0.7, w = 0.4 mrad.
--physics-params FILE.json overrides any of: bouc-wen {k, a, k3, a_bw, beta_bw, gamma_bw, n};
micro-slip {k1, k3, elements, slip_stiffness, min_slip_rad, max_slip_rad, slip_exponent};
catalogue {k1, k2, k3, t1_nm, t2_nm, positive_scale, elements, slip_stiffness, min_slip_rad,
max_slip_rad, slip_exponent}; preisach {micro-slip's, skew, skew_width_rad}.";

#[derive(Args)]
#[command(after_long_help = PHYSICS_HELP)]
pub struct SimulateArgs {
    /// Recording to write.
    #[arg(long, short, value_name = "FILE")]
    out: PathBuf,
    /// Model parameters (JSON with a `params` field) of `--physics genetic`; default: the bundled
    /// fit of the seed table.
    #[arg(long, value_name = "PARAMS.json")]
    params: Option<PathBuf>,
    /// The deflection x(t) the bench drives (A = --amplitude, f = the frequency being played,
    /// φ = 2π·f·t in its block, s(u) = 10u³ − 15u⁴ + 6u⁵ a ramp from rest over one period 1/f).
    ///
    /// sine: x = A·sin φ (today's loops). biased: ramp to b − 0.15·A, then x = b − 0.15·A·cos φ
    /// (mean b). nested: x = A·(0.75·sin φ + 0.25·sin 9φ), minor loops inside the big swing.
    /// random: 20 sines with seeded (--seed) random frequencies in [0.1·f, 3·f] and phases, faded
    /// in by s over 1/f, scaled to a peak of exactly A. hold: ramp to b − 0.02·A, then
    /// x = b − 0.02·A·cos 10φ (a dither about the load b). FILE.csv: the columns time_s (strictly
    /// increasing) and deflection_rad, played at those times (--rate, --cycles, --frequency
    /// unused). plan: the default plan of an identification experiment (what `fit` and
    /// `diagnose` need: a rest, sines of ¼·A, ½·A and A, each at f and 4·f, three cycles each,
    /// a dithered hold at 0.6·A and back to rest; --cycles unused). PLAN.json: a plan file
    /// (README, "Plan"), played at --rate (--amplitude, --frequency, --cycles unused). All but
    /// sine start at rest (x = 0, gear unstressed).
    #[arg(long, default_value = "sine", value_name = "sine|biased|nested|random|hold|plan|FILE.csv|PLAN.json", value_parser = parse_motion)]
    motion: MotionArg,
    /// The bias b of `--motion biased` and the load of `--motion hold`, rad [default: 0.6·A].
    #[arg(long, value_name = "RAD", allow_hyphen_values = true)]
    bias: Option<f64>,
    /// The gear's truth physics: the model (genetic) or one it is not; equations and defaults
    /// at the end of --help.
    #[arg(long, value_enum, default_value_t = PhysicsArg::Genetic)]
    physics: PhysicsArg,
    /// Parameters of --physics micro-slip, bouc-wen, catalogue or preisach (JSON object; missing fields
    /// keep their defaults, listed at the end of --help).
    #[arg(long, value_name = "FILE.json")]
    physics_params: Option<PathBuf>,
    /// Deflection amplitude A of the loops, rad.
    #[arg(long, default_value_t = 1.168e-3, value_name = "RAD", allow_negative_numbers = true)]
    amplitude: f64,
    /// Excitation frequency, Hz; several (comma-separated or repeated) are played in turn.
    #[arg(
        long = "frequency",
        value_delimiter = ',',
        default_value = "0.5",
        value_name = "HZ",
        allow_negative_numbers = true
    )]
    frequencies: Vec<f64>,
    /// Whole cycles at each frequency.
    #[arg(long, default_value_t = 4)]
    cycles: u32,
    /// Sample rate, Hz.
    #[arg(long, default_value_t = 1000.0, value_name = "HZ", allow_negative_numbers = true)]
    rate: f64,
    /// Gear reduction ratio N.
    #[arg(long, default_value_t = 50.0, value_name = "N", allow_negative_numbers = true)]
    ratio: f64,
    /// Input (wave generator) speed, rad/s; 0 keeps the input locked.
    #[arg(long, default_value_t = 0.0, value_name = "RAD_S", allow_negative_numbers = true)]
    input_speed: f64,
    /// Input encoder resolution, bits per revolution (default: exact angles).
    #[arg(long, value_name = "BITS")]
    input_bits: Option<u32>,
    /// Output encoder resolution, bits per revolution (default: exact angles).
    #[arg(long, value_name = "BITS")]
    output_bits: Option<u32>,
    /// Torque sensor noise, standard deviation, N·m.
    #[arg(long, default_value_t = 0.05, value_name = "NM", allow_negative_numbers = true)]
    torque_noise: f64,
    /// Add a temperature column starting at this temperature, °C.
    #[arg(long, value_name = "CELSIUS", allow_negative_numbers = true)]
    temperature: Option<f64>,
    /// Temperature rise over time, K/s (with --temperature).
    #[arg(
        long,
        default_value_t = 0.0,
        value_name = "K_PER_S",
        requires = "temperature",
        allow_negative_numbers = true
    )]
    temperature_rise: f64,
    /// Add a physical effect the model leaves out, NAME=VALUE in SI units (repeatable):
    /// backlash=WIDTH_RAD, coulomb_friction=NM, viscous_damping=NM_S_PER_RAD,
    /// kinematic_error=RAD (2nd-order amplitude), thermal_drift=PER_K, torque_offset=NM,
    /// channel_delay=S (the torque channel late by S seconds; negative: early).
    #[arg(long = "effect", value_name = "NAME=VALUE")]
    effects: Vec<EffectValue>,
    /// The deflection's zero θ0: the encoders were zeroed off the gear's true zero, so every
    /// recorded deflection is the true one + θ0 (the output encoder reads θ0 less, before its
    /// quantisation). Written as `# deflection_zero_rad:` when not 0.
    #[arg(long, default_value_t = 0.0, value_name = "RAD", allow_hyphen_values = true)]
    deflection_zero: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum PhysicsArg {
    /// The params file's model (--params, of any kind; the bundled genetic seed fit by default).
    Genetic,
    /// A Maxwell-slip/Iwan gear with many slip elements.
    MicroSlip,
    /// A Bouc–Wen gear.
    BoucWen,
    /// A harmonic-drive catalogue gear: three-segment stiffness with Maxwell-slip elements.
    Catalogue,
    /// Slip elements that grip harder on one side: a Preisach gear that is not Masing.
    Preisach,
}

#[derive(Clone, Debug)]
enum MotionArg {
    Sine,
    Biased,
    Nested,
    Random,
    Hold,
    File(PathBuf),
    /// A plan file, or the default plan.
    Plan(Option<PathBuf>),
}

fn parse_motion(text: &str) -> Result<MotionArg, String> {
    Ok(match text {
        "sine" => MotionArg::Sine,
        "biased" => MotionArg::Biased,
        "nested" => MotionArg::Nested,
        "random" => MotionArg::Random,
        "hold" => MotionArg::Hold,
        "plan" => MotionArg::Plan(None),
        _ if text.to_ascii_lowercase().ends_with(".json") => MotionArg::Plan(Some(text.into())),
        _ if text.ends_with(".csv") || text.contains(std::path::MAIN_SEPARATOR) => MotionArg::File(text.into()),
        _ => {
            return Err(
                "expected sine, biased, nested, random, hold, plan, a CSV file (FILE.csv) or a plan file (PLAN.json)"
                    .into(),
            )
        }
    })
}

pub fn run(args: SimulateArgs) -> Result<()> {
    let motion_file = match &args.motion {
        MotionArg::File(path) | MotionArg::Plan(Some(path)) => Some(path.as_path()),
        _ => None,
    };
    let inputs = args.params.as_deref().into_iter().chain(args.physics_params.as_deref()).chain(motion_file);
    let mut outputs = Outputs::new(inputs);
    outputs.refuse_inputs([args.out.as_path()]).context("--out")?;
    let params = match &args.params {
        Some(path) => {
            if args.physics != PhysicsArg::Genetic {
                bail!(
                    "--params sets the model of --physics genetic; --physics {} takes --physics-params",
                    args.physics.name()
                );
            }
            read_model(path)?
        }
        None => parse_model("data/seed/lht-20-50-fit.json (bundled)".as_ref(), SEED_FIT)?,
    };
    if args.bias.is_some() && !matches!(args.motion, MotionArg::Biased | MotionArg::Hold) {
        bail!("--bias is for --motion biased or hold, not --motion {}", args.motion.name());
    }
    let motion = match &args.motion {
        MotionArg::Sine => Motion::Sine,
        MotionArg::Biased => Motion::Biased { bias_rad: args.bias },
        MotionArg::Nested => Motion::Nested,
        MotionArg::Random => Motion::Random,
        MotionArg::Hold => Motion::Hold { load_rad: args.bias },
        MotionArg::File(path) => Motion::File(read_trajectory(path).context("--motion")?),
        MotionArg::Plan(Some(path)) => Motion::Plan(read_plan(path).context("--motion")?),
        MotionArg::Plan(None) => {
            let amplitude = args.amplitude;
            let Some(&slow) = args.frequencies.first() else {
                bail!("--motion plan plays at the first --frequency: give one")
            };
            // The deflection's limit a quarter beyond the largest loop; the torque's is the
            // joint's (simulate prescribes the deflection).
            let limits = Limits { torque_nm: f32::MAX, deflection_rad: (1.25 * amplitude) as f32 };
            Motion::Plan(PlanSpec::default_plan(Channel::Deflection, amplitude, slow, limits))
        }
    };
    let physics = match (args.physics, &args.physics_params) {
        (PhysicsArg::Genetic, None) => Physics::Model,
        (PhysicsArg::Genetic, Some(_)) => {
            bail!(
                "--physics-params is for --physics micro-slip, bouc-wen, catalogue or preisach; the genetic model takes --params"
            )
        }
        (PhysicsArg::MicroSlip, path) => Physics::MicroSlip(match path {
            Some(path) => read_physics_params(path).context("--physics-params")?,
            None => MicroSlip::default(),
        }),
        (PhysicsArg::BoucWen, path) => Physics::BoucWen(match path {
            Some(path) => read_physics_params(path).context("--physics-params")?,
            None => BoucWen::default(),
        }),
        (PhysicsArg::Catalogue, path) => Physics::Catalogue(match path {
            Some(path) => read_physics_params(path).context("--physics-params")?,
            None => Catalogue::default(),
        }),
        (PhysicsArg::Preisach, path) => Physics::Preisach(match path {
            Some(path) => read_physics_params(path).context("--physics-params")?,
            None => Preisach::default(),
        }),
    };
    // The seed table's fit (h > 0) runs its loop the active way. On the sine it plays the loop it
    // was fitted to; under any other motion its memory term is no gear's (a new user's trial:
    // random motion reached 100 N·m near θ = 0 on a gear of 28 N·m at its tips), and the user
    // is told so rather than handed it as a gear.
    let active_memory = args.physics == PhysicsArg::Genetic
        && !matches!(args.motion, MotionArg::Sine)
        && params.identifiable(args.amplitude).is_some_and(|id| id.h > 0.0);
    let simulation = Simulation {
        params,
        amplitude_rad: args.amplitude,
        frequencies_hz: args.frequencies,
        cycles: args.cycles,
        sample_rate_hz: args.rate,
        ratio: args.ratio,
        input_speed_rad_s: args.input_speed,
        input_bits: args.input_bits,
        output_bits: args.output_bits,
        torque_noise_nm: args.torque_noise,
        temperature: args.temperature.map(|start| (start, args.temperature_rise)),
        effects: args.effects,
        seed: args.seed,
    };
    let experiment = Experiment { simulation, motion, physics, deflection_zero_rad: args.deflection_zero };
    let recording = simulate_experiment(&experiment)?;
    if let Some(column) = recording.first_non_finite() {
        bail!("the simulated recording is not finite: column {column} holds NaN or infinity");
    }
    let mut text = Vec::new();
    recording.write(&mut text)?;
    outputs.stage(&args.out, &text)?;
    let duration = recording.time.last().copied().unwrap_or(0.0);
    let mut report = format!("wrote {}: {} samples, {duration} s\n", args.out.display(), recording.time.len());
    if active_memory {
        let peak = recording.torque.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        report.push_str(&format!(
            "note: this genetic gear runs its loop the active way (h > 0, as the bundled seed table's fit does): \
             away from the sine its memory term is no physical gear's (the torque here peaks at {peak:.1} N·m); \
             for a gear to test on, use --physics micro-slip, bouc-wen, catalogue or preisach, or --params with \
             h < 0\n"
        ));
    }
    super::print_then_commit(&report, outputs)
}

impl PhysicsArg {
    fn name(self) -> &'static str {
        match self {
            PhysicsArg::Genetic => "genetic",
            PhysicsArg::MicroSlip => "micro-slip",
            PhysicsArg::BoucWen => "bouc-wen",
            PhysicsArg::Catalogue => "catalogue",
            PhysicsArg::Preisach => "preisach",
        }
    }
}

impl MotionArg {
    fn name(&self) -> &'static str {
        match self {
            MotionArg::Sine => "sine",
            MotionArg::Biased => "biased",
            MotionArg::Nested => "nested",
            MotionArg::Random => "random",
            MotionArg::Hold => "hold",
            MotionArg::File(_) => "FILE.csv",
            MotionArg::Plan(None) => "plan",
            MotionArg::Plan(Some(_)) => "PLAN.json",
        }
    }
}
