extern crate std;

use super::*;
use proptest::prelude::*;
use std::vec::Vec;

/// The paper's identified values (Table 2).
const PAPER: Params<f64> =
    Params { c1: 2.4737e4, c2: 1.0e9, c3: -1.1774e14, alpha: 2.6532e6, beta: -4.2268e2, omega: -2.2631e2 };

/// The optimum `swg-host fit` finds on the seed table (identifiable form at A = 1.168e-3).
fn seed_fit() -> Params<f64> {
    Params::from_identifiable(9.0e3, 1.2e10, 0.0, Identifiable { h: 0.0128, r: -2.298 }, 1.168e-3).unwrap()
}

const A: f64 = 1.168e-3;

/// The paper's equation written out in the time domain, term by term.
fn paper_torque(p: &Params<f64>, theta: f64, direction: Direction, a: f64) -> f64 {
    let x = (theta / a).clamp(-1.0, 1.0);
    let wt = match direction {
        Direction::Rising => x.asin(),
        Direction::Falling => core::f64::consts::PI - x.asin(),
    };
    let t = wt / p.omega;
    let z = a * p.alpha * (p.omega * (-p.beta * t).exp() + p.beta * wt.sin() - p.omega * wt.cos())
        / (p.beta * p.beta + p.omega * p.omega)
        * wt.cos().abs();
    p.c1 * theta + p.c2 * theta.powi(3) + p.c3 * theta.powi(5) + z
}

fn grid(n: usize, limit: f64) -> Vec<f64> {
    (0..=n).map(|i| -limit + 2.0 * limit * i as f64 / n as f64).collect()
}

const BOTH: [Direction; 2] = [Direction::Rising, Direction::Falling];

#[test]
fn torque_matches_the_papers_equation() {
    for params in [PAPER, seed_fit()] {
        let model = Model::new(params).unwrap();
        for direction in BOTH {
            for theta in grid(400, 1.2 * A) {
                let expected = paper_torque(&params, theta, direction, A);
                let got = model.torque(theta, direction, A).unwrap();
                assert!(
                    (got - expected).abs() <= 1e-9 * (1.0 + expected.abs()),
                    "θ={theta:e} {direction:?}: {got} vs {expected}"
                );
            }
        }
    }
}

#[test]
fn stiffness_matches_finite_differences_over_the_whole_loop() {
    for params in [PAPER, seed_fit()] {
        let lp = Model::new(params).unwrap().at_amplitude(A).unwrap();
        for direction in BOTH {
            // Up to where the slope of asin is still resolvable by a central difference.
            for theta in grid(2000, 0.9999 * A) {
                let step = 1e-6 * A;
                let t = |d: f64| lp.torque(theta + d, direction).unwrap();
                // Five-point central difference: O(step⁴) truncation error.
                let fd = (8.0 * (t(step) - t(-step)) - (t(2.0 * step) - t(-2.0 * step))) / (12.0 * step);
                let analytic = lp.stiffness(theta, direction).unwrap();
                assert!(
                    (analytic - fd).abs() <= 1e-5 * analytic.abs().max(1e3),
                    "θ/A={:.6} {direction:?}: analytic {analytic} vs fd {fd}",
                    theta / A
                );
            }
        }
    }
}

#[test]
fn stiffness_at_the_turning_points_is_the_capped_edge_slope() {
    for params in [PAPER, seed_fit()] {
        let model = Model::new(params).unwrap();
        let lp = model.at_amplitude(A).unwrap();
        for direction in BOTH {
            for side in [-1.0, 1.0] {
                let at_edge = lp.stiffness(side * A, direction).unwrap();
                assert!(at_edge.is_finite());
                // Beyond ±A the hysteresis term holds its turning-point value, and the
                // stiffness holds the edge value.
                let beyond = lp.stiffness(side * 1.5 * A, direction).unwrap();
                let poly_gap = |t: f64| 3.0 * params.c2 * t * t + 5.0 * params.c3 * t.powi(4);
                assert!(((beyond - poly_gap(1.5 * A)) - (at_edge - poly_gap(A))).abs() <= 1e-9 * at_edge.abs());
                // The cap starts where |cos ωt| = 0.01, continuously.
                let x_cap = (1.0f64 - 0.01 * 0.01).sqrt();
                let inside = lp.stiffness(side * x_cap * (1.0 - 1e-12) * A, direction).unwrap();
                let outside = lp.stiffness(side * x_cap * (1.0 + 1e-12) * A, direction).unwrap();
                assert!((inside - outside).abs() <= 1e-6 * inside.abs(), "{inside} {outside}");
            }
        }
        // z is continuous at the turning points: both branches meet.
        for side in [-1.0, 1.0] {
            let rising = lp.torque(side * A, Direction::Rising).unwrap();
            let falling = lp.torque(side * A, Direction::Falling).unwrap();
            assert!((rising - falling).abs() <= 1e-9 * rising.abs().max(1.0));
        }
    }
}

