//! `swg-host record`: the joint plays an identification plan and streams what it measured
//! (`swg_protocol::experiment`). The host starts the experiment, fetches the recorded ticks in
//! batches until the experiment has ended, checks that no batch and no tick is missing, and
//! turns them into a recording (format v1) that `fit` and `diagnose` read.
//!
//! A board ticks on its own sensors; the QEMU board ticks in lockstep, and then the host runs
//! the joint it controls ([`SimulatedJoint`]: `hil`'s plant with its output clamped, a torque
//! sensor with noise and an offset, a temperature that rises with the motor's losses) and sends
//! each tick's readings ([`swg_protocol::Request::Control`]).
use crate::hil::plant::{GearTruth, Plant, PlantParams};
use crate::hil::scenario::{Environment, EnvironmentKind};
use crate::hil::{controller_config, linear_stiffness, HilError, GAINS};
use crate::input::plan::PlanSpec;
use crate::input::{deflection, Angles, Recording, START_AT_REST, START_KEY};
use crate::link::{Link, LinkError};
use model_core::memory::Hysteretic;
use model_core::GearModel;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::time::{Duration, Instant};
use swg_protocol::experiment::{
    BatchGap, ExperimentState, RecordedSample, SampleBatch, StopReason, BATCH_SAMPLES, LINK_TIMEOUT_SECONDS,
};
use swg_protocol::plan::{Channel, Limits, Plan};
use swg_protocol::{endpoint, ControlMode, ControlSample, DeviceInfo, JointParams, PROTOCOL_VERSION};

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(
        "the device speaks protocol version {device}, this tool {}: update the firmware or swg-host",
        PROTOCOL_VERSION
    )]
    Protocol { device: u16 },
    #[error("the joint has no parameter set, so it knows neither its gear ratio nor its deflection: push one first (swg-host push, or record --params)")]
    NoParams,
    #[error("the simulated joint: {0}")]
    Joint(#[from] HilError),
    #[error("the simulated joint's {name} must be {expected}, found {value}")]
    SimulatedJoint { name: &'static str, expected: &'static str, value: f64 },
    #[error("the experiment stopped after {samples} of {ticks} ticks: {reason}; nothing was written")]
    Stopped { reason: StopReason, samples: usize, ticks: u32 },
    #[error("{} gap(s) in the recording, the first: {}; nothing was written (--allow-gaps writes it with the gaps listed)", .0.len(), .0[0])]
    Gaps(Vec<BatchGap>),
    #[error("the experiment did not end within {0:?} of its plan's length (is the board ticking?)")]
    Stalled(Duration),
    #[error("the joint's last batch said \"{0}\" where the experiment had ended")]
    Unfinished(ExperimentState),
    #[error("the default plan needs {0}")]
    PlanNeeds(&'static str),
    #[error("--amplitude must be a deflection > 0 rad, found {0}")]
    Amplitude(f64),
    #[error("--params: the model cannot be evaluated: {0}")]
    Params(model_core::Error),
}

/// The joint the QEMU board controls in lockstep.
#[derive(Clone, Debug, PartialEq)]
pub struct SimulatedJoint {
    pub plant: PlantParams,
    pub truth: GearTruth,
    /// The torque sensor: its reading is the true torque + `offset_nm` + Gaussian noise.
    pub torque_offset_nm: f64,
    pub torque_noise_nm: f64,
    /// The temperature starts at `ambient_c` and rises with the motor's copper losses,
    /// `loss_w_per_nm2`·u² W (u the motor command, N·m), through a thermal resistance
    /// `kelvin_per_w` with time constant `thermal_seconds`.
    pub ambient_c: f64,
    pub loss_w_per_nm2: f64,
    pub kelvin_per_w: f64,
    pub thermal_seconds: f64,
    pub seed: u64,
}

impl SimulatedJoint {
    /// `truth` on `hil`'s default plant, with a sensor of 0.05 N·m noise and a 0.3 N·m offset,
    /// and a motor that warms by about 1 K over a minute of the default plan.
    pub fn new(truth: GearTruth) -> SimulatedJoint {
        SimulatedJoint {
            plant: PlantParams::default(),
            truth,
            torque_offset_nm: 0.3,
            torque_noise_nm: 0.05,
            ambient_c: 25.0,
            loss_w_per_nm2: 4.0,
            kelvin_per_w: 2.0,
            thermal_seconds: 30.0,
            seed: 1,
        }
    }

    /// Each figure finite and within its range: checked by [`record`] before any traffic, and
    /// by a caller before it opens the link.
    pub fn validate(&self) -> Result<(), RecordError> {
        let checks = [
            ("torque sensor's noise", "finite and ≥ 0 N·m", self.torque_noise_nm, self.torque_noise_nm >= 0.0),
            ("torque sensor's offset", "a finite torque, N·m", self.torque_offset_nm, true),
            ("ambient temperature", "finite, °C", self.ambient_c, true),
            ("losses", "finite and ≥ 0 W/(N·m)²", self.loss_w_per_nm2, self.loss_w_per_nm2 >= 0.0),
            ("thermal resistance", "finite and ≥ 0 K/W", self.kelvin_per_w, self.kelvin_per_w >= 0.0),
            ("thermal time constant", "finite and > 0 s", self.thermal_seconds, self.thermal_seconds > 0.0),
        ];
        if let Some((name, expected, value, _)) = checks.into_iter().find(|(_, _, v, ok)| !(*ok && v.is_finite())) {
            return Err(RecordError::SimulatedJoint { name, expected, value });
        }
        Ok(())
    }

    /// The output clamped on the bench: a stiff, damped fixture (0.05 kg·m², 2·10⁵ N·m/rad).
    fn clamp() -> Environment {
        Environment { inertia: 0.05, damping: 0.0, kind: EnvironmentKind::Spring { stiffness: 2.0e5, damping: 50.0 } }
    }
}

/// What the user asked of the default plan; `None` is left to the set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanRequest {
    /// The largest deflection amplitude A, rad.
    pub amplitude: Option<f64>,
    /// The slow frequency f, Hz.
    pub frequency_hz: f64,
    pub torque_limit: Option<f64>,
    pub deflection_limit: Option<f64>,
}

