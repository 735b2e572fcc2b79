//! Instructions per T_ff + K evaluation and per control tick on the emulated Cortex-M4F. Run
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
use swg_joint::{Compensator, FastModel, TURNING_POINTS};
use swg_protocol::{EvalPath, JointModel, JointParams, MODEL_VERSION, SLIP_ELEMENTS};

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
/// run; the copy is measured alone and subtracted).
fn tick_from(state: &Compensator, theta: f32, path: EvalPath) -> f32 {
    let copies = ticks(|| {
        for _ in 0..RUNS {
            black_box(black_box(state).clone());
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
        model: JointModel::Genetic(params),
        gear_ratio: RATIO,
        torque_limit: 100.0,
        direction_band: 1.0e-6,
    };
    let slip = JointParams { model: JointModel::MicroSlip(MICRO_SLIP_SET.to_f32().into()), ..genetic };

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
    swg_firmware_qemu::exit(true)
}
