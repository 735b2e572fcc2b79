//! Harness for the host's readers: the CSV tables (loop table and recording, one reader), the
//! params-file parser and the plan-file parser. Any input gives a dataset that keeps the documented invariants, or
//! an error that names the file.
use std::path::Path;
use swg_host::input::plan::parse_plan;
use swg_host::input::{parse, Dataset, MAX_DEFLECTION_RAD, MAX_TORQUE_NM};
use swg_host::report::params::parse_model;

const NAME: &str = "fuzz.csv";

/// One CSV input through the reader both formats share; `ratio` as `--ratio` gives it.
pub fn csv(data: &[u8], ratio: Option<f64>) {
    match parse(Path::new(NAME), data, ratio) {
        Ok(Dataset::LoopTable(table)) => {
            assert_eq!(table.branch.len(), table.torque.len());
            assert_eq!(table.torque.len(), table.deflection.len());
            check_values(&table.torque, &table.deflection);
        }
        Ok(Dataset::Recording(rec)) => {
            assert!(rec.ratio.is_finite() && rec.ratio > 0.0, "ratio {}", rec.ratio);
            let n = rec.time.len();
            assert_eq!(rec.torque.len(), n);
            assert_eq!(rec.deflection.len(), n);
            if let Some(angles) = &rec.angles {
                assert_eq!((angles.input.len(), angles.output.len()), (n, n));
            }
            if let Some(temperature) = &rec.temperature {
                assert_eq!(temperature.len(), n);
                assert!(temperature.iter().all(|t| t.is_finite()));
            }
            assert!(rec.time.iter().all(|t| t.is_finite()));
            assert!(rec.time.windows(2).all(|w| w[0] < w[1]), "time not strictly increasing");
            check_values(&rec.torque, &rec.deflection);
            assert_eq!(rec.first_non_finite(), None);
            let mut keys: Vec<&str> = rec.metadata.iter().map(|(k, _)| k.as_str()).collect();
            keys.sort_unstable();
            assert!(keys.windows(2).all(|w| w[0] != w[1]), "a metadata key twice");
        }
        Err(error) => {
            let message = error.to_string();
            assert!(message.starts_with(NAME), "error without the file name: {message}");
            assert!(!error.message.trim().is_empty(), "an empty error message");
        }
    }
}

fn check_values(torque: &[f64], deflection: &[f64]) {
    assert!(torque.iter().all(|t| t.is_finite() && t.abs() <= MAX_TORQUE_NM));
    assert!(deflection.iter().all(|d| d.is_finite() && d.abs() <= MAX_DEFLECTION_RAD));
}

/// One params file: a model that validates, or an error that names the file.
pub fn params(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match parse_model(Path::new("fuzz.json"), text) {
        Ok(model) => assert!(model.validate().is_ok()),
        Err(error) => assert!(error.to_string().starts_with("fuzz.json"), "{error}"),
    }
}

/// One plan file: refused with the file named, or checked at two rates and its first ticks
/// played within its channel's limit, finite.
pub fn plan(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let spec = match parse_plan(Path::new("fuzz.json"), text) {
        Ok(spec) => spec,
        Err(error) => return assert!(error.to_string().starts_with("fuzz.json"), "{error}"),
    };
    for rate in [1000.0, 20_000.0] {
        match spec.at_rate(rate) {
            Ok(plan) => {
                assert_eq!(plan.check(), Ok(()));
                let limit = f64::from(plan.limit());
                for setpoint in plan.player::<f64>().take(2000) {
                    assert!(setpoint.value.is_finite() && setpoint.slope.is_finite(), "{setpoint:?}");
                    assert!(setpoint.value.abs() <= limit * (1.0 + 1e-6), "{setpoint:?} beyond {limit}");
                }
            }
            Err(error) => assert!(error.to_string().starts_with("fuzz.json"), "{error}"),
        }
    }
}
