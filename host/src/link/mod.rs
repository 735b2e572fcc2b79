//! The host end of the joint link (`swg-protocol`): a serial port or `tcp://HOST:PORT`
//! (ser2net-style bridges, QEMU), one request at a time, each reply matched to its request by
//! the request id the device echoes. Requests go through [`Link::call`] with the endpoint
//! that pairs them with their response type (`swg_protocol::endpoint`).
pub mod push;
pub mod replay;

use std::collections::hash_map::RandomState;
use std::collections::VecDeque;
use std::hash::{BuildHasher, Hasher};
use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};
use swg_protocol::{
    decode, encode_to_vec, Endpoint, Envelope, ErrorReply, FrameError, FrameReader, RequestId, Response, MAX_FRAME_LEN,
};

/// Baud rate for serial ports; the joint boards' UARTs are set to the same.
pub const BAUD_RATE: u32 = 115_200;

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    // The cause follows as the error's source (printed by `{:#}` in the binary).
    #[error("cannot open {port}")]
    Open { port: String, source: io::Error },
    #[error("cannot open serial port {port} (a joint under QEMU or on the network is tcp://HOST:PORT)")]
    OpenSerial { port: String, source: serialport::Error },
    #[error("link I/O: {0}")]
    Io(#[from] io::Error),
    #[error(
        "no response from the device within {timeout:?} (is it running and is this its port?){}",
        unread_note(.unread)
    )]
    Timeout {
        timeout: Duration,
        /// The last error reply with the unknown id that came meanwhile: the device could not
        /// read a frame, most likely this request's.
        unread: Option<ErrorReply>,
    },
    #[error("the device closed the link")]
    Closed,
    #[error("unreadable response: {0}")]
    Frame(FrameError),
    #[error("device refused the request: {0}")]
    Refused(ErrorReply),
    #[error("unexpected response to {request}: {response:?}")]
    Unexpected { request: &'static str, response: Box<Response> },
}

fn unread_note(unread: &Option<ErrorReply>) -> String {
    match unread {
        Some(reason) => format!("; meanwhile it could not read a frame: {reason}"),
        None => String::new(),
    }
}

/// Replies the link received and did not take for the answer it waited for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Discarded {
    /// Replies carrying another request's id: late answers to a request that timed out, or a
    /// previous connection's.
    pub other_request: u64,
    /// Error replies with the unknown id: the device could not read a frame (a corrupted
    /// request, line noise).
    pub unknown_request: u64,
    /// Frames that did not decode: corrupted on the way.
    pub unreadable: u64,
}

impl Discarded {
    pub fn total(&self) -> u64 {
        self.other_request + self.unknown_request + self.unreadable
    }
}

/// Byte transport under the link.
pub trait Transport: Read + Write + Send {}
impl<T: Read + Write + Send> Transport for T {}

/// A connection to one device.
pub struct Link {
    transport: Box<dyn Transport>,
    reader: FrameReader<MAX_FRAME_LEN>,
    /// Bytes read but not yet fed to the frame reader: a read can bring a late reply and the
    /// awaited one together.
    received: VecDeque<u8>,
    timeout: Duration,
    next_id: RequestId,
    discarded: Discarded,
}

impl Link {
    /// Opens `port`: `tcp://HOST:PORT`, or a serial device such as `/dev/ttyACM0` or `COM3`.
    pub fn open(port: &str, timeout: Duration) -> Result<Link, LinkError> {
        // Reads return after this long without data, so that the deadline is checked.
        let poll = Duration::from_millis(20).min(timeout);
        let transport: Box<dyn Transport> = match port.strip_prefix("tcp://") {
            Some(address) => {
                let stream =
                    TcpStream::connect(address).map_err(|source| LinkError::Open { port: port.to_owned(), source })?;
                stream.set_nodelay(true)?;
                stream.set_read_timeout(Some(poll))?;
                Box::new(stream)
            }
            None => Box::new(
                serialport::new(port, BAUD_RATE)
                    .timeout(poll)
                    .open()
                    .map_err(|source| LinkError::OpenSerial { port: port.to_owned(), source })?,
            ),
        };
        Ok(Link::over(transport, timeout))
    }

    /// A link over any byte transport. Its request ids start at a random number, so that a
    /// reply still in flight from an earlier connection (another process, a request that
    /// timed out before a reconnect) cannot carry the id of one of this link's requests.
    pub fn over(transport: Box<dyn Transport>, timeout: Duration) -> Link {
        let random = RandomState::new().build_hasher().finish() as u32;
        Link {
            transport,
            reader: FrameReader::new(),
            received: VecDeque::new(),
            timeout,
            next_id: RequestId(random).next(),
            discarded: Discarded::default(),
        }
    }

