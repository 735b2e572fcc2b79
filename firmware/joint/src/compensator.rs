use crate::{fast::FastModel, tracker::DirectionTracker};
use model_core::{Direction, Model};
use swg_protocol::{Compensation, ErrorReply, EvalPath, Feedforward, JointParams};

/// Largest plausible torsional deflection, rad (≈ 5.7°; strain wave gears deflect a few mrad).
/// Beyond it a reading is an encoder fault: the tick is skipped without touching the loop
/// tracking, so one glitch cannot inflate the amplitude for the loops after it.
pub const MAX_DEFLECTION: f32 = 0.1;

/// A validated parameter set with everything a tick needs prepared.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Installed {
    params: JointParams,
    model: Model<f32>,
    /// `None` when the set is outside the fast path's range: ticks then use `model`.
    fast: Option<FastModel>,
}

/// The feed-forward of one joint: parameters, direction tracking, evaluation, clamping.
///
/// A new set is validated and prepared completely by [`Compensator::stage`] and takes effect
/// at the start of the next [`Compensator::tick`], so no tick ever sees half of it; a
/// refused set leaves the previous one active.
#[derive(Clone, Debug, Default)]
pub struct Compensator {
    active: Option<Installed>,
    staged: Option<Installed>,
    tracker: Option<DirectionTracker>,
}

impl Compensator {
    pub const fn new() -> Self {
        Compensator { active: None, staged: None, tracker: None }
    }

    /// Validates `params` and prepares them for the next tick.
    pub fn stage(&mut self, params: JointParams) -> Result<(), ErrorReply> {
        params.validate()?;
        let model = Model::new(params.model).map_err(|_| ErrorReply::ModelOverflow)?;
        // The model must be evaluable on the loops it will see.
        model.at_amplitude(1.0).map_err(|_| ErrorReply::ModelOverflow)?;
        let fast = FastModel::new(&params.model).ok();
        self.staged = Some(Installed { params, model, fast });
        Ok(())
    }

    /// The set the next tick will use.
    pub fn params(&self) -> Option<JointParams> {
        self.staged.as_ref().or(self.active.as_ref()).map(|installed| installed.params)
    }

