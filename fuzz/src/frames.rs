//! Harness for the wire protocol's decoders (written against the protocol API of today:
//! `decode`, `FrameReader`, `Request`, `Response`, request ids): any bytes decode to a message
//! or an error, never a panic, and a decoded message encodes again to a frame that decodes to
//! the same bytes (compared as bytes: a NaN is not equal to itself).
use swg_protocol::{decode, encode_to_vec, FrameReader, Request, Response, MAX_FRAME_LEN};

/// One byte stream: decoded whole as one frame, and fed to a frame reader byte by byte.
pub fn frames(data: &[u8]) {
    let mut frame = data.to_vec();
    if let Ok(request) = decode::<Request>(&mut frame) {
        round_trips(encode_to_vec(request.id, &request.message).unwrap(), |frame| {
            decode::<Request>(frame).map(|decoded| encode_to_vec(decoded.id, &decoded.message).unwrap())
        });
    }
    let mut frame = data.to_vec();
    if let Ok(response) = decode::<Response>(&mut frame) {
        round_trips(encode_to_vec(response.id, &response.message).unwrap(), |frame| {
            decode::<Response>(frame).map(|decoded| encode_to_vec(decoded.id, &decoded.message).unwrap())
        });
    }
    let mut reader = FrameReader::<MAX_FRAME_LEN>::new();
    for &byte in data {
        if let Some(Ok(frame)) = reader.push(byte) {
            assert!(frame.len() <= MAX_FRAME_LEN);
            let mut copy = frame.to_vec();
            let _ = decode::<Request>(frame);
            let _ = decode::<Response>(&mut copy);
        }
    }
}

/// `encoded` (a whole frame) decodes, and encodes again to the same bytes.
fn round_trips(encoded: Vec<u8>, again: impl Fn(&mut [u8]) -> Result<Vec<u8>, swg_protocol::FrameError>) {
    let mut body = encoded[..encoded.len() - 1].to_vec();
    assert_eq!(again(&mut body).as_ref(), Ok(&encoded));
}
