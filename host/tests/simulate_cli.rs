//! `swg-host simulate --motion … --physics …` end to end: today's sine unchanged, each motion
//! doing what it promises, the truth physics' loops, and errors that write nothing.
mod common;

use common::{ok, repo, swg_host};
use std::path::Path;
use swg_host::input::{read_recording, Recording};

const A: f64 = 1.168e-3;

/// FNV-1a, 64 bits.
fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3))
}

fn simulate(dir: &Path, name: &str, args: &[&str]) -> Recording {
    let out = dir.join(name);
    ok(swg_host(&[&["simulate", "--out", out.to_str().unwrap()], args].concat()));
    read_recording(&out, None).unwrap()
}

/// A failing command: its stderr, after checking that `out` was not written.
fn fails(out: &Path, args: &[&str]) -> String {
    let output = swg_host(&[&["simulate", "--out", out.to_str().unwrap()], args].concat());
    assert!(!output.status.success(), "{args:?} succeeded");
    assert!(!out.exists(), "{args:?} wrote {}", out.display());
    String::from_utf8(output.stderr).unwrap()
}

fn meta<'a>(rec: &'a Recording, key: &str) -> Option<&'a str> {
    rec.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

/// Turning points of the deflection (sign changes of its differences).
fn reversals(x: &[f64]) -> Vec<usize> {
    let d: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    (1..d.len()).filter(|&i| d[i] * d[i - 1] < 0.0).collect()
}

#[test]
fn sine_through_the_genetic_model_is_byte_for_byte_what_it_was() {
    // Hashes of the files `simulate` wrote before --motion and --physics existed (x86-64 Linux,
    // glibc's libm); with and without the new options' defaults spelled out.
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&[&str], u64); 2] = [
        (&["--cycles", "1", "--rate", "200"], 0x9cf9_b7be_49c5_7ee1),
        (
            &[
                "--frequency",
                "1,2.5",
                "--cycles",
                "2",
                "--rate",
                "300",
                "--input-speed",
                "3",
                "--input-bits",
                "16",
                "--output-bits",
                "19",
                "--temperature",
                "20",
                "--temperature-rise",
                "0.3",
                "--effect",
                "backlash=1e-4",
                "--effect",
                "coulomb_friction=0.2",
                "--effect",
                "viscous_damping=0.5",
                "--effect",
                "kinematic_error=2e-6",
                "--effect",
                "thermal_drift=0.01",
                "--effect",
                "torque_offset=-0.1",
                "--seed",
                "42",
                "--torque-noise",
                "0.2",
            ],
            0x68a9_487b_f671_46cd,
        ),
    ];
    for (args, hash) in cases {
        for explicit in [&[][..], &["--motion", "sine", "--physics", "genetic"][..]] {
            let out = dir.path().join("sine.csv");
            ok(swg_host(&[&["simulate", "--out", out.to_str().unwrap()], args, explicit].concat()));
            let text = std::fs::read_to_string(&out).unwrap();
            // The one line added since: the effects the recording was made with.
            let (effects, rest): (Vec<&str>, Vec<&str>) =
                text.split_inclusive('\n').partition(|line| line.starts_with("# effects: "));
            assert_eq!(fnv(rest.concat().as_bytes()), hash, "{args:?} {explicit:?}");
            let given: Vec<&str> = args.windows(2).filter(|w| w[0] == "--effect").map(|w| w[1]).collect();
            // NAME=VALUE as numbers: the file writes 1e-4 as 0.0001.
            let parsed = |list: Vec<&str>| -> Vec<(String, f64)> {
                list.iter()
                    .map(|e| e.split_once('=').map(|(n, v)| (n.to_owned(), v.parse().unwrap())).unwrap())
                    .collect()
            };
            match effects[..] {
                [] => assert!(given.is_empty()),
                [line] => {
                    let written = line.trim_start_matches("# effects: ").trim_end().split(' ').collect();
                    assert_eq!(parsed(written), parsed(given.clone()));
                }
                _ => panic!("{effects:?}"),
            }
        }
    }
}

