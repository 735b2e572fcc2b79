//! The identification experiment (`swg_protocol::experiment`): the link prepares a checked plan;
//! the tick plays it with the controller, records every tick's readings into a bounded queue,
//! checks the plan's limits and the link's watchdog every tick, and stops the experiment and
//! its motor on any of them; the link takes the recording out of the queue in batches when the
//! host fetches.
//!
//! Between the two priorities, as the rest of the [`handoff`](crate::handoff), without a lock:
//! - the experiment (its player and what it checks) in one slot that the link writes while it
//!   owns it and the tick plays while it owns it, handed over by one flag (so that the tick
//!   that starts an experiment copies nothing: the copies of a plan took 1,600 instructions of
//!   that tick, `bench/firmware.sh`);
//! - the recording through a sample queue (tick → link, heapless `spsc`);
//! - the state and the dropped samples as words only the tick writes; the fetches and the stop
//!   requests as words only the link writes, which the tick compares with what it saw last.
//!
//! The tick never waits: when the sample queue is full, the sample is dropped and counted.
use crate::compensator::Ticker;
use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use heapless::spsc::{Consumer, Producer, Queue};
use heapless::Vec;
use swg_protocol::experiment::{
    ExperimentState, RecordedSample, SampleBatch, StopReason, BATCH_SAMPLES, LINK_TIMEOUT_SECONDS,
};
use swg_protocol::plan::{Channel, Limits, Plan, Player};
use swg_protocol::{ControllerConfig, ErrorReply};

/// Recorded ticks the queue holds for the link: two batches, so that the tick can fill one while
/// the link sends the other.
pub const QUEUE_SAMPLES: usize = 2 * BATCH_SAMPLES;

/// A recorded tick with its number in the plan.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Stamped {
    tick: u32,
    sample: RecordedSample,
}

/// An experiment as the tick plays it.
struct Experiment {
    player: Player<f32>,
    channel: Channel,
    limits: Limits,
    /// The plan's rate, Hz: a board's own ticks must run at it (checked at the first tick).
    rate_hz: f32,
    /// The plan tick of the next sample.
    tick: u32,
    /// The link's counters when last seen (the stop requests: when the link prepared it).
    fetches: u32,
    stops: u32,
    /// Ticks since the last fetch, and how many stop the experiment.
    silent: u32,
    timeout: u32,
}

/// The experiment's slot: written by the link while the mailbox's `playing` is false, played by
/// the tick while it is true.
struct Slot(UnsafeCell<Option<Experiment>>);

// The slot is the link's while `playing` is false and the tick's while it is true; each side
// raises or lowers the flag only after its last access (Release) and reads it before its first
// (Acquire).
#[allow(unsafe_code)]
unsafe impl Sync for Slot {}

/// The experiment's part of the handoff.
pub(crate) struct Mailbox {
    slot: Slot,
    /// Raised by the link when it has prepared the slot, lowered by the tick when the
    /// experiment has ended.
    playing: AtomicBool,
    samples: Queue<Stamped, { QUEUE_SAMPLES + 1 }>,
    /// Written by the tick: the state ([`code`]), the samples dropped in this experiment and the
    /// most the queue has held (both set to 0 by the link before it hands an experiment over).
    state: AtomicU32,
    dropped: AtomicU32,
    high_water: AtomicU32,
    /// Written by the link: fetches and stop requests since boot.
    fetches: AtomicU32,
    stops: AtomicU32,
}

impl Mailbox {
    pub(crate) const fn new() -> Self {
        Mailbox {
            slot: Slot(UnsafeCell::new(None)),
            playing: AtomicBool::new(false),
            samples: Queue::new(),
            state: AtomicU32::new(0),
            dropped: AtomicU32::new(0),
            high_water: AtomicU32::new(0),
            fetches: AtomicU32::new(0),
            stops: AtomicU32::new(0),
        }
    }

    pub(crate) fn split(&mut self) -> (LinkSide<'_>, TickSide<'_>) {
        let (sample_in, sample_out) = self.samples.split();
        let (slot, playing) = (&self.slot, &self.playing);
        let (state, dropped, high_water) = (&self.state, &self.dropped, &self.high_water);
        let (fetches, stops) = (&self.fetches, &self.stops);
        (
            LinkSide { slot, playing, samples: sample_out, state, dropped, high_water, fetches, stops },
            TickSide { slot, playing, samples: sample_in, state, dropped, high_water, fetches, stops },
        )
    }
}

const REASONS: [StopReason; 7] = [
    StopReason::Host,
    StopReason::TorqueLimit,
    StopReason::DeflectionLimit,
    StopReason::LinkLost,
    StopReason::SensorFault,
    StopReason::DriveFault,
    StopReason::PlanRate,
];
const RUNNING: u32 = 0x100;

