//! An identification experiment on the joint: the host sends a [`Plan`](crate::plan::Plan)
//! ([`Request::StartExperiment`](crate::Request::StartExperiment)), the joint plays it at its
//! tick rate and records every tick, and the host fetches the recording in batches
//! ([`Request::FetchSamples`](crate::Request::FetchSamples)) until the experiment has finished
//! or stopped.
//!
//! **Batches.** Each batch carries its own sequence number (from 0 per experiment) and the plan
//! tick of its first sample; its samples are consecutive ticks. A batch lost or repeated on the
//! way shows as a sequence number out of turn; samples the joint dropped (its queue full because
//! the host fetched too slowly) show as a jump in the ticks and in [`SampleBatch::dropped`].
//! [`SampleBatch::follows`] is the host's check.
//!
//! **The watchdog.** Every fetch tells the joint the link is alive: when none has arrived for
//! [`LINK_TIMEOUT_SECONDS`] of ticks, the joint stops the experiment and its motor
//! ([`StopReason::LinkLost`]).
use core::fmt;
use serde::{Deserialize, Serialize};

/// Samples in one [`SampleBatch`] at most: 16 of at most 17 bytes each keep a batch's frame
/// within [`MAX_FRAME_LEN`](crate::MAX_FRAME_LEN) (tested).
pub const BATCH_SAMPLES: usize = 16;

/// Without a fetch for this long (in the plan's ticks), the joint stops the experiment and its
/// motor, s: within 50 ms of the link's loss, the tick that notices it included.
pub const LINK_TIMEOUT_SECONDS: f32 = 0.04;

/// One tick of an experiment as the joint measured it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecordedSample {
    /// Input (motor) side, rad, multi-turn.
    pub input_angle: f32,
    /// Output side, rad.
    pub output_angle: f32,
    /// The torque sensor's reading, N·m.
    pub torque: f32,
    /// The board's temperature reading, °C, when it has one.
    pub temperature: Option<f32>,
}

/// Why an experiment ended before its plan did.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StopReason {
    /// The host asked ([`Request::StopExperiment`](crate::Request::StopExperiment)).
    Host,
    /// The torque sensor read beyond the plan's torque limit.
    TorqueLimit,
    /// The deflection went beyond the plan's deflection limit.
    DeflectionLimit,
    /// No fetch arrived for [`LINK_TIMEOUT_SECONDS`].
    LinkLost,
    /// A sensor reading failed or was not finite.
    SensorFault,
    /// The motor drive refused a command.
    DriveFault,
    /// The plan's rate is not the rate of the board's own ticks.
    PlanRate,
}

impl fmt::Display for StopReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            StopReason::Host => "stopped by the host",
            StopReason::TorqueLimit => "the torque went beyond the plan's limit",
            StopReason::DeflectionLimit => "the deflection went beyond the plan's limit",
            StopReason::LinkLost => "the link went silent (no fetch within 40 ms)",
            StopReason::SensorFault => "a sensor reading failed",
            StopReason::DriveFault => "the motor drive refused a command",
            StopReason::PlanRate => "the plan's rate is not the board's tick rate",
        })
    }
}

/// Where the joint's experiment is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ExperimentState {
    /// None has started since boot.
    Idle,
    /// Playing this segment (from 0).
    Running { segment: u8 },
    /// The plan played to its end; the motor command is zero.
    Finished,
    /// Stopped before the plan's end, for this reason; the motor command is zero.
    Stopped(StopReason),
}

impl ExperimentState {
    /// Whether the joint still plays the plan (its recording may grow).
    pub const fn is_running(self) -> bool {
        matches!(self, ExperimentState::Running { .. })
    }
}

impl fmt::Display for ExperimentState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExperimentState::Idle => f.write_str("no experiment"),
            ExperimentState::Running { segment } => write!(f, "playing segment {}", u16::from(*segment) + 1),
            ExperimentState::Finished => f.write_str("the plan played to its end"),
            ExperimentState::Stopped(reason) => write!(f, "stopped: {reason}"),
        }
    }
}

/// Consecutive ticks of the experiment's recording, as one fetch returns them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SampleBatch {
    /// This batch's number, from 0 per experiment.
    pub sequence: u32,
    /// The plan tick of `samples[0]` (the first tick, at rest, is 0); of the next sample to come
    /// when `samples` is empty.
    pub first_tick: u32,
    /// Samples the joint dropped since the experiment started: its queue was full.
    pub dropped: u32,
    /// The most recorded ticks the joint's queue has held at once since the experiment started:
    /// how close the link came to losing samples.
    pub high_water: u32,
    /// The experiment's state after the last of `samples`.
    pub state: ExperimentState,
    pub samples: heapless::Vec<RecordedSample, BATCH_SAMPLES>,
}

/// Why a batch does not follow the one before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum BatchGap {
    /// A batch was lost or repeated on the way: this sequence number came when that one was due.
    Sequence { expected: u32, got: u32 },
    /// The joint dropped ticks `from..to` (its queue overflowed).
    Ticks { from: u32, to: u32 },
}

impl fmt::Display for BatchGap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BatchGap::Sequence { expected, got } => {
                write!(
                    f,
                    "batch {got} arrived when batch {expected} was due (a batch was lost or repeated on the link)"
                )
            }
            BatchGap::Ticks { from, to } => {
                write!(f, "the joint dropped ticks {from}..{to} (its sample queue overflowed)")
            }
        }
    }
}

impl SampleBatch {
    /// The tick after this batch's last sample.
    pub fn end_tick(&self) -> u32 {
        self.first_tick.saturating_add(self.samples.len() as u32)
    }

    /// Whether this batch follows `previous` (`None`: this is the experiment's first fetch, due
    /// at sequence 0 and tick 0) without a lost or repeated batch and without a dropped tick
    /// between them; else the gap. (Ticks dropped after the last batch's sample show in the
    /// next batch's first tick, or at the end in [`SampleBatch::dropped`].)
    pub fn follows(&self, previous: Option<&SampleBatch>) -> Result<(), BatchGap> {
        let (expected, tick) = match previous {
            Some(batch) => (batch.sequence.wrapping_add(1), batch.end_tick()),
            None => (0, 0),
        };
        if self.sequence != expected {
            return Err(BatchGap::Sequence { expected, got: self.sequence });
        }
        if self.first_tick != tick {
            return Err(BatchGap::Ticks { from: tick, to: self.first_tick });
        }
        Ok(())
    }
}
