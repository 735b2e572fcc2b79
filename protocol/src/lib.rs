//! The link between `swg-host` and the joint firmware, shared by both ends.
//!
//! Every frame, in either direction, is
//!
//! ```text
//! COBS( postcard(protocol_version: u16, id: RequestId(u32), message) ++ CRC-32/ISO-HDLC(LE) ) 0x00
//! └─────────────────────────── one frame ────────────────────────────────────────────────┘ └ delimiter
//! ```
//!
//! The host sends one [`Request`] at a time and waits for the [`Response`] that carries the
//! same [`RequestId`]. The protocol version leads the payload so that a peer speaking another
//! version gets a clear [`ErrorReply::UnsupportedProtocol`] instead of a garbled message; the
//! request id follows it, then the message.
//!
//! **Request ids.** The host numbers its requests (from a random start per connection, never
//! [`RequestId::UNKNOWN`]); the device echoes the id of the request in its reply. A reply whose
//! id is not that of the request the host waits for (a late answer after a timeout, or one a
//! freshly booted board gives to bytes queued before it) is discarded and counted, never taken
//! for the answer. An error reply to a frame the device could not read carries the id when it
//! could be read — [`ErrorReply::UndecodableRequest`] (right version and CRC) — and otherwise
//! [`RequestId::UNKNOWN`]: after a bad COBS encoding, a CRC mismatch, an overlong frame (the
//! bytes cannot be trusted) or another protocol version (whose header may be laid out
//! otherwise). The host does not take such a reply for its answer either: it counts it and
//! keeps waiting, and if its request then goes unanswered, the timeout names the device's
//! reason (most likely the request itself was corrupted on the way).
//!
//! **Endpoints.** The table in [`endpoint`] pairs each request with its response type (as
//! postcard-rpc's endpoint declarations do): the host calls one with `Link::call::<E>`, the
//! firmware answers one through [`Endpoint::reply`], so neither end can pair a request with
//! another request's response, and a request variant without a row does not compile.
#![no_std]

#[cfg(feature = "use-std")]
extern crate std;

use core::fmt;
use model_core::range::Culprit;
pub use model_core::{
    Direction, GearModel, Knot, ParamFault, ParamName, Params, SlipElement, Spring, MODEL_VERSION, SLIP_ELEMENTS,
    TURNING_POINTS,
};
use serde::{Deserialize, Serialize};

/// Version of this message set; bumped on any change to the encoding. Version 2: the model's
/// kind in [`JointParams::model`] (genetic or micro-slip), the evaluator's memory in
/// [`Feedforward`]. Version 3: the joint's torque controller ([`Request::Configure`],
/// [`Request::SetReference`], the lockstep [`Request::Control`] and their responses, the
/// error replies [`ErrorReply::InvalidGain`] and [`ErrorReply::MotorDrive`]). Version 4: the
/// controller's integral deadband and torsion damping in [`ControllerConfig`]. Version 5: the
/// [`RequestId`] in every frame's header; the tick's timing ([`Request::GetStatus`],
/// [`TickStatus`]); error replies that keep their cause's kind ([`ErrorReply::Storage`],
/// [`ErrorReply::MotorDrive`]) and [`ErrorReply::CommitWhileDriving`],
/// [`ErrorReply::NotLockstep`], [`ErrorReply::Busy`]; [`Response::Committed`] a tuple variant
/// (same bytes); an error reply names a model parameter by model-core's [`ParamName`]
/// ([`ParamField::Model`]); [`JointParams::model`] is model-core's [`GearModel`], encoded as
/// version 4's model was. Version 6: [`JointParams::model`] is the model of model version 2 (the
/// deflection's zero, the free-form spring, the micro-slip kind's elements each with its own slip
/// deflection); frames up to [`MAX_FRAME_LEN`] = 512 bytes. Version 7: the Bouc–Wen kind.
/// Version 8: the Preisach kind (its index 3, its reach and 36 weights; [`ParamName`]'s
/// `PreisachReach` and `PreisachWeight`). Version 9: the identification experiment
/// ([`Request::StartExperiment`], [`Request::FetchSamples`], [`Request::StopExperiment`],
/// [`Response::ExperimentStarted`], [`Response::Samples`]; the error replies
/// [`ErrorReply::InvalidPlan`], [`ErrorReply::ControllerOff`],
/// [`ErrorReply::ExperimentRunning`]), and the torque sensor's and temperature's readings in
/// [`ControlSample`].
pub const PROTOCOL_VERSION: u16 = 9;

/// Largest encoded frame, delimiter included: the longest message (a micro-slip
/// [`Response::Params`] with 17 knots, 16 elements and every varint at its maximum, the request
/// id's included) takes 321 bytes (tested), with room for a kind with more parameters.
pub const MAX_FRAME_LEN: usize = 512;

/// Largest payload (version, message and CRC) before COBS encoding.
const MAX_PAYLOAD_LEN: usize = MAX_FRAME_LEN - 2;

/// Bit by bit, without crc's 1 KiB table: a frame's CRC runs on the link, between ticks, and
/// the table was 1 KiB of the joint's 48 KiB of flash (`bench/firmware.sh`).
const CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);
const CRC_LEN: usize = 4;

/// CRC-32/ISO-HDLC of `bytes`: the frames' check, and the flash records' (`swg-joint`'s
/// storage). Out of line: the firmware computes it in several places, and each inlined copy
/// cost a few hundred bytes of flash.
#[inline(never)]
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC.checksum(bytes)
}

/// A `major.minor.patch` version.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Version {
    pub major: u16,
    pub minor: u16,
    pub patch: u16,
}

impl fmt::Display for Version {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}.{}", self.major, self.minor, self.patch)
    }
}

