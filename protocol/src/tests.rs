extern crate std;
use super::*;
use crate::experiment::{ExperimentState, RecordedSample, SampleBatch, StopReason, BATCH_SAMPLES};
use crate::plan::{Channel, Limits, Plan, Segment, PLAN_SEGMENTS};
use model_core::bouc_wen::{BoucWen, BoucWenTerm};
use model_core::preisach::Preisach;
use model_core::Hysteresis;
use std::{vec, vec::Vec};

fn params() -> JointParams {
    JointParams {
        model_version: MODEL_VERSION,
        model: GearModel::paper(Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 2.0, beta: -2.298, omega: 1.0 }),
        gear_ratio: 100.0,
        torque_limit: 50.0,
        direction_band: 2.0e-5,
    }
}

/// An id for tests that are not about ids.
const ID: RequestId = RequestId(77);

fn frame_of<T: Serialize>(message: &T) -> ([u8; MAX_FRAME_LEN], usize) {
    let mut out = [0u8; MAX_FRAME_LEN];
    let len = encode(ID, message, &mut out).unwrap();
    (out, len)
}

/// Decodes a whole frame as sent, delimiter included.
fn decode_sent<T: for<'a> Deserialize<'a>>(sent: &[u8]) -> Result<Envelope<T>, FrameError> {
    let (last, body) = sent.split_last().unwrap();
    assert_eq!(*last, 0, "frames end with the delimiter");
    let mut body = body.to_vec();
    decode(&mut body)
}

/// The message of a whole frame as sent, with the id tests use.
fn message_of<T: for<'a> Deserialize<'a>>(sent: &[u8]) -> Result<T, FrameError> {
    decode_sent(sent).map(|envelope| {
        assert_eq!(envelope.id, ID);
        envelope.message
    })
}

/// A spring with every field different: a polynomial part, five knots, its range; exact in f32.
fn distinct_spring(offset: f32) -> Spring<f32> {
    let knot = |x: f32, stiffness: f32| Knot { x: x / 1024.0, stiffness: stiffness + offset };
    let knots =
        [knot(-1.5, 15000.5), knot(-0.75, 9000.25), knot(0.0, 7000.75), knot(0.5, 8000.5), knot(1.25, 12000.25)];
    let mut spring = Spring::of_knots(&knots, [-1.75 / 1024.0, 1.5 / 1024.0]).unwrap();
    (spring.c1, spring.c2, spring.c3) = (150.5 + offset, 1.25e10, -3.0e14);
    spring
}

/// A genetic set with every field different, so that the golden frames fail if two fields trade
/// places (or encodings). All values are exact in f32.
fn distinct_params() -> JointParams {
    let paper = GearModel::paper(Params { c1: 0.0, c2: 0.0, c3: 0.0, alpha: 48.5, beta: -2.25, omega: 1.0 });
    JointParams {
        model_version: 1,
        model: GearModel { zero: -1.0 / 128.0, spring: distinct_spring(0.0), ..paper },
        gear_ratio: 100.0,
        torque_limit: 50.0,
        direction_band: 2.0e-5,
    }
}

/// A micro-slip set with every field different from every other (and from the genetic set's
/// joint fields), exact in f32: 16 elements, d_i = (2i + 3)/16384 rad (odd: none a knot's x),
/// k_i = 100·(i + 1) + 0.25.
fn distinct_slip_params() -> JointParams {
    let elements: Vec<SlipElement<f32>> = (0..SLIP_ELEMENTS)
        .map(|i| SlipElement { slip: (2 * i + 3) as f32 / 16384.0, stiffness: 100.0 * (i + 1) as f32 + 0.25 })
        .collect();
    JointParams {
        model_version: 1,
        model: GearModel::micro_slip(1.0 / 256.0, distinct_spring(0.125), &elements).unwrap(),
        gear_ratio: 80.0,
        torque_limit: 35.5,
        direction_band: 2.5e-6,
    }
}

/// A Bouc–Wen set with every field different from every other (and from the other sets' joint
/// fields), exact in f32: k_h 1350.5 N·m/rad, A 1.25, β 40960.5, γ 20480.25, n 1.5.
fn distinct_bouc_wen_params() -> JointParams {
    let shape = BoucWen { a: 1.25, beta: 40960.5, gamma: 20480.25, n: 1.5 };
    JointParams {
        model_version: 1,
        model: GearModel {
            zero: -3.0 / 1024.0,
            spring: distinct_spring(0.375),
            hysteresis: Hysteresis::BoucWen(BoucWenTerm { stiffness: 1350.5, shape }),
        },
        gear_ratio: 120.0,
        torque_limit: 42.25,
        direction_band: 1.0 / 65536.0,
    }
}

/// A Preisach set with every field different from every other (and from the other sets' joint
/// fields), exact in f32: reach 1.75/1024 rad, weight c = (2c + 1)/64 N·m.
fn distinct_preisach_params() -> JointParams {
    let weights = core::array::from_fn(|c| (2 * c + 1) as f32 / 64.0);
    JointParams {
        model_version: 1,
        model: GearModel {
            zero: 5.0 / 2048.0,
            spring: distinct_spring(0.625),
            hysteresis: Hysteresis::Preisach(Preisach { reach: 1.75 / 1024.0, weights }),
        },
        gear_ratio: 160.0,
        torque_limit: 27.75,
        direction_band: 1.0 / 32768.0,
    }
}

/// Every parameter of a set, model and joint, in order.
fn fields(params: &JointParams) -> Vec<f32> {
    let mut fields = Vec::new();
    params.model.map(|_, value| {
        fields.push(value);
        value
    });
    fields.extend([params.gear_ratio, params.torque_limit, params.direction_band]);
    fields
}

#[test]
fn the_distinct_sets_have_distinct_fields() {
    for set in [distinct_params(), distinct_slip_params(), distinct_bouc_wen_params(), distinct_preisach_params()] {
        let fields = fields(&set);
        for (i, a) in fields.iter().enumerate() {
            assert!(fields[i + 1..].iter().all(|b| a != b), "{fields:?}");
        }
        assert_eq!(JointParams { model_version: MODEL_VERSION, ..set }.validate(), Ok(()));
    }
}

/// Encodes `message` with `id` and compares the frame with `golden`, then decodes `golden` back.
fn assert_golden<T>(id: RequestId, message: T, golden: &[u8])
where
    T: Serialize + for<'a> Deserialize<'a> + PartialEq + core::fmt::Debug,
{
    let mut out = [0u8; MAX_FRAME_LEN];
    let len = encode(id, &message, &mut out).unwrap();
    assert_eq!(&out[..len], golden, "{message:?}");
    assert_eq!(decode_sent::<T>(golden), Ok(Envelope { id, message }));
}

/// The variant of a request, by exhaustive match: a new variant fails to compile here
/// until it has a golden frame below.
fn request_variant(request: &Request) -> usize {
    match request {
        Request::GetDeviceInfo => 0,
        Request::WriteParams(_) => 1,
        Request::ReadParams => 2,
        Request::Commit => 3,
        Request::Replay(_) => 4,
        Request::Configure(_) => 5,
        Request::SetReference(_) => 6,
        Request::Control(_) => 7,
        Request::GetStatus => 8,
        Request::StartExperiment(_) => 9,
        Request::FetchSamples => 10,
        Request::StopExperiment => 11,
    }
}

fn response_variant(response: &Response) -> usize {
    match response {
        Response::DeviceInfo(_) => 0,
        Response::ParamsAccepted => 1,
        Response::Params(_) => 2,
        Response::Committed(_) => 3,
        Response::Feedforward(_) => 4,
        Response::Error(_) => 5,
        Response::ControlAccepted => 6,
        Response::Control(_) => 7,
        Response::Status(_) => 8,
        Response::ExperimentStarted(_) => 9,
        Response::Samples(_) => 10,
    }
}

fn error_variant(error: &ErrorReply) -> usize {
    match error {
        ErrorReply::BadFrame => 0,
        ErrorReply::BadCrc => 1,
        ErrorReply::FrameTooLong => 2,
        ErrorReply::UnsupportedProtocol { .. } => 3,
        ErrorReply::UndecodableRequest => 4,
        ErrorReply::ModelVersion { .. } => 5,
        ErrorReply::InvalidParam { .. } => 6,
        ErrorReply::ModelOverflow => 7,
        ErrorReply::NoParams => 8,
        ErrorReply::Storage(_) => 9,
        ErrorReply::NonFiniteSample => 10,
        ErrorReply::InvalidGain { .. } => 11,
        ErrorReply::MotorDrive(_) => 12,
        ErrorReply::CommitWhileDriving => 13,
        ErrorReply::NotLockstep => 14,
        ErrorReply::Busy => 15,
        ErrorReply::InvalidPlan => 16,
        ErrorReply::ControllerOff => 17,
        ErrorReply::ExperimentRunning => 18,
    }
}

/// The variants in `cases` are exactly 0..n, each once.
fn covers_every_variant<T>(cases: &[(RequestId, T, &[u8])], variant: fn(&T) -> usize, n: usize) {
    let mut seen: Vec<usize> = cases.iter().map(|(_, message, _)| variant(message)).collect();
    seen.sort_unstable();
    seen.dedup();
    assert_eq!(seen, (0..n).collect::<Vec<_>>());
}

// The encoding is the contract with deployed firmware: these bytes must not change without a
// new PROTOCOL_VERSION. Each frame is COBS(payload ++ CRC-32 LE) 0x00, where the payload is
// postcard: varint protocol version (9), varint request id, varint variant index, then the
// fields in order (u16/u32 as varints, f32 as 4 bytes little-endian, enums as varint index
// followed by their fields, Option as 0/1, arrays element by element without a length). The
// comments give the payload after version and id; COBS replaces each 0x00 by the distance to
// the next one and leads with the distance to the first. Every frame has its own request id,
// of one to five varint bytes.
//
// One frame checked by hand, Request::GetDeviceInfo with id 1: the payload is 09 | 01 | 00,
// its CRC-32/ISO-HDLC is 0xe98b_d3dc (`python3 -c 'import zlib; print(hex(zlib.crc32(bytes([9, 1, 0]))))'`),
// little-endian dc d3 8b e9, so COBS(09 01 00 dc d3 8b e9) = 03 09 01 | 05 dc d3 8b e9 (each
// code byte the distance to the next zero, the last to the end) and the delimiter 00.
//
// The genetic set's payload (distinct_params(), f32 big-endian here, little-endian on the wire):
//   model_version 01 | Genetic 00 | zero -2⁻⁷ = bc000000 | spring: c1 150.5 = 43168000 |
//   c2 1.25e10 = 503a43b7 | c3 -3e14 = d7886c99 | 5 knots 05: x -1.5/1024 = bac00000,
//   k 15000.5 = 466a6200, … | range -1.75/1024 = bae00000, 1.5/1024 = 3ac00000 |
//   alpha 48.5 = 42420000 | beta -2.25 = c0100000 | omega 1 = 3f800000 |
//   gear_ratio 100 = 42c80000 | torque_limit 50 = 42480000 | direction_band 2e-5 = 37a7c5ac
// The micro-slip set's (distinct_slip_params()):
//   model_version 01 | MicroSlip 01 | zero 2⁻⁸ = 3b800000 | the spring (c1 150.625, knots' k + 0.125) |
//   16 elements 10: slip 3/16384 = 39400000, k 100.25 = 42c88000, … slip 33/16384 = 3b040000,
//   k 1600.25 = 44c80800 | gear_ratio 80 = 42a00000 | torque_limit 35.5 = 420e0000 |
//   direction_band 2.5e-6 = 3627c5ac
// The Bouc–Wen set's (distinct_bouc_wen_params()):
//   model_version 01 | BoucWen 02 | zero -3/1024 = bb400000 | the spring (c1 150.875, knots' k + 0.375) |
//   k_h 1350.5 = 44a8d000 | A 1.25 = 3fa00000 | β 40960.5 = 47200080 | γ 20480.25 = 46a00080 |
//   n 1.5 = 3fc00000 | gear_ratio 120 = 42f00000 | torque_limit 42.25 = 42290000 |
//   direction_band 2⁻¹⁶ = 37800000
// The Preisach set's (distinct_preisach_params()):
//   model_version 01 | Preisach 03 | zero 5/2048 = 3b200000 | the spring (c1 151.125, knots' k + 0.625) |
//   reach 1.75/1024 = 3ae00000 | 36 weights (2c + 1)/64: 1/64 = 3c800000, 3/64 = 3d400000, …,
//   71/64 = 3f8e0000 | gear_ratio 160 = 43200000 | torque_limit 27.75 = 41de0000 |
//   direction_band 2⁻¹⁵ = 38000000

