//! A gear's fitted model, of either kind, and running it along a motion from rest: what a
//! params file holds, what `predict` and `push` read, and what `fit --model` produces.
use model_core::memory::{GeneticMemory, Hysteretic, MicroSlip, SlipParams};
use model_core::{Evaluation, Model, Params};

/// Turning points the genetic model remembers, on the host as on the joint.
pub const TURNING_POINTS: usize = 16;
/// Elasto-slip elements of the micro-slip model, on the host as on the joint.
pub const SLIP_ELEMENTS: usize = 16;

/// Reversals smaller than this many deflection-noise standard deviations are taken for noise
/// by the stateful models, in `fit` and `predict` alike: 3σ lets one noisy sample in 700 through.
pub const BAND_IN_NOISE_SIGMAS: f64 = 3.0;

/// The reversal band for a recording whose deflection noise is `noise` (rad).
pub fn reversal_band(noise: f64) -> f64 {
    BAND_IN_NOISE_SIGMAS * noise
}

/// Name of the micro-slip kind in files.
pub const MICRO_SLIP_NAME: &str = "micro-slip";

/// The model kinds `fit --model` can identify.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModelKind {
    /// The paper's genetic model, generalised to any motion by Madelung's rules.
    Genetic,
    /// Maxwell-slip: an odd polynomial spring with [`SLIP_ELEMENTS`] elasto-slip elements.
    MicroSlip,
}

impl ModelKind {
    pub const ALL: [ModelKind; 2] = [ModelKind::Genetic, ModelKind::MicroSlip];

    /// The kind's name in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Genetic => model_core::MODEL_NAME,
            ModelKind::MicroSlip => MICRO_SLIP_NAME,
        }
    }
}

/// A fitted gear model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GearModel {
    Genetic(Params<f64>),
    MicroSlip(SlipParams<f64, SLIP_ELEMENTS>),
}

impl GearModel {
    pub fn kind(&self) -> ModelKind {
        match self {
            GearModel::Genetic(_) => ModelKind::Genetic,
            GearModel::MicroSlip(_) => ModelKind::MicroSlip,
        }
    }

    /// Checks that the model can be evaluated.
    pub fn validate(&self) -> Result<(), model_core::Error> {
        match self {
            GearModel::Genetic(params) => Model::new(*params).map(|_| ()),
            GearModel::MicroSlip(params) => MicroSlip::new(*params).map(|_| ()),
        }
    }

    /// The model's evaluator at rest; `band` is the smallest reversal the genetic kind follows
    /// (rad; the micro-slip kind needs none).
    pub fn evaluator(&self, band: f64) -> Result<Evaluator, model_core::Error> {
        Ok(match self {
            GearModel::Genetic(params) => Evaluator::Genetic(GeneticMemory::new(Model::new(*params)?, band)),
            GearModel::MicroSlip(params) => Evaluator::MicroSlip(MicroSlip::new(*params)?),
        })
    }
}

/// Either kind's stateful evaluator.
#[derive(Clone, Debug)]
pub enum Evaluator {
    Genetic(GeneticMemory<f64, TURNING_POINTS>),
    MicroSlip(MicroSlip<f64, SLIP_ELEMENTS>),
}

impl Hysteretic<f64> for Evaluator {
    fn reset(&mut self) {
        match self {
            Evaluator::Genetic(memory) => memory.reset(),
            Evaluator::MicroSlip(slip) => slip.reset(),
        }
    }

    fn step(&mut self, theta: f64) -> Result<Evaluation<f64>, model_core::Error> {
        match self {
            Evaluator::Genetic(memory) => memory.step(theta),
            Evaluator::MicroSlip(slip) => slip.step(theta),
        }
    }
}

/// Torque and stiffness of `model` along `deflection` from rest; the index of the first sample
/// that cannot be evaluated is the error's.
pub fn run(
    model: &GearModel,
    deflection: &[f64],
    band: f64,
) -> Result<Vec<Evaluation<f64>>, (usize, model_core::Error)> {
    let mut evaluator = model.evaluator(band).map_err(|e| (0, e))?;
    // Sized up front: collected through a `Result`, the vector would grow by doubling.
    let mut evaluations = Vec::with_capacity(deflection.len());
    for (i, &theta) in deflection.iter().enumerate() {
        evaluations.push(evaluator.step(theta).map_err(|e| (i, e))?);
    }
    Ok(evaluations)
}
