//! The workflow from the joint's own recording, end to end: the joint firmware on the emulated
//! Cortex-M4F (QEMU mps2-an386) plays an identification plan in lockstep with the host's
//! simulated joint (the simulator's micro-slip gear, its output clamped, a torque sensor with
//! 0.05 N·m of noise and a 0.3 N·m offset), and `record`, `fit`, `predict`, `diagnose`, `push`
//! and `hil` run on what it streamed. Needs `qemu-system-arm` and the firmware ELF, so the test
//! is ignored by a plain `cargo test`; `scripts/test-firmware.sh` runs it.
mod common;
mod qemu;

use common::{json, ok, repo, swg_host_echoed as swg_host};
use qemu::Qemu;
use swg_host::input::{read, Dataset, Recording};
use swg_host::simulate::{MicroSlip, Physics};

/// The simulated sensor's offset and noise (`record`'s defaults).
const OFFSET_NM: f64 = 0.3;
const NOISE_NM: f64 = 0.05;

/// RMS of the recorded torque against the truth physics run along the recorded deflection,
/// less the sensor's offset: what the sensor's noise and the encoders' counts leave, the floor
/// any model has on this recording.
fn truth_floor(recording: &Recording) -> f64 {
    let mut gear = Physics::MicroSlip(MicroSlip::default()).gear().unwrap().unwrap();
    let squares: f64 = recording
        .deflection
        .iter()
        .zip(&recording.torque)
        .map(|(&theta, &torque)| (torque - OFFSET_NM - gear.step(theta)).powi(2))
        .sum();
    (squares / recording.torque.len() as f64).sqrt()
}

fn recording(path: &std::path::Path) -> Recording {
    match read(path, None).unwrap() {
        Dataset::Recording(recording) => recording,
        Dataset::LoopTable(_) => panic!("{} is not a recording", path.display()),
    }
}

#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn record_then_fit_predict_diagnose_push_and_hil() {
    let mut qemu = Qemu::boot();
    drop(qemu.ready_link());
    let port = qemu.address();
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let (rec, fit, other_rec, plan) = (path("rec.csv"), path("fit.json"), path("other.csv"), path("plan.json"));
    let seed = repo("data/seed/lht-20-50-fit.json");
    let joint = ["--port", &port, "--params", &seed, "--ratio", "50", "--simulated-joint", "micro-slip"];

    // The default plan at 2 Hz and 8 Hz, amplitudes 0.25, 0.5 and 1 mrad: 7.6 s.
    let text =
        ok(swg_host(&[&["record", "--out", &rec, "--amplitude", "1e-3", "--frequency", "2"], &joint[..]].concat()));
    assert!(text.contains("recorded 7626 samples (7.6 s at 1000 Hz)") && text.contains("0 samples lost"), "{text}");
    let recorded = recording(dir.path().join("rec.csv").as_path());
    assert!(recorded.starts_at_rest());
    assert_eq!(recorded.time.len(), 7626);
    // The recording is the truth within the sensor's noise and the encoders' counts (the
    // encoders floor the angles: the deflection read is up to one count, 1 µrad at N = 50, off
    // the true one, up to 0.02 N·m at 20 kN·m/rad; 0.067 N·m in all when this was written).
    let floor = truth_floor(&recorded);
    assert!(floor > 0.9 * NOISE_NM && floor < 1.5 * NOISE_NM, "{floor}");
    let temperature = recorded.temperature.as_ref().unwrap();
    assert!(temperature.last().unwrap() > temperature.first().unwrap(), "the motor's losses warm it");

    // The fit reads the sensor's offset at rest and chooses the micro-slip kind.
    let report = json(&swg_host(&["fit", &rec, "--out", &fit, "--json"]));
    let chosen = report["model"].as_str().unwrap_or_default().to_owned();
    assert_eq!(chosen, "micro-slip", "{report}");

    // Another motion of the same joint: a biased oscillation, predicted from the fit within
    // 1.3× the truth's floor on the same recorded angles.
    let plan_text = r#"{"channel": "deflection", "limits": {"torque_nm": 60, "deflection_rad": 0.0015},
        "segments": [{"ramp": {"to": 0.0004, "seconds": 0.5}},
                     {"sine": {"amplitude": 0.0005, "frequency_hz": 3, "cycles": 4}},
                     {"ramp": {"to": 0, "seconds": 0.5}}]}"#;
    std::fs::write(&plan, plan_text).unwrap();
    ok(swg_host(&[&["record", "--out", &other_rec, "--plan", &plan], &joint[..]].concat()));
    let other = recording(dir.path().join("other.csv").as_path());
    let floor = truth_floor(&other);
    let predicted = json(&swg_host(&["predict", &fit, &other_rec, "--json"]));
    let rms = predicted["rms"].as_f64().unwrap();
    println!(
        "prediction of the other motion: RMS {rms:.4} N·m, the truth's floor {floor:.4} N·m ({:.2}×)",
        rms / floor
    );
    assert!(rms < 1.3 * floor, "prediction RMS {rms} N·m against the truth's floor {floor} N·m");

    // The diagnosis names the sensor's offset, and only it.
    let diagnosis = json(&swg_host(&["diagnose", &rec, "--json"]));
    let findings = diagnosis["findings"].as_array().unwrap();
    let names: Vec<&str> = findings.iter().map(|f| f["effect"].as_str().unwrap()).collect();
    assert_eq!(names, ["torque_offset"], "{diagnosis}");
    let offset = findings[0]["magnitude"].as_f64().unwrap();
    assert!((offset - OFFSET_NM).abs() < 0.05, "{offset}");

    // The fitted set pushed, then the closed loop on the same joint: the model mode holds the
    // torque better than the linear one.
    ok(swg_host(&["push", &fit, "--port", &port, "--ratio", "50"]));
    let hil = json(&swg_host(&["hil", &fit, "--port", &port, "--scenario", "torque-sine", "--seconds", "2", "--json"]));
    let rms_of = |mode: &str| {
        let run = hil["runs"].as_array().unwrap().iter().find(|r| r["mode"] == mode).unwrap();
        run["rms_nm"].as_f64().unwrap()
    };
    let (linear, model) = (rms_of("linear"), rms_of("model"));
    println!("hil torque-sine with the fitted set: RMS linear {linear:.4} N·m, model {model:.4} N·m");
    assert!(model < linear, "model {model} N·m vs linear {linear} N·m");
}

