//! The control tick's half of the joint: the controller, and the compensator's tick half (in
//! the [`Handoff`](crate::handoff), where the link stages sets), run by the board's timer
//! interrupt. The link ([`crate::Server`]) hands it work through the handoff; nothing else
//! touches it.
use crate::drive::{self, MotorDrive};
use crate::handoff::{Answer, Command, Sample, TickPort};
use crate::sensor;
use crate::Controller;
use swg_protocol::ErrorReply;

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

/// The controller, run by the control tick with the compensator's tick half.
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
                let output =
                    self.controller.tick(port.compensator(), sample.input_angle, sample.output_angle, sample.reference);
                match drive.apply(output.command) {
                    Ok(()) => Answer::Control(output),
                    Err(error) => Answer::Refused(ErrorReply::MotorDrive(drive::Error::kind(&error))),
                }
            }
        };
        port.answer(answer);
    }

    /// One tick of a board on its own encoders (input and output angles, rad, multi-turn, or
    /// why they could not be read) at the reference set over the link: the command goes to
    /// `drive`. A failed reading commands zero torque; failures are counted with their kind.
    /// Lockstep samples are refused ([`ErrorReply::NotLockstep`]): they would fight the
    /// encoders over the model's memory and the controller's state.
    pub fn own_tick<D: MotorDrive, E: sensor::Error>(
        &mut self,
        port: &mut TickPort,
        start: TickStart,
        angles: Result<(f32, f32), E>,
        drive: &mut D,
    ) {
        if self.begin(port, Some(start)).is_some() {
            port.answer(Answer::Refused(ErrorReply::NotLockstep));
        }
        let command = match angles {
            Ok((input, output)) => self.controller.tick_stored(port.compensator(), input, output).command,
            Err(error) => {
                port.sensor_fault(error.kind());
                0.0
            }
        };
        if let Err(error) = drive.apply(command) {
            port.drive_fault(drive::Error::kind(&error));
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
        let config = ControllerConfig {
            mode: ControlMode::OpenLoop,
            kp: 0.0,
            ki: 0.0,
            integral_deadband: 0.0,
            damping: 0.0,
            torsion_damping: 0.0,
            stiffness: 1.0,
            command_limit: 1.0,
            period: 5.0e-5,
        };
        link.post(Command::Configure(config)).unwrap();
        joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>((0.0, 0.0)), &mut drive);
        // Without parameters the controller is off: zero.
        assert_eq!(drive.applied, [0.0]);
        joint.own_tick(&mut tick, start, Err(SensorErrorKind::Corrupt), &mut drive);
        assert_eq!(drive.applied, [0.0, 0.0]);
        drive.refuse = Some(DriveErrorKind::Fault);
        joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>((0.0, 0.0)), &mut drive);
        let sample = ControlSample { input_angle: 0.0, output_angle: 0.0, reference: 1.0 };
        link.post(Command::Sample(Sample::Control(sample))).unwrap();
        drive.refuse = None;
        joint.own_tick(&mut tick, start, Ok::<_, SensorErrorKind>((0.0, 0.0)), &mut drive);
        assert_eq!(link.answer(), Some(Answer::Refused(ErrorReply::NotLockstep)));
        let status = link.status();
        assert_eq!((status.sensor_faults, status.last_sensor_fault), (1, Some(SensorErrorKind::Corrupt)));
        assert_eq!((status.drive_faults, status.last_drive_fault), (1, Some(DriveErrorKind::Fault)));
        assert_eq!(drive.applied, [0.0, 0.0, 0.0]);
    }
}
