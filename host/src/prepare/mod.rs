//! From what was read to what the fit needs: direction, amplitude and noise per sample.
pub mod rest;
pub mod segment;

use crate::gear::Reversals;
use crate::input::{Branch, Dataset, LoopTable, Recording};
use model_core::Direction;
pub use rest::{rest_window, OriginSource, RestWindow, RunOrigin};
pub use segment::{
    deflection_noise, extremes_visited, noise_from_second_differences, reversals, reversals_beyond, segment,
    SegmentError, Segmentation, TurningBand, TurningPoint,
};

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

impl NoiseModel {
    /// A sample's total-noise weight 1/(σT² + σθ²·K²) where the model's stiffness is K: the
    /// deflection's noise reaches the torque through the stiffness.
    #[inline]
    pub fn weight(&self, stiffness: f64) -> f64 {
        1.0 / (self.torque_nm.powi(2) + self.deflection_rad.powi(2) * stiffness * stiffness).max(f64::MIN_POSITIVE)
    }
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

/// A recording as the offline model follows it (a run of a fit, or what `predict` scores): its
/// turning points over the whole recording, its noise, its rest window, and where an unknown
/// start state has been wiped out.
#[derive(Clone, Debug, PartialEq)]
pub struct OfflineRun {
    pub reversals: Reversals,
    pub noise: NoiseModel,
    /// Where the run starts at rest: the rest window at its start, declared (`# start: rest`,
    /// [`Recording::starts_at_rest`]) or found ([`rest_window`]). It gives the run's θ0 and
    /// torque offset.
    pub rest: Option<RestWindow>,
    /// The first sample scored. A run that does not start at rest carries an unknown hysteresis
    /// state until its motion has visited both its extremes ([`extremes_visited`]); the model
    /// still runs through the samples before, from rest, but they are neither fitted nor
    /// scored. 0 from rest.
    pub scored_from: usize,
    /// Whether the run starts at a standstill found in the data, not declared: the gear is
    /// still, but its hysteresis may hold the remanence of the motion before the recording
    /// (`bench/real/FINDINGS.md` §1), which fits of several runs estimate
    /// (`fit::motion::START_STATES`).
    pub remanent_start: bool,
}

impl OfflineRun {
    pub fn of(recording: &Recording) -> OfflineRun {
        let deflection = &recording.deflection;
        let band = TurningBand::of(deflection);
        let rest = rest_window(&recording.time, deflection, &recording.torque, band.noise, recording.starts_at_rest());
        let scored_from = if rest.is_some() { 0 } else { extremes_visited(deflection, band.band) };
        OfflineRun {
            reversals: reversals_beyond(deflection, band.band),
            noise: NoiseModel {
                torque_nm: noise_from_second_differences(&recording.torque),
                deflection_rad: band.noise,
            },
            remanent_start: rest.is_some() && !recording.starts_at_rest(),
            rest,
            scored_from,
        }
    }

    /// Samples before the motion's extremes, not scored.
    pub fn unscored(&self) -> usize {
        self.scored_from
    }
}
