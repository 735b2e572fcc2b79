//! The simulated joint the firmware controls in lockstep: a motor with Coulomb and viscous
//! friction, the gear ratio, the gear's truth physics (independent of the model pushed to the
//! joint), and the output's inertia against an environment ([`super::scenario`]). Integrated
//! with a fixed step, [`PlantParams::substeps`] steps per control tick.
use super::scenario::Environment;
use super::HilError;
use crate::simulate::physics::Gear;
use crate::simulate::Physics;
use model_core::memory::Hysteretic;
use model_core::{Evaluator, GearModel};
use std::f64::consts::TAU;

/// The joint's mechanics. The defaults are those of a 20-size harmonic drive joint (N = 50).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantParams {
    /// Reduction ratio N.
    pub ratio: f64,
    /// Motor rotor and wave generator, kg·m².
    pub motor_inertia: f64,
    /// Motor-side Coulomb friction (bearings, wave generator), N·m at the motor.
    pub motor_coulomb: f64,
    /// Motor-side viscous friction, N·m·s/rad at the motor.
    pub motor_viscous: f64,
    /// Motor encoder resolution, bits per revolution.
    pub input_bits: u32,
    /// Output encoder resolution, bits per revolution.
    pub output_bits: u32,
    /// Integration steps per control tick (≥ 10).
    pub substeps: usize,
}

impl Default for PlantParams {
    fn default() -> Self {
        PlantParams {
            ratio: 50.0,
            // A 200 W servo motor's rotor (≈ 0.8·10⁻⁴) and a 20-size wave generator (≈ 0.2·10⁻⁴).
            motor_inertia: 1.0e-4,
            // 0.02 N·m at the motor is 1 N·m at the output: a 20-size unit's no-load running
            // torque and the motor's bearings and seal.
            motor_coulomb: 0.02,
            motor_viscous: 2.0e-5,
            input_bits: 17,
            output_bits: 20,
            substeps: 10,
        }
    }
}

impl PlantParams {
    /// One count of each encoder, rad.
    pub fn counts(&self) -> (f64, f64) {
        (TAU / 2f64.powi(self.input_bits as i32), TAU / 2f64.powi(self.output_bits as i32))
    }

    /// The deflection one encoder count stands for, rad: the coarser of an output count and a
    /// motor count through the gear.
    pub fn deflection_count(&self) -> f64 {
        let (input, output) = self.counts();
        (input / self.ratio).max(output)
    }

    pub fn validate(&self) -> Result<(), HilError> {
        let checks = [
            ("ratio", self.ratio, self.ratio >= 1.0),
            ("motor inertia", self.motor_inertia, self.motor_inertia > 0.0),
            ("motor Coulomb friction", self.motor_coulomb, self.motor_coulomb >= 0.0),
            ("motor viscous friction", self.motor_viscous, self.motor_viscous >= 0.0),
            ("input bits", f64::from(self.input_bits), (8..=32).contains(&self.input_bits)),
            ("output bits", f64::from(self.output_bits), (8..=32).contains(&self.output_bits)),
            ("substeps", self.substeps as f64, self.substeps >= 10),
        ];
        match checks.into_iter().find(|(_, value, ok)| !(*ok && value.is_finite())) {
            Some((name, value, _)) => Err(HilError::Plant { name, value }),
            None => Ok(()),
        }
    }
}

/// The genetic truth's reversal band, rad: the integrator's sub-steps make reversals of
/// 10⁻¹² rad, whose branches overflow the genetic model's formula; 1 nrad, three orders below
/// an encoder count, keeps the truth's memory to reversals that exist.
pub const TRUTH_BAND: f64 = 1.0e-9;

/// The gear's truth physics: the simulator's (`--physics`, with its defaults) or any model a
/// params file holds (`--gear`), run from rest.
#[derive(Clone, Debug, PartialEq)]
pub enum GearTruth {
    /// `simulate`'s physics; `model` is the truth of [`Physics::Model`] (the simulator's
    /// default is the bundled seed fit).
    Physics { physics: Physics, model: GearModel<f64> },
    /// A params file's model (any kind) with its memory, run from rest; `name` for reports.
    Model { model: GearModel<f64>, name: String },
}

impl GearTruth {
    /// The name in reports: the physics' (`micro-slip`, `bouc-wen`; the model's kind, `genetic`
    /// for the seed fit) or the file's.
    pub fn name(&self) -> String {
        match self {
            GearTruth::Physics { physics: Physics::Model, model } => model.kind().label().to_owned(),
            GearTruth::Physics { physics, .. } => physics.name().to_owned(),
            GearTruth::Model { name, .. } => name.clone(),
        }
    }

    fn start(&self) -> Result<TruthState, HilError> {
        Ok(match self {
            // Physics::Model has no host gear: its truth is the model with its memory.
            GearTruth::Physics { physics, model } => match physics.gear()? {
                Some(gear) => TruthState::Path(gear),
                None => TruthState::Model(Box::new(model.evaluator(TRUTH_BAND)?)),
            },
            GearTruth::Model { model, .. } => TruthState::Model(Box::new(model.evaluator(TRUTH_BAND)?)),
        })
    }
}

/// A truth gear with its state.
enum TruthState {
    Path(Box<dyn Gear>),
    Model(Box<Evaluator<f64>>),
}

impl TruthState {
    fn step(&mut self, theta: f64) -> Result<f64, HilError> {
        match self {
            TruthState::Path(gear) => Ok(gear.step(theta)),
            TruthState::Model(evaluator) => Ok(evaluator.step(theta)?.torque),
        }
    }
}