/// The default plan in deflection at A (or 80 % of `model`'s identified range), within the
/// limits asked (or 1.5·A, and 1.5× the model's largest torque within ±1.5·A).
pub fn default_plan(asked: &PlanRequest, model: Option<&GearModel<f64>>) -> Result<PlanSpec, RecordError> {
    let amplitude = match (asked.amplitude, model) {
        (Some(amplitude), _) => amplitude,
        (None, Some(model)) if model.spring.range[1] < model_core::spring::UNBOUNDED_RANGE => {
            0.8 * model.spring.range[0].abs().min(model.spring.range[1])
        }
        (None, Some(_)) => {
            return Err(RecordError::PlanNeeds(
                "--amplitude: the --params set was not fitted on a recording, so it has no identified range",
            ))
        }
        (None, None) => {
            return Err(RecordError::PlanNeeds("--amplitude (or --params, whose identified range sets it)"))
        }
    };
    if !(amplitude.is_finite() && amplitude > 0.0) {
        return Err(RecordError::Amplitude(amplitude));
    }
    let deflection_limit = asked.deflection_limit.unwrap_or(1.5 * amplitude);
    let torque_limit = match (asked.torque_limit, model) {
        (Some(limit), _) => limit,
        (None, Some(model)) => 1.5 * peak_torque(model, 1.5 * amplitude)?,
        (None, None) => return Err(RecordError::PlanNeeds("--torque-limit (or --params, whose model sets it)")),
    };
    let limits = Limits { torque_nm: torque_limit as f32, deflection_rad: deflection_limit as f32 };
    Ok(PlanSpec::default_plan(Channel::Deflection, amplitude, asked.frequency_hz, limits))
}

