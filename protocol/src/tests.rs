extern crate std;
use super::*;
use std::{vec, vec::Vec};

const PARAMS: JointParams = JointParams {
    model_version: MODEL_VERSION,
    model: GearModel::Genetic(Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 2.0, beta: -2.298, omega: 1.0 }),
    gear_ratio: 100.0,
    torque_limit: 50.0,
    direction_band: 2.0e-5,
};

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

/// A parameter set with every field different, so that the golden frames fail if two
/// fields trade places (or encodings). All values are exact in f32.
const DISTINCT_PARAMS: JointParams = JointParams {
    model_version: 1,
    model: GearModel::Genetic(Params { c1: 9000.0, c2: 1.25e10, c3: -3.0e14, alpha: 48.5, beta: -2.25, omega: 1.0 }),
    gear_ratio: 100.0,
    torque_limit: 50.0,
    direction_band: 2.0e-5,
};

/// k_i = 100·(i + 1) + 0.25 N·m/rad: every element different, all exact in f32.
const DISTINCT_STIFFNESS: [f32; SLIP_ELEMENTS] = {
    let mut k = [0.0f32; SLIP_ELEMENTS];
    let mut i = 0;
    while i < SLIP_ELEMENTS {
        k[i] = 100.0 * (i + 1) as f32 + 0.25;
        i += 1;
    }
    k
};

/// A micro-slip set with every field different from every other (and from the genetic set's
/// joint fields), exact in f32.
const DISTINCT_SLIP_PARAMS: JointParams = JointParams {
    model_version: 1,
    model: GearModel::MicroSlip(SlipParams {
        c1: 6000.0,
        c2: 2.5e9,
        c3: -5.0e13,
        stiffness: DISTINCT_STIFFNESS,
        slip_min: 1.0 / 65536.0,
        slip_max: 1.0 / 512.0,
    }),
    gear_ratio: 80.0,
    torque_limit: 35.5,
    direction_band: 2.5e-6,
};