/// What the device runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceInfo {
    pub firmware_version: Version,
    pub protocol_version: u16,
    /// [`MODEL_VERSION`] of the model-core the firmware was built with.
    pub model_version: u16,
}

/// Which request a frame answers: the host numbers its requests, the device echoes the number
/// in its reply (see the crate's documentation). On the wire a varint after the protocol
/// version.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RequestId(pub u32);

impl RequestId {
    /// The id of an error reply to a frame whose id could not be read; never a request's.
    pub const UNKNOWN: RequestId = RequestId(0);

    /// The id after this one, skipping [`RequestId::UNKNOWN`].
    pub const fn next(self) -> RequestId {
        match self.0.wrapping_add(1) {
            0 => RequestId(1),
            id => RequestId(id),
        }
    }
}

impl fmt::Display for RequestId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            RequestId::UNKNOWN => f.write_str("unknown"),
            RequestId(id) => write!(f, "{id}"),
        }
    }
}

/// The control tick's timing since boot: the board's timer starts each tick in an interrupt
/// above the link's priority, and the tick counts what went wrong with its timing; and how far
/// the active set was asked beyond its identified range. Counters wrap at 2³².
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickStatus {
    /// The tick rate, Hz; 0 when the ticks are not timed (an in-process test device runs one
    /// whenever the link hands it a sample).
    pub rate_hz: u32,
    /// Ticks run.
    pub ticks: u32,
    /// Ticks that had not finished when the next was due: the timer expired again during them.
    pub overruns: u32,
    /// Ticks that started more than `late_bound_ns` after their timer expired.
    pub late: u32,
    /// Whole periods that passed without a tick (the tick was held off longer than a period).
    pub missed: u32,
    /// The latency beyond which a tick counts as late, ns.
    pub late_bound_ns: u32,
    /// The longest latency from a timer expiry to its tick's start, ns.
    pub worst_latency_ns: u32,
    /// The longest time from a timer expiry to its tick's end, ns: the tick's worst case,
    /// measured (at most a period, else the tick overran).
    pub worst_tick_ns: u32,
    /// The board's own ticks whose encoder reading failed: the command was zero.
    pub sensor_faults: u32,
    /// The kind of the last of those.
    pub last_sensor_fault: Option<SensorErrorKind>,
    /// The board's own ticks whose command the motor drive refused.
    pub drive_faults: u32,
    /// The kind of the last of those.
    pub last_drive_fault: Option<DriveErrorKind>,
    /// Samples the active set evaluated beyond its spring's identified range (where the spring
    /// continues with the stiffness at the range's edge), since the set was activated.
    pub beyond_range: u32,
    /// The largest distance of those samples beyond the range, rad (0 when none is).
    pub max_excess_rad: f32,
}

/// Why an angle sensor's reading failed; the kinds of embedded-hal's error convention, as
/// `swg-joint`'s `sensor::Error::kind` reports them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SensorErrorKind {
    /// The transfer on the sensor's bus failed.
    Bus,
    /// The answer arrived corrupted (a parity or CRC check failed).
    Corrupt,
    /// The sensor flagged an error of its own (magnetic field, framing, a bad command).
    Sensor,
    /// Any other failure.
    Other,
}

impl fmt::Display for SensorErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SensorErrorKind::Bus => "the sensor's bus transfer failed",
            SensorErrorKind::Corrupt => "the sensor's answer was corrupted",
            SensorErrorKind::Sensor => "the sensor flagged an error",
            SensorErrorKind::Other => "the sensor failed",
        })
    }
}

/// Why the motor drive refused a command; the kinds of embedded-hal's error convention, as
/// `swg-joint`'s `drive::Error::kind` reports them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum DriveErrorKind {
    /// The command is beyond what the drive is set up to output.
    OutOfRange,
    /// The drive reports a fault (over-current, under-voltage, over-temperature).
    Fault,
    /// Any other failure.
    Other,
}

impl fmt::Display for DriveErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DriveErrorKind::OutOfRange => "the command is beyond the drive's range",
            DriveErrorKind::Fault => "the drive reports a fault",
            DriveErrorKind::Other => "the drive failed",
        })
    }
}

/// Why the parameter store could not write a set: which step of a commit failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StorageError {
    /// The flash cannot hold two slots, or its write size does not divide 8 bytes.
    Geometry,
    /// Erasing the slot failed.
    Erase,
    /// Writing the record or its CRC failed.
    Write,
    /// The record read back differs from what was written (worn or protected flash).
    Verify,
    /// The parameter set did not serialize into a record.
    Encoding,
}

impl fmt::Display for StorageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            StorageError::Geometry => "flash region too small or write size unsupported",
            StorageError::Erase => "flash erase failed",
            StorageError::Write => "flash write failed",
            StorageError::Verify => "flash read back differs from what was written",
            StorageError::Encoding => "parameter set does not fit a record",
        })
    }
}

impl core::error::Error for StorageError {}

/// Everything the joint needs for feed-forward: the model and how to apply it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointParams {
    /// [`MODEL_VERSION`] the parameters were fitted for.
    pub model_version: u16,
    /// The model of any kind, evaluated from rest with its memory (model-core's `Evaluator`).
    pub model: GearModel<f32>,
    /// Reduction ratio N of the gear: deflection θ = θ_in/N − θ_out.
    pub gear_ratio: f32,
    /// |T_ff| is clamped to this, N·m.
    pub torque_limit: f32,
    /// θ must move back this far from its extreme before the genetic model records a
    /// turning point, rad; keeps encoder noise from chattering the branch at the turning
    /// points. (The micro-slip kind needs no band: noise makes only tiny reversible loops.)
    pub direction_band: f32,
}