/// The joint's state and what the encoders read.
pub struct Plant {
    params: PlantParams,
    environment: Environment,
    gear: TruthState,
    /// Motor angle (rad) and velocity (rad/s).
    motor: (f64, f64),
    /// Output angle (rad) and velocity (rad/s).
    output: (f64, f64),
    /// The gear's torque at the present state, N·m.
    torque: f64,
}

/// The plant's state at a control tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantState {
    /// The true deflection θ = θ_motor/N − θ_out, rad.
    pub deflection: f64,
    /// The true transmitted torque, N·m.
    pub torque: f64,
    /// Output angle, rad.
    pub output_angle: f64,
    /// Motor velocity, rad/s.
    pub motor_velocity: f64,
}

impl Plant {
    /// At rest: both shafts at 0 (the environment's rest position), the gear unstressed.
    pub fn new(params: PlantParams, truth: &GearTruth, environment: Environment) -> Result<Plant, HilError> {
        params.validate()?;
        environment.validate()?;
        let mut gear = truth.start()?;
        let torque = gear.step(0.0)?;
        Ok(Plant { params, environment, gear, motor: (0.0, 0.0), output: (0.0, 0.0), torque })
    }

    /// The encoders' readings (motor, output), quantised to their counts (floor), rad.
    pub fn encoders(&self) -> (f64, f64) {
        let (input, output) = self.params.counts();
        ((self.motor.0 / input).floor() * input, (self.output.0 / output).floor() * output)
    }

    pub fn state(&self) -> PlantState {
        PlantState {
            deflection: self.motor.0 / self.params.ratio - self.output.0,
            torque: self.torque,
            output_angle: self.output.0,
            motor_velocity: self.motor.1,
        }
    }

    /// Holds the motor torque `command` (N·m) for `period` s: semi-implicit Euler steps, the
    /// motor's Coulomb friction with sticking (the velocity stops where it would change sign,
    /// and stays at 0 while the other torques stay within the friction).
    pub fn advance(&mut self, command: f64, period: f64) -> Result<(), HilError> {
        let p = self.params;
        let h = period / p.substeps as f64;
        for _ in 0..p.substeps {
            let (angle, velocity) = self.motor;
            let drive = command - self.torque / p.ratio - p.motor_viscous * velocity;
            let friction = if velocity != 0.0 {
                p.motor_coulomb * velocity.signum()
            } else {
                drive.clamp(-p.motor_coulomb, p.motor_coulomb)
            };
            let next = velocity + h * (drive - friction) / p.motor_inertia;
            let motor_velocity = if velocity != 0.0 && next.signum() != velocity.signum() { 0.0 } else { next };
            self.motor = (angle + h * motor_velocity, motor_velocity);

            let (q, v) = self.output;
            let environment = self.environment.reaction(q, v);
            let v = v + h * (self.torque - environment) / self.environment.inertia;
            self.output = (q + h * v, v);

            let theta = self.motor.0 / p.ratio - self.output.0;
            // Beyond the joint's plausible range (the firmware's MAX_DEFLECTION) the run has
            // diverged: the truth physics is not meant to be evaluated there.
            if !(theta.abs() <= f64::from(swg_protocol::MAX_DEFLECTION)) {
                return Err(HilError::Diverged);
            }
            self.torque = self.gear.step(theta)?;
            if !self.torque.is_finite() || !self.output.0.is_finite() || !self.motor.0.is_finite() {
                return Err(HilError::Diverged);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hil::scenario::Scenario;
    use crate::simulate::MicroSlip;

    fn slip() -> GearTruth {
        GearTruth::Physics {
            physics: Physics::MicroSlip(MicroSlip::default()),
            model: GearModel::paper(model_core::checks::SEED_TABLE_FIT),
        }
    }

    /// Without friction a constant motor torque u settles, against the environment's spring,
    /// where the gear transmits N·u; at rest nothing moves.
    #[test]
    fn a_constant_command_settles_at_ratio_times_command() {
        let params = PlantParams { motor_coulomb: 0.0, motor_viscous: 5.0e-3, ..PlantParams::default() };
        let environment = Scenario::TorqueSine.environment();
        let mut plant = Plant::new(params, &slip(), environment).unwrap();
        plant.advance(0.0, 1.0e-3).unwrap();
        assert_eq!(plant.state().torque, 0.0);
        assert_eq!(plant.encoders(), (0.0, 0.0));
        for _ in 0..20_000 {
            plant.advance(0.2, 1.0e-3).unwrap();
        }
        let state = plant.state();
        assert!((state.torque - 50.0 * 0.2).abs() < 0.05, "{state:?}");
        // The encoders read the angles to within a count, below them.
        let (motor, output) = plant.encoders();
        let (count_in, count_out) = params.counts();
        assert!((0.0..count_out).contains(&(state.output_angle - output)), "{output} {state:?}");
        let motor_true = (state.deflection + state.output_angle) * 50.0;
        assert!((motor_true - motor).abs() < count_in * 1.01, "{motor} {motor_true}");
    }

    /// Coulomb friction holds the motor: a command within it moves nothing.
    #[test]
    fn friction_holds_a_small_command() {
        let mut plant = Plant::new(PlantParams::default(), &slip(), Scenario::TorqueSine.environment()).unwrap();
        for _ in 0..1000 {
            plant.advance(0.019, 1.0e-3).unwrap();
        }
        assert_eq!(plant.state().motor_velocity, 0.0);
        assert_eq!(plant.state().torque, 0.0);
        plant.advance(0.03, 1.0e-3).unwrap();
        assert!(plant.state().motor_velocity > 0.0);
    }

    #[test]
    fn bad_plant_values_are_named() {
        let params = PlantParams { substeps: 5, ..PlantParams::default() };
        let error = Plant::new(params, &slip(), Scenario::TorqueSine.environment()).err().unwrap();
        assert_eq!(error.to_string(), "plant value substeps = 5 is out of range");
    }
}