#[test]
fn the_distinct_sets_have_distinct_fields() {
    let GearModel::MicroSlip(slip) = DISTINCT_SLIP_PARAMS.model else { unreachable!() };
    let mut fields = vec![slip.c1, slip.c2, slip.c3, slip.slip_min, slip.slip_max];
    fields.extend(slip.stiffness);
    fields.extend([
        DISTINCT_SLIP_PARAMS.gear_ratio,
        DISTINCT_SLIP_PARAMS.torque_limit,
        DISTINCT_SLIP_PARAMS.direction_band,
    ]);
    for (i, a) in fields.iter().enumerate() {
        assert!(fields[i + 1..].iter().all(|b| a != b), "{fields:?}");
    }
    assert_eq!(DISTINCT_SLIP_PARAMS.validate(), Ok(()));
    assert_eq!(DISTINCT_PARAMS.validate(), Ok(()));
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
// postcard: varint protocol version (5), varint request id, varint variant index, then the
// fields in order (u16/u32 as varints, f32 as 4 bytes little-endian, enums as varint index
// followed by their fields, Option as 0/1, arrays element by element without a length). The
// comments give the payload after version and id; COBS replaces each 0x00 by the distance to
// the next one and leads with the distance to the first. Every frame has its own request id,
// of one to five varint bytes.
//
// One frame checked by hand, Request::GetDeviceInfo with id 1: the payload is 05 | 01 | 00,
// its CRC-32/ISO-HDLC is 0xe091_2ab8 (`python3 -c 'import zlib; print(hex(zlib.crc32(bytes([5, 1, 0]))))'`),
// little-endian b8 2a 91 e0, so COBS(05 01 00 b8 2a 91 e0) = 03 05 01 | 05 b8 2a 91 e0 (each
// code byte the distance to the next zero, the last to the end) and the delimiter 00.
//
// The genetic set's payload (DISTINCT_PARAMS):
//   model_version 01 | Genetic 00 | c1 9e3 = 460ca000 | c2 1.25e10 = 503a43b7 |
//   c3 -3e14 = d7886c99 | alpha 48.5 = 42420000 | beta -2.25 = c0100000 | omega 1 = 3f800000 |
//   gear_ratio 100 = 42c80000 | torque_limit 50 = 42480000 | direction_band 2e-5 = 37a7c5ac
// The micro-slip set's (DISTINCT_SLIP_PARAMS):
//   model_version 01 | MicroSlip 01 | c1 6e3 = 45bb8000 | c2 2.5e9 = 4f1502f9 |
//   c3 -5e13 = d635e621 | stiffness 100.25 = 42c88000, 200.25 = 43484000, … 1600.25 = 44c80800 |
//   slip_min 2⁻¹⁶ = 37800000 | slip_max 2⁻⁹ = 3b000000 | gear_ratio 80 = 42a00000 |
//   torque_limit 35.5 = 420e0000 | direction_band 2.5e-6 = 3627c5ac

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
    let cases: [(RequestId, Request, &[u8]); 10] = [
        // id 1 | 00 (checked by hand above)
        (RequestId(1), Request::GetDeviceInfo, &[0x03, 0x05, 0x01, 0x05, 0xb8, 0x2a, 0x91, 0xe0, 0x00]),
        (
            // id 300 = ac 02 | 01 | the genetic set
            RequestId(300),
            Request::WriteParams(DISTINCT_PARAMS),
            &[
                0x06, 0x05, 0xac, 0x02, 0x01, 0x01, 0x01, 0x0c, 0xa0, 0x0c, 0x46, 0xb7, 0x43, 0x3a, 0x50, 0x99, 0x6c,
                0x88, 0xd7, 0x01, 0x03, 0x42, 0x42, 0x01, 0x03, 0x10, 0xc0, 0x01, 0x03, 0x80, 0x3f, 0x01, 0x03, 0xc8,
                0x42, 0x01, 0x0b, 0x48, 0x42, 0xac, 0xc5, 0xa7, 0x37, 0x1b, 0x7c, 0x07, 0xeb, 0x00,
            ],
        ),
        (
            // id 0x4000 = 80 80 01 | 01 | the micro-slip set
            RequestId(0x4000),
            Request::WriteParams(DISTINCT_SLIP_PARAMS),
            &[
                0x08, 0x05, 0x80, 0x80, 0x01, 0x01, 0x01, 0x01, 0x0c, 0x80, 0xbb, 0x45, 0xf9, 0x02, 0x15, 0x4f, 0x21,
                0xe6, 0x35, 0xd6, 0x04, 0x80, 0xc8, 0x42, 0x04, 0x40, 0x48, 0x43, 0x04, 0x20, 0x96, 0x43, 0x04, 0x20,
                0xc8, 0x43, 0x04, 0x20, 0xfa, 0x43, 0x04, 0x10, 0x16, 0x44, 0x04, 0x10, 0x2f, 0x44, 0x04, 0x10, 0x48,
                0x44, 0x04, 0x10, 0x61, 0x44, 0x04, 0x10, 0x7a, 0x44, 0x04, 0x88, 0x89, 0x44, 0x04, 0x08, 0x96, 0x44,
                0x04, 0x88, 0xa2, 0x44, 0x04, 0x08, 0xaf, 0x44, 0x04, 0x88, 0xbb, 0x44, 0x04, 0x08, 0xc8, 0x44, 0x01,
                0x03, 0x80, 0x37, 0x01, 0x01, 0x02, 0x3b, 0x01, 0x03, 0xa0, 0x42, 0x01, 0x0b, 0x0e, 0x42, 0xac, 0xc5,
                0x27, 0x36, 0x5d, 0x6b, 0xb4, 0xde, 0x00,
            ],
        ),
        // id 2 | 02
        (RequestId(2), Request::ReadParams, &[0x08, 0x05, 0x02, 0x02, 0x57, 0x18, 0xb2, 0x25, 0x00]),
        // id u32::MAX = ff ff ff ff 0f | 03
        (
            RequestId(u32::MAX),
            Request::Commit,
            &[0x0c, 0x05, 0xff, 0xff, 0xff, 0xff, 0x0f, 0x03, 0xf0, 0xe3, 0xf8, 0x9f, 0x00],
        ),
        (
            // id 0x12345678 = f8 ac d1 91 01 | 04 | input_angle 1 = 3f800000 |
            // output_angle -0.5 = bf000000 | Fast 01
            RequestId(0x1234_5678),
            Request::Replay(EncoderSample { input_angle: 1.0, output_angle: -0.5, path: EvalPath::Fast }),
            &[
                0x08, 0x05, 0xf8, 0xac, 0xd1, 0x91, 0x01, 0x04, 0x01, 0x03, 0x80, 0x3f, 0x01, 0x01, 0x07, 0xbf, 0x01,
                0x85, 0xd1, 0x5b, 0x57, 0x00,
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
                0x05, 0x05, 0x7f, 0x05, 0x03, 0x01, 0x03, 0x80, 0x3d, 0x01, 0x03, 0x20, 0x40, 0x01, 0x01, 0x02, 0x3e,
                0x01, 0x01, 0x02, 0x3c, 0x01, 0x01, 0x02, 0x3d, 0x01, 0x03, 0x80, 0x46, 0x01, 0x03, 0x40, 0x3f, 0x01,
                0x07, 0x80, 0x3a, 0xac, 0xc7, 0x01, 0x61, 0x00,
            ],
        ),
        (
            // id 128 = 80 01 | 06 | -7.25 = c0e80000
            RequestId(128),
            Request::SetReference(-7.25),
            &[0x05, 0x05, 0x80, 0x01, 0x06, 0x01, 0x07, 0xe8, 0xc0, 0xae, 0xa6, 0x0b, 0xec, 0x00],
        ),
        (
            // id 65535 = ff ff 03 | 07 | input_angle 12.5 = 41480000 | output_angle -0.375 = bec00000 |
            // reference 8.75 = 410c0000
            RequestId(65_535),
            Request::Control(ControlSample { input_angle: 12.5, output_angle: -0.375, reference: 8.75 }),
            &[
                0x06, 0x05, 0xff, 0xff, 0x03, 0x07, 0x01, 0x03, 0x48, 0x41, 0x01, 0x03, 0xc0, 0xbe, 0x01, 0x07, 0x0c,
                0x41, 0x34, 0x28, 0x84, 0x7a, 0x00,
            ],
        ),
        // id 9 | 08
        (RequestId(9), Request::GetStatus, &[0x08, 0x05, 0x09, 0x08, 0x82, 0x28, 0x93, 0x26, 0x00]),
    ];
    covers_every_variant(&cases, request_variant, 9);
    for (id, request, golden) in cases {
        assert_golden(id, request, golden);
    }
}