/// A plan with every field different, exact in f32: a ramp, a sine and a hold with dither.
fn distinct_plan() -> Plan {
    let limits = Limits { torque_nm: 40.5, deflection_rad: 0.0078125 };
    let segments = [
        Segment::Ramp { to: 2.5, seconds: 0.75 },
        Segment::Sine { amplitude: 1.25, frequency_hz: 2.0, cycles: 300 },
        Segment::Hold { seconds: 3.5, dither_amplitude: 0.375, dither_hz: 8.0 },
    ];
    Plan::new(Channel::Torque, limits, 1000.0, &segments).unwrap()
}

/// A batch with every field different, exact in f32: one sample with a temperature, one without.
fn distinct_batch() -> SampleBatch {
    let mut samples = heapless::Vec::new();
    let first = RecordedSample { input_angle: 6.5, output_angle: -0.0625, torque: 12.25, temperature: Some(31.5) };
    let second = RecordedSample { input_angle: 6.75, output_angle: -0.03125, torque: -3.5, temperature: None };
    samples.extend_from_slice(&[first, second]).unwrap();
    SampleBatch {
        sequence: 300,
        first_tick: 4800,
        dropped: 7,
        high_water: 29,
        state: ExperimentState::Running { segment: 2 },
        samples,
    }
}

/// A controller configuration with every field different, exact in f32.
const DISTINCT_CONFIG: ControllerConfig = ControllerConfig {
    mode: ControlMode::Model,
    kp: 0.0625,
    ki: 2.5,
    integral_deadband: 0.125,
    damping: 0.0078125,
    torsion_damping: 0.03125,
    stiffness: 16384.0,
    command_limit: 0.75,
    period: 0.0009765625,
};

