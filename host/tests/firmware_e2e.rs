//! End to end against the joint firmware on the emulated Cortex-M4F (QEMU mps2-an386):
//! push, read back, replay, bad traffic. Needs `qemu-system-arm` and the firmware ELF, so the
//! tests are ignored by a plain `cargo test`; `scripts/test-firmware.sh` builds the firmware
//! and runs them with `SWG_FIRMWARE_ELF=… cargo test --test firmware_e2e -- --ignored`.
mod common;
mod qemu;

use qemu::Qemu;

use common::{swg_host_echoed as swg_host, write_params_file};
use model_core::checks::{SEED_AMPLITUDE, SEED_TABLE_FIT as SEED};
use model_core::legacy::{GearModelV1, SlipParamsV1};
use model_core::{GearModel, ParamName, Params, MODEL_VERSION, SLIP_ELEMENTS};
use std::net::TcpListener;
use swg_host::link::push::{joint_params, push, JointSettings};
use swg_host::link::replay::{device_model, replay, samples};
use swg_host::link::LinkError;
use swg_host::simulate::{simulate, Simulation};
use swg_protocol::{
    encode_to_vec, encode_with_version, endpoint, Envelope, ErrorReply, EvalPath, JointParams, ParamFault, ParamField,
    Request, RequestId, Response, MAX_FRAME_LEN, PROTOCOL_VERSION,
};

/// The seed table's fit (canonical form, ω = 1).
const RATIO: f64 = 50.0;
/// A limit above the loop's torque, so that every sample is compared with the model.
const SETTINGS: JointSettings = JointSettings { gear_ratio: RATIO, torque_limit: 100.0, direction_band: 2.0e-6 };

/// Two loops at 1 Hz of the seed model through 20-bit encoders, 1 kHz.
fn recording() -> swg_host::input::Recording {
    simulate(&Simulation {
        params: GearModel::paper(SEED),
        amplitude_rad: SEED_AMPLITUDE,
        frequencies_hz: vec![1.0],
        cycles: 2,
        sample_rate_hz: 1000.0,
        ratio: RATIO,
        input_speed_rad_s: 0.0,
        input_bits: Some(20),
        output_bits: Some(20),
        torque_noise_nm: 0.0,
        temperature: None,
        effects: Vec::new(),
        seed: 7,
    })
    .unwrap()
}

#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn push_read_back_and_replay_match_the_host_model() {
    let mut firmware = Qemu::boot();
    let dir = tempfile::tempdir().unwrap();
    let params_file = write_params_file(dir.path(), &SEED);
    let recording_file = dir.path().join("loops.csv");
    recording().write(std::fs::File::create(&recording_file).unwrap()).unwrap();
    // Let QEMU open its port before the CLI's single attempt.
    drop(firmware.ready_link());

    let port = firmware.address();
    let pushed = swg_host(&[
        "push",
        params_file.to_str().unwrap(),
        "--port",
        &port,
        "--ratio",
        "50",
        "--torque-limit",
        "100",
        "--direction-band",
        "2e-6",
    ]);
    assert!(pushed.status.success());
    let stdout = String::from_utf8_lossy(&pushed.stdout);
    assert!(stdout.contains(&format!("protocol {PROTOCOL_VERSION}, model {MODEL_VERSION}")), "{stdout}");
    assert!(stdout.contains("committed to flash as record 1"), "{stdout}");

    // Read back what the device holds: exactly the f32 set the host computed.
    let mut link = firmware.ready_link();
    let expected = joint_params(&GearModel::paper(SEED), &SETTINGS).unwrap();
    assert_eq!(link.call::<endpoint::ReadParams>(&()).unwrap(), Some(expected));
    drop(link);

    for path in ["fast", "direct"] {
        let replayed = swg_host(&["replay", recording_file.to_str().unwrap(), "--port", &port, "--path", path]);
        assert!(replayed.status.success(), "{path}");
        let stdout = String::from_utf8_lossy(&replayed.stdout);
        assert!(stdout.contains("(0 samples outside"), "{stdout}");
        // The seed's polynomial spring is identified over ±1 rad: nothing lies beyond.
        assert!(stdout.contains("(board status): 0 samples, largest excess 0.000e0 rad"), "{stdout}");
        assert!(stdout.contains("the causal reversal band against the offline model: T_ff RMS"), "{stdout}");
    }

    // The same through the library, with the details asserted: whole loops, turning points
    // included, every sample within the f32 tolerance, on both paths.
    let mut link = firmware.ready_link();
    let samples = samples(&recording(), expected.gear_ratio).unwrap();
    for path in [EvalPath::Fast, EvalPath::Direct] {
        link.call::<endpoint::WriteParams>(&expected).unwrap(); // from rest
        let report = replay(&mut link, &expected, &device_model(&expected), &samples, path).unwrap();
        assert!(report.passed(), "{path:?}: {report}");
        assert_eq!(report.active, samples.len(), "{report}");
        assert!(report.reversals >= 3, "{report}");
        // Against the f64 model of the file (not rounded to f32): still within tolerance.
        link.call::<endpoint::WriteParams>(&expected).unwrap();
        let report = replay(&mut link, &expected, &GearModel::paper(SEED), &samples, path).unwrap();
        assert!(report.passed(), "{path:?} against the file's f64 parameters: {report}");
    }
}