#[test]
fn golden_responses() {
    let cases: [(RequestId, Response, &[u8]); 12] = [
        (
            // id 3 | 00 | 0.1.2 = 00 01 02 | protocol_version 300 = ac 02 | model_version 07
            RequestId(3),
            Response::DeviceInfo(DeviceInfo {
                firmware_version: Version { major: 0, minor: 1, patch: 2 },
                protocol_version: 300,
                model_version: 7,
            }),
            &[0x03, 0x05, 0x03, 0x01, 0x0a, 0x01, 0x02, 0xac, 0x02, 0x07, 0x1c, 0xe4, 0x48, 0xc9, 0x00],
        ),
        // id 4 | 01
        (RequestId(4), Response::ParamsAccepted, &[0x08, 0x05, 0x04, 0x01, 0x6b, 0xee, 0xe1, 0xea, 0x00]),
        (
            // id 1000 = e8 07 | 02 | Some 01 | the genetic set
            RequestId(1000),
            Response::Params(Some(DISTINCT_PARAMS)),
            &[
                0x07, 0x05, 0xe8, 0x07, 0x02, 0x01, 0x01, 0x01, 0x0c, 0xa0, 0x0c, 0x46, 0xb7, 0x43, 0x3a, 0x50, 0x99,
                0x6c, 0x88, 0xd7, 0x01, 0x03, 0x42, 0x42, 0x01, 0x03, 0x10, 0xc0, 0x01, 0x03, 0x80, 0x3f, 0x01, 0x03,
                0xc8, 0x42, 0x01, 0x0b, 0x48, 0x42, 0xac, 0xc5, 0xa7, 0x37, 0x2c, 0xd0, 0xd4, 0x04, 0x00,
            ],
        ),
        (
            // id 0x200000 = 80 80 80 01 | 02 | Some 01 | the micro-slip set
            RequestId(0x20_0000),
            Response::Params(Some(DISTINCT_SLIP_PARAMS)),
            &[
                0x0a, 0x05, 0x80, 0x80, 0x80, 0x01, 0x02, 0x01, 0x01, 0x01, 0x0c, 0x80, 0xbb, 0x45, 0xf9, 0x02, 0x15,
                0x4f, 0x21, 0xe6, 0x35, 0xd6, 0x04, 0x80, 0xc8, 0x42, 0x04, 0x40, 0x48, 0x43, 0x04, 0x20, 0x96, 0x43,
                0x04, 0x20, 0xc8, 0x43, 0x04, 0x20, 0xfa, 0x43, 0x04, 0x10, 0x16, 0x44, 0x04, 0x10, 0x2f, 0x44, 0x04,
                0x10, 0x48, 0x44, 0x04, 0x10, 0x61, 0x44, 0x04, 0x10, 0x7a, 0x44, 0x04, 0x88, 0x89, 0x44, 0x04, 0x08,
                0x96, 0x44, 0x04, 0x88, 0xa2, 0x44, 0x04, 0x08, 0xaf, 0x44, 0x04, 0x88, 0xbb, 0x44, 0x04, 0x08, 0xc8,
                0x44, 0x01, 0x03, 0x80, 0x37, 0x01, 0x01, 0x02, 0x3b, 0x01, 0x03, 0xa0, 0x42, 0x01, 0x0b, 0x0e, 0x42,
                0xac, 0xc5, 0x27, 0x36, 0x0d, 0xfb, 0x32, 0x1b, 0x00,
            ],
        ),
        // id 5 | 02 | None 00
        (RequestId(5), Response::Params(None), &[0x04, 0x05, 0x05, 0x02, 0x05, 0x47, 0x8f, 0x67, 0x22, 0x00]),
        (
            // id 6 | 03 | sequence 0x12345678 = f8 ac d1 91 01
            RequestId(6),
            Response::Committed(0x1234_5678),
            &[0x0d, 0x05, 0x06, 0x03, 0xf8, 0xac, 0xd1, 0x91, 0x01, 0x72, 0xff, 0x69, 0x24, 0x00],
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
                0x08, 0x05, 0x98, 0xf5, 0xf2, 0xf6, 0x0f, 0x04, 0x01, 0x03, 0x80, 0xba, 0x01, 0x03, 0x48, 0xc1, 0x0c,
                0x40, 0x1c, 0x47, 0x01, 0x01, 0x01, 0x03, 0x4e, 0xf1, 0x4c, 0x6a, 0x00,
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
                0x04, 0x05, 0x0a, 0x04, 0x01, 0x01, 0x02, 0x3a, 0x01, 0x03, 0xd8, 0x40, 0x04, 0x80, 0x3b, 0x46, 0x01,
                0x06, 0x0b, 0xfb, 0x81, 0x4c, 0xfc, 0x00,
            ],
        ),
        (
            // id 11 | 05 | UnsupportedProtocol 03 | got 07 | supported 02
            RequestId(11),
            Response::Error(ErrorReply::UnsupportedProtocol { got: 7, supported: 2 }),
            &[0x0b, 0x05, 0x0b, 0x05, 0x03, 0x07, 0x02, 0x81, 0xb8, 0x08, 0x02, 0x00],
        ),
        // id 12 | 06
        (RequestId(12), Response::ControlAccepted, &[0x08, 0x05, 0x0c, 0x06, 0xc0, 0xf1, 0x5c, 0xbc, 0x00]),
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
                0x04, 0x05, 0x0d, 0x07, 0x01, 0x03, 0xe0, 0xbe, 0x01, 0x09, 0x18, 0x41, 0x02, 0x01, 0xf3, 0x3a, 0x91,
                0xf7, 0x00,
            ],
        ),
        (
            // id 14 | 08 | rate_hz 20000 = a0 9c 01 | ticks 0x12345678 = f8 ac d1 91 01 |
            // overruns 01 | late 02 | missed 03 | late_bound_ns 2000 = d0 0f |
            // worst_latency_ns 300 = ac 02 | worst_tick_ns 20000 = a0 9c 01 | sensor_faults 04 | Some 01 Corrupt 01 |
            // drive_faults 05 | Some 01 Fault 01
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
            }),
            &[
                0x20, 0x05, 0x0e, 0x08, 0xa0, 0x9c, 0x01, 0xf8, 0xac, 0xd1, 0x91, 0x01, 0x01, 0x02, 0x03, 0xd0, 0x0f,
                0xac, 0x02, 0xa0, 0x9c, 0x01, 0x04, 0x01, 0x01, 0x05, 0x01, 0x01, 0xee, 0x64, 0x32, 0x89, 0x00,
            ],
        ),
    ];
    covers_every_variant(&cases, response_variant, 9);
    for (id, response, golden) in cases {
        assert_golden(id, response, golden);
    }
}

