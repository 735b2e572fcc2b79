//! The QEMU mps2-an386 board (Cortex-M4F): UART0 for the link, SysTick for counting
//! instructions, semihosting to end the emulation with a status.
#![no_std]

#[cfg(not(target_arch = "arm"))]
compile_error!("the firmware runs on thumbv7em-none-eabihf: build it from firmware/ (see firmware/.cargo/config.toml)");

// The defmt transport under QEMU: frames go to QEMU's stdout.
use defmt_semihosting as _;
use panic_semihosting as _;

pub mod uart;

/// Ends the emulation with exit status 0 or 1.
pub fn exit(success: bool) -> ! {
    use cortex_m_semihosting::debug;
    debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    // Without QEMU's semihosting (a debugger attached instead), stay here.
    loop {
        cortex_m::asm::wfi();
    }
}
