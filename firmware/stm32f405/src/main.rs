//! The joint firmware on an STM32F405 joint drive (ODrive v3 class). Board glue only: the
//! pins and peripherals; the control tick, the link and the parameter store are `swg-joint`,
//! tested on the host.
//!
//! Wiring: input (motor) and output AS5047P encoders on SPI3 (PC10 SCK, PC11 MISO, PC12
//! MOSI; chip selects PB3 input, PB4 output); the link on USART2 (PA2 TX, PA3 RX) at
//! 115200 baud; a 20 kHz control tick from SysTick at 168 MHz; the motor torque command to the
//! motor driver's analog current-reference input on PA4 (DAC channel 1, see [`DacCurrentReference`]).
//!
//! # Priorities: why the link cannot stall the tick
//!
//! | context | priority | what it does |
//! | --- | --- | --- |
//! | SysTick | 0x00, the highest | the control tick: both encoders, the model, the torque loop, the DAC |
//! | USART2 | 0x40 | moves bytes between the UART and two lock-free queues (heapless `spsc`) |
//! | thread mode | the lowest | the link: frames, requests, replies, range checks of new sets, flash commits |
//!
//! The tick preempts everything else; no other interrupt is enabled. The link hands it work
//! through `swg_joint::handoff` (lock-free queues, atomic counters) and never masks
//! interrupts. A reply is queued for the USART2 interrupt, which sends it a byte at a time
//! (128 bytes take 11 ms at 115200 baud, 220 ticks, during which the tick runs as usual). The
//! only critical sections are the handovers of the handlers' state (`HandOver`: a word moved
//! at boot and at each handler's first run); nothing logs over RTT once the tick runs
//! (defmt-rtt's writes are critical sections).
//!
//! **Flash commits.** This part has one flash bank: erasing a sector (sectors 10 and 11 hold
//! the parameters, 128 KiB each, 1–2 s to erase, up to 4 s) stalls every instruction fetch
//! from flash, the tick's included. So the link refuses a commit while the controller is
//! configured to drive the motor (`ErrorReply::CommitWhileDriving`): with the controller off
//! the tick's command is zero and the DAC holds it through the erase. The ticks the erase
//! stalls are counted as missed periods (the DWT cycle counter tells the time between two
//! ticks), so they show in `Request::GetStatus`.
//!
//! # Worst-case tick, against the 50 µs period
//!
//! - Exception entry and exit, with the FPU's lazy stacking: about 40 cycles.
//! - Encoders: each AS5047P read is two 16-bit SPI frames, two more when the sensor flags an
//!   error (to read and clear ERRFL); the output encoder is read only when the input one
//!   succeeded. Worst: 2 + 4 = 6 frames at 5.25 MHz (42 MHz APB1 / 8) = 6 × 3.05 µs = 18.3 µs,
//!   plus the chip-select gaps (≥ 350 ns, the sensor's) and the HAL's polling, about 1 µs per
//!   frame: about 24 µs.
//! - Controller + evaluator: ≤ 600 instructions per tick in the QEMU benchmark
//!   (`bench/firmware.sh`, model mode: at most 546 over its measured ticks, a full genetic
//!   memory wiped out; about 418 on average along a nested motion for the genetic kind). The whole lockstep tick under QEMU — the
//!   handoff, the timing, a sample's answer, a new set's install included — measured at most
//!   1,600 instructions (`worst_tick_ns` in `host/tests/tick_e2e.rs`, one instruction per ns
//!   under `-icount shift=0`). At ≤ 2 cycles per instruction (flash wait states behind the
//!   ART accelerator, FPU divisions) that is ≤ 3,200 cycles = 19 µs.
//! - The DAC write and the turn counters: well under 1 µs.
//!
//! About 44 µs in the worst case against 50 µs; about 25 µs on a tick with both encoders
//! answering (4 frames) and no new set to install. The firmware measures it: the status's
//! `worst_tick_ns` is the longest time from a SysTick expiry to its tick's end, and
//! `overruns` the ticks that ran into the next expiry.
#![no_std]
#![no_main]

#[cfg(not(target_arch = "arm"))]
compile_error!("the firmware runs on thumbv7em-none-eabihf: build it from firmware/ (see firmware/.cargo/config.toml)");

