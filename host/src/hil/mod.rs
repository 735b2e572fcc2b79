//! `swg-host hil`: the joint firmware controls a simulated joint in lockstep, and we measure
//! what the compensation buys. Each control tick the host sends the plant's quantised encoder
//! angles and the torque reference ([`swg_protocol::Request::Control`]); the firmware runs its
//! model and torque loop and answers with the motor command, which the plant
//! ([`plant::Plant`]) holds until the next tick. Each run is scored on the *true* transmitted
//! torque against the reference ([`score`]).
pub mod lockstep;
pub mod output;
pub mod plant;
pub mod scenario;
pub mod score;

use crate::link::LinkError;
use crate::simulate::PhysicsParamError;
pub use lockstep::{run, HilOptions, HilReport, HilRun, Tick};
use model_core::GearModel;
pub use plant::{GearTruth, Plant, PlantParams};
pub use scenario::Scenario;
use swg_protocol::{ControlMode, ControllerConfig};

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum HilError {
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(
        "the device speaks protocol version {device}, this tool {}: update the firmware or swg-host",
        swg_protocol::PROTOCOL_VERSION
    )]
    Protocol { device: u16 },
    #[error("the gear's truth physics: {0}")]
    Physics(#[from] PhysicsParamError),
    #[error("the gear's truth model cannot be evaluated: {0}")]
    Truth(#[from] model_core::Error),
    #[error("the pushed model: {0}")]
    Model(String),
    #[error("plant value {name} = {value} is out of range")]
    Plant { name: &'static str, value: f64 },
    #[error("environment out of range: {0}")]
    Environment(String),
    #[error("the simulation diverged (the deflection left the joint's range, or a value became infinite or NaN)")]
    Diverged,
    #[error("run length {0} s is out of range (more than 0.5 s, at most 600 s)")]
    Seconds(f64),
    #[error("control rate {0} Hz is out of range (1 Hz to 20 kHz)")]
    Rate(f64),
}

/// The controller's gains, chosen once for the default plant at 1 kHz and used for every
/// scenario, physics and mode (README states them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gains {
    /// Motor N·m per N·m of torque error.
    pub kp: f64,
    /// Motor N·m per N·m·s of torque error.
    pub ki: f64,
    /// Motor N·m per rad/s of motor velocity (above 3 Hz).
    pub damping: f64,
    /// Motor N·m per rad/s of the deflection rate's error at the motor (N·θ̇).
    pub torsion_damping: f64,
    /// |motor torque command| limit, N·m at the motor.
    pub command_limit: f64,
}

/// The stated gains.
pub const GAINS: Gains = Gains { kp: 0.06, ki: 6.0, damping: 0.015, torsion_damping: 0.03, command_limit: 1.0 };

/// The torque range the linear mode's one stiffness is fitted over, N·m: the scenarios'
/// references stay within it.
pub const LINEAR_FIT_TORQUE: f64 = 15.0;

/// The one stiffness of the linear mode, from the pushed model: the secant T(A)/A to the tip
/// of the model's symmetric loop whose tips (the reversal points, ±A) carry
/// [`LINEAR_FIT_TORQUE`] (the model run from rest along two cycles of a sine, the tip of the
/// second), N·m/rad. (A least-squares slope over the loop would be dragged by the hysteresis:
/// the bundled genetic seed fit, run on loops smaller than its table's, is mostly hysteresis.)
pub fn linear_stiffness(model: &GearModel<f64>) -> Result<f64, HilError> {
    const POINTS: usize = 400;
    let cycle = |amplitude: f64| -> Result<(f64, f64), HilError> {
        let mut evaluator = model.evaluator(0.0)?;
        let mut tip = 0.0;
        for i in 0..2 * POINTS {
            let theta = amplitude * (std::f64::consts::TAU * i as f64 / POINTS as f64).sin();
            let torque = evaluator.step(theta)?.torque;
            if i == POINTS + POINTS / 4 {
                // θ = +A: the loop's upper reversal point.
                tip = torque;
            }
        }
        Ok((tip / amplitude, tip))
    };
    use model_core::memory::Hysteretic;
    // Bisection on the amplitude for the tip torque, up to 5 mrad (strain wave gears deflect
    // a few mrad at their rated torque; beyond, a fitted quintic may turn over).
    let (mut low, mut high) = (1.0e-7f64, 5.0e-3f64);
    for _ in 0..60 {
        let mid = (low * high).sqrt();
        // An amplitude the model cannot evaluate counts as too large.
        match cycle(mid) {
            Ok((_, peak)) if peak < LINEAR_FIT_TORQUE => low = mid,
            _ => high = mid,
        }
    }
    let (stiffness, peak) = cycle(high).or_else(|_| cycle(low))?;
    if !(stiffness.is_finite() && stiffness > 0.0 && (peak - LINEAR_FIT_TORQUE).abs() < 0.5) {
        return Err(HilError::Model(format!(
            "no loop of it reaches {LINEAR_FIT_TORQUE} N·m within the joint's range (the linear mode's stiffness)"
        )));
    }
    Ok(stiffness)
}

/// The controller configuration of `mode` with [`Gains`], the linear `stiffness`, the
/// integral's `deadband` (N·m) and the control `period`.
pub fn controller_config(
    mode: ControlMode,
    gains: &Gains,
    stiffness: f64,
    deadband: f64,
    period: f64,
) -> ControllerConfig {
    ControllerConfig {
        mode,
        kp: gains.kp as f32,
        ki: gains.ki as f32,
        integral_deadband: deadband as f32,
        damping: gains.damping as f32,
        torsion_damping: gains.torsion_damping as f32,
        stiffness: stiffness as f32,
        command_limit: gains.command_limit as f32,
        period: period as f32,
    }
}

/// The mode's name on the command line and in reports (`open-loop`, `linear`, `model`).
pub fn mode_name(mode: ControlMode) -> &'static str {
    mode.as_str()
}

/// The modes `--mode all` runs, in order.
pub const MODES: [ControlMode; 3] = [ControlMode::OpenLoop, ControlMode::Linear, ControlMode::Model];

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::checks::{micro_slip_set, SEED_TABLE_FIT};

    #[test]
    fn the_linear_stiffness_is_the_loops_secant() {
        for model in [GearModel::paper(SEED_TABLE_FIT), micro_slip_set().unwrap()] {
            let k = linear_stiffness(&model).unwrap();
            // Between the small-signal spring and the stiffening at 15 N·m.
            println!("{model:?}: {k}");
            assert!((6000.0..25_000.0).contains(&k), "{model:?}: {k}");
        }
    }
}
