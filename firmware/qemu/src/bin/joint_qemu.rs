//! The joint firmware on the QEMU mps2-an386 board, in replay and lockstep mode: the link on
//! UART0 carries the parameter traffic, the encoder samples (one tick per sample) and the
//! lockstep control ticks of a plant simulated on the host (`swg-host hil`), whose motor
//! command goes back over the link ([`swg_firmware_qemu::LinkDrive`]).
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use embedded_io::{Read, Write};
use swg_firmware_qemu::{uart::Uart0, LinkDrive};
use swg_joint::{flash::RamFlash, storage::ParamStore, Server};
use swg_protocol::MAX_FRAME_LEN;

/// Two 1 KiB slots; QEMU's machine has no flash controller, so "flash" is RAM here and
/// lasts until QEMU exits. The storage logic is the same as on a real board.
type BoardFlash = RamFlash<2048>;

#[entry]
fn main() -> ! {
    swg_firmware_qemu::paint_stack();
    let Some(mut uart) = Uart0::take() else { swg_firmware_qemu::exit(false) };
    // Both in statics, built in place: `size` accounts for them, and the 2 KiB of flash never
    // pass through the stack.
    let Some(flash) = cortex_m::singleton!(: BoardFlash = BoardFlash::new()) else { swg_firmware_qemu::exit(false) };
    let Ok(store) = ParamStore::new(flash) else { swg_firmware_qemu::exit(false) };
    let Some(server) = cortex_m::singleton!(: Server<&'static mut BoardFlash> = Server::new(store)) else {
        swg_firmware_qemu::exit(false)
    };
    defmt::info!(
        "joint firmware {} on mps2-an386: protocol {}, model {}",
        defmt::Display2Format(&swg_joint::FIRMWARE_VERSION),
        swg_protocol::PROTOCOL_VERSION,
        model_core::MODEL_VERSION
    );
    let mut response = [0u8; MAX_FRAME_LEN];
    let mut byte = [0u8; 1];
    let mut drive = LinkDrive::default();
    loop {
        let Ok(1) = uart.read(&mut byte) else { continue };
        if let Some(len) = server.receive_driving(byte[0], &mut response, &mut drive) {
            let _ = uart.write_all(response.get(..len).unwrap_or_default());
        }
    }
}