/// Gear ratios a strain wave gear can have; 1 allows a direct-drive test rig.
pub const GEAR_RATIO_RANGE: core::ops::RangeInclusive<f32> = 1.0..=10_000.0;
/// Direction bands that make sense for an absolute encoder, rad (≤ 0.1 rad ≈ 5.7°).
pub const DIRECTION_BAND_RANGE: core::ops::RangeInclusive<f32> = 0.0..=0.1;

/// Largest plausible torsional deflection, rad (≈ 5.7°; strain wave gears deflect a few mrad).
/// The joint evaluates the model for |θ| up to this and skips a reading beyond it as an
/// encoder fault; [`JointParams::validate`] refuses a set that overflows f32 anywhere in this
/// range (model-core's `range`).
pub const MAX_DEFLECTION: f32 = 0.1;

impl JointParams {
    /// The checks the firmware applies before it uses a set; the host may run them first.
    pub fn validate(&self) -> Result<(), ErrorReply> {
        if self.model_version != MODEL_VERSION {
            return Err(ErrorReply::ModelVersion { got: self.model_version, supported: MODEL_VERSION });
        }
        self.model
            .check()
            .map_err(|(name, fault)| ErrorReply::InvalidParam { field: ParamField::Model(name), fault })?;
        let joint = [
            (ParamField::GearRatio, self.gear_ratio, GEAR_RATIO_RANGE.contains(&self.gear_ratio)),
            (ParamField::TorqueLimit, self.torque_limit, self.torque_limit > 0.0),
            (ParamField::DirectionBand, self.direction_band, DIRECTION_BAND_RANGE.contains(&self.direction_band)),
        ];
        for (field, value, in_range) in joint {
            if !value.is_finite() {
                return Err(ErrorReply::InvalidParam { field, fault: ParamFault::NotFinite });
            }
            if !in_range {
                return Err(ErrorReply::InvalidParam { field, fault: ParamFault::OutOfRange });
            }
        }
        // Evaluable in f32 over every |θ| ≤ MAX_DEFLECTION and every state the evaluators can
        // reach, or refused naming the parameter at fault (out of range).
        self.model.evaluable_within(MAX_DEFLECTION).map_err(|culprit| match culprit {
            Culprit::Param(name) => {
                ErrorReply::InvalidParam { field: ParamField::Model(name), fault: ParamFault::OutOfRange }
            }
            Culprit::Several => ErrorReply::ModelOverflow,
        })
    }

    /// The set validated ([`JointParams::validate`]) and its model's evaluator at rest, with the
    /// direction band as the genetic kind's reversal band, written over `evaluator` in place
    /// (model-core's `GearModel::prepare`; of no use where the set is refused): what a joint
    /// installs. Not inlined (nor generic): compiled once, with this crate's settings (for
    /// size; the joint prepares a set on its link's side, where time does not matter).
    #[inline(never)]
    pub fn prepare_evaluator(&self, evaluator: &mut model_core::Evaluator<f32>) -> Result<(), ErrorReply> {
        self.validate()?;
        self.model.prepare(self.direction_band, evaluator).map_err(|_| ErrorReply::ModelOverflow)
    }

    /// A model of model version 1 (from a flash record written before version 2) as today's,
    /// with the same torque: model-core's [`GearModelV1::upgrade`](model_core::legacy::GearModelV1::upgrade),
    /// compiled once with this crate's settings (for size; its 14 exponentials of the micro-slip
    /// grid were unrolled at the joint's), as [`JointParams::prepare_evaluator`].
    #[inline(never)]
    pub fn upgrade_model(model: &model_core::legacy::GearModelV1<f32>) -> Result<GearModel<f32>, model_core::Error> {
        model.upgrade()
    }

    /// The set as postcard writes it (a record's payload in flash); its length in `out`.
    #[inline(never)]
    pub fn to_postcard(&self, out: &mut [u8]) -> Result<usize, postcard::Error> {
        postcard::to_slice(self, out).map(|written| written.len())
    }

    /// The set from postcard's bytes (a record's payload in flash).
    #[inline(never)]
    pub fn from_postcard(bytes: &[u8]) -> Result<Self, postcard::Error> {
        postcard::from_bytes(bytes)
    }
}

/// Which evaluation the firmware runs for a replayed sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EvalPath {
    /// model-core's f32 evaluation (libm transcendental functions).
    Direct,
    /// The per-tick path: polynomial approximations prepared when the parameters arrive.
    Fast,
}

/// One reading of both encoders, as the control tick would take it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EncoderSample {
    /// Input (wave generator, motor) side, rad, multi-turn.
    pub input_angle: f32,
    /// Output (flexspline) side, rad.
    pub output_angle: f32,
    pub path: EvalPath,
}

/// Whether the feed-forward was applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Compensation {
    /// T_ff and K are the model's values.
    Active,
    /// The model's torque exceeded the limit; T_ff is the limit with the model's sign.
    Clamped,
    /// No valid parameters, an implausible encoder reading, or the model could not be
    /// evaluated: T_ff = K = 0.
    Off,
}

/// The firmware's feed-forward for one sample, with the deflection it used and the state of
/// its model's memory, so that the host can run its f64 model through exactly the same
/// deflections and check that both memories agree.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Feedforward {
    /// θ = θ_in/N − θ_out, rad.
    pub deflection: f32,
    /// T_ff, N·m.
    pub torque: f32,
    /// K = dT/dθ, N·m/rad.
    pub stiffness: f32,
    pub compensation: Compensation,
    /// The model's memory after this tick: the genetic kind's direction of motion (`None` at
    /// rest, before θ has left ±band); `None` for the micro-slip kind.
    pub direction: Option<Direction>,
    /// The genetic kind's stored turning points; the micro-slip kind's elements that slip (at
    /// their limit). 0 at rest.
    pub memory: u8,
}

