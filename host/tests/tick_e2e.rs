//! The control tick under link traffic, end to end on the emulated Cortex-M4F (QEMU
//! mps2-an386, `-icount shift=0`: virtual time is the instruction count, so the tick's timing
//! counters measure the firmware and not the load of the machine). Needs `qemu-system-arm` and
//! the firmware ELF, so the test is ignored by a plain `cargo test`;
//! `scripts/test-firmware.sh` runs it with `SWG_FIRMWARE_ELF=… cargo test --test tick_e2e -- --ignored`.
mod qemu;

use qemu::Qemu;

use model_core::checks::micro_slip_set;
use swg_host::link::{Discarded, Link, LinkError};
use swg_protocol::endpoint::{Configure, Control, GetDeviceInfo, GetStatus, WriteParams};
use swg_protocol::{
    ControlMode, ControlOutput, ControlSample, ControllerConfig, ErrorReply, JointParams, ParamFault, ParamField,
    ParamName, RequestId, TickStatus, MODEL_VERSION,
};

const TICKS: usize = 1_000;

fn params() -> JointParams {
    JointParams {
        model_version: MODEL_VERSION,
        model: micro_slip_set().unwrap().map(|_, v| v as f32),
        gear_ratio: 50.0,
        torque_limit: 60.0,
        direction_band: 0.0,
    }
}

fn config() -> ControllerConfig {
    ControllerConfig {
        mode: ControlMode::Model,
        kp: 0.06,
        ki: 6.0,
        integral_deadband: 0.05,
        damping: 0.015,
        torsion_damping: 0.03,
        stiffness: 9000.0,
        command_limit: 1.0,
        period: 1.0e-3,
    }
}

/// Sample k of a lockstep run: the motor angle swings the gear through ±1.5 mrad of
/// deflection, nested loops included, against a sine reference.
fn sample(k: usize) -> ControlSample {
    let phase = std::f32::consts::TAU * k as f32 / 400.0;
    let deflection = 1.5e-3 * (0.75 * phase.sin() + 0.25 * (9.0 * phase).sin());
    ControlSample {
        input_angle: 50.0 * deflection,
        output_angle: 0.0,
        reference: 8.0 * phase.sin(),
        torque: 0.0,
        temperature: None,
    }
}

/// The outputs of one lockstep run from rest; `between` runs before every sample.
fn lockstep(link: &mut Link, mut between: impl FnMut(&mut Link, usize)) -> Vec<ControlOutput> {
    link.call::<WriteParams>(&params()).unwrap();
    link.call::<Configure>(&config()).unwrap();
    let outputs = (0..TICKS)
        .map(|k| {
            between(link, k);
            link.call::<Control>(&sample(k)).unwrap()
        })
        .collect();
    link.call::<Configure>(&ControllerConfig { mode: ControlMode::Off, ..config() }).unwrap();
    outputs
}

/// A burst of link traffic during a lockstep run — before every control tick three status
/// requests and a device info; every tenth, a frame of line noise and a parameter set the
/// device range-checks and refuses — delays no tick: no overrun, no late tick, no period
/// without a tick, and the run's every command is bit for bit that of the same run without the
/// traffic.
#[test]
#[ignore = "needs QEMU and the firmware ELF: run by scripts/test-firmware.sh"]
fn link_traffic_during_a_lockstep_run_delays_no_tick() {
    let mut qemu = Qemu::boot();
    let mut link = qemu.ready_link();
    let quiet = lockstep(&mut link, |_, _| ());

    let refused = JointParams { model: params().model.with(ParamName::SlipStiffness(3), 1.0e38), ..params() };
    let refusal = ErrorReply::InvalidParam {
        field: ParamField::Model(ParamName::SlipStiffness(3)),
        fault: ParamFault::OutOfRange,
    };
    let noise: Vec<u8> = (0..120u8).map(|i| i.wrapping_mul(37) | 1).chain([0]).collect();
    let mut requests = 0;
    let busy = lockstep(&mut link, |link, k| {
        for _ in 0..3 {
            assert!(link.call::<GetStatus>(&()).unwrap().ticks > 0);
        }
        link.call::<GetDeviceInfo>(&()).unwrap();
        requests += 4;
        if k % 10 == 0 {
            let reply = link.exchange(&noise).unwrap();
            assert_eq!(reply.id, RequestId::UNKNOWN);
            let error = link.call::<WriteParams>(&refused).unwrap_err();
            assert!(matches!(error, LinkError::Refused(reason) if reason == refusal), "{error}");
            requests += 2;
        }
    });
    assert_eq!(busy.len(), quiet.len());
    for (k, (busy, quiet)) in busy.iter().zip(&quiet).enumerate() {
        assert_eq!(busy.command.to_bits(), quiet.command.to_bits(), "tick {k}: {busy:?} vs {quiet:?}");
        assert_eq!((busy.estimate.to_bits(), busy.mode), (quiet.estimate.to_bits(), quiet.mode), "tick {k}");
    }
    assert!(busy.iter().filter(|output| output.mode == ControlMode::Model).count() > TICKS / 2);

    let status: TickStatus = link.call::<GetStatus>(&()).unwrap();
    println!("{requests} requests and {} lockstep ticks over the link; tick status: {status:?}", 2 * TICKS);
    assert_eq!(status.rate_hz, 20_000);
    // The tick ran all along, not only for the lockstep samples.
    assert!(status.ticks as usize > 2 * TICKS, "{status:?}");
    assert_eq!((status.overruns, status.late, status.missed), (0, 0, 0), "{status:?}");
    assert!(status.worst_latency_ns <= status.late_bound_ns, "{status:?}");
    assert!(status.worst_tick_ns < 1_000_000_000 / status.rate_hz, "{status:?}");
    assert_eq!(link.discarded(), Discarded::default());
}
