//! Helpers shared by the integration tests that run the `swg-host` binary.
// Each test binary compiles this module and uses its own subset of it.
#![allow(dead_code)]
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `swg-host` binary built for these tests.
pub fn swg_host(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_swg-host")).args(args).output().expect("swg-host runs")
}

/// Runs `swg-host` and echoes the command and what it printed (shown with `--nocapture`).
pub fn swg_host_echoed(args: &[&str]) -> Output {
    let output = swg_host(args);
    println!(
        "$ swg-host {}\n{}{}",
        args.join(" "),
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// A path inside the repository.
pub fn repo(path: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path).display().to_string()
}

/// The stdout of a successful run.
pub fn ok(output: Output) -> String {
    assert!(output.status.success(), "stderr: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).expect("UTF-8 on stdout")
}

/// The JSON on stdout of a successful run.
pub fn json(output: &Output) -> serde_json::Value {
    assert!(output.status.success(), "stderr: {}", String::from_utf8_lossy(&output.stderr));
    serde_json::from_slice(&output.stdout).expect("valid JSON on stdout")
}

/// A parameter file (the current model version) for the paper's gear of `params` in `dir`.
pub fn write_params_file(dir: &Path, params: &model_core::Params<f64>) -> PathBuf {
    let path = dir.join("params.json");
    // The model serializes as {"model": kind, "params": {zero, spring, …}}: the file is that
    // with the model version beside it.
    let mut json = serde_json::to_value(model_core::GearModel::paper(*params)).expect("the model as JSON");
    json["model_version"] = model_core::MODEL_VERSION.into();
    std::fs::write(&path, json.to_string()).expect("params file written");
    path
}

/// The paper's six parameters of a report's or file's `params` (a genetic gear), by name: c1..c3
/// live in its spring.
pub fn paper_params(params: &serde_json::Value) -> [(&'static str, f64); 6] {
    model_core::ParamName::GENETIC.map(|name| {
        let name = name.as_str();
        let value = params[name].as_f64().or_else(|| params["spring"][name].as_f64());
        (name, value.unwrap_or_else(|| panic!("params has no number {name}: {params}")))
    })
}
