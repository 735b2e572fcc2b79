//! The joint's torque controller: a loop on the transmitted torque that the gear's deflection
//! gives, through one stiffness (`Linear`) or the installed model's stateful evaluator
//! (`Model`, the [`Compensator`]'s T_ff and K), or no loop at all (`OpenLoop`).
//!
//! With e = T_ref − T̂, N the installed set's gear ratio, θ the deflection and ω the motor's
//! velocity above [`DAMPING_CUTOFF_HZ`] (successive input angles over the period, minus their
//! first-order low-pass at that frequency), the motor torque command is
//!
//! ```text
//! u = T_ref/N + s·kp·e + I + torsion_damping·N·(s·Ṫ_ref/stiffness − θ̇) − damping·ω
//! I ← clamp(I + ki·e·period, ±command_limit)   while s·|e| > integral_deadband
//! ```
//!
//! clamped to ±command_limit (the integral is not advanced while u is clamped in the
//! direction of e). Rates are differences of successive ticks over the period. `s` is the gain
//! schedule: 1 in `Linear` mode, and in `Model` mode clamp(stiffness / K, ¼, 1) with K the
//! model's dT/dθ, so that the loop's gain from motor angle to torque stays at most that of the
//! nominal stiffness where the gear stiffens (fourfold from no load to its rated torque, and
//! far more just after a reversal); a softer stretch keeps the nominal gain.
//!
//! Each term has one job:
//! - **Torsion damping** damps the motor ringing on the gear (about 100 Hz with a light
//!   output). It acts on the deflection rate, so a damper across the gear, passive, and it
//!   leaves alone the motion the reference asks for: s·Ṫ_ref/stiffness is the deflection rate
//!   that tracks T_ref through the stiffness in use (the model's K in `Model` mode, which is
//!   what makes that mode follow a fast reference through a stiffening, hysteretic gear).
//! - **Damping** of the motor's own velocity (never the output's, which would feed the
//!   environment's motion back into the motor) damps the joint as a whole against its
//!   environment (a stiff contact, the motor's reflected inertia on a compliant one); above
//!   the cutoff only, so that the motor's slow travel is not resisted.
//! - **The integral's deadband** is the torque measurement's resolution: within one encoder
//!   count the integral has nothing to act on, and would hunt against the motor's stiction.
//!   `integral_deadband` is that count at the nominal stiffness; at the stiffness in use,
//!   stiffness/s, it is integral_deadband/s.
//!
//! **Safe modes.** Without a valid parameter set the controller commands u = 0 and reports
//! `Off`, whatever mode is configured: it knows neither N nor the deflection. A tick whose
//! torque estimate is unavailable (the deflection is beyond `MAX_DEFLECTION` or not finite, an
//! encoder fault; or, in `Model` mode, the model's torque is clamped at the set's torque
//! limit or cannot be evaluated) runs `OpenLoop` (u = T_ref/N), with the integral held and
//! the rates started afresh. The command is never NaN: a non-finite u (only possible from
//! non-finite inputs, which the server refuses) becomes 0.
use crate::compensator::Ticker;
use crate::limit;
use swg_protocol::{Compensation, ControlMode, ControlOutput, ControllerConfig, ErrorReply, EvalPath};

/// The gain schedule's range: kp scales by at least ¼ (the gear stiffens about fourfold from no
/// load to its rated torque) and at most 1 (measured on `swg-host hil`: a gain raised where the
/// model softens rings on the genetic gear's stiff reversals).
pub const SCHEDULE_RANGE: (f32, f32) = (0.25, 1.0);

/// The damping acts on the motor velocity above this frequency, Hz.
pub const DAMPING_CUTOFF_HZ: f32 = 3.0;

/// The torque controller's configuration and state.
#[derive(Clone, Copy, Debug, Default)]
pub struct Controller {
    config: Option<ControllerConfig>,
    reference: f32,
    integral: f32,
    /// The last tick's deflection (rad) and reference (N·m), for their rates.
    last: Option<(f32, f32)>,
    /// The last input angle, rad, and the motor velocity's low-pass, rad/s.
    last_input: Option<f32>,
    slow_velocity: f32,
    /// The low-pass's weight per tick, from the period: computed once in `configure`, as the
    /// tick's instruction budget (`crate::budget`) has no room.
    smoothing: f32,
}

