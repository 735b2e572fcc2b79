//! Issue 10, host side: every output at the end or none, no output over an input, plausible
//! and finite figures only, one CSV path for every table, each cause of an error printed once.
mod common;

use common::{json, ok, repo};
use std::path::{Path, PathBuf};
use std::process::Output;

/// Runs `swg-host`; `SWG_HOST_BIN` names another build (to show these tests fail on the one
/// before the fixes).
fn swg_host(args: &[&str]) -> Output {
    let bin = std::env::var("SWG_HOST_BIN").unwrap_or_else(|_| env!("CARGO_BIN_EXE_swg-host").to_owned());
    std::process::Command::new(bin).args(args).output().expect("swg-host runs")
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

fn failed(output: Output) -> String {
    assert!(!output.status.success(), "expected a failure; stdout: {}", String::from_utf8_lossy(&output.stdout));
    stderr(&output)
}

/// A small recording (2 cycles of the seed model, noisy), as `simulate` writes it.
fn recording(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(name);
    ok(swg_host(&["simulate", "--out", path.to_str().unwrap(), "--cycles", "2", "--rate", "500"]));
    path
}

/// `recording` with each data row's torque (the last column of `simulate`'s rows) replaced.
fn with_torque(source: &Path, path: &Path, torque: impl Fn(usize, &str) -> String) {
    let text = std::fs::read_to_string(source).unwrap();
    let mut data_row = 0;
    let mut header_seen = false;
    let lines: Vec<String> = text
        .lines()
        .map(|line| {
            if line.starts_with('#') || !header_seen {
                header_seen |= !line.starts_with('#');
                return line.to_owned();
            }
            let mut fields: Vec<&str> = line.split(',').collect();
            let value = torque(data_row, fields[3]);
            data_row += 1;
            fields[3] = &value;
            fields.join(",")
        })
        .collect();
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

#[test]
fn a_failed_command_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("X.json");
    std::fs::write(&out, "before").unwrap();
    let err = failed(swg_host(&[
        "fit",
        &repo("data/seed/lht-20-50.csv"),
        "--out",
        out.to_str().unwrap(),
        "--plot",
        "/no/such/dir/a.svg",
    ]));
    assert!(err.contains("/no/such/dir") && err.contains("does not exist"), "{err}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "before", "X.json replaced by a failed fit");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "a temporary file was left behind");

    // And the success path writes both.
    let plot = dir.path().join("a.svg");
    ok(swg_host(&[
        "fit",
        &repo("data/seed/lht-20-50.csv"),
        "--out",
        out.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
    ]));
    assert!(std::fs::read_to_string(&out).unwrap().contains("\"params\""));
    assert!(std::fs::read_to_string(&plot).unwrap().contains("<svg"));
}

#[test]
fn an_output_that_names_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path(), "rec.csv");
    let original = std::fs::read(&rec).unwrap();
    let dotted = dir.path().join(".").join("rec.csv");
    let err = failed(swg_host(&["fit", rec.to_str().unwrap(), "--out", dotted.to_str().unwrap()]));
    assert!(err.contains("that is an input of this command"), "{err}");
    let err = failed(swg_host(&[
        "fit",
        rec.to_str().unwrap(),
        "--plot",
        rec.with_extension("svg").to_str().unwrap(),
        "--out",
        rec.with_extension("svg").to_str().unwrap(),
    ]));
    assert!(err.contains("named twice"), "{err}");
    // simulate --motion FILE.csv --out FILE.csv
    let motion = dir.path().join("motion.csv");
    std::fs::write(&motion, "time_s,deflection_rad\n0,0\n0.5,1e-3\n1,0\n1.5,-1e-3\n2,0\n").unwrap();
    let err = failed(swg_host(&["simulate", "--motion", motion.to_str().unwrap(), "--out", motion.to_str().unwrap()]));
    assert!(err.contains("that is an input"), "{err}");
    assert!(std::fs::read_to_string(&motion).unwrap().starts_with("time_s"));
    // diagnose --plot DIR never replaces an input inside DIR
    let plots = dir.path().join("plots");
    std::fs::create_dir(&plots).unwrap();
    let inside = plots.join("loop.svg");
    std::fs::copy(&rec, &inside).unwrap();
    let err = failed(swg_host(&["diagnose", inside.to_str().unwrap(), "--plot", plots.to_str().unwrap()]));
    assert!(err.contains("that is an input"), "{err}");
    assert_eq!(std::fs::read(&inside).unwrap(), original);
    assert_eq!(std::fs::read(&rec).unwrap(), original, "the recording was replaced");
}