/// The model's largest |torque| on the way from rest to ±`reach`, N·m.
fn peak_torque(model: &GearModel<f64>, reach: f64) -> Result<f64, RecordError> {
    let mut peak = 0.0f64;
    for side in [1.0, -1.0] {
        let mut evaluator = model.evaluator(0.0).map_err(RecordError::Params)?;
        for k in 0..=100 {
            let at = evaluator.step(side * reach * f64::from(k) / 100.0).map_err(RecordError::Params)?;
            peak = peak.max(at.torque.abs());
        }
    }
    Ok(peak)
}

/// What to record.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordOptions {
    /// The plan, checked at its rate.
    pub plan: Plan,
    /// The plan in words and where it came from, for the recording's metadata.
    pub plan_text: String,
    pub plan_source: String,
    /// A set to write to the joint first (not stored), else the one it has.
    pub params: Option<JointParams>,
    /// `None`: a board on its own sensors.
    pub simulated: Option<SimulatedJoint>,
    pub allow_gaps: bool,
}

/// Where the recording stands, for a progress bar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// Ticks recorded so far, and the plan's.
    pub recorded: u64,
    pub ticks: u32,
    /// The segment playing (from 0).
    pub segment: u8,
}

/// A finished recording and how it went.
#[derive(Clone, Debug, PartialEq)]
pub struct Recorded {
    pub recording: Recording,
    pub device: DeviceInfo,
    /// Batches fetched, and those that came back empty.
    pub batches: u32,
    pub empty_batches: u32,
    /// Ticks the joint dropped (its queue full), and the gaps they and lost batches left.
    pub dropped: u32,
    /// The most ticks the joint's queue held at once.
    pub high_water: u32,
    pub gaps: Vec<BatchGap>,
    /// Wall time from the start to the last batch.
    pub wall: Duration,
}

impl Recorded {
    /// Recorded samples a second of wall time.
    pub fn samples_per_second(&self) -> f64 {
        self.recording.time.len() as f64 / self.wall.as_secs_f64().max(1e-9)
    }
}

/// Runs `options.plan` on the joint at `link` and collects its recording. Leaves the
/// controller off.
pub fn record(
    link: &mut Link,
    options: &RecordOptions,
    progress: &mut dyn FnMut(Progress),
) -> Result<Recorded, RecordError> {
    if let Some(simulated) = &options.simulated {
        simulated.validate()?;
    }
    let device = link.call::<endpoint::GetDeviceInfo>(&())?;
    if device.protocol_version != PROTOCOL_VERSION {
        return Err(RecordError::Protocol { device: device.protocol_version });
    }
    if let Some(params) = &options.params {
        link.call::<endpoint::WriteParams>(params)?;
    }
    let params = link.call::<endpoint::ReadParams>(&())?.ok_or(RecordError::NoParams)?;
    let result = run(link, options, &params, device, progress);
    // The experiment ends with the controller off; a failure may have left it driving.
    let off = link.call::<endpoint::Configure>(&off_config());
    let recorded = result?;
    off?;
    Ok(recorded)
}

fn off_config() -> swg_protocol::ControllerConfig {
    controller_config(ControlMode::Off, &GAINS, 1.0, 0.0, 1.0e-3)
}