/// A micro-slip gear of the seed's size as model version 1 wrote it: 16 elements, log grid
/// 10 µrad … 2 mrad.
fn slip_v1() -> SlipParamsV1<f64> {
    let mut stiffness = [0.0; SLIP_ELEMENTS];
    for (i, k) in stiffness.iter_mut().enumerate() {
        *k = 120.0 + 15.0 * i as f64;
    }
    SlipParamsV1 { c1: 6.0e3, c2: 1.2e10, c3: 0.0, stiffness, slip_min: 1.0e-5, slip_max: 2.0e-3 }
}

/// [`slip_v1`] as today's model.
fn slip_model() -> GearModel<f64> {
    GearModelV1::MicroSlip(slip_v1()).upgrade().unwrap()
}

/// The simulator's Bouc–Wen gear with exponent `n` and β = γ set for its z_max (0.4 mrad): n = 1
/// is integrated in closed form, any other n in sub-steps.
fn bouc_wen(n: f64) -> GearModel<f64> {
    let mut model = model_core::checks::bouc_wen_set();
    if let model_core::Hysteresis::BoucWen(term) = &mut model.hysteresis {
        let half_sum = 0.5 * term.shape.a / term.shape.z_max().powf(n);
        term.shape = model_core::bouc_wen::BoucWen { n, beta: half_sum, gamma: half_sum, ..term.shape };
    }
    model
}

/// Arbitrary motion from rest, as the encoders of a 1:50 gear with the output at rest, in f32:
/// θ = 0.6·A + 0.15·A·sin φ after a ramp (a held load with an oscillation), and
/// θ = A·(0.75·sin φ + 0.25·sin 9φ) (minor loops nested at many levels).
fn arbitrary_motions() -> [(&'static str, Vec<(f32, f32)>); 2] {
    let (a, n, tau) = (SEED_AMPLITUDE, 3000, std::f64::consts::TAU);
    let ramp = n / 5;
    let biased = (0..n).map(|i| {
        if i < ramp {
            0.6 * a * i as f64 / ramp as f64
        } else {
            0.6 * a + 0.15 * a * (tau * 4.0 * (i - ramp) as f64 / (n - ramp) as f64).sin()
        }
    });
    let nested = (0..n).map(|i| {
        let phase = tau * 2.0 * i as f64 / n as f64;
        a * (0.75 * phase.sin() + 0.25 * (9.0 * phase).sin())
    });
    let encoders = |thetas: &mut dyn Iterator<Item = f64>| thetas.map(|t| ((RATIO * t) as f32, 0.0)).collect();
    [("biased", encoders(&mut biased.into_iter())), ("nested", encoders(&mut nested.into_iter()))]
}

#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn every_kind_follows_arbitrary_motion_as_the_host_model_does() {
    let mut firmware = Qemu::boot();
    let dir = tempfile::tempdir().unwrap();
    // The micro-slip kind through the CLI: a params file as `fit --model micro-slip` of model
    // version 1 wrote it, which loads as today's model.
    let slip = slip_v1();
    let slip_file = dir.path().join("slip.json");
    let json = serde_json::json!({ "model": "micro-slip", "params": {
        "c1": slip.c1, "c2": slip.c2, "c3": slip.c3, "stiffness": slip.stiffness.to_vec(),
        "slip_min": slip.slip_min, "slip_max": slip.slip_max } });
    std::fs::write(&slip_file, json.to_string()).unwrap();
    drop(firmware.ready_link());
    let port = firmware.address();
    let pushed =
        swg_host(&["push", slip_file.to_str().unwrap(), "--port", &port, "--ratio", "50", "--torque-limit", "100"]);
    assert!(pushed.status.success());
    assert!(String::from_utf8_lossy(&pushed.stdout).contains("micro-slip zero=0e0 c1=6e3"), "{pushed:?}");

    let mut link = firmware.ready_link();
    let expected = joint_params(&slip_model(), &SETTINGS).unwrap();
    assert_eq!(link.call::<endpoint::ReadParams>(&()).unwrap(), Some(expected));
    assert_eq!(expected.model.kind(), model_core::Kind::MicroSlip);
    // Each with the depth of memory the motions must reach: Bouc–Wen's one state is z; the
    // Preisach set's grid (±1.4 mrad) holds both motions.
    let models = [
        (slip_model(), 2),
        (GearModel::paper(SEED), 2),
        (bouc_wen(1.0), 0),
        (bouc_wen(1.5), 0),
        (model_core::checks::preisach_set(), 2),
    ];
    for (model, depth) in models {
        let joint = joint_params(&model, &SETTINGS).unwrap();
        push(&mut link, &joint).unwrap();
        for (name, samples) in arbitrary_motions() {
            for path in [EvalPath::Fast, EvalPath::Direct] {
                // Each run from rest: writing the set resets the device's memory.
                link.call::<endpoint::WriteParams>(&joint).unwrap();
                let report = replay(&mut link, &joint, &device_model(&joint), &samples, path).unwrap();
                println!("{:?} {name} {path:?}: {report}", model.kind());
                assert!(report.passed(), "{:?} {name} {path:?}: {report}", model.kind());
                assert_eq!(report.active, samples.len(), "{report}");
                assert!(report.reversals >= 8 && report.deepest_memory >= depth, "{report}");
                link.call::<endpoint::WriteParams>(&joint).unwrap();
                let report = replay(&mut link, &joint, &model, &samples, path).unwrap();
                assert!(report.passed(), "{:?} {name} {path:?} against the f64 parameters: {report}", model.kind());
            }
        }
    }
}

