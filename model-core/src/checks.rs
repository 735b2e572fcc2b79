//! model-core's checks in a form that also runs without `std`: on the host through
//! `cargo test` and on the emulated Cortex-M4F (`firmware/src/bin/model_core_checks.rs`),
//! where f32 and f64 go through the target's own libm and soft-float helpers.
//!
//! Each check returns `Err` with what failed instead of panicking, so a device can report
//! every failure and exit with a status.
use crate::{Direction, Error, Model, ParamName, Params};
use core::f64::consts::PI;
// Without std the float functions come from this trait; where std's inherent methods are
// visible they shadow it and the import goes unused.
#[allow(unused_imports)]
use num_traits::Float;

/// A failed check: which property and where.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Failure {
    pub what: &'static str,
    /// The deflection (or other input) at which it failed.
    pub at: f64,
}

type Check = Result<(), Failure>;

/// A named check.
pub type NamedCheck = (&'static str, fn() -> Result<(), Failure>);

/// Every check with its name.
pub const ALL: [NamedCheck; 7] = [
    ("torque matches the paper's equation", torque_matches_the_papers_equation),
    ("stiffness matches finite differences", stiffness_matches_finite_differences),
    ("turning points are capped and continuous", turning_points_are_capped_and_continuous),
    ("f32 stays within its bound of f64", f32_stays_within_its_bound_of_f64),
    ("only h and r are identifiable", only_h_and_r_are_identifiable),
    ("bad inputs are errors, not panics", bad_inputs_are_errors_not_panics),
    ("no hysteresis when alpha is zero", no_hysteresis_when_alpha_is_zero),
];

/// The paper's identified values (Table 2).
pub const PAPER: Params<f64> =
    Params { c1: 2.4737e4, c2: 1.0e9, c3: -1.1774e14, alpha: 2.6532e6, beta: -4.2268e2, omega: -2.2631e2 };

/// The seed table's fit in canonical form (ω = 1) at A = 1.168 mrad.
pub const SEED_FIT: Params<f64> =
    Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 0.0128 * (1.0 + 2.298 * 2.298) / A, beta: -2.298, omega: 1.0 };

const A: f64 = 1.168e-3;
const BOTH: [Direction; 2] = [Direction::Rising, Direction::Falling];

fn ensure(ok: bool, what: &'static str, at: f64) -> Check {
    if ok {
        Ok(())
    } else {
        Err(Failure { what, at })
    }
}

fn model(params: Params<f64>) -> Result<Model<f64>, Failure> {
    Model::new(params).map_err(|_| Failure { what: "Model::new refused valid parameters", at: 0.0 })
}

fn eval<F: crate::Real>(m: &Model<F>, theta: F, direction: Direction, a: F) -> Result<crate::Evaluation<F>, Failure> {
    m.at_amplitude(a)
        .and_then(|lp| lp.evaluate(theta, direction))
        .map_err(|_| Failure { what: "evaluation failed", at: theta.to_f64().unwrap_or(f64::NAN) })
}

/// n + 1 points evenly over [−limit, limit].
fn grid(n: u32, limit: f64) -> impl Iterator<Item = f64> {
    (0..=n).map(move |i| -limit + 2.0 * limit * f64::from(i) / f64::from(n))
}

/// The paper's equation in the time domain, term by term.
fn paper_torque(p: &Params<f64>, theta: f64, direction: Direction, a: f64) -> f64 {
    let x = (theta / a).clamp(-1.0, 1.0);
    let wt = match direction {
        Direction::Rising => x.asin(),
        Direction::Falling => PI - x.asin(),
    };
    let t = wt / p.omega;
    let z = a * p.alpha * (p.omega * (-p.beta * t).exp() + p.beta * wt.sin() - p.omega * wt.cos())
        / (p.beta * p.beta + p.omega * p.omega)
        * wt.cos().abs();
    p.c1 * theta + p.c2 * theta.powi(3) + p.c3 * theta.powi(5) + z
}

fn torque_matches_the_papers_equation() -> Check {
    for params in [PAPER, SEED_FIT] {
        let m = model(params)?;
        for direction in BOTH {
            for theta in grid(400, 1.2 * A) {
                let expected = paper_torque(&params, theta, direction, A);
                let got = eval(&m, theta, direction, A)?.torque;
                ensure((got - expected).abs() <= 1e-9 * (1.0 + expected.abs()), "torque vs paper", theta)?;
            }
        }
    }
    Ok(())
}

fn stiffness_matches_finite_differences() -> Check {
    for params in [PAPER, SEED_FIT] {
        let m = model(params)?;
        for direction in BOTH {
            for theta in grid(500, 0.9999 * A) {
                let step = 1e-6 * A;
                let t = |d: f64| eval(&m, theta + d, direction, A).map(|e| e.torque);
                let fd = (8.0 * (t(step)? - t(-step)?) - (t(2.0 * step)? - t(-2.0 * step)?)) / (12.0 * step);
                let analytic = eval(&m, theta, direction, A)?.stiffness;
                ensure(
                    (analytic - fd).abs() <= 1e-5 * analytic.abs().max(1e3),
                    "stiffness vs finite difference",
                    theta,
                )?;
            }
        }
    }
    Ok(())
}

