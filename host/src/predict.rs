//! The `predict` pipeline: a fitted model run along a recording's deflection from rest, with
//! hysteresis memory (model-core's stateful evaluator), as the joint's firmware runs it.
use crate::gear::{reversal_band, run};
use crate::input::Recording;
use crate::prepare::deflection_noise;
use model_core::GearModel;

/// The model's torque and stiffness at every sample of a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Prediction {
    pub time: Vec<f64>,
    pub deflection: Vec<f64>,
    /// Predicted torque, N·m.
    pub torque: Vec<f64>,
    /// Predicted stiffness dT/dθ, N·m/rad.
    pub stiffness: Vec<f64>,
    /// The reversal band the evaluator used, rad.
    pub band_rad: f64,
}

/// How far a prediction is from the recording, and how smooth it is.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PredictionSummary {
    pub n: usize,
    /// Σ (measured − predicted)², (N·m)².
    pub rss: f64,
    /// RMS of measured − predicted, N·m.
    pub rms: f64,
    /// Largest change of the predicted torque between consecutive samples, N·m.
    pub max_step_nm: f64,
    /// The reversal band, rad.
    pub band_rad: f64,
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PredictError {
    #[error("the model cannot be evaluated at sample {index} (t = {time} s, θ = {deflection:e} rad): {source}")]
    Evaluation { index: usize, time: f64, deflection: f64, source: model_core::Error },
    #[error("reversal band {0} rad: expected a finite deflection ≥ 0")]
    Band(f64),
}

/// Runs `model` along `recording` from rest. `band` is the smallest reversal
/// the evaluator follows, rad; `None` takes [`reversal_band`] of the recording's deflection noise, as `fit` does.
pub fn predict(model: &GearModel<f64>, recording: &Recording, band: Option<f64>) -> Result<Prediction, PredictError> {
    let band = match band {
        Some(band) if band.is_finite() && band >= 0.0 => band,
        Some(band) => return Err(PredictError::Band(band)),
        None => reversal_band(deflection_noise(&recording.deflection)),
    };
    let evaluations = run(model, &recording.deflection, band).map_err(|(index, source)| PredictError::Evaluation {
        index,
        time: recording.time[index],
        deflection: recording.deflection[index],
        source,
    })?;
    let (torque, stiffness) = evaluations.iter().map(|e| (e.torque, e.stiffness)).unzip();
    Ok(Prediction {
        time: recording.time.clone(),
        deflection: recording.deflection.clone(),
        torque,
        stiffness,
        band_rad: band,
    })
}

impl Prediction {
    /// The prediction against the measured torque of the same samples.
    pub fn summary(&self, measured: &[f64]) -> PredictionSummary {
        let rss: f64 = measured.iter().zip(&self.torque).map(|(m, p)| (m - p) * (m - p)).sum();
        let n = self.torque.len();
        let max_step_nm = self.torque.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0, f64::max);
        PredictionSummary {
            n,
            rss,
            rms: if n == 0 { 0.0 } else { (rss / n as f64).sqrt() },
            max_step_nm,
            band_rad: self.band_rad,
        }
    }
}
