//! The joint firmware on the QEMU mps2-an386 board, in replay and lockstep mode: the link on
//! UART0 carries the parameter traffic, the encoder samples (one tick per sample) and the
//! lockstep control ticks of a plant simulated on the host (`swg-host hil`), whose motor
//! command goes back over the link ([`swg_firmware_qemu::LinkDrive`]).
//!
//! Two priorities, as on the real board:
//! - **The control tick**: the SysTick exception at [`TICK_HZ`], priority 0 (the highest; no
//!   other interrupt is enabled). Each tick takes the link's command, if any, and runs a
//!   lockstep sample handed over (this board has no encoders of its own): the sample's tick
//!   runs in the interrupt, exactly as the board's own would.
//! - **UART0's receive interrupt** (IRQ 0), priority 0x80, below the tick: moves the received
//!   byte into a lock-free queue (heapless `spsc`) for the link.
//! - **The link**: thread mode, below every interrupt: takes bytes from that queue, decodes
//!   requests, answers (UART0's transmitter, polled), prepares parameter sets, commits them to
//!   "flash" (RAM here). It hands work to the tick through `swg_joint::handoff` (lock-free
//!   queues) and waits for a sample's answer in a loop the tick preempts.
//!
//! The only critical sections are the two handovers of the tick's state (`HandOver`, a word
//! moved at boot and at the first tick). The tick measures its own timing: the latency from
//! SysTick's expiry to the handler (reload − current value, read first), the periods with no
//! tick (Timer0 runs free at the same 25 MHz), the time to the tick's end, and whether SysTick
//! expired again before the tick ended (its COUNTFLAG, read at the start and the end);
//! `Request::GetStatus` reports them.
//! Under `qemu-system-arm -icount shift=0` virtual time is the instruction count, so these
//! figures measure the firmware, not the load of the machine QEMU runs on (the tests use it).
//! The link polls RAM, never a register, and never sleeps: under `-icount` each register read
//! costs QEMU an exit (polling UART0 made virtual time crawl at 3 % of real time), and a `wfi`
//! lets QEMU warp virtual time past a SysTick expiry (`sleep=off`: two expiries merged into one
//! tick, seen as missed periods) or by the host's late wake-up (`sleep=on`: late ticks).
#![no_std]
#![no_main]

use cortex_m::peripheral::{NVIC, SYST};
use cortex_m_rt::{entry, exception};
use embedded_io::Write;
use heapless::spsc::{Consumer, Producer, Queue};
use swg_firmware_qemu::uart::{Uart0, Uart0Rx};
use swg_firmware_qemu::{timer::FreeRunning, LinkDrive};
use swg_joint::handoff::{Handoff, LinkPort, TickPort, TickTiming};
use swg_joint::handover::HandOver;
use swg_joint::{flash::RamFlash, storage::ParamStore, Joint, Server, TickStart};

/// Two 1 KiB slots; QEMU's machine has no flash controller, so "flash" is RAM here and
/// lasts until QEMU exits. The storage logic is the same as on a real board.
type BoardFlash = RamFlash<2048>;

/// SysTick's clock on this machine (the CPU clock QEMU models), Hz.
const CLOCK_HZ: u32 = 25_000_000;
/// The control tick's rate, as the STM32F405 board's.
const TICK_HZ: u32 = 20_000;
/// A tick that starts more than this after its timer expired is late, ns (50 counts).
const LATE_BOUND_NS: u32 = 2_000;
const TIMING: TickTiming = TickTiming::new(CLOCK_HZ, TICK_HZ, LATE_BOUND_NS);

/// What the SysTick handler owns.
struct Tick {
    joint: Joint,
    port: TickPort<'static>,
    drive: LinkDrive,
    syst: SYST,
    clock: FreeRunning,
}

static TICK: HandOver<&'static mut Tick> = HandOver::new();
/// The receive interrupt's end of the received bytes' queue.
static RECEIVED: HandOver<Producer<'static, u8>> = HandOver::new();

/// What the link runs on, in thread mode.
struct Link {
    server: &'static mut Server<&'static mut BoardFlash>,
    port: LinkPort<'static>,
    received: Consumer<'static, u8>,
    uart: Uart0,
}

