//! `swg-host simulate --effect` and `swg-host diagnose` end to end.
mod common;

use common::{ok, repo, swg_host};

/// A gear with decaying memory, as bench gears show; α < 0 makes its loop passive.
const GEAR: &str = r#"{"model": "genetic-hysteresis", "params": {"c1": 22000.0, "c2": 4.0e9, "c3": 0.0, "alpha": -3050.0, "beta": 1.2, "omega": 1.0}}"#;

#[test]
fn finds_friction_and_writes_the_documented_json_and_pictures() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("gear.json");
    std::fs::write(&params, GEAR).unwrap();
    let recording = dir.path().join("rec.csv");
    ok(swg_host(&[
        "simulate",
        "--params",
        params.to_str().unwrap(),
        "--out",
        recording.to_str().unwrap(),
        "--cycles",
        "3",
        "--frequency",
        "0.2,0.6",
        "--output-bits",
        "20",
        "--input-bits",
        "20",
        "--torque-noise",
        "0.05",
        "--effect",
        "coulomb_friction=0.06",
    ]));
    let plots = dir.path().join("plots");
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&[
        "diagnose",
        recording.to_str().unwrap(),
        "--json",
        "--plot",
        plots.to_str().unwrap(),
    ])))
    .unwrap();
    assert!(json["baseline"]["rss"].is_f64() && json["baseline"]["n"].is_u64());
    let findings = json["findings"].as_array().unwrap();
    assert_eq!(findings.len(), 1, "{findings:?}");
    let friction = &findings[0];
    assert_eq!(friction["effect"], "coulomb_friction");
    assert_eq!(friction["unit"], "N·m");
    let magnitude = friction["magnitude"].as_f64().unwrap();
    assert!((magnitude - 0.06).abs() < 0.25 * 0.06, "{magnitude}");
    assert!(friction["where"].as_str().unwrap().contains("direction"));
    assert!(friction["rss_after"].as_f64().unwrap() < friction["rss_before"].as_f64().unwrap());
    assert!(friction["evidence"]["delta_bic"].as_f64().unwrap() > 10.0);
    assert_eq!(json["final"]["effects"], serde_json::json!(["coulomb_friction"]));
    assert!(json["final"]["rss"].as_f64().unwrap() < json["baseline"]["rss"].as_f64().unwrap());
    let held_out = &json["held_out"];
    assert!(held_out["rms_after"].as_f64().unwrap() < held_out["rms_before"].as_f64().unwrap());
    // No verdict on what this recording cannot show.
    let cannot: Vec<&str> =
        json["not_revealable"].as_array().unwrap().iter().map(|r| r["effect"].as_str().unwrap()).collect();
    assert_eq!(cannot, ["kinematic_error", "thermal_drift"]);
    for name in ["residuals.svg", "loop.svg", "masing.svg", "drift.svg"] {
        let svg = std::fs::read_to_string(plots.join(name)).unwrap();
        assert!(svg.starts_with("<svg"), "{name}");
    }
    // One loop at two rates: Masing's rule is not tested, and the picture says why.
    assert_eq!(json["non_masing"]["tested"], "no", "{:#}", json["non_masing"]);
    let masing = std::fs::read_to_string(plots.join("masing.svg")).unwrap();
    assert!(masing.contains("not tested") && masing.contains("one loop"), "{masing}");
    let residuals = std::fs::read_to_string(plots.join("residuals.svg")).unwrap();
    for panel in ["against deflection", "against time", "against deflection rate", "input angle: not in this data"] {
        assert!(residuals.contains(panel), "{panel}");
    }
}

#[test]
fn the_seed_table_can_only_reveal_what_a_loop_table_shows() {
    let json: serde_json::Value =
        serde_json::from_str(&ok(swg_host(&["diagnose", &repo("data/seed/lht-20-50.csv"), "--json"]))).unwrap();
    let revealable: Vec<&str> = json["revealable"].as_array().unwrap().iter().map(|e| e.as_str().unwrap()).collect();
    assert_eq!(revealable, ["backlash", "coulomb_friction", "torque_offset"]);
    assert!((json["baseline"]["rss"].as_f64().unwrap() - 4.18075).abs() < 1e-3);
    // 18 points cannot carry the evidence for a dead band, though one fits where the paper
    // measures 0.143 mrad at zero torque: w/2 ≈ 0.14 mrad.
    assert_eq!(json["findings"].as_array().unwrap().len(), 0);
    let backlash = json["rejected"].as_array().unwrap().iter().find(|r| r["effect"] == "backlash").unwrap();
    let half_width = backlash["magnitude"].as_f64().unwrap() / 2.0;
    assert!((half_width - 0.143e-3).abs() < 0.02e-3, "{half_width}");
    // Its loop runs the active way: at 14 and 16 N·m the unloading branch has less deflection.
    let passivity = &json["passivity"];
    assert_eq!(passivity["active"], true, "{passivity}");
    assert!(passivity["mean_energy_j"].as_f64().unwrap() < 0.0);
    assert!(passivity["words"].as_str().unwrap().contains("branch labels are swapped"));
}

/// Simulates `GEAR` (or `params`) at `frequencies` with `effect`, and diagnoses it.
fn diagnosed(params: Option<&str>, frequencies: &str, effect: &str) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("gear.json");
    std::fs::write(&file, params.unwrap_or(GEAR)).unwrap();
    let noise = ["--output-bits", "20", "--input-bits", "20", "--torque-noise", "0.03"];
    let motion = ["--params", file.to_str().unwrap(), "--cycles", "3", "--frequency", frequencies, "--effect", effect];
    simulated_and_diagnosed(dir.path(), "rec.csv", &[&motion[..], &noise].concat())
}

/// `swg-host simulate` with `args` into `dir/name`, then the JSON of `swg-host diagnose` on it.
fn simulated_and_diagnosed(dir: &std::path::Path, name: &str, args: &[&str]) -> serde_json::Value {
    let recording = dir.join(name);
    let out = recording.to_str().unwrap();
    ok(swg_host(&[&["simulate", "--out", out][..], args].concat()));
    serde_json::from_str(&ok(swg_host(&["diagnose", out, "--json"]))).unwrap()
}

/// [`simulated_and_diagnosed`] on `simulate`'s micro-slip gear with 20-bit encoders.
fn micro_slip_diagnosed(dir: &std::path::Path, name: &str, args: &[&str]) -> serde_json::Value {
    let gear = ["--physics", "micro-slip", "--input-bits", "20", "--output-bits", "20"];
    simulated_and_diagnosed(dir, name, &[&gear[..], args].concat())
}

#[test]
fn at_one_rate_friction_damping_and_a_delay_cannot_be_told_from_the_loops_shape() {
    let json = diagnosed(None, "0.3", "coulomb_friction=0.06");
    let cannot: Vec<&str> =
        json["not_revealable"].as_array().unwrap().iter().map(|r| r["effect"].as_str().unwrap()).collect();
    assert_eq!(cannot, ["coulomb_friction", "viscous_damping", "channel_delay", "kinematic_error", "thermal_drift"]);
    let why = json["not_revealable"][0]["why"].as_str().unwrap();
    assert!(why.contains("cannot be told apart") && why.contains("second rate"), "{why}");
    assert_eq!(json["findings"].as_array().unwrap().len(), 0, "{json:#}");
}

/// A gear that stiffens 2.5× from zero to the turning points, as harmonic drives do.
const STIFFENING: &str = r#"{"model": "genetic-hysteresis", "params": {"c1": 6000.0, "c2": 1.5e10, "c3": 0.0, "alpha": -3050.0, "beta": 1.2, "omega": 1.0}}"#;

fn named(json: &serde_json::Value) -> Vec<(String, f64)> {
    let findings = json["findings"].as_array().unwrap();
    findings.iter().map(|f| (f["effect"].as_str().unwrap().to_owned(), f["magnitude"].as_f64().unwrap())).collect()
}

#[test]
fn on_a_stiffening_gear_damping_and_a_channel_delay_are_told_apart() {
    for (effect, name, truth) in [
        ("viscous_damping=20", "viscous_damping", 20.0),
        ("channel_delay=1e-3", "channel_delay", 1e-3),
        ("channel_delay=-1e-3", "channel_delay", -1e-3),
    ] {
        let json = diagnosed(Some(STIFFENING), "0.2,0.6", effect);
        let found = named(&json);
        assert_eq!(found.len(), 1, "{effect}: {json:#}");
        assert_eq!(found[0].0, name, "{effect}");
        assert!((found[0].1 - truth).abs() < 0.1 * truth.abs(), "{effect}: {}", found[0].1);
        assert!(json.get("undecided").is_none(), "{effect}");
    }
}

/// Issue 18's case: a damping recorded at 0.05, 0.2 and 0.8 Hz is below the noise at the slow
/// rates, where its estimate agrees with anything. It is named on the pooled estimate, its slow
/// and fast estimates agreeing within their errors; when each rate had to show it clearly alone,
/// it was refused ("not clear at both the slower and the faster motion").
#[test]
fn a_damping_too_small_to_see_at_the_slow_rate_is_named_from_every_rate_pooled() {
    // simulate's own gear and noise (exact angles, 0.05 N·m): the slow estimate reads 20.7 ± 7.1.
    let dir = tempfile::tempdir().unwrap();
    let motion = ["--cycles", "3", "--frequency", "0.05,0.2,0.8", "--effect", "viscous_damping=25"];
    let json = simulated_and_diagnosed(dir.path(), "rec.csv", &motion);
    let found = named(&json);
    assert_eq!(found.len(), 1, "{json:#}");
    assert_eq!(found[0].0, "viscous_damping", "{json:#}");
    assert!((found[0].1 - 25.0).abs() < 0.1 * 25.0, "{}", found[0].1);
    assert_eq!(json["findings"][0]["active"], false);
    // The same damping of the other sign gives energy back: named, and flagged active.
    let motion = ["--cycles", "3", "--frequency", "0.05,0.2,0.8", "--effect", "viscous_damping=-25"];
    let json = simulated_and_diagnosed(dir.path(), "negative.csv", &motion);
    let found = named(&json);
    assert_eq!(found.len(), 1, "{json:#}");
    assert!((found[0].1 + 25.0).abs() < 0.1 * 25.0, "{}", found[0].1);
    assert_eq!(json["findings"][0]["active"], true, "{json:#}");
}

/// Where the loop's stiffness hardly changes as it moves, damping and a delay are one column:
/// the torque is kept, both magnitudes are given, and neither is named.
#[test]
fn a_passive_gear_with_damping_seen_at_two_rates_is_passive_and_damped_or_delayed() {
    let json = diagnosed(None, "0.2,0.6", "viscous_damping=20");
    assert!(named(&json).is_empty(), "{json:#}");
    let undecided = &json["undecided"][0];
    assert_eq!(undecided["effects"], serde_json::json!(["viscous_damping", "channel_delay"]), "{json:#}");
    let damping = undecided["magnitudes"][0].as_f64().unwrap();
    assert!((damping - 20.0).abs() < 0.1 * 20.0, "{damping}");
    assert!(undecided["words"].as_str().unwrap().contains("would tell"));
    assert_eq!(json["final"]["effects"], serde_json::json!(["viscous_damping"]));
    assert_eq!(json["passivity"]["active"], false);
}

#[test]
fn effects_are_checked_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec.csv");
    for (effect, message) in [
        ("friction=0.1", "unknown effect \"friction\""),
        ("backlash=-1e-5", "dead band width must be >= 0"),
        ("viscous_damping=fast", "expected a number in N·m·s/rad"),
        ("thermal_drift=1e-4", "thermal_drift needs a temperature column"),
    ] {
        let output = swg_host(&["simulate", "--out", out.to_str().unwrap(), "--effect", effect]);
        assert!(!output.status.success(), "{effect}");
        assert!(
            String::from_utf8_lossy(&output.stderr).contains(message),
            "{effect}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        assert!(!out.exists());
    }
}

