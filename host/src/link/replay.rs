//! Streaming encoder samples through the firmware and comparing its T_ff and K with the
//! host's f64 model run through exactly the deflections the firmware used, from rest.
use super::{Link, LinkError};
use crate::gear::run_offline;
use crate::input::Recording;
use crate::prepare::segment::reversals;
use model_core::memory::Hysteretic;
use model_core::tolerance::{Bound, RELATIVE_TOLERANCE};
use model_core::{Evaluator, GearModel};
use std::collections::HashMap;
use swg_protocol::{endpoint, Compensation, EncoderSample, EvalPath, Feedforward, JointParams};

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
    /// Samples where the firmware's compensation was off (not compared, and skipped by the
    /// host's model as by the firmware's).
    pub off: usize,
    /// Reversals the host's model recognised (genetic kind: direction flips, with the band)
    /// or where θ reversed (micro-slip kind): how much of the comparison is about memory.
    pub reversals: usize,
    /// Deepest memory the firmware reported (turning points stored, or elements slipping).
    pub deepest_memory: u8,
    /// Samples where the firmware's memory (direction and stored turning points; for the
    /// micro-slip kind the slipping elements, up to those at the margin of f32 rounding)
    /// differed from the host model's.
    pub memory_mismatches: usize,
    pub torque_worst: f64,
    pub torque_rms: f64,
    pub stiffness_worst: f64,
    pub stiffness_rms: f64,
    /// Largest error / allowed error over all compared samples (≤ 1 passes).
    pub worst_bound_ratio: f64,
    /// Samples outside the bound (see [`replay`]).
    pub violations: usize,
    /// The first sample outside the bound, for the report.
    pub first_violation: Option<(usize, Feedforward, Bound)>,
    /// What the firmware's causal reversal band costs: the RMS of the firmware's T_ff against
    /// the offline model (reversals found over the whole replay, as `fit` and `predict` follow
    /// them) on the same deflections, clamped alike, N·m.
    pub offline_torque_rms: f64,
    /// The board's count of samples beyond the spring's identified range (its status, since the
    /// set was written), and the largest excess of those, rad.
    pub beyond_range: u32,
    pub max_excess_rad: f32,
}

impl ReplayReport {
    pub fn passed(&self) -> bool {
        self.violations == 0 && self.off == 0 && self.memory_mismatches == 0
    }
}

impl std::fmt::Display for ReplayReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{} samples: {} active, {} clamped, {} off; {} reversals, memory up to {}, {} samples where the memories differ",
            self.samples,
            self.active,
            self.clamped,
            self.off,
            self.reversals,
            self.deepest_memory,
            self.memory_mismatches
        )?;
        writeln!(f, "T_ff difference: worst {:.3e} N·m, RMS {:.3e} N·m", self.torque_worst, self.torque_rms)?;
        writeln!(
            f,
            "K difference:    worst {:.3e} N·m/rad, RMS {:.3e} N·m/rad",
            self.stiffness_worst, self.stiffness_rms
        )?;
        write!(
            f,
            "worst error / f32 tolerance: {:.3} ({} samples outside; tolerance: {:.0e} of the motion's T and K scale plus the f32 rounding sensitivity of the current branch)",
            self.worst_bound_ratio, self.violations, RELATIVE_TOLERANCE
        )?;
        write!(
            f,
            "\nthe causal reversal band against the offline model: T_ff RMS {:.3e} N·m\nbeyond the spring's identified range (board status): {} samples, largest excess {:.3e} rad",
            self.offline_torque_rms, self.beyond_range, self.max_excess_rad
        )?;
        if let Some((index, fw, bound)) = &self.first_violation {
            write!(
                f,
                "\nfirst outside: sample {index}: θ = {:e} rad, memory {:?}/{}: firmware T = {}, K = {}; host T = {}, K = {} (allowed ±{:e}, ±{:e})",
                fw.deflection,
                fw.direction,
                fw.memory,
                fw.torque,
                fw.stiffness,
                bound.exact.torque,
                bound.exact.stiffness,
                bound.torque,
                bound.stiffness
            )?;
        }
        Ok(())
    }
}

