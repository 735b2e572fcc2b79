use crate::controller::{Controller, MotorDrive, NoDrive};
use crate::{storage::ParamStore, Compensator, FIRMWARE_VERSION};
use embedded_storage::nor_flash::NorFlash;
use swg_protocol::{
    decode, encode, ControlOutput, DeviceInfo, ErrorReply, FrameReader, Request, Response, MAX_FRAME_LEN,
    MODEL_VERSION, PROTOCOL_VERSION,
};

/// The device end of the link: bytes in, one response frame per request frame out.
pub struct Server<F> {
    reader: FrameReader<MAX_FRAME_LEN>,
    compensator: Compensator,
    controller: Controller,
    store: ParamStore<F>,
}

impl<F: NorFlash> Server<F> {
    /// Starts with the newest valid parameter set in `store`, if any.
    pub fn new(mut store: ParamStore<F>) -> Self {
        let mut compensator = Compensator::new();
        if let Some(stored) = store.load() {
            // A stored set was validated when it was written; one that no longer validates
            // (e.g. after a model change) leaves the compensation off.
            let _ = compensator.stage(stored.params);
        }
        Server { reader: FrameReader::new(), compensator, controller: Controller::new(), store }
    }

    /// The compensator, for a board's control tick.
    pub fn compensator(&mut self) -> &mut Compensator {
        &mut self.compensator
    }

    /// One control tick of the board's own timer at the reference set over the link: the
    /// command goes to `drive` (and is returned).
    pub fn control_tick<D: MotorDrive>(
        &mut self,
        input_angle: f32,
        output_angle: f32,
        drive: &mut D,
    ) -> Result<ControlOutput, D::Error> {
        let output = self.controller.tick_stored(&mut self.compensator, input_angle, output_angle);
        drive.apply(output.command)?;
        Ok(output)
    }

    /// Feeds one received byte; when it completes a frame, writes the response frame into
    /// `out` and returns its length. Lockstep control requests go to no motor drive (the
    /// command only comes back in the response): see [`Server::receive_driving`].
    pub fn receive(&mut self, byte: u8, out: &mut [u8; MAX_FRAME_LEN]) -> Option<usize> {
        self.receive_driving(byte, out, &mut NoDrive)
    }

    /// [`Server::receive`], with the command of a lockstep [`Request::Control`] applied to
    /// `drive` before the response is written (a refused command is answered with
    /// [`ErrorReply::MotorDrive`]).
    pub fn receive_driving<D: MotorDrive>(
        &mut self,
        byte: u8,
        out: &mut [u8; MAX_FRAME_LEN],
        drive: &mut D,
    ) -> Option<usize> {
        let response = match self.reader.push(byte)? {
            Ok(frame) => match decode::<Request>(frame) {
                Ok(request) => self.handle(request, drive),
                Err(error) => Response::Error(error.into()),
            },
            Err(error) => Response::Error(error.into()),
        };
        // Every response fits MAX_FRAME_LEN (tested in the protocol crate).
        encode(&response, out).ok()
    }