#[test]
fn biased_oscillates_about_its_bias_and_hold_stays_at_its_load() {
    let dir = tempfile::tempdir().unwrap();
    let quiet = ["--torque-noise", "0", "--physics", "micro-slip"];
    let biased = simulate(dir.path(), "biased.csv", &[&quiet[..], &["--motion", "biased"]].concat());
    // One period (2 s at 0.5 Hz) of ramp from rest, then four cycles about 0.6·A.
    assert_eq!(biased.time.len(), 10_001);
    assert_eq!((biased.deflection[0], biased.torque[0]), (0.0, 0.0));
    let after = &biased.deflection[2000..10_000];
    let mean = after.iter().sum::<f64>() / after.len() as f64;
    assert!((mean - 0.6 * A).abs() < 1e-3 * A, "mean {mean}");
    assert_eq!(meta(&biased, "motion"), Some("biased"));
    assert_eq!(meta(&biased, "physics"), Some("micro-slip"));
    // The held load's torque is on one side, the oscillation a minor loop about it.
    assert!(biased.torque[2000..].iter().all(|&t| t > 5.0), "loaded throughout");

    let custom = simulate(dir.path(), "custom.csv", &[&quiet[..], &["--motion", "biased", "--bias", "-4e-4"]].concat());
    let mean = custom.deflection[2000..10_000].iter().sum::<f64>() / 8000.0;
    assert!((mean + 4e-4).abs() < 1e-3 * A, "mean {mean}");

    let hold = simulate(dir.path(), "hold.csv", &[&quiet[..], &["--motion", "hold", "--bias", "9e-4"]].concat());
    assert_eq!(hold.deflection[0], 0.0);
    assert!(hold.deflection[2000..].iter().all(|x| (x - 9e-4).abs() <= 0.02 * A * 1.000001));
    assert!(reversals(&hold.deflection[2000..]).len() >= 70, "the dither vibrates");
}

#[test]
fn nested_reverses_inside_the_big_swing_and_random_follows_its_seed() {
    let dir = tempfile::tempdir().unwrap();
    let nested = simulate(dir.path(), "nested.csv", &["--motion", "nested", "--physics", "bouc-wen"]);
    let turns = reversals(&nested.deflection);
    let inside = turns.iter().filter(|&&i| nested.deflection[i].abs() < 0.9 * A).count();
    assert!(turns.len() >= 4 * 18 && inside >= 4 * 14, "{} reversals, {inside} inside", turns.len());
    let peak = nested.deflection.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
    assert!((peak - A).abs() < 1e-9);

    let random = |seed: &str, name: &str| {
        let out = dir.path().join(name);
        ok(swg_host(&["simulate", "--out", out.to_str().unwrap(), "--motion", "random", "--seed", seed]));
        std::fs::read(out).unwrap()
    };
    let (a, again, b) = (random("3", "a.csv"), random("3", "again.csv"), random("4", "b.csv"));
    assert_eq!(a, again);
    assert_ne!(a, b);
    let rec = read_recording(&dir.path().join("b.csv"), None).unwrap();
    let peak = rec.deflection.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
    assert!((peak - A).abs() < 1e-9 && rec.deflection[0] == 0.0);
}

#[test]
fn a_motion_file_is_played_at_its_times() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("motion.csv");
    let (time, x) = ([0.0, 0.01, 0.03, 0.04, 0.1], [0.0, 2e-4, 9e-4, 1e-4, -5e-4]);
    let rows: Vec<String> = time.iter().zip(&x).map(|(t, x)| format!("{t},{x}")).collect();
    std::fs::write(&path, format!("# a bench's motion\ntime_s,deflection_rad\n{}\n", rows.join("\n"))).unwrap();
    for physics in ["genetic", "bouc-wen", "micro-slip", "catalogue"] {
        let rec = simulate(
            dir.path(),
            "played.csv",
            &["--motion", path.to_str().unwrap(), "--physics", physics, "--torque-noise", "0"],
        );
        assert_eq!(rec.time, time);
        assert_eq!(rec.deflection, x);
        assert!(rec.torque.iter().all(|t| t.is_finite()));
        assert_eq!(meta(&rec, "motion"), Some(format!("file {}", path.display()).as_str()));
        assert_eq!(meta(&rec, "amplitude_rad"), Some("0.0009"));
    }
}

