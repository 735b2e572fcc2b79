//! AS5047P (and the AS5047D/AS5048A family): 14-bit absolute magnetic angle sensor on SPI
//! mode 1, 16-bit frames, MSB first.
//!
//! Command frame: bit 15 even parity, bit 14 read, bits 13..0 address. Every frame answers
//! the previous one (bit 15 even parity, bit 14 error flag, bits 13..0 data), so a read
//! takes two frames, each in its own chip-select cycle as the sensor requires.
use crate::sensor::{self, AngleSensor, ErrorKind};
use embedded_hal::spi::SpiDevice;

/// Angle with dynamic angle error compensation.
const ANGLECOM: u16 = 0x3FFF;
/// Error register, cleared by reading it.
const ERRFL: u16 = 0x0001;
const NOP: u16 = 0x0000;
const READ: u16 = 1 << 14;
const ERROR_FLAG: u16 = 1 << 14;
const DATA_MASK: u16 = 0x3FFF;
const COUNTS_PER_TURN: f32 = 16384.0;

/// What went wrong reading the sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error<E> {
    Spi(E),
    /// The answer's parity bit is wrong: the frame was corrupted.
    Parity,
    /// The sensor flagged an error; ERRFL bits: 0 framing, 1 invalid command, 2 parity.
    Sensor {
        errfl: u16,
    },
}

impl<E: core::fmt::Debug> core::fmt::Display for Error<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::Spi(error) => write!(f, "SPI error: {error:?}"),
            Error::Parity => f.write_str("AS5047P answer failed its parity check"),
            Error::Sensor { errfl } => write!(f, "AS5047P reported error flags {errfl:#05x}"),
        }
    }
}

impl<E: core::fmt::Debug> sensor::Error for Error<E> {
    fn kind(&self) -> ErrorKind {
        match self {
            Error::Spi(_) => ErrorKind::Bus,
            Error::Parity => ErrorKind::Corrupt,
            Error::Sensor { .. } => ErrorKind::Sensor,
        }
    }
}

pub struct As5047p<SPI> {
    spi: SPI,
}

impl<SPI: SpiDevice> As5047p<SPI> {
    pub fn new(spi: SPI) -> Self {
        As5047p { spi }
    }

    pub fn release(self) -> SPI {
        self.spi
    }

    /// Raw 14-bit angle, 0..16384 per turn.
    pub fn read_counts(&mut self) -> Result<u16, Error<SPI::Error>> {
        self.read_register(ANGLECOM)
    }

    fn read_register(&mut self, address: u16) -> Result<u16, Error<SPI::Error>> {
        self.frame(read_command(address))?;
        let answer = self.frame(read_command(NOP))?;
        if !has_even_parity(answer) {
            return Err(Error::Parity);
        }
        if answer & ERROR_FLAG != 0 {
            // Reading ERRFL returns the reason and clears the flag.
            self.frame(read_command(ERRFL))?;
            let errfl = self.frame(read_command(NOP))?;
            return Err(Error::Sensor { errfl: errfl & DATA_MASK });
        }
        Ok(answer & DATA_MASK)
    }

    fn frame(&mut self, command: u16) -> Result<u16, Error<SPI::Error>> {
        let mut buffer = command.to_be_bytes();
        self.spi.transfer_in_place(&mut buffer).map_err(Error::Spi)?;
        Ok(u16::from_be_bytes(buffer))
    }
}

impl<SPI: SpiDevice> sensor::ErrorType for As5047p<SPI> {
    type Error = Error<SPI::Error>;
}

impl<SPI: SpiDevice> AngleSensor for As5047p<SPI> {
    fn read_angle(&mut self) -> Result<f32, Self::Error> {
        let counts = self.read_counts()?;
        Ok(f32::from(counts) * (core::f32::consts::TAU / COUNTS_PER_TURN))
    }
}

fn read_command(address: u16) -> u16 {
    with_parity(READ | (address & DATA_MASK))
}

/// Sets bit 15 so that the frame has an even number of ones.
fn with_parity(frame: u16) -> u16 {
    let low = frame & 0x7FFF;
    if low.count_ones() % 2 == 1 {
        low | 0x8000
    } else {
        low
    }
}

fn has_even_parity(frame: u16) -> bool {
    frame.count_ones() % 2 == 0
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use embedded_hal_mock::eh1::spi::{Mock, Transaction};
    use std::{vec, vec::Vec};

    /// One chip-select cycle sending `command` and answering `answer`.
    fn frame(command: u16, answer: u16) -> Vec<Transaction<u8>> {
        vec![
            Transaction::transaction_start(),
            Transaction::transfer_in_place(command.to_be_bytes().to_vec(), answer.to_be_bytes().to_vec()),
            Transaction::transaction_end(),
        ]
    }

    fn expect(frames: &[(u16, u16)]) -> Mock<u8> {
        Mock::new(&frames.iter().flat_map(|&(c, a)| frame(c, a)).collect::<Vec<_>>())
    }

    #[test]
    fn command_frames_match_the_datasheet() {
        // Datasheet examples: read ANGLECOM = 0xFFFF, read NOP = 0xC000, read ERRFL = 0x4001.
        assert_eq!(read_command(ANGLECOM), 0xFFFF);
        assert_eq!(read_command(NOP), 0xC000);
        assert_eq!(read_command(ERRFL), 0x4001);
    }

    #[test]
    fn reads_the_angle() {
        // 0x1000 = a quarter turn; 0x1000 has one bit set, so parity bit 15 is set.
        let mut sensor = As5047p::new(expect(&[(0xFFFF, 0x0000), (0xC000, 0x9000)]));
        let angle = sensor.read_angle().unwrap();
        assert!((angle - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
        sensor.release().done();
    }

    #[test]
    fn a_corrupted_answer_fails_parity() {
        let mut sensor = As5047p::new(expect(&[(0xFFFF, 0x0000), (0xC000, 0x1000)]));
        let error = sensor.read_angle().unwrap_err();
        assert_eq!((error, sensor::Error::kind(&error)), (Error::Parity, ErrorKind::Corrupt));
        sensor.release().done();
    }

    #[test]
    fn the_error_flag_reads_and_clears_errfl() {
        // EF set (bit 14) with even parity; ERRFL answers 0x0004 = parity error on MOSI.
        let mut sensor =
            As5047p::new(expect(&[(0xFFFF, 0x0000), (0xC000, 0x4001), (0x4001, 0x0000), (0xC000, 0x8004)]));
        let error = sensor.read_angle().unwrap_err();
        assert_eq!((error, sensor::Error::kind(&error)), (Error::Sensor { errfl: 0x0004 }, ErrorKind::Sensor));
        sensor.release().done();
    }
}