#[test]
fn golden_requests() {
    let cases: [(RequestId, Request, &[u8]); 15] = [
        // id 1 | 00 (checked by hand above)
        (RequestId(1), Request::GetDeviceInfo, &[0x03, 0x09, 0x01, 0x05, 0xdc, 0xd3, 0x8b, 0xe9, 0x00]),
        (
            // id 300 = ac 02 | 01 | the genetic set
            RequestId(300),
            Request::WriteParams(distinct_params()),
            &[
                0x06, 0x09, 0xac, 0x02, 0x01, 0x01, 0x01, 0x01, 0x01, 0x02, 0xbc, 0x0d, 0x80, 0x16, 0x43, 0xb7, 0x43,
                0x3a, 0x50, 0x99, 0x6c, 0x88, 0xd7, 0x05, 0x01, 0x03, 0xc0, 0xba, 0x04, 0x62, 0x6a, 0x46, 0x01, 0x03,
                0x40, 0xba, 0x04, 0xa1, 0x0c, 0x46, 0x01, 0x01, 0x01, 0x01, 0x04, 0xc6, 0xda, 0x45, 0x01, 0x01, 0x02,
                0x3a, 0x04, 0x04, 0xfa, 0x45, 0x01, 0x03, 0xa0, 0x3a, 0x04, 0x81, 0x3b, 0x46, 0x01, 0x03, 0xe0, 0xba,
                0x01, 0x03, 0xc0, 0x3a, 0x01, 0x03, 0x42, 0x42, 0x01, 0x03, 0x10, 0xc0, 0x01, 0x03, 0x80, 0x3f, 0x01,
                0x03, 0xc8, 0x42, 0x01, 0x0b, 0x48, 0x42, 0xac, 0xc5, 0xa7, 0x37, 0xf0, 0x23, 0xca, 0x57, 0x00,
            ],
        ),
        (
            // id 70000 = f0 a2 04 | 01 | the Bouc–Wen set
            RequestId(70_000),
            Request::WriteParams(distinct_bouc_wen_params()),
            &[
                0x08, 0x09, 0xf0, 0xa2, 0x04, 0x01, 0x01, 0x02, 0x01, 0x03, 0x40, 0xbb, 0x0d, 0xe0, 0x16, 0x43, 0xb7,
                0x43, 0x3a, 0x50, 0x99, 0x6c, 0x88, 0xd7, 0x05, 0x01, 0x07, 0xc0, 0xba, 0x80, 0x63, 0x6a, 0x46, 0x01,
                0x07, 0x40, 0xba, 0x80, 0xa2, 0x0c, 0x46, 0x01, 0x01, 0x01, 0x01, 0x04, 0xc9, 0xda, 0x45, 0x01, 0x01,
                0x02, 0x3a, 0x04, 0x07, 0xfa, 0x45, 0x01, 0x07, 0xa0, 0x3a, 0x80, 0x82, 0x3b, 0x46, 0x01, 0x03, 0xe0,
                0xba, 0x01, 0x03, 0xc0, 0x3a, 0x04, 0xd0, 0xa8, 0x44, 0x01, 0x04, 0xa0, 0x3f, 0x80, 0x04, 0x20, 0x47,
                0x80, 0x03, 0xa0, 0x46, 0x01, 0x03, 0xc0, 0x3f, 0x01, 0x03, 0xf0, 0x42, 0x01, 0x03, 0x29, 0x42, 0x01,
                0x07, 0x80, 0x37, 0xa9, 0x6f, 0x11, 0xfd, 0x00,
            ],
        ),
        (
            // id 0x4000 = 80 80 01 | 01 | the micro-slip set
            RequestId(0x4000),
            Request::WriteParams(distinct_slip_params()),
            &[
                0x08, 0x09, 0x80, 0x80, 0x01, 0x01, 0x01, 0x01, 0x01, 0x03, 0x80, 0x3b, 0x0d, 0xa0, 0x16, 0x43, 0xb7,
                0x43, 0x3a, 0x50, 0x99, 0x6c, 0x88, 0xd7, 0x05, 0x01, 0x07, 0xc0, 0xba, 0x80, 0x62, 0x6a, 0x46, 0x01,
                0x07, 0x40, 0xba, 0x80, 0xa1, 0x0c, 0x46, 0x01, 0x01, 0x01, 0x01, 0x04, 0xc7, 0xda, 0x45, 0x01, 0x01,
                0x02, 0x3a, 0x04, 0x05, 0xfa, 0x45, 0x01, 0x07, 0xa0, 0x3a, 0x80, 0x81, 0x3b, 0x46, 0x01, 0x03, 0xe0,
                0xba, 0x01, 0x04, 0xc0, 0x3a, 0x10, 0x01, 0x03, 0x40, 0x39, 0x04, 0x80, 0xc8, 0x42, 0x01, 0x03, 0xa0,
                0x39, 0x04, 0x40, 0x48, 0x43, 0x01, 0x03, 0xe0, 0x39, 0x04, 0x20, 0x96, 0x43, 0x01, 0x03, 0x10, 0x3a,
                0x04, 0x20, 0xc8, 0x43, 0x01, 0x03, 0x30, 0x3a, 0x04, 0x20, 0xfa, 0x43, 0x01, 0x03, 0x50, 0x3a, 0x04,
                0x10, 0x16, 0x44, 0x01, 0x03, 0x70, 0x3a, 0x04, 0x10, 0x2f, 0x44, 0x01, 0x03, 0x88, 0x3a, 0x04, 0x10,
                0x48, 0x44, 0x01, 0x03, 0x98, 0x3a, 0x04, 0x10, 0x61, 0x44, 0x01, 0x03, 0xa8, 0x3a, 0x04, 0x10, 0x7a,
                0x44, 0x01, 0x03, 0xb8, 0x3a, 0x04, 0x88, 0x89, 0x44, 0x01, 0x03, 0xc8, 0x3a, 0x04, 0x08, 0x96, 0x44,
                0x01, 0x03, 0xd8, 0x3a, 0x04, 0x88, 0xa2, 0x44, 0x01, 0x03, 0xe8, 0x3a, 0x04, 0x08, 0xaf, 0x44, 0x01,
                0x03, 0xf8, 0x3a, 0x04, 0x88, 0xbb, 0x44, 0x01, 0x03, 0x04, 0x3b, 0x04, 0x08, 0xc8, 0x44, 0x01, 0x03,
                0xa0, 0x42, 0x01, 0x0b, 0x0e, 0x42, 0xac, 0xc5, 0x27, 0x36, 0x2e, 0x2a, 0xc4, 0x6a, 0x00,
            ],
        ),
        (
            // id 0x300000 = 80 80 c0 01 | 01 | the Preisach set
            RequestId(0x30_0000),
            Request::WriteParams(distinct_preisach_params()),
            &[
                0x09, 0x09, 0x80, 0x80, 0xc0, 0x01, 0x01, 0x01, 0x03, 0x01, 0x03, 0x20, 0x3b, 0x0d, 0x20, 0x17, 0x43,
                0xb7, 0x43, 0x3a, 0x50, 0x99, 0x6c, 0x88, 0xd7, 0x05, 0x01, 0x07, 0xc0, 0xba, 0x80, 0x64, 0x6a, 0x46,
                0x01, 0x07, 0x40, 0xba, 0x80, 0xa3, 0x0c, 0x46, 0x01, 0x01, 0x01, 0x01, 0x04, 0xcb, 0xda, 0x45, 0x01,
                0x01, 0x02, 0x3a, 0x04, 0x09, 0xfa, 0x45, 0x01, 0x07, 0xa0, 0x3a, 0x80, 0x83, 0x3b, 0x46, 0x01, 0x03,
                0xe0, 0xba, 0x01, 0x03, 0xc0, 0x3a, 0x01, 0x03, 0xe0, 0x3a, 0x01, 0x03, 0x80, 0x3c, 0x01, 0x03, 0x40,
                0x3d, 0x01, 0x03, 0xa0, 0x3d, 0x01, 0x03, 0xe0, 0x3d, 0x01, 0x03, 0x10, 0x3e, 0x01, 0x03, 0x30, 0x3e,
                0x01, 0x03, 0x50, 0x3e, 0x01, 0x03, 0x70, 0x3e, 0x01, 0x03, 0x88, 0x3e, 0x01, 0x03, 0x98, 0x3e, 0x01,
                0x03, 0xa8, 0x3e, 0x01, 0x03, 0xb8, 0x3e, 0x01, 0x03, 0xc8, 0x3e, 0x01, 0x03, 0xd8, 0x3e, 0x01, 0x03,
                0xe8, 0x3e, 0x01, 0x03, 0xf8, 0x3e, 0x01, 0x03, 0x04, 0x3f, 0x01, 0x03, 0x0c, 0x3f, 0x01, 0x03, 0x14,
                0x3f, 0x01, 0x03, 0x1c, 0x3f, 0x01, 0x03, 0x24, 0x3f, 0x01, 0x03, 0x2c, 0x3f, 0x01, 0x03, 0x34, 0x3f,
                0x01, 0x03, 0x3c, 0x3f, 0x01, 0x03, 0x44, 0x3f, 0x01, 0x03, 0x4c, 0x3f, 0x01, 0x03, 0x54, 0x3f, 0x01,
                0x03, 0x5c, 0x3f, 0x01, 0x03, 0x64, 0x3f, 0x01, 0x03, 0x6c, 0x3f, 0x01, 0x03, 0x74, 0x3f, 0x01, 0x03,
                0x7c, 0x3f, 0x01, 0x03, 0x82, 0x3f, 0x01, 0x03, 0x86, 0x3f, 0x01, 0x03, 0x8a, 0x3f, 0x01, 0x03, 0x8e,
                0x3f, 0x01, 0x03, 0x20, 0x43, 0x01, 0x03, 0xde, 0x41, 0x01, 0x01, 0x06, 0x38, 0x7e, 0x3f, 0xc3, 0x5f,
                0x00,
            ],
        ),
        // id 2 | 02
        (RequestId(2), Request::ReadParams, &[0x08, 0x09, 0x02, 0x02, 0x33, 0xe1, 0xa8, 0x2c, 0x00]),
        // id u32::MAX = ff ff ff ff 0f | 03
        (
            RequestId(u32::MAX),
            Request::Commit,
            &[0x0c, 0x09, 0xff, 0xff, 0xff, 0xff, 0x0f, 0x03, 0x84, 0x89, 0x58, 0x58, 0x00],
        ),
        (
            // id 0x12345678 = f8 ac d1 91 01 | 04 | input_angle 1 = 3f800000 |
            // output_angle -0.5 = bf000000 | Fast 01
            RequestId(0x1234_5678),
            Request::Replay(EncoderSample { input_angle: 1.0, output_angle: -0.5, path: EvalPath::Fast }),
            &[
                0x08, 0x09, 0xf8, 0xac, 0xd1, 0x91, 0x01, 0x04, 0x01, 0x03, 0x80, 0x3f, 0x01, 0x01, 0x07, 0xbf, 0x01,
                0x4d, 0x02, 0x79, 0xf0, 0x00,
            ],
        ),
        (
            // id 127 = 7f | 05 | Model 03 | kp 0.0625 = 3d800000 | ki 2.5 = 40200000 |
            // integral_deadband 0.125 = 3e000000 | damping 2⁻⁷ = 3c000000 |
            // torsion_damping 2⁻⁵ = 3d000000 | stiffness 16384 = 46800000 |
            // command_limit 0.75 = 3f400000 | period 2⁻¹⁰ = 3a800000
            RequestId(127),
            Request::Configure(DISTINCT_CONFIG),
            &[
                0x05, 0x09, 0x7f, 0x05, 0x03, 0x01, 0x03, 0x80, 0x3d, 0x01, 0x03, 0x20, 0x40, 0x01, 0x01, 0x02, 0x3e,
                0x01, 0x01, 0x02, 0x3c, 0x01, 0x01, 0x02, 0x3d, 0x01, 0x03, 0x80, 0x46, 0x01, 0x03, 0x40, 0x3f, 0x01,
                0x07, 0x80, 0x3a, 0x15, 0x2e, 0xf1, 0x29, 0x00,
            ],
        ),
        (
            // id 128 = 80 01 | 06 | -7.25 = c0e80000
            RequestId(128),
            Request::SetReference(-7.25),
            &[0x05, 0x09, 0x80, 0x01, 0x06, 0x01, 0x07, 0xe8, 0xc0, 0xe1, 0xb3, 0xa4, 0xbb, 0x00],
        ),
        (
            // id 65535 = ff ff 03 | 07 | input_angle 12.5 = 41480000 | output_angle -0.375 = bec00000 |
            // reference 8.75 = 410c0000 | torque -1.5 = bfc00000 | temperature Some 01, 36.5 = 42120000
            RequestId(65_535),
            Request::Control(ControlSample {
                input_angle: 12.5,
                output_angle: -0.375,
                reference: 8.75,
                torque: -1.5,
                temperature: Some(36.5),
            }),
            &[
                0x06, 0x09, 0xff, 0xff, 0x03, 0x07, 0x01, 0x03, 0x48, 0x41, 0x01, 0x03, 0xc0, 0xbe, 0x01, 0x03, 0x0c,
                0x41, 0x01, 0x04, 0xc0, 0xbf, 0x01, 0x01, 0x07, 0x12, 0x42, 0x43, 0xe0, 0xdd, 0xec, 0x00,
            ],
        ),
        // id 9 | 08
        (RequestId(9), Request::GetStatus, &[0x08, 0x09, 0x09, 0x08, 0xe6, 0xd1, 0x89, 0x2f, 0x00]),
        (
            // id 10 | 09 | Torque 01 | limits 40.5 = 42220000, 0.0078125 = 3c000000 | rate 1000 = 447a0000 |
            // 12 segments: Ramp 00 2.5 = 40200000 0.75 = 3f400000 | Sine 01 1.25 = 3fa00000
            // 2 = 40000000 cycles 300 = ac 02 | Hold 02 3.5 = 40600000 0.375 = 3ec00000 8 = 41000000 |
            // 9 × the unused Ramp 00 0 0 | count 03
            RequestId(10),
            Request::StartExperiment(distinct_plan()),
            &[
                0x05, 0x09, 0x0a, 0x09, 0x01, 0x01, 0x03, 0x22, 0x42, 0x01, 0x01, 0x02, 0x3c, 0x01, 0x03, 0x7a, 0x44,
                0x01, 0x01, 0x03, 0x20, 0x40, 0x01, 0x04, 0x40, 0x3f, 0x01, 0x01, 0x03, 0xa0, 0x3f, 0x01, 0x01, 0x05,
                0x40, 0xac, 0x02, 0x02, 0x01, 0x03, 0x60, 0x40, 0x01, 0x03, 0xc0, 0x3e, 0x01, 0x01, 0x02, 0x41, 0x01,
                0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01,
                0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01,
                0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01,
                0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01,
                0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x01, 0x06, 0x03, 0x6c, 0xf7, 0xe7, 0x9a,
                0x00,
            ],
        ),
        // id 11 | 0a
        (RequestId(11), Request::FetchSamples, &[0x08, 0x09, 0x0b, 0x0a, 0x48, 0xd2, 0xb1, 0xf3, 0x00]),
        // id 12 | 0b
        (RequestId(12), Request::StopExperiment, &[0x08, 0x09, 0x0c, 0x0b, 0x19, 0x74, 0xf7, 0xcb, 0x00]),
    ];
    covers_every_variant(&cases, request_variant, 12);
    for (id, request, golden) in cases {
        assert_golden(id, request, golden);
    }
}