#[test]
fn a_bad_motion_file_names_file_line_and_column_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.csv");
    let path = dir.path().join("bad.csv");
    let motion = path.to_str().unwrap();
    std::fs::write(&path, "time_s,deflection_rad\n0,0\n0.1,1e-4\n0.2,abc\n").unwrap();
    let stderr = fails(&out, &["--motion", motion]);
    assert!(stderr.contains(&format!("{motion}:4: column 2 (deflection_rad): expected a number")), "{stderr}");
    std::fs::write(&path, "time_s,deflection_rad\n0,0\n0.1,1e-4\n0.05,2e-4\n").unwrap();
    let stderr = fails(&out, &["--motion", motion]);
    assert!(stderr.contains(&format!("{motion}:4: column 1 (time_s): time must increase")), "{stderr}");
    std::fs::write(&path, "time_s,torque_nm\n0,0\n").unwrap();
    assert!(fails(&out, &["--motion", motion]).contains("missing column `deflection_rad`"));
    let stderr = fails(&out, &["--motion", dir.path().join("absent.csv").to_str().unwrap()]);
    assert!(stderr.contains("absent.csv: cannot read"), "{stderr}");
}

/// Samples a cycle at 0.5 Hz and `--rate 1200`.
const CYCLE: usize = 2400;

/// (∮T dθ over the last cycle, rising − falling torque at θ = 0 on it, peak torque), for a
/// sine of `CYCLE` samples a cycle (zero crossings at the cycle's 0 and CYCLE/2).
fn loop_figures(rec: &Recording) -> (f64, f64, f64) {
    let end = rec.time.len() - 1;
    let cycle = end - CYCLE..end;
    let work = cycle
        .clone()
        .map(|i| 0.5 * (rec.torque[i] + rec.torque[i + 1]) * (rec.deflection[i + 1] - rec.deflection[i]))
        .sum();
    let peak = rec.torque[cycle].iter().fold(0.0, |m: f64, t| m.max(t.abs()));
    (work, rec.torque[end - CYCLE] - rec.torque[end - CYCLE / 2], peak)
}

#[test]
fn the_truth_physics_loops_are_passive_and_a_few_percent_wide() {
    let dir = tempfile::tempdir().unwrap();
    for physics in ["bouc-wen", "micro-slip", "catalogue"] {
        let rec = simulate(dir.path(), "loop.csv", &["--physics", physics, "--torque-noise", "0", "--rate", "1200"]);
        assert_eq!(meta(&rec, "start"), Some("rest"), "{physics}");
        let (work, width, peak) = loop_figures(&rec);
        assert!(work > 0.0, "{physics}: ∮T dθ = {work}");
        assert!((25.0..32.0).contains(&peak), "{physics}: peak {peak}");
        assert!((0.02..0.05).contains(&(width / peak)), "{physics}: width {width} of {peak}");
        // Falling below rising at mid deflection, +A/2 (samples 1/12 and 5/12 into the cycle).
        let start = rec.time.len() - 1 - CYCLE;
        let (rising, falling) = (start + CYCLE / 12, start + 5 * CYCLE / 12);
        assert!((rec.deflection[rising] - rec.deflection[falling]).abs() < 1e-12);
        assert!(rec.torque[rising] > rec.torque[falling] + 0.01 * peak, "{physics}");
    }
}