#[test]
fn absurd_values_are_refused_where_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path(), "rec.csv");
    let huge = dir.path().join("huge.csv");
    with_torque(&rec, &huge, |row, t| if row == 3 { "1e200".into() } else { t.into() });
    let header_line = std::fs::read_to_string(&rec).unwrap().lines().position(|l| l.starts_with("time_s")).unwrap() + 1;
    let line = header_line + 4;
    for command in ["fit", "diagnose"] {
        let err = failed(swg_host(&[command, huge.to_str().unwrap()]));
        assert!(
            err.contains(&format!("huge.csv:{line}: column 4 (torque_nm): torque of 1e200 N·m is beyond any gear")),
            "{err}"
        );
    }
    let bent = dir.path().join("bent.csv");
    std::fs::write(&bent, "branch,torque_nm,deflection_rad\nforward_loading,1,0.001\nforward_loading,2,3.5\n").unwrap();
    let err = failed(swg_host(&["fit", bent.to_str().unwrap()]));
    assert!(err.contains("bent.csv:3: column 3 (deflection_rad): deflection of 3.5e0 rad is beyond"), "{err}");
}

/// Every number in `value`, with no `null` anywhere.
fn assert_finite_json(value: &serde_json::Value, context: &str) {
    match value {
        serde_json::Value::Null => panic!("null in the JSON of {context}"),
        serde_json::Value::Number(n) => assert!(n.as_f64().unwrap().is_finite(), "{context}"),
        serde_json::Value::Array(items) => items.iter().for_each(|v| assert_finite_json(v, context)),
        serde_json::Value::Object(fields) => fields.values().for_each(|v| assert_finite_json(v, context)),
        _ => {}
    }
}

#[test]
fn no_nan_or_null_reaches_stdout_or_json() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path(), "rec.csv");
    let zero = dir.path().join("zero.csv");
    with_torque(&rec, &zero, |_, _| "0".into());
    let constant = dir.path().join("constant.csv");
    with_torque(&rec, &constant, |_, _| "5".into());
    // Noise-free: the model fits it exactly, the evidence tests have no scale.
    let clean = dir.path().join("clean.csv");
    ok(swg_host(&[
        "simulate",
        "--out",
        clean.to_str().unwrap(),
        "--cycles",
        "2",
        "--rate",
        "500",
        "--torque-noise",
        "0",
    ]));
    let params = dir.path().join("params.json");
    ok(swg_host(&["fit", rec.to_str().unwrap(), "--out", params.to_str().unwrap(), "--model", "genetic"]));
    let seed = repo("data/seed/lht-20-50.csv");

    let runs: Vec<Vec<&str>> = vec![
        vec!["fit", seed.as_str()],
        vec!["fit", rec.to_str().unwrap()],
        vec!["fit", clean.to_str().unwrap()],
        vec!["fit", zero.to_str().unwrap()],
        vec!["fit", constant.to_str().unwrap()],
        vec!["diagnose", seed.as_str()],
        vec!["diagnose", rec.to_str().unwrap()],
        vec!["diagnose", clean.to_str().unwrap()],
        vec!["diagnose", zero.to_str().unwrap()],
        vec!["diagnose", constant.to_str().unwrap()],
        vec!["predict", params.to_str().unwrap(), rec.to_str().unwrap()],
        vec!["predict", params.to_str().unwrap(), clean.to_str().unwrap()],
        vec!["predict", params.to_str().unwrap(), zero.to_str().unwrap()],
    ];
    for run in runs {
        for json_flag in [false, true] {
            let mut args = run.clone();
            if json_flag {
                args.push("--json");
            }
            let output = swg_host(&args);
            let text = format!("{}{}", String::from_utf8_lossy(&output.stdout), stderr(&output));
            let words: Vec<&str> = text.split(|c: char| !c.is_alphanumeric()).collect();
            for bad in ["NaN", "nan", "inf", "null"] {
                assert!(!words.contains(&bad), "`{}` printed {bad}:\n{text}", args.join(" "));
            }
            if output.status.success() && json_flag {
                assert_finite_json(&json(&output), &args.join(" "));
            }
            if !output.status.success() {
                let err = stderr(&output);
                assert!(err.starts_with("error: ") && err.lines().count() == 1, "{err}");
            }
        }
    }
    let err = failed(swg_host(&["diagnose", constant.to_str().unwrap()]));
    assert!(err.contains("the torque is 5 N·m on every sample"), "{err}");
    let err = failed(swg_host(&["fit", zero.to_str().unwrap()]));
    assert!(err.contains("the torque is 0 N·m on every sample"), "{err}");
}