    /// Sends `request` to endpoint `E` and waits for its reply: the endpoint's response, or
    /// the device's refusal as [`LinkError::Refused`]. Replies to other requests that arrive
    /// meanwhile are discarded and counted ([`Link::discarded`]).
    pub fn call<E: Endpoint>(&mut self, request: &E::Request) -> Result<E::Response, LinkError> {
        let id = self.next_id;
        self.next_id = id.next();
        let frame = encode_to_vec(id, &E::request(request)).map_err(LinkError::Frame)?;
        self.send(&frame)?;
        match self.reply_to(id)? {
            Response::Error(reason) => Err(LinkError::Refused(reason)),
            response => E::response(response)
                .map_err(|response| LinkError::Unexpected { request: E::NAME, response: Box::new(response) }),
        }
    }

    /// The replies this link has discarded so far.
    pub fn discarded(&self) -> Discarded {
        self.discarded
    }

    /// Sends raw bytes (a delimiter first, so that earlier noise cannot merge with them) and
    /// returns the next reply whatever its id: for tests of what the device does with bad
    /// traffic.
    pub fn exchange(&mut self, bytes: &[u8]) -> Result<Envelope<Response>, LinkError> {
        self.send(bytes)?;
        let deadline = Instant::now() + self.timeout;
        match self.next_frame(deadline)? {
            Some(frame) => frame.map_err(LinkError::Frame),
            None => Err(LinkError::Timeout { timeout: self.timeout, unread: None }),
        }
    }

    fn send(&mut self, frame: &[u8]) -> Result<(), LinkError> {
        self.transport.write_all(&[0])?;
        self.transport.write_all(frame)?;
        self.transport.flush()?;
        Ok(())
    }

    /// Waits for the reply carrying `id`, discarding every other.
    fn reply_to(&mut self, id: RequestId) -> Result<Response, LinkError> {
        let deadline = Instant::now() + self.timeout;
        let mut unread = None;
        loop {
            match self.next_frame(deadline)? {
                None => return Err(LinkError::Timeout { timeout: self.timeout, unread }),
                Some(Ok(reply)) if reply.id == id => return Ok(reply.message),
                Some(Ok(Envelope { id: RequestId::UNKNOWN, message })) => {
                    self.discarded.unknown_request += 1;
                    if let Response::Error(reason) = message {
                        unread = Some(reason);
                    }
                }
                Some(Ok(_)) => self.discarded.other_request += 1,
                // A device of another protocol: waiting longer will not help.
                Some(Err(error @ FrameError::Version(_))) => return Err(LinkError::Frame(error)),
                Some(Err(_)) => self.discarded.unreadable += 1,
            }
        }
    }

    /// The next frame received, decoded or not; `None` once `deadline` has passed.
    fn next_frame(&mut self, deadline: Instant) -> Result<Option<Result<Envelope<Response>, FrameError>>, LinkError> {
        let mut buffer = [0u8; 256];
        loop {
            while let Some(byte) = self.received.pop_front() {
                if let Some(frame) = self.reader.push(byte) {
                    return Ok(Some(frame.and_then(decode::<Response>)));
                }
            }
            if Instant::now() > deadline {
                return Ok(None);
            }
            let count = match self.transport.read(&mut buffer) {
                Ok(0) => return Err(LinkError::Closed),
                Ok(count) => count,
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => continue,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e.into()),
            };
            self.received.extend(&buffer[..count]);
        }
    }
}

#[cfg(test)]
pub(crate) mod fake {
    use super::*;
    use swg_joint::{flash::RamFlash, storage::ParamStore, Device, NoDrive};

    /// An in-process device: the firmware's own link server and tick behind a fake port.
    pub struct FakeDevice {
        device: Device<RamFlash<2048>, NoDrive>,
        /// Reply bytes not yet read.
        pub pending: VecDeque<u8>,
    }

    impl FakeDevice {
        pub fn new() -> Self {
            FakeDevice {
                device: Device::new(ParamStore::new(RamFlash::new()).unwrap(), NoDrive),
                pending: VecDeque::new(),
            }
        }

        pub fn link(self) -> Link {
            Link::over(Box::new(self), Duration::from_millis(100))
        }
    }