/// What the joint's torque controller closes its loop on (see `swg-joint`'s `Controller`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControlMode {
    /// No command: the motor torque is 0. The state at boot, and the safe mode without a valid
    /// parameter set (the controller then knows neither the gear ratio nor the deflection).
    Off,
    /// Current feed-forward only: motor torque = T_ref / N.
    OpenLoop,
    /// The torque loop on one stiffness: T̂ = [`ControllerConfig::stiffness`]·θ.
    Linear,
    /// The torque loop on the model: T̂ = T_ff of the installed set's stateful evaluator.
    Model,
}

impl ControlMode {
    /// The name on the command line and in files.
    pub const fn as_str(self) -> &'static str {
        match self {
            ControlMode::Off => "off",
            ControlMode::OpenLoop => "open-loop",
            ControlMode::Linear => "linear",
            ControlMode::Model => "model",
        }
    }
}

impl fmt::Display for ControlMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The torque controller's mode and gains. With e = T_ref − T̂, N the gear ratio, θ the
/// deflection and ω the motor's velocity above the firmware's damping cutoff (3 Hz: the
/// joint's modes, not its slow travel), the motor torque command is
///
/// ```text
/// u = T_ref/N + s·kp·e + ∫ ki·e dt + torsion_damping·N·(s·Ṫ_ref/stiffness − θ̇) − damping·ω
/// ```
///
/// with |u| ≤ command_limit and the integral held while s·|e| ≤ integral_deadband, in `Linear`
/// and `Model` modes (s = 1, or in `Model` mode the gain schedule clamp(stiffness / K, ¼, 2)
/// with K the model's dT/dθ, so that the loop gain stays that of the nominal stiffness and
/// s·Ṫ_ref/stiffness is the deflection rate the reference asks for), and u = T_ref/N in
/// `OpenLoop`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControllerConfig {
    pub mode: ControlMode,
    /// Proportional gain, motor N·m per N·m of joint-torque error (≥ 0).
    pub kp: f32,
    /// Integral gain, motor N·m per N·m·s of joint-torque error (≥ 0).
    pub ki: f32,
    /// The integral rests while s·|e| is within this, N·m (≥ 0): about one encoder count of
    /// torque at `stiffness` (so one count at the stiffness in use, stiffness/s), so that
    /// quantisation and the motor's stiction cannot make it hunt.
    pub integral_deadband: f32,
    /// Damping of the motor's velocity (above the cutoff), motor N·m per rad/s (≥ 0).
    pub damping: f32,
    /// Damping of the gear's deflection rate against the one the reference asks for, motor
    /// N·m per rad/s at the motor (N·θ̇) (≥ 0).
    pub torsion_damping: f32,
    /// The linear mode's stiffness and the model mode's nominal stiffness, N·m/rad (> 0).
    pub stiffness: f32,
    /// |u| is clamped to this, N·m at the motor shaft (> 0).
    pub command_limit: f32,
    /// The control period, s (in (0, 1]).
    pub period: f32,
}

/// A field of [`ControllerConfig`] named in an error reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GainField {
    Kp,
    Ki,
    Damping,
    Stiffness,
    CommandLimit,
    Period,
    IntegralDeadband,
    TorsionDamping,
}

impl GainField {
    pub const fn as_str(self) -> &'static str {
        match self {
            GainField::Kp => "kp",
            GainField::Ki => "ki",
            GainField::Damping => "damping",
            GainField::Stiffness => "stiffness",
            GainField::CommandLimit => "command_limit",
            GainField::Period => "period",
            GainField::IntegralDeadband => "integral_deadband",
            GainField::TorsionDamping => "torsion_damping",
        }
    }
}

impl fmt::Display for GainField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl ControllerConfig {
    /// The checks the firmware applies before it uses a configuration.
    pub fn validate(&self) -> Result<(), ErrorReply> {
        let fields = [
            (GainField::Kp, self.kp, self.kp >= 0.0),
            (GainField::Ki, self.ki, self.ki >= 0.0),
            (GainField::IntegralDeadband, self.integral_deadband, self.integral_deadband >= 0.0),
            (GainField::Damping, self.damping, self.damping >= 0.0),
            (GainField::TorsionDamping, self.torsion_damping, self.torsion_damping >= 0.0),
            (GainField::Stiffness, self.stiffness, self.stiffness > 0.0),
            (GainField::CommandLimit, self.command_limit, self.command_limit > 0.0),
            (GainField::Period, self.period, self.period > 0.0 && self.period <= 1.0),
        ];
        for (field, value, in_range) in fields {
            if !value.is_finite() {
                return Err(ErrorReply::InvalidGain { field, fault: ParamFault::NotFinite });
            }
            if !in_range {
                return Err(ErrorReply::InvalidGain { field, fault: ParamFault::OutOfRange });
            }
        }
        Ok(())
    }
}

/// One lockstep control tick: both encoders' angles (as [`EncoderSample`]), the joint torque
/// reference, and what the board's other sensors read (recorded by an experiment).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControlSample {
    /// Input (motor) side, rad, multi-turn.
    pub input_angle: f32,
    /// Output side, rad.
    pub output_angle: f32,
    /// T_ref, N·m at the joint; while an experiment runs, its plan's reference is used instead.
    pub reference: f32,
    /// The joint torque sensor's reading, N·m.
    pub torque: f32,
    /// The board's temperature reading, °C, when it has one.
    pub temperature: Option<f32>,
}

impl ControlSample {
    /// Every reading finite (the temperature when there is one).
    pub fn is_finite(&self) -> bool {
        let temperature = self.temperature.unwrap_or(0.0);
        [self.input_angle, self.output_angle, self.reference, self.torque, temperature].iter().all(|v| v.is_finite())
    }
}