/// `state` as one word: 0 idle, 1 finished, 2 + the reason's index stopped, 0x100 + the
/// segment running.
fn code(state: ExperimentState) -> u32 {
    match state {
        ExperimentState::Idle => 0,
        ExperimentState::Finished => 1,
        ExperimentState::Stopped(reason) => 2 + REASONS.iter().position(|r| *r == reason).unwrap_or(0) as u32,
        ExperimentState::Running { segment } => RUNNING + u32::from(segment),
    }
}

fn state_of(code: u32) -> ExperimentState {
    match code {
        0 => ExperimentState::Idle,
        1 => ExperimentState::Finished,
        RUNNING.. => ExperimentState::Running { segment: (code - RUNNING) as u8 },
        code => ExperimentState::Stopped(REASONS.get(code as usize - 2).copied().unwrap_or(StopReason::Host)),
    }
}

/// Adds one to a word only this side writes.
fn bump(counter: &AtomicU32) {
    counter.store(counter.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
}

/// The link's side of the [`Mailbox`].
pub struct LinkSide<'a> {
    slot: &'a Slot,
    playing: &'a AtomicBool,
    samples: Consumer<'a, Stamped>,
    state: &'a AtomicU32,
    dropped: &'a AtomicU32,
    high_water: &'a AtomicU32,
    fetches: &'a AtomicU32,
    stops: &'a AtomicU32,
}

impl LinkSide<'_> {
    /// The experiment's state; `Running` from the moment the link hands it to the tick.
    pub fn state(&self) -> ExperimentState {
        let playing = self.playing.load(Ordering::Acquire);
        match state_of(self.state.load(Ordering::Acquire)) {
            // Handed over, not yet taken up by a tick: the state word is the last experiment's.
            state if playing && !state.is_running() => ExperimentState::Running { segment: 0 },
            state => state,
        }
    }

    /// Prepares the experiment of a checked `plan` for the next tick, after the last
    /// experiment's leftover samples are discarded; [`ErrorReply::ExperimentRunning`] while one
    /// runs.
    pub fn start(&mut self, plan: &Plan) -> Result<(), ErrorReply> {
        if self.playing.load(Ordering::Acquire) {
            return Err(ErrorReply::ExperimentRunning);
        }
        while self.samples.dequeue().is_some() {}
        // The timeout at the plan's rate, rounded down (so that the tick that notices is within
        // the timeout's bound), at least one tick.
        let timeout = ((LINK_TIMEOUT_SECONDS * plan.rate_hz()) as u32).max(1);
        let experiment = Experiment {
            player: plan.player(),
            channel: plan.channel(),
            limits: plan.limits(),
            rate_hz: plan.rate_hz(),
            tick: 0,
            fetches: self.fetches.load(Ordering::Relaxed),
            stops: self.stops.load(Ordering::Relaxed),
            silent: 0,
            timeout,
        };
        // The slot is the link's: `playing` is false, and only the link raises it.
        #[allow(unsafe_code)]
        unsafe {
            *self.slot.0.get() = Some(experiment);
        }
        // The tick writes them only while an experiment plays.
        self.dropped.store(0, Ordering::Relaxed);
        self.high_water.store(0, Ordering::Relaxed);
        self.playing.store(true, Ordering::Release);
        Ok(())
    }

    /// Asks the tick to stop the experiment.
    pub fn stop(&mut self) {
        bump(self.stops);
    }

    /// The next batch, `sequence`, of consecutive recorded ticks (up to [`BATCH_SAMPLES`]),
    /// from `next_tick` on when the queue is empty; feeds the tick's watchdog. The state is
    /// read before the queue, so that a batch in a state that is no longer running holds the
    /// last samples only when it comes back empty (see `swg_protocol::experiment`).
    #[inline(never)]
    pub fn fetch(&mut self, sequence: u32, next_tick: u32) -> SampleBatch {
        bump(self.fetches);
        let state = self.state();
        let (dropped, high_water) = (self.dropped.load(Ordering::Acquire), self.high_water.load(Ordering::Acquire));
        let first_tick = self.samples.peek().map_or(next_tick, |head| head.tick);
        let mut samples = Vec::new();
        while let Some(head) = self.samples.peek() {
            if head.tick != first_tick.wrapping_add(samples.len() as u32) || samples.push(head.sample).is_err() {
                break;
            }
            self.samples.dequeue();
        }
        SampleBatch { sequence, first_tick, dropped, high_water, state, samples }
    }
}

/// The tick's side of the [`Mailbox`].
pub struct TickSide<'a> {
    slot: &'a Slot,
    playing: &'a AtomicBool,
    samples: Producer<'a, Stamped>,
    state: &'a AtomicU32,
    dropped: &'a AtomicU32,
    high_water: &'a AtomicU32,
    fetches: &'a AtomicU32,
    stops: &'a AtomicU32,
}

