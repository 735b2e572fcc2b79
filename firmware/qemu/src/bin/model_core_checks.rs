//! model-core's checks and the fast path's error bound, on the emulated Cortex-M4F: the
//! target's libm, soft-float f64 helpers and FPU instructions instead of the host's.
//! Prints one line per failure and "N passed, M failed"; exits 0 only if all passed.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use model_core::checks::{ALL, PAPER_TABLE_2, SEED_TABLE_FIT};
use swg_joint::fast::verify::check_fast_path;

#[entry]
fn main() -> ! {
    let mut passed = 0u32;
    let mut failed = 0u32;
    let mut record = |name: &str, result: Result<(), &dyn core::fmt::Debug>| match result {
        Ok(()) => {
            passed += 1;
            hprintln!("ok      {}", name);
        }
        Err(failure) => {
            failed += 1;
            hprintln!("FAILED  {}: {:?}", name, failure);
        }
    };
    for (name, check) in ALL {
        record(name, check().as_ref().map(|_| ()).map_err(|f| f as &dyn core::fmt::Debug));
    }
    for (set, params) in [("paper", PAPER_TABLE_2), ("seed fit", SEED_TABLE_FIT)] {
        for amplitude in [0.3e-3f32, 1.168e-3, 2.0e-3] {
            let result = check_fast_path(&params, amplitude);
            let name = "fast path within its bound of f64";
            hprintln!("        ({} parameters, A = {} rad)", set, amplitude);
            record(name, result.as_ref().map(|_| ()).map_err(|v| v as &dyn core::fmt::Debug));
        }
    }
    // The direct path's √ (the FPU's `vsqrt`) and asin (integer f64 steps) against libm's, on
    // the target's own FPU and integer code: every 67th f32 from 0.5 to 1 of either sign (the
    // asin branch libm computes in f64), every 4099th non-negative f32 for √.
    let asin_misses = (0x3f00_0000u32..=0x3f80_0000)
        .step_by(67)
        .flat_map(|bits| [f32::from_bits(bits), -f32::from_bits(bits)])
        .find(|&x| swg_joint::direct::asin(x).to_bits() != libm::asinf(x).to_bits());
    record("direct path: asin is libm's, bit for bit", asin_misses.as_ref().map_or(Ok(()), |x| Err(x as _)));
    let sqrt_misses = (0..0x7f80_0000u32)
        .step_by(4099)
        .map(f32::from_bits)
        .find(|&v| swg_joint::fast::sqrt(v).to_bits() != libm::sqrtf(v).to_bits());
    let name = "direct path: vsqrt is libm's sqrtf, bit for bit";
    record(name, sqrt_misses.as_ref().map_or(Ok(()), |v| Err(v as _)));
    hprintln!("model-core on Cortex-M4F (QEMU): {} passed, {} failed", passed, failed);
    swg_firmware_qemu::exit(failed == 0)
}
