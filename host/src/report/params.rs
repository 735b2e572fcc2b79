//! Parameter files: model-core's [`GearModel`] in its serde form, `{"model": kind,
//! "model_version": 2, "params": {…}}` (what `swg-host fit --out` writes, with more fields that
//! are ignored here):
//!
//! - `params` holds `zero` (θ0, rad), `spring` ({c1, c2, c3, knots: [{x, stiffness}…], range:
//!   [lo, hi]}) and the kind's own: `alpha`, `beta`, `omega` (`"model": "genetic-hysteresis"`),
//!   `elements`: [{slip, stiffness}…] (`"model": "micro-slip"`).
//! - Files of model version 1 (`model_version` 1, or none) still load, upgraded to the same torque
//!   (model-core's `legacy`): `params` {c1, c2, c3, alpha, beta, omega}, or for the micro-slip kind
//!   {c1, c2, c3, stiffness: [16 values], slip_min, slip_max}; no `model` at all (files from before
//!   the micro-slip kind) is the genetic kind.
use model_core::legacy::GearModelV1;
use model_core::{GearModel, Kind, Params, MODEL_VERSION};
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
    #[error(
        "{path}: this command takes the {:?} model on the paper's spring, as `swg-host fit --model genetic-loop` \
         writes it; the file holds {found:?}",
        Kind::Genetic.name()
    )]
    WrongModel { path: PathBuf, found: &'static str },
    #[error(
        "{path}: this command takes the {:?} model on the paper's spring (c1·θ + c2·θ³ + c3·θ⁵ about θ = 0); the \
         file holds it {how}, as `swg-host fit` writes it: run without the file (the baseline is then fitted), or \
         give the file of `swg-host fit --model genetic-loop`",
        Kind::Genetic.name()
    )]
    NotThePapersSpring { path: PathBuf, how: String },
    #[error("{path}: {source}")]
    Invalid { path: PathBuf, source: model_core::Error },
    #[error(
        "{path}: model_version {found} is not one this tool reads (1 to {MODEL_VERSION}): a newer swg-host wrote it"
    )]
    UnknownVersion { path: PathBuf, found: u16 },
    #[error(
        "{path}: a `swg-host diagnose --json` report, not a parameter file: its `final.form_model`, where it has \
         one, is a parameter file of the form it names (save that object alone), or `swg-host fit --out` writes one"
    )]
    DiagnoseReport { path: PathBuf },
}

/// The kinds' names in files, quoted, for an error: "a", "b" or "c".
fn known_kinds() -> String {
    let names = Kind::ALL.map(|kind| format!("{:?}", kind.name()));
    match names.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    }
}

#[derive(serde::Deserialize)]
struct Header {
    model: Option<String>,
    model_version: Option<u16>,
    /// A `diagnose --json` report has these, a parameter file neither.
    findings: Option<serde::de::IgnoredAny>,
    criteria: Option<serde::de::IgnoredAny>,
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
    if model.kind() != Kind::Genetic {
        return Err(ParamsFileError::WrongModel { path: path.to_owned(), found: model.kind().name() });
    }
    model.paper_params().ok_or_else(|| {
        let knots = model.spring.knots().len();
        let spring = (knots > 0).then(|| format!("on a free-form spring of {knots} knots"));
        let zero = (model.zero != 0.0).then(|| format!("about θ0 = {:.4} mrad", 1e3 * model.zero));
        let how = spring.into_iter().chain(zero).collect::<Vec<_>>().join(" and ");
        ParamsFileError::NotThePapersSpring { path: path.to_owned(), how }
    })
}

/// A model as a parameter file holds it and nothing more, `{"model": kind, "model_version": 2,
/// "params": {…}}`: what [`parse_model`] reads back (`diagnose` writes the form it names so).
#[derive(Clone, Debug, serde::Serialize)]
pub struct ModelFile {
    pub model: &'static str,
    pub model_version: u16,
    #[serde(serialize_with = "GearModel::serialize_params")]
    pub params: GearModel<f64>,
}

impl ModelFile {
    pub fn of(model: GearModel<f64>) -> Self {
        ModelFile { model: model.kind().name(), model_version: MODEL_VERSION, params: model }
    }
}

