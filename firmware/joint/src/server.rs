//! The link's half of the joint: bytes in, one reply frame per request frame out, the
//! parameter store, and the [`Handoff`](crate::handoff) to the control tick. It runs at the
//! board's lowest priority; the tick ([`Joint`]) preempts it whenever its timer expires, so
//! nothing here (a slow reply, a range check of a new set, a flash commit) can delay a tick
//! beyond the few instructions of an exception entry.
use crate::drive::MotorDrive;
use crate::handoff::{Answer, Command, Handoff, LinkPort, Sample, TickTiming};
use crate::tick::Joint;
use crate::{storage::ParamStore, FIRMWARE_VERSION};
use embedded_storage::nor_flash::NorFlash;
use swg_protocol::endpoint::{
    Commit, Configure, Control, FetchSamples, GetDeviceInfo, GetStatus, ReadParams, Replay, SetReference,
    StartExperiment, StopExperiment, WriteParams,
};
use swg_protocol::plan::Plan;
use swg_protocol::{
    decode_request, encode_response, ControlMode, ControllerConfig, Deferred, DeviceInfo, Endpoint, Envelope,
    ErrorReply, FrameError, FrameReader, JointParams, RequestId, RequestOf, Response, MAX_FRAME_LEN, MODEL_VERSION,
    PROTOCOL_VERSION,
};

/// A request as the link decodes it: a parameter set's bytes left in the frame buffer
/// ([`decode_request`]).
type Request = RequestOf<Deferred>;

/// The device end of the link.
pub struct Server<F> {
    reader: FrameReader<MAX_FRAME_LEN>,
    store: ParamStore<F>,
    /// The set the next tick uses: the last one accepted, or the stored one at boot. The link
    /// answers reads and commits from this copy; the tick has its own.
    params: Option<JointParams>,
    /// The last accepted controller configuration drives the motor (a mode other than `Off`).
    driving: bool,
    /// A configuration that drives was accepted since the last experiment started: an
    /// experiment's end turns the controller off, so each experiment needs one of its own.
    armed: bool,
    /// The request whose lockstep sample the tick has been handed: its answer is due.
    awaiting: Option<RequestId>,
    /// The experiment's next batch number, and the plan tick after the last batch's samples.
    batch_sequence: u32,
    next_tick: u32,
}

impl<F: NorFlash> Server<F> {
    /// A server on `store`, with no set yet: [`Server::boot`] stages the stored one. (Two
    /// steps, so that a board builds the server in its static and boots it there.)
    pub const fn new(store: ParamStore<F>) -> Self {
        Server {
            reader: FrameReader::new(),
            store,
            params: None,
            driving: false,
            armed: false,
            awaiting: None,
            batch_sequence: 0,
            next_tick: 0,
        }
    }

    /// Stages the newest valid parameter set in the store, if any, through `port` for the
    /// first tick. A stored set was validated when it was written; one that no longer
    /// validates (e.g. after a model change) leaves the compensation off. Not inlined: what
    /// it needs on the stack is gone when the link runs.
    #[inline(never)]
    pub fn boot(&mut self, port: &mut LinkPort) {
        if let Some(stored) = self.store.load() {
            if port.stage(&stored.params).is_ok() {
                self.params = Some(stored.params);
            }
        }
    }

    /// Whether the server takes the next byte: not while a lockstep sample waits for its
    /// tick, nor before the tick has taken the last command (at most one period either way).
    /// Bytes wait in the board's receive buffer meanwhile.
    pub fn ready(&self, port: &LinkPort) -> bool {
        self.awaiting.is_none() && port.has_room()
    }

    /// Feeds one received byte; when it completes a frame whose reply is ready, returns the
    /// reply frame (in the server's one frame buffer: send it before the next byte). A lockstep
    /// sample's reply comes from [`Server::poll`] once the tick has run it. Call only when
    /// [`Server::ready`].
    pub fn receive(&mut self, byte: u8, port: &mut LinkPort) -> Option<&[u8]> {
        let frame = self.reader.push(byte)?.map(|frame| frame.len());
        let len = self.answer(frame, port)?;
        self.reader.spare()?.get(..len)
    }

    /// The reply to the lockstep sample the tick has run (in the server's frame buffer, as
    /// [`Server::receive`]'s).
    pub fn poll(&mut self, port: &mut LinkPort) -> Option<&[u8]> {
        let len = self.answer_sample(port)?;
        self.reader.spare()?.get(..len)
    }