/// `diagnose --params` starts from the paper's genetic model. The file `fit` writes holds the
/// genetic kind on a free-form spring, which it cannot take: the error says so and what to give
/// instead (it said "takes the genetic-hysteresis model; the file holds genetic-hysteresis"),
/// and the file of `fit --model genetic-loop` is taken.
#[test]
fn a_baseline_on_a_free_form_spring_is_refused_with_what_to_give_instead() {
    let dir = tempfile::tempdir().unwrap();
    let recording = simulated(dir.path(), "rec.csv", GEAR, &["--cycles", "2", "--torque-noise", "0.03"]);
    let params = |model: &str| {
        let path = dir.path().join(format!("{model}.json")).display().to_string();
        ok(swg_host(&["fit", &recording, "--model", model, "--out", &path]));
        path
    };
    let free = params("genetic");
    let output = swg_host(&["diagnose", &recording, "--params", &free]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && stderr.contains("free-form spring of"), "{stderr}");
    assert!(stderr.contains("fit --model genetic-loop"), "{stderr}");
    ok(swg_host(&["diagnose", &recording, "--params", &params("genetic-loop")]));
}

/// A `--motion` file in `dir`: 2 s at rest, then three cycles of a 0.25 Hz sine of `amplitude`.
fn rest_then_sine(dir: &std::path::Path, amplitude: f64) -> std::path::PathBuf {
    rest_then_cycles(dir, amplitude, 3)
}

/// A `--motion` file in `dir`: 2 s at rest, then `cycles` cycles of a 0.25 Hz sine of `amplitude`.
fn rest_then_cycles(dir: &std::path::Path, amplitude: f64, cycles: u32) -> std::path::PathBuf {
    let rows: String = (0..=2_000 + 4_000 * cycles)
        .map(|k| {
            let t = f64::from(k) / 1000.0;
            let x = if t < 2.0 { 0.0 } else { amplitude * (std::f64::consts::TAU * 0.25 * (t - 2.0)).sin() };
            format!("{t:.3},{x:.9e}\n")
        })
        .collect();
    let motion = dir.join(format!("motion-{cycles}.csv"));
    std::fs::write(&motion, format!("time_s,deflection_rad\n{rows}")).unwrap();
    motion
}

/// A recording that starts at rest is measured from the deflection it reads there, as `fit`
/// and `predict` place each run: with its encoders zeroed 0.5 mrad off the gear's zero, the
/// diagnosis is the one of the gear zeroed right (unzeroed, the symmetric baseline was fitted
/// about the encoders' zero; on the measured spring, θ0 = −8.4 mrad, that left RMS 6.3 N·m).
#[test]
fn the_deflection_is_measured_from_the_zero_read_at_rest() {
    let dir = tempfile::tempdir().unwrap();
    let gear = dir.path().join("gear.json");
    std::fs::write(&gear, GEAR).unwrap();
    let motion = rest_then_sine(dir.path(), 1.168e-3);
    let diagnosed_with_zero = |zero: &str| {
        let (gear, motion) = (gear.to_str().unwrap(), motion.to_str().unwrap());
        let args = ["--params", gear, "--motion", motion, "--deflection-zero", zero, "--torque-noise", "0.03"];
        simulated_and_diagnosed(dir.path(), &format!("rec-{zero}.csv"), &args)
    };
    let (right, off) = (diagnosed_with_zero("0"), diagnosed_with_zero("5e-4"));
    let zero = off["origin"]["zero_rad"].as_f64().unwrap();
    assert!((zero - 5e-4).abs() < 1e-9, "θ0 read at rest: {zero}");
    assert_eq!(off["origin"]["source"], "rest_window");
    let rms = |json: &serde_json::Value| json["baseline"]["rms"].as_f64().unwrap();
    assert!((rms(&off) - rms(&right)).abs() <= 1e-6 * rms(&right), "{} against {}", rms(&off), rms(&right));
    assert_eq!(off["findings"], right["findings"]);
}

/// A recording declared at rest that moves from its second sample reads θ0 at its first
/// sample and no torque: the report says so, rather than a torque of 0 "read at rest".
#[test]
fn a_rest_too_short_to_read_the_torque_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let recording = dir.path().join("rec.csv").display().to_string();
    let gear = ["--physics", "micro-slip", "--cycles", "2", "--output-bits", "20", "--input-bits", "20"];
    ok(swg_host(&[&["simulate", "--out", &recording, "--effect", "torque_offset=-0.3"][..], &gear].concat()));
    let text = ok(swg_host(&["diagnose", &recording]));
    assert!(text.contains("too soon to read the torque there"), "{text}");
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&["diagnose", &recording, "--json"]))).unwrap();
    assert!(json["origin"].is_object() && json["rest_torque_nm"].is_null(), "{:#}", json["origin"]);
}

/// A micro-slip gear whose spring's + side is `plus` times and − side `minus` times a spring
/// that stiffens from 12000 N·m/rad (three slip elements; model version 2).
fn sided_gear(plus: f64, minus: f64) -> String {
    let knot = |x: f64, k: f64| format!(r#"{{"x": {x:e}, "stiffness": {k}}}"#);
    let knots = [
        knot(-2e-3, minus * 40_000.0),
        knot(-1e-3, minus * 22_000.0),
        knot(0.0, 12_000.0),
        knot(1e-3, plus * 22_000.0),
        knot(2e-3, plus * 40_000.0),
    ];
    format!(
        r#"{{"model": "micro-slip", "model_version": 2, "params": {{"zero": 0.0, "spring": {{"c1": 0.0, "c2": 0.0, "c3": 0.0,
        "knots": [{}], "range": [-2e-3, 2e-3]}}, "elements": [{{"slip": 5e-5, "stiffness": 1500.0}},
        {{"slip": 2e-4, "stiffness": 1500.0}}, {{"slip": 5e-4, "stiffness": 1500.0}}]}}}}"#,
        knots.join(", ")
    )
}

/// The spring's two sides: a gear whose + side is 15 % softer and − side 15 % stiffer than a
/// symmetric one is named asymmetric, with the tips' secant stiffnesses of the truth (its loop
/// from rest to +A, −A, +A, run here on the truth params); the symmetric gear is not. Without a
/// rest window to read the zero at, it is not tested.
#[test]
fn an_asymmetric_spring_is_named_with_its_tips_secants_and_a_symmetric_one_is_not() {
    let dir = tempfile::tempdir().unwrap();
    let amplitude = 1.168e-3;
    let motion = rest_then_sine(dir.path(), amplitude);
    let diagnosed = |name: &str, gear: &str| {
        let path = dir.path().join(format!("{name}.json"));
        std::fs::write(&path, gear).unwrap();
        let args = ["--params", path.to_str().unwrap(), "--motion", motion.to_str().unwrap(), "--torque-noise", "0.03"];
        simulated_and_diagnosed(dir.path(), &format!("{name}.csv"), &args)
    };
    let asymmetric = diagnosed("asymmetric", &sided_gear(0.85, 1.15));
    // The rest before the one-frequency sine is no second rate (counted as one, it let a
    // channel delay of 38 ms be named).
    let cannot: Vec<&str> =
        asymmetric["not_revealable"].as_array().unwrap().iter().map(|r| r["effect"].as_str().unwrap()).collect();
    assert!(cannot.contains(&"channel_delay") && cannot.contains(&"viscous_damping"), "{cannot:?}");
    let found = &asymmetric["asymmetry"];
    assert_eq!(found["tested"], "yes", "{found:#}");
    assert!(found["rejected"].is_null(), "{found:#}");
    // The truth's tips, along the same loop.
    let truth: model_core::GearModel<f64> =
        swg_host::report::params::parse_model("truth".as_ref(), &sided_gear(0.85, 1.15)).unwrap();
    let a = found["extent_rad"].as_f64().unwrap();
    assert!((a - amplitude).abs() < 1e-5 * amplitude, "extent {a}");
    let steps = 200;
    let leg = |from: f64, to: f64| (1..=steps).map(move |k| from + (to - from) * f64::from(k) / f64::from(steps));
    let path: Vec<f64> = std::iter::once(0.0).chain(leg(0.0, a)).chain(leg(a, -a)).chain(leg(-a, a)).collect();
    let torque = swg_host::gear::run_offline(&truth, &path, &swg_host::prepare::reversals(&path)).unwrap();
    let (plus, minus) = (torque.last().unwrap().torque / a, torque[2 * steps as usize].torque / -a);
    let expected = 2.0 * (plus - minus) / (plus + minus);
    let magnitude = found["magnitude"].as_f64().unwrap();
    println!("asymmetry {magnitude:.4} against the truth's {expected:.4}");
    assert!(expected < -0.1 && (magnitude - expected).abs() < 0.02, "{magnitude} against {expected}");
    for (side, truth) in [("plus_nm_per_rad", plus), ("minus_nm_per_rad", minus)] {
        let fitted = found[side].as_f64().unwrap();
        assert!((fitted - truth).abs() < 0.02 * truth, "{side}: {fitted} against {truth}");
    }
    let symmetric = diagnosed("symmetric", &sided_gear(1.0, 1.0));
    assert_eq!(symmetric["asymmetry"]["tested"], "yes");
    assert!(symmetric["asymmetry"]["rejected"].is_string(), "{:#}", symmetric["asymmetry"]);
    // The same recording from mid-rise, without its rest (nor its `# start: rest` line): the
    // zero is not known.
    let recorded = std::fs::read_to_string(dir.path().join("asymmetric.csv")).unwrap();
    let (comments, rows): (Vec<&str>, Vec<&str>) = recorded.lines().partition(|line| line.starts_with('#'));
    let mut cut: Vec<&str> = comments.into_iter().filter(|line| !line.contains("start:")).collect();
    cut.push(rows[0]);
    cut.extend(&rows[2500..]);
    let moving = dir.path().join("moving.csv");
    std::fs::write(&moving, cut.join("\n")).unwrap();
    let unzeroed: serde_json::Value =
        serde_json::from_str(&ok(swg_host(&["diagnose", moving.to_str().unwrap(), "--json"]))).unwrap();
    assert_eq!(unzeroed["asymmetry"]["tested"], "no", "{:#}", unzeroed["asymmetry"]);
}

/// No effect is named that makes the measured torque fit worse: on the seed gear's random motion,
/// which the genetic baseline cannot follow, the weights favoured a torque offset of 23.8 N·m
/// that took the unweighted RSS 5.6× up.
#[test]
fn no_effect_is_named_that_makes_the_torque_fit_worse() {
    let dir = tempfile::tempdir().unwrap();
    let motion = ["--motion", "random", "--input-bits", "20", "--output-bits", "20", "--torque-noise", "0.03"];
    let json = simulated_and_diagnosed(dir.path(), "random.csv", &motion);
    for finding in json["findings"].as_array().unwrap() {
        let (before, after) = (finding["rss_before"].as_f64().unwrap(), finding["rss_after"].as_f64().unwrap());
        assert!(after <= before, "{finding:#}");
    }
    let offset = json["rejected"].as_array().unwrap().iter().find(|r| r["effect"] == "torque_offset");
    let reason = offset.map(|r| r["reason"].as_str().unwrap()).unwrap_or_default();
    assert!(reason.contains("fits worse with it"), "{json:#}");
}

