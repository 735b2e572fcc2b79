//! What passes between a board's two priorities, without a lock: the link ([`crate::Server`]:
//! frames, requests, replies, flash commits; the lowest priority) and the control tick
//! ([`crate::Joint`]: compensator and controller; a timer interrupt above everything else).
//!
//! - Link → tick: a parameter set, prepared by the link in the [`Compensator`]'s slot the tick
//!   does not use and switched to by the next tick (the compensator's two halves; the set is
//!   never copied); and one [`Command`] at a time through a single-producer single-consumer
//!   queue (heapless `spsc`, two atomic indices): a controller configuration, a reference, or
//!   a lockstep sample. The tick takes it at its start.
//! - Tick → link: the answer to a lockstep sample through a second such queue (the link waits
//!   for it before it reads the next request), and the timing counters ([`TickStatus`]) as
//!   atomic words that only the tick writes.
//!
//! No critical section: the queues' indices, the compensator's flag and the counters are single
//! words, each written by one side only (the flag raised by the link, lowered by the tick). The
//! link never waits on the tick with interrupts masked; the tick never waits at all (its answer
//! queue cannot be full: the link hands over one sample at a time).
use crate::compensator::{Compensator, Stager, Ticker};
use crate::experiment::{LinkSide, Mailbox, TickSide};
use core::sync::atomic::{AtomicU32, AtomicU8, Ordering};
use heapless::spsc::{Consumer, Producer, Queue};
use swg_protocol::{
    ControlOutput, ControlSample, ControllerConfig, DriveErrorKind, EncoderSample, ErrorReply, Feedforward,
    JointParams, SensorErrorKind, TickStatus,
};

/// What the link hands the tick besides parameter sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// A validated controller configuration.
    Configure(ControllerConfig),
    /// A finite joint torque reference, N·m.
    SetReference(f32),
    /// A lockstep sample: the tick runs it and answers.
    Sample(Sample),
}

/// A sample the link hands the tick in lockstep (the board's own encoders not read).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sample {
    /// The compensator alone ([`swg_protocol::Request::Replay`]).
    Replay(EncoderSample),
    /// The controller with its compensator, the command to the drive
    /// ([`swg_protocol::Request::Control`]).
    Control(ControlSample),
}

/// The tick's answer to a lockstep [`Sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Answer {
    /// The compensator's output ([`Sample::Replay`]).
    Replay(Feedforward),
    /// The controller's ([`Sample::Control`]).
    Control(ControlOutput),
    /// Why the tick did not run the sample, or the drive refused its command.
    Refused(ErrorReply),
}

/// The board's tick timer, as the link reports it and the tick measures with it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickTiming {
    /// The clock the board measures ticks with (its timer's and a free-running counter's), Hz.
    pub clock_hz: u32,
    /// Clock counts per tick period; 0 for ticks that are not timed.
    pub period: u32,
    /// A tick that starts more than this many counts after its timer expired is late.
    pub late_bound: u32,
}

impl TickTiming {
    /// An in-process device's: it runs a tick whenever the link waits for one.
    pub const UNTIMED: TickTiming = TickTiming { clock_hz: 0, period: 0, late_bound: 0 };

    /// Ticks at `rate_hz` measured on a `clock_hz` clock, late beyond `late_bound_ns`.
    pub const fn new(clock_hz: u32, rate_hz: u32, late_bound_ns: u32) -> TickTiming {
        let late_bound = (late_bound_ns as u64 * clock_hz as u64 / 1_000_000_000) as u32;
        TickTiming { clock_hz, period: clock_hz / rate_hz, late_bound }
    }

    /// Counts since the timer's last expiry, from its current value: a down-counter that
    /// reaches 0 at the expiry (when it requests the interrupt) and reloads `period − 1` on its
    /// next count, as SysTick does.
    pub fn since_expiry(&self, current: u32) -> u32 {
        self.period.checked_sub(current).and_then(|counts| counts.checked_rem(self.period)).unwrap_or(0)
    }