    /// The reply to the frame of `frame` bytes that the frame buffer holds (or to one that could
    /// not be read), encoded in that buffer; its length. Not inlined, as the others that make a
    /// reply: a response is on the stack only while it runs. A parameter set is decoded from the
    /// frame buffer by [`Server::write_params`], under this frame only (the link's stack is
    /// deepest while a set is decoded).
    #[inline(never)]
    fn answer(&mut self, frame: Result<usize, FrameError>, port: &mut LinkPort) -> Option<usize> {
        let request = match frame {
            Ok(len) => decode_request(self.reader.spare()?.get_mut(..len)?),
            Err(error) => Err(error),
        };
        match request {
            Ok((Envelope { id, message: Request::WriteParams(Deferred) }, set)) => {
                let accepted = match port.experiment().state().is_running() {
                    true => Err(ErrorReply::ExperimentRunning),
                    false => self.write_params(set, port),
                };
                self.accept(id, accepted)
            }
            Ok((Envelope { id, message }, _)) => self.handle(id, &message, port),
            Err(error) => self.refuse(error.request_id(), error.into()),
        }
    }

    /// [`Server::poll`]'s reply, encoded in the frame buffer; its length.
    #[inline(never)]
    fn answer_sample(&mut self, port: &mut LinkPort) -> Option<usize> {
        let id = self.awaiting?;
        let response = match port.answer()? {
            Answer::Replay(feedforward) => Replay::reply(feedforward),
            Answer::Control(output) => Control::reply(output),
            Answer::Refused(reason) => Response::Error(reason),
        };
        self.awaiting = None;
        self.reply(id, &response)
    }

    /// `response` to request `id` as a frame, encoded in the frame buffer, which no request's
    /// bytes occupy now (a whole frame was read, or a lockstep sample's answer awaited); its
    /// length.
    fn reply(&mut self, id: RequestId, response: &Response) -> Option<usize> {
        // Every response fits MAX_FRAME_LEN (tested in the protocol crate).
        encode_response(id, response, self.reader.spare()?).ok()
    }

    /// The error reply to request `id`, encoded as [`Server::reply`]'s. Not inlined: its
    /// response is not on the stack under a request being decoded.
    #[inline(never)]
    fn refuse(&mut self, id: RequestId, reason: ErrorReply) -> Option<usize> {
        self.reply(id, &Response::Error(reason))
    }

    /// The reply to a [`swg_protocol::Request::WriteParams`], `id`, encoded as
    /// [`Server::reply`]'s. Not inlined, as [`Server::refuse`].
    #[inline(never)]
    fn accept(&mut self, id: RequestId, accepted: Result<(), ErrorReply>) -> Option<usize> {
        self.reply(id, &answer::<WriteParams>(accepted))
    }

    /// The reply to `request`, encoded as [`Server::reply`]'s, or `None` when the tick has been
    /// handed its sample. Not inlined: what a request needs on the stack (a set staged, a
    /// commit, a response) is there only while it runs.
    #[inline(never)]
    fn handle(&mut self, id: RequestId, request: &Request, port: &mut LinkPort) -> Option<usize> {
        let response = match *request {
            Request::GetDeviceInfo => GetDeviceInfo::reply(DeviceInfo {
                firmware_version: FIRMWARE_VERSION,
                protocol_version: PROTOCOL_VERSION,
                model_version: MODEL_VERSION,
            }),
            Request::GetStatus => GetStatus::reply(port.status()),
            // Never here: `answer` answers it (and decodes its set).
            Request::WriteParams(Deferred) => Response::Error(ErrorReply::UndecodableRequest),
            Request::ReadParams => ReadParams::reply(self.params),
            Request::Commit => answer::<Commit>(self.commit()),
            Request::Configure(config) => answer::<Configure>(self.configure(config, port)),
            Request::SetReference(reference) => answer::<SetReference>(if reference.is_finite() {
                port.post(Command::SetReference(reference))
            } else {
                Err(ErrorReply::NonFiniteSample)
            }),
            Request::Replay(sample) => {
                let finite = sample.input_angle.is_finite() && sample.output_angle.is_finite();
                self.lockstep(id, finite, Sample::Replay(sample), port)?
            }
            Request::Control(sample) => self.lockstep(id, sample.is_finite(), Sample::Control(sample), port)?,
            Request::StartExperiment(plan) => answer::<StartExperiment>(self.start_experiment(&plan, port)),
            Request::FetchSamples => {
                let batch = port.experiment().fetch(self.batch_sequence, self.next_tick);
                self.batch_sequence = self.batch_sequence.wrapping_add(1);
                self.next_tick = batch.end_tick();
                FetchSamples::reply(batch)
            }
            Request::StopExperiment => {
                port.experiment().stop();
                StopExperiment::reply(())
            }
        };
        self.reply(id, &response)
    }