#[test]
fn golden_responses() {
    let cases: [(RequestId, Response, &[u8]); 16] = [
        (
            // id 3 | 00 | 0.1.2 = 00 01 02 | protocol_version 300 = ac 02 | model_version 07
            RequestId(3),
            Response::DeviceInfo(DeviceInfo {
                firmware_version: Version { major: 0, minor: 1, patch: 2 },
                protocol_version: 300,
                model_version: 7,
            }),
            &[0x03, 0x09, 0x03, 0x01, 0x0a, 0x01, 0x02, 0xac, 0x02, 0x07, 0x08, 0x17, 0x7c, 0x2f, 0x00],
        ),
        // id 4 | 01
        (RequestId(4), Response::ParamsAccepted, &[0x08, 0x09, 0x04, 0x01, 0x0f, 0x17, 0xfb, 0xe3, 0x00]),
        (
            // id 1000 = e8 07 | 02 | Some 01 | the genetic set
            RequestId(1000),
            Response::Params(Some(distinct_params())),
            &[
                0x07, 0x09, 0xe8, 0x07, 0x02, 0x01, 0x01, 0x01, 0x01, 0x01, 0x02, 0xbc, 0x0d, 0x80, 0x16, 0x43, 0xb7,
                0x43, 0x3a, 0x50, 0x99, 0x6c, 0x88, 0xd7, 0x05, 0x01, 0x03, 0xc0, 0xba, 0x04, 0x62, 0x6a, 0x46, 0x01,
                0x03, 0x40, 0xba, 0x04, 0xa1, 0x0c, 0x46, 0x01, 0x01, 0x01, 0x01, 0x04, 0xc6, 0xda, 0x45, 0x01, 0x01,
                0x02, 0x3a, 0x04, 0x04, 0xfa, 0x45, 0x01, 0x03, 0xa0, 0x3a, 0x04, 0x81, 0x3b, 0x46, 0x01, 0x03, 0xe0,
                0xba, 0x01, 0x03, 0xc0, 0x3a, 0x01, 0x03, 0x42, 0x42, 0x01, 0x03, 0x10, 0xc0, 0x01, 0x03, 0x80, 0x3f,
                0x01, 0x03, 0xc8, 0x42, 0x01, 0x0b, 0x48, 0x42, 0xac, 0xc5, 0xa7, 0x37, 0x9c, 0xb8, 0x65, 0x42, 0x00,
            ],
        ),
        (
            // id 500 = f4 03 | 02 | Some 01 | the Bouc–Wen set
            RequestId(500),
            Response::Params(Some(distinct_bouc_wen_params())),
            &[
                0x08, 0x09, 0xf4, 0x03, 0x02, 0x01, 0x01, 0x02, 0x01, 0x03, 0x40, 0xbb, 0x0d, 0xe0, 0x16, 0x43, 0xb7,
                0x43, 0x3a, 0x50, 0x99, 0x6c, 0x88, 0xd7, 0x05, 0x01, 0x07, 0xc0, 0xba, 0x80, 0x63, 0x6a, 0x46, 0x01,
                0x07, 0x40, 0xba, 0x80, 0xa2, 0x0c, 0x46, 0x01, 0x01, 0x01, 0x01, 0x04, 0xc9, 0xda, 0x45, 0x01, 0x01,
                0x02, 0x3a, 0x04, 0x07, 0xfa, 0x45, 0x01, 0x07, 0xa0, 0x3a, 0x80, 0x82, 0x3b, 0x46, 0x01, 0x03, 0xe0,
                0xba, 0x01, 0x03, 0xc0, 0x3a, 0x04, 0xd0, 0xa8, 0x44, 0x01, 0x04, 0xa0, 0x3f, 0x80, 0x04, 0x20, 0x47,
                0x80, 0x03, 0xa0, 0x46, 0x01, 0x03, 0xc0, 0x3f, 0x01, 0x03, 0xf0, 0x42, 0x01, 0x03, 0x29, 0x42, 0x01,
                0x07, 0x80, 0x37, 0x88, 0x45, 0xc1, 0xe3, 0x00,
            ],
        ),
        (
            // id 501 = f5 03 | 02 | Some 01 | the Preisach set
            RequestId(501),
            Response::Params(Some(distinct_preisach_params())),
            &[
                0x08, 0x09, 0xf5, 0x03, 0x02, 0x01, 0x01, 0x03, 0x01, 0x03, 0x20, 0x3b, 0x0d, 0x20, 0x17, 0x43, 0xb7,
                0x43, 0x3a, 0x50, 0x99, 0x6c, 0x88, 0xd7, 0x05, 0x01, 0x07, 0xc0, 0xba, 0x80, 0x64, 0x6a, 0x46, 0x01,
                0x07, 0x40, 0xba, 0x80, 0xa3, 0x0c, 0x46, 0x01, 0x01, 0x01, 0x01, 0x04, 0xcb, 0xda, 0x45, 0x01, 0x01,
                0x02, 0x3a, 0x04, 0x09, 0xfa, 0x45, 0x01, 0x07, 0xa0, 0x3a, 0x80, 0x83, 0x3b, 0x46, 0x01, 0x03, 0xe0,
                0xba, 0x01, 0x03, 0xc0, 0x3a, 0x01, 0x03, 0xe0, 0x3a, 0x01, 0x03, 0x80, 0x3c, 0x01, 0x03, 0x40, 0x3d,
                0x01, 0x03, 0xa0, 0x3d, 0x01, 0x03, 0xe0, 0x3d, 0x01, 0x03, 0x10, 0x3e, 0x01, 0x03, 0x30, 0x3e, 0x01,
                0x03, 0x50, 0x3e, 0x01, 0x03, 0x70, 0x3e, 0x01, 0x03, 0x88, 0x3e, 0x01, 0x03, 0x98, 0x3e, 0x01, 0x03,
                0xa8, 0x3e, 0x01, 0x03, 0xb8, 0x3e, 0x01, 0x03, 0xc8, 0x3e, 0x01, 0x03, 0xd8, 0x3e, 0x01, 0x03, 0xe8,
                0x3e, 0x01, 0x03, 0xf8, 0x3e, 0x01, 0x03, 0x04, 0x3f, 0x01, 0x03, 0x0c, 0x3f, 0x01, 0x03, 0x14, 0x3f,
                0x01, 0x03, 0x1c, 0x3f, 0x01, 0x03, 0x24, 0x3f, 0x01, 0x03, 0x2c, 0x3f, 0x01, 0x03, 0x34, 0x3f, 0x01,
                0x03, 0x3c, 0x3f, 0x01, 0x03, 0x44, 0x3f, 0x01, 0x03, 0x4c, 0x3f, 0x01, 0x03, 0x54, 0x3f, 0x01, 0x03,
                0x5c, 0x3f, 0x01, 0x03, 0x64, 0x3f, 0x01, 0x03, 0x6c, 0x3f, 0x01, 0x03, 0x74, 0x3f, 0x01, 0x03, 0x7c,
                0x3f, 0x01, 0x03, 0x82, 0x3f, 0x01, 0x03, 0x86, 0x3f, 0x01, 0x03, 0x8a, 0x3f, 0x01, 0x03, 0x8e, 0x3f,
                0x01, 0x03, 0x20, 0x43, 0x01, 0x03, 0xde, 0x41, 0x01, 0x01, 0x02, 0x38, 0x04, 0x34, 0x80, 0x5a, 0x00,
            ],
        ),
        (
            // id 0x200000 = 80 80 80 01 | 02 | Some 01 | the micro-slip set
            RequestId(0x20_0000),
            Response::Params(Some(distinct_slip_params())),
            &[
                0x0a, 0x09, 0x80, 0x80, 0x80, 0x01, 0x02, 0x01, 0x01, 0x01, 0x01, 0x03, 0x80, 0x3b, 0x0d, 0xa0, 0x16,
                0x43, 0xb7, 0x43, 0x3a, 0x50, 0x99, 0x6c, 0x88, 0xd7, 0x05, 0x01, 0x07, 0xc0, 0xba, 0x80, 0x62, 0x6a,
                0x46, 0x01, 0x07, 0x40, 0xba, 0x80, 0xa1, 0x0c, 0x46, 0x01, 0x01, 0x01, 0x01, 0x04, 0xc7, 0xda, 0x45,
                0x01, 0x01, 0x02, 0x3a, 0x04, 0x05, 0xfa, 0x45, 0x01, 0x07, 0xa0, 0x3a, 0x80, 0x81, 0x3b, 0x46, 0x01,
                0x03, 0xe0, 0xba, 0x01, 0x04, 0xc0, 0x3a, 0x10, 0x01, 0x03, 0x40, 0x39, 0x04, 0x80, 0xc8, 0x42, 0x01,
                0x03, 0xa0, 0x39, 0x04, 0x40, 0x48, 0x43, 0x01, 0x03, 0xe0, 0x39, 0x04, 0x20, 0x96, 0x43, 0x01, 0x03,
                0x10, 0x3a, 0x04, 0x20, 0xc8, 0x43, 0x01, 0x03, 0x30, 0x3a, 0x04, 0x20, 0xfa, 0x43, 0x01, 0x03, 0x50,
                0x3a, 0x04, 0x10, 0x16, 0x44, 0x01, 0x03, 0x70, 0x3a, 0x04, 0x10, 0x2f, 0x44, 0x01, 0x03, 0x88, 0x3a,
                0x04, 0x10, 0x48, 0x44, 0x01, 0x03, 0x98, 0x3a, 0x04, 0x10, 0x61, 0x44, 0x01, 0x03, 0xa8, 0x3a, 0x04,
                0x10, 0x7a, 0x44, 0x01, 0x03, 0xb8, 0x3a, 0x04, 0x88, 0x89, 0x44, 0x01, 0x03, 0xc8, 0x3a, 0x04, 0x08,
                0x96, 0x44, 0x01, 0x03, 0xd8, 0x3a, 0x04, 0x88, 0xa2, 0x44, 0x01, 0x03, 0xe8, 0x3a, 0x04, 0x08, 0xaf,
                0x44, 0x01, 0x03, 0xf8, 0x3a, 0x04, 0x88, 0xbb, 0x44, 0x01, 0x03, 0x04, 0x3b, 0x04, 0x08, 0xc8, 0x44,
                0x01, 0x03, 0xa0, 0x42, 0x01, 0x0b, 0x0e, 0x42, 0xac, 0xc5, 0x27, 0x36, 0x07, 0x4c, 0x5b, 0x85, 0x00,
            ],
        ),
        // id 5 | 02 | None 00
        (RequestId(5), Response::Params(None), &[0x04, 0x09, 0x05, 0x02, 0x05, 0xff, 0x30, 0xb1, 0x68, 0x00]),
        (
            // id 6 | 03 | sequence 0x12345678 = f8 ac d1 91 01
            RequestId(6),
            Response::Committed(0x1234_5678),
            &[0x0d, 0x09, 0x06, 0x03, 0xf8, 0xac, 0xd1, 0x91, 0x01, 0x3d, 0xea, 0xc6, 0x73, 0x00],
        ),
        (
            // id 0xfedcba98 = 98 f5 f2 f6 0f | 04 | deflection -2⁻¹⁰ = ba800000 | torque -12.5 = c1480000 |
            // stiffness 4e4 = 471c4000 | Clamped 01 | Some 01 Falling 01 | memory 03
            RequestId(0xfedc_ba98),
            Response::Feedforward(Feedforward {
                deflection: -0.0009765625,
                torque: -12.5,
                stiffness: 40000.0,
                compensation: Compensation::Clamped,
                direction: Some(Direction::Falling),
                memory: 3,
            }),
            &[
                0x08, 0x09, 0x98, 0xf5, 0xf2, 0xf6, 0x0f, 0x04, 0x01, 0x03, 0x80, 0xba, 0x01, 0x03, 0x48, 0xc1, 0x0c,
                0x40, 0x1c, 0x47, 0x01, 0x01, 0x01, 0x03, 0xfb, 0x13, 0xa9, 0x6a, 0x00,
            ],
        ),
        (
            // id 10 | 04 | deflection 2⁻¹¹ = 3a000000 | torque 6.75 = 40d80000 |
            // stiffness 1.2e4 = 463b8000 | Active 00 | None 00 | memory 0b
            RequestId(10),
            Response::Feedforward(Feedforward {
                deflection: 0.00048828125,
                torque: 6.75,
                stiffness: 12000.0,
                compensation: Compensation::Active,
                direction: None,
                memory: 11,
            }),
            &[
                0x04, 0x09, 0x0a, 0x04, 0x01, 0x01, 0x02, 0x3a, 0x01, 0x03, 0xd8, 0x40, 0x04, 0x80, 0x3b, 0x46, 0x01,
                0x06, 0x0b, 0xf1, 0xf8, 0xb5, 0xe0, 0x00,
            ],
        ),
        (
            // id 11 | 05 | UnsupportedProtocol 03 | got 07 | supported 02
            RequestId(11),
            Response::Error(ErrorReply::UnsupportedProtocol { got: 7, supported: 2 }),
            &[0x0b, 0x09, 0x0b, 0x05, 0x03, 0x07, 0x02, 0xfa, 0x78, 0xca, 0x75, 0x00],
        ),
        // id 12 | 06
        (RequestId(12), Response::ControlAccepted, &[0x08, 0x09, 0x0c, 0x06, 0xa4, 0x08, 0x46, 0xb5, 0x00]),
        (
            // id 13 | 07 | command -0.4375 = bee00000 | estimate 9.5 = 41180000 | Linear 02 | true 01
            RequestId(13),
            Response::Control(ControlOutput {
                command: -0.4375,
                estimate: 9.5,
                mode: ControlMode::Linear,
                saturated: true,
            }),
            &[
                0x04, 0x09, 0x0d, 0x07, 0x01, 0x03, 0xe0, 0xbe, 0x01, 0x09, 0x18, 0x41, 0x02, 0x01, 0x08, 0x83, 0x2b,
                0x6d, 0x00,
            ],
        ),
        (
            // id 14 | 08 | rate_hz 20000 = a0 9c 01 | ticks 0x12345678 = f8 ac d1 91 01 |
            // overruns 01 | late 02 | missed 03 | late_bound_ns 2000 = d0 0f |
            // worst_latency_ns 300 = ac 02 | worst_tick_ns 20000 = a0 9c 01 | sensor_faults 04 | Some 01 Corrupt 01 |
            // drive_faults 05 | Some 01 Fault 01 | beyond_range 06 | max_excess_rad 1.0 = 00 00 80 3f
            RequestId(14),
            Response::Status(TickStatus {
                rate_hz: 20_000,
                ticks: 0x1234_5678,
                overruns: 1,
                late: 2,
                missed: 3,
                late_bound_ns: 2000,
                worst_latency_ns: 300,
                worst_tick_ns: 20_000,
                sensor_faults: 4,
                last_sensor_fault: Some(SensorErrorKind::Corrupt),
                drive_faults: 5,
                last_drive_fault: Some(DriveErrorKind::Fault),
                beyond_range: 6,
                max_excess_rad: 1.0,
            }),
            &[
                0x1d, 0x09, 0x0e, 0x08, 0xa0, 0x9c, 0x01, 0xf8, 0xac, 0xd1, 0x91, 0x01, 0x01, 0x02, 0x03, 0xd0, 0x0f,
                0xac, 0x02, 0xa0, 0x9c, 0x01, 0x04, 0x01, 0x01, 0x05, 0x01, 0x01, 0x06, 0x01, 0x07, 0x80, 0x3f, 0xa3,
                0x92, 0x17, 0xb8, 0x00,
            ],
        ),
        // id 15 | 09 | 70000 = f0 a2 04
        (
            RequestId(15),
            Response::ExperimentStarted(70_000),
            &[0x0b, 0x09, 0x0f, 0x09, 0xf0, 0xa2, 0x04, 0x92, 0x41, 0x0d, 0x47, 0x00],
        ),
        (
            // id 16 | 0a | sequence 300 = ac 02 | first_tick 4800 = c0 25 | dropped 07 | high_water 1d |
            // Running 01 segment 02 | 2 samples 02: 6.5 = 40d00000, -0.0625 = bd800000,
            // 12.25 = 41440000, Some 01 31.5 = 41fc0000 | 6.75 = 40d80000, -0.03125 = bd000000,
            // -3.5 = c0600000, None 00
            RequestId(16),
            Response::Samples(distinct_batch()),
            &[
                0x0d, 0x09, 0x10, 0x0a, 0xac, 0x02, 0xc0, 0x25, 0x07, 0x1d, 0x01, 0x02, 0x02, 0x01, 0x03, 0xd0, 0x40,
                0x01, 0x03, 0x80, 0xbd, 0x01, 0x04, 0x44, 0x41, 0x01, 0x01, 0x03, 0xfc, 0x41, 0x01, 0x03, 0xd8, 0x40,
                0x01, 0x01, 0x02, 0xbd, 0x01, 0x03, 0x60, 0xc0, 0x05, 0x50, 0x30, 0x77, 0xcd, 0x00,
            ],
        ),
    ];
    covers_every_variant(&cases, response_variant, 11);
    for (id, response, golden) in cases {
        assert_golden(id, response, golden);
    }
}