/// What one control tick commanded.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControlOutput {
    /// The motor torque command u, N·m at the motor shaft: finite, |u| ≤ the command limit.
    pub command: f32,
    /// T̂, the joint torque the loop closed on, N·m (0 in `OpenLoop` and `Off`).
    pub estimate: f32,
    /// The mode this tick ran: the configured one, or its fallback (`OpenLoop` for a tick
    /// whose torque estimate is unavailable, `Off` without a valid parameter set).
    pub mode: ControlMode,
    /// u was clamped to the command limit.
    pub saturated: bool,
}

/// Host → device. Each variant is one [`endpoint`]'s request.
pub type Request = RequestOf<JointParams>;

/// [`Request`] with `P` for the parameter set of [`Request::WriteParams`]: the device decodes
/// requests as `RequestOf<Deferred>` ([`decode_request`]), which leaves a set's bytes in the
/// frame for it to decode where it handles the request. The same bytes either way.
// A request is decoded into one stack slot of the link's task and never stored in a queue, and
// no_std has no Box: the large parameter set stays inline.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RequestOf<P> {
    GetDeviceInfo,
    /// Validate and activate (at the next tick); not yet stored.
    WriteParams(P),
    /// The active set, exactly as the firmware holds it.
    ReadParams,
    /// Store the active set in flash.
    Commit,
    /// Run one control tick on a recorded sample (replay mode).
    Replay(EncoderSample),
    /// Set the torque controller's mode and gains; resets its integrator and velocity.
    Configure(ControllerConfig),
    /// Set the joint torque reference T_ref, N·m, for the board's own control ticks.
    SetReference(f32),
    /// Run one control tick on these angles and reference (lockstep with a simulated plant);
    /// the command goes to the board's motor drive and comes back in the response.
    Control(ControlSample),
    /// The control tick's timing counters.
    GetStatus,
    /// Check the plan and play it from the next tick, recording every tick.
    StartExperiment(plan::Plan),
    /// The experiment's next batch of recorded ticks; keeps its watchdog fed.
    FetchSamples,
    /// Stop the experiment at the next tick (motor command zero).
    StopExperiment,
}

/// Device → host, one per request: its endpoint's response, or [`Response::Error`].
// As for Request: the parameter set stays inline.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Response {
    DeviceInfo(DeviceInfo),
    ParamsAccepted,
    /// `None` when the device has no valid parameters.
    Params(Option<JointParams>),
    /// Stored with this sequence number.
    Committed(u32),
    Feedforward(Feedforward),
    Error(ErrorReply),
    /// A [`Request::Configure`] or [`Request::SetReference`] took effect.
    ControlAccepted,
    Control(ControlOutput),
    Status(TickStatus),
    /// The experiment starts at the next tick and plays this many ticks.
    ExperimentStarted(u32),
    Samples(experiment::SampleBatch),
}

/// One request type and its response type: what the host sends and what the device answers
/// when it does not refuse ([`Response::Error`] may answer any). Declared by the table in
/// [`endpoint`]; the wire carries them as the [`Request`] and [`Response`] variants named there.
pub trait Endpoint {
    /// The request's content.
    type Request;
    /// The answer's content.
    type Response;
    /// The endpoint's name, for errors.
    const NAME: &'static str;
    /// `request` as the wire's message.
    fn request(request: &Self::Request) -> Request;
    /// The wire's answer as this endpoint's response, or back as it came when it is not.
    // The response came on the stack and goes back unchanged for the caller's error: no copy to
    // save by boxing it, and no_std has no Box.
    #[allow(clippy::result_large_err)]
    fn response(response: Response) -> Result<Self::Response, Response>;
    /// `response` as the wire's message: the device's side of [`Endpoint::response`].
    fn reply(response: Self::Response) -> Response;
}