    /// Decodes the parameter set of a [`swg_protocol::Request::WriteParams`] from the frame
    /// buffer's bytes `set` (as [`decode_request`] leaves them; a set that does not decode is
    /// refused as the request would have been, [`ErrorReply::UndecodableRequest`]) and stages it.
    /// Not inlined: the set is on the stack only while it runs.
    #[inline(never)]
    fn write_params(&mut self, set: core::ops::Range<usize>, port: &mut LinkPort) -> Result<(), ErrorReply> {
        let bytes = self.reader.spare().and_then(|buffer| buffer.get(set)).ok_or(ErrorReply::UndecodableRequest)?;
        // By reference: a set moved out of the result is a second copy on the stack.
        let decoded = JointParams::from_postcard(bytes);
        let Ok(params) = &decoded else { return Err(ErrorReply::UndecodableRequest) };
        port.stage(params)?;
        self.params = Some(*params);
        Ok(())
    }

    /// A flash commit stalls the processor, and with it the tick, while it erases: refused
    /// while the controller may drive the motor. With the controller off the command is zero,
    /// and the ticks the erase takes are counted as missed.
    fn commit(&mut self) -> Result<u32, ErrorReply> {
        let params = self.params.as_ref().ok_or(ErrorReply::NoParams)?;
        if self.driving {
            return Err(ErrorReply::CommitWhileDriving);
        }
        self.store.save(params).map_err(ErrorReply::Storage)
    }

    fn configure(&mut self, config: ControllerConfig, port: &mut LinkPort) -> Result<(), ErrorReply> {
        config.validate()?;
        if port.experiment().state().is_running() {
            return Err(ErrorReply::ExperimentRunning);
        }
        port.post(Command::Configure(config))?;
        self.driving = config.mode != ControlMode::Off;
        self.armed = self.driving;
        Ok(())
    }

    /// Checks `plan` and what an experiment needs (no other running, a parameter set for the
    /// deflection, the controller configured to drive since the last experiment), then hands it
    /// to the tick; the ticks it plays.
    fn start_experiment(&mut self, plan: &Plan, port: &mut LinkPort) -> Result<u32, ErrorReply> {
        plan.check().map_err(|_| ErrorReply::InvalidPlan)?;
        if port.experiment().state().is_running() {
            return Err(ErrorReply::ExperimentRunning);
        }
        if self.params.is_none() {
            return Err(ErrorReply::NoParams);
        }
        if !self.armed {
            return Err(ErrorReply::ControllerOff);
        }
        port.experiment().start(plan)?;
        self.armed = false;
        (self.batch_sequence, self.next_tick) = (0, 0);
        Ok(plan.ticks())
    }

    fn lockstep(&mut self, id: RequestId, finite: bool, sample: Sample, port: &mut LinkPort) -> Option<Response> {
        if !finite {
            return Some(Response::Error(ErrorReply::NonFiniteSample));
        }
        match port.post(Command::Sample(sample)) {
            Ok(()) => {
                self.awaiting = Some(id);
                None
            }
            Err(reason) => Some(Response::Error(reason)),
        }
    }

    /// Gives the storage back, e.g. to simulate a reboot in tests.
    pub fn into_store(self) -> ParamStore<F> {
        self.store
    }
}

/// `result` as the endpoint's reply, or the error reply.
fn answer<E: Endpoint>(result: Result<E::Response, ErrorReply>) -> Response {
    match result {
        Ok(response) => E::reply(response),
        Err(reason) => Response::Error(reason),
    }
}

/// The whole joint in one thread, for tests and the host's fake device: the link's server and
/// the tick's joint over their handoff, the tick run (untimed) whenever the link hands it
/// something, as the board's timer would at its next expiry.
pub struct Device<F, D> {
    handoff: Handoff,
    server: Server<F>,
    joint: Joint,
    drive: D,
}

impl<F: NorFlash, D: MotorDrive> Device<F, D> {
    pub fn new(store: ParamStore<F>, drive: D) -> Self {
        let mut handoff = Handoff::new(TickTiming::UNTIMED);
        let mut server = Server::new(store);
        server.boot(&mut handoff.split().0);
        Device { handoff, server, joint: Joint::new(), drive }
    }

    /// Feeds one received byte; returns the length of the reply frame written into `out`
    /// when the byte completed a request.
    pub fn receive(&mut self, byte: u8, out: &mut [u8; MAX_FRAME_LEN]) -> Option<usize> {
        let (mut link, mut tick) = self.handoff.split();
        let mut copy = |frame: &[u8]| {
            let into = out.get_mut(..frame.len())?;
            into.copy_from_slice(frame);
            Some(frame.len())
        };
        let reply = self.server.receive(byte, &mut link).and_then(&mut copy);
        if !self.server.ready(&link) {
            self.joint.lockstep_tick(&mut tick, None, &mut self.drive);
        }
        reply.or_else(|| self.server.poll(&mut link).and_then(copy))
    }

