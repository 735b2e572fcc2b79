//! The control tick's half of the joint: the controller, and the compensator's tick half (in
//! the [`Handoff`](crate::handoff), where the link stages sets), run by the board's timer
//! interrupt. The link ([`crate::Server`]) hands it work through the handoff; nothing else
//! touches it.
use crate::drive::{self, MotorDrive};
use crate::experiment::{Readings, Step};
use crate::handoff::{Answer, Command, Sample, TickPort};
use crate::sensor;
use crate::Controller;
use swg_protocol::experiment::StopReason;
use swg_protocol::{ControlOutput, ErrorReply};

/// When a tick started, from the board's timer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickStart {
    /// Counts of the timer's clock from its expiry to the handler's start (a SysTick handler
    /// reads it as reload − current value, first thing).
    pub latency: u32,
    /// A free-running, wrapping count of the same clock at the handler's start: the time
    /// between two expiries tells the periods that passed without a tick.
    pub now: u32,
}

/// The controller, run by the control tick with the compensator's and the experiment's tick
/// halves.
#[derive(Clone, Debug, Default)]
pub struct Joint {
    controller: Controller,
    /// The clock count at the last timer expiry.
    last_expiry: Option<u32>,
}

impl Joint {
    /// At boot: the controller not configured (a stored set is staged by the link's
    /// [`Server::boot`](crate::Server::boot), active from the first tick).
    pub const fn new() -> Self {
        Joint { controller: Controller::new(), last_expiry: None }
    }

    /// One tick of a board without encoders of its own (QEMU): runs the sample the link handed
    /// over, if any, and answers it; the command of a lockstep control sample goes to `drive`.
    /// `start` is `None` for ticks that are not timed (an in-process device).
    pub fn lockstep_tick<D: MotorDrive>(&mut self, port: &mut TickPort, start: Option<TickStart>, drive: &mut D) {
        let Some(sample) = self.begin(port, start) else { return };
        let answer = match sample {
            Sample::Replay(sample) => {
                Answer::Replay(port.compensator().tick(sample.input_angle, sample.output_angle, sample.path))
            }
            Sample::Control(sample) => {
                let readings = Readings {
                    input_angle: sample.input_angle,
                    output_angle: sample.output_angle,
                    torque: Some(sample.torque),
                    temperature: sample.temperature,
                };
                let output = self.control(port, &readings, sample.reference, None);
                match drive.apply(output.command) {
                    Ok(()) => Answer::Control(output),
                    Err(error) => {
                        self.abort(port, StopReason::DriveFault);
                        Answer::Refused(ErrorReply::MotorDrive(drive::Error::kind(&error)))
                    }
                }
            }
        };
        port.answer(answer);
    }

    /// One tick of a board on its own sensors (the encoders' input and output angles, rad,
    /// multi-turn, and the other readings, or why they could not be read) at the reference set
    /// over the link, or an experiment's: the command goes to `drive`. A failed reading
    /// commands zero torque; failures are counted with their kind, and stop an experiment.
    /// Lockstep samples are refused ([`ErrorReply::NotLockstep`]): they would fight the
    /// encoders over the model's memory and the controller's state.
    pub fn own_tick<D: MotorDrive, E: sensor::Error>(
        &mut self,
        port: &mut TickPort,
        start: TickStart,
        readings: Result<Readings, E>,
        drive: &mut D,
    ) {
        if self.begin(port, Some(start)).is_some() {
            port.answer(Answer::Refused(ErrorReply::NotLockstep));
        }
        let timing = port.timing();
        let rate = timing.clock_hz.checked_div(timing.period);
        let command = match readings {
            Ok(readings) => self.control(port, &readings, self.controller.reference(), rate).command,
            Err(error) => {
                port.sensor_fault(error.kind());
                self.abort(port, StopReason::SensorFault);
                0.0
            }
        };
        if let Err(error) = drive.apply(command) {
            port.drive_fault(drive::Error::kind(&error));
            self.abort(port, StopReason::DriveFault);
        }
    }

