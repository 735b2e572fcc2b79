//! The fuzz targets of `fuzz/` on stable, in a few seconds: every checked-in corpus input
//! (`fuzz/corpus/<target>/`), and seeded mutations of each, through the same harness the
//! cargo-fuzz targets call (`fuzz/src/`, included here by path). No input may panic; the
//! harness asserts the readers' invariants on what they accept and that every refusal names
//! the file. Long runs: `bash bench/fuzz.sh` (nightly and cargo-fuzz).
#[path = "../../fuzz/src/frames.rs"]
mod frames;
#[path = "../../fuzz/src/host.rs"]
mod host;

use std::path::{Path, PathBuf};
use swg_protocol::experiment::{ExperimentState, RecordedSample, SampleBatch};
use swg_protocol::plan::{Channel, Limits, Plan, Segment};
use swg_protocol::{
    encode_to_vec, Compensation, ControlMode, ControlOutput, ControlSample, ControllerConfig, DeviceInfo,
    DriveErrorKind, EncoderSample, ErrorReply, EvalPath, Feedforward, GearModel, JointParams, Params, Request,
    RequestId, Response, StorageError, TickStatus, Version, MODEL_VERSION, PROTOCOL_VERSION,
};

/// Mutations of each corpus input, beside the input itself.
const MUTATIONS: u64 = 300;

type Target = fn(&[u8]);

fn targets() -> [(&'static str, Target); 5] {
    [
        ("csv_loop_table", |data| host::csv(data, None)),
        ("csv_recording", |data| {
            host::csv(data, None);
            host::csv(data, Some(50.0));
        }),
        ("params", host::params),
        ("plan", host::plan),
        ("frame_decode", frames::frames),
    ]
}

fn corpus(target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus").join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.unwrap().path())
        .collect();
    files.sort();
    files
}

/// A small deterministic generator (SplitMix64), so that a failure can be replayed.
struct Mix(u64);

impl Mix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// The fuzzer's usual moves: flip a bit, delete, insert a byte that matters to the format,
/// truncate, repeat a piece, or splice in a line of another input.
fn mutate(data: &[u8], other: &[u8], seed: u64) -> Vec<u8> {
    const BYTES: &[u8] = b",#\r\n .-+e0159\"\xef\xbb\xbf\x00\xffNaninf";
    let mut rng = Mix(seed);
    let mut out = data.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(out.len() + 1);
        match rng.below(6) {
            0 if !out.is_empty() => {
                let i = at.min(out.len() - 1);
                out[i] ^= 1 << rng.below(8);
            }
            1 => {
                let end = (at + 1 + rng.below(8)).min(out.len());
                out.drain(at..end);
            }
            2 => out.insert(at, BYTES[rng.below(BYTES.len())]),
            3 => out.truncate(at),
            4 if !out.is_empty() => {
                let from = rng.below(out.len());
                let piece: Vec<u8> = out[from..(from + 1 + rng.below(32)).min(out.len())].to_vec();
                out.splice(at..at, piece);
            }
            _ if !other.is_empty() => {
                let from = rng.below(other.len());
                let piece: Vec<u8> = other[from..(from + 1 + rng.below(64)).min(other.len())].to_vec();
                out.splice(at..at, piece);
            }
            _ => {}
        }
    }
    out
}

#[test]
fn the_fuzz_corpus_replays_without_a_panic() {
    let start = std::time::Instant::now();
    let mut runs = 0;
    let mut report = Vec::new();
    for (name, target) in targets() {
        let inputs: Vec<(PathBuf, Vec<u8>)> =
            corpus(name).into_iter().map(|p| (p.clone(), std::fs::read(p).unwrap())).collect();
        assert!(inputs.len() >= 20, "{name}: only {} corpus inputs", inputs.len());
        let mut count = 0;
        for (index, (path, data)) in inputs.iter().enumerate() {
            let other = &inputs[(index + 1) % inputs.len()].1;
            for m in 0..=MUTATIONS {
                let seed = (index as u64) << 32 | m;
                let input = if m == 0 { data.clone() } else { mutate(data, other, seed) };
                if std::panic::catch_unwind(|| target(&input)).is_err() {
                    panic!(
                        "{name}: {} mutation {m} (seed {seed:#x}) panicked; input: {:?}",
                        path.display(),
                        String::from_utf8_lossy(&input)
                    );
                }
                count += 1;
            }
        }
        report.push(format!("{name}: {} inputs, {count} runs", inputs.len()));
        runs += count;
    }
    println!("{} ({runs} runs in {:.2?})", report.join("; "), start.elapsed());
}

