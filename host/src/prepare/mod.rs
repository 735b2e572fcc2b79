//! From what was read to what the fit needs: direction, amplitude and noise per sample.
pub mod segment;

use crate::input::{Branch, Dataset, LoopTable, Recording};
use model_core::Direction;
pub use segment::{deflection_noise, noise_from_second_differences, segment, SegmentError, Segmentation, TurningPoint};

/// Deflection samples with what the model needs to evaluate them.
#[derive(Clone, Debug, Default)]
pub struct FitData {
    pub theta: Vec<f64>,
    pub torque: Vec<f64>,
    pub direction: Vec<Direction>,
    pub amplitude: Vec<f64>,
}

/// Standard deviations of the measurement noise.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct NoiseModel {
    /// Torque sensor noise, N·m.
    pub torque_nm: f64,
    /// Deflection noise (encoders), rad.
    pub deflection_rad: f64,
}

/// A dataset ready to fit.
#[derive(Clone, Debug)]
pub struct Prepared {
    pub data: FitData,
    /// The loading branch of every sample (given by a loop table, derived for a recording).
    pub branch: Vec<Branch>,
    /// Measurement noise, estimated from a recording; `None` for a loop table.
    pub noise: Option<NoiseModel>,
    /// Direction analysis of a recording. Its per-sample `direction` and `amplitude` are moved
    /// into `data` (held once), so here they are empty.
    pub segmentation: Option<Segmentation>,
}

pub fn prepare(dataset: &Dataset) -> Result<Prepared, SegmentError> {
    match dataset {
        Dataset::LoopTable(table) => Ok(from_loop_table(table)),
        Dataset::Recording(recording) => from_recording(recording),
    }
}

/// A loop table is one loop: A is its largest |θ|, the direction its branch's.
pub fn from_loop_table(table: &LoopTable) -> Prepared {
    let amplitude = table.deflection.iter().map(|t| t.abs()).fold(0.0, f64::max);
    Prepared {
        data: FitData {
            theta: table.deflection.clone(),
            torque: table.torque.clone(),
            direction: table.branch.iter().map(|b| b.direction()).collect(),
            amplitude: vec![amplitude; table.deflection.len()],
        },
        branch: table.branch.clone(),
        noise: None,
        segmentation: None,
    }
}

pub fn from_recording(recording: &Recording) -> Result<Prepared, SegmentError> {
    let mut segmentation = segment(&recording.time, &recording.deflection)?;
    let branch = recording
        .deflection
        .iter()
        .zip(&segmentation.direction)
        .map(|(&theta, &direction)| Branch::of(direction, theta))
        .collect();
    let noise =
        NoiseModel { torque_nm: noise_from_second_differences(&recording.torque), deflection_rad: segmentation.noise };
    Ok(Prepared {
        data: FitData {
            theta: recording.deflection.clone(),
            torque: recording.torque.clone(),
            direction: std::mem::take(&mut segmentation.direction),
            amplitude: std::mem::take(&mut segmentation.amplitude),
        },
        branch,
        noise: Some(noise),
        segmentation: Some(segmentation),
    })
}