/// Masing's rule: the Preisach gear (slip elements that grip harder where their play sits on
/// the + side, so a loop depends on where it sits) under the nested motion is named, the
/// micro-slip gear (Maxwell-slip, Masing by construction) under the same motion is not, and one
/// loop run over and over is not tested (`bench/diagnose.sh`'s genetic gear under a sine: a loop
/// whose branches cross, sharper at its tips than the slip elements' grid, which the Preisach
/// cells fitted better).
#[test]
fn loops_that_depend_on_where_they_sit_break_masings_rule_and_one_loop_is_not_tested() {
    let dir = tempfile::tempdir().unwrap();
    let nested = ["--motion", "nested", "--input-bits", "20", "--output-bits", "20", "--torque-noise", "0.03"];
    let check = |name: &str, args: &[&str]| {
        let json = simulated_and_diagnosed(dir.path(), &format!("{name}.csv"), args);
        let found = json["non_masing"].clone();
        println!("{name}: {found}");
        assert_eq!(found["tested"], "yes", "{name}: {found:#}");
        found
    };
    let preisach = check("preisach", &[&["--physics", "preisach"][..], &nested].concat());
    assert!(preisach["rejected"].is_null(), "{preisach:#}");
    let plots = dir.path().join("plots");
    let recording = dir.path().join("preisach.csv");
    let text = ok(swg_host(&["diagnose", recording.to_str().unwrap(), "--plot", plots.to_str().unwrap()]));
    assert!(text.contains("do not follow Masing's rule"), "{text}");
    let picture = std::fs::read_to_string(plots.join("masing.svg")).unwrap();
    assert!(picture.contains("(named)") && picture.contains("cannot follow"), "{picture}");
    let [masing, free] = [0, 1].map(|k| preisach["held_out_rms"][k].as_f64().unwrap());
    assert!(free < masing && preisach["explained"].as_f64().unwrap() > 0.1, "{preisach:#}");
    let micro_slip = check("micro-slip", &[&["--physics", "micro-slip"][..], &nested].concat());
    assert!(micro_slip["rejected"].is_string() && micro_slip["delta_bic"].as_f64().unwrap() < 0.0, "{micro_slip:#}");
    let gear = dir.path().join("crossing.json");
    std::fs::write(
        &gear,
        r#"{"model": "genetic-hysteresis", "params": {"c1": 22000.0, "c2": 4.0e9, "c3": 0.0, "alpha": -3050.0, "beta": 1.2, "omega": 1.0}}"#,
    )
    .unwrap();
    let sine = ["--params", gear.to_str().unwrap(), "--cycles", "4", "--output-bits", "20", "--torque-noise", "0.05"];
    let json = simulated_and_diagnosed(dir.path(), "one-loop.csv", &sine);
    let one_loop = &json["non_masing"];
    assert_eq!(one_loop["tested"], "no", "{one_loop:#}");
    assert!(one_loop["why"].as_str().unwrap().contains("one loop"), "{one_loop:#}");
}

/// Ratcheting: under a held load with a dither, the Bouc–Wen gear's loops drift (its peak torque
/// falls cycle after cycle) and are named, with the maxima and the minima drifting alike; the
/// micro-slip gear's loops close where they started and are not.
#[test]
fn loops_held_under_a_dither_drift_on_a_bouc_wen_gear_and_close_on_a_micro_slip_gear() {
    let dir = tempfile::tempdir().unwrap();
    let hold = ["--motion", "hold", "--input-bits", "20", "--output-bits", "20", "--torque-noise", "0.03"];
    let check = |physics: &str| {
        let json = simulated_and_diagnosed(
            dir.path(),
            &format!("{physics}.csv"),
            &[&["--physics", physics][..], &hold].concat(),
        );
        let found = json["ratcheting"].clone();
        println!("{physics}: {found}");
        assert_eq!(found["tested"], "yes", "{physics}: {found:#}");
        found
    };
    let bouc_wen = check("bouc-wen");
    assert!(bouc_wen["rejected"].is_null(), "{bouc_wen:#}");
    let plots = dir.path().join("plots");
    let recording = dir.path().join("bouc-wen.csv");
    let text = ok(swg_host(&["diagnose", recording.to_str().unwrap(), "--plot", plots.to_str().unwrap()]));
    assert!(text.contains("loops run over and over drift"), "{text}");
    let picture = std::fs::read_to_string(plots.join("drift.svg")).unwrap();
    assert!(picture.contains("(named)") && picture.contains("maxima"), "{picture}");
    let drift = bouc_wen["drift_nm_per_cycle"].as_f64().unwrap();
    let ends = [0, 1].map(|k| bouc_wen["ends"][k].as_f64().unwrap());
    assert!(drift < 0.0 && ends.iter().all(|e| *e < 0.0), "{bouc_wen:#}");
    assert!(bouc_wen["cycles"].as_u64().unwrap() >= 30, "{bouc_wen:#}");
    let micro_slip = check("micro-slip");
    assert!(micro_slip["rejected"].is_string(), "{micro_slip:#}");
    assert!(micro_slip["drift_nm_per_cycle"].as_f64().unwrap().abs() < 0.1 * drift.abs(), "{micro_slip:#}");
    // A dither held at +A/2, then at −A/2 (1 kHz): both holds relax towards zero torque, and
    // measured along the torque each holds they add up (as measured, they cancelled: unnamed).
    let amplitude = 1.168e-3;
    let smooth = |u: f64| u * u * u * (10.0 + u * (-15.0 + 6.0 * u));
    let mut rows = vec!["time_s,deflection_rad".to_string()];
    let mut push = |theta: f64| rows.push(format!("{:.6},{theta:e}", rows.len() as f64 / 1000.0));
    (0..500).for_each(|_| push(0.0));
    for (from, to) in [(0.0, 0.5), (0.5, -0.5)] {
        (0..2000).for_each(|i| push((from + (to - from) * smooth(f64::from(i) / 2000.0)) * amplitude));
        (0..6000).for_each(|i| {
            push((to - 0.04 * (1.0 - (std::f64::consts::TAU * 5.0 * f64::from(i) / 1000.0).cos())) * amplitude)
        });
    }
    let motion = dir.path().join("two-holds-motion.csv");
    std::fs::write(&motion, rows.join("\n") + "\n").unwrap();
    let args = ["--physics", "bouc-wen", "--motion", motion.to_str().unwrap()];
    let json = simulated_and_diagnosed(dir.path(), "two-holds.csv", &[&args[..], &hold[2..]].concat());
    let two = &json["ratcheting"];
    assert!(two["rejected"].is_null() && two["runs"] == 2, "{two:#}");
    assert!(two["drift_nm_per_cycle"].as_f64().unwrap() < 0.0, "{two:#}");
    // A warming micro-slip gear whose thermal drift the search refused: its torque drifts with
    // the temperature, which a drift of the loops cannot be told from (it was named ratcheting).
    let warming = ["--physics", "micro-slip", "--cycles", "8", "--temperature", "25", "--temperature-rise", "0.2"];
    let effect = ["--effect", "thermal_drift=0.01", "--seed", "2"];
    let json = simulated_and_diagnosed(dir.path(), "warming.csv", &[&warming[..], &effect, &hold].concat());
    let named: Vec<&str> = json["findings"].as_array().unwrap().iter().map(|f| f["effect"].as_str().unwrap()).collect();
    if !named.contains(&"thermal_drift") {
        assert_eq!(json["ratcheting"]["tested"], "no", "{:#}", json["ratcheting"]);
    }
}

/// On gears of an independent simulator (`data/opensees/`, see its README) a channel delay does
/// not stand in for the loop's shape. On OpenSees' Bouc–Wen material with nothing concealed it is
/// tested on top of the micro-slip form, with the form's own stiffness, and withdrawn. On the
/// peak-oriented material with damping concealed (40 N·m·s/rad), the delay that the genetic
/// model's stiffness preferred fits the form no better than damping: the torque is real and its
/// mechanism untold, so both are kept as either of two, with their magnitudes on the form (on
/// the genetic model the damping read 165). Before either, both named a delay of 1.6–2.7 ms:
/// wrong physics; then the peak-oriented material's damping was rejected: a miss.
#[test]
fn on_an_independent_simulators_gears_a_channel_delay_does_not_stand_in_for_the_loops_shape() {
    let diagnosed = |file: &str| -> serde_json::Value {
        let path = repo(&format!("data/opensees/{file}"));
        let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&["diagnose", &path, "--json"]))).unwrap();
        let named: Vec<&str> =
            json["findings"].as_array().unwrap().iter().map(|f| f["effect"].as_str().unwrap()).collect();
        assert!(!named.contains(&"channel_delay"), "{file}: {named:?}");
        assert!(json["model_form"].is_object(), "{file}: {:#}", json["model_form"]);
        json
    };
    let json = diagnosed("bouc-wen-none.csv");
    let delay = json["rejected"].as_array().unwrap().iter().find(|r| r["effect"] == "channel_delay");
    let reason = delay.map(|r| r["reason"].as_str().unwrap()).unwrap_or_default();
    assert!(reason.contains("stands in for the loop's shape"), "{reason}");
    assert!(json["undecided"].as_array().is_none_or(Vec::is_empty), "{:#}", json["undecided"]);

    let json = diagnosed("hysteretic-viscous_damping.csv");
    let [kept] = &json["undecided"].as_array().unwrap()[..] else { panic!("{:#}", json["undecided"]) };
    assert!(kept["words"].as_str().unwrap().contains("mechanism cannot be told"), "{kept:#}");
    let effects: Vec<&str> = kept["effects"].as_array().unwrap().iter().map(|e| e.as_str().unwrap()).collect();
    let damping = effects.iter().position(|e| *e == "viscous_damping").expect("damping among the two");
    assert!(effects.contains(&"channel_delay"), "{effects:?}");
    let magnitude = kept["magnitudes"][damping].as_f64().unwrap();
    assert!((magnitude - 40.0).abs() <= 0.25 * 40.0, "damping {magnitude} N·m·s/rad against 40 concealed");
}

/// `data/opensees/FILE` diagnosed, as JSON, after `edit` has rewritten its rows (time_s,
/// theta_in_rad, theta_out_rad, torque_nm): the recording of a gear of an independent simulator.
fn opensees_diagnosed(file: &str, edit: impl Fn(Vec<[f64; 4]>) -> Vec<[f64; 4]>) -> serde_json::Value {
    let text = std::fs::read_to_string(repo(&format!("data/opensees/{file}"))).unwrap();
    let (head, body): (Vec<&str>, Vec<&str>) =
        text.lines().partition(|l| l.starts_with('#') || l.starts_with("time_s"));
    let rows: Vec<[f64; 4]> = body
        .iter()
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    let lines: Vec<String> = head
        .iter()
        .map(|l| l.to_string())
        .chain(edit(rows).iter().map(|r| r.map(|x| x.to_string()).join(",")))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(file);
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    serde_json::from_str(&ok(swg_host(&["diagnose", path.to_str().unwrap(), "--json"]))).unwrap()
}

/// `rows` after a rest of 2 s before them: the first row's angles held, the torque reading
/// `torque` with noise of σ = 0.05 N·m (a fixed sequence), the rows after moved on in time.
fn after_a_rest(rows: Vec<[f64; 4]>, torque: f64) -> Vec<[f64; 4]> {
    let dt = rows[1][0] - rows[0][0];
    let count = (2.0 / dt).round() as usize;
    let mut state: u64 = 11;
    let mut noise = move || {
        // Sum of 12 uniforms less 6: near-Gaussian, σ = 1.
        (0..12)
            .map(|_| {
                state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                (state >> 11) as f64 / (1u64 << 53) as f64
            })
            .sum::<f64>()
            - 6.0
    };
    let rest = (0..count).map(|k| [k as f64 * dt, rows[0][1], rows[0][2], torque + 0.05 * noise()]);
    rest.chain(rows.iter().map(|r| [r[0] + count as f64 * dt, r[1], r[2], r[3]])).collect()
}

