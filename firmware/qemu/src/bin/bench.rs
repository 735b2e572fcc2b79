//! Instructions per T_ff + K evaluation, per compensator tick, and per tick of the torque
//! controller with its evaluator (`Controller::tick` in model mode) on the emulated Cortex-M4F. Run
//! under `qemu-system-arm -icount shift=0`: one instruction per ns of virtual time, SysTick at
//! 25 MHz, so one SysTick tick is 40 instructions, exactly repeatable (bench/firmware.sh).
#![no_std]
#![no_main]

use core::hint::black_box;
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use model_core::checks::{MICRO_SLIP_SET, SEED_TABLE_FIT};
use model_core::{Direction, Model};
use swg_joint::{Compensator, Controller, FastModel};
use swg_protocol::{
    ControlMode, ControllerConfig, EvalPath, GearModel, JointParams, MODEL_VERSION, SLIP_ELEMENTS, TURNING_POINTS,
};

const INSTRUCTIONS_PER_TICK: u32 = 40;
const RUNS: u32 = 2000;
const AMPLITUDE: f32 = 1.168e-3;
const RATIO: f32 = 100.0;

/// SysTick ticks taken by `body` (a 24-bit down-counter; runs stay below its period).
fn ticks(body: impl FnOnce()) -> u32 {
    let start = SYST::get_current();
    body();
    let end = SYST::get_current();
    start.wrapping_sub(end) & 0x00FF_FFFF
}

/// Deflection of run `i`: points spread over the loop, both branches.
fn point(i: u32) -> (f32, Direction) {
    let x = ((i * 37) % 200) as f32 / 100.0 - 1.0;
    let direction = if i % 2 == 0 { Direction::Rising } else { Direction::Falling };
    (x * AMPLITUDE * 0.999, direction)
}

fn per_run(total_ticks: u32, baseline_ticks: u32) -> f32 {
    (total_ticks.saturating_sub(baseline_ticks) * INSTRUCTIONS_PER_TICK) as f32 / RUNS as f32
}

/// Instructions of one tick at θ from the compensator state `state` (copied afresh for every
/// run; the copy is measured alone, written exactly as in the timed loop, and subtracted: a
/// copy passed by value to `black_box` is a second copy the timed loop does not make, and
/// subtracting it undercounted the tick by about one state copy).
fn tick_from(state: &Compensator, theta: f32, path: EvalPath) -> f32 {
    let copies = ticks(|| {
        for _ in 0..RUNS {
            let compensator = black_box(state).clone();
            black_box(&compensator);
        }
    });
    let ticked = ticks(|| {
        for _ in 0..RUNS {
            let mut compensator = black_box(state).clone();
            black_box(compensator.tick(black_box(theta) * RATIO, 0.0, path));
            black_box(&compensator);
        }
    });
    per_run(ticked, copies)
}

/// Instructions of one controller tick (model mode: the evaluator's step, the gain schedule,
/// the loop, the clamp) at θ from `state`, copied afresh for every run as in [`tick_from`].
fn control_from(state: &(Controller, Compensator), theta: f32) -> f32 {
    let copies = ticks(|| {
        for _ in 0..RUNS {
            let (controller, compensator) = black_box(state).clone();
            black_box((&controller, &compensator));
        }
    });
    let ticked = ticks(|| {
        for _ in 0..RUNS {
            let (mut controller, mut compensator) = black_box(state).clone();
            black_box(controller.tick(&mut compensator, black_box(theta) * RATIO, 0.0, black_box(12.5)));
            black_box((&controller, &compensator));
        }
    });
    per_run(ticked, copies)
}

/// θ along a nested motion from rest, A·(0.75·sin φ + 0.25·sin 9φ) over two cycles in
/// [`RUNS`] ticks: a reversal every ~55 ticks, minor loops at many levels.
fn nested_motion() -> [f32; RUNS as usize] {
    let mut motion = [0.0f32; RUNS as usize];
    for (i, theta) in motion.iter_mut().enumerate() {
        let phase = core::f32::consts::TAU * 2.0 * i as f32 / RUNS as f32;
        *theta = AMPLITUDE * (0.75 * libm::sinf(phase) + 0.25 * libm::sinf(9.0 * phase));
    }
    motion
}