    /// The motor drive, as the ticks left it.
    pub fn drive(&self) -> &D {
        &self.drive
    }

    /// Gives the storage back, e.g. to simulate a reboot in tests.
    pub fn into_store(self) -> ParamStore<F> {
        self.server.into_store()
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::drive::NoDrive;
    use crate::flash::RamFlash;
    use crate::test_support::Recorder;
    use model_core::Params;
    use std::vec::Vec;
    use swg_protocol::Request;
    use swg_protocol::{
        decode, encode, encode_with_version, Compensation, ControlSample, DriveErrorKind, EncoderSample, EvalPath,
        GainField, GearModel, ParamFault, ParamField, ParamName, SlipElement, Spring, StorageError, SLIP_ELEMENTS,
    };

    fn params() -> JointParams {
        JointParams {
            model_version: MODEL_VERSION,
            model: GearModel::paper(Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 68.0, beta: -2.298, omega: 1.0 }),
            gear_ratio: 100.0,
            torque_limit: 50.0,
            direction_band: 2.0e-6,
        }
    }

    const CONFIG: ControllerConfig = ControllerConfig {
        mode: ControlMode::OpenLoop,
        kp: 0.05,
        ki: 1.0,
        integral_deadband: 0.1,
        damping: 1.0e-3,
        torsion_damping: 2.0e-3,
        stiffness: 9000.0,
        command_limit: 1.0,
        period: 1.0e-3,
    };

    type Test<D = NoDrive> = Device<RamFlash<4096>, D>;

    fn device() -> Test {
        Device::new(ParamStore::new(RamFlash::new()).unwrap(), NoDrive)
    }