/// Sends every sample through the firmware's control tick (`path`) and compares the results
/// with `model` in f64 (by default the device's own set, [`device_model`], so only evaluation
/// differs), run stateful from rest through the same f32 deflections the firmware reports,
/// with the device's direction band as the genetic kind's reversal band. The device should be
/// at rest too: push (or write) the parameters just before, which resets its memory.
///
/// The tolerance of each sample, for a model with memory: [`RELATIVE_TOLERANCE`] of the
/// motion's scale (max |T| and max |K| of the model over |θ| up to the largest deflection so
/// far, model-core's `GearModel::scales`), plus how far the exact model moves when the f32
/// quantities it depends on move by their rounding (model-core's `Evaluator::rounding`, which
/// says how for each kind). The memories are compared too: direction and depth, within the
/// rounding's allowance.
///
/// Beside it, the firmware's T_ff against the offline model on the same deflections (what its
/// causal band costs), and the board's beyond-range counters, read from its status after the
/// replay.
pub fn replay(
    link: &mut Link,
    joint: &JointParams,
    model: &GearModel<f64>,
    samples: &[(f32, f32)],
    path: EvalPath,
) -> Result<ReplayReport, ReplayError> {
    let mut comparison = Comparison::new(model, joint)?;
    for (index, &(input_angle, output_angle)) in samples.iter().enumerate() {
        let feedforward = link.call::<endpoint::Replay>(&EncoderSample { input_angle, output_angle, path })?;
        comparison.add(index, &feedforward)?;
    }
    let status = link.call::<endpoint::GetStatus>(&())?;
    let mut report = comparison.finish()?;
    (report.beyond_range, report.max_excess_rad) = (status.beyond_range, status.max_excess_rad);
    Ok(report)
}

/// Accumulates the comparison, sample by sample: the f64 model with its memory, and the
/// tolerance.
struct Comparison {
    model: GearModel<f64>,
    evaluator: Evaluator<f64>,
    torque_limit: f64,
    /// The largest |θ| so far: the motion's amplitude for the scale of the tolerance.
    envelope: f64,
    /// Scales per envelope, quantised to steps of 2^(1/8) (upward).
    scales: HashMap<i32, (f64, f64)>,
    last_direction: Option<model_core::Direction>,
    last_theta: Option<(f64, f64)>,
    torque_squares: f64,
    stiffness_squares: f64,
    /// The deflection and T_ff of every sample the firmware evaluated, for the offline model.
    evaluated: Vec<(f64, f64)>,
    report: ReplayReport,
}

impl Comparison {
    fn new(model: &GearModel<f64>, joint: &JointParams) -> Result<Self, ReplayError> {
        Ok(Comparison {
            model: *model,
            evaluator: model.evaluator(f64::from(joint.direction_band))?,
            torque_limit: f64::from(joint.torque_limit),
            envelope: 0.0,
            scales: HashMap::new(),
            last_direction: None,
            last_theta: None,
            torque_squares: 0.0,
            stiffness_squares: 0.0,
            evaluated: Vec::new(),
            report: ReplayReport::default(),
        })
    }

    /// max |T| and max |K| of the model over |θ| ≤ the envelope (rounded up to 2^(k/8)).
    fn scales(&mut self) -> Result<(f64, f64), ReplayError> {
        let key = (self.envelope.max(1.0e-9).log2() * 8.0).ceil() as i32;
        if let Some(&scales) = self.scales.get(&key) {
            return Ok(scales);
        }
        let amplitude = (f64::from(key) / 8.0).exp2();
        let scales = self.model.scales(amplitude)?;
        self.scales.insert(key, scales);
        Ok(scales)
    }

    /// The host's step to θ and the allowed torque and stiffness errors there; whether its
    /// memory matches the firmware's.
    fn step(&mut self, theta: f64, fw: &Feedforward) -> Result<(Bound, bool), ReplayError> {
        self.envelope = self.envelope.max(theta.abs());
        let scales = self.scales()?;
        let base = (RELATIVE_TOLERANCE * scales.0, RELATIVE_TOLERANCE * scales.1);
        let exact = self.evaluator.step(theta)?;
        let rounding = self.evaluator.rounding(theta, &exact)?;
        let memory = self.evaluator.memory();
        // Reversals: the evaluator's direction flips where it follows one (with its band), else
        // where θ reversed.
        let reversed = match (memory.direction, self.last_theta) {
            (Some(_), _) => self.last_direction.is_some() && memory.direction != self.last_direction,
            (None, Some((previous, before))) => (theta - previous) * (previous - before) < 0.0,
            (None, None) => false,
        };
        if reversed {
            self.report.reversals += 1;
        }
        self.last_direction = memory.direction;
        let same_memory =
            fw.direction == memory.direction && usize::from(fw.memory).abs_diff(memory.depth) <= rounding.memory;
        Ok((Bound { exact, torque: base.0 + rounding.torque, stiffness: base.1 + rounding.stiffness }, same_memory))
    }

