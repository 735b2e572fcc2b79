extern crate std;
use super::*;
use std::{vec, vec::Vec};

const PARAMS: JointParams = JointParams {
    model_version: MODEL_VERSION,
    model: Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 2.0, beta: -2.298, omega: 1.0 },
    gear_ratio: 100.0,
    torque_limit: 50.0,
    direction_band: 2.0e-5,
};

fn frame_of<T: Serialize>(message: &T) -> ([u8; MAX_FRAME_LEN], usize) {
    let mut out = [0u8; MAX_FRAME_LEN];
    let len = encode(message, &mut out).unwrap();
    (out, len)
}

/// Decodes a whole frame as sent, delimiter included.
fn decode_sent<T: for<'a> Deserialize<'a>>(sent: &[u8]) -> Result<T, FrameError> {
    let (last, body) = sent.split_last().unwrap();
    assert_eq!(*last, 0, "frames end with the delimiter");
    let mut body = body.to_vec();
    decode(&mut body)
}

/// The encoding is the contract with deployed firmware: these bytes must not change
/// without a new PROTOCOL_VERSION.
#[test]
fn golden_bytes() {
    let cases: [(Request, &[u8]); 4] = [
        (Request::GetDeviceInfo, &[0x02, 0x01, 0x05, 0xbe, 0x23, 0xc2, 0x58, 0x00]),
        (Request::ReadParams, &[0x07, 0x01, 0x02, 0x92, 0x42, 0xcc, 0xb6, 0x00]),
        (Request::Commit, &[0x07, 0x01, 0x03, 0x04, 0x72, 0xcb, 0xc1, 0x00]),
        (
            Request::Replay(EncoderSample { input_angle: 1.0, output_angle: -0.5, path: EvalPath::Fast }),
            &[
                // version 1, variant 4, f32 1.0, f32 -0.5, Fast, CRC; COBS-stuffed
                0x03, 0x01, 0x04, 0x01, 0x03, 0x80, 0x3f, 0x01, 0x01, 0x07, 0xbf, 0x01, 0x3d, 0x13, 0x82, 0xca, 0x00,
            ],
        ),
    ];
    for (request, expected) in cases {
        let (out, len) = frame_of(&request);
        assert_eq!(&out[..len], expected, "{request:?}");
    }
    let response = Response::Error(ErrorReply::UnsupportedProtocol { got: 7, supported: 1 });
    let (out, len) = frame_of(&response);
    assert_eq!(&out[..len], &[0x0a, 0x01, 0x05, 0x03, 0x07, 0x01, 0x97, 0x36, 0x9c, 0xf6, 0x00]);
}

#[test]
fn every_message_round_trips() {
    let requests = [
        Request::GetDeviceInfo,
        Request::WriteParams(PARAMS),
        Request::ReadParams,
        Request::Commit,
        Request::Replay(EncoderSample { input_angle: 12.5, output_angle: 0.125, path: EvalPath::Direct }),
    ];
    for request in requests {
        let (out, len) = frame_of(&request);
        assert_eq!(decode_sent::<Request>(&out[..len]), Ok(request));
    }
    let responses = [
        Response::DeviceInfo(DeviceInfo {
            firmware_version: Version { major: 0, minor: 1, patch: 0 },
            protocol_version: PROTOCOL_VERSION,
            model_version: MODEL_VERSION,
        }),
        Response::ParamsAccepted,
        Response::Params(Some(PARAMS)),
        Response::Params(None),
        Response::Committed { sequence: u32::MAX },
        Response::Feedforward(Feedforward {
            deflection: -1.0e-3,
            direction: Direction::Falling,
            amplitude: 1.2e-3,
            torque: -f32::MAX,
            stiffness: 1.0e6,
            compensation: Compensation::Clamped,
        }),
        Response::Error(ErrorReply::InvalidParam { field: ParamField::DirectionBand, fault: ParamFault::OutOfRange }),
    ];
    for response in responses {
        let (out, len) = frame_of(&response);
        assert!(len <= MAX_FRAME_LEN);
        assert_eq!(decode_sent::<Response>(&out[..len]), Ok(response));
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
            let result = decode_sent::<Request>(&corrupted);
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
    let len = encode_with_version(PROTOCOL_VERSION + 1, &Request::GetDeviceInfo, &mut out).unwrap();
    assert_eq!(decode_sent::<Request>(&out[..len]), Err(FrameError::Version(PROTOCOL_VERSION + 1)));
    assert_eq!(
        ErrorReply::from(FrameError::Version(2)),
        ErrorReply::UnsupportedProtocol { got: 2, supported: PROTOCOL_VERSION }
    );
}

#[test]
fn a_response_is_not_taken_for_a_request() {
    // Same version and CRC, but variant 5 does not exist among requests.
    let (out, len) = frame_of(&Response::Error(ErrorReply::BadCrc));
    assert_eq!(decode_sent::<Request>(&out[..len]), Err(FrameError::Message));
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
            results.push(frame.map(decode::<Request>));
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
    assert_eq!(with(|p| p.model.c2 = f32::NAN), invalid(ParamField::C2, ParamFault::NotFinite));
    assert_eq!(with(|p| p.model.beta = f32::INFINITY), invalid(ParamField::Beta, ParamFault::NotFinite));
    assert_eq!(with(|p| p.model.omega = 0.0), invalid(ParamField::Omega, ParamFault::OutOfRange));
    assert_eq!(with(|p| p.gear_ratio = 0.5), invalid(ParamField::GearRatio, ParamFault::OutOfRange));
    assert_eq!(with(|p| p.torque_limit = 0.0), invalid(ParamField::TorqueLimit, ParamFault::OutOfRange));
    assert_eq!(with(|p| p.direction_band = -1.0), invalid(ParamField::DirectionBand, ParamFault::OutOfRange));
    assert_eq!(
        with(|p| p.model_version = MODEL_VERSION + 1),
        Err(ErrorReply::ModelVersion { got: MODEL_VERSION + 1, supported: MODEL_VERSION })
    );
}