#[test]
fn golden_error_replies() {
    let cases: [(RequestId, ErrorReply, &[u8]); 21] = [
        // Each is id | 05 (Response::Error) | variant index | fields. The replies to frames that
        // could not be read carry the unknown id, 00.
        (RequestId::UNKNOWN, ErrorReply::BadFrame, &[0x02, 0x09, 0x02, 0x05, 0x05, 0xd3, 0x64, 0x3b, 0x21, 0x00]),
        (RequestId::UNKNOWN, ErrorReply::BadCrc, &[0x02, 0x09, 0x07, 0x05, 0x01, 0x45, 0x54, 0x3c, 0x56, 0x00]),
        (RequestId::UNKNOWN, ErrorReply::FrameTooLong, &[0x02, 0x09, 0x07, 0x05, 0x02, 0xff, 0x05, 0x35, 0xcf, 0x00]),
        (
            // got 07, supported 02
            RequestId::UNKNOWN,
            ErrorReply::UnsupportedProtocol { got: 7, supported: 2 },
            &[0x02, 0x09, 0x09, 0x05, 0x03, 0x07, 0x02, 0xeb, 0x49, 0x1a, 0x02, 0x00],
        ),
        // id 20 | 05 | 04
        (RequestId(20), ErrorReply::UndecodableRequest, &[0x09, 0x09, 0x14, 0x05, 0x04, 0x66, 0xab, 0x79, 0x3d, 0x00]),
        (
            // id 21 | 05 | 05 | got 02, supported 01
            RequestId(21),
            ErrorReply::ModelVersion { got: 2, supported: 1 },
            &[0x0b, 0x09, 0x15, 0x05, 0x05, 0x02, 0x01, 0x54, 0x88, 0xe9, 0x4a, 0x00],
        ),
        (
            // id 22 | 05 | 06 | field TorqueLimit 07, fault OutOfRange 01
            RequestId(22),
            ErrorReply::InvalidParam { field: ParamField::TorqueLimit, fault: ParamFault::OutOfRange },
            &[0x0b, 0x09, 0x16, 0x05, 0x06, 0x02, 0x01, 0xdd, 0x4c, 0x0f, 0x0f, 0x00],
        ),
        (
            // id 23 | 05 | 06 | field SlipStiffness 09 with element 0d, fault NotFinite 00
            RequestId(23),
            ErrorReply::InvalidParam {
                field: ParamField::Model(ParamName::SlipStiffness(13)),
                fault: ParamFault::NotFinite,
            },
            &[0x05, 0x09, 0x17, 0x05, 0x06, 0x03, 0x06, 0x0d, 0x02, 0xee, 0x03, 0xba, 0xb6, 0x00],
        ),
        // id 24 | 05 | 07
        (RequestId(24), ErrorReply::ModelOverflow, &[0x09, 0x09, 0x18, 0x05, 0x07, 0xb8, 0x03, 0x6a, 0xad, 0x00]),
        // id 25 | 05 | 08
        (RequestId(25), ErrorReply::NoParams, &[0x09, 0x09, 0x19, 0x05, 0x08, 0x1e, 0x74, 0x17, 0x3c, 0x00]),
        // id 26 | 05 | 09 | Erase 01
        (
            RequestId(26),
            ErrorReply::Storage(StorageError::Erase),
            &[0x0a, 0x09, 0x1a, 0x05, 0x09, 0x01, 0xa3, 0x6b, 0x98, 0x54, 0x00],
        ),
        // id 27 | 05 | 09 | Verify 03
        (
            RequestId(27),
            ErrorReply::Storage(StorageError::Verify),
            &[0x0a, 0x09, 0x1b, 0x05, 0x09, 0x03, 0xea, 0x6d, 0x2a, 0x02, 0x00],
        ),
        // id 28 | 05 | 0a
        (RequestId(28), ErrorReply::NonFiniteSample, &[0x09, 0x09, 0x1c, 0x05, 0x0a, 0xd9, 0xd7, 0xd2, 0xd4, 0x00]),
        (
            // id 29 | 05 | 0b | field Period 05, fault NotFinite 00
            RequestId(29),
            ErrorReply::InvalidGain { field: GainField::Period, fault: ParamFault::NotFinite },
            &[0x06, 0x09, 0x1d, 0x05, 0x0b, 0x05, 0x05, 0xce, 0x48, 0x41, 0x48, 0x00],
        ),
        // id 30 | 05 | 0c | OutOfRange 00
        (
            RequestId(30),
            ErrorReply::MotorDrive(DriveErrorKind::OutOfRange),
            &[0x05, 0x09, 0x1e, 0x05, 0x0c, 0x05, 0x27, 0x38, 0x8a, 0xd1, 0x00],
        ),
        // id 31 | 05 | 0d
        (RequestId(31), ErrorReply::CommitWhileDriving, &[0x09, 0x09, 0x1f, 0x05, 0x0d, 0x23, 0xfc, 0xf0, 0x48, 0x00]),
        // id 32 | 05 | 0e
        (RequestId(32), ErrorReply::NotLockstep, &[0x09, 0x09, 0x20, 0x05, 0x0e, 0x34, 0x0f, 0xce, 0xfe, 0x00]),
        // id 33 | 05 | 0f
        (RequestId(33), ErrorReply::Busy, &[0x09, 0x09, 0x21, 0x05, 0x0f, 0x95, 0x55, 0x0b, 0x88, 0x00]),
        // id 34 | 05 | 10
        (RequestId(34), ErrorReply::InvalidPlan, &[0x09, 0x09, 0x22, 0x05, 0x10, 0x39, 0xe6, 0x45, 0x07, 0x00]),
        // id 35 | 05 | 11
        (RequestId(35), ErrorReply::ControllerOff, &[0x09, 0x09, 0x23, 0x05, 0x11, 0x98, 0xbc, 0x80, 0x71, 0x00]),
        // id 36 | 05 | 12
        (RequestId(36), ErrorReply::ExperimentRunning, &[0x09, 0x09, 0x24, 0x05, 0x12, 0xa7, 0xfb, 0xc6, 0xed, 0x00]),
    ];
    covers_every_variant(&cases, error_variant, 19);
    for (id, error, golden) in cases {
        assert_golden(id, Response::Error(error), golden);
    }
}

