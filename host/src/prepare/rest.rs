//! A recording's rest window: the samples at its start during which the gear stands still at
//! (nearly) zero torque. A run with one starts at rest, its deflection's zero θ0 is what it reads
//! there and the torque sensor's offset is the torque it reads there.
use super::OfflineRun;
use crate::numeric::mean;
use model_core::GearModel;

/// The samples at a recording's start during which the gear stands still, and what they read.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RestWindow {
    /// Samples from the first.
    pub samples: usize,
    /// How long it lasts, s.
    pub seconds: f64,
    /// The mean deflection, rad: θ0 for a gear at rest.
    pub deflection_rad: f64,
    /// Its standard error, rad: the deflection noise over √samples, or the reading's step over
    /// √12 where the readings at rest vary by less than half a step (see [`rest_window`]).
    pub deflection_se_rad: f64,
    /// The deflection's standard deviation there, rad: how much the encoders jitter at rest
    /// (none in a window too short to tell).
    pub deflection_sd_rad: Option<f64>,
    /// The mean torque, N·m: the torque sensor's offset for a gear at rest. None in a window
    /// too short to read it (a declared rest the motion leaves at once).
    pub torque_nm: Option<f64>,
}

/// Band around the first sample's deflection within which the gear counts as still, in σθ:
/// wider than noise ever spans at these sample counts, and wider than one encoder step
/// (σθ ≥ step/√12).
const REST_BAND_IN_NOISE: f64 = 4.0;
/// Fewest samples of a rest window that reads the torque offset, and of one the recording does
/// not declare (`# start: rest`). Fewer are the first steps of a motion that starts at once: their
/// mean torque is the spring's over those steps, not the sensor's offset (a sine from rest in
/// 20-bit angles leaves a 4σθ band within 2 samples, and their torque biased a prediction by
/// 1.9× the floor of `tests/prediction.rs`), and their mean deflection lags the first sample.
const MIN_REST: usize = 20;
/// An undeclared rest window's torque is at most this fraction of the recording's torque range:
/// a gear held still under load is not at rest.
const REST_TORQUE_FRACTION: f64 = 0.05;

/// The leading samples whose deflection stays within 4σθ of the first's, when they make a rest
/// window: at least 20 at a torque within 5 % of the recording's torque range, or, when the
/// recording says it starts at rest (`declared`), any number (fewer than 20 read θ0 at the first
/// sample and no torque offset).
pub fn rest_window(time: &[f64], deflection: &[f64], torque: &[f64], noise: f64, declared: bool) -> Option<RestWindow> {
    let first = *deflection.first()?;
    let samples = without_drift(deflection, within_rest_band(deflection.iter(), noise), noise);
    let still = deflection.get(..samples)?;
    let torque_still = torque.get(..samples)?;
    let seconds = time.get(samples - 1).zip(time.first()).map_or(0.0, |(end, start)| end - start);
    if samples < MIN_REST {
        let first = RestWindow {
            samples,
            seconds,
            deflection_rad: first,
            deflection_se_rad: noise,
            deflection_sd_rad: None,
            torque_nm: None,
        };
        return declared.then_some(first);
    }
    let torque_nm = mean(torque_still);
    let deflection_rad = mean(still);
    let variance = still.iter().map(|theta| (theta - deflection_rad).powi(2)).sum::<f64>() / (samples - 1) as f64;
    // Readings that hardly leave one encoder step are not dithered: their mean is that step's
    // value, off the true deflection by up to half a step whatever their number (a 20-bit
    // recording at rest read θ0 "± 0.0000 mrad"). Its uncertainty is then the step's rounding,
    // uniform: step/√12.
    let averaged = noise / (samples as f64).sqrt();
    let deflection_se_rad = match reading_step(deflection) {
        Some(step) if variance.sqrt() < 0.5 * step => averaged.max(step / 12f64.sqrt()),
        _ => averaged,
    };
    let window = RestWindow {
        samples,
        seconds,
        deflection_rad,
        deflection_se_rad,
        deflection_sd_rad: Some(variance.sqrt()),
        torque_nm: Some(torque_nm),
    };
    let (lo, hi) = torque.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &t| (l.min(t), h.max(t)));
    (declared || torque_nm.abs() <= REST_TORQUE_FRACTION * (hi - lo)).then_some(window)
}

