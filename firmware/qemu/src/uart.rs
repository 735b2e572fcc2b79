//! CMSDK APB UART0 of the mps2-an386 at 0x4000_4000, polled, as an embedded-io port.
use core::convert::Infallible;
use core::ptr;

const BASE: usize = 0x4000_4000;
const DATA: usize = BASE;
const STATE: usize = BASE + 0x04;
const CTRL: usize = BASE + 0x08;
const BAUDDIV: usize = BASE + 0x10;
const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_ENABLE: u32 = 1 << 0;
const CTRL_RX_ENABLE: u32 = 1 << 1;

/// UART0; exists once (see [`Uart0::take`]).
pub struct Uart0 {
    _private: (),
}

// The register accesses: the only unsafe code of this board besides `paint_stack`.
#[allow(unsafe_code)]
impl Uart0 {
    /// Enables the UART; `None` when it was taken before.
    pub fn take() -> Option<Self> {
        use core::sync::atomic::{AtomicBool, Ordering};
        static TAKEN: AtomicBool = AtomicBool::new(false);
        if TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        // SAFETY: MMIO registers of UART0 on this machine, owned by this single instance.
        // BAUDDIV must be ≥ 16; QEMU ignores the rate. Without TX enable TX stays full.
        unsafe {
            ptr::write_volatile(BAUDDIV as *mut u32, 16);
            ptr::write_volatile(CTRL as *mut u32, CTRL_TX_ENABLE | CTRL_RX_ENABLE);
        }
        Some(Uart0 { _private: () })
    }

    fn state(&self) -> u32 {
        // SAFETY: reading UART0's status register has no side effect.
        unsafe { ptr::read_volatile(STATE as *const u32) }
    }

    fn read_byte(&mut self) -> Option<u8> {
        if self.state() & STATE_RX_FULL == 0 {
            return None;
        }
        // SAFETY: owned MMIO register; reading DATA takes the received byte.
        Some(unsafe { ptr::read_volatile(DATA as *const u32) } as u8)
    }

    fn write_byte(&mut self, byte: u8) {
        while self.state() & STATE_TX_FULL != 0 {}
        // SAFETY: owned MMIO register; TX has room.
        unsafe { ptr::write_volatile(DATA as *mut u32, u32::from(byte)) }
    }
}

impl embedded_io::ErrorType for Uart0 {
    type Error = Infallible;
}

impl embedded_io::Read for Uart0 {
    /// Waits for at least one byte, then returns what is there.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let mut count = 0;
        for slot in buf.iter_mut() {
            let byte = loop {
                match self.read_byte() {
                    Some(byte) => break Some(byte),
                    None if count > 0 => break None,
                    None => {}
                }
            };
            match byte {
                Some(byte) => {
                    *slot = byte;
                    count += 1;
                }
                None => break,
            }
        }
        Ok(count)
    }
}

impl embedded_io::Write for Uart0 {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        for &byte in buf {
            self.write_byte(byte);
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}