/// The index of every variant of the enums inside messages (postcard encodes an enum as
/// its index): reordering them changes the wire format.
#[test]
fn golden_enum_indices() {
    fn index_of<T: Serialize>(value: T) -> Vec<u8> {
        let mut buffer = [0u8; 16];
        postcard::to_slice(&value, &mut buffer).unwrap().to_vec()
    }
    let names = [
        ParamName::C1,
        ParamName::C2,
        ParamName::C3,
        ParamName::Alpha,
        ParamName::Beta,
        ParamName::Omega,
        ParamName::SlipStiffness(5),
        ParamName::Slip(6),
        ParamName::Zero,
        ParamName::Knot(7),
        ParamName::KnotStiffness(8),
        ParamName::RangeMin,
        ParamName::RangeMax,
        ParamName::HysteresisStiffness,
        ParamName::BoucWenA,
        ParamName::BoucWenBeta,
        ParamName::BoucWenGamma,
        ParamName::BoucWenN,
        ParamName::PreisachReach,
        ParamName::PreisachWeight(9),
    ];
    for (index, name) in (0u8..).zip(names) {
        let expected = match name {
            ParamName::SlipStiffness(i)
            | ParamName::Slip(i)
            | ParamName::Knot(i)
            | ParamName::KnotStiffness(i)
            | ParamName::PreisachWeight(i) => vec![0, index, i],
            _ => vec![0, index],
        };
        assert_eq!(index_of(ParamField::Model(name)), expected, "{name:?}");
    }
    for (index, field) in (1u8..).zip([ParamField::GearRatio, ParamField::TorqueLimit, ParamField::DirectionBand]) {
        assert_eq!(index_of(field), [index], "{field:?}");
    }
    // The kinds by their index, before their parameters.
    let mut buffer = [0u8; MAX_FRAME_LEN];
    let sets = [distinct_params(), distinct_slip_params(), distinct_bouc_wen_params(), distinct_preisach_params()];
    for (index, set) in sets.into_iter().enumerate() {
        assert_eq!(postcard::to_slice(&set.model, &mut buffer).unwrap()[0], index as u8, "{set:?}");
    }
    assert_eq!(index_of(ParamFault::NotFinite), [0]);
    assert_eq!(index_of(ParamFault::OutOfRange), [1]);
    assert_eq!(index_of(EvalPath::Direct), [0]);
    assert_eq!(index_of(EvalPath::Fast), [1]);
    assert_eq!(index_of(Compensation::Active), [0]);
    assert_eq!(index_of(Compensation::Clamped), [1]);
    assert_eq!(index_of(Compensation::Off), [2]);
    assert_eq!(index_of(Direction::Rising), [0]);
    assert_eq!(index_of(Direction::Falling), [1]);
    let modes = [ControlMode::Off, ControlMode::OpenLoop, ControlMode::Linear, ControlMode::Model];
    for (index, mode) in (0u8..).zip(modes) {
        assert_eq!(index_of(mode), [index], "{mode:?}");
    }
    let gains = [
        GainField::Kp,
        GainField::Ki,
        GainField::Damping,
        GainField::Stiffness,
        GainField::CommandLimit,
        GainField::Period,
        GainField::IntegralDeadband,
        GainField::TorsionDamping,
    ];
    for (index, field) in (0u8..).zip(gains) {
        assert_eq!(index_of(field), [index], "{field:?}");
    }
    let storage = [
        StorageError::Geometry,
        StorageError::Erase,
        StorageError::Write,
        StorageError::Verify,
        StorageError::Encoding,
    ];
    for (index, error) in (0u8..).zip(storage) {
        assert_eq!(index_of(error), [index], "{error:?}");
    }
    let drive = [DriveErrorKind::OutOfRange, DriveErrorKind::Fault, DriveErrorKind::Other];
    for (index, kind) in (0u8..).zip(drive) {
        assert_eq!(index_of(kind), [index], "{kind:?}");
    }
    let sensor = [SensorErrorKind::Bus, SensorErrorKind::Corrupt, SensorErrorKind::Sensor, SensorErrorKind::Other];
    for (index, kind) in (0u8..).zip(sensor) {
        assert_eq!(index_of(kind), [index], "{kind:?}");
    }
    let reasons = [
        StopReason::Host,
        StopReason::TorqueLimit,
        StopReason::DeflectionLimit,
        StopReason::LinkLost,
        StopReason::SensorFault,
        StopReason::DriveFault,
        StopReason::PlanRate,
    ];
    for (index, reason) in (0u8..).zip(reasons) {
        assert_eq!(index_of(reason), [index], "{reason:?}");
        assert_eq!(index_of(ExperimentState::Stopped(reason)), [3, index], "{reason:?}");
    }
    assert_eq!(index_of(ExperimentState::Idle), [0]);
    assert_eq!(index_of(ExperimentState::Running { segment: 11 }), [1, 11]);
    assert_eq!(index_of(ExperimentState::Finished), [2]);
    assert_eq!(index_of(Channel::Deflection), [0]);
    assert_eq!(index_of(Channel::Torque), [1]);
    assert_eq!(index_of(Segment::Ramp { to: 0.0, seconds: 0.0 })[0], 0);
    assert_eq!(index_of(Segment::Sine { amplitude: 0.0, frequency_hz: 0.0, cycles: 0 })[0], 1);
    assert_eq!(index_of(Segment::Hold { seconds: 0.0, dither_amplitude: 0.0, dither_hz: 0.0 })[0], 2);
}

/// Each endpoint wraps its request in its own variant, takes only its own response variant,
/// and the device's reply is that variant; the request names its endpoint.
#[test]
fn endpoints_pair_each_request_with_its_response() {
    use endpoint::*;
    fn round_trip<E: Endpoint>(request: E::Request, response: E::Response) -> (Request, Response)
    where
        E::Response: PartialEq + core::fmt::Debug + Clone,
    {
        let wire = E::reply(response.clone());
        assert_eq!(E::response(wire.clone()), Ok(response), "{}", E::NAME);
        // An error reply or another endpoint's answer is handed back as it came.
        let error = Response::Error(ErrorReply::NoParams);
        assert_eq!(E::response(error.clone()), Err(error));
        let request = E::request(&request);
        assert_eq!(request.endpoint(), E::NAME);
        (request, wire)
    }
    let sample = EncoderSample { input_angle: 1.0, output_angle: 0.0, path: EvalPath::Direct };
    let control = ControlSample { input_angle: 1.0, output_angle: 0.0, reference: 2.0, torque: 1.5, temperature: None };
    let output = ControlOutput { command: 0.5, estimate: 1.0, mode: ControlMode::Model, saturated: false };
    let feedforward = Feedforward {
        deflection: 0.0,
        torque: 0.0,
        stiffness: 0.0,
        compensation: Compensation::Off,
        direction: None,
        memory: 0,
    };
    let info = DeviceInfo {
        firmware_version: Version { major: 1, minor: 2, patch: 3 },
        protocol_version: 5,
        model_version: 1,
    };
    let pairs = [
        round_trip::<GetDeviceInfo>((), info),
        round_trip::<WriteParams>(params(), ()),
        round_trip::<ReadParams>((), Some(params())),
        round_trip::<Commit>((), 7),
        round_trip::<Replay>(sample, feedforward),
        round_trip::<Configure>(DISTINCT_CONFIG, ()),
        round_trip::<SetReference>(2.5, ()),
        round_trip::<Control>(control, output),
        round_trip::<GetStatus>((), TickStatus::default()),
        round_trip::<StartExperiment>(distinct_plan(), 9),
        round_trip::<FetchSamples>((), distinct_batch()),
        round_trip::<StopExperiment>((), ()),
    ];
    let expected = [
        (Request::GetDeviceInfo, Response::DeviceInfo(info)),
        (Request::WriteParams(params()), Response::ParamsAccepted),
        (Request::ReadParams, Response::Params(Some(params()))),
        (Request::Commit, Response::Committed(7)),
        (Request::Replay(sample), Response::Feedforward(feedforward)),
        (Request::Configure(DISTINCT_CONFIG), Response::ControlAccepted),
        (Request::SetReference(2.5), Response::ControlAccepted),
        (Request::Control(control), Response::Control(output)),
        (Request::GetStatus, Response::Status(TickStatus::default())),
        (Request::StartExperiment(distinct_plan()), Response::ExperimentStarted(9)),
        (Request::FetchSamples, Response::Samples(distinct_batch())),
        (Request::StopExperiment, Response::ControlAccepted),
    ];
    assert_eq!(pairs, expected);
    // One endpoint's answer is not another's.
    assert_eq!(ReadParams::response(Response::ParamsAccepted), Err(Response::ParamsAccepted));
    assert_eq!(Configure::response(Response::ParamsAccepted), Err(Response::ParamsAccepted));
}

#[test]
fn request_ids_skip_the_unknown_id() {
    assert_eq!(RequestId(7).next(), RequestId(8));
    assert_eq!(RequestId(u32::MAX).next(), RequestId(1));
    assert_eq!(RequestId::UNKNOWN.next(), RequestId(1));
    assert_eq!(std::format!("{} {}", RequestId(42), RequestId::UNKNOWN), "42 unknown");
}

