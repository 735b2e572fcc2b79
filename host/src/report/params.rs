//! Parameter files: model-core's [`GearModel`] in its serde form, `{"model": kind, "params":
//! {…}}` (what `swg-host fit --out` writes, with more fields that are ignored here):
//!
//! - `"model": "genetic-hysteresis"`: `params` {c1, c2, c3, alpha, beta, omega};
//! - `"model": "micro-slip"`: `params` {c1, c2, c3, stiffness: [16 values, N·m/rad], slip_min,
//!   slip_max (rad)};
//! - no `model` (files from before the micro-slip kind): the genetic kind's `params`.
use model_core::{GearModel, Kind, Params};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ParamsFileError {
    #[error("{path}: cannot read: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{path}:{line}:{column}: {message}")]
    Syntax { path: PathBuf, line: usize, column: usize, message: String },
    #[error("{path}: model {found:?} is not one this tool knows ({})", known_kinds())]
    UnknownModel { path: PathBuf, found: String },
    #[error("{path}: this command takes the {:?} model; the file holds {found:?}", Kind::Genetic.name())]
    WrongModel { path: PathBuf, found: &'static str },
    #[error("{path}: {source}")]
    Invalid { path: PathBuf, source: model_core::Error },
}

/// The kinds' names in files, quoted, for an error.
fn known_kinds() -> String {
    Kind::ALL.map(|kind| format!("{:?}", kind.name())).join(" or ")
}

#[derive(serde::Deserialize)]
struct Header {
    model: Option<String>,
}

/// A params file from before the kinds had names: the genetic model's parameters.
#[derive(serde::Deserialize)]
struct UnnamedFile {
    params: Params<f64>,
}

/// Reads and validates a parameter file of any kind.
pub fn read_model(path: &Path) -> Result<GearModel<f64>, ParamsFileError> {
    let text =
        std::fs::read_to_string(path).map_err(|source| ParamsFileError::Read { path: path.to_owned(), source })?;
    parse_model(path, &text)
}

/// Reads a parameter file that must hold the genetic model.
pub fn read_params(path: &Path) -> Result<Params<f64>, ParamsFileError> {
    let text =
        std::fs::read_to_string(path).map_err(|source| ParamsFileError::Read { path: path.to_owned(), source })?;
    parse_params(path, &text)
}

/// [`read_params`] of a text already read.
pub fn parse_params(path: &Path, text: &str) -> Result<Params<f64>, ParamsFileError> {
    let model = parse_model(path, text)?;
    model.as_genetic().copied().ok_or(ParamsFileError::WrongModel { path: path.to_owned(), found: model.kind().name() })
}

/// [`read_model`] of a text already read.
pub fn parse_model(path: &Path, text: &str) -> Result<GearModel<f64>, ParamsFileError> {
    let syntax = |e: serde_json::Error| ParamsFileError::Syntax {
        path: path.to_owned(),
        line: e.line(),
        column: e.column(),
        message: e.to_string().split(" at line ").next().unwrap_or_default().to_owned(),
    };
    let header: Header = serde_json::from_str(text).map_err(syntax)?;
    let model = match header.model.as_deref() {
        None => GearModel::Genetic(serde_json::from_str::<UnnamedFile>(text).map_err(syntax)?.params),
        Some(name) if Kind::ALL.iter().any(|kind| kind.name() == name) => {
            serde_json::from_str::<GearModel<f64>>(text).map_err(syntax)?
        }
        Some(name) => return Err(ParamsFileError::UnknownModel { path: path.to_owned(), found: name.to_owned() }),
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
        let err = parse_params(path, other).unwrap_err();
        assert!(matches!(err, ParamsFileError::UnknownModel { .. }), "{err}");
        assert!(err.to_string().ends_with("(\"genetic-hysteresis\" or \"micro-slip\")"), "{err}");
    }

    #[test]
    fn reads_the_micro_slip_kind_and_checks_its_elements() {
        let path = Path::new("slip.json");
        let stiffness: Vec<String> = (0..model_core::SLIP_ELEMENTS).map(|i| format!("{}", 100 * i)).collect();
        let text = format!(
            r#"{{"model": "micro-slip", "params": {{"c1": 9000, "c2": 0, "c3": 0, "stiffness": [{}], "slip_min": 1e-6, "slip_max": 1e-3}}}}"#,
            stiffness.join(",")
        );
        let GearModel::MicroSlip(params) = parse_model(path, &text).unwrap() else { panic!("not micro-slip") };
        assert_eq!(params.stiffness[3], 300.0);
        let err = parse_params(path, &text).unwrap_err().to_string();
        assert!(err.contains("takes the \"genetic-hysteresis\" model"), "{err}");
        let short = text.replace("[0,", "[");
        let err = parse_model(path, &short).unwrap_err().to_string();
        assert!(
            err.starts_with("slip.json:1:") && err.contains("invalid length 15, expected a list of 16 numbers"),
            "{err}"
        );
        let negative = text.replace("[0,", "[-1,");
        assert!(matches!(parse_model(path, &negative), Err(ParamsFileError::Invalid { .. })));
    }
}