/// Instructions per tick along `motion`, consecutive ticks from rest with no copies: the
/// compensator alone, and the controller (model mode) with it.
fn along(params: JointParams, motion: &[f32; RUNS as usize]) -> (f32, f32) {
    let baseline = ticks(|| {
        for &theta in motion {
            black_box(black_box(theta) * RATIO);
        }
    });
    let mut compensator = Compensator::new();
    let _ = compensator.stage(params);
    let alone = ticks(|| {
        for &theta in motion {
            black_box(compensator.tick(black_box(theta) * RATIO, 0.0, EvalPath::Fast));
        }
    });
    let mut compensator = Compensator::new();
    let _ = compensator.stage(params);
    let (mut controller, mut compensator) = controlling(compensator, 0.0);
    let controlled = ticks(|| {
        for &theta in motion {
            black_box(controller.tick(&mut compensator, black_box(theta) * RATIO, 0.0, black_box(12.5)));
        }
    });
    (per_run(alone, baseline), per_run(controlled, baseline))
}

/// The controller in model mode after a first tick, with `compensator`.
fn controlling(compensator: Compensator, last: f32) -> (Controller, Compensator) {
    let mut controller = Controller::new();
    let config = ControllerConfig {
        mode: ControlMode::Model,
        kp: 0.06,
        ki: 6.0,
        integral_deadband: 0.1,
        damping: 0.015,
        torsion_damping: 0.03,
        stiffness: 9000.0,
        command_limit: 1.0,
        period: 1.0e-3,
    };
    let _ = controller.configure(config);
    let mut compensator = compensator;
    controller.tick(&mut compensator, last * RATIO, 0.0, 12.5);
    (controller, compensator)
}

/// A motion from rest that leaves the genetic model's stack full: a zigzag of shrinking
/// excursions about 0.2·A, each reversing inside the last ([`TURNING_POINTS`] of them).
/// Returns the compensator after it and the last θ.
fn full_stack(params: JointParams) -> Option<(Compensator, f32)> {
    let mut compensator = Compensator::new();
    compensator.stage(params).ok()?;
    let mut theta = 0.0;
    for k in 0..TURNING_POINTS as u32 + 2 {
        let size = AMPLITUDE * (1.0 - 0.05 * k as f32);
        let target = if k % 2 == 0 { size } else { -0.6 * size };
        // Ten steps to each turning point.
        for s in 1..=10 {
            let t = theta + (target - theta) * s as f32 / 10.0;
            compensator.tick(t * RATIO, 0.0, EvalPath::Direct);
        }
        theta = target;
    }
    Some((compensator, theta))
}