    impl Write for FakeDevice {
        fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
            let mut out = [0u8; MAX_FRAME_LEN];
            for &byte in bytes {
                if let Some(len) = self.device.receive(byte, &mut out) {
                    self.pending.extend(&out[..len]);
                }
            }
            Ok(bytes.len())
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Read for FakeDevice {
        fn read(&mut self, buffer: &mut [u8]) -> io::Result<usize> {
            if self.pending.is_empty() {
                std::thread::sleep(Duration::from_millis(1));
                return Err(io::ErrorKind::TimedOut.into());
            }
            let count = buffer.len().min(self.pending.len());
            for (slot, byte) in buffer.iter_mut().zip(self.pending.drain(..count)) {
                *slot = byte;
            }
            Ok(count)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::fake::FakeDevice;
    use super::*;
    use swg_protocol::endpoint::{Commit, GetDeviceInfo, GetStatus, ReadParams, Replay, WriteParams};
    use swg_protocol::{encode, Compensation, EncoderSample, EvalPath, GearModel, JointParams, Params, MODEL_VERSION};

    #[test]
    fn a_silent_device_times_out() {
        struct Silent;
        impl Read for Silent {
            fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
                std::thread::sleep(Duration::from_millis(5));
                Err(io::ErrorKind::WouldBlock.into())
            }
        }
        impl Write for Silent {
            fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
                Ok(bytes.len())
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let mut link = Link::over(Box::new(Silent), Duration::from_millis(30));
        let error = link.call::<GetDeviceInfo>(&()).unwrap_err();
        assert!(matches!(error, LinkError::Timeout { unread: None, .. }), "{error}");
        assert!(error.to_string().contains("no response"));
    }

    #[test]
    fn error_replies_are_refusals() {
        let mut link = FakeDevice::new().link();
        let error = link.call::<Commit>(&()).unwrap_err();
        assert!(matches!(error, LinkError::Refused(ErrorReply::NoParams)), "{error}");
        assert_eq!(error.to_string(), "device refused the request: no valid parameters on the device");
    }

    #[test]
    fn unknown_ports_fail_to_open_with_their_name() {
        let error = Link::open("/dev/does-not-exist", Duration::from_secs(1)).err().unwrap();
        assert!(error.to_string().contains("/dev/does-not-exist"), "{error}");
        let error = Link::open("tcp://127.0.0.1:1", Duration::from_secs(1)).err().unwrap();
        assert!(error.to_string().contains("tcp://127.0.0.1:1"), "{error}");
    }

    fn params() -> JointParams {
        JointParams {
            model_version: MODEL_VERSION,
            model: GearModel::paper(Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 68.0, beta: -2.298, omega: 1.0 }),
            gear_ratio: 100.0,
            torque_limit: 50.0,
            direction_band: 2.0e-6,
        }
    }

    /// How [`Unreliable`] delivers the reply to one request (counted from 0).
    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Delivery {
        /// Held back, and delivered after the next request's reply.
        AfterNext,
        /// Held back, and delivered before the next request's reply.
        BeforeNext,
        /// The request's frame is corrupted on the way to the device.
        CorruptRequest,
    }

    /// The fake device behind a link that delays, reorders and corrupts, request by request.
    struct Unreliable {
        device: FakeDevice,
        faults: Vec<(usize, Delivery)>,
        /// Requests seen so far (each ends with its frame's delimiter).
        requests: usize,
        /// A held reply and how it is to be delivered.
        held: Option<(Vec<u8>, Delivery)>,
        out: VecDeque<u8>,
    }

    impl Unreliable {
        fn link(faults: &[(usize, Delivery)]) -> Link {
            let transport = Unreliable {
                device: FakeDevice::new(),
                faults: faults.to_vec(),
                requests: 0,
                held: None,
                out: VecDeque::new(),
            };
            Link::over(Box::new(transport), Duration::from_millis(60))
        }
    }

    impl Write for Unreliable {
        fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
            // The link writes a lone delimiter, then one frame ending in its delimiter.
            if bytes == [0] {
                return self.device.write(bytes);
            }
            let fault = self.faults.iter().find(|(at, _)| *at == self.requests).map(|&(_, fault)| fault);
            self.requests += 1;
            let mut frame = bytes.to_vec();
            if fault == Some(Delivery::CorruptRequest) {
                frame[2] ^= 0x01;
            }
            self.device.write(&frame)?;
            let reply: Vec<u8> = self.device.pending.drain(..).collect();
            match (fault, self.held.take()) {
                (Some(delay @ (Delivery::AfterNext | Delivery::BeforeNext)), _) => self.held = Some((reply, delay)),
                (_, Some((late, Delivery::AfterNext))) => {
                    self.out.extend(reply);
                    self.out.extend(late);
                }
                (_, Some((late, _))) => {
                    self.out.extend(late);
                    self.out.extend(reply);
                }
                (_, None) => self.out.extend(reply),
            }
            Ok(bytes.len())
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Read for Unreliable {
        fn read(&mut self, buffer: &mut [u8]) -> io::Result<usize> {
            if self.out.is_empty() {
                std::thread::sleep(Duration::from_millis(1));
                return Err(io::ErrorKind::TimedOut.into());
            }
            let count = buffer.len().min(self.out.len());
            for (slot, byte) in buffer.iter_mut().zip(self.out.drain(..count)) {
                *slot = byte;
            }
            Ok(count)
        }
    }

    /// Replays θ_k = k·10 µrad (θ_in = 100·θ): each reply's deflection names its request.
    fn replay_sample(k: usize) -> EncoderSample {
        EncoderSample { input_angle: 100.0 * 1.0e-5 * k as f32, output_angle: 0.0, path: EvalPath::Direct }
    }

    fn assert_answers(link: &mut Link, k: usize) {
        let feedforward = link.call::<Replay>(&replay_sample(k)).unwrap();
        let want = replay_sample(k).input_angle / 100.0;
        assert_eq!(feedforward.deflection, want, "sample {k} got another request's answer: {feedforward:?}");
        assert_eq!(feedforward.compensation, Compensation::Active);
    }

    /// A reply held back past its request's timeout and delivered after (or before) the next
    /// request's reply is never taken for that request's answer, nor for any later one; the
    /// caller sees it counted.
    #[test]
    fn a_late_reply_is_never_taken_for_another_requests_answer() {
        for delivery in [Delivery::AfterNext, Delivery::BeforeNext] {
            // Request 0 writes the parameters; the replies to requests 2 and 5 come late.
            let mut link = Unreliable::link(&[(2, delivery), (5, delivery)]);
            link.call::<WriteParams>(&params()).unwrap();
            assert_answers(&mut link, 1);
            let error = link.call::<Replay>(&replay_sample(2)).unwrap_err();
            assert!(matches!(error, LinkError::Timeout { unread: None, .. }), "{error}");
            for k in 3..8 {
                if k == 5 {
                    assert!(link.call::<Replay>(&replay_sample(k)).is_err());
                    continue;
                }
                assert_answers(&mut link, k);
            }
            // Both late replies were read and discarded, whichever way round they came.
            assert_eq!(link.discarded(), Discarded { other_request: 2, ..Discarded::default() }, "{delivery:?}");
            // And a reply of another type cannot be mistaken either: the endpoints pair them.
            assert_eq!(link.call::<ReadParams>(&()).unwrap(), Some(params()));
        }
    }

    /// Bytes queued before the link opened — the answer a freshly booted board gives to a
    /// request of an earlier connection — are skipped by the first request.
    #[test]
    fn a_stale_answer_from_before_the_connection_is_skipped() {
        let mut device = FakeDevice::new();
        let mut stale = [0u8; MAX_FRAME_LEN];
        let len = encode(RequestId(12_345), &Response::Params(Some(params())), &mut stale).unwrap();
        device.pending.extend(&stale[..len]);
        let mut link = device.link();
        assert_eq!(link.call::<ReadParams>(&()).unwrap(), None);
        assert_eq!(link.discarded().other_request, 1);
    }

    /// A device of another protocol version answers in its own frames: named at once, not
    /// waited out.
    #[test]
    fn a_device_of_another_protocol_is_named() {
        let mut device = FakeDevice::new();
        let mut frame = [0u8; MAX_FRAME_LEN];
        let reply = Response::Error(ErrorReply::UnsupportedProtocol { got: 5, supported: 4 });
        let len = swg_protocol::encode_with_version(4, RequestId::UNKNOWN, &reply, &mut frame).unwrap();
        device.pending.extend(&frame[..len]);
        let error = device.link().call::<GetDeviceInfo>(&()).unwrap_err();
        assert!(matches!(error, LinkError::Frame(FrameError::Version(4))), "{error}");
        assert!(error.to_string().contains("peer speaks protocol version 4"), "{error}");
    }

    /// A request corrupted on the way: the device answers with the unknown id, which the link
    /// does not take for the answer; the timeout names the device's reason, and the next
    /// request is answered.
    #[test]
    fn an_unknown_id_error_is_not_an_answer() {
        let mut link = Unreliable::link(&[(1, Delivery::CorruptRequest)]);
        link.call::<GetDeviceInfo>(&()).unwrap();
        let error = link.call::<GetStatus>(&()).unwrap_err();
        assert!(
            matches!(error, LinkError::Timeout { unread: Some(ErrorReply::BadCrc | ErrorReply::BadFrame), .. }),
            "{error}"
        );
        assert!(error.to_string().contains("meanwhile it could not read a frame"), "{error}");
        assert_eq!(link.discarded(), Discarded { unknown_request: 1, ..Discarded::default() });
        assert_eq!(link.call::<GetStatus>(&()).unwrap().ticks, 0);
    }
}