fn run(
    link: &mut Link,
    options: &RecordOptions,
    params: &JointParams,
    device: DeviceInfo,
    progress: &mut dyn FnMut(Progress),
) -> Result<Recorded, RecordError> {
    let plan = &options.plan;
    let rate = f64::from(plan.rate_hz());
    let model = params.model.map(|_, value| f64::from(value));
    // The linear mode: a deflection plan's reference is stiffness·θ_ref, which it holds θ at.
    let stiffness = linear_stiffness(&model)?;
    let ratio = f64::from(params.gear_ratio);
    let mut joint = match &options.simulated {
        Some(simulated) => Some(Lockstep::new(simulated, ratio, rate)?),
        None => None,
    };
    let deadband = joint.as_ref().map_or(0.0, |j| stiffness * j.plant_params.deflection_count());
    link.call::<endpoint::Configure>(&controller_config(ControlMode::Linear, &GAINS, stiffness, deadband, 1.0 / rate))?;
    let ticks = link.call::<endpoint::StartExperiment>(plan)?;
    let start = Instant::now();
    let mut collector = Collector::new();
    let mut ticked = 0u64;
    // In lockstep, a fetch after every batch of ticks, and often enough for the joint's
    // watchdog at low rates (it allows LINK_TIMEOUT_SECONDS of ticks without one).
    let per_fetch = ((f64::from(LINK_TIMEOUT_SECONDS) * rate) as usize).clamp(1, BATCH_SAMPLES);
    loop {
        if let Some(joint) = &mut joint {
            // A batch of ticks (and the one that ends the experiment), then a fetch.
            for _ in 0..per_fetch {
                if ticked > u64::from(ticks) || !collector.running() {
                    break;
                }
                joint.tick(link, 1.0 / rate)?;
                ticked += 1;
            }
        }
        let batch = link.call::<endpoint::FetchSamples>(&())?;
        let done = !batch.state.is_running() && batch.samples.is_empty();
        // In lockstep every tick has been sent: a joint still running has lost count.
        let lost_count = joint.is_some() && ticked > u64::from(ticks) && batch.samples.is_empty();
        if lost_count && batch.state.is_running() {
            return Err(RecordError::Unfinished(batch.state));
        }
        collector.take(batch);
        progress(Progress { recorded: collector.samples.len() as u64, ticks, segment: collector.segment() });
        if done {
            break;
        }
        let allowed = Duration::from_secs_f64(f64::from(ticks) / rate * 2.0 + 10.0);
        if joint.is_none() && start.elapsed() > allowed {
            return Err(RecordError::Stalled(allowed));
        }
    }
    let wall = start.elapsed();
    collector.finish(ticks, options.allow_gaps)?;
    let recording = collector.recording(ratio, rate, &device, options);
    Ok(Recorded {
        recording,
        device,
        batches: collector.batches,
        empty_batches: collector.empty_batches,
        dropped: collector.dropped,
        high_water: collector.high_water,
        gaps: collector.gaps,
        wall,
    })
}

/// The batches as they come: checked against the one before, their samples kept with their ticks.
struct Collector {
    last: Option<SampleBatch>,
    samples: Vec<(u32, RecordedSample)>,
    gaps: Vec<BatchGap>,
    state: ExperimentState,
    dropped: u32,
    high_water: u32,
    batches: u32,
    empty_batches: u32,
}

impl Collector {
    fn new() -> Collector {
        Collector {
            last: None,
            samples: Vec::new(),
            gaps: Vec::new(),
            state: ExperimentState::Running { segment: 0 },
            dropped: 0,
            high_water: 0,
            batches: 0,
            empty_batches: 0,
        }
    }

    fn running(&self) -> bool {
        self.state.is_running()
    }

    fn segment(&self) -> u8 {
        match self.state {
            ExperimentState::Running { segment } => segment,
            _ => 0,
        }
    }

    fn next_tick(&self) -> u32 {
        self.last.as_ref().map_or(0, SampleBatch::end_tick)
    }

    /// Ticks missing in the gaps found so far.
    fn gap_ticks(&self) -> u32 {
        self.gaps
            .iter()
            .map(|gap| if let BatchGap::Ticks { from, to } = gap { to.saturating_sub(*from) } else { 0 })
            .sum()
    }

    /// The experiment's end as the last batch tells it: finished, with no gap unless
    /// `allow_gaps` (ticks dropped after the last sample count as a gap at the end).
    fn finish(&mut self, ticks: u32, allow_gaps: bool) -> Result<(), RecordError> {
        match self.state {
            ExperimentState::Finished => {}
            ExperimentState::Stopped(reason) => {
                return Err(RecordError::Stopped { reason, samples: self.samples.len(), ticks });
            }
            ExperimentState::Idle | ExperimentState::Running { .. } => return Err(RecordError::Unfinished(self.state)),
        }
        let missing = self.gap_ticks();
        if self.dropped > missing {
            let end = self.next_tick();
            self.gaps.push(BatchGap::Ticks { from: end, to: end + (self.dropped - missing) });
        }
        match self.gaps.first() {
            Some(_) if !allow_gaps => Err(RecordError::Gaps(self.gaps.clone())),
            _ => Ok(()),
        }
    }