use cortex_m::peripheral::{DWT, NVIC, SYST};
use cortex_m_rt::{entry, exception};
use defmt_rtt as _;
use embedded_hal_bus::spi::{AtomicDevice, NoDelay};
use embedded_hal_bus::util::AtomicCell;
use embedded_hal_nb::serial::{Read as _, Write as _};
use heapless::spsc::{Consumer, Producer, Queue};
use panic_probe as _;
use stm32f4xx_hal::{
    dac::{DacExt, DacOut, DacPin, C1},
    flash::{FlashExt, LockedFlash},
    gpio::{Output, Pin, PinState},
    pac::{self, interrupt, Interrupt, SPI3, USART2},
    prelude::*,
    rcc::Config,
    serial::{Rx, RxListen, Tx, TxISR, TxListen},
    spi::{Mode, Phase, Polarity, Spi},
};
use swg_joint::handoff::{Handoff, TickPort, TickTiming};
use swg_joint::handover::HandOver;
use swg_joint::Readings;
use swg_joint::{as5047p::As5047p, drive, flash::Region, sensor, storage::ParamStore, AngleSensor, MotorDrive};
use swg_joint::{Joint, Server, TickStart, TurnCounter};

const SYSCLK_HZ: u32 = 168_000_000;
const TICK_HZ: u32 = 20_000;
/// A tick that starts more than this after its timer expired is late, ns (336 cycles: the
/// exception entry takes 12 of them).
const LATE_BOUND_NS: u32 = 2_000;
/// SysTick and the DWT cycle counter both count the core clock.
const TIMING: TickTiming = TickTiming::new(SYSCLK_HZ, TICK_HZ, LATE_BOUND_NS);
/// Flash sectors 10 and 11, as offsets from the start of flash (see memory.x).
const PARAM_FLASH_START: u32 = 0xC_0000;
const PARAM_FLASH_LEN: u32 = 0x4_0000;
/// The motor torque at full scale of the current reference, N·m at the motor shaft: the motor
/// driver is set up so that 0 V … 3.3 V on its reference input spans −this … +this (its
/// current gain times the motor's torque constant). Set it to the drive's configuration.
const FULL_SCALE_TORQUE: f32 = 1.0;
/// USART2's priority: below SysTick's 0 (the upper four bits count on this part).
const LINK_PRIORITY: u8 = 0x40;

/// The motor driver's current (torque) reference as an analog voltage: DAC channel 1 on PA4,
/// 12 bits, mid-scale (2048, 1.65 V) = zero torque, 0 and 4095 = ∓[`FULL_SCALE_TORQUE`]. A
/// servo amplifier in torque mode (or a FOC stage with an analog current command) reads it and
/// closes the current loop. The controller's command is already clamped to its
/// `command_limit`; a command beyond the full scale is refused, so that a configuration that
/// asks for more than the driver is set up for cannot pass silently.
struct DacCurrentReference {
    channel: C1,
}

/// A command beyond the DAC's full scale.
#[derive(Debug)]
struct BeyondFullScale;

impl drive::Error for BeyondFullScale {
    fn kind(&self) -> drive::ErrorKind {
        drive::ErrorKind::OutOfRange
    }
}

impl drive::ErrorType for DacCurrentReference {
    type Error = BeyondFullScale;
}

impl MotorDrive for DacCurrentReference {
    fn apply(&mut self, torque: f32) -> Result<(), BeyondFullScale> {
        let unit = torque / FULL_SCALE_TORQUE;
        if !(-1.0..=1.0).contains(&unit) {
            // Refused (NaN too): the driver holds the last reference until the next tick.
            return Err(BeyondFullScale);
        }
        // [−1, 1] → [0, 4095]: 2047.5·(1 + unit), rounded.
        let code = (2047.5 * (1.0 + unit) + 0.5) as u16;
        self.channel.set_value(code.min(4095));
        Ok(())
    }
}

/// SPI3, shared by the two encoders: both are the tick's, so they never contend for it (an
/// atomic flag marks it in use, no lock).
type Bus = AtomicCell<Spi<SPI3>>;
type Encoder<const PIN: u8> = As5047p<AtomicDevice<'static, Spi<SPI3>, Pin<'B', PIN, Output>, NoDelay>>;