impl Controller {
    /// At boot: not configured, u = 0.
    pub const fn new() -> Self {
        Controller {
            config: None,
            reference: 0.0,
            integral: 0.0,
            last: None,
            last_input: None,
            slow_velocity: 0.0,
            smoothing: 0.0,
        }
    }

    /// Validates and installs `config`; the integral and the velocity start afresh.
    pub fn configure(&mut self, config: ControllerConfig) -> Result<(), ErrorReply> {
        config.validate()?;
        self.install(config);
        Ok(())
    }

    /// Installs a configuration that [`ControllerConfig::validate`] accepted (the link
    /// validates, the tick installs); the integral and the velocity start afresh.
    pub(crate) fn install(&mut self, config: ControllerConfig) {
        // First-order low-pass at the cutoff (forward Euler, at most the whole step).
        let smoothing = limit(core::f32::consts::TAU * DAMPING_CUTOFF_HZ * config.period, 0.0, 1.0);
        *self = Controller { config: Some(config), reference: self.reference, smoothing, ..Controller::new() };
    }

    /// The configuration in use.
    pub fn config(&self) -> Option<ControllerConfig> {
        self.config
    }

    /// T_ref, N·m: the last one set or played.
    pub fn reference(&self) -> f32 {
        self.reference
    }

    /// Not configured, u = 0, as at boot: an experiment's end or stop.
    pub(crate) fn halt(&mut self) {
        *self = Controller::new();
    }

    /// Sets T_ref, N·m, for the board's own ticks; a value that is not finite is refused.
    pub fn set_reference(&mut self, reference: f32) -> Result<(), ErrorReply> {
        if !reference.is_finite() {
            return Err(ErrorReply::NonFiniteSample);
        }
        self.reference = reference;
        Ok(())
    }

    /// One control tick: steps the compensator's model (in every mode, so that its memory
    /// follows the gear's history whichever mode runs) and computes the motor command.
    pub fn tick(
        &mut self,
        compensator: &mut Ticker<'_>,
        input_angle: f32,
        output_angle: f32,
        reference: f32,
    ) -> ControlOutput {
        self.reference = reference;
        let feedforward = compensator.tick(input_angle, output_angle, EvalPath::Fast);
        let off = ControlOutput { command: 0.0, estimate: 0.0, mode: ControlMode::Off, saturated: false };
        let (Some(config), Some(gear_ratio)) = (self.config, compensator.active_gear_ratio()) else {
            self.last = None;
            self.last_input = None;
            return off;
        };
        let usable = feedforward.compensation != Compensation::Off;
        let velocity = match self.last_input {
            Some(last) if input_angle.is_finite() => (input_angle - last) / config.period,
            _ => self.slow_velocity,
        };
        self.last_input = input_angle.is_finite().then_some(input_angle);
        self.slow_velocity += self.smoothing * (velocity - self.slow_velocity);
        let fast_velocity = velocity - self.slow_velocity;
        let feedforward_command = reference / gear_ratio;
        // The torque estimate and the gain schedule, or None for an open-loop tick.
        let closed = match config.mode {
            ControlMode::Off => return off,
            ControlMode::OpenLoop => None,
            ControlMode::Linear if usable => Some((config.stiffness * feedforward.deflection, 1.0)),
            ControlMode::Model if feedforward.compensation == Compensation::Active => {
                let schedule = if feedforward.stiffness > 0.0 {
                    limit(config.stiffness / feedforward.stiffness, SCHEDULE_RANGE.0, SCHEDULE_RANGE.1)
                } else {
                    SCHEDULE_RANGE.1
                };
                Some((feedforward.torque, schedule))
            }
            ControlMode::Linear | ControlMode::Model => None,
        };
        let bound = config.command_limit;
        let Some((estimate, schedule)) = closed else {
            self.last = None;
            let (command, saturated) = clamp(feedforward_command, bound);
            return ControlOutput { command, estimate: 0.0, mode: ControlMode::OpenLoop, saturated };
        };
        let deflection = feedforward.deflection;
        // N·(s·Ṫ_ref/stiffness − θ̇), rad/s at the motor; 0 on the first closed-loop tick.
        let torsion_rate = match self.last {
            Some((last_deflection, last_reference)) => {
                let wanted = schedule * (reference - last_reference) / config.stiffness;
                gear_ratio * (wanted - (deflection - last_deflection)) / config.period
            }
            None => 0.0,
        };
        self.last = Some((deflection, reference));
        let error = reference - estimate;
        let unclamped =
            feedforward_command + schedule * config.kp * error + self.integral + config.torsion_damping * torsion_rate
                - config.damping * fast_velocity;
        let (command, saturated) = clamp(unclamped, bound);
        // Conditional integration: not further into a clamped command, not within the deadband
        // (one encoder count of torque at the stiffness in use).
        if !(saturated && (error > 0.0) == (unclamped > 0.0)) && error.abs() * schedule > config.integral_deadband {
            self.integral = limit(self.integral + config.ki * error * config.period, -bound, bound);
        }
        if !both_finite(self.integral, self.slow_velocity) {
            self.integral = 0.0;
            self.slow_velocity = 0.0;
        }
        ControlOutput { command, estimate, mode: config.mode, saturated }
    }
}