#[test]
fn physics_parameter_files_override_the_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("slip.json");
    // Twice the slip stiffness: a wider loop.
    std::fs::write(&params, r#"{"slip_stiffness": 6000, "k1": 3000, "elements": 1000}"#).unwrap();
    let args = ["--physics", "micro-slip", "--torque-noise", "0", "--rate", "1200"];
    let default = loop_figures(&simulate(dir.path(), "a.csv", &args));
    let wider = loop_figures(&simulate(
        dir.path(),
        "b.csv",
        &[&args[..], &["--physics-params", params.to_str().unwrap()]].concat(),
    ));
    assert!((wider.1 / default.1 - 2.0).abs() < 0.02, "{wider:?} vs {default:?}");

    let bouc = dir.path().join("bw.json");
    std::fs::write(&bouc, r#"{"k3": 0, "a": 0.5}"#).unwrap();
    let rec = simulate(dir.path(), "c.csv", &["--physics", "bouc-wen", "--physics-params", bouc.to_str().unwrap()]);
    assert!(rec.torque.iter().all(|t| t.is_finite()));

    // A catalogue gear whose + side is 20 % softer: its + peak is the lower one, its − peak
    // the default's.
    let catalogue = dir.path().join("catalogue.json");
    std::fs::write(&catalogue, r#"{"positive_scale": 0.8}"#).unwrap();
    let args = ["--physics", "catalogue", "--torque-noise", "0", "--rate", "1200"];
    let peaks = |rec: &Recording| {
        let max = rec.torque.iter().fold(f64::MIN, |m, &t| m.max(t));
        let min = rec.torque.iter().fold(f64::MAX, |m, &t| m.min(t));
        (max, min)
    };
    let symmetric = peaks(&simulate(dir.path(), "d.csv", &args));
    let softer = peaks(&simulate(
        dir.path(),
        "e.csv",
        &[&args[..], &["--physics-params", catalogue.to_str().unwrap()]].concat(),
    ));
    assert!((symmetric.0 + symmetric.1).abs() < 0.01 * symmetric.0, "{symmetric:?}");
    assert!(softer.0 < 0.9 * symmetric.0, "{softer:?} vs {symmetric:?}");
    assert!((softer.1 - symmetric.1).abs() < 0.01 * symmetric.0, "{softer:?} vs {symmetric:?}");
}

#[test]
fn a_deflection_zero_offsets_the_recorded_deflection_within_the_encoder_step() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["--physics", "catalogue", "--motion", "nested", "--input-bits", "20", "--output-bits", "20"];
    let zeroed = simulate(dir.path(), "a.csv", &args);
    let offset = simulate(dir.path(), "b.csv", &[&args[..], &["--deflection-zero", "-3e-4"]].concat());
    assert_eq!(meta(&zeroed, "deflection_zero_rad"), None);
    assert_eq!(meta(&offset, "deflection_zero_rad"), Some("-0.0003"));
    assert_eq!(meta(&offset, "start"), Some("rest"));
    let step = std::f64::consts::TAU / f64::from(1 << 20);
    for (a, b) in zeroed.deflection.iter().zip(&offset.deflection) {
        assert!((b - a + 3e-4).abs() <= step, "{a} {b}");
    }
    assert_eq!(zeroed.torque, offset.torque);
}

#[test]
fn every_option_keeps_working_with_the_truth_physics() {
    let dir = tempfile::tempdir().unwrap();
    for physics in ["bouc-wen", "micro-slip", "catalogue", "genetic"] {
        let rec = simulate(
            dir.path(),
            "all.csv",
            &[
                "--physics",
                physics,
                "--motion",
                "nested",
                "--input-speed",
                "4",
                "--input-bits",
                "18",
                "--output-bits",
                "20",
                "--temperature",
                "30",
                "--temperature-rise",
                "0.5",
                "--ratio",
                "100",
                "--effect",
                "backlash=5e-5",
                "--effect",
                "coulomb_friction=0.3",
                "--effect",
                "thermal_drift=0.01",
                "--effect",
                "kinematic_error=3e-6",
                "--frequency",
                "0.5,1",
                "--cycles",
                "2",
            ],
        );
        assert_eq!(rec.ratio, 100.0);
        assert_eq!(rec.time.len(), 6001);
        assert!(rec.temperature.as_ref().unwrap().last().unwrap() > &31.0);
        assert!(rec.torque.iter().all(|t| t.is_finite()));
    }
}

#[test]
fn bad_options_are_named_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.csv");
    let json = dir.path().join("p.json");
    std::fs::write(&json, "{\n  \"k\": 9000,\n  \"kk\": 1\n}\n").unwrap();
    let params = repo("data/seed/lht-20-50-fit.json");
    let cases: [(&[&str], &str); 14] = [
        (&["--motion", "sinus"], "invalid value 'sinus' for '--motion"),
        (&["--physics", "dahl"], "invalid value 'dahl' for '--physics"),
        (&["--bias", "1e-3"], "--bias is for --motion biased or hold, not --motion sine"),
        (
            &["--physics-params", json.to_str().unwrap()],
            "--physics-params is for --physics micro-slip, bouc-wen, catalogue or preisach",
        ),
        (&["--physics", "bouc-wen", "--params", &params], "--params sets the model of --physics genetic"),
        (
            &["--physics", "bouc-wen", "--physics-params", json.to_str().unwrap()],
            "p.json:3: column 6: unknown field `kk`",
        ),
        (&["--physics", "micro-slip", "--physics-params", json.to_str().unwrap()], "unknown field `k`"),
        (&["--physics", "catalogue", "--physics-params", json.to_str().unwrap()], "unknown field `k`"),
        (&["--deflection-zero", "2"], "deflection zero must be within ±1 rad, got 2"),
        (&["--motion", "biased", "--bias", "nan"], "bias must be a finite deflection"),
        (&["--physics", "bouc-wen", "--effect", "backlash=0.1", "--rate", "0"], "sample rate must be > 0 Hz"),
        // A negative value is read as one, and its range named (not "unexpected argument '-1'").
        (&["--amplitude", "-1"], "amplitude must be > 0 rad, got -1"),
        (&["--frequency", "-2"], "frequency must be > 0 Hz, got -2"),
        (&["--torque-noise", "-0.1"], "torque noise must be >= 0 N·m, got -0.1"),
    ];
    for (args, expected) in cases {
        let stderr = fails(&out, args);
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
    }
    std::fs::write(&json, r#"{"a": 1.5}"#).unwrap();
    let stderr = fails(&out, &["--physics", "bouc-wen", "--physics-params", json.to_str().unwrap()]);
    assert!(stderr.contains("bouc-wen parameter a must be in [0, 1), got 1.5"), "{stderr}");
    std::fs::write(&json, r#"{"skew": 1.0}"#).unwrap();
    let stderr = fails(&out, &["--physics", "preisach", "--physics-params", json.to_str().unwrap()]);
    assert!(stderr.contains("preisach parameter skew must be in (-1, 1)"), "{stderr}");
    std::fs::write(&json, r#"{"t1_nm": 25}"#).unwrap();
    let stderr = fails(&out, &["--physics", "catalogue", "--physics-params", json.to_str().unwrap()]);
    assert!(stderr.contains("catalogue parameter t2_nm must be > t1_nm N·m, got 19"), "{stderr}");
}

/// The bundled seed fit runs its loop the active way: under a motion other than the sine its
/// memory term is no gear's, and `simulate` says so (random motion: 100 N·m near θ = 0 on a gear
/// of 28 N·m at its tips); on the sine, the loop it was fitted to, it does not; nor on a passive
/// genetic gear (h < 0).
#[test]
fn an_active_genetic_gear_under_a_motion_other_than_the_sine_is_said_to_be_no_gear() {
    let dir = tempfile::tempdir().unwrap();
    let out = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let note = "note: this genetic gear runs its loop the active way";
    let random = ok(swg_host(&["simulate", "--out", &out("random.csv"), "--motion", "random"]));
    assert!(random.contains(note), "{random}");
    let sine = ok(swg_host(&["simulate", "--out", &out("sine.csv")]));
    assert!(!sine.contains(note), "{sine}");
    let id = model_core::Identifiable { h: -1.5, r: 1.2 };
    let passive = model_core::Params::from_identifiable(2.2e4, 4.0e9, 0.0, id, 1.2e-3).unwrap();
    let params = common::write_params_file(dir.path(), &passive);
    let args = ["--motion", "random", "--params", params.to_str().unwrap()];
    let passive = ok(swg_host(&[&["simulate", "--out", &out("passive.csv")][..], &args].concat()));
    assert!(!passive.contains(note), "{passive}");
}

/// The default plan of an identification experiment (what the joint's experiment will play):
/// three amplitudes, each at two rates, then a dithered hold, from rest back to rest. Played
/// through a micro-slip gear with a torque sensor offset and damping, it gives `diagnose` what
/// it needs to name both: the offset read at rest, and the damping told from hysteresis and
/// friction by the two rates.
#[test]
fn the_default_plan_records_what_diagnose_needs_to_name_an_offset_and_a_damping() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "--motion",
        "plan",
        "--physics",
        "micro-slip",
        "--effect",
        "torque_offset=0.3",
        "--effect",
        "viscous_damping=20",
    ];
    let rec = simulate(dir.path(), "plan.csv", &args);
    assert_eq!(rec.time.len(), 30_501, "30.5 s at 1 kHz");
    assert_eq!(meta(&rec, "motion"), Some("plan: the default plan"));
    let plan = meta(&rec, "plan").unwrap();
    assert!(plan.starts_with("deflection (rad): hold 2 s, dither 0 at 0 Hz; sine 0.000292 at 0.5 Hz × 3"), "{plan}");
    assert_eq!(meta(&rec, "amplitude_rad"), Some("0.001168"));
    let peak = rec.deflection.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
    assert!((peak - A).abs() < 1e-3 * A, "{peak}");
    assert!(rec.deflection.first().unwrap().abs() < 1e-12 && rec.deflection.last().unwrap().abs() < 1e-9);
    let report = common::json(&swg_host(&["diagnose", dir.path().join("plan.csv").to_str().unwrap(), "--json"]));
    let named = |effect: &str| {
        report["findings"]
            .as_array()
            .unwrap()
            .iter()
            .find(|f| f["effect"] == effect)
            .map(|f| f["magnitude"].as_f64().unwrap())
    };
    let offset = named("torque_offset").unwrap_or_else(|| panic!("{report:#}"));
    let damping = named("viscous_damping").unwrap_or_else(|| panic!("{report:#}"));
    assert!((offset - 0.3).abs() < 0.01 && (damping - 20.0).abs() < 1.0, "{offset} {damping}");
    assert_eq!(report["findings"].as_array().unwrap().len(), 2, "{:#}", report["findings"]);
}

#[test]
fn a_plan_file_is_played_and_a_bad_one_names_file_line_and_column_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.json");
    let plan = r#"{
  "channel": "deflection",
  "limits": { "torque_nm": 60, "deflection_rad": 0.0015 },
  "segments": [
    { "ramp": { "to": 0.0006, "seconds": 2 } },
    { "hold": { "seconds": 4, "dither_amplitude": 0.00002, "dither_hz": 5 } },
    { "ramp": { "to": 0, "seconds": 2 } }
  ]
}"#;
    std::fs::write(&path, plan).unwrap();
    let file = path.to_str().unwrap();
    let rec = simulate(dir.path(), "played.csv", &["--motion", file, "--physics", "bouc-wen", "--rate", "500"]);
    assert_eq!(rec.time.len(), 4001, "8 s at 500 Hz");
    assert_eq!(meta(&rec, "motion"), Some(format!("plan: {file}").as_str()));
    let held = rec.deflection[2000];
    assert!((held - 6e-4).abs() <= 2e-5 + 1e-9, "{held}");

    let out = dir.path().join("out.csv");
    std::fs::write(&path, plan.replace("0.0006", "0.0016")).unwrap();
    let stderr = fails(&out, &["--motion", file]);
    assert!(stderr.contains(&format!("{file}:5: column 5: segment 1 reaches 0.001600")), "{stderr}");
    std::fs::write(&path, plan.replace("\"dither_hz\": 5", "\"dither_hz\": 30")).unwrap();
    let stderr = fails(&out, &["--motion", file, "--rate", "500"]);
    assert!(stderr.contains(&format!("{file}:6: column 5: segment 2: its frequency, 30 Hz, must be")), "{stderr}");
    std::fs::write(&path, plan.replace("\"deflection\"", "\"torque\"")).unwrap();
    let stderr = fails(&out, &["--motion", file]);
    assert!(stderr.contains(&format!("{file}: the plan is of the torque")), "{stderr}");
    // The joint would stop where the torque passes the plan's limit: simulate says where.
    std::fs::write(&path, plan.replace("\"torque_nm\": 60", "\"torque_nm\": 5")).unwrap();
    let stderr = fails(&out, &["--motion", file, "--physics", "bouc-wen"]);
    assert!(stderr.contains(&format!("{file}: the gear's torque reaches")), "{stderr}");
    assert!(stderr.contains("beyond the plan's limit of 5 N·m"), "{stderr}");
    std::fs::write(&path, plan.replace("\"seconds\": 4,", "\"seconds\": 4, \"speed\": 1,")).unwrap();
    let stderr = fails(&out, &["--motion", file]);
    assert!(stderr.contains(&format!("{file}:6: column")) && stderr.contains("unknown field `speed`"), "{stderr}");
}
