//! The joint firmware on an STM32F405 joint drive (ODrive v3 class). Board glue only: the
//! pins and peripherals are in `Board`; the control tick, the link and the parameter store
//! are `swg-joint`, tested on the host.
//!
//! Wiring: input (motor) and output AS5047P encoders on SPI3 (PC10 SCK, PC11 MISO, PC12
//! MOSI; chip selects PB3 input, PB4 output); the link on USART2 (PA2 TX, PA3 RX) at
//! 115200 baud; a 20 kHz control tick from SysTick at 168 MHz; the motor torque command to the
//! motor driver's analog current-reference input on PA4 (DAC channel 1, see [`DacCurrentReference`]).
#![no_std]
#![no_main]

#[cfg(not(target_arch = "arm"))]
compile_error!("the firmware runs on thumbv7em-none-eabihf: build it from firmware/ (see firmware/.cargo/config.toml)");

use core::cell::RefCell;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::entry;
use defmt_rtt as _;
use embedded_hal_bus::spi::RefCellDevice;
use embedded_hal_nb::serial::Read as _;
use embedded_io::Write as _;
use panic_probe as _;
use stm32f4xx_hal::{
    dac::{DacExt, DacOut, DacPin, C1},
    flash::{FlashExt, LockedFlash},
    pac,
    prelude::*,
    rcc::Config,
    spi::{Mode, Phase, Polarity},
    timer::SysDelay,
};
use swg_joint::{as5047p::As5047p, flash::Region, storage::ParamStore, AngleSensor, MotorDrive, Server, TurnCounter};
use swg_protocol::MAX_FRAME_LEN;

const SYSCLK_HZ: u32 = 168_000_000;
const TICK_HZ: u32 = 20_000;
/// Flash sectors 10 and 11, as offsets from the start of flash (see memory.x).
const PARAM_FLASH_START: u32 = 0xC_0000;
const PARAM_FLASH_LEN: u32 = 0x4_0000;
/// The motor torque at full scale of the current reference, N·m at the motor shaft: the motor
/// driver is set up so that 0 V … 3.3 V on its reference input spans −this … +this (its
/// current gain times the motor's torque constant). Set it to the drive's configuration.
const FULL_SCALE_TORQUE: f32 = 1.0;

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

impl MotorDrive for DacCurrentReference {
    type Error = BeyondFullScale;
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

#[entry]
// A board that cannot set up its peripherals stops at boot: panic-probe reports the message
// over RTT and halts, before the control tick ever runs.
#[allow(clippy::panic)]
fn main() -> ! {
    let (Some(dp), Some(cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        panic!("peripherals taken twice")
    };
    let mut rcc = dp.RCC.freeze(Config::hse(8.MHz()).sysclk(SYSCLK_HZ.Hz()));
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    let Ok(mut link) = dp.USART2.serial::<u8>((gpioa.pa2, gpioa.pa3), 115_200.bps(), &mut rcc) else {
        panic!("USART2 configuration")
    };

    // AS5047P: SPI mode 1, ≤ 10 MHz.
    let mode = Mode { polarity: Polarity::IdleLow, phase: Phase::CaptureOnSecondTransition };
    let spi = dp.SPI3.spi((Some(gpioc.pc10), Some(gpioc.pc11), Some(gpioc.pc12)), mode, 8.MHz(), &mut rcc);
    let bus = RefCell::new(spi);
    let delay: SysDelay = cp.SYST.delay(&rcc.clocks);
    let mut syst = delay.release().release();
    let cs_input = gpiob.pb3.into_push_pull_output_in_state(stm32f4xx_hal::gpio::PinState::High);
    let cs_output = gpiob.pb4.into_push_pull_output_in_state(stm32f4xx_hal::gpio::PinState::High);
    // GPIO outputs cannot fail on this chip, so the bus devices are infallible.
    let Ok(input_device) = RefCellDevice::new_no_delay(&bus, cs_input);
    let Ok(output_device) = RefCellDevice::new_no_delay(&bus, cs_output);
    let mut input_encoder = As5047p::new(input_device);
    let mut output_encoder = As5047p::new(output_device);

    let mut flash = LockedFlash::new(dp.FLASH);
    let Some(region) = Region::new(flash.unlocked(), PARAM_FLASH_START, PARAM_FLASH_LEN) else {
        panic!("parameter flash region")
    };
    let Ok(store) = ParamStore::new(region) else { panic!("parameter store") };
    let mut server = Server::new(store);
    // The current reference starts at zero torque before the control tick runs.
    let mut dac = dp.DAC.constrain(gpioa.pa4.into_analog(), &mut rcc);
    dac.enable();
    let mut drive = DacCurrentReference { channel: dac };
    let _ = drive.apply(0.0);
    defmt::info!("joint firmware {} on STM32F405", defmt::Display2Format(&swg_joint::FIRMWARE_VERSION));

    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(SYSCLK_HZ / TICK_HZ - 1);
    syst.clear_current();
    syst.enable_counter();
    // Both shafts can cross the sensors' zero: count turns on both sides.
    let mut input_turns = TurnCounter::default();
    let mut output_turns = TurnCounter::default();
    let mut response = [0u8; MAX_FRAME_LEN];
    loop {
        if syst.has_wrapped() {
            // One control tick at the reference set over the link (`Request::SetReference`):
            // the model's step, the torque loop in the configured mode, the command to the
            // DAC. A failed encoder reading commands zero torque for this tick.
            match (input_encoder.read_angle(), output_encoder.read_angle()) {
                (Ok(input), Ok(output)) => {
                    let (input, output) = (input_turns.update(input), output_turns.update(output));
                    if let Err(error) = server.control_tick(input, output, &mut drive) {
                        defmt::warn!("motor command refused: {}", defmt::Debug2Format(&error));
                    }
                }
                _ => {
                    let _ = drive.apply(0.0);
                }
            }
        }
        if let Ok(byte) = link.read() {
            if let Some(len) = server.receive(byte, &mut response) {
                let _ = link.write_all(response.get(..len).unwrap_or_default());
            }
        }
    }
}