/// The reason of an error reply, and the id it carries.
fn refused(reply: Result<Envelope<Response>, LinkError>) -> (RequestId, ErrorReply) {
    match reply.unwrap() {
        Envelope { id, message: Response::Error(reason) } => (id, reason),
        other => panic!("expected an error reply, got {other:?}"),
    }
}

#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn bad_traffic_gets_a_clear_error_and_the_old_parameters_stay() {
    let mut firmware = Qemu::boot();
    let mut link = firmware.ready_link();
    let good = joint_params(&GearModel::paper(SEED), &SETTINGS).unwrap();
    push(&mut link, &good).unwrap();

    let frame = encode_to_vec(RequestId(1), &Request::WriteParams(JointParams { torque_limit: 5.0, ..good })).unwrap();
    let mut corrupted = frame.clone();
    corrupted[swg_protocol::payload_index(&frame, 12).unwrap()] ^= 0x10;
    let truncated = [&frame[..frame.len() / 2], &[0u8]].concat();
    let mut other_version = [0u8; MAX_FRAME_LEN];
    let len =
        encode_with_version(PROTOCOL_VERSION + 1, RequestId(2), &Request::ReadParams, &mut other_version).unwrap();
    let with = |name: ParamName, value: f32| JointParams { model: good.model.with(name, value), ..good };
    let nan = with(ParamName::Beta, f32::NAN);
    let out_of_range = JointParams { gear_ratio: 0.0, ..good };
    let infinite = with(ParamName::C1, f32::INFINITY);
    let slip = joint_params(&slip_model(), &SETTINGS).unwrap().model;
    let negative = JointParams { model: slip.with(ParamName::SlipStiffness(11), -5.0), ..good };
    // The last element's slip deflection below the one before it.
    let inverted = JointParams { model: slip.with(ParamName::Slip(15), 1.0e-5), ..good };
    // Finite, but the model overflows f32 within |θ| ≤ MAX_DEFLECTION: refused, not committed.
    let overflowing = with(ParamName::C3, 1.0e38);
    let stiff = JointParams { model: slip.with(ParamName::SlipStiffness(3), 1.0e38), ..good };
    // Longer than any frame the device reads.
    let garbage = [0x13u8; swg_protocol::MAX_FRAME_LEN + 100];

    // The replies to frames the device cannot read carry the unknown id; the others, the
    // request's own (the frames' ids are 11 onwards, in order).
    let cases: Vec<(&str, Vec<u8>, ErrorReply)> = vec![
        ("corrupted byte", corrupted, ErrorReply::BadCrc),
        ("truncated frame", truncated, ErrorReply::BadFrame),
        (
            "wrong protocol version",
            other_version[..len].to_vec(),
            ErrorReply::UnsupportedProtocol { got: PROTOCOL_VERSION + 1, supported: PROTOCOL_VERSION },
        ),
        (
            "NaN parameter",
            encode_to_vec(RequestId(11), &Request::WriteParams(nan)).unwrap(),
            ErrorReply::InvalidParam { field: ParamField::Model(ParamName::Beta), fault: ParamFault::NotFinite },
        ),
        (
            "infinite parameter",
            encode_to_vec(RequestId(12), &Request::WriteParams(infinite)).unwrap(),
            ErrorReply::InvalidParam { field: ParamField::Model(ParamName::C1), fault: ParamFault::NotFinite },
        ),
        (
            "out-of-range parameter",
            encode_to_vec(RequestId(13), &Request::WriteParams(out_of_range)).unwrap(),
            ErrorReply::InvalidParam { field: ParamField::GearRatio, fault: ParamFault::OutOfRange },
        ),
        (
            "negative element stiffness",
            encode_to_vec(RequestId(14), &Request::WriteParams(negative)).unwrap(),
            ErrorReply::InvalidParam {
                field: ParamField::Model(ParamName::SlipStiffness(11)),
                fault: ParamFault::OutOfRange,
            },
        ),
        (
            "slip deflections out of order",
            encode_to_vec(RequestId(15), &Request::WriteParams(inverted)).unwrap(),
            ErrorReply::InvalidParam { field: ParamField::Model(ParamName::Slip(15)), fault: ParamFault::OutOfRange },
        ),
        (
            "c3 that overflows f32 in range",
            encode_to_vec(RequestId(16), &Request::WriteParams(overflowing)).unwrap(),
            ErrorReply::InvalidParam { field: ParamField::Model(ParamName::C3), fault: ParamFault::OutOfRange },
        ),
        (
            "element stiffness that overflows f32 in range",
            encode_to_vec(RequestId(17), &Request::WriteParams(stiff)).unwrap(),
            ErrorReply::InvalidParam {
                field: ParamField::Model(ParamName::SlipStiffness(3)),
                fault: ParamFault::OutOfRange,
            },
        ),
        ("line noise", [&garbage[..], &[0u8]].concat(), ErrorReply::FrameTooLong),
    ];
    for (what, bytes, expected) in cases {
        let (id, reason) = refused(link.exchange(&bytes));
        assert_eq!(reason, expected, "{what}");
        let readable = !matches!(
            reason,
            ErrorReply::BadCrc
                | ErrorReply::BadFrame
                | ErrorReply::FrameTooLong
                | ErrorReply::UnsupportedProtocol { .. }
        );
        let sent = bytes.iter().position(|&b| b == 0).and_then(|end| {
            let mut frame = bytes[..end].to_vec();
            swg_protocol::decode::<Request>(&mut frame).ok().map(|envelope| envelope.id)
        });
        assert_eq!(id, if readable { sent.unwrap() } else { RequestId::UNKNOWN }, "{what}");
        // Still answering, with the old parameters active.
        assert_eq!(link.call::<endpoint::GetDeviceInfo>(&()).unwrap().protocol_version, PROTOCOL_VERSION, "{what}");
        assert_eq!(link.call::<endpoint::ReadParams>(&()).unwrap(), Some(good), "{what}");
    }
    // The reply names the reason in words, as the CLI prints it.
    let error = link.call::<endpoint::WriteParams>(&nan).unwrap_err();
    assert_eq!(error.to_string(), "device refused the request: parameter beta is not finite");
    // And the compensation still runs on the old set.
    let sample = swg_protocol::EncoderSample { input_angle: 0.05, output_angle: 0.0, path: EvalPath::Fast };
    let feedforward = link.call::<endpoint::Replay>(&sample).unwrap();
    assert_eq!(feedforward.compensation, swg_protocol::Compensation::Active);
}

#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn push_refuses_values_the_device_would_refuse_and_says_why() {
    let mut firmware = Qemu::boot();
    drop(firmware.ready_link());
    let dir = tempfile::tempdir().unwrap();
    let params_file = write_params_file(dir.path(), &SEED);
    let port = firmware.address();
    let out = swg_host(&["push", params_file.to_str().unwrap(), "--port", &port, "--ratio", "0.5"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("parameter gear_ratio is out of range"));
    // A set the joint could not evaluate (c3 = 1e38 overflows 5·c3·θ⁴ in f32): refused before
    // sending, with the device's reason.
    let huge_dir = tempfile::tempdir().unwrap();
    let huge = write_params_file(huge_dir.path(), &Params { c3: 1.0e38, ..SEED });
    let out = swg_host(&["push", huge.to_str().unwrap(), "--port", &port, "--ratio", "50"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("parameters rejected before sending: parameter c3 is out of range"), "{stderr}");
    // Nothing listens here: a clear error, not a hang.
    let closed = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let out = swg_host(&[
        "push",
        params_file.to_str().unwrap(),
        "--port",
        &format!("tcp://127.0.0.1:{closed}"),
        "--ratio",
        "50",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot open tcp://127.0.0.1:"));
}
