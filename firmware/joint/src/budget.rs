//! The firmware's budgets, in one place: `bench/firmware.sh` measures the QEMU build against
//! them (the benchmark binary, `firmware/qemu/src/bin/bench.rs`, exits non-zero when an
//! instruction count exceeds its budget; the script checks flash and RAM) and fails.
//!
//! Instruction counts are per control tick on the Cortex-M4F, the fast path where there is
//! one, and hold for **every** tick of the benchmark's motions from rest (the maximum and the
//! mean), not only for chosen ticks.
use model_core::Kind;
use swg_protocol::GearModel;

/// Flash of the QEMU build (text + data), bytes.
pub const FLASH_BYTES: u32 = 48 * 1024;

/// RAM of the QEMU build (data + bss + the stack's high-water mark), bytes.
pub const RAM_BYTES: u32 = 8 * 1024;

/// Instructions of one tick of the torque controller with its evaluator
/// (`Controller::tick` in model mode), every tick.
pub const CONTROL_TICK_INSTRUCTIONS: u32 = 600;

/// Instructions of one tick of the bare evaluator of `model`'s kind (`Compensator::tick`),
/// every tick. A new kind adds its arm here: the one place the firmware looks at the kind.
pub const fn evaluator_tick_instructions(model: &GearModel<f32>) -> u32 {
    match model.kind() {
        Kind::Genetic => 400,
        Kind::MicroSlip => 400,
        Kind::BoucWen => 400,
        Kind::Preisach => 400,
    }
}