#[test]
fn f32_stays_within_its_bound_of_f64() {
    for params in [PAPER, seed_fit()] {
        let p32 = params.to_f32();
        let l64 = Model::new(params).unwrap().at_amplitude(A).unwrap();
        let l32 = Model::new(p32).unwrap().at_amplitude(A as f32).unwrap();
        let scale = grid(200, A).iter().map(|&t| l64.torque(t, Direction::Rising).unwrap().abs()).fold(0.0, f64::max);
        for direction in BOTH {
            for theta in grid(4000, 1.05 * A) {
                let e64 = l64.evaluate(theta, direction).unwrap();
                let e32 = l32.evaluate(theta as f32, direction).unwrap();
                // What rounding θ/A to f32 alone does to the exact model: near |θ| = A the
                // torque is a steep function of θ/A, and no f32 evaluation can beat that.
                let ulps = 4.0 * f32::EPSILON as f64;
                let sensitivity =
                    |f: &dyn Fn(f64) -> f64| (f(theta * (1.0 + ulps)) - f(theta * (1.0 - ulps))).abs() / 2.0;
                let torque_in = sensitivity(&|t| l64.torque(t, direction).unwrap());
                let stiffness_in = sensitivity(&|t| l64.stiffness(t, direction).unwrap());
                // Torque: 2·10⁻⁵ of the loop's torque range (≈ 0.6 mN·m on a 30 N·m loop)
                // on top of the input rounding.
                assert!(
                    (e32.torque as f64 - e64.torque).abs() <= 2e-5 * scale + torque_in,
                    "θ={theta:e}: {} vs {}",
                    e32.torque,
                    e64.torque
                );
                // Stiffness: 10⁻³ relative; near |θ| = A it is a steep function of θ/A.
                assert!(
                    (e32.stiffness as f64 - e64.stiffness).abs()
                        <= 1e-3 * e64.stiffness.abs().max(scale / A) + stiffness_in,
                    "θ={theta:e}: {} vs {}",
                    e32.stiffness,
                    e64.stiffness
                );
            }
        }
    }
}

#[test]
fn only_h_and_r_are_identifiable() {
    let model = Model::new(PAPER).unwrap();
    let id = PAPER.identifiable(A).unwrap();
    for scale in [-1.0, 2.0, 0.5, -3.7, 1e3] {
        let scaled =
            Params { alpha: PAPER.alpha * scale, beta: PAPER.beta * scale, omega: PAPER.omega * scale, ..PAPER };
        let other = Model::new(scaled).unwrap();
        let id_scaled = scaled.identifiable(A).unwrap();
        assert!((id_scaled.h - id.h).abs() <= 1e-12 * id.h.abs());
        assert!((id_scaled.r - id.r).abs() <= 1e-12 * id.r.abs());
        for direction in BOTH {
            for theta in grid(100, A) {
                let a = model.torque(theta, direction, A).unwrap();
                let b = other.torque(theta, direction, A).unwrap();
                assert!((a - b).abs() <= 1e-9 * (1.0 + a.abs()), "scale {scale}: {a} vs {b}");
            }
        }
    }
    // The canonical point of the line: ω = 1, β = r, same torque.
    let canonical = Params::from_identifiable(PAPER.c1, PAPER.c2, PAPER.c3, id, A).unwrap();
    assert_eq!(canonical.omega, 1.0);
    assert!((canonical.beta - PAPER.beta / PAPER.omega).abs() < 1e-12);
    let back = canonical.identifiable(A).unwrap();
    assert!((back.h - id.h).abs() <= 1e-12 * id.h.abs());
    let m = Model::new(canonical).unwrap();
    for theta in grid(50, A) {
        let a = model.torque(theta, Direction::Falling, A).unwrap();
        let b = m.torque(theta, Direction::Falling, A).unwrap();
        assert!((a - b).abs() <= 1e-9 * (1.0 + a.abs()));
    }
}