    fn add(&mut self, index: usize, fw: &Feedforward) -> Result<(), ReplayError> {
        self.report.samples += 1;
        match fw.compensation {
            Compensation::Off => {
                // The firmware skipped the sample (its memory untouched): so does the host.
                self.report.off += 1;
                return Ok(());
            }
            Compensation::Active => self.report.active += 1,
            Compensation::Clamped => self.report.clamped += 1,
        }
        let theta = f64::from(fw.deflection);
        self.evaluated.push((theta, f64::from(fw.torque)));
        let (bound, same_memory) = self.step(theta, fw)?;
        self.last_theta = Some((theta, self.last_theta.map_or(theta, |(previous, _)| previous)));
        let report = &mut self.report;
        report.deepest_memory = report.deepest_memory.max(fw.memory);
        if !same_memory {
            report.memory_mismatches += 1;
        }
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

    fn finish(mut self) -> Result<ReplayReport, ReplayError> {
        let compared = (self.report.active + self.report.clamped).max(1) as f64;
        self.report.torque_rms = (self.torque_squares / compared).sqrt();
        self.report.stiffness_rms = (self.stiffness_squares / compared).sqrt();
        let (theta, firmware): (Vec<f64>, Vec<f64>) = self.evaluated.into_iter().unzip();
        let offline = run_offline(&self.model, &theta, &reversals(&theta)).map_err(|(_, error)| error)?;
        let squares: f64 = offline
            .iter()
            .zip(&firmware)
            .map(|(model, fw)| (fw - model.torque.clamp(-self.torque_limit, self.torque_limit)).powi(2))
            .sum();
        self.report.offline_torque_rms = (squares / compared).sqrt();
        Ok(self.report)
    }
}

/// The device's parameters, which replay needs.
pub fn device_params(link: &mut Link) -> Result<JointParams, ReplayError> {
    link.call::<endpoint::ReadParams>(&())?.ok_or(ReplayError::NoParams)
}

/// The f64 model of a device set, exactly as the device holds it (every f32 is an f64).
pub fn device_model(joint: &JointParams) -> GearModel<f64> {
    joint.model.map(|_, value| f64::from(value))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::fake::FakeDevice;
    use crate::link::push::{joint_params, push, JointSettings};
    use crate::simulate::{simulate, Simulation};

    use model_core::checks::{micro_slip_set, SEED_AMPLITUDE as AMPLITUDE, SEED_TABLE_FIT as SEED_PARAMS};

    fn seed() -> GearModel<f64> {
        GearModel::paper(SEED_PARAMS)
    }

    fn slip() -> GearModel<f64> {
        micro_slip_set().unwrap()
    }

    fn recording(input_bits: Option<u32>) -> Recording {
        simulate(&Simulation {
            params: seed(),
            amplitude_rad: AMPLITUDE,
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

    /// θ = 0.6·A + 0.15·A·sin φ (after a ramp from rest) and θ = A·(0.75·sin φ + 0.25·sin 9φ),
    /// as encoder samples of a 1:50 gear with the output at rest.
    fn motions() -> [Vec<(f32, f32)>; 2] {
        let n = 3000;
        let tau = std::f64::consts::TAU;
        let biased = (0..n)
            .map(|i| {
                let ramp = n / 5;
                if i < ramp {
                    0.6 * AMPLITUDE * i as f64 / ramp as f64
                } else {
                    0.6 * AMPLITUDE + 0.15 * AMPLITUDE * (tau * 4.0 * (i - ramp) as f64 / (n - ramp) as f64).sin()
                }
            })
            .map(|theta| ((50.0 * theta) as f32, 0.0))
            .collect();
        let nested = (0..n)
            .map(|i| {
                let phase = tau * 2.0 * i as f64 / n as f64;
                AMPLITUDE * (0.75 * phase.sin() + 0.25 * (9.0 * phase).sin())
            })
            .map(|theta| ((50.0 * theta) as f32, 0.0))
            .collect();
        [biased, nested]
    }

    fn pushed(model: &GearModel<f64>, torque_limit: f64) -> (Link, JointParams) {
        let mut link = FakeDevice::new().link();
        let settings = JointSettings { gear_ratio: 50.0, torque_limit, direction_band: 2.0e-6 };
        let joint = joint_params(model, &settings).unwrap();
        push(&mut link, &joint).unwrap();
        (link, joint)
    }

    #[test]
    fn both_paths_match_the_f64_model_over_whole_loops() {
        let (mut link, joint) = pushed(&seed(), 100.0);
        let samples = samples(&recording(None), joint.gear_ratio).unwrap();
        for path in [EvalPath::Direct, EvalPath::Fast] {
            // Each replay from rest: a write resets the device's memory.
            link.call::<endpoint::WriteParams>(&joint).unwrap();
            let report = replay(&mut link, &joint, &device_model(&joint), &samples, path).unwrap();
            assert!(report.passed(), "{path:?}: {report}");
            assert_eq!((report.samples, report.active), (samples.len(), samples.len()));
            assert!(report.reversals >= 3, "{report}");
        }
    }

    #[test]
    fn biased_and_nested_motions_of_both_kinds_match_the_f64_model() {
        for model in [seed(), slip()] {
            let (mut link, joint) = pushed(&model, 100.0);
            for samples in motions() {
                for path in [EvalPath::Direct, EvalPath::Fast] {
                    link.call::<endpoint::WriteParams>(&joint).unwrap();
                    let report = replay(&mut link, &joint, &device_model(&joint), &samples, path).unwrap();
                    assert!(report.passed(), "{:?} {path:?}: {report}", model.kind());
                    assert!(report.reversals >= 8 && report.deepest_memory >= 2, "{report}");
                    // Against the unrounded f64 parameters too.
                    link.call::<endpoint::WriteParams>(&joint).unwrap();
                    let report = replay(&mut link, &joint, &model, &samples, path).unwrap();
                    assert!(report.passed(), "{:?} {path:?} against f64: {report}", model.kind());
                }
            }
        }
    }

    /// The band costs the genetic kind against the offline model (its reversals are late by
    /// the band), not the micro-slip kind (which has none); the board counts the samples beyond
    /// a spring's range narrowed to half the motion's, with their largest excess.
    #[test]
    fn the_band_cost_and_the_samples_beyond_the_range_are_reported() {
        let [_, nested] = motions();
        let half = 0.5 * AMPLITUDE;
        let (beyond, largest) = nested.iter().map(|&(input, _)| f64::from(input / 50.0).abs() - half).fold(
            (0, 0.0f64),
            |(count, largest), excess| if excess > 0.0 { (count + 1, largest.max(excess)) } else { (count, largest) },
        );
        let mut costs = Vec::new();
        for model in [seed(), slip()] {
            let narrowed = GearModel { spring: model_core::Spring { range: [-half, half], ..model.spring }, ..model };
            let (mut link, joint) = pushed(&narrowed, 100.0);
            let report = replay(&mut link, &joint, &device_model(&joint), &nested, EvalPath::Fast).unwrap();
            assert!(report.passed(), "{report}");
            assert!(report.beyond_range.abs_diff(beyond) <= 2, "{} beyond, expected {beyond}", report.beyond_range);
            assert!((f64::from(report.max_excess_rad) - largest).abs() < 1.0e-3 * AMPLITUDE, "{report}");
            costs.push(report.offline_torque_rms);
        }
        let peak = seed().scales(AMPLITUDE).unwrap().0;
        let [genetic, micro_slip] = costs[..] else { unreachable!() };
        assert!(genetic > 1.0e-5 * peak && genetic < 1.0e-2 * peak, "genetic band cost {genetic:e} N·m, peak {peak}");
        assert!(micro_slip < 1.0e-5 * peak, "micro-slip {micro_slip:e} N·m");
    }

    #[test]
    fn a_device_not_at_rest_fails_the_comparison() {
        let (mut link, joint) = pushed(&seed(), 100.0);
        let [biased, _] = motions();
        replay(&mut link, &joint, &seed(), &biased[..1000], EvalPath::Fast).unwrap();
        // No write in between: the device remembers the first replay, the host starts at rest.
        let report = replay(&mut link, &joint, &seed(), &biased, EvalPath::Fast).unwrap();
        assert!(!report.passed() && report.memory_mismatches > 0, "{report}");
    }

    #[test]
    fn clamped_samples_are_compared_against_the_limit() {
        let (mut link, joint) = pushed(&seed(), 5.0);
        let samples = samples(&recording(Some(20)), joint.gear_ratio).unwrap();
        let report = replay(&mut link, &joint, &device_model(&joint), &samples, EvalPath::Fast).unwrap();
        assert!(report.clamped > 0 && report.active > 0, "{report}");
        assert!(report.passed(), "{report}");
    }

    #[test]
    fn a_different_model_fails_the_comparison() {
        let samples = motions()[1].clone();
        let other = GearModel::paper(model_core::Params { c1: SEED_PARAMS.c1 * 1.001, ..SEED_PARAMS });
        let (mut link, joint) = pushed(&seed(), 100.0);
        let report = replay(&mut link, &joint, &other, &samples, EvalPath::Fast).unwrap();
        assert!(!report.passed() && report.first_violation.is_some(), "{report}");
        let k = slip().slip_elements()[3].stiffness;
        let other = slip().with(model_core::ParamName::SlipStiffness(3), 1.01 * k);
        let (mut link, joint) = pushed(&slip(), 100.0);
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