/// What one tick reads, besides its timing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Readings {
    /// Input (motor) side, rad, multi-turn.
    pub input_angle: f32,
    /// Output side, rad.
    pub output_angle: f32,
    /// The torque sensor's reading, N·m; `None` on a board without one (an experiment there
    /// stops at its first tick, [`StopReason::SensorFault`]).
    pub torque: Option<f32>,
    /// The temperature, °C, when the board has a sensor.
    pub temperature: Option<f32>,
}

/// What the controller does this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Step {
    /// No experiment: the reference the link set.
    Idle,
    /// The plan's joint torque reference, N·m.
    Play(f32),
    /// The experiment ended at this tick: the motor command goes to zero.
    Halt,
}

impl TickSide<'_> {
    /// The experiment the link handed over, while it plays.
    fn experiment(&mut self) -> Option<&mut Experiment> {
        if !self.playing.load(Ordering::Acquire) {
            return None;
        }
        // The slot is the tick's: `playing` is raised, and only the tick lowers it.
        #[allow(unsafe_code)]
        let slot = unsafe { &mut *self.slot.0.get() };
        slot.as_mut()
    }

    /// Ends the experiment in `state`, handing the slot back to the link.
    fn end(&mut self, state: ExperimentState) -> Step {
        self.state.store(code(state), Ordering::Release);
        self.playing.store(false, Ordering::Release);
        Step::Halt
    }

    /// Stops the experiment, if one plays, for `reason` (a failed reading or a drive that
    /// refused the tick's command); whether one played.
    pub(crate) fn halt(&mut self, reason: StopReason) -> bool {
        let playing = self.experiment().is_some();
        if playing {
            self.end(ExperimentState::Stopped(reason));
        }
        playing
    }

    /// One tick of the experiment, if one plays: checks the host's stop and the watchdog,
    /// records `readings`, checks them against the plan's limits, and gives the plan's
    /// reference (a deflection plan's as T_ref = stiffness·θ_ref: in `Linear` mode the torque
    /// loop then holds θ at θ_ref). `own_rate_hz`: the board's own tick rate, checked at the
    /// first tick (`None` in lockstep).
    pub(crate) fn step(
        &mut self,
        ticker: &Ticker,
        readings: &Readings,
        config: Option<ControllerConfig>,
        own_rate_hz: Option<u32>,
    ) -> Step {
        let (stops, fetches) = (self.stops.load(Ordering::Relaxed), self.fetches.load(Ordering::Relaxed));
        let Some(experiment) = self.experiment() else { return Step::Idle };
        if experiment.tick == 0 && own_rate_hz.is_some_and(|own| (experiment.rate_hz - own as f32).abs() > 0.5) {
            return self.end(ExperimentState::Stopped(StopReason::PlanRate));
        }
        if stops != experiment.stops {
            return self.end(ExperimentState::Stopped(StopReason::Host));
        }
        if fetches != experiment.fetches {
            (experiment.fetches, experiment.silent) = (fetches, 0);
        } else {
            experiment.silent += 1;
            if experiment.silent > experiment.timeout {
                return self.end(ExperimentState::Stopped(StopReason::LinkLost));
            }
        }
        let Some(setpoint) = experiment.player.next() else {
            return self.end(ExperimentState::Finished);
        };
        let (channel, limits, tick) = (experiment.channel, experiment.limits, experiment.tick);
        experiment.tick = tick.wrapping_add(1);
        let Readings { input_angle, output_angle, torque, temperature } = *readings;
        let torque = torque.unwrap_or(f32::NAN);
        let sample = RecordedSample { input_angle, output_angle, torque, temperature };
        if self.samples.enqueue(Stamped { tick, sample }).is_err() {
            bump(self.dropped);
        }
        let held = self.samples.len() as u32;
        if held > self.high_water.load(Ordering::Relaxed) {
            self.high_water.store(held, Ordering::Relaxed);
        }
        let deflection = match ticker.active_gear_ratio() {
            Some(ratio) => input_angle / ratio - output_angle,
            None => f32::NAN,
        };
        let (Some(config), true) = (config, torque.is_finite() && deflection.is_finite()) else {
            return self.end(ExperimentState::Stopped(StopReason::SensorFault));
        };
        if torque.abs() > limits.torque_nm {
            return self.end(ExperimentState::Stopped(StopReason::TorqueLimit));
        }
        if deflection.abs() > limits.deflection_rad {
            return self.end(ExperimentState::Stopped(StopReason::DeflectionLimit));
        }
        self.state.store(code(ExperimentState::Running { segment: setpoint.segment as u8 }), Ordering::Release);
        Step::Play(match channel {
            Channel::Torque => setpoint.value,
            Channel::Deflection => config.stiffness * setpoint.value,
        })
    }
}