/// What the SysTick handler owns.
struct Tick {
    joint: Joint,
    port: TickPort<'static>,
    drive: DacCurrentReference,
    syst: SYST,
    input_encoder: Encoder<3>,
    output_encoder: Encoder<4>,
    /// Both shafts can cross the sensors' zero: turns are counted on both sides.
    input_turns: TurnCounter,
    output_turns: TurnCounter,
}

/// What the USART2 handler owns: the UART's halves and its ends of the byte queues.
struct Link {
    rx: Rx<USART2>,
    tx: Tx<USART2>,
    received: Producer<'static, u8>,
    to_send: Consumer<'static, u8>,
}

static TICK: HandOver<&'static mut Tick> = HandOver::new();
static LINK: HandOver<&'static mut Link> = HandOver::new();

#[entry]
// A board that cannot set up its peripherals stops at boot: panic-probe reports the message
// over RTT and halts, before the control tick ever runs.
#[allow(clippy::panic)]
fn main() -> ! {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        panic!("peripherals taken twice")
    };
    let mut rcc = dp.RCC.freeze(Config::hse(8.MHz()).sysclk(SYSCLK_HZ.Hz()));
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    let Ok(serial) = dp.USART2.serial::<u8>((gpioa.pa2, gpioa.pa3), 115_200.bps(), &mut rcc) else {
        panic!("USART2 configuration")
    };
    let (tx, mut rx) = serial.split();
    rx.listen();

    // AS5047P: SPI mode 1, ≤ 10 MHz. SPI3 runs from APB1 (42 MHz) with a power-of-two
    // prescaler: 6 MHz asked gives 42/8 = 5.25 MHz (8 MHz asked gave 42/4 = 10.5 MHz, beyond
    // the sensor's limit).
    let mode = Mode { polarity: Polarity::IdleLow, phase: Phase::CaptureOnSecondTransition };
    let spi = dp.SPI3.spi((Some(gpioc.pc10), Some(gpioc.pc11), Some(gpioc.pc12)), mode, 6.MHz(), &mut rcc);
    let Some(bus) = cortex_m::singleton!(: Bus = AtomicCell::new(spi)) else { panic!("SPI bus taken twice") };
    let cs_input = gpiob.pb3.into_push_pull_output_in_state(PinState::High);
    let cs_output = gpiob.pb4.into_push_pull_output_in_state(PinState::High);
    // GPIO outputs cannot fail on this chip, so the bus devices are infallible.
    let Ok(input_device) = AtomicDevice::new_no_delay(bus, cs_input);
    let Ok(output_device) = AtomicDevice::new_no_delay(bus, cs_output);

    let mut flash = LockedFlash::new(dp.FLASH);
    let Some(region) = Region::new(flash.unlocked(), PARAM_FLASH_START, PARAM_FLASH_LEN) else {
        panic!("parameter flash region")
    };
    let Ok(store) = ParamStore::new(region) else { panic!("parameter store") };
    // The current reference starts at zero torque before the control tick runs.
    let mut dac = dp.DAC.constrain(gpioa.pa4.into_analog(), &mut rcc);
    dac.enable();
    let mut drive = DacCurrentReference { channel: dac };
    let _ = drive.apply(0.0);

    let Some(handoff) = cortex_m::singleton!(: Handoff = Handoff::new(TIMING)) else { panic!("handoff taken twice") };
    let (mut link_port, tick_port) = handoff.split();
    let mut server = Server::new(store);
    server.boot(&mut link_port);
    let joint = Joint::new();
    let Some(received) = cortex_m::singleton!(: Queue<u8, 256> = Queue::new()) else { panic!("queue taken twice") };
    let (received_in, mut received) = received.split();
    let Some(to_send) = cortex_m::singleton!(: Queue<u8, 256> = Queue::new()) else { panic!("queue taken twice") };
    let (mut sending, to_send) = to_send.split();
    let link = Link { rx, tx, received: received_in, to_send };
    let Some(link) = cortex_m::singleton!(: Link = link) else { panic!("link taken twice") };
    LINK.put(link);
    defmt::info!("joint firmware {} on STM32F405", defmt::Display2Format(&swg_joint::FIRMWARE_VERSION));

    // The free-running clock for the time between two ticks.
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    let syst = start(&mut cp.SCB, &mut cp.NVIC, cp.SYST);
    // The ticks before this handover (a few instructions away) find no state and return.
    let tick = Tick {
        joint,
        port: tick_port,
        drive,
        syst,
        input_encoder: As5047p::new(input_device),
        output_encoder: As5047p::new(output_device),
        input_turns: TurnCounter::default(),
        output_turns: TurnCounter::default(),
    };
    let Some(tick) = cortex_m::singleton!(: Tick = tick) else { panic!("tick taken twice") };
    TICK.put(tick);

    // The link, in thread mode below both interrupts.
    loop {
        // A lockstep sample's answer, else (when ready for the next byte) a request's reply.
        let reply = if !server.ready(&link_port) {
            server.poll(&mut link_port)
        } else {
            match received.dequeue() {
                Some(byte) => server.receive(byte, &mut link_port),
                // Nothing to do until a byte arrives or the tick runs.
                None => {
                    cortex_m::asm::wfi();
                    None
                }
            }
        };
        if let Some(reply) = reply {
            for &byte in reply {
                // A full queue (two replies still on the wire) drains at 11.5 bytes per ms.
                while sending.enqueue(byte).is_err() {
                    NVIC::pend(Interrupt::USART2);
                }
            }
            // The handler starts the transmission.
            NVIC::pend(Interrupt::USART2);
        }
    }
}