    /// In single precision (the FPU's), which is ample for a report and spares the link a
    /// 64-bit division routine.
    fn nanoseconds(&self, counts: u32) -> u32 {
        match self.clock_hz {
            0 => 0,
            clock => (counts as f32 * (1.0e9 / clock as f32) + 0.5) as u32,
        }
    }
}

/// The tick's counters: each written by the tick only (a load and a store, no read-modify-write
/// that the link could interleave), read by the link.
#[derive(Debug)]
struct Counters {
    ticks: AtomicU32,
    overruns: AtomicU32,
    late: AtomicU32,
    missed: AtomicU32,
    worst_latency: AtomicU32,
    worst_tick: AtomicU32,
    sensor_faults: AtomicU32,
    drive_faults: AtomicU32,
    /// 0, or 1 + the index of the kind in [`SENSOR_KINDS`] / [`DRIVE_KINDS`].
    last_sensor_fault: AtomicU8,
    last_drive_fault: AtomicU8,
}

const SENSOR_KINDS: [SensorErrorKind; 4] =
    [SensorErrorKind::Bus, SensorErrorKind::Corrupt, SensorErrorKind::Sensor, SensorErrorKind::Other];
const DRIVE_KINDS: [DriveErrorKind; 3] = [DriveErrorKind::OutOfRange, DriveErrorKind::Fault, DriveErrorKind::Other];

/// `kind` stored as 1 + its index in `kinds` (the last entry, `Other`, for a kind added later).
fn kind_code<T: PartialEq>(kinds: &[T], kind: &T) -> u8 {
    let index = kinds.iter().position(|k| k == kind).unwrap_or(kinds.len().saturating_sub(1));
    u8::try_from(index + 1).unwrap_or(u8::MAX)
}

fn kind_of<T: Copy>(kinds: &[T], code: u8) -> Option<T> {
    usize::from(code).checked_sub(1).and_then(|index| kinds.get(index)).copied()
}

/// Adds one to a counter only the tick writes.
fn bump(counter: &AtomicU32, by: u32) {
    counter.store(counter.load(Ordering::Relaxed).wrapping_add(by), Ordering::Relaxed);
}

impl Counters {
    const fn new() -> Self {
        Counters {
            ticks: AtomicU32::new(0),
            overruns: AtomicU32::new(0),
            late: AtomicU32::new(0),
            missed: AtomicU32::new(0),
            worst_latency: AtomicU32::new(0),
            worst_tick: AtomicU32::new(0),
            sensor_faults: AtomicU32::new(0),
            drive_faults: AtomicU32::new(0),
            last_sensor_fault: AtomicU8::new(0),
            last_drive_fault: AtomicU8::new(0),
        }
    }
}

/// The compensator, queues and counters between the link and the tick; split once into the two
/// sides' ports ([`Handoff::split`]). A board keeps it in a static (`cortex_m::singleton!`).
pub struct Handoff {
    compensator: Compensator,
    commands: Queue<Command, 2>,
    answers: Queue<Answer, 2>,
    counters: Counters,
    timing: TickTiming,
    experiment: Mailbox,
}

impl Handoff {
    pub fn new(timing: TickTiming) -> Self {
        Handoff {
            compensator: Compensator::new(),
            commands: Queue::new(),
            answers: Queue::new(),
            counters: Counters::new(),
            timing,
            experiment: Mailbox::new(),
        }
    }

    /// The link's port and the tick's.
    pub fn split(&mut self) -> (LinkPort<'_>, TickPort<'_>) {
        let (stager, ticker) = self.compensator.split();
        let (command_in, command_out) = self.commands.split();
        let (answer_in, answer_out) = self.answers.split();
        let (counters, timing) = (&self.counters, &self.timing);
        let (link_experiment, tick_experiment) = self.experiment.split();
        (
            LinkPort {
                stager,
                commands: command_in,
                answers: answer_out,
                counters,
                timing,
                experiment: link_experiment,
            },
            TickPort {
                ticker,
                commands: command_out,
                answers: answer_in,
                counters,
                timing,
                experiment: tick_experiment,
            },
        )
    }
}