/// Names of the findings of a diagnosis' JSON.
fn effects_named(json: &serde_json::Value) -> Vec<String> {
    json["findings"].as_array().unwrap().iter().map(|f| f["effect"].as_str().unwrap().to_string()).collect()
}

/// A torque offset that the search cannot tell without the torque read at rest (the motion
/// leaves rest at once) is not taken for a finding of form: on a symmetric micro-slip gear with
/// 0.3 N·m, the asymmetry's secants read +2.5 % (named), and under nested motion the Preisach
/// cells took it up as a departure from Masing's rule (ΔBIC 16374); a free offset stands beside
/// their forms, as beside the kinks' scan (a new user's trial).
#[test]
fn an_offset_the_search_cannot_tell_is_not_taken_for_a_finding_of_form() {
    let dir = tempfile::tempdir().unwrap();
    let sine = ["--frequency", "0.2,0.8", "--deflection-zero", "4e-4", "--effect", "torque_offset=0.3"];
    let report = micro_slip_diagnosed(dir.path(), "sine.csv", &sine);
    assert!(report["asymmetry"]["rejected"].is_string(), "{:#}", report["asymmetry"]);
    let nested = ["--motion", "nested", "--frequency", "0.25,1", "--effect", "torque_offset=0.3"];
    let report = micro_slip_diagnosed(dir.path(), "nested.csv", &nested);
    assert_eq!(report["non_masing"]["tested"], "yes", "{:#}", report["non_masing"]);
    assert!(report["non_masing"]["rejected"].is_string(), "{:#}", report["non_masing"]);
}

/// A channel delay on a micro-slip gear at two rates: on the form its slower and faster
/// estimates read 1.900 ± 0.018 and 1.961 ± 0.004 ms, 3 standard errors apart but 3 % of each
/// other, and the delay was refused ("does not scale with the rate"), the final model leaving
/// 4.2× the noise. Within 10 % they agree.
#[test]
fn a_delay_read_alike_at_two_rates_on_the_form_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["--motion", "nested", "--frequency", "0.25,1", "--effect", "channel_delay=0.002"];
    let report = micro_slip_diagnosed(dir.path(), "rec.csv", &args);
    let named = named(&report);
    assert_eq!(named.len(), 1, "{:#}", report["findings"]);
    let (effect, delay) = &named[0];
    assert_eq!(effect, "channel_delay", "{:#}", report["findings"]);
    assert!((delay - 0.002).abs() < 0.1 * 0.002, "delay {delay} s against 0.002");
}

/// Where a form is named and nothing beside it, the final model is that form, and the JSON holds
/// it as a parameter file (`final.form_model`, θ0 the zero read at rest): `predict --keep-zero`
/// runs it along the recording to the final RMS. `final.params` stay the genetic model's, which a
/// new user's trial took for the final model. Beside an effect there is no such file (it would
/// leave the effect out). The text gives the magnitude each effect refused was tried at.
#[test]
fn the_form_named_is_written_as_a_parameter_file_that_predict_runs() {
    let dir = tempfile::tempdir().unwrap();
    let report = micro_slip_diagnosed(dir.path(), "rec.csv", &["--motion", "nested", "--deflection-zero", "2e-4"]);
    let final_model = &report["final"];
    assert_eq!(final_model["form"], "micro-slip", "{final_model:#}");
    assert!(report["baseline"].get("form_model").is_none(), "{:#}", report["baseline"]);
    let form = &final_model["form_model"];
    assert_eq!(form["model"], "micro-slip", "{form:#}");
    let zero = form["params"]["zero"].as_f64().unwrap();
    assert!((zero - 2e-4).abs() < 1e-5, "θ0 {zero}");
    let params = dir.path().join("form.json");
    std::fs::write(&params, form.to_string()).unwrap();
    let recording = dir.path().join("rec.csv");
    let predicted = common::json(&swg_host(&[
        "predict",
        params.to_str().unwrap(),
        recording.to_str().unwrap(),
        "--keep-zero",
        "--json",
    ]));
    let (rms, final_rms) = (predicted["rms"].as_f64().unwrap(), final_model["rms"].as_f64().unwrap());
    assert!((rms - final_rms).abs() <= 1e-6 * final_rms, "predict {rms} N·m, the final model {final_rms}");
    // The text says at what magnitude each effect refused was tried (a trial missed it).
    let text = ok(swg_host(&["diagnose", recording.to_str().unwrap()]));
    let refused = report["rejected"].as_array().unwrap();
    assert!(!refused.is_empty(), "{report:#}");
    for rejection in refused.iter().filter(|r| r["magnitude"].as_f64().is_some_and(|m| m != 0.0)) {
        let line = format!("  - {} (tried at ", rejection["effect"].as_str().unwrap());
        assert!(text.contains(&line), "{line:?} in\n{text}");
    }
    // The whole report given for a parameter file: said so, with where the file is.
    let whole = dir.path().join("report.json");
    std::fs::write(&whole, report.to_string()).unwrap();
    let refused = swg_host(&["predict", whole.to_str().unwrap(), recording.to_str().unwrap()]);
    assert!(!refused.status.success());
    let said = String::from_utf8_lossy(&refused.stderr);
    assert!(said.contains("a `swg-host diagnose --json` report") && said.contains("final.form_model"), "{said}");
    let damped = ["--frequency", "0.2,0.8", "--effect", "viscous_damping=30"];
    let report = micro_slip_diagnosed(dir.path(), "damped.csv", &damped);
    assert_eq!(report["final"]["form"], "micro-slip", "{:#}", report["final"]);
    assert_eq!(report["final"]["effects"][0], "viscous_damping", "{:#}", report["final"]);
    assert!(report["final"].get("form_model").is_none(), "{:#}", report["final"]);
}

/// The search on the form. OpenSees' Iwan material is a micro-slip gear: with 40 N·m·s/rad of
/// damping concealed, the genetic form's misfit made the slow and fast estimates disagree (159
/// and 49) and the damping was refused; searched on the micro-slip form it is named at 40 ± 10 %,
/// and the final model is that form with it, on the held-out cycles too.
/// With a torque sensor's offset of 0.15 N·m added, read at rest too, both are named. An offset
/// needs that reading on the form: OpenSees' asymmetric spring with nothing concealed is fitted
/// there with an offset of −0.055 N·m that its loop does not have (wrong physics until the rest
/// was asked for); with a rest that reads 0 it is not named either.
#[test]
fn effects_the_genetic_form_hid_are_found_on_the_micro_slip_form() {
    let magnitude = |json: &serde_json::Value, effect: &str| {
        let finding = json["findings"].as_array().unwrap().iter().find(|f| f["effect"] == effect);
        finding.map(|f| f["magnitude"].as_f64().unwrap()).unwrap_or(f64::NAN)
    };
    let json = opensees_diagnosed("iwan-viscous_damping.csv", |rows| rows);
    assert!(json["model_form"].is_object(), "{:#}", json["model_form"]);
    assert_eq!(effects_named(&json), ["viscous_damping"], "{:#}", json["findings"]);
    let damping = magnitude(&json, "viscous_damping");
    assert!((damping - 40.0).abs() <= 4.0, "damping {damping} N·m·s/rad against 40 concealed");
    assert!(json["findings"][0]["where"].as_str().unwrap().contains("micro-slip form"), "{:#}", json["findings"]);
    // The final model is the form with the damping beside it, and the held-out line shows it.
    let (final_model, held_out) = (&json["final"], &json["held_out"]);
    assert_eq!(final_model["form"], "micro-slip", "{final_model:#}");
    let (before, after) = (held_out["rms_before"].as_f64().unwrap(), held_out["rms_after"].as_f64().unwrap());
    assert!(after < 0.5 * before && after < 1.2 * final_model["rms"].as_f64().unwrap(), "{held_out:#}");

    let offset = 0.15;
    let json = opensees_diagnosed("iwan-viscous_damping.csv", |rows| {
        after_a_rest(rows.into_iter().map(|[t, a, b, torque]| [t, a, b, torque + offset]).collect(), offset)
    });
    let mut found = effects_named(&json);
    found.sort();
    assert_eq!(found, ["torque_offset", "viscous_damping"], "{:#}", json["findings"]);
    let read = magnitude(&json, "torque_offset");
    assert!((read - offset).abs() <= 0.1 * offset, "offset {read} N·m against {offset}");

    for rest in [false, true] {
        let json = opensees_diagnosed("asymmetric-none.csv", |rows| if rest { after_a_rest(rows, 0.0) } else { rows });
        assert!(effects_named(&json).is_empty(), "rest {rest}: {:#}", json["findings"]);
        // Without the rest the offset cannot be told on the form: the report says so, and does
        // not refuse it (a refusal read as its absence).
        let untellable = untellable(&json);
        let refused = json["rejected"].as_array().unwrap().iter().any(|r| r["effect"] == "torque_offset");
        assert_eq!(refused, rest, "rest {rest}: {:#}", json["rejected"]);
        let why = untellable.iter().find(|(effect, _)| effect == "torque_offset").map(|(_, why)| why.as_str());
        assert_eq!(why.is_some_and(|why| why.contains("without the torque read at rest")), !rest, "{why:?}");
    }
}

/// A rate effect on the form is tested on one form for both rates, the effect's column split by
/// rate: OpenSees' asymmetric spring with 40 N·m·s/rad of damping concealed read 4.8 ± 11 at the
/// slower rate and 39.6 ± 0.7 at the faster when the form was refitted on each rate alone (it
/// took the damping's opening at the slower rate as its own), and the damping was refused. On
/// one form both read 40 within their errors, and it is named; with nothing concealed nothing is.
#[test]
fn a_damping_on_the_form_is_tested_at_each_rate_on_one_form() {
    let json = opensees_diagnosed("asymmetric-viscous_damping.csv", |rows| rows);
    assert_eq!(effects_named(&json), ["viscous_damping"], "{:#}", json["rejected"]);
    let finding = &json["findings"][0];
    let damping = finding["magnitude"].as_f64().unwrap();
    assert!((damping - 40.0).abs() <= 4.0, "damping {damping} N·m·s/rad against 40 concealed");
    assert!(finding["where"].as_str().unwrap().contains("micro-slip form"), "{finding:#}");
    let json = opensees_diagnosed("asymmetric-none.csv", |rows| rows);
    assert!(effects_named(&json).is_empty(), "{:#}", json["findings"]);
}