/// SysTick at [`TICK_HZ`] from the core clock at priority 0, USART2 below it, both enabled.
#[allow(unsafe_code)]
fn start(scb: &mut cortex_m::peripheral::SCB, nvic: &mut NVIC, mut syst: SYST) -> SYST {
    swg_joint::systick::start(scb, &mut syst, &TIMING);
    // SAFETY: no code relies on this priority for memory safety (the handlers share only
    // lock-free queues and atomics with the link); unmasking USART2 runs its handler, which
    // expects it.
    unsafe {
        nvic.set_priority(Interrupt::USART2, LINK_PRIORITY);
        NVIC::unmask(Interrupt::USART2);
    }
    syst
}

/// One control tick: its timing first, then both encoders, the joint's work and the DAC, then
/// how long it took and whether SysTick expired again meanwhile.
#[exception]
fn SysTick() {
    static mut STATE: Option<&'static mut Tick> = None;
    // First: the counts since the expiry.
    let latency = swg_joint::systick::latency(&TIMING);
    if STATE.is_none() {
        *STATE = TICK.take();
    }
    let Some(tick) = STATE.as_deref_mut() else { return };
    let start = TickStart { latency, now: DWT::cycle_count() };
    let Tick { joint, port, drive, syst, input_encoder, output_encoder, input_turns, output_turns } = tick;
    swg_joint::systick::timed(syst, &TIMING, start, port, |port, start| {
        // No torque sensor wired on this board yet: an experiment stops at its first tick
        // (StopReason::SensorFault) rather than record without the torque.
        let readings = input_encoder
            .read_angle()
            .and_then(|input| Ok((input, output_encoder.read_angle()?)))
            .map(|(input, output)| Readings {
                input_angle: input_turns.update(input),
                output_angle: output_turns.update(output),
                torque: None,
                temperature: None,
            })
            .map_err(|error| sensor::Error::kind(&error));
        joint.own_tick(port, start, readings, drive);
    });
}

/// USART2: received bytes into the link's queue (a full queue drops the byte: its frame then
/// fails its check and the host retries); queued reply bytes out while the transmitter is empty,
/// its interrupt off once none are left.
#[interrupt]
fn USART2() {
    static mut STATE: Option<&'static mut Link> = None;
    if STATE.is_none() {
        *STATE = LINK.take();
    }
    let Some(link) = STATE.as_deref_mut() else { return };
    // The hardware holds one byte; a read with an error (overrun, noise, framing) clears it.
    for _ in 0..2 {
        match link.rx.read() {
            Ok(byte) => {
                let _ = link.received.enqueue(byte);
            }
            Err(stm32f4xx_hal::nb::Error::WouldBlock) => break,
            Err(stm32f4xx_hal::nb::Error::Other(_)) => {}
        }
    }
    while link.tx.is_tx_empty() {
        match link.to_send.dequeue() {
            Some(byte) => {
                let _ = link.tx.write(byte);
            }
            None => break,
        }
    }
    if link.to_send.ready() {
        link.tx.listen();
    } else {
        link.tx.unlisten();
    }
}
