//! CMSDK APB UART0 of the mps2-an386 at 0x4000_4000: received bytes taken by its receive
//! interrupt (IRQ 0, [`Uart0::take_received`]) into a queue the link reads; bytes out polled, as
//! an embedded-io port (QEMU's transmitter is never full for long).
use core::convert::Infallible;
use core::ptr;

const BASE: usize = 0x4000_4000;
const DATA: usize = BASE;
const STATE: usize = BASE + 0x04;
const CTRL: usize = BASE + 0x08;
const INTSTATUS: usize = BASE + 0x0C;
const BAUDDIV: usize = BASE + 0x10;
const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_ENABLE: u32 = 1 << 0;
const CTRL_RX_ENABLE: u32 = 1 << 1;
const CTRL_RX_INTERRUPT: u32 = 1 << 3;
const INT_RX: u32 = 1 << 1;

/// UART0's receive interrupt in the NVIC.
#[derive(Clone, Copy, Debug)]
pub struct Uart0Rx;

// SAFETY: IRQ 0 is UART0's receive interrupt on the mps2-an386, a valid interrupt number.
#[allow(unsafe_code)]
unsafe impl cortex_m::interrupt::InterruptNumber for Uart0Rx {
    fn number(self) -> u16 {
        0
    }
}

/// UART0; exists once (see [`Uart0::take`]).
pub struct Uart0 {
    _private: (),
}

// The register accesses: the only unsafe code of this board besides `paint_stack`.
#[allow(unsafe_code)]
impl Uart0 {
    /// Enables the UART and its receive interrupt request (the NVIC line stays masked until the
    /// board unmasks [`Uart0Rx`]); `None` when it was taken before.
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
            ptr::write_volatile(CTRL as *mut u32, CTRL_TX_ENABLE | CTRL_RX_ENABLE | CTRL_RX_INTERRUPT);
        }
        Some(Uart0 { _private: () })
    }

    /// For the receive interrupt's handler, the only reader of received bytes: clears the
    /// interrupt, then takes the received byte, if any (QEMU holds one and never overruns).
    pub fn take_received() -> Option<u8> {
        // SAFETY: writing 1 to INTSTATUS's RX bit clears that interrupt and nothing else;
        // reading STATE has no side effect; reading DATA takes the received byte, which only
        // this function does (the `Uart0` instance only transmits).
        unsafe {
            ptr::write_volatile(INTSTATUS as *mut u32, INT_RX);
            if ptr::read_volatile(STATE as *const u32) & STATE_RX_FULL == 0 {
                return None;
            }
            Some(ptr::read_volatile(DATA as *const u32) as u8)
        }
    }

    fn state(&self) -> u32 {
        // SAFETY: reading UART0's status register has no side effect.
        unsafe { ptr::read_volatile(STATE as *const u32) }
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