    fn take(&mut self, batch: SampleBatch) {
        if let Err(gap) = batch.follows(self.last.as_ref()) {
            self.gaps.push(gap);
        }
        self.batches += 1;
        self.empty_batches += u32::from(batch.samples.is_empty());
        self.state = batch.state;
        self.dropped = batch.dropped;
        self.high_water = batch.high_water;
        let first = batch.first_tick;
        self.samples.extend(batch.samples.iter().enumerate().map(|(i, s)| (first + i as u32, *s)));
        self.last = Some(batch);
    }

    fn recording(&self, ratio: f64, rate: f64, device: &DeviceInfo, options: &RecordOptions) -> Recording {
        let n = self.samples.len();
        let mut angles = Angles { input: Vec::with_capacity(n), output: Vec::with_capacity(n) };
        let (mut time, mut torque, mut deflections) =
            (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
        let mut temperature = Some(Vec::with_capacity(n));
        for &(tick, sample) in &self.samples {
            let (input, output) = (f64::from(sample.input_angle), f64::from(sample.output_angle));
            time.push(f64::from(tick) / rate);
            angles.input.push(input);
            angles.output.push(output);
            deflections.push(deflection(input, output, ratio));
            torque.push(f64::from(sample.torque));
            temperature = match (temperature, sample.temperature) {
                (Some(mut values), Some(value)) => {
                    values.push(f64::from(value));
                    Some(values)
                }
                _ => None,
            };
        }
        let board = match options.simulated {
            Some(_) => "QEMU mps2-an386, in lockstep with swg-host's simulated joint",
            None => "a joint board on its own sensors",
        };
        let mut metadata = vec![
            (START_KEY.to_owned(), START_AT_REST.to_owned()),
            ("board".to_owned(), board.to_owned()),
            (
                "firmware".to_owned(),
                format!(
                    "{}, protocol {}, model {}",
                    device.firmware_version, device.protocol_version, device.model_version
                ),
            ),
            ("motion".to_owned(), format!("record: {}", options.plan_source)),
            ("plan".to_owned(), options.plan_text.clone()),
            ("rate_hz".to_owned(), rate.to_string()),
        ];
        if !self.gaps.is_empty() {
            let gaps: Vec<String> = self.gaps.iter().map(ToString::to_string).collect();
            metadata.push(("gaps".to_owned(), gaps.join("; ")));
        }
        Recording { ratio, metadata, time, angles: Some(angles), deflection: deflections, torque, temperature }
    }
}

/// The simulated joint with its sensors and its temperature.
struct Lockstep {
    plant: Plant,
    plant_params: PlantParams,
    noise: Normal<f64>,
    rng: rand_chacha::ChaCha8Rng,
    joint: SimulatedJoint,
    temperature: f64,
}

impl Lockstep {
    /// At the control rate `rate` Hz: the plant integrated in steps of 0.1 ms at most (the
    /// clamp's mode is at 320 Hz).
    fn new(joint: &SimulatedJoint, ratio: f64, rate: f64) -> Result<Lockstep, RecordError> {
        let substeps = joint.plant.substeps.max((1.0e4 / rate).ceil() as usize);
        let plant_params = PlantParams { ratio, substeps, ..joint.plant };
        joint.validate()?;
        let noise = Normal::new(0.0, joint.torque_noise_nm).map_err(|_| RecordError::SimulatedJoint {
            name: "torque sensor's noise",
            expected: "finite and ≥ 0 N·m",
            value: joint.torque_noise_nm,
        })?;
        Ok(Lockstep {
            plant: Plant::new(plant_params, &joint.truth, SimulatedJoint::clamp())?,
            plant_params,
            noise,
            rng: rand_chacha::ChaCha8Rng::seed_from_u64(joint.seed),
            joint: joint.clone(),
            temperature: joint.ambient_c,
        })
    }