/// Declares the endpoints: `Name: Request::Variant(Payload) => Response::Variant(Payload);`, a
/// unit variant's payload being `()`. Generates a marker type per row implementing
/// [`Endpoint`], and [`Request::endpoint`], whose match over every request variant makes a
/// request without a row a compile error.
macro_rules! endpoints {
    ($(
        $(#[$doc:meta])*
        $name:ident: Request::$request:ident $(($request_type:ty))? => Response::$response:ident $(($response_type:ty))?;
    )*) => {
        $(
            $(#[$doc])*
            #[derive(Clone, Copy, Debug)]
            pub enum $name {}

            impl $crate::Endpoint for $name {
                type Request = endpoints!(@type $($request_type)?);
                type Response = endpoints!(@type $($response_type)?);
                const NAME: &'static str = stringify!($name);
                fn request(request: &Self::Request) -> $crate::Request {
                    endpoints!(@wrap $crate::Request::$request, request $(, $request_type)?)
                }
                fn response(response: $crate::Response) -> Result<Self::Response, $crate::Response> {
                    match response {
                        endpoints!(@pattern $crate::Response::$response, value $(, $response_type)?) => {
                            Ok(endpoints!(@value value $(, $response_type)?))
                        }
                        other => Err(other),
                    }
                }
                fn reply(response: Self::Response) -> $crate::Response {
                    endpoints!(@move $crate::Response::$response, response $(, $response_type)?)
                }
            }
        )*

        impl $crate::Request {
            /// The name of the endpoint this request belongs to.
            pub const fn endpoint(&self) -> &'static str {
                match self {
                    $(endpoints!(@pattern $crate::Request::$request, _value $(, $request_type)?) => stringify!($name),)*
                }
            }
        }
    };
    (@type) => { () };
    (@type $payload:ty) => { $payload };
    (@wrap $variant:path, $value:expr) => {{
        let () = *$value;
        $variant
    }};
    (@wrap $variant:path, $value:expr, $payload:ty) => { $variant(*$value) };
    (@move $variant:path, $value:expr) => {{
        let () = $value;
        $variant
    }};
    (@move $variant:path, $value:expr, $payload:ty) => { $variant($value) };
    (@pattern $variant:path, $value:ident) => { $variant };
    (@pattern $variant:path, $value:ident, $payload:ty) => { $variant($value) };
    (@value $value:ident) => { () };
    (@value $value:ident, $payload:ty) => { $value };
}

pub mod experiment;
pub mod plan;

/// The link's endpoints: each request paired with its response.
pub mod endpoint {
    use crate::experiment::SampleBatch;
    use crate::plan::Plan;
    use crate::TickStatus;
    use crate::{ControlOutput, ControlSample, ControllerConfig, DeviceInfo, EncoderSample, Feedforward, JointParams};

    endpoints! {
        /// The device's firmware, protocol and model versions.
        GetDeviceInfo: Request::GetDeviceInfo => Response::DeviceInfo(DeviceInfo);
        /// Validates a set and activates it at the next tick, from rest; not yet stored.
        WriteParams: Request::WriteParams(JointParams) => Response::ParamsAccepted;
        /// The set the next tick uses, exactly as the firmware holds it.
        ReadParams: Request::ReadParams => Response::Params(Option<JointParams>);
        /// Stores the active set in flash; answers its record's sequence number.
        Commit: Request::Commit => Response::Committed(u32);
        /// One tick of the compensator on a recorded sample.
        Replay: Request::Replay(EncoderSample) => Response::Feedforward(Feedforward);
        /// The torque controller's mode and gains (its integral and velocity start afresh).
        Configure: Request::Configure(ControllerConfig) => Response::ControlAccepted;
        /// The joint torque reference for the board's own ticks.
        SetReference: Request::SetReference(f32) => Response::ControlAccepted;
        /// One lockstep control tick: angles and reference in, the motor command out.
        Control: Request::Control(ControlSample) => Response::Control(ControlOutput);
        /// The control tick's timing counters.
        GetStatus: Request::GetStatus => Response::Status(TickStatus);
        /// Checks a plan and plays it from the next tick; answers the ticks it plays.
        StartExperiment: Request::StartExperiment(Plan) => Response::ExperimentStarted(u32);
        /// The experiment's next batch of recorded ticks, with its state.
        FetchSamples: Request::FetchSamples => Response::Samples(SampleBatch);
        /// Stops the experiment at the next tick; the motor command goes to zero.
        StopExperiment: Request::StopExperiment => Response::ControlAccepted;
    }
}

/// A parameter named in an error reply: one of the model's (model-core's [`ParamName`], which
/// names every kind's parameters) or one of the joint's three.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamField {
    Model(ParamName),
    GearRatio,
    TorqueLimit,
    DirectionBand,
}

impl fmt::Display for ParamField {
    /// The name as in files; an element's stiffness with its index, `stiffness[3]`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamField::Model(name) => write!(f, "{name}"),
            ParamField::GearRatio => f.write_str("gear_ratio"),
            ParamField::TorqueLimit => f.write_str("torque_limit"),
            ParamField::DirectionBand => f.write_str("direction_band"),
        }
    }
}

/// Why the device refused a request. The previous parameters stay active in every case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ErrorReply {
    /// The frame was not valid COBS or too short to hold a CRC.
    BadFrame,
    /// The frame's CRC did not match: bytes were corrupted on the way.
    BadCrc,
    /// The frame did not fit the device's receive buffer.
    FrameTooLong,
    UnsupportedProtocol {
        got: u16,
        supported: u16,
    },
    /// Right version and CRC, but not a request of this protocol.
    UndecodableRequest,
    ModelVersion {
        got: u16,
        supported: u16,
    },
    InvalidParam {
        field: ParamField,
        fault: ParamFault,
    },
    /// The parameters are valid numbers but the model overflows f32 with them.
    ModelOverflow,
    /// Commit without a valid active parameter set.
    NoParams,
    /// The parameter store failed at this step of the commit.
    Storage(StorageError),
    /// A replayed or lockstep control sample held NaN or infinity.
    NonFiniteSample,
    /// A controller configuration with a gain that is not finite or out of its range.
    InvalidGain {
        field: GainField,
        fault: ParamFault,
    },
    /// The board's motor drive refused the command (the tick's command was not applied).
    MotorDrive(DriveErrorKind),
    /// Commit while the controller is configured to drive the motor: erasing flash stalls the
    /// processor, and the control tick with it, for up to seconds on a single-bank part.
    CommitWhileDriving,
    /// A replay or lockstep control sample on a board whose ticks read its own encoders.
    NotLockstep,
    /// The control tick has not yet taken the link's previous command (the link waits for it
    /// before it reads another request, so only a tick that stopped leads here).
    Busy,
    /// A plan that does not pass [`plan::Plan::check`] (the host checks it first, and names why).
    InvalidPlan,
    /// An experiment needs the controller configured to drive (a mode other than `Off`).
    ControllerOff,
    /// An experiment runs: stop it first.
    ExperimentRunning,
}