#[test]
fn golden_error_replies() {
    let cases: [(RequestId, ErrorReply, &[u8]); 18] = [
        // Each is id | 05 (Response::Error) | variant index | fields. The replies to frames that
        // could not be read carry the unknown id, 00.
        (RequestId::UNKNOWN, ErrorReply::BadFrame, &[0x02, 0x05, 0x02, 0x05, 0x05, 0x6b, 0xdb, 0xed, 0x6b, 0x00]),
        (RequestId::UNKNOWN, ErrorReply::BadCrc, &[0x02, 0x05, 0x07, 0x05, 0x01, 0xfd, 0xeb, 0xea, 0x1c, 0x00]),
        (RequestId::UNKNOWN, ErrorReply::FrameTooLong, &[0x02, 0x05, 0x07, 0x05, 0x02, 0x47, 0xba, 0xe3, 0x85, 0x00]),
        (
            // got 07, supported 02
            RequestId::UNKNOWN,
            ErrorReply::UnsupportedProtocol { got: 7, supported: 2 },
            &[0x02, 0x05, 0x09, 0x05, 0x03, 0x07, 0x02, 0x90, 0x89, 0xd8, 0x75, 0x00],
        ),
        // id 20 | 05 | 04
        (RequestId(20), ErrorReply::UndecodableRequest, &[0x09, 0x05, 0x14, 0x05, 0x04, 0xde, 0x14, 0xaf, 0x77, 0x00]),
        (
            // id 21 | 05 | 05 | got 02, supported 01
            RequestId(21),
            ErrorReply::ModelVersion { got: 2, supported: 1 },
            &[0x0b, 0x05, 0x15, 0x05, 0x05, 0x02, 0x01, 0x2f, 0x48, 0x2b, 0x3d, 0x00],
        ),
        (
            // id 22 | 05 | 06 | field TorqueLimit 07, fault OutOfRange 01
            RequestId(22),
            ErrorReply::InvalidParam { field: ParamField::TorqueLimit, fault: ParamFault::OutOfRange },
            &[0x0b, 0x05, 0x16, 0x05, 0x06, 0x02, 0x01, 0xa6, 0x8c, 0xcd, 0x78, 0x00],
        ),
        (
            // id 23 | 05 | 06 | field SlipStiffness 09 with element 0d, fault NotFinite 00
            RequestId(23),
            ErrorReply::InvalidParam {
                field: ParamField::Model(ParamName::SlipStiffness(13)),
                fault: ParamFault::NotFinite,
            },
            &[0x05, 0x05, 0x17, 0x05, 0x06, 0x03, 0x06, 0x0d, 0x05, 0xa1, 0x15, 0x15, 0xe1, 0x00],
        ),
        // id 24 | 05 | 07
        (RequestId(24), ErrorReply::ModelOverflow, &[0x05, 0x05, 0x18, 0x05, 0x07, 0x04, 0xbc, 0xbc, 0xe7, 0x00]),
        // id 25 | 05 | 08
        (RequestId(25), ErrorReply::NoParams, &[0x09, 0x05, 0x19, 0x05, 0x08, 0xa6, 0xcb, 0xc1, 0x76, 0x00]),
        // id 26 | 05 | 09 | Erase 01
        (
            RequestId(26),
            ErrorReply::Storage(StorageError::Erase),
            &[0x0a, 0x05, 0x1a, 0x05, 0x09, 0x01, 0xa2, 0x86, 0x68, 0x91, 0x00],
        ),
        // id 27 | 05 | 09 | Verify 03
        (
            RequestId(27),
            ErrorReply::Storage(StorageError::Verify),
            &[0x0a, 0x05, 0x1b, 0x05, 0x09, 0x03, 0xeb, 0x80, 0xda, 0xc7, 0x00],
        ),
        // id 28 | 05 | 0a
        (RequestId(28), ErrorReply::NonFiniteSample, &[0x09, 0x05, 0x1c, 0x05, 0x0a, 0x61, 0x68, 0x04, 0x9e, 0x00]),
        (
            // id 29 | 05 | 0b | field Period 05, fault NotFinite 00
            RequestId(29),
            ErrorReply::InvalidGain { field: GainField::Period, fault: ParamFault::NotFinite },
            &[0x06, 0x05, 0x1d, 0x05, 0x0b, 0x05, 0x05, 0xb5, 0x88, 0x83, 0x3f, 0x00],
        ),
        // id 30 | 05 | 0c | OutOfRange 00
        (
            RequestId(30),
            ErrorReply::MotorDrive(DriveErrorKind::OutOfRange),
            &[0x05, 0x05, 0x1e, 0x05, 0x0c, 0x05, 0x26, 0xd5, 0x7a, 0x14, 0x00],
        ),
        // id 31 | 05 | 0d
        (RequestId(31), ErrorReply::CommitWhileDriving, &[0x09, 0x05, 0x1f, 0x05, 0x0d, 0x9b, 0x43, 0x26, 0x02, 0x00]),
        // id 32 | 05 | 0e
        (RequestId(32), ErrorReply::NotLockstep, &[0x09, 0x05, 0x20, 0x05, 0x0e, 0x8c, 0xb0, 0x18, 0xb4, 0x00]),
        // id 33 | 05 | 0f
        (RequestId(33), ErrorReply::Busy, &[0x09, 0x05, 0x21, 0x05, 0x0f, 0x2d, 0xea, 0xdd, 0xc2, 0x00]),
    ];
    covers_every_variant(&cases, error_variant, 16);
    for (id, error, golden) in cases {
        assert_golden(id, Response::Error(error), golden);
    }
}