/// A finding of form: the catalogue's three-segment spring (OpenSees `ElasticMultiLinear`, K1 =
/// 14000 up to 7 N·m, K2 = 26000 up to 19 N·m, K3 = 42000 N·m/rad beyond: kinks at ±0.500 and
/// ±0.962 mrad) is named with its four kinks, each where the catalogue puts it and by about the
/// step it gives. On the smooth springs of the same corpus none is named; nor where an offset the
/// form cannot tell is in the torque (0.3 N·m added, no rest: steps each side of zero stood in for
/// it on OpenSees' Bouc–Wen and Iwan gears until the scan fitted an offset beside them).
#[test]
fn a_catalogue_springs_kinks_are_named_where_they_are_and_a_smooth_springs_are_not() {
    let json = opensees_diagnosed("catalogue-none.csv", |rows| rows);
    let check = &json["stiffness_kinks"];
    assert_eq!(check["tested"], "yes", "{check:#}");
    assert!(check["rejected"].is_null(), "{check:#}");
    let mut kinks: Vec<(f64, f64, f64)> = check["kinks"]
        .as_array()
        .unwrap()
        .iter()
        .zip(check["torque_nm"].as_array().unwrap())
        .map(|(k, t)| {
            let step = k["outer_nm_per_rad"].as_f64().unwrap() - k["inner_nm_per_rad"].as_f64().unwrap();
            (k["at_rad"].as_f64().unwrap(), step, t.as_f64().unwrap())
        })
        .collect();
    kinks.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (theta1, theta2) = (7.0 / 14000.0, 7.0 / 14000.0 + 12.0 / 26000.0);
    let truth = [(-theta2, 16000.0, -19.0), (-theta1, 12000.0, -7.0), (theta1, 12000.0, 7.0), (theta2, 16000.0, 19.0)];
    assert_eq!(kinks.len(), truth.len(), "{kinks:?}");
    for ((at, step, torque), (at_truth, step_truth, torque_truth)) in kinks.iter().zip(truth) {
        // One step of the scan's grid (A / 32 = 0.037 mrad) from the truth.
        assert!((at - at_truth).abs() <= 0.04e-3, "kink at {at} rad against {at_truth}");
        assert!((step - step_truth).abs() <= 0.25 * step_truth, "step {step} N·m/rad against {step_truth}");
        assert!((torque - torque_truth).abs() <= 1.0, "torque {torque} N·m against {torque_truth}");
    }
    // The loop picture marks where the stiffness steps.
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("plots");
    ok(swg_host(&["diagnose", &repo("data/opensees/catalogue-none.csv"), "--plot", plots.to_str().unwrap()]));
    let picture = std::fs::read_to_string(plots.join("loop.svg")).unwrap();
    assert!(picture.contains("stiffness steps (stiffness_kinks)"), "loop.svg lacks the kinks");
    let named = |json: &serde_json::Value| {
        json["stiffness_kinks"]["tested"] == "yes" && json["stiffness_kinks"]["rejected"].is_null()
    };
    for file in ["asymmetric-none.csv", "bouc-wen-none.csv", "iwan-viscous_damping.csv"] {
        let json = opensees_diagnosed(file, |rows| rows);
        assert!(!named(&json), "{file}: {:#}", json["stiffness_kinks"]);
    }
    for file in ["bouc-wen-none.csv", "iwan-viscous_damping.csv"] {
        let json = opensees_diagnosed(file, |rows| {
            rows.into_iter().map(|[t, a, b, torque]| [t, a, b, torque + 0.3]).collect()
        });
        assert!(!named(&json), "{file} + 0.3 N·m: {:#}", json["stiffness_kinks"]);
    }
}

/// The simulator's catalogue gear with its + side 0.8× as stiff: the kinks lie at the same
/// torques, so at other deflections on each side (− side: −0.500 and −0.962 mrad; + side:
/// +0.625 mrad, and +1.202 beyond the motion). Each kink named is one of them, with its step
/// (− side: K2 − K1 = 12000, K3 − K2 = 10000 N·m/rad) within 25 %, and the − side's two are
/// found. The best step by its fit, at +0.64 mrad, fits better sharp than spread by under 10:
/// the scan used to stop there and name none; it goes on to the next best.
#[test]
fn an_asymmetric_catalogue_springs_kinks_are_found_where_each_side_has_them() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("catalogue.json");
    std::fs::write(&params, r#"{"positive_scale": 0.8}"#).unwrap();
    let args = [
        "--physics",
        "catalogue",
        "--physics-params",
        params.to_str().unwrap(),
        "--frequency",
        "0.2,0.6",
        "--cycles",
        "3",
        "--input-bits",
        "20",
        "--output-bits",
        "20",
        "--seed",
        "4",
    ];
    let json = simulated_and_diagnosed(dir.path(), "catalogue.csv", &args);
    let check = &json["stiffness_kinks"];
    assert!(check["rejected"].is_null(), "{check:#}");
    let truth = [(-0.962e-3, 10000.0), (-0.500e-3, 12000.0), (0.625e-3, 0.8 * 12000.0)];
    let mut found = Vec::new();
    for kink in check["kinks"].as_array().unwrap() {
        let at = kink["at_rad"].as_f64().unwrap();
        let step = kink["outer_nm_per_rad"].as_f64().unwrap() - kink["inner_nm_per_rad"].as_f64().unwrap();
        let Some(&(_, truth_step)) = truth.iter().find(|(x, _)| (at - x).abs() <= 0.04e-3) else {
            panic!("a kink named at {at} rad, where the spring has none: {check:#}");
        };
        assert!((step - truth_step).abs() <= 0.25 * truth_step, "step {step} at {at} against {truth_step}");
        found.push(at);
    }
    for side in [-0.962e-3, -0.500e-3] {
        assert!(found.iter().any(|at| (at - side).abs() <= 0.04e-3), "no kink at {side}: {check:#}");
    }
}

/// A backlash's dead band is a step of stiffness at ±w/2 that the backlash already names: the
/// scan runs on the deflection the final model sees, moved by the backlash it accepted. Before,
/// the micro-slip gear with a backlash of 0.3 mrad had it named (0.307 mrad) and steps of +6800
/// and +7300 N·m/rad at ±0.155 mrad named beside it.
#[test]
fn a_backlash_named_is_not_named_again_as_kinks_at_its_edges() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "--physics",
        "micro-slip",
        "--cycles",
        "4",
        "--frequency",
        "0.5",
        "--seed",
        "1",
        "--effect",
        "backlash=0.0003",
    ];
    let json = simulated_and_diagnosed(dir.path(), "backlash.csv", &args);
    assert_eq!(effects_named(&json), ["backlash"], "{:#}", json["findings"]);
    assert!(!json["stiffness_kinks"]["rejected"].is_null(), "{:#}", json["stiffness_kinks"]);
}

/// A known limit, kept from being named by the share a finding must explain. `simulate`'s
/// encoders are quantised without noise and its sine repeats every sample's phase, so the
/// quantisation errors fall at the same deflections every cycle: on the micro-slip gear (a
/// smooth cubic spring) swept to ±1.5 mrad with 20-bit encoders, steps at ±1.22 mrad pass every
/// test of a kink (sharp, alike on both branches) but explain 4.1 % of the smooth spring's
/// residual, under the 5 % asked. With 24-bit encoders or exact angles no step is found.
#[test]
fn an_encoder_artefact_on_a_repeated_sine_is_not_named_a_kink() {
    let dir = tempfile::tempdir().unwrap();
    let args: Vec<&str> =
        "--physics micro-slip --amplitude 0.0015 --cycles 10 --frequency 0.25 --rate 1000 --input-bits 20 --output-bits 20 --seed 3".split(' ').collect();
    let json = simulated_and_diagnosed(dir.path(), "stiffening.csv", &args);
    let check = &json["stiffness_kinks"];
    assert_eq!(check["tested"], "yes", "{check:#}");
    let why = check["rejected"].as_str().unwrap_or_default();
    assert!(why.contains("less than 5 %"), "{check:#}");
}

/// The step a diagnosis' JSON tested for a kink and refused, which dropped the criterion by more
/// than 10: none was named.
fn kink_refused(json: &serde_json::Value) -> serde_json::Value {
    let check = &json["stiffness_kinks"];
    assert_eq!(check["tested"], "yes", "{check:#}");
    assert!(!check["rejected"].is_null(), "{check:#}");
    let refused = check["refused"].clone();
    assert!(refused["delta_bic"].as_f64().unwrap() > 10.0, "{check:#}");
    refused
}

/// On the measured spring no kink is named. Run 3-5 offers a step of +1570 N·m/rad at −1.06 mrad
/// (ΔBIC 127), but its side leaves no room for the same change spread four times as wide, so it
/// cannot be told from a gradual change: the report says so under "cannot be told from this
/// data" (it was refused, which read as "no kink"), and stays finite (an infinite comparison
/// made `diagnose` refuse the whole report).
#[test]
fn a_step_that_cannot_be_told_from_a_gradual_change_is_said_so_and_the_report_stays_finite() {
    let run = repo("data/real/sea-spring-2/kt-3-5-20-2-27022023-172613.csv");
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&["diagnose", &run, "--json"]))).unwrap();
    let check = &json["stiffness_kinks"];
    assert_eq!(check["tested"], "no", "{check:#}");
    assert!(check["why"].as_str().unwrap().contains("cannot be told from a gradual change"), "{check:#}");
}

/// The scan fits a torque offset beside the steps where the search accepted none: without a
/// torque read at rest the form cannot tell one. A genetic gear fitted to the micro-slip gear's
/// sine (its spring piecewise linear in stiffness, 7600 N·m/rad at 0 rising to 13000 at +0.146
/// mrad and falling again), recorded at ±0.8 mrad with 18-bit encoders, had a step of +9060
/// N·m/rad at +0.14 mrad named without it, explaining 9 %; beside an offset that step is refused.
#[test]
fn a_step_is_tested_beside_a_torque_offset_the_form_cannot_tell() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (micro_slip, params, genetic) = (path("micro-slip.csv"), path("genetic.json"), path("genetic.csv"));
    let sine = ["--frequency", "0.5", "--seed", "1"];
    ok(swg_host(
        &[&["simulate", "--physics", "micro-slip", "--cycles", "6", "--out", &micro_slip][..], &sine].concat(),
    ));
    ok(swg_host(&["fit", &micro_slip, "--model", "genetic", "--out", &params]));
    let recording = ["simulate", "--params", &params, "--out", &genetic, "--amplitude", "0.0008", "--cycles", "8"];
    let bits = ["--input-bits", "18", "--output-bits", "18"];
    ok(swg_host(&[&recording[..], &bits, &sine].concat()));
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&["diagnose", &genetic, "--json"]))).unwrap();
    let check = &json["stiffness_kinks"];
    assert_eq!(check["tested"], "yes", "{check:#}");
    assert!(!check["rejected"].is_null(), "{check:#}");
}

/// A kink is a step of the spring's stiffness, the same on the rising and the falling branch.
/// The simulator's micro-slip gear (a smooth cubic spring) recorded with 20-bit encoders, 10
/// cycles at 0.25 and 0.5 Hz, offers a step at −0.67 mrad that fits better sharp than spread
/// (ΔBIC 140): an artefact of the encoders' steps (see the test below), which the branches show
/// differently (χ² 15 lower with a step of its own on the rising branch), so it is refused.
/// Without that test four steps were named, at ±0.67 and ±1.02 mrad, explaining 6 %.
#[test]
fn a_step_that_the_two_branches_show_differently_is_not_a_kink() {
    let dir = tempfile::tempdir().unwrap();
    let args: Vec<&str> =
        "--physics micro-slip --cycles 10 --frequency 0.25,0.5 --rate 1000 --input-bits 20 --output-bits 20 --seed 1"
            .split(' ')
            .collect();
    let refused = kink_refused(&simulated_and_diagnosed(dir.path(), "micro-slip.csv", &args));
    assert!(refused["branches"].as_f64().unwrap() > 10.0, "{refused:#}");
}

/// A torque sensor that clips at the loop's tips reads one value at every turning point: the
/// final model's residual there does not scatter, and the test of drifting loops had 0/0 for
/// its criterion, so the whole diagnosis was refused as "not finite". It is now untested, and
/// says why.
#[test]
fn a_torque_clipped_at_the_tips_leaves_the_drift_untested_and_the_diagnosis_whole() {
    let dir = tempfile::tempdir().unwrap();
    let recording = dir.path().join("clipped.csv");
    let out = recording.to_str().unwrap();
    let simulate = ["simulate", "--physics", "micro-slip", "--out", out, "--cycles", "8", "--frequency", "0.5"];
    ok(swg_host(&[&simulate[..], &["--seed", "1"]].concat()));
    let text = std::fs::read_to_string(&recording).unwrap();
    let peak = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("time_s"))
        .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max);
    let clipped: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with('#') || l.starts_with("time_s") {
                return l.to_string();
            }
            let (head, torque) = l.rsplit_once(',').unwrap();
            let torque: f64 = torque.parse().unwrap();
            format!("{head},{}", torque.clamp(-0.8 * peak, 0.8 * peak))
        })
        .collect();
    std::fs::write(&recording, clipped.join("\n") + "\n").unwrap();
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&["diagnose", out, "--json"]))).unwrap();
    assert_eq!(json["ratcheting"]["tested"], "no", "{:#}", json["ratcheting"]);
    assert!(json["ratcheting"]["why"].as_str().unwrap().contains("same at every turning point"));
}

