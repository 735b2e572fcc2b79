//! model-core's checks in a form that also runs without `std`: on the host through
//! `cargo test` (one test per check, `tests.rs`) and on the emulated Cortex-M4F (the
//! firmware's `model-core-checks`), where f32 and f64 go through the target's own libm and
//! soft-float helpers.
//!
//! Each check returns `Err` with what failed instead of panicking, so a device can report
//! every failure and exit with a status.
//!
//! The reference parameter sets of the project live here: [`PAPER_TABLE_2`] and
//! [`SEED_TABLE_FIT`], each equal to a file in `data/seed/` (a test compares them).
use crate::tolerance::{loop_scales, Bound};
use crate::{Direction, Error, Evaluation, Model, ParamName, Params, Real};
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

/// The paper's identified values as printed in its Table 2 (`data/seed/paper-params.json`).
pub const PAPER_TABLE_2: Params<f64> =
    Params { c1: 2.4737e4, c2: 1.0e9, c3: -1.1774e14, alpha: 2.6532e6, beta: -4.2268e2, omega: -2.2631e2 };

/// The bundled fit of the seed table `data/seed/lht-20-50.csv`: exactly the `params` of
/// `data/seed/lht-20-50-fit.json` (canonical form, ω = 1). Regenerate both together.
pub const SEED_TABLE_FIT: Params<f64> = Params {
    c1: 9017.390264630189,
    c2: 12248781620.661516,
    c3: -297350209733149.75,
    alpha: 48.61317264674619,
    beta: -2.29817742071738,
    omega: 1.0,
};

/// The seed table's loop amplitude A, rad (`amplitude_rad` of the fit file); the checks
/// evaluate both sets on a loop of this amplitude.
pub const SEED_AMPLITUDE: f64 = 1.168e-3;

/// The reference set of the micro-slip kind for tests and benchmarks, as model version 1 wrote it:
/// 16 elements of rising stiffness k_i = 120 + 15·i N·m/rad on the slip grid 10⁻⁵ … 2·10⁻³ rad,
/// beside the spring 6·10³·θ + 1.2·10¹⁰·θ³.
pub const MICRO_SLIP_V1: crate::legacy::SlipParamsV1<f64> = crate::legacy::SlipParamsV1 {
    c1: 6.0e3,
    c2: 1.2e10,
    c3: 0.0,
    stiffness: [
        120.0, 135.0, 150.0, 165.0, 180.0, 195.0, 210.0, 225.0, 240.0, 255.0, 270.0, 285.0, 300.0, 315.0, 330.0, 345.0,
    ],
    slip_min: 1.0e-5,
    slip_max: 2.0e-3,
};

/// [`MICRO_SLIP_V1`] as today's model (`legacy`'s upgrade: the same torque).
pub fn micro_slip_set() -> Result<crate::GearModel<f64>, Error> {
    crate::legacy::GearModelV1::MicroSlip(MICRO_SLIP_V1).upgrade()
}

/// The simulator's default Bouc–Wen gear (`simulate --physics bouc-wen`) as a model: the spring
/// a·k·x + k3·x³ (a = 0.85, k = 9000 N·m/rad, k3 = 1.2·10¹⁰ N·m/rad³) and H = (1 − a)·k·z with
/// A = 1, β = γ = 1250 1/rad, n = 1.
pub fn bouc_wen_set() -> crate::GearModel<f64> {
    let shape = crate::bouc_wen::BoucWen { a: 1.0, beta: 1250.0, gamma: 1250.0, n: 1.0 };
    crate::GearModel {
        zero: 0.0,
        spring: crate::Spring::polynomial(0.85 * 9000.0, 1.2e10, 0.0),
        hysteresis: crate::Hysteresis::BoucWen(crate::bouc_wen::BoucWenTerm { stiffness: 0.15 * 9000.0, shape }),
    }
}

/// The reference set of the Preisach kind for tests and benchmarks: the spring
/// 9000·x + 1.2·10¹⁰·x³ and a density on a grid of reach 1.4·10⁻³ rad (the seed loop's
/// amplitude and a fifth) that is heavier towards the diagonal and towards high α, so that its
/// loops depend on where they sit: w(i, j) = 0.06·(1 + i/4)/(1 + i − j) N·m.
pub fn preisach_set() -> crate::GearModel<f64> {
    use crate::preisach::{cell, Preisach, CELLS, INTERVALS};
    let mut weights = [0.0; CELLS];
    for i in 0..INTERVALS {
        for j in 0..=i {
            if let Some(w) = weights.get_mut(cell(i, j)) {
                *w = 0.06 * (1.0 + i as f64 / 4.0) / (1.0 + (i - j) as f64);
            }
        }
    }
    crate::GearModel {
        zero: 0.0,
        spring: crate::Spring::polynomial(9000.0, 1.2e10, 0.0),
        hysteresis: crate::Hysteresis::Preisach(Preisach { reach: 1.4e-3, weights }),
    }
}