/// The index of every variant of the enums inside messages (postcard encodes an enum as
/// its index): reordering them changes the wire format.
#[test]
fn golden_enum_indices() {
    fn index_of<T: Serialize>(value: T) -> Vec<u8> {
        let mut buffer = [0u8; 4];
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
        ParamName::SlipMin,
        ParamName::SlipMax,
    ];
    for (index, name) in (0u8..).zip(names) {
        let expected = match name {
            ParamName::SlipStiffness(i) => vec![0, index, i],
            _ => vec![0, index],
        };
        assert_eq!(index_of(ParamField::Model(name)), expected, "{name:?}");
    }
    for (index, field) in (1u8..).zip([ParamField::GearRatio, ParamField::TorqueLimit, ParamField::DirectionBand]) {
        assert_eq!(index_of(field), [index], "{field:?}");
    }
    let GearModel::MicroSlip(slip) = DISTINCT_SLIP_PARAMS.model else { unreachable!() };
    let mut buffer = [0u8; 128];
    let zero = Params { c1: 0.0, c2: 0.0, c3: 0.0, alpha: 0.0, beta: 0.0, omega: 0.0 };
    assert_eq!(postcard::to_slice(&GearModel::Genetic(zero), &mut buffer).unwrap()[0], 0);
    assert_eq!(postcard::to_slice(&GearModel::MicroSlip(slip), &mut buffer).unwrap()[0], 1);
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
}

