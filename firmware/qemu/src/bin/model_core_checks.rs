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
    hprintln!("model-core on Cortex-M4F (QEMU): {} passed, {} failed", passed, failed);
    swg_firmware_qemu::exit(failed == 0)
}
