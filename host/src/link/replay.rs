//! Streaming encoder samples through the firmware and comparing its T_ff and K with the
//! host's f64 model at exactly the deflection, direction and amplitude the firmware used.
use super::{Link, LinkError};
use crate::input::Recording;
use model_core::tolerance::{loop_scales, Bound};
use model_core::{Model, Params};
use std::collections::HashMap;
use swg_protocol::{Compensation, EncoderSample, EvalPath, Feedforward, JointParams};

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReplayError {
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error("the host model cannot evaluate these parameters: {0}")]
    Model(#[from] model_core::Error),
    #[error("the device has no parameters: push some first")]
    NoParams,
    #[error(
        "the recording's gear ratio is {recording}, the device's {device}: push parameters with --ratio {recording}"
    )]
    RatioMismatch { recording: f64, device: f32 },
}

/// The encoder samples of a recording as the firmware reads them: input and output angles,
/// or, for a recording with deflections only, θ·N on the input with the output at rest.
pub fn samples(recording: &Recording, device_ratio: f32) -> Result<Vec<(f32, f32)>, ReplayError> {
    if let Some(angles) = &recording.angles {
        if (recording.ratio - f64::from(device_ratio)).abs() > 1e-6 * recording.ratio.abs() {
            return Err(ReplayError::RatioMismatch { recording: recording.ratio, device: device_ratio });
        }
        return Ok(angles.input.iter().zip(&angles.output).map(|(&i, &o)| (i as f32, o as f32)).collect());
    }
    let ratio = f64::from(device_ratio);
    Ok(recording.deflection.iter().map(|&theta| ((theta * ratio) as f32, 0.0)).collect())
}

/// The comparison over a replay.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReplayReport {
    pub samples: usize,
    /// Samples where the firmware's compensation was active (compared in full).
    pub active: usize,
    /// Samples where the firmware clamped the torque (compared against the clamped model).
    pub clamped: usize,
    /// Samples where the firmware's compensation was off (not compared).
    pub off: usize,
    /// Compared samples within 1 % of the amplitude from a turning point.
    pub near_turning_points: usize,
    pub torque_worst: f64,
    pub torque_rms: f64,
    pub stiffness_worst: f64,
    pub stiffness_rms: f64,
    /// Largest error / allowed error over all compared samples (≤ 1 passes).
    pub worst_bound_ratio: f64,
    /// Samples outside the bound of [`model_core::tolerance`].
    pub violations: usize,
    /// The first sample outside the bound, for the report.
    pub first_violation: Option<(usize, Feedforward, Bound)>,
}

impl ReplayReport {
    pub fn passed(&self) -> bool {
        self.violations == 0 && self.off == 0
    }
}

impl std::fmt::Display for ReplayReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{} samples: {} active, {} clamped, {} off; {} within 1 % of a turning point",
            self.samples, self.active, self.clamped, self.off, self.near_turning_points
        )?;
        writeln!(f, "T_ff difference: worst {:.3e} N·m, RMS {:.3e} N·m", self.torque_worst, self.torque_rms)?;
        writeln!(
            f,
            "K difference:    worst {:.3e} N·m/rad, RMS {:.3e} N·m/rad",
            self.stiffness_worst, self.stiffness_rms
        )?;
        write!(
            f,
            "worst error / f32 tolerance: {:.3} ({} samples outside; tolerance: {:.0e} of the loop's T and K scale plus the f32 rounding sensitivity of θ/A)",
            self.worst_bound_ratio,
            self.violations,
            model_core::tolerance::RELATIVE_TOLERANCE
        )?;
        if let Some((index, fw, bound)) = &self.first_violation {
            write!(
                f,
                "\nfirst outside: sample {index}: θ = {:e} rad {:?} A = {:e}: firmware T = {}, K = {}; host T = {}, K = {}",
                fw.deflection, fw.direction, fw.amplitude, fw.torque, fw.stiffness, bound.exact.torque, bound.exact.stiffness
            )?;
        }
        Ok(())
    }
}

/// Sends every sample through the firmware's control tick (`path`) and compares the results
/// with `params` in f64 (by default the device's own set, so only evaluation differs).
pub fn replay(
    link: &mut Link,
    joint: &JointParams,
    params: &Params<f64>,
    samples: &[(f32, f32)],
    path: EvalPath,
) -> Result<ReplayReport, ReplayError> {
    let model = Model::new(*params)?;
    let mut comparison = Comparison::new(model, f64::from(joint.torque_limit));
    for (index, &(input_angle, output_angle)) in samples.iter().enumerate() {
        let feedforward = link.replay(&EncoderSample { input_angle, output_angle, path })?;
        comparison.add(index, &feedforward)?;
    }
    Ok(comparison.finish())
}

/// Accumulates the comparison, sample by sample.
struct Comparison {
    model: Model<f64>,
    torque_limit: f64,
    /// The loop's scales per amplitude (f32 bits): the amplitude changes only at turning points.
    scales: HashMap<u32, (f64, f64)>,
    torque_squares: f64,
    stiffness_squares: f64,
    report: ReplayReport,
}

impl Comparison {
    fn new(model: Model<f64>, torque_limit: f64) -> Self {
        Comparison {
            model,
            torque_limit,
            scales: HashMap::new(),
            torque_squares: 0.0,
            stiffness_squares: 0.0,
            report: ReplayReport::default(),
        }
    }

