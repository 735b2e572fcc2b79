//! The `predict` pipeline: a fitted model run along a recording's deflection from rest, with
//! hysteresis memory (model-core's stateful evaluator), following the recording's reversals as
//! `fit` does: found offline over the whole recording ([`crate::gear::step_offline`]), or, with
//! a band, causally as the joint's firmware finds them.
//!
//! Like a fit's runs, a recording that starts at rest is zeroed on its rest window: θ0 and the
//! torque sensor's offset are what it reads there ([`RunOrigin::place`]); the params file's θ0
//! is kept otherwise, or when asked ([`Zeroing::Model`]).
use crate::gear::{run, run_offline};
use crate::input::Recording;
use crate::prepare::{OfflineRun, RunOrigin};
use model_core::GearModel;

/// Where `predict` takes θ0 and the torque sensor's offset from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Zeroing {
    /// The recording's rest window where it has one (as `fit` places each run), else the model's
    /// θ0 and no offset.
    #[default]
    RestWindow,
    /// The model's θ0 and no offset, always (as the joint runs it).
    Model,
}

/// The model's torque and stiffness at every sample of a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Prediction {
    pub time: Vec<f64>,
    pub deflection: Vec<f64>,
    /// Predicted torque, N·m.
    pub torque: Vec<f64>,
    /// Predicted stiffness dT/dθ, N·m/rad.
    pub stiffness: Vec<f64>,
    /// The causal reversal band the evaluator used, rad; `None`: the offline reversals.
    pub band_rad: Option<f64>,
    /// The first sample scored: the ones before came before the motion's extremes wiped out an
    /// unknown start state (0 for a recording that starts at rest), as `fit` counts them.
    pub scored_from: usize,
    /// θ0 and the torque offset read in the recording's rest window, where the model was placed
    /// there ([`Zeroing::RestWindow`]); the predicted torque includes the offset.
    pub origin: Option<RunOrigin>,
    /// The deflections the model's spring was identified over, [min, max] rad (its θ0 as placed).
    pub range: [f64; 2],
}

/// How far a prediction is from the recording, and how smooth it is.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PredictionSummary {
    /// Samples predicted.
    pub n: usize,
    /// Samples before the motion had visited both its extremes, in a recording that does not
    /// say it starts at rest: the model ran through them, but they are not scored.
    pub start_state_samples: usize,
    /// Σ (measured − predicted)² over the scored samples, (N·m)².
    pub rss: f64,
    /// RMS of measured − predicted over the scored samples, N·m.
    pub rms: f64,
    /// Largest change of the predicted torque between consecutive samples, N·m.
    pub max_step_nm: f64,
    /// Samples beyond the spring's identified range, where it continues with its edge's
    /// stiffness.
    pub beyond_range_samples: usize,
    /// The largest distance of a sample beyond that range, rad (0 when none is).
    pub max_excess_rad: f64,
    /// RMS over the scored samples within that range, N·m (none when no scored sample is).
    pub within_range_rms: Option<f64>,
    /// θ0 and the torque offset read in the recording's rest window, where the model was placed
    /// there.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub origin: Option<RunOrigin>,
    /// How the reversals were found: `offline` (over the whole recording) or `band`.
    pub reversals: &'static str,
    /// The causal reversal band, rad (with `band`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub band_rad: Option<f64>,
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PredictError {
    #[error("the model cannot be evaluated at sample {index} (t = {time} s, θ = {deflection:e} rad): {source}")]
    Evaluation { index: usize, time: f64, deflection: f64, source: model_core::Error },
    #[error("reversal band {0} rad: expected a finite deflection ≥ 0")]
    Band(f64),
}

/// Runs `model` along `recording` from rest, placed by `zeroing`. Without `band` it follows the
/// reversals found offline over the whole recording (as `fit`); with one, it follows them
/// causally, taking reversals smaller than `band` (rad) for noise, as the joint does.
pub fn predict(
    model: &GearModel<f64>,
    recording: &Recording,
    band: Option<f64>,
    zeroing: Zeroing,
) -> Result<Prediction, PredictError> {
    let offline = OfflineRun::of(recording);
    let (model, origin) = match zeroing {
        Zeroing::RestWindow => RunOrigin::place(model, &offline),
        Zeroing::Model => (*model, None),
    };
    let offset = origin.map_or(0.0, |o| o.torque_offset_nm);
    let deflection = &recording.deflection;
    let evaluations = match band {
        None => run_offline(&model, deflection, &offline.reversals),
        Some(band) if band.is_finite() && band >= 0.0 => run(&model, deflection, band),
        Some(band) => return Err(PredictError::Band(band)),
    }
    .map_err(|(index, source)| PredictError::Evaluation {
        index,
        time: recording.time[index],
        deflection: deflection[index],
        source,
    })?;
    let (torque, stiffness) = evaluations.iter().map(|e| (e.torque + offset, e.stiffness)).unzip();
    Ok(Prediction {
        time: recording.time.clone(),
        deflection: deflection.clone(),
        torque,
        stiffness,
        band_rad: band,
        scored_from: offline.scored_from,
        origin,
        range: model.range(),
    })
}

impl Prediction {
    /// Whether sample `index` is scored.
    pub fn is_scored(&self, index: usize) -> bool {
        index >= self.scored_from
    }

    /// The prediction against the measured torque of the same samples, over the scored ones.
    pub fn summary(&self, measured: &[f64]) -> PredictionSummary {
        let scored = self.scored_from.min(self.torque.len());
        let rss: f64 = measured.iter().zip(&self.torque).skip(scored).map(|(m, p)| (m - p) * (m - p)).sum();
        let n = self.torque.len();
        let max_step_nm = self.torque.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0, f64::max);
        let [lo, hi] = self.range;
        let excess = |theta: f64| (theta - hi).max(lo - theta);
        let beyond = self.deflection.iter().map(|&theta| excess(theta)).filter(|&e| e > 0.0);
        let (beyond_range_samples, max_excess_rad) = beyond.fold((0, 0.0f64), |(n, most), e| (n + 1, most.max(e)));
        let (within_rss, within) = measured
            .iter()
            .zip(&self.torque)
            .zip(&self.deflection)
            .skip(scored)
            .filter(|(_, &theta)| excess(theta) <= 0.0)
            .fold((0.0, 0usize), |(rss, count), ((m, p), _)| (rss + (m - p) * (m - p), count + 1));
        PredictionSummary {
            n,
            start_state_samples: scored,
            rss,
            rms: if n > scored { (rss / (n - scored) as f64).sqrt() } else { 0.0 },
            max_step_nm,
            beyond_range_samples,
            max_excess_rad,
            within_range_rms: (within > 0).then(|| (within_rss / within as f64).sqrt()),
            origin: self.origin,
            reversals: if self.band_rad.is_some() { "band" } else { "offline" },
            band_rad: self.band_rad,
        }
    }
}