#[test]
fn bad_parameters_and_inputs_are_errors_not_panics() {
    let nan = Params { c2: f64::NAN, ..PAPER };
    assert_eq!(Model::new(nan), Err(Error::NonFiniteParameter(ParamName::C2)));
    let inf = Params { beta: f64::INFINITY, ..PAPER };
    assert_eq!(inf.validate(), Err(Error::NonFiniteParameter(ParamName::Beta)));
    assert_eq!(Model::new(Params { omega: 0.0, ..PAPER }), Err(Error::ZeroOmega));
    let model = Model::new(PAPER).unwrap();
    for a in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        assert_eq!(model.at_amplitude(a), Err(Error::InvalidAmplitude));
    }
    for theta in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        assert_eq!(model.torque(theta, Direction::Rising, A), Err(Error::NonFiniteDeflection));
    }
    // exp(−rφ) with r = 1e6 over φ up to 3π/2 overflows any float: an error, not ∞.
    let steep = Params { beta: -1e6, omega: 1.0, alpha: 1.0, ..PAPER };
    let lp = Model::new(steep).unwrap().at_amplitude(A).unwrap();
    assert_eq!(lp.torque(0.0, Direction::Falling), Err(Error::Overflow));
    // … while a tiny α keeps the same r finite, thanks to the log domain.
    let balanced = Params { alpha: 1e-300, beta: -100.0, omega: 1.0, ..PAPER };
    let value = Model::new(balanced).unwrap().torque(-A, Direction::Falling, A).unwrap();
    assert!(value.is_finite());
    // f32 overflows earlier; still an error.
    let p32 = Params { c1: 1.0f32, c2: 0.0, c3: 0.0, alpha: 1e30, beta: -30.0, omega: 1.0 };
    assert_eq!(Model::new(p32).unwrap().torque(0.0, Direction::Falling, 1.0), Err(Error::Overflow));
}

#[test]
fn no_hysteresis_when_alpha_is_zero() {
    let elastic = Params { alpha: 0.0, ..PAPER };
    let lp = Model::new(elastic).unwrap().at_amplitude(A).unwrap();
    for theta in grid(20, A) {
        let up = lp.torque(theta, Direction::Rising).unwrap();
        let down = lp.torque(theta, Direction::Falling).unwrap();
        assert_eq!(up, down);
    }
}

#[test]
fn error_messages_name_the_problem() {
    use std::string::ToString;
    assert_eq!(Error::NonFiniteParameter(ParamName::Alpha).to_string(), "parameter alpha is not a finite number");
    assert!(Error::InvalidAmplitude.to_string().contains("amplitude"));
}

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1e3f64..1e3,
        1 => any::<f64>(),
        1 => Just(0.0),
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
    ]
}

proptest! {
    #[test]
    fn evaluation_is_finite_or_an_error(
        c1 in any_f64(), c2 in any_f64(), c3 in any_f64(),
        alpha in any_f64(), beta in any_f64(), omega in any_f64(),
        amplitude in any_f64(), theta in any_f64(), rising in any::<bool>(),
    ) {
        let direction = if rising { Direction::Rising } else { Direction::Falling };
        let params = Params { c1, c2, c3, alpha, beta, omega };
        if let Ok(model) = Model::new(params) {
            if let Ok(e) = model.at_amplitude(amplitude).and_then(|l| l.evaluate(theta, direction)) {
                prop_assert!(e.torque.is_finite() && e.stiffness.is_finite());
            }
        }
        let p32 = Params {
            c1: c1 as f32, c2: c2 as f32, c3: c3 as f32,
            alpha: alpha as f32, beta: beta as f32, omega: omega as f32,
        };
        if let Ok(model) = Model::new(p32) {
            if let Ok(e) = model.at_amplitude(amplitude as f32).and_then(|l| l.evaluate(theta as f32, direction)) {
                prop_assert!(e.torque.is_finite() && e.stiffness.is_finite());
            }
        }
    }
}
