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
