//! The host end of the joint link (`swg-protocol`): a serial port or `tcp://HOST:PORT`
//! (ser2net-style bridges, QEMU), one request and one response at a time.
pub mod push;
pub mod replay;

use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};
use swg_protocol::{
    decode, encode_to_vec, ControlOutput, ControlSample, ControllerConfig, DeviceInfo, EncoderSample, ErrorReply,
    Feedforward, FrameError, FrameReader, JointParams, Request, Response, MAX_FRAME_LEN,
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
    #[error("no response from the device within {0:?} (is it running and is this its port?)")]
    Timeout(Duration),
    #[error("the device closed the link")]
    Closed,
    #[error("unreadable response: {0}")]
    Frame(FrameError),
    #[error("device refused the request: {0}")]
    Refused(ErrorReply),
    #[error("unexpected response to {request}: {response:?}")]
    Unexpected { request: &'static str, response: Response },
}

/// Byte transport under the link.
pub trait Transport: Read + Write + Send {}
impl<T: Read + Write + Send> Transport for T {}

/// A connection to one device.
pub struct Link {
    transport: Box<dyn Transport>,
    reader: FrameReader<MAX_FRAME_LEN>,
    timeout: Duration,
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

    /// A link over any byte transport.
    pub fn over(transport: Box<dyn Transport>, timeout: Duration) -> Link {
        Link { transport, reader: FrameReader::new(), timeout }
    }

    /// Sends one request; returns the device's response, error replies included.
    pub fn request(&mut self, request: &Request) -> Result<Response, LinkError> {
        let frame = encode_to_vec(request).map_err(LinkError::Frame)?;
        self.exchange(&frame)
    }

    /// Sends raw bytes (a delimiter first, so that earlier noise cannot merge with them) and
    /// waits for one response: for tests of what the device does with bad traffic.
    pub fn exchange(&mut self, bytes: &[u8]) -> Result<Response, LinkError> {
        self.transport.write_all(&[0])?;
        self.transport.write_all(bytes)?;
        self.transport.flush()?;
        self.receive()
    }

    fn receive(&mut self) -> Result<Response, LinkError> {
        let deadline = Instant::now() + self.timeout;
        let mut buffer = [0u8; 256];
        loop {
            if Instant::now() > deadline {
                return Err(LinkError::Timeout(self.timeout));
            }
            let count = match self.transport.read(&mut buffer) {
                Ok(0) => return Err(LinkError::Closed),
                Ok(count) => count,
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => continue,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e.into()),
            };
            // One request, one response: bytes after the response's delimiter cannot occur.
            for &byte in &buffer[..count] {
                if let Some(frame) = self.reader.push(byte) {
                    let frame = frame.map_err(LinkError::Frame)?;
                    return decode::<Response>(frame).map_err(LinkError::Frame);
                }
            }
        }
    }

    /// [`Link::request`] with error replies as [`LinkError::Refused`].
    fn call(&mut self, request: &Request) -> Result<Response, LinkError> {
        match self.request(request)? {
            Response::Error(reason) => Err(LinkError::Refused(reason)),
            response => Ok(response),
        }
    }

    pub fn device_info(&mut self) -> Result<DeviceInfo, LinkError> {
        match self.call(&Request::GetDeviceInfo)? {
            Response::DeviceInfo(info) => Ok(info),
            response => Err(LinkError::Unexpected { request: "device info", response }),
        }
    }

    pub fn write_params(&mut self, params: &JointParams) -> Result<(), LinkError> {
        match self.call(&Request::WriteParams(*params))? {
            Response::ParamsAccepted => Ok(()),
            response => Err(LinkError::Unexpected { request: "write parameters", response }),
        }
    }

    pub fn read_params(&mut self) -> Result<Option<JointParams>, LinkError> {
        match self.call(&Request::ReadParams)? {
            Response::Params(params) => Ok(params),
            response => Err(LinkError::Unexpected { request: "read parameters", response }),
        }
    }

    /// Stores the active set in flash; returns its sequence number.
    pub fn commit(&mut self) -> Result<u32, LinkError> {
        match self.call(&Request::Commit)? {
            Response::Committed { sequence } => Ok(sequence),
            response => Err(LinkError::Unexpected { request: "commit", response }),
        }
    }

    pub fn replay(&mut self, sample: &EncoderSample) -> Result<Feedforward, LinkError> {
        match self.call(&Request::Replay(*sample))? {
            Response::Feedforward(feedforward) => Ok(feedforward),
            response => Err(LinkError::Unexpected { request: "replay", response }),
        }
    }

    /// Sets the torque controller's mode and gains (its integral and velocity start afresh).
    pub fn configure(&mut self, config: &ControllerConfig) -> Result<(), LinkError> {
        match self.call(&Request::Configure(*config))? {
            Response::ControlAccepted => Ok(()),
            response => Err(LinkError::Unexpected { request: "configure the controller", response }),
        }
    }

    /// One lockstep control tick: angles and reference in, the motor command out.
    pub fn control(&mut self, sample: &ControlSample) -> Result<ControlOutput, LinkError> {
        match self.call(&Request::Control(*sample))? {
            Response::Control(output) => Ok(output),
            response => Err(LinkError::Unexpected { request: "control tick", response }),
        }
    }
}

/// An in-process device for the tests: the firmware's own link server behind a fake port.
#[cfg(test)]
pub(crate) mod fake {
    use super::*;
    use std::collections::VecDeque;
    use swg_joint::{flash::RamFlash, storage::ParamStore, Server};

    pub struct FakeDevice {
        pub server: Server<RamFlash<2048>>,
        pending: VecDeque<u8>,
    }

    impl FakeDevice {
        pub fn new() -> Self {
            FakeDevice { server: Server::new(ParamStore::new(RamFlash::new()).unwrap()), pending: VecDeque::new() }
        }

        pub fn link(self) -> Link {
            Link::over(Box::new(self), Duration::from_millis(100))
        }
    }

    impl Write for FakeDevice {
        fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
            let mut out = [0u8; MAX_FRAME_LEN];
            for &byte in bytes {
                if let Some(len) = self.server.receive(byte, &mut out) {
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
        let error = link.device_info().unwrap_err();
        assert!(matches!(error, LinkError::Timeout(_)), "{error}");
        assert!(error.to_string().contains("no response"));
    }

    #[test]
    fn error_replies_are_refusals() {
        let mut link = FakeDevice::new().link();
        let error = link.commit().unwrap_err();
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
}