/// Every message, at its longest (varints at their maximum, no zero byte for COBS to
/// reuse), fits MAX_FRAME_LEN, the buffer both ends encode into and receive with.
#[test]
fn the_longest_message_of_each_kind_fits_a_frame() {
    // Every float at f32::MIN (no zero byte anywhere), 17 knots, 16 elements.
    let widest_model = |model: GearModel<f32>| {
        let mut widest = model.map(|_, _| f32::MIN);
        widest.spring.knots = ([Knot { x: f32::MIN, stiffness: f32::MIN }; model_core::spring::MAX_KNOTS], u8::MAX);
        widest.spring.knots.1 = model_core::spring::MAX_KNOTS as u8;
        widest
    };
    let widest_genetic = JointParams {
        model_version: u16::MAX,
        model: widest_model(distinct_params().model),
        gear_ratio: f32::MIN,
        torque_limit: f32::MIN,
        direction_band: f32::MIN,
    };
    let mut slip = widest_model(distinct_slip_params().model);
    if let model_core::Hysteresis::MicroSlip((elements, count)) = &mut slip.hysteresis {
        *elements = [SlipElement { slip: f32::MIN, stiffness: f32::MIN }; SLIP_ELEMENTS];
        *count = SLIP_ELEMENTS as u8;
    }
    let widest = JointParams { model: slip, ..widest_genetic };
    // The Preisach set: 36 weights beside the widest spring.
    let widest_preisach = JointParams { model: widest_model(distinct_preisach_params().model), ..widest_genetic };
    let sample = EncoderSample { input_angle: f32::MIN, output_angle: f32::MIN, path: EvalPath::Fast };
    let version = Version { major: u16::MAX, minor: u16::MAX, patch: u16::MAX };
    let feedforward = Feedforward {
        deflection: f32::MIN,
        torque: f32::MIN,
        stiffness: f32::MIN,
        compensation: Compensation::Off,
        direction: Some(Direction::Falling),
        memory: u8::MAX,
    };
    let big = u16::MAX;
    // Twelve holds, each with every float at its widest in the plan's checks' eyes (the bytes
    // are what count: a plan's floats are 4 bytes whatever their value).
    let widest_hold = Segment::Hold { seconds: 1.0, dither_amplitude: f32::MIN_POSITIVE, dither_hz: 10.0 };
    let limits = Limits { torque_nm: f32::MAX, deflection_rad: f32::MAX };
    let widest_plan = Plan::new(Channel::Torque, limits, 1000.0, &[widest_hold; PLAN_SEGMENTS]).unwrap();
    let widest_sample =
        RecordedSample { input_angle: f32::MIN, output_angle: f32::MIN, torque: f32::MIN, temperature: Some(f32::MIN) };
    let widest_batch = SampleBatch {
        sequence: u32::MAX,
        first_tick: u32::MAX,
        dropped: u32::MAX,
        high_water: u32::MAX,
        state: ExperimentState::Stopped(StopReason::PlanRate),
        samples: heapless::Vec::from_slice(&[widest_sample; BATCH_SAMPLES]).unwrap(),
    };
    let requests = [
        Request::GetStatus,
        Request::GetDeviceInfo,
        Request::WriteParams(widest_genetic),
        Request::WriteParams(widest),
        Request::WriteParams(widest_preisach),
        Request::ReadParams,
        Request::Commit,
        Request::Replay(sample),
        Request::Configure(ControllerConfig {
            mode: ControlMode::Model,
            kp: f32::MIN,
            ki: f32::MIN,
            integral_deadband: f32::MIN,
            damping: f32::MIN,
            torsion_damping: f32::MIN,
            stiffness: f32::MIN,
            command_limit: f32::MIN,
            period: f32::MIN,
        }),
        Request::SetReference(f32::MIN),
        Request::Control(ControlSample {
            input_angle: f32::MIN,
            output_angle: f32::MIN,
            reference: f32::MIN,
            torque: f32::MIN,
            temperature: Some(f32::MIN),
        }),
        Request::StartExperiment(widest_plan),
        Request::FetchSamples,
        Request::StopExperiment,
    ];
    let responses = [
        Response::DeviceInfo(DeviceInfo { firmware_version: version, protocol_version: big, model_version: big }),
        Response::ParamsAccepted,
        Response::Params(Some(widest_genetic)),
        Response::Params(Some(widest)),
        Response::Params(Some(widest_preisach)),
        Response::Committed(u32::MAX),
        Response::Feedforward(feedforward),
        Response::Status(TickStatus {
            rate_hz: u32::MAX,
            ticks: u32::MAX,
            overruns: u32::MAX,
            late: u32::MAX,
            missed: u32::MAX,
            late_bound_ns: u32::MAX,
            worst_latency_ns: u32::MAX,
            worst_tick_ns: u32::MAX,
            sensor_faults: u32::MAX,
            last_sensor_fault: Some(SensorErrorKind::Other),
            drive_faults: u32::MAX,
            last_drive_fault: Some(DriveErrorKind::Other),
            beyond_range: u32::MAX,
            max_excess_rad: f32::MAX,
        }),
        Response::Error(ErrorReply::UnsupportedProtocol { got: big, supported: big }),
        Response::Error(ErrorReply::ModelVersion { got: big, supported: big }),
        Response::Error(ErrorReply::InvalidParam { field: ParamField::DirectionBand, fault: ParamFault::OutOfRange }),
        Response::Error(ErrorReply::InvalidParam {
            field: ParamField::Model(ParamName::SlipStiffness(u8::MAX)),
            fault: ParamFault::OutOfRange,
        }),
        Response::ControlAccepted,
        Response::Control(ControlOutput {
            command: f32::MIN,
            estimate: f32::MIN,
            mode: ControlMode::Model,
            saturated: true,
        }),
        Response::Error(ErrorReply::InvalidGain { field: GainField::Period, fault: ParamFault::OutOfRange }),
        Response::ExperimentStarted(u32::MAX),
        Response::Samples(widest_batch),
    ];
    // A message too long for a frame fails here already (encode's payload buffer is sized
    // for MAX_FRAME_LEN); the larger output buffer only keeps that buffer the one limit.
    fn encoded<T: Serialize>(message: &T) -> Vec<u8> {
        let mut out = [0u8; 2 * MAX_FRAME_LEN];
        let len = encode(RequestId(u32::MAX), message, &mut out).unwrap();
        out[..len].to_vec()
    }
    let mut frames: Vec<Vec<u8>> = requests.iter().map(encoded).collect();
    frames.extend(responses.iter().map(encoded));
    let longest = frames.iter().map(Vec::len).max().unwrap();
    // Params(Some(widest_preisach)): version 1 + id u32::MAX 5 + variant 1 + Some 1 +
    // u16::MAX 3 + kind 1 + θ0 4 + spring (3 × 4 + knot count 1 + 17 × 8 + range 8 = 157) +
    // reach 4 + 36 weights × 4 + the joint's 3 × 4 = 333 bytes (the micro-slip set's elements,
    // count 1 + 16 × 8, make 314), + CRC 4, + 2 COBS code bytes (no zero byte to reuse; one per
    // 254 bytes), + the delimiter. A message that grows fails here first.
    assert_eq!(longest, 333 + 4 + 2 + 1);
    assert!(longest <= MAX_FRAME_LEN, "{longest} > {MAX_FRAME_LEN}");
    // And a receiver with a MAX_FRAME_LEN buffer takes every one of them.
    let mut reader = FrameReader::<MAX_FRAME_LEN>::new();
    for frame in &frames {
        let (last, body) = frame.split_last().unwrap();
        assert!(body.iter().all(|&byte| reader.push(byte).is_none()));
        assert!(matches!(reader.push(*last), Some(Ok(_))), "{frame:02x?}");
    }
}

#[test]
fn every_message_round_trips() {
    let requests = [
        Request::GetDeviceInfo,
        Request::WriteParams(params()),
        Request::WriteParams(distinct_slip_params()),
        Request::ReadParams,
        Request::Commit,
        Request::Replay(EncoderSample { input_angle: 12.5, output_angle: 0.125, path: EvalPath::Direct }),
        Request::Configure(DISTINCT_CONFIG),
        Request::SetReference(3.5),
        Request::Control(ControlSample {
            input_angle: -1.5,
            output_angle: 0.25,
            reference: -2.0,
            torque: 0.75,
            temperature: Some(25.0),
        }),
        Request::GetStatus,
        Request::StartExperiment(distinct_plan()),
        Request::FetchSamples,
        Request::StopExperiment,
    ];
    for request in requests {
        let (out, len) = frame_of(&request);
        assert_eq!(message_of::<Request>(&out[..len]), Ok(request));
        // The device's decoding: the same request, a parameter set's bytes left in the frame.
        let mut frame = out[..len - 1].to_vec();
        let (Envelope { id, message }, rest) = decode_request(&mut frame).unwrap();
        assert_eq!(id, ID);
        let deferred = match request {
            Request::GetDeviceInfo => RequestOf::GetDeviceInfo,
            Request::WriteParams(params) => {
                assert_eq!(JointParams::from_postcard(&frame[rest.clone()]), Ok(params));
                RequestOf::WriteParams(Deferred)
            }
            Request::ReadParams => RequestOf::ReadParams,
            Request::Commit => RequestOf::Commit,
            Request::Replay(sample) => RequestOf::Replay(sample),
            Request::Configure(config) => RequestOf::Configure(config),
            Request::SetReference(reference) => RequestOf::SetReference(reference),
            Request::Control(sample) => RequestOf::Control(sample),
            Request::GetStatus => RequestOf::GetStatus,
            Request::StartExperiment(plan) => RequestOf::StartExperiment(plan),
            Request::FetchSamples => RequestOf::FetchSamples,
            Request::StopExperiment => RequestOf::StopExperiment,
        };
        assert_eq!(message, deferred);
        if !matches!(request, Request::WriteParams(_)) {
            assert!(rest.is_empty(), "{request:?}: {rest:?}");
        }
    }
    let responses = [
        Response::DeviceInfo(DeviceInfo {
            firmware_version: Version { major: 0, minor: 1, patch: 0 },
            protocol_version: PROTOCOL_VERSION,
            model_version: MODEL_VERSION,
        }),
        Response::ParamsAccepted,
        Response::Params(Some(params())),
        Response::Params(Some(distinct_slip_params())),
        Response::Params(None),
        Response::Committed(u32::MAX),
        Response::Feedforward(Feedforward {
            deflection: -1.0e-3,
            torque: -f32::MAX,
            stiffness: 1.0e6,
            compensation: Compensation::Clamped,
            direction: Some(Direction::Rising),
            memory: 16,
        }),
        Response::Error(ErrorReply::InvalidParam { field: ParamField::DirectionBand, fault: ParamFault::OutOfRange }),
        Response::ControlAccepted,
        Response::Control(ControlOutput {
            command: 0.125,
            estimate: 0.0,
            mode: ControlMode::OpenLoop,
            saturated: false,
        }),
        Response::Error(ErrorReply::MotorDrive(DriveErrorKind::Fault)),
        Response::Error(ErrorReply::Storage(StorageError::Write)),
        Response::Status(TickStatus { rate_hz: 1000, ticks: 5, ..TickStatus::default() }),
        Response::ExperimentStarted(30_500),
        Response::Samples(distinct_batch()),
    ];
    for response in responses {
        let (out, len) = frame_of(&response);
        assert_eq!(message_of::<Response>(&out[..len]), Ok(response));
    }
}

#[test]
fn any_flipped_bit_is_detected() {
    let (out, len) = frame_of(&Request::WriteParams(params()));
    for index in 0..len - 1 {
        for bit in 0..8 {
            let mut corrupted = out[..len].to_vec();
            corrupted[index] ^= 1 << bit;
            if corrupted[index] == 0 {
                // A new delimiter splits the frame: both halves must be refused.
                let (first, second) = corrupted.split_at_mut(index);
                assert!(decode::<Request>(first).is_err());
                assert!(decode::<Request>(&mut second[1..len - index - 1]).is_err());
                continue;
            }
            let result = message_of::<Request>(&corrupted);
            assert!(
                matches!(result, Err(FrameError::Crc | FrameError::Malformed)),
                "byte {index} bit {bit}: {result:?}"
            );
        }
    }
}

#[test]
fn truncated_frames_are_refused() {
    let (out, len) = frame_of(&Request::WriteParams(params()));
    for cut in 0..len - 1 {
        let mut truncated = out[..cut].to_vec();
        assert!(decode::<Request>(&mut truncated).is_err(), "cut at {cut}");
    }
}

#[test]
fn another_protocol_version_is_named() {
    let mut out = [0u8; MAX_FRAME_LEN];
    let len = encode_with_version(PROTOCOL_VERSION + 1, ID, &Request::GetDeviceInfo, &mut out).unwrap();
    let error = decode_sent::<Request>(&out[..len]).unwrap_err();
    assert_eq!(error, FrameError::Version(PROTOCOL_VERSION + 1));
    // Another version's header may be laid out otherwise: its id is not read.
    assert_eq!(error.request_id(), RequestId::UNKNOWN);
    assert_eq!(
        ErrorReply::from(FrameError::Version(2)),
        ErrorReply::UnsupportedProtocol { got: 2, supported: PROTOCOL_VERSION }
    );
}

#[test]
fn a_response_is_not_taken_for_a_request() {
    // Same version and CRC, but variant 5 does not exist among requests: the reply to it can
    // still name the request by its id.
    let (out, len) = frame_of(&Response::Error(ErrorReply::BadCrc));
    let error = decode_sent::<Request>(&out[..len]).unwrap_err();
    assert_eq!(error, FrameError::Message(ID));
    assert_eq!(error.request_id(), ID);
    assert_eq!(ErrorReply::from(error), ErrorReply::UndecodableRequest);
}

#[test]
fn reader_splits_a_stream_and_survives_garbage() {
    let (first, first_len) = frame_of(&Request::Commit);
    let (second, second_len) = frame_of(&Request::ReadParams);
    let mut stream = vec![0u8, 0];
    stream.extend_from_slice(&[0x55; 40]); // line noise longer than the buffer
    stream.push(0);
    stream.extend_from_slice(&first[..first_len]);
    stream.extend_from_slice(&second[..second_len]);

    let mut reader = FrameReader::<32>::new();
    let mut results = Vec::new();
    for byte in stream {
        if let Some(frame) = reader.push(byte) {
            results.push(frame.map(|frame| decode::<Request>(frame).map(|envelope| envelope.message)));
        }
    }
    assert_eq!(results, vec![Err(FrameError::TooLong), Ok(Ok(Request::Commit)), Ok(Ok(Request::ReadParams))]);
}

