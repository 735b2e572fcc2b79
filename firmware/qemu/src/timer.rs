//! CMSDK APB Timer0 of the mps2-an386 at 0x4000_0000, free-running at the 25 MHz system clock
//! (SysTick's): the control tick's clock for the time between two timer expiries, which
//! SysTick's current value alone cannot tell beyond one period.
use core::ptr;

const BASE: usize = 0x4000_0000;
const CTRL: usize = BASE;
const VALUE: usize = BASE + 0x04;
const RELOAD: usize = BASE + 0x08;
const CTRL_ENABLE: u32 = 1 << 0;

/// Timer0, counting down from 2³² − 1 and wrapping (every 172 s at 25 MHz).
pub struct FreeRunning {
    _private: (),
}

// The register accesses.
#[allow(unsafe_code)]
impl FreeRunning {
    /// Starts Timer0; `None` when it was taken before.
    pub fn take() -> Option<Self> {
        use core::sync::atomic::{AtomicBool, Ordering};
        static TAKEN: AtomicBool = AtomicBool::new(false);
        if TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        // SAFETY: MMIO registers of Timer0 on this machine, owned by this single instance; its
        // interrupt stays disabled.
        unsafe {
            ptr::write_volatile(RELOAD as *mut u32, u32::MAX);
            ptr::write_volatile(VALUE as *mut u32, u32::MAX);
            ptr::write_volatile(CTRL as *mut u32, CTRL_ENABLE);
        }
        Some(FreeRunning { _private: () })
    }

    /// Counts since the start, wrapping.
    pub fn now(&self) -> u32 {
        // SAFETY: reading Timer0's current value has no side effect.
        u32::MAX - unsafe { ptr::read_volatile(VALUE as *const u32) }
    }
}
