//! Host-only tests: one test per entry of [`checks::ALL`] (the properties themselves live in
//! `checks.rs`, which also runs on the Cortex-M4F), the reference sets against their files in
//! `data/seed/`, and what needs std (Display, property tests).
extern crate std;

use super::*;
use checks::{PAPER_TABLE_2, SEED_AMPLITUDE, SEED_TABLE_FIT};
use proptest::prelude::*;
use std::vec::Vec;

/// Runs the entry of [`checks::ALL`] named `name`.
fn run_check(name: &str) {
    let check = checks::ALL.iter().find(|(n, _)| *n == name).map(|(_, check)| check);
    let check = check.unwrap_or_else(|| panic!("no check named {name:?} in checks::ALL"));
    assert_eq!(check(), Ok(()), "{name}");
}

/// One `#[test]` per check, so that each failure is reported on its own, and a test that
/// [`checks::ALL`] holds exactly these (in this order): a new check needs a line here.
macro_rules! one_test_per_check {
    ($($test:ident: $name:literal,)*) => {
        $(
            #[test]
            fn $test() {
                run_check($name);
            }
        )*

        #[test]
        fn every_check_has_its_own_test() {
            let all: Vec<&str> = checks::ALL.iter().map(|(name, _)| *name).collect();
            assert_eq!(all, [$($name),*]);
        }
    };
}

one_test_per_check! {
    torque_matches_the_papers_equation: "torque matches the paper's equation",
    stiffness_matches_finite_differences: "stiffness matches finite differences",
    turning_points_are_capped_and_continuous: "turning points are capped and continuous",
    f32_stays_within_its_bound_of_f64: "f32 stays within its bound of f64",
    only_h_and_r_are_identifiable: "only h and r are identifiable",
    bad_inputs_are_errors_not_panics: "bad inputs are errors, not panics",
    no_hysteresis_when_alpha_is_zero: "no hysteresis when alpha is zero",
}

/// The paper's six parameters of a `params` object in a JSON file, exactly as written there:
/// flat (model version 1, as `paper-params.json` prints the paper's table) or as a model version 2
/// gear whose spring is the polynomial alone, zero at 0.
fn params_in(json: &str) -> Params<f64> {
    let file: serde_json::Value = serde_json::from_str(json).unwrap();
    let params = file["params"].as_object().unwrap();
    let spring = match params.get("spring") {
        Some(spring) => {
            assert_eq!(params["zero"].as_f64(), Some(0.0), "a paper gear's zero is 0");
            assert_eq!(spring["knots"].as_array().map(Vec::len), Some(0), "a paper gear's spring has no knots");
            spring.as_object().unwrap()
        }
        None => params,
    };
    let get = |object: &serde_json::Map<std::string::String, serde_json::Value>, name: &str| {
        object[name].as_f64().unwrap_or_else(|| panic!("{name} is not a number"))
    };
    Params {
        c1: get(spring, "c1"),
        c2: get(spring, "c2"),
        c3: get(spring, "c3"),
        alpha: get(params, "alpha"),
        beta: get(params, "beta"),
        omega: get(params, "omega"),
    }
}

/// Bit for bit, so that a one-ulp difference (or -0.0 for 0.0) fails.
fn assert_same_bits(constant: Params<f64>, file: Params<f64>, what: &str) {
    let pairs = [
        ("c1", constant.c1, file.c1),
        ("c2", constant.c2, file.c2),
        ("c3", constant.c3, file.c3),
        ("alpha", constant.alpha, file.alpha),
        ("beta", constant.beta, file.beta),
        ("omega", constant.omega, file.omega),
    ];
    for (name, a, b) in pairs {
        assert_eq!(a.to_bits(), b.to_bits(), "{what}: {name} is {a:e} in model_core::checks, {b:e} in the file");
    }
}

#[test]
fn paper_table_2_is_the_paper_params_file() {
    let file = params_in(include_str!("../../data/seed/paper-params.json"));
    assert_same_bits(PAPER_TABLE_2, file, "data/seed/paper-params.json");
}

#[test]
fn seed_table_fit_is_the_bundled_fit() {
    let json = include_str!("../../data/seed/lht-20-50-fit.json");
    assert_same_bits(SEED_TABLE_FIT, params_in(json), "data/seed/lht-20-50-fit.json");
    let file: serde_json::Value = serde_json::from_str(json).unwrap();
    let identifiable = &file["identifiable"];
    assert_eq!(identifiable["amplitude_rad"].as_f64(), Some(SEED_AMPLITUDE));
    // The file's (h, r) are the same point as its params.
    let id = SEED_TABLE_FIT.identifiable(SEED_AMPLITUDE).unwrap();
    let (h, r) = (identifiable["h"].as_f64().unwrap(), identifiable["r"].as_f64().unwrap());
    assert!((id.h - h).abs() <= 1e-12 * h.abs() && id.r == r, "{id:?} vs h = {h}, r = {r}");
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
        if let Ok(model) = Model::new(params.to_f32()) {
            if let Ok(e) = model.at_amplitude(amplitude as f32).and_then(|l| l.evaluate(theta as f32, direction)) {
                prop_assert!(e.torque.is_finite() && e.stiffness.is_finite());
            }
        }
    }
}