    fn add(&mut self, index: usize, fw: &Feedforward) -> Result<(), ReplayError> {
        let report = &mut self.report;
        report.samples += 1;
        match fw.compensation {
            Compensation::Off => {
                report.off += 1;
                return Ok(());
            }
            Compensation::Active => report.active += 1,
            Compensation::Clamped => report.clamped += 1,
        }
        let amplitude = f64::from(fw.amplitude);
        let scales = match self.scales.get(&fw.amplitude.to_bits()) {
            Some(&scales) => scales,
            None => {
                let scales = loop_scales(&self.model, amplitude)?;
                self.scales.insert(fw.amplitude.to_bits(), scales);
                scales
            }
        };
        let theta = f64::from(fw.deflection);
        let bound = Bound::at(&self.model, theta, fw.direction, amplitude, scales)?;
        let (torque_error, stiffness_error) = match fw.compensation {
            Compensation::Clamped => {
                // The firmware saturates at the limit; the model must be there too, within bound.
                let over = self.torque_limit - bound.exact.torque.abs();
                let sign_ok = f64::from(fw.torque).signum() == bound.exact.torque.signum();
                let error = if sign_ok { over.max(0.0) } else { f64::INFINITY };
                (error, 0.0)
            }
            _ => (
                (f64::from(fw.torque) - bound.exact.torque).abs(),
                (f64::from(fw.stiffness) - bound.exact.stiffness).abs(),
            ),
        };
        if theta.abs() >= 0.99 * amplitude {
            report.near_turning_points += 1;
        }
        report.torque_worst = report.torque_worst.max(torque_error);
        report.stiffness_worst = report.stiffness_worst.max(stiffness_error);
        self.torque_squares += torque_error * torque_error;
        self.stiffness_squares += stiffness_error * stiffness_error;
        let ratio = (torque_error / bound.torque).max(stiffness_error / bound.stiffness);
        report.worst_bound_ratio = report.worst_bound_ratio.max(ratio);
        if !(ratio <= 1.0) {
            report.violations += 1;
            report.first_violation.get_or_insert((index, *fw, bound));
        }
        Ok(())
    }

    fn finish(mut self) -> ReplayReport {
        let compared = (self.report.active + self.report.clamped).max(1) as f64;
        self.report.torque_rms = (self.torque_squares / compared).sqrt();
        self.report.stiffness_rms = (self.stiffness_squares / compared).sqrt();
        self.report
    }
}

/// The device's parameters, which replay needs.
pub fn device_params(link: &mut Link) -> Result<JointParams, ReplayError> {
    link.read_params()?.ok_or(ReplayError::NoParams)
}

/// The f64 model of a device set, exactly as the device holds it.
pub fn widen(params: &Params<f32>) -> Params<f64> {
    Params {
        c1: params.c1.into(),
        c2: params.c2.into(),
        c3: params.c3.into(),
        alpha: params.alpha.into(),
        beta: params.beta.into(),
        omega: params.omega.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::fake::FakeDevice;
    use crate::link::push::{joint_params, push, JointSettings};
    use crate::simulate::{simulate, Simulation};

    const SEED: Params<f64> = Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 68.0, beta: -2.298, omega: 1.0 };

    fn recording(input_bits: Option<u32>) -> Recording {
        simulate(&Simulation {
            params: SEED,
            amplitude_rad: 1.168e-3,
            frequencies_hz: vec![1.0],
            cycles: 2,
            sample_rate_hz: 500.0,
            ratio: 50.0,
            input_speed_rad_s: 0.0,
            input_bits,
            output_bits: input_bits,
            torque_noise_nm: 0.0,
            temperature: None,
            effects: Vec::new(),
            seed: 1,
        })
        .unwrap()
    }

    fn pushed(torque_limit: f64) -> (Link, JointParams) {
        let mut link = FakeDevice::new().link();
        let settings = JointSettings { gear_ratio: 50.0, torque_limit, direction_band: 2.0e-6 };
        let joint = joint_params(&SEED, &settings).unwrap();
        push(&mut link, &joint).unwrap();
        (link, joint)
    }

    #[test]
    fn both_paths_match_the_f64_model_over_whole_loops() {
        let (mut link, joint) = pushed(100.0);
        let samples = samples(&recording(None), joint.gear_ratio).unwrap();
        for path in [EvalPath::Direct, EvalPath::Fast] {
            let report = replay(&mut link, &joint, &widen(&joint.model), &samples, path).unwrap();
            assert!(report.passed(), "{path:?}: {report}");
            assert_eq!((report.samples, report.active), (samples.len(), samples.len()));
            assert!(report.near_turning_points >= 8, "{report}");
        }
    }

    #[test]
    fn clamped_samples_are_compared_against_the_limit() {
        let (mut link, joint) = pushed(5.0);
        let samples = samples(&recording(Some(20)), joint.gear_ratio).unwrap();
        let report = replay(&mut link, &joint, &widen(&joint.model), &samples, EvalPath::Fast).unwrap();
        assert!(report.clamped > 0 && report.active > 0, "{report}");
        assert!(report.passed(), "{report}");
    }

    #[test]
    fn a_different_model_fails_the_comparison() {
        let (mut link, joint) = pushed(100.0);
        let samples = samples(&recording(None), joint.gear_ratio).unwrap();
        let other = Params { c1: SEED.c1 * 1.001, ..SEED };
        let report = replay(&mut link, &joint, &other, &samples, EvalPath::Fast).unwrap();
        assert!(!report.passed() && report.first_violation.is_some(), "{report}");
    }

    #[test]
    fn a_ratio_mismatch_is_named() {
        let error = samples(&recording(None), 100.0).unwrap_err();
        assert_eq!(
            error.to_string(),
            "the recording's gear ratio is 50, the device's 100: push parameters with --ratio 50"
        );
    }
}