/// The link's side of the [`Handoff`].
pub struct LinkPort<'a> {
    stager: Stager<'a>,
    commands: Producer<'a, Command>,
    answers: Consumer<'a, Answer>,
    counters: &'a Counters,
    timing: &'a TickTiming,
    experiment: LinkSide<'a>,
}

impl<'a> LinkPort<'a> {
    /// Whether the tick has taken the last command and the last parameter set.
    pub fn has_room(&self) -> bool {
        self.commands.ready() && self.stager.has_room()
    }

    /// Validates `params` and prepares them for the next tick (the compensator's
    /// [`Stager::stage`]); [`ErrorReply::Busy`] if the tick has not taken the last set.
    pub fn stage(&mut self, params: &JointParams) -> Result<(), ErrorReply> {
        self.stager.stage(params)
    }

    /// Hands `command` to the next tick; [`ErrorReply::Busy`] if the tick has not taken the
    /// last one.
    pub fn post(&mut self, command: Command) -> Result<(), ErrorReply> {
        self.commands.enqueue(command).map_err(|_| ErrorReply::Busy)
    }

    /// The experiment's side of the link.
    pub fn experiment(&mut self) -> &mut LinkSide<'a> {
        &mut self.experiment
    }

    /// The tick's answer to a lockstep sample, once it ran.
    pub(crate) fn answer(&mut self) -> Option<Answer> {
        self.answers.dequeue()
    }

    /// The tick's counters now.
    pub fn status(&self) -> TickStatus {
        let c = self.counters;
        let load = |counter: &AtomicU32| counter.load(Ordering::Relaxed);
        let (beyond_range, max_excess_rad) = self.stager.beyond_range();
        TickStatus {
            rate_hz: self.timing.clock_hz.checked_div(self.timing.period).unwrap_or(0),
            ticks: load(&c.ticks),
            overruns: load(&c.overruns),
            late: load(&c.late),
            missed: load(&c.missed),
            late_bound_ns: self.timing.nanoseconds(self.timing.late_bound),
            worst_latency_ns: self.timing.nanoseconds(load(&c.worst_latency)),
            worst_tick_ns: self.timing.nanoseconds(load(&c.worst_tick)),
            sensor_faults: load(&c.sensor_faults),
            last_sensor_fault: kind_of(&SENSOR_KINDS, c.last_sensor_fault.load(Ordering::Relaxed)),
            drive_faults: load(&c.drive_faults),
            last_drive_fault: kind_of(&DRIVE_KINDS, c.last_drive_fault.load(Ordering::Relaxed)),
            beyond_range,
            max_excess_rad,
        }
    }
}

/// The tick's side of the [`Handoff`].
pub struct TickPort<'a> {
    ticker: Ticker<'a>,
    commands: Consumer<'a, Command>,
    answers: Producer<'a, Answer>,
    counters: &'a Counters,
    timing: &'a TickTiming,
    experiment: TickSide<'a>,
}

impl<'a> TickPort<'a> {
    /// The end of a tick, as the board's timer tells it: `elapsed` counts since the timer
    /// expired (measured as the start's latency), and whether the timer expired again
    /// meanwhile — the next tick already due, an overrun (the elapsed time then counts as a
    /// whole period: the timer's value has started over).
    pub fn finish(&mut self, elapsed: u32, overran: bool) {
        let c = self.counters;
        let elapsed = if overran { self.timing.period } else { elapsed };
        if overran {
            bump(&c.overruns, 1);
        }
        if elapsed > c.worst_tick.load(Ordering::Relaxed) {
            c.worst_tick.store(elapsed, Ordering::Relaxed);
        }
    }

    pub(crate) fn timing(&self) -> TickTiming {
        *self.timing
    }

    pub(crate) fn command(&mut self) -> Option<Command> {
        self.commands.dequeue()
    }