fn turning_points_are_capped_and_continuous() -> Check {
    for params in [PAPER, SEED_FIT] {
        let m = model(params)?;
        for direction in BOTH {
            for side in [-1.0, 1.0] {
                let edge = eval(&m, side * A, direction, A)?.stiffness;
                ensure(edge.is_finite(), "finite stiffness at the turning point", side * A)?;
                let x_cap = (1.0f64 - 0.01 * 0.01).sqrt();
                let inside = eval(&m, side * x_cap * (1.0 - 1e-12) * A, direction, A)?.stiffness;
                let outside = eval(&m, side * x_cap * (1.0 + 1e-12) * A, direction, A)?.stiffness;
                ensure((inside - outside).abs() <= 1e-6 * inside.abs(), "stiffness continuous at the cap", side * A)?;
            }
        }
        for side in [-1.0, 1.0] {
            let rising = eval(&m, side * A, Direction::Rising, A)?.torque;
            let falling = eval(&m, side * A, Direction::Falling, A)?.torque;
            ensure(
                (rising - falling).abs() <= 1e-9 * rising.abs().max(1.0),
                "branches meet at the turning point",
                side * A,
            )?;
        }
    }
    Ok(())
}

fn f32_stays_within_its_bound_of_f64() -> Check {
    for params in [PAPER, SEED_FIT] {
        let m64 = model(params)?;
        let m32 = Model::new(params.to_f32()).map_err(|_| Failure { what: "f32 model refused", at: 0.0 })?;
        let mut scale: f64 = 0.0;
        for theta in grid(200, A) {
            scale = scale.max(eval(&m64, theta, Direction::Rising, A)?.torque.abs());
        }
        for direction in BOTH {
            for theta in grid(1000, 1.05 * A) {
                let e64 = eval(&m64, theta, direction, A)?;
                let e32 = eval(&m32, theta as f32, direction, A as f32)?;
                // What rounding θ/A to f32 alone does to the exact model near |θ| = A.
                let ulps = 4.0 * f64::from(f32::EPSILON);
                let up = eval(&m64, theta * (1.0 + ulps), direction, A)?;
                let down = eval(&m64, theta * (1.0 - ulps), direction, A)?;
                let torque_in = (up.torque - down.torque).abs() / 2.0;
                let stiffness_in = (up.stiffness - down.stiffness).abs() / 2.0;
                ensure((f64::from(e32.torque) - e64.torque).abs() <= 2e-5 * scale + torque_in, "f32 torque", theta)?;
                ensure(
                    (f64::from(e32.stiffness) - e64.stiffness).abs()
                        <= 1e-3 * e64.stiffness.abs().max(scale / A) + stiffness_in,
                    "f32 stiffness",
                    theta,
                )?;
            }
        }
    }
    Ok(())
}

fn only_h_and_r_are_identifiable() -> Check {
    let m = model(PAPER)?;
    let id = PAPER.identifiable(A).map_err(|_| Failure { what: "identifiable", at: A })?;
    for scale in [-1.0, 2.0, 0.5, -3.7, 1e3] {
        let scaled =
            Params { alpha: PAPER.alpha * scale, beta: PAPER.beta * scale, omega: PAPER.omega * scale, ..PAPER };
        let other = model(scaled)?;
        for direction in BOTH {
            for theta in grid(100, A) {
                let a = eval(&m, theta, direction, A)?.torque;
                let b = eval(&other, theta, direction, A)?.torque;
                ensure((a - b).abs() <= 1e-9 * (1.0 + a.abs()), "scaled (alpha, beta, omega) same torque", theta)?;
            }
        }
    }
    let canonical = Params::from_identifiable(PAPER.c1, PAPER.c2, PAPER.c3, id, A)
        .map_err(|_| Failure { what: "from_identifiable", at: A })?;
    ensure(canonical.omega == 1.0, "canonical omega is 1", canonical.omega)?;
    let back = model(canonical)?;
    for theta in grid(50, A) {
        let a = eval(&m, theta, Direction::Falling, A)?.torque;
        let b = eval(&back, theta, Direction::Falling, A)?.torque;
        ensure((a - b).abs() <= 1e-9 * (1.0 + a.abs()), "canonical point same torque", theta)?;
    }
    Ok(())
}

fn bad_inputs_are_errors_not_panics() -> Check {
    let refused = |what, ok: bool| ensure(ok, what, 0.0);
    refused("NaN c2", Model::new(Params { c2: f64::NAN, ..PAPER }) == Err(Error::NonFiniteParameter(ParamName::C2)))?;
    refused("zero omega", Model::new(Params { omega: 0.0, ..PAPER }) == Err(Error::ZeroOmega))?;
    let m = model(PAPER)?;
    for a in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        ensure(m.at_amplitude(a) == Err(Error::InvalidAmplitude), "bad amplitude refused", a)?;
    }
    for theta in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        ensure(
            m.torque(theta, Direction::Rising, A) == Err(Error::NonFiniteDeflection),
            "bad deflection refused",
            theta,
        )?;
    }
    let steep = Params { beta: -1e6, omega: 1.0, alpha: 1.0, ..PAPER };
    refused(
        "overflow is an error",
        Model::new(steep).map(|m| m.torque(0.0, Direction::Falling, A)) == Ok(Err(Error::Overflow)),
    )?;
    let p32 = Params { c1: 1.0f32, c2: 0.0, c3: 0.0, alpha: 1e30, beta: -30.0, omega: 1.0 };
    refused(
        "f32 overflow is an error",
        Model::new(p32).map(|m| m.torque(0.0, Direction::Falling, 1.0)) == Ok(Err(Error::Overflow)),
    )
}

fn no_hysteresis_when_alpha_is_zero() -> Check {
    let m = model(Params { alpha: 0.0, ..PAPER })?;
    for theta in grid(20, A) {
        let up = eval(&m, theta, Direction::Rising, A)?.torque;
        let down = eval(&m, theta, Direction::Falling, A)?.torque;
        ensure(up == down, "same torque on both branches", theta)?;
    }
    Ok(())
}

#[cfg(test)]
mod on_the_host {
    #[test]
    fn every_check_passes() {
        for (name, check) in super::ALL {
            assert_eq!(check(), Ok(()), "{name}");
        }
    }
}
