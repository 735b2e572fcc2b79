//! Instructions per T_ff + K evaluation on the emulated Cortex-M4F. Run under
//! `qemu-system-arm -icount shift=0`: one instruction per ns of virtual time, SysTick at
//! 25 MHz, so one SysTick tick is 40 instructions, exactly repeatable (bench/firmware.sh).
#![no_std]
#![no_main]

use core::hint::black_box;
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use model_core::{checks::SEED_TABLE_FIT, Direction, Model};
use swg_joint::FastModel;
use swg_protocol::{EvalPath, JointParams, MODEL_VERSION};

const INSTRUCTIONS_PER_TICK: u32 = 40;
const RUNS: u32 = 2000;
const AMPLITUDE: f32 = 1.168e-3;

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

#[entry]
fn main() -> ! {
    let Some(mut core) = cortex_m::Peripherals::take() else { swg_firmware_qemu::exit(false) };
    core.SYST.set_clock_source(SystClkSource::Core);
    core.SYST.set_reload(0x00FF_FFFF);
    core.SYST.clear_current();
    core.SYST.enable_counter();

    let params = SEED_TABLE_FIT.to_f32();
    let (Ok(model), Ok(fast)) = (Model::new(params), FastModel::new(&params)) else { swg_firmware_qemu::exit(false) };
    let mut compensator = swg_joint::Compensator::new();
    let joint = JointParams {
        model_version: MODEL_VERSION,
        model: params,
        gear_ratio: 100.0,
        torque_limit: 100.0,
        direction_band: 1.0e-6,
    };
    if compensator.stage(joint).is_err() {
        swg_firmware_qemu::exit(false)
    }

    // The loop and the black boxes alone, subtracted from every measurement.
    let baseline = ticks(|| {
        for i in 0..RUNS {
            black_box(point(black_box(i)));
        }
    });
    let direct = ticks(|| {
        for i in 0..RUNS {
            let (theta, direction) = point(black_box(i));
            // As a tick runs it: the loop's constants for the current amplitude, then T and K.
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
    let tick = ticks(|| {
        for i in 0..RUNS {
            let (theta, _) = point(black_box(i));
            // θ_in = N·θ with θ_out = 0: a full tick incl. deflection and direction tracking.
            black_box(compensator.tick(theta * 100.0, 0.0, EvalPath::Fast));
        }
    });
    hprintln!("instructions per T_ff + K evaluation, direct (model-core f32, libm): {}", per_run(direct, baseline));
    hprintln!("instructions per T_ff + K evaluation, fast path: {}", per_run(fast_path, baseline));
    hprintln!(
        "instructions per full control tick (deflection, tracking, fast path, clamp): {}",
        per_run(tick, baseline)
    );
    swg_firmware_qemu::exit(true)
}
