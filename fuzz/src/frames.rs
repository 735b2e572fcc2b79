//! Harness for the wire protocol's decoders (written against the protocol API of today:
//! `decode`, `FrameReader`, `Request`, `Response`): any bytes decode to a message or an error,
//! never a panic, and a decoded message encodes again.
use swg_protocol::{decode, encode_to_vec, FrameReader, Request, Response, MAX_FRAME_LEN};

/// One byte stream: decoded whole as one frame, and fed to a frame reader byte by byte.
pub fn frames(data: &[u8]) {
    let mut frame = data.to_vec();
    if let Ok(request) = decode::<Request>(&mut frame) {
        assert!(encode_to_vec(&request).is_ok());
    }
    let mut frame = data.to_vec();
    if let Ok(response) = decode::<Response>(&mut frame) {
        assert!(encode_to_vec(&response).is_ok());
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
