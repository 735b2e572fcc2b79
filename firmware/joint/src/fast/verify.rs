//! The fast path's error bound against the f64 model ([`model_core::tolerance`]), checkable
//! without `std`: run by the host tests and, with the target's own FPU `vsqrt` and float
//! code, on the emulated Cortex-M4F (`model-core-checks`).
use super::FastModel;
use model_core::tolerance::{loop_scales, Bound};
use model_core::{Direction, Evaluation, Model, Params};

/// Where an evaluation left its bound (`None`: it could not be evaluated at all).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Violation {
    pub theta: f32,
    pub direction: Direction,
    pub got: Option<Evaluation<f32>>,
    pub bound: Option<Bound>,
}

/// Deflections over [−A, A], dense near the turning points (down to 10⁻⁷·A away).
pub fn deflections(amplitude: f32) -> impl Iterator<Item = f32> {
    let even = (0..=400).map(move |i| amplitude * (-1.0 + i as f32 / 200.0));
    let near_edges = (1..=7).flat_map(move |k| {
        let gap = libm::powf(10.0, -(k as f32));
        [amplitude * (1.0 - gap), -amplitude * (1.0 - gap)]
    });
    even.chain(near_edges)
}

/// Checks `evaluate` (θ, direction, A → T and K in f32) against the f64 model of `params`
/// over one loop of amplitude `amplitude`.
pub fn check(
    params: &Params<f64>,
    amplitude: f32,
    evaluate: impl Fn(f32, Direction, f32) -> Option<Evaluation<f32>>,
) -> Result<(), Violation> {
    let fail = |theta, direction| Violation { theta, direction, got: None, bound: None };
    let model = Model::new(*params).map_err(|_| fail(0.0, Direction::Rising))?;
    let scales = loop_scales(&model, f64::from(amplitude)).map_err(|_| fail(0.0, Direction::Rising))?;
    for theta in deflections(amplitude) {
        for direction in [Direction::Rising, Direction::Falling] {
            let bound = Bound::at(&model, f64::from(theta), direction, f64::from(amplitude), scales)
                .map_err(|_| fail(theta, direction))?;
            let got = evaluate(theta, direction, amplitude);
            match got {
                Some(e) if bound.admits(f64::from(e.torque), f64::from(e.stiffness)) => {}
                _ => return Err(Violation { theta, direction, got, bound: Some(bound) }),
            }
        }
    }
    Ok(())
}

/// [`check`] for the fast path of `params` (rounded to f32 as the firmware holds them).
pub fn check_fast_path(params: &Params<f64>, amplitude: f32) -> Result<(), Violation> {
    let fast = FastModel::new(&params.to_f32()).map_err(|_| Violation {
        theta: 0.0,
        direction: Direction::Rising,
        got: None,
        bound: None,
    })?;
    check(params, amplitude, |theta, direction, a| fast.evaluate(theta, direction, a))
}