/// A backlash that the genetic form refused for explaining too little of its misfit (1.0 % of it
/// on OpenSees' catalogue spring, 20 µrad concealed) is tried on the micro-slip form where that
/// form is named, and named there with its width; the final model is the form on the deflection
/// the backlash moves. The same gear without one has none named.
#[test]
fn a_backlash_the_genetic_forms_misfit_hid_is_found_on_the_form() {
    let dir = tempfile::tempdir().unwrap();
    let gear = ["--physics", "catalogue", "--frequency", "0.2,0.6", "--cycles", "3", "--seed", "5"];
    let bits = ["--input-bits", "20", "--output-bits", "20"];
    let with =
        simulated_and_diagnosed(dir.path(), "with", &[&gear[..], &bits[..], &["--effect", "backlash=2e-5"]].concat());
    let backlash = with["findings"].as_array().unwrap().iter().find(|f| f["effect"] == "backlash");
    let backlash = backlash.unwrap_or_else(|| panic!("no backlash named: {:#}", with["rejected"]));
    let width = backlash["magnitude"].as_f64().unwrap();
    assert!((width - 2e-5).abs() <= 0.15 * 2e-5, "width {width} rad against 2e-5 concealed");
    assert!(backlash["where"].as_str().unwrap().contains("micro-slip form"), "{backlash:#}");
    assert_eq!(with["final"]["form"], "micro-slip", "{:#}", with["final"]);
    let without = simulated_and_diagnosed(dir.path(), "without", &[&gear[..], &bits[..]].concat());
    assert!(!effects_named(&without).contains(&"backlash".to_string()), "{:#}", without["findings"]);
}

/// Behind a dead band the gear does not move, so its torque holds across the band; a spring
/// soft about zero moves there. The catalogue gear's first segment (14000 N·m/rad to ±0.5 mrad)
/// under nested motion was taken for a dead band: 24 µrad named on the form at 1.5 mrad, and
/// 100 µrad named on the genetic form at 2 mrad and kept beside the form. Inside those bands the
/// torque's slope is the one just beyond them (a new user's trial): neither is named now.
#[test]
fn a_spring_soft_about_zero_is_not_taken_for_a_dead_band() {
    let dir = tempfile::tempdir().unwrap();
    let nested = ["--physics", "catalogue", "--motion", "nested", "--frequency", "0.2,0.6", "--cycles", "4"];
    let bits = ["--input-bits", "20", "--output-bits", "20", "--seed", "1"];
    for amplitude in ["0.0015", "0.002"] {
        let json =
            simulated_and_diagnosed(dir.path(), amplitude, &[&nested[..], &bits, &["--amplitude", amplitude]].concat());
        assert!(!effects_named(&json).contains(&"backlash".to_string()), "{amplitude}: {:#}", json["findings"]);
        let backlash = json["rejected"].as_array().unwrap().iter().find(|r| r["effect"] == "backlash").unwrap();
        assert!(backlash["reason"].as_str().unwrap().contains("the gear moves inside it"), "{backlash:#}");
    }
}

/// The search on the genetic form asks a backlash for a flat torque inside its band too. The
/// catalogue gear at 3 mrad under nested motion, a 20 µrad dead band and a 2 ms channel delay
/// concealed, had 401 µrad named there beside an offset of −0.65 N·m it lacks, its first segment
/// moving inside that band as stiff as beyond it; now the form is named with the delay.
#[test]
fn a_dead_band_wider_than_the_torque_holds_is_refused_on_the_genetic_form_too() {
    let dir = tempfile::tempdir().unwrap();
    let gear = ["--physics", "catalogue", "--amplitude", "0.003", "--motion", "nested", "--frequency", "1"];
    let effects = ["--effect", "backlash=2e-05", "--effect", "channel_delay=0.002", "--cycles", "6", "--seed", "33"];
    let json = simulated_and_diagnosed(dir.path(), "nested.csv", &[&gear[..], &effects].concat());
    assert_eq!(effects_named(&json), ["channel_delay"], "{:#}", json["findings"]);
    let delay = json["findings"][0]["magnitude"].as_f64().unwrap();
    assert!((delay - 0.002).abs() <= 0.1 * 0.002, "delay {delay} s against 0.002 concealed");
    let backlash = json["rejected"].as_array().unwrap().iter().find(|r| r["effect"] == "backlash").unwrap();
    assert!(backlash["reason"].as_str().unwrap().contains("the gear moves inside it"), "{backlash:#}");
}

/// A trial whose column the data cannot determine (here a backlash fitted wider than the motion,
/// which leaves its column zero) has an unbounded standard error, so no evidence: rounding left
/// its error zero, its z infinite, and the whole report was refused as "not finite" (the
/// simulator's genetic gear under random motion, `bash bench/kinks.sh`).
#[test]
fn an_effect_the_data_cannot_determine_has_no_evidence_and_the_report_stands() {
    let dir = tempfile::tempdir().unwrap();
    let recording = dir.path().join("random.csv");
    let out = recording.to_str().unwrap();
    let bits = ["--input-bits", "20", "--output-bits", "20", "--seed", "3", "--cycles", "6"];
    let motion = ["simulate", "--out", out, "--amplitude", "0.0015", "--motion", "random"];
    ok(swg_host(&[&motion[..], &bits[..]].concat()));
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&["diagnose", out, "--json"]))).unwrap();
    let backlash = json["rejected"].as_array().unwrap().iter().find(|r| r["effect"] == "backlash").unwrap();
    assert_eq!(backlash["evidence"]["z"], 0.0, "{backlash:#}");
}

/// The effects a diagnosis' JSON says cannot be told from its data, with why.
fn untellable(json: &serde_json::Value) -> Vec<(String, String)> {
    let entries = json["not_revealable"].as_array().unwrap().iter();
    entries.map(|r| (r["effect"].as_str().unwrap().to_string(), r["why"].as_str().unwrap().to_string())).collect()
}

/// Coulomb friction on the micro-slip form is a slip element of no width, which the form's
/// narrowest elements follow: where the genetic form's search did not name it, the report says it
/// cannot be told, and neither refuses it (which read as "no friction": OpenSees' Iwan and
/// catalogue springs with 0.1 N·m of friction concealed were refused so, as standing in for the
/// loop's shape) nor lists it as revealable. Where the genetic search names a friction the form
/// keeps, it is named (OpenSees' Bouc–Wen material with 0.1 N·m, `bash bench/opensees/run.sh`).
#[test]
fn friction_on_the_micro_slip_form_is_said_to_be_untellable_not_refused() {
    let friction = 0.1;
    let json = opensees_diagnosed("iwan-viscous_damping.csv", |rows| {
        // The deflection θ_in/50 − θ_out (the recording's ratio), along which friction opposes.
        let deflection: Vec<f64> = rows.iter().map(|r| r[1] / 50.0 - r[2]).collect();
        // Its sign over ±2 samples, held where the encoders read no change.
        let mut sign = 1.0;
        let mut with = rows.clone();
        for k in 0..rows.len() {
            let change = deflection[(k + 2).min(rows.len() - 1)] - deflection[k.saturating_sub(2)];
            if change != 0.0 {
                sign = change.signum();
            }
            with[k][3] += friction * sign;
        }
        with
    });
    assert!(json["model_form"].is_object(), "{:#}", json["model_form"]);
    assert!(!effects_named(&json).contains(&"coulomb_friction".to_string()), "{:#}", json["findings"]);
    let why = untellable(&json).into_iter().find(|(effect, _)| effect == "coulomb_friction").map(|(_, why)| why);
    assert!(why.as_ref().is_some_and(|why| why.contains("slip element of no width")), "{why:?}");
    assert!(!json["rejected"].as_array().unwrap().iter().any(|r| r["effect"] == "coulomb_friction"));
    assert!(!json["revealable"].as_array().unwrap().iter().any(|e| e == "coulomb_friction"));
}

/// The measured spring's runs read their deflection's zero at rest: the three 1 A runs read one
/// zero (−8.42 mrad, within a few µrad of one another), and with a 3 A run recorded after the
/// first −4 N·m excursion the zero has moved (−8.97 mrad, `data/real/README.md`): the report says
/// it moves, and pools nothing.
#[test]
fn several_measured_runs_read_one_deflection_zero_until_a_large_loop_moves_it() {
    let run = |name: &str| repo(&format!("data/real/sea-spring-2/{name}"));
    let small =
        ["kt-1-4-13-2-27022023-171453.csv", "kt-1-5-14-2-27022023-171936.csv", "kt-1-6-15-2-27022023-172030.csv"];
    let paths: Vec<String> = small.iter().map(|n| run(n)).collect();
    let args: Vec<&str> = ["diagnose", "--json"].into_iter().chain(paths.iter().map(String::as_str)).collect();
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&args))).unwrap();
    assert_eq!(json["runs"].as_array().unwrap().len(), 3);
    let zero = &json["across"]["zero"];
    assert_eq!(zero["one_zero"], true, "{zero:#}");
    let pooled = zero["pooled"][0].as_f64().unwrap();
    assert!((pooled + 8.422e-3).abs() < 1e-5, "{zero:#}");

    let later = run("kt-3-5-20-2-27022023-172613.csv");
    let args: Vec<&str> = args.into_iter().chain([later.as_str()]).collect();
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&args))).unwrap();
    let zero = &json["across"]["zero"];
    assert_eq!(zero["one_zero"], false, "{zero:#}");
    assert!(zero["pooled"].is_null() && (zero["range"][0].as_f64().unwrap() + 8.97e-3).abs() < 1e-5, "{zero:#}");
    let text = ok(swg_host(&args[..1].iter().chain(&args[2..]).copied().collect::<Vec<_>>()));
    assert!(text.contains("run 4: ") && text.contains("deflection zero: moves between the 4 runs"), "{text}");
}

/// Runs that read one zero share their encoders' rounding: 4 runs of a gear zeroed 3 µrad off,
/// in 20-bit angles (a step of 6 µrad), each read 6.0 ± 1.7 µrad at rest. Pooled as if their
/// errors were independent (± 0.9 µrad) they named an encoder zero twice the true one, 3.5 of
/// its errors away; the pooled zero keeps the best run's error, and the truth is within it.
#[test]
fn runs_that_read_one_zero_pool_it_no_finer_than_their_encoders_round_it() {
    let dir = tempfile::tempdir().unwrap();
    let motion = rest_then_sine(dir.path(), 1e-3);
    let runs: Vec<String> = (1..=4)
        .map(|seed| {
            let recording = dir.path().join(format!("run-{seed}.csv")).display().to_string();
            let (motion, seed) = (motion.to_str().unwrap(), seed.to_string());
            let encoders = ["--output-bits", "20", "--input-bits", "20", "--torque-noise", "0.03", "--seed", &seed];
            let gear = ["--physics", "micro-slip", "--motion", motion, "--deflection-zero", "3e-6"];
            ok(swg_host(&[&["simulate", "--out", &recording][..], &gear, &encoders].concat()));
            recording
        })
        .collect();
    let runs: Vec<&str> = runs.iter().map(String::as_str).collect();
    let zero = diagnosed_together(&runs)["across"]["zero"].clone();
    assert_eq!(zero["one_zero"], true, "{zero:#}");
    let [mean, error] = [0, 1].map(|k| zero["pooled"][k].as_f64().unwrap());
    let each = zero["runs"][0][1].as_f64().unwrap();
    assert!(error >= each, "pooled ± {error} rad, finer than one run's ± {each} rad");
    assert!((mean - 3e-6).abs() <= 3.0 * error, "pooled {mean} ± {error} rad against 3e-6");
}