/// How many of `deflection`'s readings, from its first, stay within the rest band (4σθ, `noise`
/// being σθ) of the first: a rest at that end, before the drift test shortens it.
pub fn within_rest_band<'a>(mut deflection: impl Iterator<Item = &'a f64>, noise: f64) -> usize {
    let Some(&first) = deflection.next() else { return 0 };
    1 + deflection.take_while(|&&theta| (theta - first).abs() <= REST_BAND_IN_NOISE * noise).count()
}

/// The smallest change between consecutive readings, rad: the deflection's step where its
/// encoders quantise it; `None` where it never changes.
fn reading_step(deflection: &[f64]) -> Option<f64> {
    deflection.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|d| *d > 0.0).min_by(f64::total_cmp)
}

/// The first `samples` of `deflection` shortened (by a tenth at a time) until their two halves' means agree
/// within 3 standard errors (the larger of the noise σθ and the window's own spread): a motion
/// that starts slowly (the s-ramp of `simulate`'s biased motion reaches 4σθ only after 0.2 s)
/// stays within the band long after it has left rest, and its mean deflection and torque are
/// the spring's, not θ0 and the sensor's offset (1.9 µrad and 0.02 N·m there, which biased the
/// micro-slip gear's predictions of `bench/prediction.sh` to 2× the floor). It stops once fewer than
/// 2·[`MIN_REST`] samples remain.
fn without_drift(deflection: &[f64], mut samples: usize, noise: f64) -> usize {
    while samples >= 2 * MIN_REST {
        let Some(window) = deflection.get(..samples) else { break };
        let half = samples / 2;
        let (first, second) = window.split_at(half);
        let centre = mean(window);
        let spread = (window.iter().map(|theta| (theta - centre).powi(2)).sum::<f64>() / (samples - 1) as f64).sqrt();
        let standard_error = noise.max(spread) * (1.0 / first.len() as f64 + 1.0 / second.len() as f64).sqrt();
        if (mean(first) - mean(second)).abs() <= DRIFT_IN_STANDARD_ERRORS * standard_error {
            break;
        }
        samples -= samples.div_ceil(10);
    }
    samples
}

/// How far apart (in standard errors) the two halves of a rest window may read before the
/// window counts as moving.
const DRIFT_IN_STANDARD_ERRORS: f64 = 3.0;

/// How a run's θ0 and torque offset were found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OriginSource {
    /// Both read in the run's rest window.
    RestWindow,
    /// θ0 fitted (the spring's zero torque), the offset taken as 0.
    Fitted,
}

/// A run's θ0 and torque offset.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RunOrigin {
    /// θ0, rad.
    pub zero_rad: f64,
    /// Its uncertainty, rad, where it has one: the standard error of a rest reading, the span of
    /// the θ0s a fit cannot tell apart (`fit/zero.rs`).
    pub zero_se_rad: Option<f64>,
    /// The torque sensor's offset, N·m: what it reads when the gear's torque is 0.
    pub torque_offset_nm: f64,
    pub source: OriginSource,
}

impl RunOrigin {
    /// `model` as it runs along a recording `run` from its own start, and the torque sensor's
    /// offset there (N·m): zeroed on the run's rest window where it has one (as a fit places each
    /// run), else with the model's own θ0 and no offset. What `predict` and a fit's `--compare`
    /// run.
    pub fn place(model: &GearModel<f64>, run: &OfflineRun) -> (GearModel<f64>, Option<RunOrigin>) {
        match RunOrigin::at_rest(run) {
            Some(origin) => (GearModel { zero: origin.zero_rad, ..*model }, Some(origin)),
            None => (*model, None),
        }
    }