/// Both reference sets with a short name, for running a check on each.
pub const REFERENCE_SETS: [(&str, Params<f64>); 2] =
    [("paper Table 2", PAPER_TABLE_2), ("seed table fit", SEED_TABLE_FIT)];

const A: f64 = SEED_AMPLITUDE;
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

fn eval<F: Real>(m: &Model<F>, theta: F, direction: Direction, a: F) -> Result<Evaluation<F>, Failure> {
    m.at_amplitude(a)
        .and_then(|lp| lp.evaluate(theta, direction))
        .map_err(|_| Failure { what: "evaluation failed", at: theta.to_f64().unwrap_or(f64::NAN) })
}

/// The loop's torque and stiffness scales ([`loop_scales`]): what tolerances are relative to.
fn scales(m: &Model<f64>) -> Result<(f64, f64), Failure> {
    loop_scales(m, A).map_err(|_| Failure { what: "loop scales", at: A })
}

/// n + 1 points evenly over [−limit, limit].
fn grid(n: u32, limit: f64) -> impl Iterator<Item = f64> {
    (0..=n).map(move |i| -limit + 2.0 * limit * f64::from(i) / f64::from(n))
}

/// The paper's equation in the time domain, term by term: the reference that
/// [`Model`] is checked against.
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
    for (_, params) in REFERENCE_SETS {
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
    for (_, params) in REFERENCE_SETS {
        let m = model(params)?;
        for direction in BOTH {
            // Up to where the slope of asin is still resolvable by a central difference.
            for theta in grid(2000, 0.9999 * A) {
                let step = 1e-6 * A;
                let t = |d: f64| eval(&m, theta + d, direction, A).map(|e| e.torque);
                // Five-point central difference: O(step⁴) truncation error.
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
    for (_, params) in REFERENCE_SETS {
        let m = model(params)?;
        // The polynomial's stiffness less c1, to compare the hysteresis term's slope.
        let poly_gap = |t: f64| 3.0 * params.c2 * t * t + 5.0 * params.c3 * t.powi(4);
        for direction in BOTH {
            for side in [-1.0, 1.0] {
                let edge = eval(&m, side * A, direction, A)?.stiffness;
                ensure(edge.is_finite(), "finite stiffness at the turning point", side * A)?;
                // Beyond ±A the hysteresis term holds its turning-point value and slope.
                let beyond = eval(&m, side * 1.5 * A, direction, A)?.stiffness;
                ensure(
                    ((beyond - poly_gap(1.5 * A)) - (edge - poly_gap(A))).abs() <= 1e-9 * edge.abs(),
                    "stiffness beyond the turning point is the edge value",
                    side * 1.5 * A,
                )?;
                // The cap starts where |cos ωt| = 0.01, continuously.
                let x_cap = (1.0f64 - 0.01 * 0.01).sqrt();
                let inside = eval(&m, side * x_cap * (1.0 - 1e-12) * A, direction, A)?.stiffness;
                let outside = eval(&m, side * x_cap * (1.0 + 1e-12) * A, direction, A)?.stiffness;
                ensure((inside - outside).abs() <= 1e-6 * inside.abs(), "stiffness continuous at the cap", side * A)?;
            }
        }
        // z is continuous at the turning points: both branches meet.
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

/// The f32 model (parameters, θ and A rounded to f32) against the f64 model, within
/// [`Bound`], over 1.05 loops and close to the turning points.
fn f32_stays_within_its_bound_of_f64() -> Check {
    for (_, params) in REFERENCE_SETS {
        let m64 = model(params)?;
        let m32 = Model::new(params.to_f32()).map_err(|_| Failure { what: "f32 model refused", at: 0.0 })?;
        let scales = scales(&m64)?;
        let near_edges = (1..=7).flat_map(|k| {
            let gap = 10f64.powi(-k);
            [(1.0 - gap) * A, -(1.0 - gap) * A]
        });
        for theta in grid(4000, 1.05 * A).chain(near_edges) {
            for direction in BOTH {
                let bound = Bound::at(&m64, theta, direction, A, scales)
                    .map_err(|_| Failure { what: "f64 bound", at: theta })?;
                let e32 = eval(&m32, theta as f32, direction, A as f32)?;
                ensure(
                    bound.admits(f64::from(e32.torque), f64::from(e32.stiffness)),
                    "f32 torque and stiffness within tolerance::Bound",
                    theta,
                )?;
            }
        }
    }
    Ok(())
}

fn only_h_and_r_are_identifiable() -> Check {
    let paper = PAPER_TABLE_2;
    let m = model(paper)?;
    let identifiable = |p: Params<f64>| p.identifiable(A).map_err(|_| Failure { what: "identifiable", at: A });
    let id = identifiable(paper)?;
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
    for scale in [-1.0, 2.0, 0.5, -3.7, 1e3] {
        let scaled =
            Params { alpha: paper.alpha * scale, beta: paper.beta * scale, omega: paper.omega * scale, ..paper };
        let other = model(scaled)?;
        let id_scaled = identifiable(scaled)?;
        ensure(same(id_scaled.h, id.h) && same(id_scaled.r, id.r), "scaled (alpha, beta, omega) same h and r", scale)?;
        for direction in BOTH {
            for theta in grid(100, A) {
                let a = eval(&m, theta, direction, A)?.torque;
                let b = eval(&other, theta, direction, A)?.torque;
                ensure((a - b).abs() <= 1e-9 * (1.0 + a.abs()), "scaled (alpha, beta, omega) same torque", theta)?;
            }
        }
    }
    // The canonical point of the line: ω = 1, β = r, same h and the same torque.
    let canonical = Params::from_identifiable(paper.c1, paper.c2, paper.c3, id, A)
        .map_err(|_| Failure { what: "from_identifiable", at: A })?;
    ensure(canonical.omega == 1.0, "canonical omega is 1", canonical.omega)?;
    ensure((canonical.beta - paper.beta / paper.omega).abs() < 1e-12, "canonical beta is r", canonical.beta)?;
    ensure(same(identifiable(canonical)?.h, id.h), "canonical point same h", canonical.alpha)?;
    let back = model(canonical)?;
    for theta in grid(50, A) {
        let a = eval(&m, theta, Direction::Falling, A)?.torque;
        let b = eval(&back, theta, Direction::Falling, A)?.torque;
        ensure((a - b).abs() <= 1e-9 * (1.0 + a.abs()), "canonical point same torque", theta)?;
    }
    Ok(())
}

fn bad_inputs_are_errors_not_panics() -> Check {
    let paper = PAPER_TABLE_2;
    let refused = |what, ok: bool| ensure(ok, what, 0.0);
    refused("NaN c2", Model::new(Params { c2: f64::NAN, ..paper }) == Err(Error::NonFiniteParameter(ParamName::C2)))?;
    refused(
        "infinite beta",
        Params { beta: f64::INFINITY, ..paper }.validate() == Err(Error::NonFiniteParameter(ParamName::Beta)),
    )?;
    refused("zero omega", Model::new(Params { omega: 0.0, ..paper }) == Err(Error::ZeroOmega))?;
    let m = model(paper)?;
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
    // exp(−rφ) with r = 1e6 over φ up to 3π/2 overflows any float: an error, not ∞.
    let steep = Params { beta: -1e6, omega: 1.0, alpha: 1.0, ..paper };
    refused(
        "overflow is an error",
        Model::new(steep).map(|m| m.torque(0.0, Direction::Falling, A)) == Ok(Err(Error::Overflow)),
    )?;
    // … while a tiny α keeps the same kind of r finite, thanks to the log domain.
    let balanced = Params { alpha: 1e-300, beta: -100.0, omega: 1.0, ..paper };
    refused(
        "tiny alpha with large r stays finite",
        Model::new(balanced).and_then(|m| m.torque(-A, Direction::Falling, A)).is_ok_and(f64::is_finite),
    )?;
    // f32 overflows earlier; still an error.
    let p32 = Params { c1: 1.0f32, c2: 0.0, c3: 0.0, alpha: 1e30, beta: -30.0, omega: 1.0 };
    refused(
        "f32 overflow is an error",
        Model::new(p32).map(|m| m.torque(0.0, Direction::Falling, 1.0)) == Ok(Err(Error::Overflow)),
    )
}

fn no_hysteresis_when_alpha_is_zero() -> Check {
    let m = model(Params { alpha: 0.0, ..PAPER_TABLE_2 })?;
    for theta in grid(20, A) {
        let up = eval(&m, theta, Direction::Rising, A)?.torque;
        let down = eval(&m, theta, Direction::Falling, A)?.torque;
        ensure(up == down, "same torque on both branches", theta)?;
    }
    Ok(())
}
