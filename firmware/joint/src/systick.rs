//! SysTick as both boards' control tick (Cortex-M only): its set-up, and the timing around one
//! tick that the link reports (`Request::GetStatus`).
use crate::handoff::{TickPort, TickTiming};
use crate::TickStart;
use cortex_m::peripheral::scb::SystemHandler;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};

/// SysTick expiring every `timing.period` counts of the core clock, its exception at priority
/// 0 (the highest), counting. A board sets its link's interrupt (below it) itself.
#[allow(unsafe_code)]
pub fn start(scb: &mut SCB, syst: &mut SYST, timing: &TickTiming) {
    // SAFETY: no code relies on this priority for memory safety (the tick shares only
    // lock-free queues and atomics with the link); 0 is SysTick's value at reset, set here to
    // say so.
    unsafe { scb.set_priority(SystemHandler::SysTick, 0) };
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(timing.period - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// SysTick's counts since its expiry: a handler reads this first.
#[inline(always)]
pub fn latency(timing: &TickTiming) -> u32 {
    timing.since_expiry(SYST::get_current())
}

/// One timed tick after [`latency`]: `work` with the tick's start (`now`: the board's
/// free-running clock, read at the handler's start), then the counts to its end and whether
/// SysTick expired again meanwhile, to `port`.
#[inline(always)]
pub fn timed(
    syst: &mut SYST,
    timing: &TickTiming,
    start: TickStart,
    port: &mut TickPort<'_>,
    work: impl FnOnce(&mut TickPort<'_>, TickStart),
) {
    // Reading COUNTFLAG clears it: set from here on means a new expiry during this tick.
    syst.has_wrapped();
    work(port, start);
    let elapsed = timing.since_expiry(SYST::get_current());
    let overran = syst.has_wrapped();
    port.finish(elapsed, overran);
}
