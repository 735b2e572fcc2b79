//! The QEMU mps2-an386 board (Cortex-M4F): UART0 for the link, SysTick for the control tick
//! (and for counting instructions in the benchmark), Timer0 as the tick's free-running clock,
//! semihosting to end the emulation with a status.
#![no_std]

#[cfg(not(target_arch = "arm"))]
compile_error!("the firmware runs on thumbv7em-none-eabihf: build it from firmware/ (see firmware/.cargo/config.toml)");

// The defmt transport under QEMU: frames go to QEMU's stdout.
use defmt_semihosting as _;

/// Ends the emulation with a failure status, after printing where the panic happened (and its
/// message where it is a plain string) over defmt.
///
/// Our own rather than `panic-semihosting`'s: that one formats the panic's message with
/// `core::fmt`, whose machinery was 2,340 B of the 48 KiB flash budget (`bench/firmware.sh`),
/// for code the firmware is built never to reach (clippy denies panicking constructs).
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let message = info.message().as_str().unwrap_or("(a formatted message)");
    match info.location() {
        Some(at) => {
            defmt::error!("panicked at {=str}:{=u32}:{=u32}: {=str}", at.file(), at.line(), at.column(), message)
        }
        None => defmt::error!("panicked: {=str}", message),
    }
    cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

pub mod timer;
pub mod uart;

extern "C" {
    /// cortex-m-rt's handler of the interrupts without one of their own: a program's own
    /// (`#[exception] fn DefaultHandler`, as `joint-qemu`'s for UART0) or its default.
    fn DefaultHandler();
}

/// The interrupt vectors after the exceptions' (cortex-m-rt's `device` feature, as a PAC
/// provides them): the one interrupt the board enables, UART0's receive interrupt (IRQ 0,
/// [`uart::Uart0Rx`]), to `DefaultHandler`. Without it cortex-m-rt puts in all 240 of
/// ARMv7-M's, 960 B of flash. An interrupt beyond this table must stay masked (none is
/// unmasked: the NVIC resets with every line disabled).
// SAFETY (the unsafe_code lint's `no_mangle` and `link_section`): this is the symbol and
// section cortex-m-rt's link.x places right after the exception vectors; nothing else is
// named so.
#[allow(unsafe_code)]
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
pub static __INTERRUPTS: [unsafe extern "C" fn(); 1] = [DefaultHandler];

/// The QEMU board's motor drive: this machine has no motor, the plant is simulated on the host
/// (`swg-host hil`), and the command reaches it in the lockstep [`swg_protocol::Response::Control`]
/// that answers each control tick. The drive keeps the last command and counts them (for a
/// debugger or a log); it never refuses one.
#[derive(Clone, Copy, Debug, Default)]
pub struct LinkDrive {
    /// The last motor torque command, N·m at the motor shaft.
    pub last: f32,
    /// Commands applied since boot.
    pub count: u32,
}

impl swg_joint::drive::ErrorType for LinkDrive {
    type Error = core::convert::Infallible;
}

impl swg_joint::MotorDrive for LinkDrive {
    fn apply(&mut self, torque: f32) -> Result<(), Self::Error> {
        self.last = torque;
        self.count = self.count.wrapping_add(1);
        Ok(())
    }
}

/// The pattern [`paint_stack`] writes; bench/firmware.sh reads the deepest overwritten word
/// through QEMU's monitor to measure the stack's high-water mark.
pub const STACK_PAINT: u32 = 0x5AFE_57AC;
/// How far below the top of RAM (the stack's start) the stack is painted.
pub const STACK_PAINT_BYTES: usize = 16 * 1024;

/// Fills the stack's unused part, down to [`STACK_PAINT_BYTES`] below its start, with
/// [`STACK_PAINT`]. Call once at boot, before interrupts are enabled.
#[inline(never)]
#[allow(unsafe_code)]
pub fn paint_stack() {
    extern "C" {
        // cortex-m-rt's initial stack pointer: the top of RAM.
        static _stack_start: u32;
    }
    let top = core::ptr::addr_of!(_stack_start) as usize;
    // Everything below this function's frame is unused: no interrupts run yet, and Arm
    // code never uses memory below the stack pointer.
    let below_frame = cortex_m::register::msp::read() as usize - 16;
    let mut address = top - STACK_PAINT_BYTES;
    while address < below_frame {
        // SAFETY: RAM between the bottom of the painted area and the live stack, which
        // nothing else uses (the statics lie at the start of RAM, 4 MiB below).
        unsafe { core::ptr::write_volatile(address as *mut u32, STACK_PAINT) };
        address += 4;
    }
}

/// Ends the emulation with exit status 0 or 1.
pub fn exit(success: bool) -> ! {
    use cortex_m_semihosting::debug;
    debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    // Without QEMU's semihosting (a debugger attached instead), stay here.
    loop {
        cortex_m::asm::wfi();
    }
}