    /// The controller's tick at `reference`, or at the experiment's (which records the
    /// readings, and may end at this tick: the controller is then off, its command zero).
    fn control(
        &mut self,
        port: &mut TickPort,
        readings: &Readings,
        reference: f32,
        rate: Option<u32>,
    ) -> ControlOutput {
        let (side, ticker) = port.experiment();
        let reference = match side.step(ticker, readings, self.controller.config(), rate) {
            Step::Idle => reference,
            Step::Play(planned) => planned,
            Step::Halt => {
                self.controller.halt();
                0.0
            }
        };
        self.controller.tick(port.compensator(), readings.input_angle, readings.output_angle, reference)
    }

    /// Stops a running experiment for `reason`, and the motor with it.
    fn abort(&mut self, port: &mut TickPort, reason: StopReason) {
        if port.experiment().0.halt(reason) {
            self.controller.halt();
        }
    }

    /// Switches to a set the link staged, counts the tick and its timing, applies the link's
    /// command; a lockstep sample is returned for the caller to run.
    fn begin(&mut self, port: &mut TickPort, start: Option<TickStart>) -> Option<Sample> {
        port.compensator().activate_staged();
        let timing = port.timing();
        let mut missed = 0;
        if let (Some(start), true) = (start, timing.period > 0) {
            let expiry = start.now.wrapping_sub(start.latency);
            if let Some(last) = self.last_expiry {
                // Whole periods between the two expiries, rounded: jitter in the latency cannot
                // make one out of none.
                let elapsed = expiry.wrapping_sub(last).saturating_add(timing.period / 2);
                missed = elapsed.checked_div(timing.period).unwrap_or(0).saturating_sub(1);
            }
            self.last_expiry = Some(expiry);
        }
        port.count_tick(start.filter(|_| timing.period > 0).map(|start| start.latency), missed);
        match port.command()? {
            // Validated by the link already.
            Command::Configure(config) => self.controller.install(config),
            Command::SetReference(reference) => {
                let _ = self.controller.set_reference(reference);
            }
            Command::Sample(sample) => return Some(sample),
        }
        None
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::handoff::{Handoff, TickTiming};
    use crate::test_support::Recorder;
    use swg_protocol::{ControlMode, ControlSample, ControllerConfig, DriveErrorKind, SensorErrorKind};

    const TIMING: TickTiming = TickTiming { clock_hz: 1_000_000, period: 100, late_bound: 5 };
    /// The controller open-loop (u = T_ref/N), at the 10 kHz of [`TIMING`].
    const OPEN_LOOP: ControllerConfig = ControllerConfig {
        mode: ControlMode::OpenLoop,
        kp: 0.0,
        ki: 0.0,
        integral_deadband: 0.0,
        damping: 0.0,
        torsion_damping: 0.0,
        stiffness: 1.0,
        command_limit: 1.0,
        period: 1.0e-4,
    };
    const AT_REST: Readings = Readings { input_angle: 0.0, output_angle: 0.0, torque: Some(0.0), temperature: None };

    #[test]
    fn late_ticks_and_missed_periods_are_counted() {
        let mut handoff = Handoff::new(TIMING);
        let (link, mut tick) = handoff.split();
        let mut joint = Joint::new();
        // Expiries at 1000, 1100 (latency 5: on time), 1200 (latency 6: late), then 1500
        // (latency 40: late): two periods without a tick, and the jitter of the latencies
        // makes no missed period of its own.
        for (now, latency) in [(1_000, 0), (1_105, 5), (1_206, 6), (1_540, 40), (1_601, 1)] {
            joint.lockstep_tick(&mut tick, Some(TickStart { latency, now }), &mut Recorder::default());
        }
        let status = link.status();
        assert_eq!((status.ticks, status.late, status.missed, status.overruns), (5, 2, 2, 0));
        assert_eq!(status.worst_latency_ns, 40_000);
        // The counter wraps between two ticks: still one period.
        let mut joint = Joint::new();
        for now in [u32::MAX - 50, 49] {
            joint.lockstep_tick(&mut tick, Some(TickStart { latency: 0, now }), &mut Recorder::default());
        }
        assert_eq!(link.status().missed, 2);
    }

    #[test]
    fn own_ticks_drive_count_faults_and_refuse_lockstep_samples() {
        let mut handoff = Handoff::new(TIMING);
        let (mut link, mut tick) = handoff.split();
        let mut joint = Joint::new();
        let mut drive = Recorder::default();
        let start = TickStart { latency: 0, now: 0 };
        link.post(Command::Configure(OPEN_LOOP)).unwrap();
        joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>(AT_REST), &mut drive);
        // Without parameters the controller is off: zero.
        assert_eq!(drive.applied, [0.0]);
        joint.own_tick(&mut tick, start, Err(SensorErrorKind::Corrupt), &mut drive);
        assert_eq!(drive.applied, [0.0, 0.0]);
        drive.refuse = Some(DriveErrorKind::Fault);
        joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>(AT_REST), &mut drive);
        let sample =
            ControlSample { input_angle: 0.0, output_angle: 0.0, reference: 1.0, torque: 0.0, temperature: None };
        link.post(Command::Sample(Sample::Control(sample))).unwrap();
        drive.refuse = None;
        joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>(AT_REST), &mut drive);
        assert_eq!(link.answer(), Some(Answer::Refused(ErrorReply::NotLockstep)));
        let status = link.status();
        assert_eq!((status.sensor_faults, status.last_sensor_fault), (1, Some(SensorErrorKind::Corrupt)));
        assert_eq!((status.drive_faults, status.last_drive_fault), (1, Some(DriveErrorKind::Fault)));
        assert_eq!(drive.applied, [0.0, 0.0, 0.0]);
    }

    #[test]
    fn own_ticks_stop_an_experiment_at_another_rate_or_without_a_torque_reading() {
        use model_core::Params;
        use swg_protocol::experiment::ExperimentState;
        use swg_protocol::plan::{Channel, Limits, Plan, Segment};
        use swg_protocol::{GearModel, JointParams, MODEL_VERSION};
        let params = JointParams {
            model_version: MODEL_VERSION,
            model: GearModel::paper(Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 68.0, beta: -2.298, omega: 1.0 }),
            gear_ratio: 100.0,
            torque_limit: 50.0,
            direction_band: 2.0e-6,
        };
        let limits = Limits { torque_nm: 20.0, deflection_rad: 0.01 };
        let plan =
            |rate| Plan::new(Channel::Torque, limits, rate, &[Segment::Ramp { to: 5.0, seconds: 0.05 }]).unwrap();
        let start = TickStart { latency: 0, now: 0 };
        // The board ticks at 10 kHz (TIMING).
        for (rate, readings, stopped) in [
            (1000.0, AT_REST, StopReason::PlanRate),
            (10_000.0, Readings { torque: None, ..AT_REST }, StopReason::SensorFault),
        ] {
            let mut handoff = Handoff::new(TIMING);
            let (mut link, mut tick) = handoff.split();
            let mut joint = Joint::new();
            let mut drive = Recorder::default();
            link.stage(&params).unwrap();
            link.post(Command::Configure(OPEN_LOOP)).unwrap();
            joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>(AT_REST), &mut drive);
            link.experiment().start(&plan(rate)).unwrap();
            for _ in 0..10 {
                joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>(readings), &mut drive);
            }
            assert_eq!(link.experiment().state(), ExperimentState::Stopped(stopped));
            assert!(drive.applied.iter().all(|&u| u == 0.0), "{:?}", drive.applied);
        }
        // At the board's rate it plays until a reading fails, then the motor stays at zero.
        let mut handoff = Handoff::new(TIMING);
        let (mut link, mut tick) = handoff.split();
        let (mut joint, mut drive) = (Joint::new(), Recorder::default());
        link.stage(&params).unwrap();
        link.post(Command::Configure(OPEN_LOOP)).unwrap();
        joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>(AT_REST), &mut drive);
        link.experiment().start(&plan(10_000.0)).unwrap();
        for _ in 0..30 {
            joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>(AT_REST), &mut drive);
        }
        assert!(drive.applied[30] > 0.0, "{:?}", drive.applied);
        joint.own_tick(&mut tick, start, Err(SensorErrorKind::Bus), &mut drive);
        joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>(AT_REST), &mut drive);
        assert_eq!(link.experiment().state(), ExperimentState::Stopped(StopReason::SensorFault));
        assert_eq!(drive.applied[31..], [0.0, 0.0]);
    }
}
