//! Panics on purpose: `scripts/test-firmware.sh` runs it under QEMU and asks for the failure
//! status that the board's panic handler (`swg_firmware_qemu`) ends the emulation with, so that
//! a panic in any QEMU program can never pass for success.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use swg_firmware_qemu as _;

#[entry]
fn main() -> ! {
    // black_box: the panic is reached at run time, not folded away.
    #[allow(clippy::panic)]
    if core::hint::black_box(true) {
        panic!("panic-check: a deliberate panic");
    }
    swg_firmware_qemu::exit(true)
}