#[test]
fn every_table_takes_the_same_path() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording(dir.path(), "rec.csv");
    let text = std::fs::read_to_string(&rec).unwrap();
    let fitted =
        |path: &Path| json(&swg_host(&["fit", path.to_str().unwrap(), "--json", "--model", "genetic"]))["rss"].clone();
    let reference = fitted(&rec);

    let variants: [(&str, String); 4] = [
        ("bom.csv", format!("\u{feff}{text}")),
        (
            "indented.csv",
            text.lines()
                .map(|l| if l.starts_with('#') { format!("  {l}") } else { l.to_owned() })
                .collect::<Vec<_>>()
                .join("\n"),
        ),
        ("cr.csv", text.replace('\n', "\r")),
        ("crlf.csv", text.replace('\n', "\r\n")),
    ];
    for (name, contents) in variants {
        let path = dir.path().join(name);
        std::fs::write(&path, contents).unwrap();
        assert_eq!(fitted(&path), reference, "{name}");
    }
    let table = std::fs::read_to_string(repo("data/seed/lht-20-50.csv")).unwrap();
    let bom_table = dir.path().join("bom-table.csv");
    std::fs::write(&bom_table, format!("\u{feff}{}", table.replace('\n', "\r"))).unwrap();
    ok(swg_host(&["fit", bom_table.to_str().unwrap()]));

    // Two `# ratio:` lines: an error naming both.
    let twice = dir.path().join("twice.csv");
    std::fs::write(&twice, text.replacen("# ratio: 50\n", "# ratio: 50\n# ratio: 100\n", 1)).unwrap();
    let err = failed(swg_host(&["fit", twice.to_str().unwrap()]));
    assert!(err.contains("twice.csv:3: metadata key `ratio` appears twice, on lines 2 and 3"), "{err}");

    // A bad cell is named at the same line whatever the line endings.
    let bad = text.replacen("\n0.004,", "\n0.004x,", 1);
    let bad_line = bad.lines().position(|l| l.starts_with("0.004x")).unwrap() + 1;
    for (name, contents) in
        [("bad.csv", bad.clone()), ("bad-cr.csv", bad.replace('\n', "\r")), ("bad-bom.csv", format!("\u{feff}{bad}"))]
    {
        let path = dir.path().join(name);
        std::fs::write(&path, contents).unwrap();
        let err = failed(swg_host(&["fit", path.to_str().unwrap()]));
        assert!(err.contains(&format!("{name}:{bad_line}: column 1 (time_s): expected a number")), "{err}");
    }

    // simulate --motion FILE.csv reads through the same path.
    let motion = dir.path().join("motion.csv");
    std::fs::write(
        &motion,
        "\u{feff}  # a motion\r\ntime_s,deflection_rad\r\n0,0\r\n0.5,1e-3\r\n1,0\r\n1.5,-1e-3\r\n2,0\r\n",
    )
    .unwrap();
    let out = dir.path().join("from-motion.csv");
    ok(swg_host(&["simulate", "--motion", motion.to_str().unwrap(), "--out", out.to_str().unwrap()]));
}

#[test]
fn each_cause_is_printed_once() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.csv");
    let cases: Vec<Vec<String>> = vec![
        vec!["fit".into(), missing.display().to_string()],
        vec!["diagnose".into(), missing.display().to_string()],
        vec!["predict".into(), dir.path().join("p.json").display().to_string(), missing.display().to_string()],
        vec![
            "fit".into(),
            repo("data/seed/lht-20-50.csv"),
            "--compare".into(),
            dir.path().join("p.json").display().to_string(),
        ],
        vec![
            "simulate".into(),
            "--params".into(),
            dir.path().join("p.json").display().to_string(),
            "--out".into(),
            dir.path().join("o.csv").display().to_string(),
        ],
    ];
    for args in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let err = failed(swg_host(&args));
        assert_eq!(err.matches("(os error 2)").count(), 1, "`{}`: {err}", args.join(" "));
    }
}
