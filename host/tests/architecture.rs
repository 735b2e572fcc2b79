//! The import rules of ARCHITECTURE.md, checked on the source: each folder of `host/src` uses
//! only the folders listed for it. Adding `use crate::report::…` to `fit/` fails this test.
use std::collections::BTreeSet;
use std::path::Path;

/// Each top-level module of the library and the modules it may use (`crate::…`). Tests inside
/// a module may also use what the module's own tests need, listed under `tests`.
const ALLOWED: &[(&str, &[&str], &[&str])] = &[
    ("numeric", &[], &[]),
    ("input", &[], &[]),
    ("prepare", &["gear", "input", "numeric"], &[]),
    ("fit", &["gear", "prepare", "input", "numeric"], &[]),
    ("diagnose", &["fit", "gear", "prepare", "input", "numeric"], &[]),
    ("gear", &[], &[]),
    ("predict", &["gear", "prepare", "input"], &[]),
    ("simulate", &["input", "diagnose::effects"], &[]),
    ("report", &["diagnose", "fit", "gear", "predict", "prepare", "input", "numeric"], &[]),
    ("link", &["gear", "input", "prepare"], &["simulate"]),
    ("hil", &["gear", "input", "simulate", "link", "report"], &["fit"]),
    ("record", &["hil", "input", "link"], &["simulate"]),
];

/// The `crate::x` or `crate::diagnose::effects` paths a file names, outside and inside its
/// `#[cfg(test)]` module (everything after the first `#[cfg(test)]` counts as test code).
fn crate_paths(text: &str) -> (BTreeSet<String>, BTreeSet<String>) {
    let (code, tests) = text.split_once("#[cfg(test)]").unwrap_or((text, ""));
    let paths = |part: &str| {
        part.match_indices("crate::")
            .map(|(at, _)| {
                let rest = &part[at + "crate::".len()..];
                let path: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':').collect();
                path.trim_end_matches(':').to_string()
            })
            .collect::<BTreeSet<_>>()
    };
    (paths(code), paths(tests))
}

fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn each_folder_imports_only_what_architecture_md_allows() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut violations = Vec::new();
    let mut checked = 0;
    for file in &files {
        let relative = file.strip_prefix(&src).unwrap();
        let module = relative.iter().next().unwrap().to_string_lossy().trim_end_matches(".rs").to_string();
        let Some((_, allowed, test_only)) = ALLOWED.iter().find(|(name, _, _)| *name == module) else {
            continue;
        };
        checked += 1;
        let (code, tests) = crate_paths(&std::fs::read_to_string(file).unwrap());
        let permitted = |path: &str, extra: &[&str]| {
            path == module
                || path.starts_with(&format!("{module}::"))
                || allowed.iter().chain(extra).any(|a| path == *a || path.starts_with(&format!("{a}::")))
        };
        for path in code.iter().filter(|p| !permitted(p, &[])) {
            violations.push(format!("{}: crate::{path}", relative.display()));
        }
        for path in tests.iter().filter(|p| !permitted(p, test_only)) {
            violations.push(format!("{} (tests): crate::{path}", relative.display()));
        }
    }
    assert!(checked >= 20, "only {checked} files checked: has host/src moved?");
    assert!(violations.is_empty(), "imports ARCHITECTURE.md does not allow:\n{}", violations.join("\n"));
}

#[test]
fn the_checker_sees_a_forbidden_import() {
    let (code, tests) =
        crate_paths("use crate::report::fit::FitReport;\n#[cfg(test)]\nmod t { use crate::simulate::x; }");
    assert!(code.contains("report::fit::FitReport"));
    assert!(tests.contains("simulate::x"));
}