/// [`read_model`] of a text already read.
pub fn parse_model(path: &Path, text: &str) -> Result<GearModel<f64>, ParamsFileError> {
    let syntax = |e: serde_json::Error| ParamsFileError::Syntax {
        path: path.to_owned(),
        line: e.line(),
        column: e.column(),
        message: e.to_string().split(" at line ").next().unwrap_or_default().to_owned(),
    };
    let invalid = |source| ParamsFileError::Invalid { path: path.to_owned(), source };
    // A recording or a table given for the parameters: say what was expected, not serde's
    // "expected value".
    let body = text.trim_start_matches('\u{feff}');
    let start = body.len() - body.trim_start().len();
    if !body[start..].starts_with('{') {
        let before = &body[..start];
        let first: String = body[start..].lines().next().unwrap_or_default().chars().take(40).collect();
        let found = if first.is_empty() { "nothing".to_owned() } else { format!("{first:?}") };
        return Err(ParamsFileError::Syntax {
            path: path.to_owned(),
            line: before.matches('\n').count() + 1,
            column: before.rsplit('\n').next().unwrap_or_default().chars().count() + 1,
            message: format!(
                "expected a parameter file, a JSON object as `swg-host fit --out` writes it; found {found}"
            ),
        });
    }
    let header: Header = serde_json::from_str(text).map_err(syntax)?;
    if header.findings.is_some() && header.criteria.is_some() {
        return Err(ParamsFileError::DiagnoseReport { path: path.to_owned() });
    }
    // A file without model_version is of version 1, unless it names a kind version 1 did not
    // have: then it can only be of this one (and its errors are this version's).
    let kind_of_version_1 =
        header.model.as_deref().is_none_or(|name| [Kind::Genetic, Kind::MicroSlip].iter().any(|k| k.name() == name));
    let version_1 = header.model_version.map_or(kind_of_version_1, |version| version == 1);
    let model = match header.model.as_deref() {
        None => GearModel::paper(serde_json::from_str::<UnnamedFile>(text).map_err(syntax)?.params),
        Some(name) if !Kind::ALL.iter().any(|kind| kind.name() == name) => {
            return Err(ParamsFileError::UnknownModel { path: path.to_owned(), found: name.to_owned() })
        }
        Some(_) if version_1 => {
            serde_json::from_str::<GearModelV1<f64>>(text).map_err(syntax)?.upgrade().map_err(invalid)?
        }
        Some(_) if header.model_version.unwrap_or(MODEL_VERSION) == MODEL_VERSION => {
            serde_json::from_str::<GearModel<f64>>(text).map_err(syntax)?
        }
        Some(_) => {
            return Err(ParamsFileError::UnknownVersion {
                path: path.to_owned(),
                found: header.model_version.unwrap_or(0),
            })
        }
    };
    model.validate().map_err(invalid)?;
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kind that model version 1 did not have, in a file without model_version, is read as
    /// this version: a missing `params` is said so (it was "unknown variant `bouc-wen`").
    #[test]
    fn a_file_without_version_naming_a_newer_kind_is_read_as_this_version() {
        let err = parse_model(Path::new("p.json"), r#"{"model": "bouc-wen"}"#).unwrap_err().to_string();
        assert!(err.contains("missing field `params`"), "{err}");
    }

    /// A recording given for the parameters says what was expected, where (it was serde's
    /// "expected value").
    #[test]
    fn a_recording_or_nothing_given_for_the_parameters_says_a_json_file_was_expected() {
        for (text, at, found) in [
            ("# swg-recording v1\ntime_s,theta_in_rad", "r.csv:1:1:", "found \"# swg-recording v1\""),
            ("\n  [1, 2]", "r.csv:2:3:", "found \"[1, 2]\""),
            ("", "r.csv:1:1:", "found nothing"),
        ] {
            let err = parse_model(Path::new("r.csv"), text).unwrap_err().to_string();
            assert!(err.starts_with(at) && err.contains("expected a parameter file") && err.ends_with(found), "{err}");
        }
    }

    #[test]
    fn reads_params_and_points_at_errors() {
        let path = Path::new("p.json");
        let ok = r#"{"model": "genetic-hysteresis", "params": {"c1": 1, "c2": 2, "c3": 3, "alpha": 4, "beta": 5, "omega": 6}}"#;
        assert_eq!(parse_params(path, ok).unwrap().omega, 6.0);
        let missing = "{\"params\": {\"c1\": 1,\n \"c2\": 2}}";
        let err = parse_params(path, missing).unwrap_err().to_string();
        assert!(err.starts_with("p.json:2:") && err.contains("missing field `c3`"), "{err}");
        let zero = r#"{"params": {"c1": 1, "c2": 2, "c3": 3, "alpha": 4, "beta": 5, "omega": 0}}"#;
        let err = parse_params(path, zero).unwrap_err().to_string();
        assert!(err.contains("parameter omega is out of range: it must not be zero"), "{err}");
        let other = r#"{"model": "dahl", "params": {"c1": 1, "c2": 2, "c3": 3, "alpha": 4, "beta": 5, "omega": 1}}"#;
        let err = parse_params(path, other).unwrap_err();
        assert!(matches!(err, ParamsFileError::UnknownModel { .. }), "{err}");
        assert!(
            err.to_string().ends_with("(\"genetic-hysteresis\", \"micro-slip\", \"bouc-wen\" or \"preisach\")"),
            "{err}"
        );
    }

    #[test]
    fn reads_the_micro_slip_kind_and_checks_its_elements() {
        let path = Path::new("slip.json");
        let stiffness: Vec<String> = (0..model_core::SLIP_ELEMENTS).map(|i| format!("{}", 100 * i)).collect();
        let text = format!(
            r#"{{"model": "micro-slip", "params": {{"c1": 9000, "c2": 0, "c3": 0, "stiffness": [{}], "slip_min": 1e-6, "slip_max": 1e-3}}}}"#,
            stiffness.join(",")
        );
        let model = parse_model(path, &text).unwrap();
        assert_eq!(model.kind(), Kind::MicroSlip);
        assert_eq!(model.slip_elements()[3].stiffness, 300.0);
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