/// Each endpoint wraps its request in its own variant, takes only its own response variant,
/// and the device's reply is that variant; the request names its endpoint.
#[test]
fn endpoints_pair_each_request_with_its_response() {
    use endpoint::*;
    fn round_trip<E: Endpoint>(request: E::Request, response: E::Response) -> (Request, Response)
    where
        E::Response: PartialEq + core::fmt::Debug + Copy,
    {
        let wire = E::reply(response);
        assert_eq!(E::response(wire), Ok(response), "{}", E::NAME);
        // An error reply or another endpoint's answer is handed back as it came.
        let error = Response::Error(ErrorReply::NoParams);
        assert_eq!(E::response(error), Err(error));
        let request = E::request(&request);
        assert_eq!(request.endpoint(), E::NAME);
        (request, wire)
    }
    let sample = EncoderSample { input_angle: 1.0, output_angle: 0.0, path: EvalPath::Direct };
    let control = ControlSample { input_angle: 1.0, output_angle: 0.0, reference: 2.0 };
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
        round_trip::<WriteParams>(PARAMS, ()),
        round_trip::<ReadParams>((), Some(PARAMS)),
        round_trip::<Commit>((), 7),
        round_trip::<Replay>(sample, feedforward),
        round_trip::<Configure>(DISTINCT_CONFIG, ()),
        round_trip::<SetReference>(2.5, ()),
        round_trip::<Control>(control, output),
        round_trip::<GetStatus>((), TickStatus::default()),
    ];
    let expected = [
        (Request::GetDeviceInfo, Response::DeviceInfo(info)),
        (Request::WriteParams(PARAMS), Response::ParamsAccepted),
        (Request::ReadParams, Response::Params(Some(PARAMS))),
        (Request::Commit, Response::Committed(7)),
        (Request::Replay(sample), Response::Feedforward(feedforward)),
        (Request::Configure(DISTINCT_CONFIG), Response::ControlAccepted),
        (Request::SetReference(2.5), Response::ControlAccepted),
        (Request::Control(control), Response::Control(output)),
        (Request::GetStatus, Response::Status(TickStatus::default())),
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
    let widest_genetic = JointParams {
        model_version: u16::MAX,
        model: GearModel::Genetic(Params {
            c1: f32::MIN,
            c2: f32::MIN,
            c3: f32::MIN,
            alpha: f32::MIN,
            beta: f32::MIN,
            omega: f32::MIN,
        }),
        gear_ratio: f32::MIN,
        torque_limit: f32::MIN,
        direction_band: f32::MIN,
    };
    let widest = JointParams {
        model: GearModel::MicroSlip(SlipParams {
            c1: f32::MIN,
            c2: f32::MIN,
            c3: f32::MIN,
            stiffness: [f32::MIN; SLIP_ELEMENTS],
            slip_min: f32::MIN,
            slip_max: f32::MIN,
        }),
        ..widest_genetic
    };
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
    let requests = [
        Request::GetStatus,
        Request::GetDeviceInfo,
        Request::WriteParams(widest_genetic),
        Request::WriteParams(widest),
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
        Request::Control(ControlSample { input_angle: f32::MIN, output_angle: f32::MIN, reference: f32::MIN }),
    ];
    let responses = [
        Response::DeviceInfo(DeviceInfo { firmware_version: version, protocol_version: big, model_version: big }),
        Response::ParamsAccepted,
        Response::Params(Some(widest_genetic)),
        Response::Params(Some(widest)),
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
    // Params(Some(widest)), micro-slip: version 1 + id u32::MAX 5 + variant 1 + Some 1 +
    // u16::MAX 3 + kind 1 + (3 + 16 + 2 + 3) × f32 96 = 108 bytes, + CRC 4, + 1 COBS code byte
    // (no zero byte to reuse; under 254 bytes), + the delimiter. A message that grows fails
    // here first.
    assert_eq!(longest, 108 + 4 + 1 + 1);
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
        Request::WriteParams(PARAMS),
        Request::WriteParams(DISTINCT_SLIP_PARAMS),
        Request::ReadParams,
        Request::Commit,
        Request::Replay(EncoderSample { input_angle: 12.5, output_angle: 0.125, path: EvalPath::Direct }),
        Request::Configure(DISTINCT_CONFIG),
        Request::SetReference(3.5),
        Request::Control(ControlSample { input_angle: -1.5, output_angle: 0.25, reference: -2.0 }),
        Request::GetStatus,
    ];
    for request in requests {
        let (out, len) = frame_of(&request);
        assert_eq!(message_of::<Request>(&out[..len]), Ok(request));
    }
    let responses = [
        Response::DeviceInfo(DeviceInfo {
            firmware_version: Version { major: 0, minor: 1, patch: 0 },
            protocol_version: PROTOCOL_VERSION,
            model_version: MODEL_VERSION,
        }),
        Response::ParamsAccepted,
        Response::Params(Some(PARAMS)),
        Response::Params(Some(DISTINCT_SLIP_PARAMS)),
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
    ];
    for response in responses {
        let (out, len) = frame_of(&response);
        assert_eq!(message_of::<Response>(&out[..len]), Ok(response));
    }
}