#[entry]
fn main() -> ! {
    swg_firmware_qemu::paint_stack();
    let (Link { server, mut port, mut received, mut uart }, tick_port, clock, core) = statics();
    // The stored set, staged for the first tick: from here, not under the frame that built the
    // statics (the deepest the link's stack gets is decoding a stored set).
    server.boot(&mut port);
    let version = swg_joint::FIRMWARE_VERSION;
    // The version's numbers as defmt's own integers: its `Display` would pull in core::fmt's
    // number formatting (about 300 bytes of flash).
    defmt::info!(
        "joint firmware {}.{}.{} on mps2-an386: protocol {}, model {}, tick {} Hz",
        version.major,
        version.minor,
        version.patch,
        swg_protocol::PROTOCOL_VERSION,
        model_core::MODEL_VERSION,
        TICK_HZ
    );
    let syst = start_tick(core.SCB, core.NVIC, core.SYST);
    // The ticks before this handover (a few instructions away) find no state and return.
    let tick = Tick { joint: Joint::new(), port: tick_port, drive: LinkDrive::default(), syst, clock };
    let Some(tick) = cortex_m::singleton!(: Tick = tick) else { swg_firmware_qemu::exit(false) };
    TICK.put(tick);

    loop {
        if let Some(reply) = server.poll(&mut port) {
            let _ = uart.write_all(reply);
        }
        if !server.ready(&port) {
            continue;
        }
        if let Some(byte) = received.dequeue() {
            if let Some(reply) = server.receive(byte, &mut port) {
                let _ = uart.write_all(reply);
            }
        }
    }
}

/// The statics: the flash, the handoff, the received bytes' queue, the server (without its
/// stored set yet). Not inlined: building them passes them through the stack, gone before the
/// link runs.
#[inline(never)]
fn statics() -> (Link, TickPort<'static>, FreeRunning, cortex_m::Peripherals) {
    let (Some(uart), Some(clock), Some(core)) = (Uart0::take(), FreeRunning::take(), cortex_m::Peripherals::take())
    else {
        swg_firmware_qemu::exit(false)
    };
    let Some(flash) = cortex_m::singleton!(: BoardFlash = BoardFlash::new()) else { swg_firmware_qemu::exit(false) };
    let Ok(store) = ParamStore::new(flash) else { swg_firmware_qemu::exit(false) };
    let Some(handoff) = cortex_m::singleton!(: Handoff = Handoff::new(TIMING)) else { swg_firmware_qemu::exit(false) };
    // A request's frame (512 bytes at most) arrives while the link reads it byte by byte.
    let Some(received) = cortex_m::singleton!(: Queue<u8, 256> = Queue::new()) else { swg_firmware_qemu::exit(false) };
    let (producer, received): (Producer<'static, u8>, Consumer<'static, u8>) = received.split();
    RECEIVED.put(producer);
    let (port, tick_port) = handoff.split();
    let Some(server) = cortex_m::singleton!(: Server<&'static mut BoardFlash> = Server::new(store)) else {
        swg_firmware_qemu::exit(false)
    };
    (Link { server, port, received, uart }, tick_port, clock, core)
}

/// SysTick at [`TICK_HZ`] from the CPU clock, its exception at priority 0, the highest; UART0's
/// receive interrupt below it.
#[allow(unsafe_code)]
fn start_tick(mut scb: cortex_m::peripheral::SCB, mut nvic: NVIC, mut syst: SYST) -> SYST {
    swg_joint::systick::start(&mut scb, &mut syst, &TIMING);
    // SAFETY: no code relies on this priority for memory safety (the receive interrupt touches
    // one UART register and a lock-free queue); unmasking IRQ 0 runs `DefaultHandler`, which
    // expects it.
    unsafe {
        nvic.set_priority(Uart0Rx, 0x80);
        NVIC::unmask(Uart0Rx);
    }
    syst
}

/// One control tick: its timing first, then the joint's work, then how long it took and
/// whether SysTick expired again meanwhile.
#[exception]
fn SysTick() {
    static mut STATE: Option<&'static mut Tick> = None;
    // First: the counts since the expiry.
    let latency = swg_joint::systick::latency(&TIMING);
    if STATE.is_none() {
        *STATE = TICK.take();
    }
    let Some(tick) = STATE.as_deref_mut() else { return };
    let start = TickStart { latency, now: tick.clock.now() };
    let (joint, drive) = (&mut tick.joint, &mut tick.drive);
    swg_joint::systick::timed(&mut tick.syst, &TIMING, start, &mut tick.port, |port, start| {
        joint.lockstep_tick(port, Some(start), drive)
    });
}

/// The interrupts without a handler of their own: UART0's receive interrupt, the only one
/// enabled besides SysTick. The byte goes to the link's queue; were it full (the link holds at
/// most one frame at a time, so it is not), the byte would be dropped and its frame refused.
// cortex-m-rt requires `unsafe` on this handler, and gives it no safe handler-local statics.
#[allow(unsafe_code)]
#[exception]
unsafe fn DefaultHandler(_irqn: i16) {
    static mut QUEUE: Option<Producer<'static, u8>> = None;
    // SAFETY: QUEUE is this handler's alone, and the handler does not preempt itself.
    let queue = unsafe { &mut *core::ptr::addr_of_mut!(QUEUE) };
    if queue.is_none() {
        *queue = RECEIVED.take();
    }
    if let (Some(byte), Some(queue)) = (Uart0::take_received(), queue.as_mut()) {
        let _ = queue.enqueue(byte);
    }
}