impl fmt::Display for ErrorReply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ErrorReply::BadFrame => f.write_str("frame is not valid COBS or too short"),
            ErrorReply::BadCrc => f.write_str("frame CRC mismatch (corrupted bytes)"),
            ErrorReply::FrameTooLong => f.write_str("frame longer than the receive buffer"),
            ErrorReply::UnsupportedProtocol { got, supported } => {
                write!(f, "protocol version {got} not supported (device speaks {supported})")
            }
            ErrorReply::UndecodableRequest => f.write_str("request not understood"),
            ErrorReply::ModelVersion { got, supported } => {
                write!(f, "model version {got} not supported (device runs {supported})")
            }
            ErrorReply::InvalidParam { field, fault } => match fault {
                ParamFault::NotFinite => write!(f, "parameter {field} is not finite"),
                ParamFault::OutOfRange => write!(f, "parameter {field} is out of range"),
            },
            ErrorReply::ModelOverflow => f.write_str("model overflows f32 with these parameters"),
            ErrorReply::NoParams => f.write_str("no valid parameters on the device"),
            ErrorReply::Storage(error) => write!(f, "storing the parameters failed: {error}"),
            ErrorReply::NonFiniteSample => f.write_str("encoder sample is not finite"),
            ErrorReply::InvalidGain { field, fault } => match fault {
                ParamFault::NotFinite => write!(f, "controller gain {field} is not finite"),
                ParamFault::OutOfRange => write!(f, "controller gain {field} is out of range"),
            },
            ErrorReply::MotorDrive(kind) => write!(f, "the motor drive refused the command: {kind}"),
            ErrorReply::CommitWhileDriving => {
                f.write_str("commit refused while the controller drives the motor: configure it off first")
            }
            ErrorReply::NotLockstep => {
                f.write_str("this board ticks on its own encoders: replay and lockstep control are refused")
            }
            ErrorReply::Busy => f.write_str("the control tick has not taken the previous command"),
            ErrorReply::InvalidPlan => f.write_str("the plan does not pass the device's checks"),
            ErrorReply::ControllerOff => {
                f.write_str("an experiment needs the controller configured to drive the motor (not off)")
            }
            ErrorReply::ExperimentRunning => f.write_str("an experiment is running: stop it first"),
        }
    }
}

impl core::error::Error for ErrorReply {}

/// Why a frame could not be built or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameError {
    /// Not valid COBS, or shorter than a CRC.
    Malformed,
    Crc,
    TooLong,
    /// Intact frame of another protocol version.
    Version(u16),
    /// Intact frame of this version whose message does not decode; the request id when it
    /// could be read, else [`RequestId::UNKNOWN`].
    Message(RequestId),
    /// The message does not fit [`MAX_FRAME_LEN`] or the output buffer.
    BufferTooSmall,
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::Malformed => f.write_str("malformed frame"),
            FrameError::Crc => f.write_str("frame CRC mismatch"),
            FrameError::TooLong => f.write_str("frame too long"),
            FrameError::Version(got) => {
                write!(f, "peer speaks protocol version {got}, this end {PROTOCOL_VERSION}")
            }
            FrameError::Message(_) => f.write_str("frame holds no message of this protocol"),
            FrameError::BufferTooSmall => f.write_str("message does not fit the frame buffer"),
        }
    }
}

impl core::error::Error for FrameError {}

impl FrameError {
    /// The id an error reply to this frame carries: the frame's own when it could be read.
    pub const fn request_id(&self) -> RequestId {
        match self {
            FrameError::Message(id) => *id,
            _ => RequestId::UNKNOWN,
        }
    }
}

impl From<FrameError> for ErrorReply {
    fn from(error: FrameError) -> Self {
        match error {
            FrameError::Malformed | FrameError::BufferTooSmall => ErrorReply::BadFrame,
            FrameError::Crc => ErrorReply::BadCrc,
            FrameError::TooLong => ErrorReply::FrameTooLong,
            FrameError::Version(got) => ErrorReply::UnsupportedProtocol { got, supported: PROTOCOL_VERSION },
            FrameError::Message(_) => ErrorReply::UndecodableRequest,
        }
    }
}

/// A decoded frame: the request id from its header and its message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Envelope<T> {
    pub id: RequestId,
    pub message: T,
}

/// Encodes `message` with the request id `id` as one frame into `out`, delimiter included;
/// returns its length.
pub fn encode<T: Serialize>(id: RequestId, message: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    encode_with_version(PROTOCOL_VERSION, id, message, out)
}

/// [`encode`] with an explicit protocol version, for tests of version handling.
pub fn encode_with_version<T: Serialize>(
    version: u16,
    id: RequestId,
    message: &T,
    out: &mut [u8],
) -> Result<usize, FrameError> {
    let mut payload = [0u8; MAX_PAYLOAD_LEN];
    let body_len =
        postcard::to_slice(&(version, id, message), &mut payload).map_err(|_| FrameError::BufferTooSmall)?.len();
    let crc = crc32(payload.get(..body_len).ok_or(FrameError::BufferTooSmall)?);
    let with_crc = body_len + CRC_LEN;
    payload.get_mut(body_len..with_crc).ok_or(FrameError::BufferTooSmall)?.copy_from_slice(&crc.to_le_bytes());
    let source = payload.get(..with_crc).ok_or(FrameError::BufferTooSmall)?;
    let encoded = cobs::try_encode(source, out).map_err(|_| FrameError::BufferTooSmall)?;
    *out.get_mut(encoded).ok_or(FrameError::BufferTooSmall)? = 0;
    Ok(encoded + 1)
}

/// Encodes `message` with the request id `id` as one frame into a new vector, delimiter included.
#[cfg(feature = "use-std")]
pub fn encode_to_vec<T: Serialize>(id: RequestId, message: &T) -> Result<std::vec::Vec<u8>, FrameError> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let len = encode(id, message, &mut out)?;
    Ok(out.get(..len).ok_or(FrameError::BufferTooSmall)?.to_vec())
}

/// A [`Request::WriteParams`]'s parameter set not decoded yet: it reads nothing, and the set's
/// bytes follow ([`decode_request`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Deferred;

