//! The link between `swg-host` and the joint firmware, shared by both ends.
//!
//! Every frame, in either direction, is
//!
//! ```text
//! COBS( postcard(protocol_version: u16, message) ++ CRC-32/ISO-HDLC(LE) ) 0x00
//! ```
//!
//! The host sends one [`Request`] and waits for one [`Response`]. The protocol version
//! leads the payload so that a peer speaking another version gets a clear
//! [`ErrorReply::UnsupportedProtocol`] instead of a garbled message.
#![no_std]

#[cfg(feature = "use-std")]
extern crate std;

use core::fmt;
use model_core::range::Culprit;
pub use model_core::{
    Direction, GearModel, ParamFault, ParamName, Params, SlipParams, MODEL_VERSION, SLIP_ELEMENTS, TURNING_POINTS,
};
use serde::{Deserialize, Serialize};

/// Version of this message set; bumped on any change to the encoding. Version 2: the model's
/// kind in [`JointParams::model`] (genetic or micro-slip), the evaluator's memory in
/// [`Feedforward`]. Version 3: the joint's torque controller ([`Request::Configure`],
/// [`Request::SetReference`], the lockstep [`Request::Control`] and their responses, the
/// error replies [`ErrorReply::InvalidGain`] and [`ErrorReply::MotorDrive`]). Version 4: the
/// controller's integral deadband and torsion damping in [`ControllerConfig`]. Version 5: an
/// error reply names a model parameter by model-core's [`ParamName`] ([`ParamField::Model`]);
/// [`JointParams::model`] is model-core's [`GearModel`], encoded as version 4's model was.
pub const PROTOCOL_VERSION: u16 = 5;

/// Largest encoded frame, delimiter included: the longest message (a micro-slip
/// [`Response::Params`] with every varint at its maximum) takes 109 bytes (tested), with room
/// to spare.
pub const MAX_FRAME_LEN: usize = 128;

/// Largest payload (version, message and CRC) before COBS encoding.
const MAX_PAYLOAD_LEN: usize = MAX_FRAME_LEN - 2;

const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
const CRC_LEN: usize = 4;

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

/// One lockstep control tick: both encoders' angles (as [`EncoderSample`]) and the joint
/// torque reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControlSample {
    /// Input (motor) side, rad, multi-turn.
    pub input_angle: f32,
    /// Output side, rad.
    pub output_angle: f32,
    /// T_ref, N·m at the joint.
    pub reference: f32,
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

/// Host → device.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    GetDeviceInfo,
    /// Validate and activate (between two ticks); not yet stored.
    WriteParams(JointParams),
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
}

/// Device → host, one per request.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Response {
    DeviceInfo(DeviceInfo),
    ParamsAccepted,
    /// `None` when the device has no valid parameters.
    Params(Option<JointParams>),
    /// Stored with this sequence number.
    Committed {
        sequence: u32,
    },
    Feedforward(Feedforward),
    Error(ErrorReply),
    /// A [`Request::Configure`] or [`Request::SetReference`] took effect.
    ControlAccepted,
    Control(ControlOutput),
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
    /// Writing flash failed.
    Storage,
    /// A replayed or lockstep control sample held NaN or infinity.
    NonFiniteSample,
    /// A controller configuration with a gain that is not finite or out of its range.
    InvalidGain {
        field: GainField,
        fault: ParamFault,
    },
    /// The board's motor drive refused the command (the tick's command was not applied).
    MotorDrive,
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
            ErrorReply::Storage => f.write_str("flash write failed"),
            ErrorReply::NonFiniteSample => f.write_str("encoder sample is not finite"),
            ErrorReply::InvalidGain { field, fault } => match fault {
                ParamFault::NotFinite => write!(f, "controller gain {field} is not finite"),
                ParamFault::OutOfRange => write!(f, "controller gain {field} is out of range"),
            },
            ErrorReply::MotorDrive => f.write_str("the motor drive refused the command"),
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
    /// Intact frame whose message does not decode.
    Message,
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
            FrameError::Message => f.write_str("frame holds no message of this protocol"),
            FrameError::BufferTooSmall => f.write_str("message does not fit the frame buffer"),
        }
    }
}

impl core::error::Error for FrameError {}

impl From<FrameError> for ErrorReply {
    fn from(error: FrameError) -> Self {
        match error {
            FrameError::Malformed | FrameError::BufferTooSmall => ErrorReply::BadFrame,
            FrameError::Crc => ErrorReply::BadCrc,
            FrameError::TooLong => ErrorReply::FrameTooLong,
            FrameError::Version(got) => ErrorReply::UnsupportedProtocol { got, supported: PROTOCOL_VERSION },
            FrameError::Message => ErrorReply::UndecodableRequest,
        }
    }
}

/// Encodes `message` as one frame into `out`, delimiter included; returns its length.
pub fn encode<T: Serialize>(message: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    encode_with_version(PROTOCOL_VERSION, message, out)
}

/// [`encode`] with an explicit protocol version, for tests of version handling.
pub fn encode_with_version<T: Serialize>(version: u16, message: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut payload = [0u8; MAX_PAYLOAD_LEN];
    let body_len = postcard::to_slice(&(version, message), &mut payload).map_err(|_| FrameError::BufferTooSmall)?.len();
    let crc = CRC.checksum(payload.get(..body_len).ok_or(FrameError::BufferTooSmall)?);
    let with_crc = body_len + CRC_LEN;
    payload.get_mut(body_len..with_crc).ok_or(FrameError::BufferTooSmall)?.copy_from_slice(&crc.to_le_bytes());
    let source = payload.get(..with_crc).ok_or(FrameError::BufferTooSmall)?;
    let encoded = cobs::try_encode(source, out).map_err(|_| FrameError::BufferTooSmall)?;
    *out.get_mut(encoded).ok_or(FrameError::BufferTooSmall)? = 0;
    Ok(encoded + 1)
}

/// Encodes `message` as one frame into a new vector, delimiter included.
#[cfg(feature = "use-std")]
pub fn encode_to_vec<T: Serialize>(message: &T) -> Result<std::vec::Vec<u8>, FrameError> {
    let mut out = [0u8; MAX_FRAME_LEN];
    let len = encode(message, &mut out)?;
    Ok(out.get(..len).ok_or(FrameError::BufferTooSmall)?.to_vec())
}

/// Decodes one frame (the bytes between two delimiters) in place.
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a mut [u8]) -> Result<T, FrameError> {
    let len = cobs::decode_in_place(frame).map_err(|_| FrameError::Malformed)?;
    let payload = frame.get(..len).ok_or(FrameError::Malformed)?;
    let body_len = len.checked_sub(CRC_LEN).filter(|&n| n > 0).ok_or(FrameError::Malformed)?;
    let (body, crc) = payload.split_at(body_len);
    if crc != CRC.checksum(body).to_le_bytes() {
        return Err(FrameError::Crc);
    }
    let (version, message) = postcard::take_from_bytes::<u16>(body).map_err(|_| FrameError::Message)?;
    if version != PROTOCOL_VERSION {
        return Err(FrameError::Version(version));
    }
    postcard::from_bytes(message).map_err(|_| FrameError::Message)
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
}

#[cfg(test)]
mod tests;
