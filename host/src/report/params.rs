//! Parameter files: a JSON object with the model's kind in `model` and its parameters in
//! `params`, which is what `swg-host fit --out` writes.
//!
//! - `"model": "genetic-hysteresis"` (or no `model`, as files from before the micro-slip kind):
//!   `params` {c1, c2, c3, alpha, beta, omega};
//! - `"model": "micro-slip"`: `params` {c1, c2, c3, stiffness: [16 values, N·m/rad], slip_min,
//!   slip_max (rad)}.
use crate::gear::{GearModel, ModelKind, MICRO_SLIP_NAME, SLIP_ELEMENTS};
use model_core::memory::SlipParams;
use model_core::{Params, MODEL_NAME};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ParamsFileError {
    #[error("{path}: cannot read: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{path}:{line}:{column}: {message}")]
    Syntax { path: PathBuf, line: usize, column: usize, message: String },
    #[error("{path}: model {found:?} is not one this tool knows ({MODEL_NAME:?} or {MICRO_SLIP_NAME:?})")]
    UnknownModel { path: PathBuf, found: String },
    #[error("{path}: this command takes the {MODEL_NAME:?} model; the file holds {found:?}")]
    WrongModel { path: PathBuf, found: &'static str },
    #[error("{path}: params.stiffness: expected {SLIP_ELEMENTS} values, found {found}")]
    ElementCount { path: PathBuf, found: usize },
    #[error("{path}: {source}")]
    Invalid { path: PathBuf, source: model_core::Error },
}

#[derive(serde::Deserialize)]
struct Header {
    model: Option<String>,
}

#[derive(serde::Deserialize)]
struct GeneticFile {
    params: Params<f64>,
}

/// The micro-slip parameters as files write them (a list where model-core has an array).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SlipParamsFile {
    pub c1: f64,
    pub c2: f64,
    pub c3: f64,
    /// k_i, N·m/rad, one per element, on the log grid from `slip_min` to `slip_max`.
    pub stiffness: Vec<f64>,
    /// d_min, rad.
    pub slip_min: f64,
    /// d_max, rad.
    pub slip_max: f64,
}

impl From<&SlipParams<f64, SLIP_ELEMENTS>> for SlipParamsFile {
    fn from(p: &SlipParams<f64, SLIP_ELEMENTS>) -> Self {
        SlipParamsFile {
            c1: p.c1,
            c2: p.c2,
            c3: p.c3,
            stiffness: p.stiffness.to_vec(),
            slip_min: p.slip_min,
            slip_max: p.slip_max,
        }
    }
}

#[derive(serde::Deserialize)]
struct SlipFile {
    params: SlipParamsFile,
}

/// Reads and validates a parameter file of either kind.
pub fn read_model(path: &Path) -> Result<GearModel, ParamsFileError> {
    let text =
        std::fs::read_to_string(path).map_err(|source| ParamsFileError::Read { path: path.to_owned(), source })?;
    parse_model(path, &text)
}

/// Reads a parameter file that must hold the genetic model.
pub fn read_params(path: &Path) -> Result<Params<f64>, ParamsFileError> {
    match read_model(path)? {
        GearModel::Genetic(params) => Ok(params),
        other => Err(ParamsFileError::WrongModel { path: path.to_owned(), found: other.kind().name() }),
    }
}

/// [`read_params`] of a text already read.
pub fn parse_params(path: &Path, text: &str) -> Result<Params<f64>, ParamsFileError> {
    match parse_model(path, text)? {
        GearModel::Genetic(params) => Ok(params),
        other => Err(ParamsFileError::WrongModel { path: path.to_owned(), found: other.kind().name() }),
    }
}

/// [`read_model`] of a text already read.
pub fn parse_model(path: &Path, text: &str) -> Result<GearModel, ParamsFileError> {
    let syntax = |e: serde_json::Error| ParamsFileError::Syntax {
        path: path.to_owned(),
        line: e.line(),
        column: e.column(),
        message: e.to_string().split(" at line ").next().unwrap_or_default().to_owned(),
    };
    let header: Header = serde_json::from_str(text).map_err(syntax)?;
    let kind = match header.model.as_deref() {
        None => ModelKind::Genetic,
        Some(name) => ModelKind::ALL
            .into_iter()
            .find(|kind| kind.name() == name)
            .ok_or_else(|| ParamsFileError::UnknownModel { path: path.to_owned(), found: name.to_owned() })?,
    };
    let model =
        match kind {
            ModelKind::Genetic => GearModel::Genetic(serde_json::from_str::<GeneticFile>(text).map_err(syntax)?.params),
            ModelKind::MicroSlip => {
                let file = serde_json::from_str::<SlipFile>(text).map_err(syntax)?.params;
                let stiffness: [f64; SLIP_ELEMENTS] = file.stiffness.as_slice().try_into().map_err(|_| {
                    ParamsFileError::ElementCount { path: path.to_owned(), found: file.stiffness.len() }
                })?;
                GearModel::MicroSlip(SlipParams {
                    c1: file.c1,
                    c2: file.c2,
                    c3: file.c3,
                    stiffness,
                    slip_min: file.slip_min,
                    slip_max: file.slip_max,
                })
            }
        };
    model.validate().map_err(|source| ParamsFileError::Invalid { path: path.to_owned(), source })?;
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_params_and_points_at_errors() {
        let path = Path::new("p.json");
        let ok = r#"{"model": "genetic-hysteresis", "params": {"c1": 1, "c2": 2, "c3": 3, "alpha": 4, "beta": 5, "omega": 6}}"#;
        assert_eq!(parse_params(path, ok).unwrap().omega, 6.0);
        let missing = "{\"params\": {\"c1\": 1,\n \"c2\": 2}}";
        let err = parse_params(path, missing).unwrap_err().to_string();
        assert!(err.starts_with("p.json:2:") && err.contains("missing field `c3`"), "{err}");
        let zero = r#"{"params": {"c1": 1, "c2": 2, "c3": 3, "alpha": 4, "beta": 5, "omega": 0}}"#;
        assert!(parse_params(path, zero).unwrap_err().to_string().contains("omega is zero"));
        let other = r#"{"model": "dahl", "params": {"c1": 1, "c2": 2, "c3": 3, "alpha": 4, "beta": 5, "omega": 1}}"#;
        assert!(matches!(parse_params(path, other), Err(ParamsFileError::UnknownModel { .. })));
    }

    #[test]
    fn reads_the_micro_slip_kind_and_checks_its_elements() {
        let path = Path::new("slip.json");
        let stiffness: Vec<String> = (0..SLIP_ELEMENTS).map(|i| format!("{}", 100 * i)).collect();
        let text = format!(
            r#"{{"model": "micro-slip", "params": {{"c1": 9000, "c2": 0, "c3": 0, "stiffness": [{}], "slip_min": 1e-6, "slip_max": 1e-3}}}}"#,
            stiffness.join(",")
        );
        let GearModel::MicroSlip(params) = parse_model(path, &text).unwrap() else { panic!("not micro-slip") };
        assert_eq!(params.stiffness[3], 300.0);
        let err = parse_params(path, &text).unwrap_err().to_string();
        assert!(err.contains("takes the \"genetic-hysteresis\" model"), "{err}");
        let short = text.replace("[0,", "[");
        assert!(matches!(parse_model(path, &short), Err(ParamsFileError::ElementCount { found: 15, .. })));
        let negative = text.replace("[0,", "[-1,");
        assert!(matches!(parse_model(path, &negative), Err(ParamsFileError::Invalid { .. })));
    }
}
