//! Running a gear's model (model-core's [`GearModel`], of any kind) along a motion from rest,
//! with the reversal band that `fit`, `predict` and `push` share.
use model_core::{Evaluation, GearModel, Hysteretic};

/// Reversals smaller than this many deflection-noise standard deviations are taken for noise
/// by the stateful models, in `fit` and `predict` alike: 3σ lets one noisy sample in 700 through.
pub const BAND_IN_NOISE_SIGMAS: f64 = 3.0;

/// The reversal band for a recording whose deflection noise is `noise` (rad).
pub fn reversal_band(noise: f64) -> f64 {
    BAND_IN_NOISE_SIGMAS * noise
}

/// Torque and stiffness of `model` along `deflection` from rest; the index of the first sample
/// that cannot be evaluated is the error's.
pub fn run(
    model: &GearModel<f64>,
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