/// A device's request frames: [`decode`] of a [`Request`], but a [`Request::WriteParams`]'s
/// parameter set left in `frame`, at the range returned with the request (what follows the
/// message's other bytes, the set's postcard bytes for that request), for the device to decode
/// with [`JointParams::from_postcard`] where it handles the request: decoded here, the set went
/// up through every frame of the decoding, the link's deepest stack. A set that does not decode
/// is the same [`FrameError::Message`] (with the request's id) as if decoded here. Not inlined
/// nor generic, so compiled once with this crate's settings (for size), as
/// [`encode_response`].
#[inline(never)]
pub fn decode_request(
    frame: &mut [u8],
) -> Result<(Envelope<RequestOf<Deferred>>, core::ops::Range<usize>), FrameError> {
    decode_leaving_rest(frame)
}

/// See [`decode_request`].
#[inline(never)]
pub fn encode_response(id: RequestId, response: &Response, out: &mut [u8]) -> Result<usize, FrameError> {
    encode(id, response, out)
}

/// Decodes one frame (the bytes between two delimiters) in place.
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a mut [u8]) -> Result<Envelope<T>, FrameError> {
    decode_leaving_rest(frame).map(|(message, _)| message)
}

/// [`decode`], and where in `frame` the bytes after the message lie (none but the CRC in a frame
/// [`encode`] writes).
fn decode_leaving_rest<'a, T: Deserialize<'a>>(
    frame: &'a mut [u8],
) -> Result<(Envelope<T>, core::ops::Range<usize>), FrameError> {
    let len = cobs_decode_in_place(frame).ok_or(FrameError::Malformed)?;
    let payload = frame.get(..len).ok_or(FrameError::Malformed)?;
    let body_len = len.checked_sub(CRC_LEN).filter(|&n| n > 0).ok_or(FrameError::Malformed)?;
    let (body, crc) = payload.split_at(body_len);
    if crc != crc32(body).to_le_bytes() {
        return Err(FrameError::Crc);
    }
    let (version, rest) =
        postcard::take_from_bytes::<u16>(body).map_err(|_| FrameError::Message(RequestId::UNKNOWN))?;
    if version != PROTOCOL_VERSION {
        return Err(FrameError::Version(version));
    }
    let (id, message) =
        postcard::take_from_bytes::<RequestId>(rest).map_err(|_| FrameError::Message(RequestId::UNKNOWN))?;
    let (message, rest) = postcard::take_from_bytes(message).map_err(|_| FrameError::Message(id))?;
    // `rest` ends where the body does.
    Ok((Envelope { id, message }, body_len - rest.len()..body_len))
}

/// COBS-decodes `frame` in place up to its first 0x00 (or its end); the decoded length, or `None`
/// where a block runs past that end (or the frame is empty). `cobs::decode_in_place`'s decoding,
/// byte for byte and refusal for refusal (tested against it), without its indexing: that one's
/// bounds check, which never fails, linked core::fmt's integer formatting into the firmware for
/// its panic message (0.7 KiB of flash).
fn cobs_decode_in_place(frame: &mut [u8]) -> Option<usize> {
    if frame.is_empty() {
        return None;
    }
    let end = frame.iter().position(|&byte| byte == 0).unwrap_or(frame.len());
    let (mut read, mut written) = (0, 0);
    while read < end {
        // A block: its code n (≠ 0 before `end`), then n − 1 data bytes, then a zero unless
        // n = 0xFF or the frame ends there.
        let code = *frame.get(read)?;
        let block_end = read + usize::from(code);
        if block_end > end {
            return None;
        }
        for at in read + 1..block_end {
            let byte = *frame.get(at)?;
            *frame.get_mut(written)? = byte;
            written += 1;
        }
        read = block_end;
        if code != 0xFF && read < end {
            *frame.get_mut(written)? = 0;
            written += 1;
        }
    }
    Some(written)
}

/// The position in an encoded frame (as [`encode`] writes it) of byte `n` of what it carries
/// (version, id, message and CRC), skipping COBS's code bytes: what a test flips to corrupt a frame
/// without breaking its COBS structure, so that the CRC must catch it.
pub fn payload_index(frame: &[u8], n: usize) -> Option<usize> {
    let mut code_at = 0;
    let mut seen = 0;
    while let Some(&code) = frame.get(code_at) {
        if code == 0 {
            return None;
        }
        let data = code_at + 1..code_at + usize::from(code);
        if n < seen + data.len() {
            return Some(data.start + (n - seen));
        }
        seen += data.len();
        code_at = data.end;
    }
    None
}

/// Splits a byte stream into frames at the 0x00 delimiters.
pub struct FrameReader<const N: usize> {
    buffer: [u8; N],
    len: usize,
    overflowed: bool,
}

impl<const N: usize> Default for FrameReader<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameReader<N> {
    pub const fn new() -> Self {
        FrameReader { buffer: [0; N], len: 0, overflowed: false }
    }

    /// Feeds one received byte. At a delimiter, returns the frame collected since the last
    /// one (ready for [`decode`]), or [`FrameError::TooLong`] if it did not fit.
    /// Empty frames (repeated delimiters, used to resynchronise) are skipped.
    pub fn push(&mut self, byte: u8) -> Option<Result<&mut [u8], FrameError>> {
        if byte != 0 {
            match self.buffer.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflowed = true,
            }
            return None;
        }
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflowed) {
            return Some(Err(FrameError::TooLong));
        }
        if len == 0 {
            return None;
        }
        self.buffer.get_mut(..len).map(Ok)
    }

    /// The buffer between two frames (no byte of the next one pushed yet): it still holds the
    /// frame [`push`] returned last, at its start, and a device may encode its reply over it (one
    /// frame buffer for both directions). The next [`push`] overwrites it; `None` while a frame
    /// is being collected.
    ///
    /// [`push`]: FrameReader::push
    pub fn spare(&mut self) -> Option<&mut [u8; N]> {
        (self.len == 0 && !self.overflowed).then_some(&mut self.buffer)
    }
}

#[cfg(test)]
mod tests;