/// A plan the joint cannot play is refused before anything moves, naming where; a plan that
/// runs into its own limit stops the motor, and nothing is written.
#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn bad_plans_and_a_stopped_experiment_write_nothing() {
    let mut qemu = Qemu::boot();
    drop(qemu.ready_link());
    let port = qemu.address();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec.csv");
    let seed = repo("data/seed/lht-20-50-fit.json");
    let joint = ["--port", &port, "--params", &seed, "--ratio", "50", "--simulated-joint", "micro-slip"];
    let record = |plan: &str| {
        let path = dir.path().join("plan.json");
        std::fs::write(&path, plan).unwrap();
        swg_host(&[&["record", "--out", out.to_str().unwrap(), "--plan", path.to_str().unwrap()], &joint[..]].concat())
    };
    let unknown = record(
        r#"{"channel": "deflection", "limits": {"torque_nm": 60, "deflection_rad": 0.002},
  "segments": [{"ramp": {"to": 0.001, "seconds": 0.5}}, {"chirp": {"to": 0}}]}"#,
    );
    let stderr = String::from_utf8_lossy(&unknown.stderr);
    assert!(!unknown.status.success() && stderr.contains("plan.json:2:"), "{stderr}");
    // The joint's own limit: the plan asks 0.5 mrad (about 10 N·m), its torque limit is 5 N·m.
    let stopped = record(
        r#"{"channel": "deflection", "limits": {"torque_nm": 5, "deflection_rad": 0.002},
  "segments": [{"ramp": {"to": 0.0004, "seconds": 0.5}}, {"sine": {"amplitude": 0.0001, "frequency_hz": 2, "cycles": 3}}]}"#,
    );
    let stderr = String::from_utf8_lossy(&stopped.stderr);
    assert!(!stopped.status.success() && stderr.contains("the torque went beyond the plan's limit"), "{stderr}");
    assert!(!out.exists());
}