/// A `--motion` file in `dir`: three cycles of a 0.25 Hz sine of 1 mrad that starts mid-motion.
fn mid_motion(dir: &std::path::Path) -> std::path::PathBuf {
    let rows: String = (0..=12_000)
        .map(|k| {
            let t = f64::from(k) / 1000.0;
            format!("{t:.3},{:.9e}\n", 1e-3 * (std::f64::consts::TAU * 0.25 * t + 1.0).sin())
        })
        .collect();
    let motion = dir.join("mid-motion.csv");
    std::fs::write(&motion, format!("time_s,deflection_rad\n{rows}")).unwrap();
    motion
}

/// A recording that starts mid-motion, its encoders zeroed 0.5 mrad off a 1 mrad loop of the
/// micro-slip gear: the symmetric baseline was fitted about the encoders' zero, and a damping of
/// −1846 N·m·s/rad was named that the gear does not have. Its zero is now fitted, as `fit`
/// places such a run, and nothing is named.
#[test]
fn a_recording_off_its_zero_without_a_rest_is_measured_from_a_fitted_zero() {
    let dir = tempfile::tempdir().unwrap();
    let motion = mid_motion(dir.path());
    let recording = dir.path().join("off.csv").display().to_string();
    let gear = ["--physics", "micro-slip", "--motion", motion.to_str().unwrap(), "--seed", "8"];
    ok(swg_host(&[&["simulate", "--out", &recording, "--deflection-zero", "5e-4"][..], &gear].concat()));
    let json: serde_json::Value = serde_json::from_str(&ok(swg_host(&["diagnose", &recording, "--json"]))).unwrap();
    let origin = &json["origin"];
    assert_eq!(origin["source"], "fitted", "{origin:#}");
    let (zero, error) = (origin["zero_rad"].as_f64().unwrap(), origin["zero_se_rad"].as_f64().unwrap());
    assert!((zero - 5e-4).abs() <= error.max(1e-5), "θ0 {zero} ± {error} rad of 5e-4");
    assert!(effects_named(&json).is_empty(), "{:#}", json["findings"]);
}

/// Runs that start mid-motion read no zero: the text says so and what to record, rather than
/// leaving the zero out of what the runs show together.
#[test]
fn runs_without_a_rest_say_that_no_zero_was_read() {
    let dir = tempfile::tempdir().unwrap();
    let motion = mid_motion(dir.path());
    let runs: Vec<String> = ["3", "4"]
        .iter()
        .map(|seed| {
            let recording = dir.path().join(format!("run-{seed}.csv")).display().to_string();
            let gear = ["--physics", "micro-slip", "--motion", motion.to_str().unwrap(), "--seed", seed];
            ok(swg_host(&[&["simulate", "--out", &recording, "--torque-noise", "0.03"][..], &gear].concat()));
            recording
        })
        .collect();
    let text = ok(swg_host(&["diagnose", &runs[0], &runs[1]]));
    assert!(text.contains("deflection zero: not read: no run starts at rest"), "{text}");
    assert!(diagnosed_together(&[&runs[0], &runs[1]])["across"]["zero"].is_null());
}

/// The measured spring's run 5-3: the genetic baseline misses by 0.95 N·m, and the micro-slip
/// form fits it to 0.20. Judged against the noise the genetic loop's stiffness implies (infinite
/// at its tips: 3.50 N·m RMS) that passed for noise and the report said "no missing physics
/// found"; against the form's (0.067 N·m) the misfit is 14× the noise, and the form, which
/// predicts the held-out leg better, is named. On 4-6 the form fits better but predicts the
/// held-out leg worse: structure remains, and the report says why.
#[test]
fn a_misfit_far_beyond_the_noise_is_not_taken_for_noise() {
    let diagnosed = |run: &str| -> serde_json::Value {
        let run = repo(&format!("data/real/sea-spring-2/{run}"));
        serde_json::from_str(&ok(swg_host(&["diagnose", &run, "--json"]))).unwrap()
    };
    let form = &diagnosed("kt-5-3-27-2-27022023-173634.csv")["model_form"];
    let (misfit, noise) = (form["rms_before"].as_f64().unwrap_or(0.0), form["noise_rms"].as_f64().unwrap_or(1.0));
    assert!(misfit > 10.0 * noise && noise < 0.1, "{form:#}");
    let unexplained = &diagnosed("kt-4-6-24-2-27022023-173150.csv")["unexplained"];
    let (rms, noise) = (unexplained["rms"].as_f64().unwrap_or(0.0), unexplained["noise_rms"].as_f64().unwrap_or(1.0));
    assert!(rms > 4.0 * noise && noise < 0.1, "{unexplained:#}");
    assert!(unexplained["words"].as_str().unwrap().contains("predicts the held-out samples worse"), "{unexplained:#}");
}

/// Simulates `gear` (JSON) along `args` into `dir/name`; the recording's path.
fn simulated(dir: &std::path::Path, name: &str, gear: &str, args: &[&str]) -> String {
    let params = dir.join(format!("{name}.json"));
    std::fs::write(&params, gear).unwrap();
    let recording = dir.join(name).display().to_string();
    ok(swg_host(&[&["simulate", "--params", params.to_str().unwrap(), "--out", &recording][..], args].concat()));
    recording
}

/// `diagnose --json` of several runs.
fn diagnosed_together(runs: &[&str]) -> serde_json::Value {
    serde_json::from_str(&ok(swg_host(&[&["diagnose", "--json"][..], runs].concat()))).unwrap()
}

/// An effect named in several runs is pooled where the runs read one magnitude (a torque offset
/// of 0.2 N·m in two runs of independent noise), and said to disagree where they do not (a third
/// run reads 0.6 N·m): the runs are independent parts, judged by the rule the halves of one run
/// follow.
#[test]
fn an_effect_named_in_several_runs_is_pooled_where_they_agree_and_not_where_they_differ() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, offset: f64, seed: &str| {
        let effect = format!("torque_offset={offset}");
        let noise = ["--output-bits", "20", "--input-bits", "20", "--torque-noise", "0.03", "--seed", seed];
        let motion = ["--cycles", "3", "--frequency", "0.2,0.6", "--effect", &effect];
        simulated(dir.path(), name, GEAR, &[&motion[..], &noise].concat())
    };
    let (a, b, c) = (run("a.csv", 0.2, "1"), run("b.csv", 0.2, "2"), run("c.csv", 0.6, "3"));
    let offset = |json: &serde_json::Value| -> serde_json::Value {
        let effects = json["across"]["effects"].as_array().unwrap();
        effects.iter().find(|e| e["effect"] == "torque_offset").cloned().unwrap_or_default()
    };
    let json = diagnosed_together(&[&a, &b]);
    let both = offset(&json);
    assert_eq!((both["named_in"].as_u64(), &both["agree"]), (Some(2), &serde_json::json!(true)), "{both:#}");
    let pooled = both["pooled"][0].as_f64().unwrap();
    assert!((pooled - 0.2).abs() < 0.02, "pooled {pooled} N·m of 0.2");
    // The text gives the unit once, after the pooled figure.
    let text = ok(swg_host(&["diagnose", &a, &b]));
    let line = text.lines().find(|l| l.contains("torque_offset: named in 2 of 2")).unwrap_or_default();
    assert!(line.contains(" N·m (run 1: named") && line.matches("N·m").count() == 1, "{text}");

    let all = offset(&diagnosed_together(&[&a, &b, &c]));
    assert_eq!((all["named_in"].as_u64(), &all["agree"]), (Some(3), &serde_json::json!(false)), "{all:#}");
    assert!(all["pooled"].is_null(), "{all:#}");
}