    /// One control tick: the readings to the joint, its command held for `period`.
    fn tick(&mut self, link: &mut Link, period: f64) -> Result<(), RecordError> {
        let (input_angle, output_angle) = self.plant.encoders();
        let torque = self.plant.state().torque + self.joint.torque_offset_nm + self.noise.sample(&mut self.rng);
        let sample = ControlSample {
            input_angle: input_angle as f32,
            output_angle: output_angle as f32,
            reference: 0.0,
            torque: torque as f32,
            temperature: Some(self.temperature as f32),
        };
        let command = f64::from(link.call::<endpoint::Control>(&sample)?.command);
        self.plant.advance(command, period)?;
        let joint = &self.joint;
        let target = joint.ambient_c + joint.kelvin_per_w * joint.loss_w_per_nm2 * command * command;
        self.temperature += (target - self.temperature) * (period / joint.thermal_seconds).min(1.0);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hil::plant::GearTruth;
    use crate::link::fake::FakeDevice;
    use crate::link::push::{joint_params, JointSettings};
    use crate::simulate::{MicroSlip, Physics};
    use model_core::GearModel;
    use swg_protocol::plan::{Channel, Limits, Segment};

    fn batch(sequence: u32, first_tick: u32, len: usize, dropped: u32, state: ExperimentState) -> SampleBatch {
        let sample = RecordedSample { input_angle: 0.0, output_angle: 0.0, torque: 0.0, temperature: None };
        let samples = std::iter::repeat_n(sample, len).collect();
        SampleBatch { sequence, first_tick, dropped, high_water: 0, state, samples }
    }

    const RUNNING: ExperimentState = ExperimentState::Running { segment: 0 };

    #[test]
    fn a_lost_batch_or_a_dropped_tick_is_a_gap_and_fails_the_recording() {
        // In turn, then finished: no gap.
        let mut collector = Collector::new();
        for b in
            [batch(0, 0, 16, 0, RUNNING), batch(1, 16, 4, 0, RUNNING), batch(2, 20, 0, 0, ExperimentState::Finished)]
        {
            collector.take(b);
        }
        assert!(collector.finish(20, false).is_ok());
        assert_eq!(collector.samples.len(), 20);
        // A batch lost on the way.
        let mut collector = Collector::new();
        collector.take(batch(0, 0, 16, 0, RUNNING));
        collector.take(batch(2, 32, 0, 0, ExperimentState::Finished));
        let Err(RecordError::Gaps(gaps)) = collector.finish(32, false) else { panic!("a lost batch passed") };
        assert_eq!(gaps[0], BatchGap::Sequence { expected: 1, got: 2 });
        // Ticks the joint dropped, between batches and after the last one: each a gap, counted.
        let mut collector = Collector::new();
        collector.take(batch(0, 0, 16, 3, RUNNING));
        collector.take(batch(1, 19, 0, 5, ExperimentState::Finished));
        let Err(RecordError::Gaps(gaps)) = collector.finish(40, false) else { panic!("dropped ticks passed") };
        assert_eq!(gaps, [BatchGap::Ticks { from: 16, to: 19 }, BatchGap::Ticks { from: 19, to: 21 }]);
        // --allow-gaps keeps them, for the metadata.
        assert!(collector.finish(40, true).is_ok());
        // A stop is an error with its reason.
        let mut collector = Collector::new();
        collector.take(batch(0, 0, 5, 0, ExperimentState::Stopped(StopReason::LinkLost)));
        let Err(RecordError::Stopped { reason, samples, .. }) = collector.finish(100, false) else { panic!() };
        assert_eq!((reason, samples), (StopReason::LinkLost, 5));
    }

    #[test]
    fn the_default_plan_takes_what_is_asked_and_says_what_it_lacks() {
        let asked = PlanRequest { amplitude: None, frequency_hz: 0.5, torque_limit: None, deflection_limit: None };
        assert!(matches!(default_plan(&asked, None), Err(RecordError::PlanNeeds(m)) if m.starts_with("--amplitude")));
        let negative = PlanRequest { amplitude: Some(-1.0e-3), ..asked };
        assert!(matches!(default_plan(&negative, None), Err(RecordError::Amplitude(a)) if a == -1.0e-3));
        let no_torque = PlanRequest { amplitude: Some(1.0e-3), ..asked };
        assert!(matches!(default_plan(&no_torque, None), Err(RecordError::PlanNeeds(m)) if m.starts_with("--torque")));
        let spec = default_plan(&PlanRequest { torque_limit: Some(30.0), ..no_torque }, None).unwrap();
        assert_eq!((spec.limits.torque_nm, spec.limits.deflection_rad), (30.0, 1.5e-3));
        // From the seed set: 1.5× its largest torque within ±1.5 mrad.
        let seed = GearModel::paper(model_core::checks::SEED_TABLE_FIT);
        let spec = default_plan(&no_torque, Some(&seed)).unwrap();
        let peak = peak_torque(&seed, 1.5e-3).unwrap();
        assert!(peak > 10.0 && (f64::from(spec.limits.torque_nm) - 1.5 * peak).abs() < 1e-3 * peak);
    }

    #[test]
    fn the_in_process_joint_records_every_tick_of_its_plan() {
        let seed = GearModel::paper(model_core::checks::SEED_TABLE_FIT);
        let settings = JointSettings { gear_ratio: 50.0, torque_limit: 60.0, direction_band: 2.0e-6 };
        let segments = [
            Segment::Hold { seconds: 0.1, dither_amplitude: 0.0, dither_hz: 0.0 },
            Segment::Sine { amplitude: 5.0e-4, frequency_hz: 5.0, cycles: 3 },
        ];
        let limits = Limits { torque_nm: 40.0, deflection_rad: 1.0e-3 };
        let plan = Plan::new(Channel::Deflection, limits, 1000.0, &segments).unwrap();
        let truth = GearTruth::Physics { physics: Physics::MicroSlip(MicroSlip::default()), model: seed };
        let options = RecordOptions {
            plan,
            plan_text: "a test plan".into(),
            plan_source: "the test".into(),
            params: Some(joint_params(&seed, &settings).unwrap()),
            simulated: Some(SimulatedJoint::new(truth)),
            allow_gaps: false,
        };
        let mut seen = Vec::new();
        let recorded = record(&mut FakeDevice::new().link(), &options, &mut |p| seen.push(p.recorded)).unwrap();
        let recording = &recorded.recording;
        assert_eq!(recording.time.len() as u32, plan.ticks());
        assert!(recorded.gaps.is_empty() && recorded.dropped == 0);
        assert!(recorded.high_water <= BATCH_SAMPLES as u32);
        assert!(recording.starts_at_rest());
        assert!(seen.windows(2).all(|w| w[0] <= w[1]) && seen.last() == Some(&u64::from(plan.ticks())));
        // At rest the sensor reads its offset; the sine reaches most of its amplitude.
        let rest: f64 = recording.torque[..100].iter().sum::<f64>() / 100.0;
        assert!((rest - 0.3).abs() < 0.02, "{rest}");
        let reached = recording.deflection.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        assert!(reached > 4.5e-4 && reached < 5.5e-4, "{reached}");
        assert_eq!(recording.time[1] - recording.time[0], 1.0e-3);
        // At 250 Hz the joint's watchdog allows 10 silent ticks: the lockstep fetches in time.
        let slow_segments = [
            Segment::Hold { seconds: 0.5, dither_amplitude: 0.0, dither_hz: 0.0 },
            Segment::Sine { amplitude: 1.0e-4, frequency_hz: 2.0, cycles: 3 },
        ];
        let slow = Plan::new(Channel::Deflection, limits, 250.0, &slow_segments).unwrap();
        let options = RecordOptions { plan: slow, ..options };
        let recorded = record(&mut FakeDevice::new().link(), &options, &mut |_| {}).unwrap();
        assert_eq!(recorded.recording.time.len() as u32, slow.ticks());
    }
}