    fn handle<D: MotorDrive>(&mut self, request: Request, drive: &mut D) -> Response {
        match request {
            Request::GetDeviceInfo => Response::DeviceInfo(DeviceInfo {
                firmware_version: FIRMWARE_VERSION,
                protocol_version: PROTOCOL_VERSION,
                model_version: MODEL_VERSION,
            }),
            Request::WriteParams(params) => match self.compensator.stage(params) {
                Ok(()) => Response::ParamsAccepted,
                Err(reason) => Response::Error(reason),
            },
            Request::ReadParams => Response::Params(self.compensator.params()),
            Request::Commit => match self.compensator.params() {
                None => Response::Error(ErrorReply::NoParams),
                Some(params) => match self.store.save(&params) {
                    Ok(sequence) => Response::Committed { sequence },
                    Err(_) => Response::Error(ErrorReply::Storage),
                },
            },
            Request::Replay(sample) => {
                if !(sample.input_angle.is_finite() && sample.output_angle.is_finite()) {
                    return Response::Error(ErrorReply::NonFiniteSample);
                }
                let feedforward = self.compensator.tick(sample.input_angle, sample.output_angle, sample.path);
                Response::Feedforward(feedforward)
            }
            Request::Configure(config) => match self.controller.configure(config) {
                Ok(()) => Response::ControlAccepted,
                Err(reason) => Response::Error(reason),
            },
            Request::SetReference(reference) => match self.controller.set_reference(reference) {
                Ok(()) => Response::ControlAccepted,
                Err(reason) => Response::Error(reason),
            },
            Request::Control(sample) => {
                let finite = [sample.input_angle, sample.output_angle, sample.reference];
                if !finite.iter().all(|value| value.is_finite()) {
                    return Response::Error(ErrorReply::NonFiniteSample);
                }
                let output = self.controller.tick(
                    &mut self.compensator,
                    sample.input_angle,
                    sample.output_angle,
                    sample.reference,
                );
                match drive.apply(output.command) {
                    Ok(()) => Response::Control(output),
                    Err(_) => Response::Error(ErrorReply::MotorDrive),
                }
            }
        }
    }

    /// Gives the storage back, e.g. to simulate a reboot in tests.
    pub fn into_store(self) -> ParamStore<F> {
        self.store
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::flash::RamFlash;
    use model_core::Params;
    use std::vec::Vec;
    use swg_protocol::{
        encode_with_version, Compensation, EncoderSample, EvalPath, GearModel, JointParams, ParamFault, ParamField,
        ParamName, SlipParams, SLIP_ELEMENTS,
    };

    const PARAMS: JointParams = JointParams {
        model_version: MODEL_VERSION,
        model: GearModel::Genetic(Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 68.0, beta: -2.298, omega: 1.0 }),
        gear_ratio: 100.0,
        torque_limit: 50.0,
        direction_band: 2.0e-6,
    };

    fn server() -> Server<RamFlash<4096>> {
        Server::new(ParamStore::new(RamFlash::new()).unwrap())
    }

