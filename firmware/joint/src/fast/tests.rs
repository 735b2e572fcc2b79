extern crate std;
use super::verify::{check, check_fast_path};
use super::*;
use model_core::checks::{PAPER_TABLE_2, REFERENCE_SETS, SEED_AMPLITUDE, SEED_TABLE_FIT};
use model_core::Model;

const AMPLITUDES: [f32; 3] = [0.3e-3, SEED_AMPLITUDE as f32, 2.0e-3];

#[test]
fn fast_path_error_bound() {
    for (_, params) in REFERENCE_SETS {
        for amplitude in AMPLITUDES {
            assert_eq!(check_fast_path(&params, amplitude), Ok(()), "A = {amplitude}");
        }
    }
}

#[test]
fn the_direct_f32_path_meets_the_same_bound() {
    for (_, params) in REFERENCE_SETS {
        let direct = Model::new(params.to_f32()).unwrap();
        for amplitude in AMPLITUDES {
            let result = check(&params, amplitude, |theta, direction, a| {
                direct.at_amplitude(a).and_then(|lp| lp.evaluate(theta, direction)).ok()
            });
            assert_eq!(result, Ok(()), "A = {amplitude}");
        }
    }
}

#[test]
fn the_bound_catches_a_small_error() {
    // A fast path off by 10⁻⁴ of the hysteresis term must fail the check.
    let fast = FastModel::new(&SEED_TABLE_FIT.to_f32()).unwrap();
    let result = check(&SEED_TABLE_FIT, SEED_AMPLITUDE as f32, |theta, direction, a| {
        let mut e = fast.evaluate(theta, direction, a)?;
        e.torque *= 1.0 + 1.0e-4;
        Some(e)
    });
    assert!(result.is_err());
}

#[test]
fn elementary_functions_are_accurate() {
    for i in 0..=20_000 {
        let x = -1.0 + i as f32 / 10_000.0;
        assert!((f64::from(asin(x)) - f64::from(x).asin()).abs() < 3.0e-7, "asin {x}");
    }
    for i in 0..=20_000 {
        let y = -80.0 + i as f32 * 0.008;
        let exact = f64::from(y).exp();
        assert!(((f64::from(exp(y)) - exact) / exact).abs() < 5.0e-7, "exp {y}");
    }
    for i in 0..=20_000 {
        let y = -30.0 + i as f32 * 0.003;
        let exact = f64::from(y).exp_m1();
        assert!((f64::from(exp_m1(y)) - exact).abs() <= 1.0e-6 * exact.abs(), "exp_m1 {y}");
    }
    for i in 0..=20_000 {
        let y = (i as f32 - 10_000.0) * 2.5e-5;
        let exact = f64::from(y).exp_m1();
        assert!((f64::from(exp_m1(y)) - exact).abs() <= 2.0e-7 * exact.abs(), "exp_m1 {y}");
    }
    for i in 0..=20_000 {
        let v = 2f32.powf(-126.0 + i as f32 * 0.0126);
        let exact = f64::from(v).ln();
        assert!((f64::from(ln(v)) - exact).abs() <= 2.0e-7 * exact.abs().max(1.0), "ln {v}");
    }
    for i in 0..=20_000 {
        let v = 2f32.powf(-40.0 + i as f32 * 0.0021);
        for n in [1.2f32, 1.5, 2.0, 3.5, 6.0] {
            let exact = f64::from(v).powf(f64::from(n));
            if exact < f64::from(f32::MIN_POSITIVE) {
                assert_eq!(pow(v, n), 0.0, "pow {v} {n}");
                continue;
            }
            let error = (f64::from(pow(v, n)) - exact).abs() / exact;
            // log2 v and y = n·log2 v round to f32: each a relative error of 2^y of up to
            // |y|·2⁻²⁴·ln 2.
            let y = (f64::from(n) * f64::from(v).log2()).abs();
            assert!(error <= 1.6e-6 * f64::from(n) + 1.0e-7 * y + 2.0e-7, "pow {v} {n}: {error:.1e}");
        }
    }
    assert_eq!(pow(1.0e-30, 6.0), 0.0);
    assert_eq!(<FastMath as Elementary<f32>>::exp(-200.0), exp(-EXP_RANGE));
    assert!(<FastMath as Elementary<f32>>::exp(200.0).is_finite());
}

#[test]
fn out_of_range_sets_have_no_fast_path() {
    let mut params = SEED_TABLE_FIT.to_f32();
    params.beta = 20.0;
    assert_eq!(FastModel::new(&params), Err(FastPathError::DecayOutOfRange));
    params.beta = 1.0;
    params.alpha = f32::NAN;
    assert_eq!(FastModel::new(&params), Err(FastPathError::Invalid));
    params.alpha = f32::MAX;
    params.omega = 1.0e-30;
    params.beta = 0.0;
    assert_eq!(FastModel::new(&params), Err(FastPathError::Overflow));
}

#[test]
fn invalid_inputs_give_none_not_nan() {
    let fast = FastModel::new(&PAPER_TABLE_2.to_f32()).unwrap();
    assert_eq!(fast.evaluate(f32::NAN, Direction::Rising, 1.0e-3), None);
    assert_eq!(fast.evaluate(0.0, Direction::Rising, 0.0), None);
    assert_eq!(fast.evaluate(0.0, Direction::Falling, f32::INFINITY), None);
}