    /// The origin a run's rest window gives, if it has one.
    pub fn at_rest(run: &OfflineRun) -> Option<RunOrigin> {
        run.rest.map(|rest| RunOrigin {
            zero_rad: rest.deflection_rad,
            zero_se_rad: Some(rest.deflection_se_rad),
            torque_offset_nm: rest.torque_nm.unwrap_or(0.0),
            source: OriginSource::RestWindow,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deflection noise of σ from a fixed sequence (uniform, scaled to σ).
    fn jitter(n: usize, sigma: f64) -> Vec<f64> {
        let mut state: u64 = 7;
        (0..n)
            .map(|_| {
                state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                let uniform = (state >> 11) as f64 / (1u64 << 53) as f64;
                (uniform - 0.5) * sigma * 12f64.sqrt()
            })
            .collect()
    }

    /// `rest` samples still, then the s-ramp 10u³ − 15u⁴ + 6u⁵ to `height` over `ramp` samples.
    fn rest_then_ramp(rest: usize, ramp: usize, height: f64, sigma: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = rest + ramp;
        let clean = (0..n).map(|i| {
            let u = i.saturating_sub(rest) as f64 / ramp as f64;
            height * u.powi(3) * (10.0 - 15.0 * u + 6.0 * u * u)
        });
        let deflection: Vec<f64> = clean.zip(jitter(n, sigma)).map(|(x, e)| x + e).collect();
        let torque = deflection.iter().map(|x| 1.0e4 * x).collect();
        ((0..n).map(|i| i as f64 * 1.0e-3).collect(), deflection, torque)
    }

    #[test]
    fn a_motion_that_starts_slowly_is_not_read_as_rest() {
        // The biased motion of `bench/prediction.sh`: from rest at once, 0.53 mrad over 2 s.
        let sigma = 1.7e-6;
        let (time, deflection, torque) = rest_then_ramp(0, 2000, 5.3e-4, sigma);
        let window = rest_window(&time, &deflection, &torque, sigma, true).unwrap();
        // Within the 4σ band for ≈ 250 samples whose mean is ≈ 1σ off rest; the drift test
        // keeps the ones before the ramp shows.
        assert!(window.deflection_rad.abs() < 0.5 * sigma, "{window:?}");
        assert!(window.samples >= 2 * MIN_REST, "{window:?}");
    }

    #[test]
    fn a_rest_read_within_one_encoder_step_is_known_to_that_step() {
        // Quantised to a step larger than the jitter: every reading at rest is one value.
        let (sigma, step) = (1.0e-7, 6.0e-6);
        let (time, exact, torque) = rest_then_ramp(4000, 2000, 5.3e-4, sigma);
        let deflection: Vec<f64> = exact.iter().map(|x| (x / step).round() * step).collect();
        let window = rest_window(&time, &deflection, &torque, sigma, true).unwrap();
        assert_eq!(window.deflection_sd_rad, Some(0.0));
        assert!((window.deflection_se_rad - step / 12f64.sqrt()).abs() < 1e-12, "{window:?}");
        // Dithered by a jitter larger than the step, the mean averages below it.
        let (time, exact, torque) = rest_then_ramp(4000, 2000, 5.3e-4, 10.0 * step);
        let deflection: Vec<f64> = exact.iter().map(|x| (x / step).round() * step).collect();
        let window = rest_window(&time, &deflection, &torque, 10.0 * step, true).unwrap();
        assert!(window.deflection_se_rad < 0.2 * step, "{window:?}");
    }

    #[test]
    fn a_still_window_is_kept_whole() {
        let sigma = 1.7e-6;
        let (time, deflection, torque) = rest_then_ramp(4000, 2000, 5.3e-4, sigma);
        let window = rest_window(&time, &deflection, &torque, sigma, false).unwrap();
        // Within a tenth of the 4000 still samples.
        assert!((3600..=4000).contains(&window.samples), "{window:?}");
        assert!(window.deflection_rad.abs() < 0.2 * sigma, "{window:?}");
    }
}