/// A run of one cycle cannot check an asymmetry on its own parts (each a leg, one side of the
/// loop), as the measured spring's runs are recorded: two such runs are the parts. The gear
/// whose + side is 15 % softer is named asymmetric across two runs of independent noise, with
/// the mean of their magnitudes; the symmetric gear is not.
#[test]
fn runs_of_one_cycle_each_check_an_asymmetry_that_no_one_of_them_can() {
    let dir = tempfile::tempdir().unwrap();
    let motion = rest_then_cycles(dir.path(), 1.168e-3, 1);
    let pair = |gear: &str, name: &str| -> serde_json::Value {
        let runs: Vec<String> = ["1", "2"]
            .iter()
            .map(|seed| {
                let args = ["--motion", motion.to_str().unwrap(), "--torque-noise", "0.03", "--seed", seed];
                simulated(dir.path(), &format!("{name}-{seed}.csv"), gear, &args)
            })
            .collect();
        diagnosed_together(&runs.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let asymmetric = pair(&sided_gear(0.85, 1.15), "asymmetric");
    for run in asymmetric["runs"].as_array().unwrap() {
        let alone = run["asymmetry"]["rejected"].as_str().unwrap_or_default();
        assert!(alone.contains("do not each reach both sides"), "{alone}");
    }
    let across = &asymmetric["across"]["asymmetry"];
    assert_eq!(across["named"], true, "{across:#}");
    let magnitude = across["magnitude"].as_f64().unwrap();
    assert!((-0.4..-0.2).contains(&magnitude), "{across:#}");

    let symmetric = pair(&sided_gear(1.0, 1.0), "symmetric");
    assert_eq!(symmetric["across"]["asymmetry"]["named"], false, "{:#}", symmetric["across"]["asymmetry"]);
}

/// Runs are diagnosed together only where they can be: a loop table is one loop, a run given
/// twice would agree with itself, and a run that cannot be read is named; nothing is written.
#[test]
fn several_runs_are_checked_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("plots");
    let plot = plots.to_str().unwrap();
    let recording = repo("data/real/sea-spring-2/kt-1-4-13-2-27022023-171453.csv");
    let table = repo("data/seed/lht-20-50.csv");
    let broken = dir.path().join("broken.csv");
    std::fs::write(&broken, "# swg-recording v1\ntime_s,deflection_rad,torque_nm\n0,0,0\n0.01,x,0\n").unwrap();
    let copy = dir.path().join("copy.csv");
    std::fs::copy(&recording, &copy).unwrap();
    let cases = [
        (table.as_str(), "a loop table is one loop"),
        (broken.to_str().unwrap(), "broken.csv"),
        (recording.as_str(), "given twice (runs 1 and 2)"),
        (copy.to_str().unwrap(), "the same recording as"),
    ];
    for (second, expected) in cases {
        let output = swg_host(&["diagnose", &recording, second, "--plot", plot]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success() && stderr.contains(expected), "{stderr}");
        assert!(!plots.exists());
    }
    // A file given as the pictures' directory is refused before the diagnosis, untouched.
    let output = swg_host(&["diagnose", &recording, "--plot", broken.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && stderr.contains("--plot takes a directory"), "{stderr}");
    assert!(std::fs::read_to_string(&broken).unwrap().ends_with("0.01,x,0\n"));
}

/// Masing's rule across runs, what "record several amplitudes" asks for: the Preisach gear
/// (loops that depend on where they sit) run at three amplitudes, twice each, breaks it, and the
/// micro-slip gear (Masing by construction) does not. Each run alone is one loop, which cannot
/// show it; one run at each amplitude cannot check it on two independent parts, and says which
/// runs would.
#[test]
fn runs_at_several_amplitudes_test_masings_rule_that_no_one_of_them_can() {
    let dir = tempfile::tempdir().unwrap();
    let runs = |physics: &str, seeds: &[&str]| -> Vec<String> {
        let mut paths = Vec::new();
        for amplitude in ["0.4e-3", "0.8e-3", "1.2e-3"] {
            for seed in seeds {
                let recording = dir.path().join(format!("{physics}-{amplitude}-{seed}.csv")).display().to_string();
                let noise = ["--output-bits", "20", "--input-bits", "20", "--torque-noise", "0.03", "--seed", seed];
                let motion = ["--physics", physics, "--amplitude", amplitude, "--cycles", "3", "--frequency", "0.5"];
                ok(swg_host(&[&["simulate", "--out", &recording][..], &motion, &noise].concat()));
                paths.push(recording);
            }
        }
        paths
    };
    let masing = |paths: &[String]| -> serde_json::Value {
        let json = diagnosed_together(&paths.iter().map(String::as_str).collect::<Vec<_>>());
        for run in json["runs"].as_array().unwrap() {
            assert_eq!(run["non_masing"]["tested"], "no", "one loop alone: {:#}", run["non_masing"]);
        }
        json["across"]["non_masing"].clone()
    };
    let preisach = masing(&runs("preisach", &["1", "2"]));
    assert_eq!((&preisach["tested"], &preisach["rejected"]), (&"yes".into(), &serde_json::Value::Null), "{preisach:#}");
    let [masing_held, free_held] = [0, 1].map(|k| preisach["held_out_rms"][k].as_f64().unwrap());
    assert!(free_held < masing_held && preisach["explained"].as_f64().unwrap() > 0.1, "{preisach:#}");

    let micro_slip = masing(&runs("micro-slip", &["1", "2"]));
    assert!(micro_slip["rejected"].is_string() && micro_slip["delta_bic"].as_f64().unwrap() < 0.0, "{micro_slip:#}");

    let once = masing(&runs("preisach", &["3"]));
    let why = once["rejected"].as_str().unwrap_or_default();
    assert!(why.contains("record each amplitude twice"), "{once:#}");
}

/// A rate effect across runs at different rates, what "record the same loop at a second rate"
/// asks for: each run at one rate cannot tell a damping from the hysteresis, and says so; the
/// micro-slip gear with 25 N·m·s/rad of damping run at 0.1 Hz and at 0.4 Hz names it across the
/// runs, with its magnitude; without damping, nothing is named; two runs at one rate cannot
/// test it, and say which runs would.
#[test]
fn runs_at_different_rates_tell_a_damping_that_no_one_of_them_can() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, frequency: &str, effect: &[&str]| -> String {
        let recording = dir.path().join(name).display().to_string();
        let noise = ["--output-bits", "20", "--input-bits", "20", "--torque-noise", "0.03", "--seed", "4"];
        let motion = ["--physics", "micro-slip", "--cycles", "3", "--frequency", frequency];
        ok(swg_host(&[&["simulate", "--out", &recording][..], &motion, &noise, effect].concat()));
        recording
    };
    let damping = ["--effect", "viscous_damping=25"];
    let (slow, fast) = (run("slow.csv", "0.1", &damping), run("fast.csv", "0.4", &damping));
    let json = diagnosed_together(&[&slow, &fast]);
    for alone in json["runs"].as_array().unwrap() {
        let cannot = untellable(alone);
        assert!(cannot.iter().any(|(e, why)| e == "viscous_damping" && why.contains("second rate")), "{cannot:?}");
    }
    let rate = &json["across"]["rate"];
    assert_eq!((&rate["verdict"], &rate["effect"]), (&"named".into(), &"viscous_damping".into()), "{rate:#}");
    let magnitude = rate["magnitude"].as_f64().unwrap();
    assert!((magnitude - 25.0).abs() < 2.5, "{magnitude} N·m·s/rad of 25");

    let (slow, fast) = (run("slow-none.csv", "0.1", &[]), run("fast-none.csv", "0.4", &[]));
    let rate = diagnosed_together(&[&slow, &fast])["across"]["rate"].clone();
    assert_eq!(rate["verdict"], "refused", "{rate:#}");

    let again = run("fast-again.csv", "0.4", &damping);
    let rate = diagnosed_together(&[&fast, &again])["across"]["rate"].clone();
    assert_eq!(rate["verdict"], "untested", "{rate:#}");
    assert!(rate["why"].as_str().unwrap().contains("twice the frequency"), "{rate:#}");
}

/// The form is judged on the held-out samples against the genetic model with its effects, so it
/// is fitted there with the same effects' columns. Fitted without them, the micro-slip form of a
/// micro-slip gear with a 2 ms delay held out 0.193 N·m against the genetic model's 0.143 with
/// the delay; the form was not named, and on the genetic form a torque offset of 0.27 N·m, which
/// the gear lacks, leaned on the misfit beside the delay.
#[test]
fn the_form_is_held_out_with_the_effects_the_genetic_model_is_held_out_with() {
    let dir = tempfile::tempdir().unwrap();
    let json = simulated_and_diagnosed(
        dir.path(),
        "delayed.csv",
        &["--physics", "micro-slip", "--effect", "channel_delay=2e-3", "--frequency", "0.5,2"],
    );
    assert_eq!(json["model_form"]["model"], "micro-slip", "{:#}", json["model_form"]);
    assert_eq!(effects_named(&json), ["channel_delay"], "{:#}", json["findings"]);
    let delay = json["findings"][0]["magnitude"].as_f64().unwrap();
    assert!((delay - 2e-3).abs() <= 0.1 * 2e-3, "delay {delay} s against 2 ms");
}

/// On a catalogue gear (three stiffness segments, the softest about zero) a backlash of 73 µrad
/// stood in for the soft segment that the form's free spring takes, and was named beside the
/// form. The form's re-test then withdrew it ("stands in for the loop's shape"); now the genetic
/// search refuses it already, the torque inside that band moving as stiffly as beyond it, and
/// so does the search on the form.
#[test]
fn a_soft_first_segment_is_not_taken_for_backlash() {
    let dir = tempfile::tempdir().unwrap();
    let json = simulated_and_diagnosed(
        dir.path(),
        "catalogue.csv",
        &["--physics", "catalogue", "--frequency", "0.25,1", "--amplitude", "2e-3"],
    );
    assert_eq!(json["model_form"]["model"], "micro-slip", "{:#}", json["model_form"]);
    assert!(effects_named(&json).is_empty(), "{:#}", json["findings"]);
    let refused = json["rejected"].as_array().unwrap().iter().find(|r| r["effect"] == "backlash");
    assert!(
        refused.is_some_and(|r| r["reason"].as_str().unwrap().contains("the gear moves inside it")),
        "{:#}",
        json["rejected"]
    );
}

/// `simulate`'s default gear, the paper's published parameters, runs its loop the active way:
/// the report names that cause beside a bench's (it read "the measurement, not the gear"), and a
/// diagnosis of several runs says which run is active (its summary line said only "no effect
/// named").
#[test]
fn an_active_loop_is_said_with_its_causes_alone_and_among_runs() {
    let dir = tempfile::tempdir().unwrap();
    let (active, passive) = (dir.path().join("seed.csv"), dir.path().join("slip.csv"));
    let (active, passive) = (active.to_str().unwrap(), passive.to_str().unwrap());
    ok(swg_host(&["simulate", "--out", active]));
    ok(swg_host(&["simulate", "--physics", "micro-slip", "--out", passive]));
    let alone = ok(swg_host(&["diagnose", active]));
    assert!(alone.contains("active loop") && alone.contains("the paper's published parameters"), "{alone}");
    let together = ok(swg_host(&["diagnose", passive, active]));
    let lines: Vec<&str> = together.lines().filter(|l| l.contains("active loop")).collect();
    assert_eq!(lines.len(), 1, "{together}");
    assert!(
        together.lines().skip_while(|l| !l.starts_with("run 2")).nth(1).is_some_and(|l| l.contains("active loop")),
        "{together}"
    );
}

/// An effect named on the genetic form that a later finding on the form makes redundant is
/// withdrawn: on random motion of a micro-slip gear with a 2 ms delay, a Coulomb friction took
/// the delay's torque on the genetic form, and stayed named at 7.5·10⁻⁴ N·m beside the delay
/// the search on the form then found.
#[test]
fn an_effect_a_later_finding_on_the_form_makes_redundant_is_withdrawn() {
    let dir = tempfile::tempdir().unwrap();
    let json = simulated_and_diagnosed(
        dir.path(),
        "random.csv",
        &["--physics", "micro-slip", "--motion", "random", "--effect", "channel_delay=2e-3"],
    );
    assert_eq!(effects_named(&json), ["channel_delay"], "{:#}", json["findings"]);
    let friction = json["rejected"].as_array().unwrap().iter().find(|r| r["effect"] == "coulomb_friction");
    assert!(
        friction.is_some_and(|r| r["reason"].as_str().unwrap().contains("stands in for channel_delay")),
        "{:#}",
        json["rejected"]
    );
}

/// A micro-slip gear with 40 N·m·s/rad of damping under the nested motion at three rates,
/// recorded mid-motion (its first 1.3 s cut, as a logger started late would). The genetic form
/// names a friction of 0.25 N·m for the loop's shape; beside the damping named on the micro-slip
/// form it is left at 0.008 N·m, still significant (ΔBIC 103 over 12 000 samples) but 0.4 % of
/// the form's residual, and withdrawn as any effect that explains less than 5 % is (a new user's
/// trial: it was named).
#[test]
fn a_friction_the_form_leaves_at_a_trace_beside_its_damping_is_withdrawn() {
    let dir = tempfile::tempdir().unwrap();
    let full = dir.path().join("full.csv");
    let args = ["--physics", "micro-slip", "--motion", "nested", "--frequency", "0.25,0.5,1"];
    let encoders = ["--effect", "viscous_damping=40", "--input-bits", "20", "--output-bits", "20"];
    ok(swg_host(&[&["simulate", "--out", full.to_str().unwrap()][..], &args, &encoders].concat()));
    let cut: String = std::fs::read_to_string(&full)
        .unwrap()
        .lines()
        .filter(|line| {
            if line.starts_with('#') {
                return !line.starts_with("# start:");
            }
            line.starts_with("time_s") || line.split(',').next().unwrap().parse::<f64>().unwrap() >= 1.3 - 1e-12
        })
        .map(|line| format!("{line}\n"))
        .collect();
    let recording = dir.path().join("cut.csv");
    std::fs::write(&recording, cut).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&ok(swg_host(&["diagnose", recording.to_str().unwrap(), "--json"]))).unwrap();
    assert!(json["start_state_samples"].as_u64().unwrap() > 0, "{json:#}");
    assert_eq!(effects_named(&json), ["viscous_damping"], "{:#}", json["rejected"]);
    let rejected = json["rejected"].as_array().unwrap();
    let friction = rejected.iter().find(|r| r["effect"] == "coulomb_friction").expect("friction refused");
    assert!(friction["reason"].as_str().unwrap().contains("stands in for viscous_damping"), "{friction:#}");
}

/// A thermal drift found on the micro-slip form gives its halves in its own unit, 1/K, as its
/// magnitude: they were the column's raw coefficients (N·m/(rad·K)), thousands of times it.
#[test]
fn a_thermal_drift_found_on_the_form_gives_its_halves_in_its_unit() {
    let dir = tempfile::tempdir().unwrap();
    let args =
        ["--motion", "plan", "--effect", "thermal_drift=0.005", "--temperature", "25", "--temperature-rise", "1"];
    let json = micro_slip_diagnosed(dir.path(), "warming.csv", &args);
    let finding = json["findings"].as_array().unwrap().iter().find(|f| f["effect"] == "thermal_drift").unwrap();
    let magnitude = finding["magnitude"].as_f64().unwrap();
    for half in finding["evidence"]["halves"].as_array().unwrap() {
        let half = half.as_f64().unwrap();
        assert!((half / magnitude - 1.0).abs() < 0.2, "half {half} against {magnitude}: {finding:#}");
    }
}