/// Whether `a` and `b` are both finite: x − x is 0 for every finite x and NaN otherwise, one
/// comparison for both where `is_finite` tests each one's bits (twice the M4F's instructions).
#[inline(always)]
#[allow(clippy::eq_op)]
fn both_finite(a: f32, b: f32) -> bool {
    (a - a) + (b - b) == 0.0
}

/// `value` within ±`bound`, and whether it was clamped; NaN becomes 0.
#[inline(always)]
fn clamp(value: f32, bound: f32) -> (f32, bool) {
    if value.is_nan() {
        return (0.0, true);
    }
    let clamped = limit(value, -bound, bound);
    (clamped, clamped != value)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::Compensator;
    use model_core::{checks::micro_slip_set, Hysteretic, MODEL_VERSION};
    use swg_protocol::JointParams;

    const RATIO: f32 = 50.0;
    const PERIOD: f32 = 1.0e-3;

    fn slip() -> JointParams {
        JointParams {
            model_version: MODEL_VERSION,
            model: micro_slip_set().unwrap().map(|_, v| v as f32),
            gear_ratio: RATIO,
            torque_limit: 60.0,
            direction_band: 0.0,
        }
    }

    /// Gains of the kind `swg-host hil` states, for the test plant below.
    fn config(mode: ControlMode) -> ControllerConfig {
        ControllerConfig {
            mode,
            kp: 0.06,
            ki: 6.0,
            integral_deadband: 0.05,
            damping: 0.015,
            torsion_damping: 0.03,
            stiffness: 9000.0,
            command_limit: 1.0,
            period: PERIOD,
        }
    }

    fn installed(mode: ControlMode) -> (Controller, Compensator) {
        let mut compensator = Compensator::new();
        compensator.stage(slip()).unwrap();
        let mut controller = Controller::new();
        controller.configure(config(mode)).unwrap();
        (controller, compensator)
    }

    /// A locked-output joint: motor inertia J with Coulomb friction on the test set's gear
    /// itself (model-core's micro-slip evaluator in f64, as truth), integrated at 10 sub-steps a
    /// tick. Returns the true torque and the controller's output per tick.
    fn run_locked(
        controller: &mut Controller,
        compensator: &mut Compensator,
        reference: f32,
        ticks: usize,
    ) -> std::vec::Vec<(f64, ControlOutput)> {
        let mut gear = micro_slip_set().unwrap().evaluator(0.0).unwrap();
        let (inertia, friction, ratio) = (1.0e-4f64, 0.02f64, f64::from(RATIO));
        let (mut angle, mut velocity, mut command, mut torque) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut out = std::vec::Vec::new();
        for _ in 0..ticks {
            for _ in 0..10 {
                let h = f64::from(PERIOD) / 10.0;
                let drive = command - torque / ratio;
                let resist =
                    if velocity != 0.0 { friction * velocity.signum() } else { drive.clamp(-friction, friction) };
                let next = velocity + h * (drive - resist) / inertia;
                velocity = if velocity != 0.0 && next.signum() != velocity.signum() { 0.0 } else { next };
                angle += h * velocity;
                torque = gear.step(angle / ratio).unwrap().torque;
            }
            let output = controller.tick(&mut compensator.ticker(), angle as f32, 0.0, reference);
            command = f64::from(output.command);
            out.push((torque, output));
        }
        out
    }

    #[test]
    fn without_parameters_the_command_is_zero() {
        let mut controller = Controller::new();
        controller.configure(config(ControlMode::Model)).unwrap();
        let mut compensator = Compensator::new();
        let out = controller.tick(&mut compensator.ticker(), 0.5, 0.0, 10.0);
        assert_eq!(out, ControlOutput { command: 0.0, estimate: 0.0, mode: ControlMode::Off, saturated: false });
        // Not configured: zero too, with parameters.
        compensator.stage(slip()).unwrap();
        let out = Controller::new().tick(&mut compensator.ticker(), 0.5, 0.0, 10.0);
        assert_eq!((out.command, out.mode), (0.0, ControlMode::Off));
    }

    #[test]
    fn open_loop_is_the_feedforward_alone() {
        let (mut controller, mut compensator) = installed(ControlMode::OpenLoop);
        let out = controller.tick(&mut compensator.ticker(), 0.01, 0.0, 10.0);
        assert_eq!(
            out,
            ControlOutput { command: 10.0 / RATIO, estimate: 0.0, mode: ControlMode::OpenLoop, saturated: false }
        );
    }

    #[test]
    fn the_command_is_clamped_and_never_nan() {
        for mode in [ControlMode::OpenLoop, ControlMode::Linear, ControlMode::Model] {
            let (mut controller, mut compensator) = installed(mode);
            // 1000 N·m asked: far beyond the 1 N·m·50 the motor may give.
            let out = controller.tick(&mut compensator.ticker(), 0.0, 0.0, 1000.0);
            assert_eq!((out.command, out.saturated), (1.0, true), "{mode:?}");
            let out = controller.tick(&mut compensator.ticker(), 0.0, 0.0, -1000.0);
            assert_eq!((out.command, out.saturated), (-1.0, true), "{mode:?}");
            // An encoder fault (deflection beyond MAX_DEFLECTION): open loop for that tick.
            let out = controller.tick(&mut compensator.ticker(), 100.0, 0.0, 5.0);
            assert_eq!((out.command, out.mode), (5.0 / RATIO, ControlMode::OpenLoop), "{mode:?}");
            // NaN angles (refused by the server, but the tick itself is safe too).
            let out = controller.tick(&mut compensator.ticker(), f32::NAN, 0.0, 5.0);
            assert!(out.command.is_finite() && out.command.abs() <= 1.0, "{mode:?} {out:?}");
            let out = controller.tick(&mut compensator.ticker(), 0.0, 0.0, f32::NAN);
            assert_eq!(out.command, 0.0, "{mode:?} {out:?}");
        }
    }

    #[test]
    fn the_integral_winds_up_no_further_than_the_limit() {
        let (mut controller, mut compensator) = installed(ControlMode::Linear);
        for _ in 0..10_000 {
            controller.tick(&mut compensator.ticker(), 0.0, 0.0, 1000.0);
        }
        // Back at a reachable reference the command leaves the limit within a few ticks.
        let ticks = (0..50).position(|_| !controller.tick(&mut compensator.ticker(), 0.0, 0.0, 0.0).saturated);
        assert!(matches!(ticks, Some(t) if t < 5), "{ticks:?}");
    }

    #[test]
    fn model_mode_closes_on_the_models_torque() {
        let (mut controller, mut compensator) = installed(ControlMode::Model);
        // θ = 0.4 mrad from rest.
        let out = controller.tick(&mut compensator.ticker(), 0.4e-3 * RATIO, 0.0, 0.0);
        let mut reference = Compensator::new();
        reference.stage(slip()).unwrap();
        let expected = reference.tick(0.4e-3 * RATIO, 0.0, EvalPath::Fast);
        assert_eq!((out.estimate, out.mode), (expected.torque, ControlMode::Model));
        // The linear mode closes on stiffness·θ instead.
        let (mut linear, mut compensator) = installed(ControlMode::Linear);
        let out = linear.tick(&mut compensator.ticker(), 0.4e-3 * RATIO, 0.0, 0.0);
        assert!((out.estimate - 9000.0 * 0.4e-3).abs() < 1e-3, "{out:?}");
    }

    #[test]
    fn a_mode_switch_starts_afresh() {
        let (mut controller, mut compensator) = installed(ControlMode::Linear);
        for _ in 0..100 {
            controller.tick(&mut compensator.ticker(), 0.0, 0.0, 5.0);
        }
        controller.configure(config(ControlMode::Model)).unwrap();
        let out = controller.tick(&mut compensator.ticker(), 0.0, 0.0, 5.0);
        // Integral, velocity and rates reset: u = T_ref/N + s·kp·e on the first tick, with s
        // from the model's K at θ = 0 (the model's memory runs on through the switch).
        let mut reference = Compensator::new();
        reference.stage(slip()).unwrap();
        let at_rest = reference.tick(0.0, 0.0, EvalPath::Fast);
        let schedule = limit(9000.0 / at_rest.stiffness, SCHEDULE_RANGE.0, SCHEDULE_RANGE.1);
        let expected = 5.0 / RATIO + schedule * config(ControlMode::Model).kp * (5.0 - at_rest.torque);
        assert!((out.command - expected).abs() < 1e-6, "{out:?} vs {expected}");
        assert_eq!(out.mode, ControlMode::Model);
        controller.configure(config(ControlMode::Off)).unwrap();
        assert_eq!(controller.tick(&mut compensator.ticker(), 0.0, 0.0, 5.0).command, 0.0);
        // A refused configuration leaves the last one.
        let bad = ControllerConfig { kp: f32::NAN, ..config(ControlMode::Model) };
        assert!(controller.configure(bad).is_err());
        assert_eq!(controller.config(), Some(config(ControlMode::Off)));
    }

    /// Within the deadband the integral rests, beyond it the integral acts: on a joint held at
    /// one deflection, the command stays put for an error of 0.8 deadbands and grows by
    /// ki·e·period a tick for 1.2; a deadband is one count at the stiffness in use, so
    /// integral_deadband/s in `Model` mode (s < 1 here: the model is stiffer than nominal).
    #[test]
    fn the_integral_rests_within_its_deadband() {
        let theta = 0.5e-3f32;
        let mut reference = Compensator::new();
        reference.stage(slip()).unwrap();
        let held = reference.tick(theta * RATIO, 0.0, EvalPath::Fast);
        let model_schedule = limit(9000.0 / held.stiffness, SCHEDULE_RANGE.0, SCHEDULE_RANGE.1);
        assert!(model_schedule < 0.9, "{model_schedule}");
        for (mode, estimate, schedule) in
            [(ControlMode::Linear, 9000.0 * theta, 1.0), (ControlMode::Model, held.torque, model_schedule)]
        {
            let deadband = config(mode).integral_deadband / schedule;
            for (error, grows) in [(0.8 * deadband, false), (1.2 * deadband, true)] {
                let (mut controller, mut compensator) = installed(mode);
                let first = controller.tick(&mut compensator.ticker(), theta * RATIO, 0.0, estimate + error).command;
                let later = (0..100)
                    .map(|_| controller.tick(&mut compensator.ticker(), theta * RATIO, 0.0, estimate + error))
                    .last();
                let growth = later.unwrap().command - first;
                let per_tick = config(mode).ki * error * PERIOD;
                if grows {
                    assert!((growth - 100.0 * per_tick).abs() < 0.05 * 100.0 * per_tick, "{mode:?} {error}: {growth}");
                } else {
                    assert_eq!(growth, 0.0, "{mode:?} {error}");
                }
            }
        }
    }

    /// The torsion damping acts on the deflection rate against the one the reference asks
    /// for: zero when θ follows Ṫ_ref/stiffness, torsion_damping·N·Ṫ_ref/stiffness with θ held,
    /// and against θ's own rate at a constant reference.
    #[test]
    fn the_torsion_damping_lets_the_asked_for_deflection_rate_through() {
        let (rate, stiffness) = (2000.0f32, config(ControlMode::Linear).stiffness);
        let undamped = ControllerConfig { torsion_damping: 0.0, ..config(ControlMode::Linear) };
        // Two ticks with (θ, T_ref) moving as given; the second command with and without it.
        let second = |config: ControllerConfig, thetas: [f32; 2], references: [f32; 2]| {
            let mut compensator = Compensator::new();
            compensator.stage(slip()).unwrap();
            let mut controller = Controller::new();
            controller.configure(config).unwrap();
            controller.tick(&mut compensator.ticker(), thetas[0] * RATIO, 0.0, references[0]);
            controller.tick(&mut compensator.ticker(), thetas[1] * RATIO, 0.0, references[1]).command
        };
        let torsion = |thetas: [f32; 2], references: [f32; 2]| {
            second(config(ControlMode::Linear), thetas, references) - second(undamped, thetas, references)
        };
        let step = rate * PERIOD;
        let theta = 2.0e-4;
        let gain = config(ControlMode::Linear).torsion_damping * RATIO;
        // Following the reference: nothing.
        let following = torsion([theta, theta + step / stiffness], [9000.0 * theta, 9000.0 * theta + step]);
        assert!(following.abs() < 1e-5, "{following}");
        // Held: the asked-for rate, pushed.
        let held = torsion([theta, theta], [9000.0 * theta, 9000.0 * theta + step]);
        assert!((held - gain * rate / stiffness).abs() < 1e-3 * held.abs(), "{held}");
        // Moving at a constant reference: resisted.
        let moving = torsion([theta, theta + step / stiffness], [9000.0 * theta; 2]);
        assert!((moving + gain * rate / stiffness).abs() < 1e-2 * moving.abs(), "{moving}");
    }

    /// Closed loop on the test plant: each loop mode settles on a step with the gains above,
    /// without oscillation once settled; the model mode on the true torque, the linear mode on
    /// its own estimate (its stiffness is not the gear's); the open loop wherever friction stops it.
    #[test]
    fn the_loop_settles_on_a_locked_joint() {
        for mode in [ControlMode::Linear, ControlMode::Model] {
            let (mut controller, mut compensator) = installed(mode);
            let run = run_locked(&mut controller, &mut compensator, 10.0, 2000);
            let settled = &run[1000..];
            let (low, high) = settled.iter().fold((f64::MAX, f64::MIN), |(l, h), &(t, _)| (l.min(t), h.max(t)));
            assert!(high - low < 0.1, "{mode:?}: peak to peak {}", high - low);
            let (torque, output) = settled[settled.len() - 1];
            assert!((output.estimate - 10.0).abs() < 0.05, "{mode:?}: {output:?}");
            assert_eq!(output.mode, mode);
            if mode == ControlMode::Model {
                assert!((torque - 10.0).abs() < 0.05, "{mode:?}: true torque {torque}");
            } else {
                assert!((torque - 10.0).abs() > 0.5, "linear on another stiffness misses: {torque}");
            }
        }
        let (mut controller, mut compensator) = installed(ControlMode::OpenLoop);
        let (torque, _) = run_locked(&mut controller, &mut compensator, 10.0, 2000)[1999];
        // At rest where friction holds the motor: within N·friction = 1 N·m of the reference.
        assert!((torque - 10.0).abs() <= 1.0 + 1e-6, "{torque}");
    }
}