    fn frame(request: &Request) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME_LEN];
        let len = encode(request, &mut out).unwrap();
        out[..len].to_vec()
    }

    /// Sends raw bytes; returns every response they produced.
    fn exchange(server: &mut Server<RamFlash<4096>>, bytes: &[u8]) -> Vec<Response> {
        let mut out = [0u8; MAX_FRAME_LEN];
        let mut responses = Vec::new();
        for &byte in bytes {
            if let Some(len) = server.receive(byte, &mut out) {
                responses.push(decode(&mut out[..len - 1]).unwrap());
            }
        }
        responses
    }

    fn request(server: &mut Server<RamFlash<4096>>, request: &Request) -> Response {
        let responses = exchange(server, &frame(request));
        assert_eq!(responses.len(), 1);
        responses[0]
    }

    fn replay(server: &mut Server<RamFlash<4096>>) -> Response {
        let sample = EncoderSample { input_angle: 0.05, output_angle: 0.0, path: EvalPath::Fast };
        request(server, &Request::Replay(sample))
    }

    #[test]
    fn device_info_names_all_versions() {
        let Response::DeviceInfo(info) = request(&mut server(), &Request::GetDeviceInfo) else { panic!() };
        assert_eq!(info.protocol_version, PROTOCOL_VERSION);
        assert_eq!(info.model_version, MODEL_VERSION);
        assert_eq!(info.firmware_version, FIRMWARE_VERSION);
    }

    #[test]
    fn write_read_commit_and_reboot() {
        let mut server = server();
        assert_eq!(request(&mut server, &Request::ReadParams), Response::Params(None));
        assert_eq!(request(&mut server, &Request::Commit), Response::Error(ErrorReply::NoParams));
        assert_eq!(request(&mut server, &Request::WriteParams(PARAMS)), Response::ParamsAccepted);
        assert_eq!(request(&mut server, &Request::ReadParams), Response::Params(Some(PARAMS)));
        assert_eq!(request(&mut server, &Request::Commit), Response::Committed { sequence: 1 });
        let mut rebooted = Server::new(server.into_store());
        assert_eq!(request(&mut rebooted, &Request::ReadParams), Response::Params(Some(PARAMS)));
        let Response::Feedforward(out) = replay(&mut rebooted) else { panic!() };
        assert_eq!(out.compensation, Compensation::Active);
    }

    #[test]
    fn a_micro_slip_set_is_written_committed_and_survives_a_reboot() {
        let slip = JointParams {
            model: GearModel::MicroSlip(SlipParams {
                c1: 6.0e3,
                c2: 1.2e10,
                c3: 0.0,
                stiffness: [150.0; SLIP_ELEMENTS],
                slip_min: 2.0e-5,
                slip_max: 2.0e-3,
            }),
            ..PARAMS
        };
        let mut server = server();
        assert_eq!(request(&mut server, &Request::WriteParams(PARAMS)), Response::ParamsAccepted);
        assert_eq!(request(&mut server, &Request::Commit), Response::Committed { sequence: 1 });
        assert_eq!(request(&mut server, &Request::WriteParams(slip)), Response::ParamsAccepted);
        assert_eq!(request(&mut server, &Request::ReadParams), Response::Params(Some(slip)));
        assert_eq!(request(&mut server, &Request::Commit), Response::Committed { sequence: 2 });
        let mut rebooted = Server::new(server.into_store());
        assert_eq!(request(&mut rebooted, &Request::ReadParams), Response::Params(Some(slip)));
        let Response::Feedforward(out) = replay(&mut rebooted) else { panic!() };
        assert_eq!((out.compensation, out.direction), (Compensation::Active, None));
        // θ = 0.5 mrad from rest: the elements with d_i below it slip.
        assert!(out.memory > 0 && usize::from(out.memory) < SLIP_ELEMENTS, "{out:?}");
    }

    #[test]
    fn bad_traffic_gets_a_reason_and_changes_nothing() {
        let mut server = server();
        request(&mut server, &Request::WriteParams(PARAMS));
        let before = replay(&mut server);

        let mut nan = PARAMS;
        if let GearModel::Genetic(model) = &mut nan.model {
            model.c1 = f32::NAN;
        }
        let mut huge_band = PARAMS;
        huge_band.direction_band = 1.0;
        let good = frame(&Request::WriteParams(huge_band));
        let mut corrupted = good.clone();
        corrupted[10] ^= 0x40;
        let truncated = [&good[..good.len() / 2], &[0u8][..]].concat();
        let mut other_version = [0u8; MAX_FRAME_LEN];
        let len = encode_with_version(PROTOCOL_VERSION + 1, &Request::Commit, &mut other_version).unwrap();
        let too_long = [&[0x55u8; 300][..], &[0u8][..]].concat();

        let cases: [(Vec<u8>, ErrorReply); 6] = [
            (
                frame(&Request::WriteParams(nan)),
                ErrorReply::InvalidParam { field: ParamField::Model(ParamName::C1), fault: ParamFault::NotFinite },
            ),
            (good, ErrorReply::InvalidParam { field: ParamField::DirectionBand, fault: ParamFault::OutOfRange }),
            (corrupted, ErrorReply::BadCrc),
            (truncated, ErrorReply::BadFrame),
            (
                other_version[..len].to_vec(),
                ErrorReply::UnsupportedProtocol { got: PROTOCOL_VERSION + 1, supported: PROTOCOL_VERSION },
            ),
            (too_long, ErrorReply::FrameTooLong),
        ];
        for (bytes, reason) in cases {
            assert_eq!(exchange(&mut server, &bytes), [Response::Error(reason)]);
            assert_eq!(request(&mut server, &Request::ReadParams), Response::Params(Some(PARAMS)));
        }
        let nan_sample = EncoderSample { input_angle: f32::NAN, output_angle: 0.0, path: EvalPath::Direct };
        assert_eq!(request(&mut server, &Request::Replay(nan_sample)), Response::Error(ErrorReply::NonFiniteSample));
        // Same tick result as before: the model's memory saw the same θ again.
        assert_eq!(replay(&mut server), before);
    }

    /// A drive that records what it was given, and refuses when told to.
    #[derive(Default)]
    struct Recorder {
        applied: Vec<f32>,
        refuse: bool,
    }

    impl MotorDrive for Recorder {
        type Error = ();
        fn apply(&mut self, torque: f32) -> Result<(), ()> {
            if self.refuse {
                return Err(());
            }
            self.applied.push(torque);
            Ok(())
        }
    }

    #[test]
    fn control_requests_configure_tick_and_drive() {
        use swg_protocol::{ControlMode, ControlSample, ControllerConfig, GainField};
        let config = ControllerConfig {
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
        let mut server = server();
        let mut drive = Recorder::default();
        let talk = |server: &mut Server<RamFlash<4096>>, drive: &mut Recorder, request: &Request| {
            let mut out = [0u8; MAX_FRAME_LEN];
            let mut responses = Vec::new();
            for byte in frame(request) {
                if let Some(len) = server.receive_driving(byte, &mut out, drive) {
                    responses.push(decode::<Response>(&mut out[..len - 1]).unwrap());
                }
            }
            assert_eq!(responses.len(), 1);
            responses[0]
        };
        let sample = ControlSample { input_angle: 0.0, output_angle: 0.0, reference: 10.0 };
        // Not configured, no parameters: Off, zero command, applied.
        let Response::Control(out) = talk(&mut server, &mut drive, &Request::Control(sample)) else { panic!() };
        assert_eq!((out.command, out.mode), (0.0, ControlMode::Off));
        assert_eq!(talk(&mut server, &mut drive, &Request::Configure(config)), Response::ControlAccepted);
        assert_eq!(talk(&mut server, &mut drive, &Request::WriteParams(PARAMS)), Response::ParamsAccepted);
        let Response::Control(out) = talk(&mut server, &mut drive, &Request::Control(sample)) else { panic!() };
        assert_eq!((out.command, out.mode), (10.0 / PARAMS.gear_ratio, ControlMode::OpenLoop));
        assert_eq!(drive.applied, [0.0, 0.1]);
        // Bad requests change nothing.
        let bad = ControllerConfig { period: 0.0, ..config };
        assert_eq!(
            talk(&mut server, &mut drive, &Request::Configure(bad)),
            Response::Error(ErrorReply::InvalidGain { field: GainField::Period, fault: ParamFault::OutOfRange })
        );
        let nan = ControlSample { reference: f32::NAN, ..sample };
        assert_eq!(talk(&mut server, &mut drive, &Request::Control(nan)), Response::Error(ErrorReply::NonFiniteSample));
        assert_eq!(
            talk(&mut server, &mut drive, &Request::SetReference(f32::INFINITY)),
            Response::Error(ErrorReply::NonFiniteSample)
        );
        assert_eq!(drive.applied.len(), 2);
        // The board's own tick runs at the stored reference.
        assert_eq!(talk(&mut server, &mut drive, &Request::SetReference(-5.0)), Response::ControlAccepted);
        let out = server.control_tick(0.0, 0.0, &mut drive).unwrap();
        assert_eq!(out.command, -5.0 / PARAMS.gear_ratio);
        assert_eq!(drive.applied.last(), Some(&-0.05));
        // A drive that refuses: the reply says so.
        drive.refuse = true;
        assert_eq!(talk(&mut server, &mut drive, &Request::Control(sample)), Response::Error(ErrorReply::MotorDrive));
        assert!(server.control_tick(0.0, 0.0, &mut drive).is_err());
    }
}