/// The reader's buffer is lent between frames only (a reply encoded there is overwritten by
/// the next frame, never a frame being collected).
#[test]
fn the_buffer_is_spare_between_frames_only() {
    let mut reader = FrameReader::<32>::new();
    assert!(reader.spare().is_some());
    reader.push(0x11);
    assert!(reader.spare().is_none(), "a frame is being collected");
    assert!(reader.push(0).is_some());
    let spare = reader.spare().unwrap();
    assert_eq!(spare[0], 0x11, "the frame just read");
    spare[..3].copy_from_slice(&[1, 2, 3]);
    for byte in [0x55u8; 40] {
        reader.push(byte);
    }
    assert!(reader.spare().is_none(), "an overlong frame is being skipped");
    assert_eq!(reader.push(0), Some(Err(FrameError::TooLong)));
    assert!(reader.spare().is_some());
}

#[test]
fn validation_names_the_field() {
    assert_eq!(params().validate(), Ok(()));
    let invalid = |field, fault| Err(ErrorReply::InvalidParam { field, fault });
    let with =
        |name: ParamName, value: f32| JointParams { model: params().model.with(name, value), ..params() }.validate();
    assert_eq!(with(ParamName::C2, f32::NAN), invalid(ParamField::Model(ParamName::C2), ParamFault::NotFinite));
    assert_eq!(
        with(ParamName::Beta, f32::INFINITY),
        invalid(ParamField::Model(ParamName::Beta), ParamFault::NotFinite)
    );
    assert_eq!(with(ParamName::Omega, 0.0), invalid(ParamField::Model(ParamName::Omega), ParamFault::OutOfRange));
    let joint = |edit: fn(&mut JointParams)| {
        let mut p = params();
        edit(&mut p);
        p.validate()
    };
    assert_eq!(joint(|p| p.gear_ratio = 0.5), invalid(ParamField::GearRatio, ParamFault::OutOfRange));
    assert_eq!(joint(|p| p.torque_limit = 0.0), invalid(ParamField::TorqueLimit, ParamFault::OutOfRange));
    assert_eq!(joint(|p| p.direction_band = -1.0), invalid(ParamField::DirectionBand, ParamFault::OutOfRange));
    assert_eq!(
        joint(|p| p.model_version = MODEL_VERSION + 1),
        Err(ErrorReply::ModelVersion { got: MODEL_VERSION + 1, supported: MODEL_VERSION })
    );
}

#[test]
fn micro_slip_validation_names_the_field() {
    let set = JointParams { model_version: MODEL_VERSION, ..distinct_slip_params() };
    let with = |name: ParamName, value: f32| JointParams { model: set.model.with(name, value), ..set }.validate();
    let invalid = |name, fault| Err(ErrorReply::InvalidParam { field: ParamField::Model(name), fault });
    assert_eq!(set.validate(), Ok(()));
    assert_eq!(with(ParamName::C1, f32::NAN), invalid(ParamName::C1, ParamFault::NotFinite));
    assert_eq!(with(ParamName::Zero, f32::NEG_INFINITY), invalid(ParamName::Zero, ParamFault::NotFinite));
    assert_eq!(
        with(ParamName::SlipStiffness(7), f32::INFINITY),
        invalid(ParamName::SlipStiffness(7), ParamFault::NotFinite)
    );
    assert_eq!(with(ParamName::SlipStiffness(15), -1.0), invalid(ParamName::SlipStiffness(15), ParamFault::OutOfRange));
    // k = 0 is an element that is not there: allowed (the fit's non-negative least squares gives it).
    assert_eq!(with(ParamName::SlipStiffness(3), 0.0), Ok(()));
    assert_eq!(with(ParamName::Slip(0), f32::NAN), invalid(ParamName::Slip(0), ParamFault::NotFinite));
    assert_eq!(with(ParamName::Slip(0), 0.0), invalid(ParamName::Slip(0), ParamFault::OutOfRange));
    assert_eq!(with(ParamName::Slip(9), 1.0e-6), invalid(ParamName::Slip(9), ParamFault::OutOfRange));
    assert_eq!(with(ParamName::KnotStiffness(2), -1.0), invalid(ParamName::KnotStiffness(2), ParamFault::OutOfRange));
    assert_eq!(with(ParamName::Knot(3), -1.0), invalid(ParamName::Knot(3), ParamFault::OutOfRange));
    assert_eq!(with(ParamName::RangeMin, 1.0e-3), invalid(ParamName::RangeMin, ParamFault::OutOfRange));
    // An element that could only slip beyond the joint's travel: out of range.
    assert_eq!(with(ParamName::Slip(15), 1.0), invalid(ParamName::Slip(15), ParamFault::OutOfRange));
    // The joint's own fields as for the genetic kind.
    assert_eq!(JointParams { direction_band: 0.5, ..set }.validate(), invalid_joint(ParamField::DirectionBand));
    // Every set the protocol accepts, model-core accepts too.
    assert_eq!(set.model.validate(), Ok(()));
    // The error names the element.
    let error = ErrorReply::InvalidParam {
        field: ParamField::Model(ParamName::SlipStiffness(3)),
        fault: ParamFault::OutOfRange,
    };
    assert_eq!(std::format!("{error}"), "parameter stiffness[3] is out of range");
}

fn invalid_joint(field: ParamField) -> Result<(), ErrorReply> {
    Err(ErrorReply::InvalidParam { field, fault: ParamFault::OutOfRange })
}

#[test]
fn controller_validation_names_the_gain() {
    assert_eq!(DISTINCT_CONFIG.validate(), Ok(()));
    let with = |edit: fn(&mut ControllerConfig)| {
        let mut config = DISTINCT_CONFIG;
        edit(&mut config);
        config.validate()
    };
    let invalid = |field, fault| Err(ErrorReply::InvalidGain { field, fault });
    assert_eq!(with(|c| c.kp = f32::NAN), invalid(GainField::Kp, ParamFault::NotFinite));
    assert_eq!(with(|c| c.kp = -0.5), invalid(GainField::Kp, ParamFault::OutOfRange));
    assert_eq!(with(|c| c.ki = f32::INFINITY), invalid(GainField::Ki, ParamFault::NotFinite));
    assert_eq!(with(|c| c.ki = -1.0), invalid(GainField::Ki, ParamFault::OutOfRange));
    assert_eq!(with(|c| c.damping = -1.0e-3), invalid(GainField::Damping, ParamFault::OutOfRange));
    assert_eq!(with(|c| c.stiffness = 0.0), invalid(GainField::Stiffness, ParamFault::OutOfRange));
    assert_eq!(with(|c| c.command_limit = 0.0), invalid(GainField::CommandLimit, ParamFault::OutOfRange));
    assert_eq!(with(|c| c.period = 0.0), invalid(GainField::Period, ParamFault::OutOfRange));
    assert_eq!(with(|c| c.period = 1.5), invalid(GainField::Period, ParamFault::OutOfRange));
    assert_eq!(with(|c| c.period = f32::NEG_INFINITY), invalid(GainField::Period, ParamFault::NotFinite));
    // Zero gains are allowed: an open loop, or a pure P loop.
    assert_eq!(with(|c| (c.kp, c.ki, c.damping) = (0.0, 0.0, 0.0)), Ok(()));
    let error = ErrorReply::InvalidGain { field: GainField::CommandLimit, fault: ParamFault::OutOfRange };
    assert_eq!(std::format!("{error}"), "controller gain command_limit is out of range");
    assert_eq!(std::format!("{}", ControlMode::OpenLoop), "open-loop");
}

/// The frames' COBS decoder decodes and refuses exactly as the `cobs` crate's
/// `decode_in_place` (which `encode`'s `cobs::try_encode` pairs with), leaving the same bytes
/// behind: every string of up to 6 bytes over an alphabet of the codes that matter, then
/// encoded and damaged frames of every length up to a frame's.
#[test]
fn cobs_decoding_is_the_cobs_crate_s() {
    fn same(bytes: &[u8]) {
        let (mut ours, mut theirs) = (bytes.to_vec(), bytes.to_vec());
        let got = cobs_decode_in_place(&mut ours);
        let want = cobs::decode_in_place(&mut theirs).ok();
        assert_eq!((got, &ours), (want, &theirs), "{bytes:?}");
    }
    const ALPHABET: [u8; 8] = [0, 1, 2, 3, 5, 0x7F, 0xFE, 0xFF];
    for len in 0..=6u32 {
        for index in 0..ALPHABET.len().pow(len) {
            let bytes: Vec<u8> = (0..len).map(|at| ALPHABET[index / ALPHABET.len().pow(at) % ALPHABET.len()]).collect();
            same(&bytes);
        }
    }
    // xorshift32: reproducible without a dependency.
    let mut state = 0x9E37_79B9u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    };
    let mut encoded = [0u8; 2 * MAX_FRAME_LEN];
    for round in 0..20_000 {
        let len = next() as usize % (MAX_FRAME_LEN + 1);
        // Runs of zeros and of non-zero bytes of every length, blocks of 254 included.
        let zeros = next() % 64;
        let data: Vec<u8> = (0..len).map(|_| if next() % 64 < zeros { 0 } else { next() as u8 | 1 }).collect();
        let n = cobs::try_encode(&data, &mut encoded).unwrap();
        let mut frame = encoded[..n].to_vec();
        same(&frame);
        if n > 0 && round % 2 == 1 {
            let at = next() as usize % n;
            frame[at] = next() as u8;
            same(&frame);
            frame.truncate(at);
            same(&frame);
        }
    }
}

#[test]
fn a_batch_lost_repeated_or_after_dropped_ticks_is_a_gap() {
    use crate::experiment::BatchGap;
    let batch = |sequence, first_tick| SampleBatch { sequence, first_tick, ..distinct_batch() };
    // Two samples each.
    let (first, second) = (batch(0, 0), batch(1, 2));
    assert_eq!(first.follows(None), Ok(()));
    assert_eq!(second.follows(Some(&first)), Ok(()));
    assert_eq!(second.follows(None), Err(BatchGap::Sequence { expected: 0, got: 1 }));
    // Lost on the way, or repeated.
    assert_eq!(batch(2, 4).follows(Some(&first)), Err(BatchGap::Sequence { expected: 1, got: 2 }));
    assert_eq!(first.follows(Some(&first)), Err(BatchGap::Sequence { expected: 1, got: 0 }));
    // In turn, but the joint dropped ticks 2..5.
    assert_eq!(batch(1, 5).follows(Some(&first)), Err(BatchGap::Ticks { from: 2, to: 5 }));
    assert_eq!(batch(0, 3).follows(None), Err(BatchGap::Ticks { from: 0, to: 3 }));
}