/// The frame decoder's seeds in `fuzz/corpus/frame_decode/` that hold frames of this
/// protocol: one of every request and response (and some error replies), two frames in a row,
/// and a frame after line noise. Written by `regenerate_the_frame_seeds`.
fn frame_seeds() -> Vec<(String, Vec<u8>)> {
    let params = JointParams {
        model_version: MODEL_VERSION,
        model: GearModel::paper(Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 68.0, beta: -2.298, omega: 1.0 }),
        gear_ratio: 100.0,
        torque_limit: 50.0,
        direction_band: 2.0e-6,
    };
    let config = ControllerConfig {
        mode: ControlMode::Model,
        kp: 0.06,
        ki: 6.0,
        integral_deadband: 0.05,
        damping: 0.015,
        torsion_damping: 0.03,
        stiffness: 9000.0,
        command_limit: 1.0,
        period: 1.0e-3,
    };
    let segments =
        [Segment::Ramp { to: 5.0e-4, seconds: 0.5 }, Segment::Sine { amplitude: 2.0e-4, frequency_hz: 2.0, cycles: 3 }];
    let limits = Limits { torque_nm: 30.0, deflection_rad: 1.0e-3 };
    let plan = Plan::new(Channel::Deflection, limits, 1000.0, &segments).unwrap();
    let sample = RecordedSample { input_angle: 0.025, output_angle: 1.0e-5, torque: 4.5, temperature: Some(30.5) };
    let batch = SampleBatch {
        sequence: 3,
        first_tick: 48,
        dropped: 0,
        high_water: 16,
        state: ExperimentState::Running { segment: 1 },
        samples: std::iter::repeat_n(sample, 3).collect(),
    };
    let requests = [
        Request::GetDeviceInfo,
        Request::WriteParams(params),
        Request::ReadParams,
        Request::Commit,
        Request::Replay(EncoderSample { input_angle: 0.05, output_angle: 0.0, path: EvalPath::Fast }),
        Request::Configure(config),
        Request::SetReference(5.0),
        Request::Control(ControlSample {
            input_angle: 0.05,
            output_angle: 0.0,
            reference: 5.0,
            torque: 2.5,
            temperature: Some(31.0),
        }),
        Request::GetStatus,
        Request::StartExperiment(plan),
        Request::FetchSamples,
        Request::StopExperiment,
    ];
    let version = Version { major: 0, minor: 1, patch: 0 };
    let responses = [
        Response::DeviceInfo(DeviceInfo {
            firmware_version: version,
            protocol_version: PROTOCOL_VERSION,
            model_version: MODEL_VERSION,
        }),
        Response::ParamsAccepted,
        Response::Params(Some(params)),
        Response::Committed(3),
        Response::Feedforward(Feedforward {
            deflection: 5.0e-4,
            torque: 6.5,
            stiffness: 12_000.0,
            compensation: Compensation::Active,
            direction: None,
            memory: 2,
        }),
        Response::Error(ErrorReply::BadCrc),
        Response::ControlAccepted,
        Response::Control(ControlOutput { command: 0.1, estimate: 5.0, mode: ControlMode::Model, saturated: false }),
        Response::Status(TickStatus { rate_hz: 20_000, ticks: 1_000, ..TickStatus::default() }),
        Response::Error(ErrorReply::Storage(StorageError::Verify)),
        Response::Error(ErrorReply::MotorDrive(DriveErrorKind::Fault)),
        Response::ExperimentStarted(1_501),
        Response::Samples(batch),
        Response::Error(ErrorReply::ExperimentRunning),
    ];
    let mut frames: Vec<Vec<u8>> =
        requests.iter().zip(1..).map(|(r, id)| encode_to_vec(RequestId(id), r).unwrap()).collect();
    frames.extend(responses.iter().zip(100..).map(|(r, id)| encode_to_vec(RequestId(id), r).unwrap()));
    let mut seeds: Vec<(String, Vec<u8>)> =
        frames.iter().enumerate().map(|(i, frame)| (format!("golden-{i}.bin"), frame.clone())).collect();
    seeds.push(("two-frames.bin".into(), [frames[0].clone(), frames[2].clone()].concat()));
    seeds.push(("garbage-then-frame.bin".into(), [&[0x13, 0x37, 0xff, 0x00][..], &frames[0]].concat()));
    let bouc_wen = JointParams { model: model_core::checks::bouc_wen_set().map(|_, v| v as f32), ..params };
    seeds.push(("write-bouc-wen.bin".into(), encode_to_vec(RequestId(200), &Request::WriteParams(bouc_wen)).unwrap()));
    let preisach = JointParams { model: model_core::checks::preisach_set().map(|_, v| v as f32), ..params };
    seeds.push(("write-preisach.bin".into(), encode_to_vec(RequestId(201), &Request::WriteParams(preisach)).unwrap()));
    seeds
}

fn frame_seed_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus/frame_decode")
}

/// The seeds are frames of this protocol: after a protocol change they fail here until
/// `cargo test -p swg-host --test fuzz_corpus -- --ignored regenerate` rewrites them.
#[test]
fn the_frame_seeds_are_frames_of_this_protocol() {
    for (name, bytes) in frame_seeds() {
        let stored = std::fs::read(frame_seed_dir().join(&name)).unwrap_or_default();
        assert!(stored == bytes, "fuzz/corpus/frame_decode/{name} is stale: regenerate the frame seeds");
    }
}

#[test]
#[ignore = "rewrites fuzz/corpus/frame_decode/golden-*.bin after a protocol change"]
fn regenerate_the_frame_seeds() {
    for (name, bytes) in frame_seeds() {
        std::fs::write(frame_seed_dir().join(name), bytes).unwrap();
    }
}