    /// The compensator's tick half.
    pub(crate) fn compensator(&mut self) -> &mut Ticker<'a> {
        &mut self.ticker
    }

    /// The experiment's side of the tick, and the compensator's (for the gear ratio).
    pub(crate) fn experiment(&mut self) -> (&mut TickSide<'a>, &Ticker<'a>) {
        (&mut self.experiment, &self.ticker)
    }

    /// Answers a lockstep sample. The queue always has room: the link hands over one sample
    /// and reads no request until its answer is taken.
    pub(crate) fn answer(&mut self, answer: Answer) {
        let _ = self.answers.enqueue(answer);
    }

    pub(crate) fn count_tick(&mut self, latency: Option<u32>, missed: u32) {
        let c = self.counters;
        bump(&c.ticks, 1);
        bump(&c.missed, missed);
        if let Some(latency) = latency {
            if latency > c.worst_latency.load(Ordering::Relaxed) {
                c.worst_latency.store(latency, Ordering::Relaxed);
            }
            if latency > self.timing.late_bound {
                bump(&c.late, 1);
            }
        }
    }

    pub(crate) fn sensor_fault(&mut self, kind: SensorErrorKind) {
        bump(&self.counters.sensor_faults, 1);
        self.counters.last_sensor_fault.store(kind_code(&SENSOR_KINDS, &kind), Ordering::Relaxed);
    }

    pub(crate) fn drive_fault(&mut self, kind: DriveErrorKind) {
        bump(&self.counters.drive_faults, 1);
        self.counters.last_drive_fault.store(kind_code(&DRIVE_KINDS, &kind), Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timing_converts_between_rate_counts_and_nanoseconds() {
        // The STM32F405's: 168 MHz, 20 kHz, late beyond 2 µs.
        let timing = TickTiming::new(168_000_000, 20_000, 2_000);
        assert_eq!((timing.period, timing.late_bound), (8_400, 336));
        assert_eq!(timing.nanoseconds(8_400), 50_000);
        let mut handoff = Handoff::new(timing);
        let (link, mut tick) = handoff.split();
        tick.count_tick(Some(336), 0);
        tick.finish(4_200, false);
        tick.count_tick(Some(337), 2);
        tick.finish(100, true);
        let status = link.status();
        assert_eq!((status.rate_hz, status.late_bound_ns), (20_000, 2_000));
        assert_eq!((status.ticks, status.late, status.missed, status.overruns), (2, 1, 2, 1));
        assert_eq!(status.worst_latency_ns, 2_006);
        // The overrun's tick lasted a whole period at least.
        assert_eq!(status.worst_tick_ns, 50_000);
        assert_eq!(Handoff::new(TickTiming::UNTIMED).split().0.status(), TickStatus::default());
        // SysTick's value: 0 at the expiry, then 8399, 8398, … one count later each.
        assert_eq!([0, 8_399, 8_398, 1].map(|current| timing.since_expiry(current)), [0, 1, 2, 8_399]);
    }

    #[test]
    fn fault_kinds_come_back_as_they_went() {
        let mut handoff = Handoff::new(TickTiming::UNTIMED);
        let (link, mut tick) = handoff.split();
        assert_eq!((link.status().last_sensor_fault, link.status().last_drive_fault), (None, None));
        for kind in SENSOR_KINDS {
            tick.sensor_fault(kind);
            assert_eq!(link.status().last_sensor_fault, Some(kind));
        }
        for kind in DRIVE_KINDS {
            tick.drive_fault(kind);
            assert_eq!(link.status().last_drive_fault, Some(kind));
        }
        assert_eq!((link.status().sensor_faults, link.status().drive_faults), (4, 3));
    }

    #[test]
    fn one_command_at_a_time() {
        let mut handoff = Handoff::new(TickTiming::UNTIMED);
        let (mut link, mut tick) = handoff.split();
        assert!(link.has_room());
        assert_eq!(link.post(Command::SetReference(1.0)), Ok(()));
        assert!(!link.has_room());
        assert_eq!(link.post(Command::SetReference(2.0)), Err(ErrorReply::Busy));
        assert_eq!(tick.command(), Some(Command::SetReference(1.0)));
        assert_eq!(tick.command(), None);
        assert!(link.has_room());
    }
}
