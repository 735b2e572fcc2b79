//! Parameter files: any JSON object with a `params` field {c1, c2, c3, alpha, beta, omega},
//! which is what `swg-host fit --out` writes.
use model_core::{Params, MODEL_NAME};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum ParamsFileError {
    #[error("{path}: cannot read: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{path}:{line}:{column}: {message}")]
    Syntax { path: PathBuf, line: usize, column: usize, message: String },
    #[error("{path}: model {found:?} is not {MODEL_NAME:?}")]
    WrongModel { path: PathBuf, found: String },
    #[error("{path}: {source}")]
    Invalid { path: PathBuf, source: model_core::Error },
}

#[derive(serde::Deserialize)]
struct ParamsFile {
    model: Option<String>,
    params: Params<f64>,
}

/// Reads and validates a parameter file.
pub fn read_params(path: &Path) -> Result<Params<f64>, ParamsFileError> {
    let text =
        std::fs::read_to_string(path).map_err(|source| ParamsFileError::Read { path: path.to_owned(), source })?;
    parse_params(path, &text)
}

pub fn parse_params(path: &Path, text: &str) -> Result<Params<f64>, ParamsFileError> {
    let file: ParamsFile = serde_json::from_str(text).map_err(|e| ParamsFileError::Syntax {
        path: path.to_owned(),
        line: e.line(),
        column: e.column(),
        message: e.to_string().split(" at line ").next().unwrap_or_default().to_owned(),
    })?;
    if let Some(model) = file.model.filter(|m| m != MODEL_NAME) {
        return Err(ParamsFileError::WrongModel { path: path.to_owned(), found: model });
    }
    file.params.validate().map_err(|source| ParamsFileError::Invalid { path: path.to_owned(), source })?;
    Ok(file.params)
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
        assert!(matches!(parse_params(path, other), Err(ParamsFileError::WrongModel { .. })));
    }
}