    /// One control tick on the two encoder angles (rad; the input side multi-turn).
    /// Never NaN: without valid parameters, with a deflection that is not finite or beyond
    /// [`MAX_DEFLECTION`], or when the model cannot be evaluated, the compensation is off and
    /// T_ff = K = 0.
    pub fn tick(&mut self, input_angle: f32, output_angle: f32, path: EvalPath) -> Feedforward {
        // Copies the set only when one is staged: the tick works on references otherwise.
        if self.staged.is_some() {
            self.active = self.staged.take();
        }
        let off = Feedforward {
            deflection: 0.0,
            direction: Direction::Rising,
            amplitude: 0.0,
            torque: 0.0,
            stiffness: 0.0,
            compensation: Compensation::Off,
        };
        let Some(installed) = self.active.as_ref() else { return off };
        let deflection = input_angle / installed.params.gear_ratio - output_angle;
        if deflection.is_nan() || deflection.abs() > MAX_DEFLECTION {
            return off;
        }
        let band = installed.params.direction_band;
        let tracker = self.tracker.get_or_insert_with(|| DirectionTracker::new(band));
        tracker.set_band(band);
        let (direction, amplitude) = tracker.update(deflection);
        let evaluation = match (path, &installed.fast) {
            (EvalPath::Fast, Some(fast)) => fast.evaluate(deflection, direction, amplitude),
            _ => {
                installed.model.at_amplitude(amplitude).and_then(|on_loop| on_loop.evaluate(deflection, direction)).ok()
            }
        };
        let Some(evaluation) = evaluation else {
            return Feedforward { deflection, direction, amplitude, ..off };
        };
        let limit = installed.params.torque_limit;
        let (torque, stiffness, compensation) = if evaluation.torque.abs() <= limit {
            (evaluation.torque, evaluation.stiffness, Compensation::Active)
        } else {
            // Saturated: the output no longer changes with θ.
            (limit.copysign(evaluation.torque), 0.0, Compensation::Clamped)
        };
        Feedforward { deflection, direction, amplitude, torque, stiffness, compensation }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model_core::{checks::PAPER_TABLE_2, MODEL_VERSION};
    use swg_protocol::{ParamFault, ParamField};

    /// The paper's Table 2 on a 1:100 gear, |T_ff| ≤ 40 N·m.
    fn paper() -> JointParams {
        JointParams {
            model_version: MODEL_VERSION,
            model: PAPER_TABLE_2.to_f32(),
            gear_ratio: 100.0,
            torque_limit: 40.0,
            direction_band: 1.0e-6,
        }
    }

    #[test]
    fn no_parameters_no_compensation() {
        let mut compensator = Compensator::new();
        let out = compensator.tick(1.0, 0.0, EvalPath::Fast);
        assert_eq!((out.torque, out.stiffness, out.compensation), (0.0, 0.0, Compensation::Off));
    }

    #[test]
    fn deflection_is_input_over_ratio_minus_output() {
        let mut compensator = Compensator::new();
        compensator.stage(paper()).unwrap();
        let out = compensator.tick(10.0, 0.0995, EvalPath::Direct);
        assert!((out.deflection - 0.5e-3).abs() < 1e-8, "{}", out.deflection);
        assert_eq!(out.compensation, Compensation::Active);
        let expected = Model::new(paper().model).unwrap().at_amplitude(out.amplitude).unwrap();
        let expected = expected.evaluate(out.deflection, out.direction).unwrap();
        assert_eq!((out.torque, out.stiffness), (expected.torque, expected.stiffness));
    }

    #[test]
    fn torque_is_clamped_and_never_nan() {
        let mut compensator = Compensator::new();
        compensator.stage(paper()).unwrap();
        for output in [-0.5f32, -1.0e-2, 1.0e-2, 0.5, f32::NAN, f32::INFINITY, 1.0e30, -0.09] {
            for path in [EvalPath::Direct, EvalPath::Fast] {
                let out = compensator.tick(0.0, output, path);
                assert!(out.torque.abs() <= paper().torque_limit, "{out:?}");
                assert!(!out.torque.is_nan() && !out.stiffness.is_nan(), "{out:?}");
            }
        }
        // θ = ±2 mrad, past the paper's loop: |T| ≈ 55 N·m > 40 N·m, with the sign of θ.
        for (output, limit) in [(-2.0e-3, paper().torque_limit), (2.0e-3, -paper().torque_limit)] {
            let mut compensator = Compensator::new();
            compensator.stage(paper()).unwrap();
            let out = compensator.tick(0.0, output, EvalPath::Fast);
            assert_eq!((out.torque, out.stiffness, out.compensation), (limit, 0.0, Compensation::Clamped));
        }
    }

    #[test]
    fn an_encoder_glitch_does_not_disturb_the_loop() {
        let mut steady = Compensator::new();
        steady.stage(paper()).unwrap();
        let mut glitched = steady.clone();
        let thetas = [0.2e-3f32, 0.6e-3, 1.0e-3, 0.7e-3, 0.1e-3];
        for (i, theta) in thetas.into_iter().enumerate() {
            if i == 2 {
                let out = glitched.tick(0.0, -0.5, EvalPath::Fast);
                assert_eq!((out.torque, out.compensation), (0.0, Compensation::Off));
            }
            let expected = steady.tick(100.0 * theta, 0.0, EvalPath::Fast);
            assert_eq!(glitched.tick(100.0 * theta, 0.0, EvalPath::Fast), expected);
        }
    }

    #[test]
    fn refused_parameters_leave_the_old_ones_active() {
        let mut compensator = Compensator::new();
        compensator.stage(paper()).unwrap();
        let before = compensator.tick(10.0, 0.0995, EvalPath::Direct);
        let mut bad = paper();
        bad.model.alpha = f32::NAN;
        assert_eq!(
            compensator.stage(bad),
            Err(ErrorReply::InvalidParam { field: ParamField::Alpha, fault: ParamFault::NotFinite })
        );
        let mut huge = paper();
        huge.model.alpha = f32::MAX;
        huge.model.omega = f32::MIN_POSITIVE;
        assert_eq!(compensator.stage(huge), Err(ErrorReply::ModelOverflow));
        assert_eq!(compensator.params(), Some(paper()));
        assert_eq!(compensator.tick(10.0, 0.0995, EvalPath::Direct).torque, before.torque);
    }

    #[test]
    fn a_staged_set_applies_whole_at_the_next_tick() {
        let mut compensator = Compensator::new();
        compensator.stage(paper()).unwrap();
        compensator.tick(10.0, 0.0995, EvalPath::Fast);
        let mut stiffer = paper();
        stiffer.model.c1 *= 2.0;
        stiffer.gear_ratio = 50.0;
        compensator.stage(stiffer).unwrap();
        assert_eq!(compensator.params(), Some(stiffer), "read-back shows the staged set");
        // Same deflection as before only under the new ratio: both fields changed together.
        let out = compensator.tick(5.0, 0.0995, EvalPath::Direct);
        assert!((out.deflection - 0.5e-3).abs() < 1e-8);
        let expected = Model::new(stiffer.model).unwrap().at_amplitude(out.amplitude).unwrap();
        assert_eq!(out.torque, expected.torque(out.deflection, out.direction).unwrap());
    }
}