#[test]
fn any_flipped_bit_is_detected() {
    let (out, len) = frame_of(&Request::WriteParams(PARAMS));
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
    let (out, len) = frame_of(&Request::WriteParams(PARAMS));
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

#[test]
fn validation_names_the_field() {
    assert_eq!(PARAMS.validate(), Ok(()));
    let with = |edit: fn(&mut JointParams)| {
        let mut params = PARAMS;
        edit(&mut params);
        params.validate()
    };
    let invalid = |field, fault| Err(ErrorReply::InvalidParam { field, fault });
    fn genetic(p: &mut JointParams) -> &mut Params<f32> {
        match &mut p.model {
            GearModel::Genetic(model) => model,
            GearModel::MicroSlip(_) => unreachable!(),
        }
    }
    assert_eq!(with(|p| genetic(p).c2 = f32::NAN), invalid(ParamField::Model(ParamName::C2), ParamFault::NotFinite));
    assert_eq!(
        with(|p| genetic(p).beta = f32::INFINITY),
        invalid(ParamField::Model(ParamName::Beta), ParamFault::NotFinite)
    );
    assert_eq!(with(|p| genetic(p).omega = 0.0), invalid(ParamField::Model(ParamName::Omega), ParamFault::OutOfRange));
    assert_eq!(with(|p| p.gear_ratio = 0.5), invalid(ParamField::GearRatio, ParamFault::OutOfRange));
    assert_eq!(with(|p| p.torque_limit = 0.0), invalid(ParamField::TorqueLimit, ParamFault::OutOfRange));
    assert_eq!(with(|p| p.direction_band = -1.0), invalid(ParamField::DirectionBand, ParamFault::OutOfRange));
    assert_eq!(
        with(|p| p.model_version = MODEL_VERSION + 1),
        Err(ErrorReply::ModelVersion { got: MODEL_VERSION + 1, supported: MODEL_VERSION })
    );
}

#[test]
fn micro_slip_validation_names_the_field() {
    let with = |edit: fn(&mut SlipParams<f32, SLIP_ELEMENTS>)| {
        let mut params = DISTINCT_SLIP_PARAMS;
        let GearModel::MicroSlip(model) = &mut params.model else { unreachable!() };
        edit(model);
        params.validate()
    };
    let invalid = |field, fault| Err(ErrorReply::InvalidParam { field, fault });
    assert_eq!(with(|_| ()), Ok(()));
    assert_eq!(with(|m| m.c1 = f32::NAN), invalid(ParamField::Model(ParamName::C1), ParamFault::NotFinite));
    assert_eq!(with(|m| m.c3 = f32::NEG_INFINITY), invalid(ParamField::Model(ParamName::C3), ParamFault::NotFinite));
    assert_eq!(
        with(|m| m.stiffness[7] = f32::INFINITY),
        invalid(ParamField::Model(ParamName::SlipStiffness(7)), ParamFault::NotFinite)
    );
    assert_eq!(
        with(|m| m.stiffness[15] = -1.0),
        invalid(ParamField::Model(ParamName::SlipStiffness(15)), ParamFault::OutOfRange)
    );
    // k = 0 is an element that is not there: allowed (the fit's non-negative least squares gives it).
    assert_eq!(with(|m| m.stiffness = [0.0; SLIP_ELEMENTS]), Ok(()));
    assert_eq!(with(|m| m.slip_min = f32::NAN), invalid(ParamField::Model(ParamName::SlipMin), ParamFault::NotFinite));
    assert_eq!(
        with(|m| m.slip_max = f32::INFINITY),
        invalid(ParamField::Model(ParamName::SlipMax), ParamFault::NotFinite)
    );
    assert_eq!(with(|m| m.slip_min = 0.0), invalid(ParamField::Model(ParamName::SlipMin), ParamFault::OutOfRange));
    assert_eq!(with(|m| m.slip_min = -1.0e-5), invalid(ParamField::Model(ParamName::SlipMin), ParamFault::OutOfRange));
    assert_eq!(
        with(|m| m.slip_max = m.slip_min),
        invalid(ParamField::Model(ParamName::SlipMax), ParamFault::OutOfRange)
    );
    // The joint's own fields as for the genetic kind.
    let mut params = DISTINCT_SLIP_PARAMS;
    params.direction_band = 0.5;
    assert_eq!(params.validate(), invalid(ParamField::DirectionBand, ParamFault::OutOfRange));
    // Every set the protocol accepts, model-core accepts too.
    let GearModel::MicroSlip(model) = DISTINCT_SLIP_PARAMS.model else { unreachable!() };
    assert_eq!(model.validate(), Ok(()));
    // The error names the element.
    let error = ErrorReply::InvalidParam {
        field: ParamField::Model(ParamName::SlipStiffness(3)),
        fault: ParamFault::OutOfRange,
    };
    assert_eq!(std::format!("{error}"), "parameter stiffness[3] is out of range");
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
