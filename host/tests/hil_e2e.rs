//! The lockstep closed loop end to end: the joint firmware on the emulated Cortex-M4F (QEMU
//! mps2-an386) controls the host's simulated joint, one `Control` request per 1 kHz tick.
//! Needs `qemu-system-arm` and the firmware ELF, so the tests are ignored by a plain
//! `cargo test`; `scripts/test-firmware.sh` runs them with
//! `SWG_FIRMWARE_ELF=… cargo test --test hil_e2e -- --ignored`.
mod common;
mod qemu;

use qemu::Qemu;

use common::{json, swg_host_echoed as swg_host, write_params_file};
use model_core::checks::micro_slip_set;
use model_core::GearModel;
use model_core::Params;
use swg_host::hil::{self, GearTruth, HilOptions, Scenario};
use swg_host::simulate::{MicroSlip, Physics};
use swg_protocol::{endpoint, ControlMode, PROTOCOL_VERSION};

/// The library pipeline against QEMU: one contact second in each mode on the simulator's
/// micro-slip gear with model-core's reference micro-slip set pushed. The loop runs (no
/// fallback, no divergence), the model mode beats the open loop, the firmware answers the
/// protocol version this host speaks, and its tick kept time.
#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn the_firmware_closes_the_loop_in_lockstep() {
    let mut qemu = Qemu::boot();
    let mut link = qemu.ready_link();
    assert_eq!(link.call::<endpoint::GetDeviceInfo>(&()).unwrap().protocol_version, PROTOCOL_VERSION);
    let truth = GearTruth::Physics {
        physics: Physics::MicroSlip(MicroSlip::default()),
        model: GearModel::paper(model_core::checks::SEED_TABLE_FIT),
    };
    let options = HilOptions { scenarios: vec![Scenario::Contact], seconds: 1.5, ..HilOptions::new(truth) };
    let report = hil::run(&mut link, &micro_slip_set().unwrap(), &options).unwrap();
    println!("{}", report.human());
    assert_eq!(report.runs.len(), 3);
    let rms = |mode| {
        let run = report.runs.iter().find(|r| r.mode == mode).unwrap();
        assert_eq!(run.fallbacks, 0, "{mode:?}");
        assert_eq!(run.ticks.len(), 1500);
        run.score.unwrap_or_else(|| panic!("{mode:?} diverged")).rms_nm
    };
    let (open, model) = (rms(ControlMode::OpenLoop), rms(ControlMode::Model));
    assert!(model < open, "model {model} N·m vs open loop {open} N·m");
    // The device is left with its controller off.
    let out = link
        .call::<endpoint::Control>(&swg_protocol::ControlSample {
            input_angle: 0.0,
            output_angle: 0.0,
            reference: 5.0,
            torque: 0.0,
            temperature: None,
        })
        .unwrap();
    assert_eq!((out.command, out.mode), (0.0, ControlMode::Off));
    // Every lockstep sample ran in the firmware's control tick, and no tick came late.
    let status = link.call::<endpoint::GetStatus>(&()).unwrap();
    assert!(status.ticks as usize > 3 * 1500, "{status:?}");
    assert_eq!((status.overruns, status.late, status.missed), (0, 0, 0), "{status:?}");
}

/// The command: JSON with every run, pictures written, and nothing written when it fails.
#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn swg_host_hil_prints_json_and_draws() {
    let mut qemu = Qemu::boot();
    // The firmware answers: the CLI's single attempt will find it. (A late answer to the helper's
    // request would carry that request's id, and the CLI would discard it.)
    drop(qemu.ready_link());
    let dir = tempfile::tempdir().unwrap();
    // A passive genetic gear as the pushed model (the truth is the simulator's micro-slip gear).
    let passive = Params { c1: 2.2e4, c2: 4.0e9, c3: 0.0, alpha: -3050.0, beta: 1.2, omega: 1.0 };
    let params = write_params_file(dir.path(), &passive);
    let plots = dir.path().join("plots");
    let port = qemu.address();
    // Two seconds: four steps of 0.5 s, the limit cycle measured over the last 0.25 s of each.
    let args = ["hil", params.to_str().unwrap(), "--port", &port, "--scenario", "torque-steps", "--seconds", "2"];
    let output = swg_host(&[&args[..], &["--json", "--plot", plots.to_str().unwrap()]].concat());
    let report = json(&output);
    let runs = report["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 3);
    for (run, mode) in runs.iter().zip(["open-loop", "linear", "model"]) {
        assert_eq!(run["scenario"], "torque-steps");
        assert_eq!(run["physics"], "micro-slip");
        assert_eq!(run["mode"], mode);
        assert!(run["rms_nm"].as_f64().unwrap() > 0.0, "{run}");
        assert!(run["max_nm"].as_f64().unwrap() >= run["rms_nm"].as_f64().unwrap(), "{run}");
        assert!(run["limit_cycle_nm"].as_f64().is_some(), "{run}");
    }
    let svg = std::fs::read_to_string(plots.join("hil-torque-steps-micro-slip.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("T_true − T_ref"));
    // A failing run (an unreadable gear file) writes nothing.
    let elsewhere = dir.path().join("none");
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{").unwrap();
    let output =
        swg_host(&[&args[..], &["--gear", bad.to_str().unwrap(), "--plot", elsewhere.to_str().unwrap()]].concat());
    assert!(!output.status.success());
    assert!(!elsewhere.exists());
}