    fn frame(id: RequestId, request: &Request) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME_LEN];
        let len = encode(id, request, &mut out).unwrap();
        out[..len].to_vec()
    }

    /// Sends raw bytes; returns every reply they produced, with its id.
    fn exchange<D: MotorDrive>(device: &mut Test<D>, bytes: &[u8]) -> Vec<(RequestId, Response)> {
        let mut out = [0u8; MAX_FRAME_LEN];
        let mut replies = Vec::new();
        for &byte in bytes {
            if let Some(len) = device.receive(byte, &mut out) {
                let envelope = decode::<Response>(&mut out[..len - 1]).unwrap();
                replies.push((envelope.id, envelope.message));
            }
        }
        replies
    }

    /// One request, one reply, carrying the request's id.
    fn request<D: MotorDrive>(device: &mut Test<D>, request: &Request) -> Response {
        let id = RequestId(0x5EED);
        let mut replies = exchange(device, &frame(id, request));
        assert_eq!(replies.len(), 1);
        assert_eq!(replies[0].0, id, "the reply echoes the request's id");
        replies.swap_remove(0).1
    }

    fn replay<D: MotorDrive>(device: &mut Test<D>) -> Response {
        let sample = EncoderSample { input_angle: 0.05, output_angle: 0.0, path: EvalPath::Fast };
        request(device, &Request::Replay(sample))
    }

    #[test]
    fn device_info_names_all_versions() {
        let Response::DeviceInfo(info) = request(&mut device(), &Request::GetDeviceInfo) else { panic!() };
        assert_eq!(info.protocol_version, PROTOCOL_VERSION);
        assert_eq!(info.model_version, MODEL_VERSION);
        assert_eq!(info.firmware_version, FIRMWARE_VERSION);
    }

    #[test]
    fn write_read_commit_and_reboot() {
        let mut device = device();
        assert_eq!(request(&mut device, &Request::ReadParams), Response::Params(None));
        assert_eq!(request(&mut device, &Request::Commit), Response::Error(ErrorReply::NoParams));
        assert_eq!(request(&mut device, &Request::WriteParams(params())), Response::ParamsAccepted);
        assert_eq!(request(&mut device, &Request::ReadParams), Response::Params(Some(params())));
        assert_eq!(request(&mut device, &Request::Commit), Response::Committed(1));
        let mut rebooted = Device::new(device.into_store(), NoDrive);
        assert_eq!(request(&mut rebooted, &Request::ReadParams), Response::Params(Some(params())));
        let Response::Feedforward(out) = replay(&mut rebooted) else { panic!() };
        assert_eq!(out.compensation, Compensation::Active);
    }

    #[test]
    fn a_micro_slip_set_is_written_committed_and_survives_a_reboot() {
        let slip = JointParams {
            model: GearModel::micro_slip(
                0.0,
                Spring::polynomial(6.0e3, 1.2e10, 0.0),
                &model_core::memory::slip_grid::<f32, SLIP_ELEMENTS>(2.0e-5, 2.0e-3)
                    .unwrap()
                    .map(|slip| SlipElement { slip, stiffness: 150.0 }),
            )
            .unwrap(),
            ..params()
        };
        let mut device = device();
        assert_eq!(request(&mut device, &Request::WriteParams(params())), Response::ParamsAccepted);
        assert_eq!(request(&mut device, &Request::Commit), Response::Committed(1));
        assert_eq!(request(&mut device, &Request::WriteParams(slip)), Response::ParamsAccepted);
        assert_eq!(request(&mut device, &Request::ReadParams), Response::Params(Some(slip)));
        assert_eq!(request(&mut device, &Request::Commit), Response::Committed(2));
        let mut rebooted = Device::new(device.into_store(), NoDrive);
        assert_eq!(request(&mut rebooted, &Request::ReadParams), Response::Params(Some(slip)));
        let Response::Feedforward(out) = replay(&mut rebooted) else { panic!() };
        assert_eq!((out.compensation, out.direction), (Compensation::Active, None));
        // θ = 0.5 mrad from rest: the elements with d_i below it slip.
        assert!(out.memory > 0 && usize::from(out.memory) < SLIP_ELEMENTS, "{out:?}");
    }

    /// Bad frames are answered with the reason and, where the frame's id could be read, that
    /// id; the unknown id otherwise.
    #[test]
    fn bad_traffic_gets_a_reason_and_changes_nothing() {
        let mut device = device();
        request(&mut device, &Request::WriteParams(params()));
        let before = replay(&mut device);

        let nan = JointParams { model: params().model.with(ParamName::C1, f32::NAN), ..params() };
        let mut huge_band = params();
        huge_band.direction_band = 1.0;
        let good = frame(RequestId(41), &Request::WriteParams(huge_band));
        let mut corrupted = good.clone();
        corrupted[swg_protocol::payload_index(&good, 10).unwrap()] ^= 0x40;
        let truncated = [&good[..good.len() / 2], &[0u8][..]].concat();
        let mut other_version = [0u8; MAX_FRAME_LEN];
        let len =
            encode_with_version(PROTOCOL_VERSION + 1, RequestId(43), &Request::Commit, &mut other_version).unwrap();
        let too_long = [&[0x55u8; MAX_FRAME_LEN + 100][..], &[0u8][..]].concat();
        // A response where a request belongs: intact, so its id is read.
        let mut not_a_request = [0u8; MAX_FRAME_LEN];
        let not_a_request_len = encode(RequestId(44), &Response::ParamsAccepted, &mut not_a_request).unwrap();

        let unknown = RequestId::UNKNOWN;
        let cases: [(Vec<u8>, RequestId, ErrorReply); 7] = [
            (
                frame(RequestId(40), &Request::WriteParams(nan)),
                RequestId(40),
                ErrorReply::InvalidParam { field: ParamField::Model(ParamName::C1), fault: ParamFault::NotFinite },
            ),
            (
                good,
                RequestId(41),
                ErrorReply::InvalidParam { field: ParamField::DirectionBand, fault: ParamFault::OutOfRange },
            ),
            (corrupted, unknown, ErrorReply::BadCrc),
            (truncated, unknown, ErrorReply::BadFrame),
            (
                other_version[..len].to_vec(),
                unknown,
                ErrorReply::UnsupportedProtocol { got: PROTOCOL_VERSION + 1, supported: PROTOCOL_VERSION },
            ),
            (too_long, unknown, ErrorReply::FrameTooLong),
            (not_a_request[..not_a_request_len].to_vec(), RequestId(44), ErrorReply::UndecodableRequest),
        ];
        for (bytes, id, reason) in cases {
            assert_eq!(exchange(&mut device, &bytes), [(id, Response::Error(reason))]);
            assert_eq!(request(&mut device, &Request::ReadParams), Response::Params(Some(params())));
        }
        let nan_sample = EncoderSample { input_angle: f32::NAN, output_angle: 0.0, path: EvalPath::Direct };
        assert_eq!(request(&mut device, &Request::Replay(nan_sample)), Response::Error(ErrorReply::NonFiniteSample));
        // Same tick result as before: the model's memory saw the same θ again.
        assert_eq!(replay(&mut device), before);
    }

    #[test]
    fn control_requests_configure_tick_and_drive() {
        let mut device = Device::new(ParamStore::new(RamFlash::new()).unwrap(), Recorder::default());
        let sample =
            ControlSample { input_angle: 0.0, output_angle: 0.0, reference: 10.0, torque: 0.0, temperature: None };
        // Not configured, no parameters: Off, zero command, applied.
        let Response::Control(out) = request(&mut device, &Request::Control(sample)) else { panic!() };
        assert_eq!((out.command, out.mode), (0.0, ControlMode::Off));
        assert_eq!(request(&mut device, &Request::Configure(CONFIG)), Response::ControlAccepted);
        assert_eq!(request(&mut device, &Request::WriteParams(params())), Response::ParamsAccepted);
        let Response::Control(out) = request(&mut device, &Request::Control(sample)) else { panic!() };
        assert_eq!((out.command, out.mode), (10.0 / params().gear_ratio, ControlMode::OpenLoop));
        assert_eq!(device.drive().applied, [0.0, 0.1]);
        // Bad requests change nothing.
        let bad = ControllerConfig { period: 0.0, ..CONFIG };
        assert_eq!(
            request(&mut device, &Request::Configure(bad)),
            Response::Error(ErrorReply::InvalidGain { field: GainField::Period, fault: ParamFault::OutOfRange })
        );
        let nan = ControlSample { reference: f32::NAN, ..sample };
        assert_eq!(request(&mut device, &Request::Control(nan)), Response::Error(ErrorReply::NonFiniteSample));
        assert_eq!(
            request(&mut device, &Request::SetReference(f32::INFINITY)),
            Response::Error(ErrorReply::NonFiniteSample)
        );
        assert_eq!(request(&mut device, &Request::SetReference(-5.0)), Response::ControlAccepted);
        assert_eq!(device.drive().applied.len(), 2);
        // A drive that refuses: the reply says so, with its kind.
        device.drive.refuse = Some(DriveErrorKind::OutOfRange);
        assert_eq!(
            request(&mut device, &Request::Control(sample)),
            Response::Error(ErrorReply::MotorDrive(DriveErrorKind::OutOfRange))
        );
    }

    /// While the controller may drive the motor, a commit is refused (a flash erase would stall
    /// the tick); once it is configured off, the commit goes through.
    #[test]
    fn no_commit_while_the_controller_drives() {
        let mut device = device();
        assert_eq!(request(&mut device, &Request::WriteParams(params())), Response::ParamsAccepted);
        assert_eq!(request(&mut device, &Request::Configure(CONFIG)), Response::ControlAccepted);
        assert_eq!(request(&mut device, &Request::Commit), Response::Error(ErrorReply::CommitWhileDriving));
        let off = ControllerConfig { mode: ControlMode::Off, ..CONFIG };
        assert_eq!(request(&mut device, &Request::Configure(off)), Response::ControlAccepted);
        assert_eq!(request(&mut device, &Request::Commit), Response::Committed(1));
    }

    /// A store that cannot erase: the commit's reply names the step.
    #[test]
    fn a_failed_commit_says_which_step_failed() {
        use embedded_storage::nor_flash::{ErrorType, NorFlashErrorKind, ReadNorFlash};
        struct NoErase(RamFlash<4096>);
        impl ErrorType for NoErase {
            type Error = NorFlashErrorKind;
        }
        impl ReadNorFlash for NoErase {
            const READ_SIZE: usize = 1;
            fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
                self.0.read(offset, bytes)
            }
            fn capacity(&self) -> usize {
                self.0.capacity()
            }
        }
        impl NorFlash for NoErase {
            const WRITE_SIZE: usize = RamFlash::<4096>::WRITE_SIZE;
            const ERASE_SIZE: usize = RamFlash::<4096>::ERASE_SIZE;
            fn erase(&mut self, _: u32, _: u32) -> Result<(), Self::Error> {
                Err(NorFlashErrorKind::Other)
            }
            fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
                self.0.write(offset, bytes)
            }
        }
        let mut device = Device::new(ParamStore::new(NoErase(RamFlash::new())).unwrap(), NoDrive);
        let mut out = [0u8; MAX_FRAME_LEN];
        let mut reply = None;
        for request in [Request::WriteParams(params()), Request::Commit] {
            for byte in frame(RequestId(9), &request) {
                if let Some(len) = device.receive(byte, &mut out) {
                    reply = Some(decode::<Response>(&mut out[..len - 1]).unwrap().message);
                }
            }
        }
        let error = ErrorReply::Storage(StorageError::Erase);
        assert_eq!(reply, Some(Response::Error(error)));
        assert_eq!(std::format!("{error}"), "storing the parameters failed: flash erase failed");
    }

    /// The status counts the ticks the link handed work to (an in-process device is untimed).
    #[test]
    fn the_status_counts_ticks() {
        let mut device = device();
        for _ in 0..3 {
            replay(&mut device);
        }
        let Response::Status(status) = request(&mut device, &Request::GetStatus) else { panic!() };
        assert_eq!((status.rate_hz, status.ticks, status.overruns, status.late), (0, 3, 0, 0));
    }

    // The experiment (crate::experiment): the device's side, tick by tick in lockstep.

    use swg_protocol::experiment::{ExperimentState, SampleBatch, StopReason, BATCH_SAMPLES};
    use swg_protocol::plan::{Channel, Limits, Plan, Segment};

    const LIMITS: Limits = Limits { torque_nm: 20.0, deflection_rad: 0.01 };

    /// Up to 5 N·m and back in 0.1 s at `rate_hz`.
    fn torque_plan(rate_hz: f32) -> Plan {
        let segments = [Segment::Ramp { to: 5.0, seconds: 0.05 }, Segment::Ramp { to: 0.0, seconds: 0.05 }];
        Plan::new(Channel::Torque, LIMITS, rate_hz, &segments).unwrap()
    }

    /// A device with a set and the controller open-loop (u = T_ref/N, so that each command shows
    /// the reference the tick played), its experiment started.
    fn experimenting(plan: &Plan) -> Test<Recorder> {
        let mut device = Device::new(ParamStore::new(RamFlash::new()).unwrap(), Recorder::default());
        assert_eq!(request(&mut device, &Request::WriteParams(params())), Response::ParamsAccepted);
        assert_eq!(request(&mut device, &Request::Configure(CONFIG)), Response::ControlAccepted);
        assert_eq!(request(&mut device, &Request::StartExperiment(*plan)), Response::ExperimentStarted(plan.ticks()));
        device
    }

    /// One lockstep tick reading `torque`, N·m, at rest; its command.
    fn tick(device: &mut Test<Recorder>, torque: f32) -> f32 {
        let sample =
            ControlSample { input_angle: 0.0, output_angle: 0.0, reference: 3.0, torque, temperature: Some(40.0) };
        let Response::Control(output) = request(device, &Request::Control(sample)) else { panic!() };
        output.command
    }

    fn fetch<D: MotorDrive>(device: &mut Test<D>) -> SampleBatch {
        let Response::Samples(batch) = request(device, &Request::FetchSamples) else { panic!() };
        batch
    }

    #[test]
    fn an_experiment_plays_its_plan_records_every_tick_and_stops_the_motor_at_its_end() {
        let plan = torque_plan(1000.0);
        let mut device = experimenting(&plan);
        let (mut batches, mut commands) = (Vec::<SampleBatch>::new(), Vec::new());
        for k in 0..plan.ticks() + 5 {
            commands.push(tick(&mut device, 0.01 * k as f32));
            if k % BATCH_SAMPLES as u32 == 0 {
                batches.push(fetch(&mut device));
            }
        }
        // The last samples come in a batch of a finished experiment; then an empty one.
        loop {
            let batch = fetch(&mut device);
            let done = batch.samples.is_empty();
            batches.push(batch);
            if done {
                break;
            }
        }
        for (index, batch) in batches.iter().enumerate() {
            let previous = index.checked_sub(1).map(|i| &batches[i]);
            assert_eq!(batch.follows(previous), Ok(()), "batch {index}");
            assert_eq!(batch.dropped, 0);
        }
        // Fetched every 16 ticks: the queue never held more than one batch.
        assert_eq!(batches.last().unwrap().high_water, BATCH_SAMPLES as u32);
        let samples: Vec<_> = batches.iter().flat_map(|b| b.samples.iter().copied()).collect();
        assert_eq!(samples.len() as u32, plan.ticks());
        for (k, sample) in samples.iter().enumerate() {
            assert_eq!((sample.torque, sample.temperature), (0.01 * k as f32, Some(40.0)));
        }
        assert_eq!(batches.last().unwrap().state, ExperimentState::Finished);
        // Open loop: u = T_ref/N, the plan's reference, not the sample's 3 N·m; zero once it ended.
        let played: Vec<f32> = plan.player::<f32>().map(|setpoint| setpoint.value / 100.0).collect();
        let ticks = plan.ticks() as usize;
        assert_eq!(commands[..ticks], played[..]);
        assert!(commands[50] > 0.049, "{}", commands[50]);
        assert_eq!(commands[ticks..], [0.0; 5]);
        // The controller is off: the sample's reference does not drive the motor any more.
        assert_eq!(tick(&mut device, 0.0), 0.0);
    }

    #[test]
    fn a_reading_beyond_a_limit_stops_the_experiment_and_the_motor() {
        for (torque, input_angle, reason) in
            [(20.5, 0.0, StopReason::TorqueLimit), (0.0, 100.0 * 0.0105, StopReason::DeflectionLimit)]
        {
            let mut device = experimenting(&torque_plan(1000.0));
            // The first tick plays the rest the plan starts from.
            assert_eq!(tick(&mut device, 1.0), 0.0);
            for _ in 0..30 {
                assert_ne!(tick(&mut device, 1.0), 0.0);
            }
            let sample = ControlSample { input_angle, output_angle: 0.0, reference: 0.0, torque, temperature: None };
            let Response::Control(output) = request(&mut device, &Request::Control(sample)) else { panic!() };
            assert_eq!((output.command, output.mode), (0.0, ControlMode::Off), "{reason:?}");
            let mut recorded = Vec::new();
            let state = loop {
                let batch = fetch(&mut device);
                if batch.samples.is_empty() {
                    break batch.state;
                }
                recorded.extend(batch.samples);
            };
            assert_eq!(state, ExperimentState::Stopped(reason));
            // The tick beyond the limit is recorded, the last one.
            assert_eq!((recorded.len(), recorded.last().map(|s| s.torque)), (32, Some(torque)));
            assert_eq!(tick(&mut device, 1.0), 0.0);
        }
    }

    #[test]
    fn a_silent_link_stops_the_motor_within_the_timeout() {
        // 40 ms at 1 kHz: the 41st tick without a fetch (40 ms after the first) stops it.
        let mut device = experimenting(&torque_plan(1000.0));
        let commands: Vec<f32> = (0..45).map(|_| tick(&mut device, 1.0)).collect();
        // The first tick plays the rest (0) the plan starts from; the ramp runs until the stop.
        let stopped = commands.iter().skip(1).position(|&u| u == 0.0).map(|i| i + 1);
        assert_eq!(stopped, Some(40), "{commands:?}");
        assert!(commands[40..].iter().all(|&u| u == 0.0));
        assert_eq!(fetch(&mut device).state, ExperimentState::Stopped(StopReason::LinkLost));
    }

    #[test]
    fn a_full_queue_drops_samples_and_counts_them() {
        // 10 kHz: 400 silent ticks allowed, and 50 ticks without a fetch overflow the queue of 32.
        let mut device = experimenting(&torque_plan(10_000.0));
        for _ in 0..50 {
            tick(&mut device, 1.0);
        }
        let first = fetch(&mut device);
        let second = fetch(&mut device);
        assert_eq!((first.dropped, first.samples.len(), second.samples.len()), (18, 16, 16));
        assert_eq!(first.high_water, crate::experiment::QUEUE_SAMPLES as u32);
        assert_eq!(second.follows(Some(&first)), Ok(()));
        tick(&mut device, 1.0);
        let third = fetch(&mut device);
        assert_eq!(third.first_tick, 50);
        assert_eq!(
            third.follows(Some(&second)),
            Err(swg_protocol::experiment::BatchGap::Ticks { from: 32, to: 50 }),
            "the drop shows where it happened"
        );
    }

    #[test]
    fn an_experiment_is_refused_without_what_it_needs_and_guards_the_joint_while_it_runs() {
        let plan = torque_plan(1000.0);
        let mut device = device();
        let start = Request::StartExperiment(plan);
        assert_eq!(request(&mut device, &start), Response::Error(ErrorReply::NoParams));
        assert_eq!(request(&mut device, &Request::WriteParams(params())), Response::ParamsAccepted);
        assert_eq!(request(&mut device, &start), Response::Error(ErrorReply::ControllerOff));
        // A plan that does not pass the checks: its rate made NaN on the wire.
        let mut bytes = [0u8; 256];
        let len = postcard::to_slice(&plan, &mut bytes).unwrap().len();
        let rate = 1000f32.to_le_bytes();
        let at = bytes[..len].windows(4).position(|w| w == rate).unwrap();
        bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        let broken: Plan = postcard::from_bytes(&bytes[..len]).unwrap();
        assert_eq!(request(&mut device, &Request::Configure(CONFIG)), Response::ControlAccepted);
        assert_eq!(request(&mut device, &Request::StartExperiment(broken)), Response::Error(ErrorReply::InvalidPlan));
        assert_eq!(request(&mut device, &start), Response::ExperimentStarted(plan.ticks()));
        // Before its first tick as after: another start, a new set, new gains are refused.
        for refused in [start, Request::WriteParams(params()), Request::Configure(CONFIG)] {
            assert_eq!(request(&mut device, &refused), Response::Error(ErrorReply::ExperimentRunning));
        }
        assert_eq!(request(&mut device, &Request::StopExperiment), Response::ControlAccepted);
        let sample =
            ControlSample { input_angle: 0.0, output_angle: 0.0, reference: 3.0, torque: 0.0, temperature: None };
        let Response::Control(output) = request(&mut device, &Request::Control(sample)) else { panic!() };
        assert_eq!(output.command, 0.0);
        assert_eq!(fetch(&mut device).state, ExperimentState::Stopped(StopReason::Host));
        // Its end turned the controller off: the next experiment needs the controller again.
        assert_eq!(request(&mut device, &start), Response::Error(ErrorReply::ControllerOff));
        assert_eq!(request(&mut device, &Request::Configure(CONFIG)), Response::ControlAccepted);
        assert_eq!(request(&mut device, &start), Response::ExperimentStarted(plan.ticks()));
    }
}