#[entry]
fn main() -> ! {
    let Some(mut core) = cortex_m::Peripherals::take() else { swg_firmware_qemu::exit(false) };
    core.SYST.set_clock_source(SystClkSource::Core);
    core.SYST.set_reload(0x00FF_FFFF);
    core.SYST.clear_current();
    core.SYST.enable_counter();

    let params = SEED_TABLE_FIT.to_f32();
    let (Ok(model), Ok(fast)) = (Model::new(params), FastModel::new(&params)) else { swg_firmware_qemu::exit(false) };
    let genetic = JointParams {
        model_version: MODEL_VERSION,
        model: GearModel::Genetic(params),
        gear_ratio: RATIO,
        torque_limit: 100.0,
        direction_band: 1.0e-6,
    };
    let slip = JointParams { model: GearModel::MicroSlip(MICRO_SLIP_SET.to_f32()), ..genetic };

    // The loop and the black boxes alone, subtracted from every measurement.
    let baseline = ticks(|| {
        for i in 0..RUNS {
            black_box(point(black_box(i)));
        }
    });
    let direct = ticks(|| {
        for i in 0..RUNS {
            let (theta, direction) = point(black_box(i));
            let result = model.at_amplitude(black_box(AMPLITUDE)).and_then(|lp| lp.evaluate(theta, direction));
            black_box(result.ok());
        }
    });
    let fast_path = ticks(|| {
        for i in 0..RUNS {
            let (theta, direction) = point(black_box(i));
            black_box(fast.evaluate(theta, direction, black_box(AMPLITUDE)));
        }
    });
    hprintln!(
        "symmetric loop, one T_ff + K evaluation: direct (model-core f32, libm) {}, fast path {}",
        per_run(direct, baseline),
        per_run(fast_path, baseline)
    );

    // Genetic kind, stack full (16 turning points): the worst of a tick on the innermost
    // branch, a tick that reverses (the stack being full, it retraces), and a tick that wipes
    // out every stored turning point (θ beyond the outermost).
    let Some((full, last)) = full_stack(genetic) else { swg_firmware_qemu::exit(false) };
    let depth = full.clone().tick(last * 1.001 * RATIO, 0.0, EvalPath::Fast).memory;
    hprintln!("(genetic stack: {} turning points stored)", depth);
    for path in [EvalPath::Fast, EvalPath::Direct] {
        // The last excursion ended at `last`: onward is further, a reversal back by 5 % of A.
        let onward = tick_from(&full, last * 1.001, path);
        let reversal = tick_from(&full, last - 0.05 * AMPLITUDE * last.signum(), path);
        let wipe_out = tick_from(&full, 1.05 * AMPLITUDE, path);
        let worst = onward.max(reversal).max(wipe_out);
        hprintln!(
            "genetic, {} turning points, {:?} path, per tick: on the branch {}, reversal {}, wipe-out of all {}; worst {}",
            TURNING_POINTS, path, onward, reversal, wipe_out, worst
        );
    }
    // Micro-slip kind, 16 elements: a tick in the middle of a branch, and a reversal.
    let Some((slipping, last)) = full_stack(slip) else { swg_firmware_qemu::exit(false) };
    let onward = tick_from(&slipping, last * 1.001, EvalPath::Fast);
    let reversal = tick_from(&slipping, last - 0.05 * AMPLITUDE * last.signum(), EvalPath::Fast);
    let big = tick_from(&slipping, 1.05 * AMPLITUDE, EvalPath::Fast);
    hprintln!(
        "micro-slip, {} elements, per tick: on the branch {}, reversal {}, large step {}; worst {}",
        SLIP_ELEMENTS,
        onward,
        reversal,
        big,
        onward.max(reversal).max(big)
    );
    // The controller with its evaluator, model mode, from the same states: the worst of the
    // same three ticks for each kind (fast path).
    let Some((genetic_full, genetic_last)) = full_stack(genetic) else { swg_firmware_qemu::exit(false) };
    let state = controlling(genetic_full, genetic_last);
    let genetic_ticks = [
        control_from(&state, genetic_last * 1.001),
        control_from(&state, genetic_last - 0.05 * AMPLITUDE * genetic_last.signum()),
        control_from(&state, 1.05 * AMPLITUDE),
    ];
    let Some((slip_full, slip_last)) = full_stack(slip) else { swg_firmware_qemu::exit(false) };
    let state = controlling(slip_full, slip_last);
    let slip_ticks = [
        control_from(&state, slip_last * 1.001),
        control_from(&state, slip_last - 0.05 * AMPLITUDE * slip_last.signum()),
        control_from(&state, 1.05 * AMPLITUDE),
    ];
    for (kind, [onward, reversal, big]) in
        [("genetic, 16 turning points", genetic_ticks), ("micro-slip, 16 elements", slip_ticks)]
    {
        hprintln!(
            "controller + evaluator (model mode), {}, per tick: on the branch {}, reversal {}, large step {}; worst {}",
            kind,
            onward,
            reversal,
            big,
            onward.max(reversal).max(big)
        );
    }
    let motion = nested_motion();
    for (kind, params) in [("genetic", genetic), ("micro-slip", slip)] {
        let (alone, controlled) = along(params, &motion);
        hprintln!(
            "{} along a nested motion from rest, mean per tick: compensator {}, controller + evaluator (model mode) {}",
            kind,
            alone,
            controlled
        );
    }
    swg_firmware_qemu::exit(true)
}
