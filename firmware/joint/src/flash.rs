//! Flash held in RAM, for boards without a flash driver (QEMU) and for tests.
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};

/// NOR flash semantics in RAM: erase sets bytes to 0xFF, a write can only clear bits.
#[derive(Clone, Debug)]
pub struct RamFlash<const SIZE: usize> {
    bytes: [u8; SIZE],
}

impl<const SIZE: usize> Default for RamFlash<SIZE> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const SIZE: usize> RamFlash<SIZE> {
    /// Erased flash.
    pub const fn new() -> Self {
        RamFlash { bytes: [0xFF; SIZE] }
    }

    fn range(&self, offset: u32, len: usize, align: usize) -> Result<core::ops::Range<usize>, NorFlashErrorKind> {
        let start = offset as usize;
        if start % align != 0 || len % align != 0 {
            return Err(NorFlashErrorKind::NotAligned);
        }
        let end = start.checked_add(len).filter(|&end| end <= SIZE);
        end.map(|end| start..end).ok_or(NorFlashErrorKind::OutOfBounds)
    }
}

impl<const SIZE: usize> ErrorType for RamFlash<SIZE> {
    type Error = NorFlashErrorKind;
}

impl<const SIZE: usize> ReadNorFlash for RamFlash<SIZE> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let range = self.range(offset, bytes.len(), Self::READ_SIZE)?;
        let source = self.bytes.get(range).ok_or(NorFlashErrorKind::OutOfBounds)?;
        bytes.copy_from_slice(source);
        Ok(())
    }

    fn capacity(&self) -> usize {
        SIZE
    }
}

impl<const SIZE: usize> NorFlash for RamFlash<SIZE> {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = 1024;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let len = (to as usize).checked_sub(from as usize).ok_or(NorFlashErrorKind::OutOfBounds)?;
        let range = self.range(from, len, Self::ERASE_SIZE)?;
        self.bytes.get_mut(range).ok_or(NorFlashErrorKind::OutOfBounds)?.fill(0xFF);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let range = self.range(offset, bytes.len(), Self::WRITE_SIZE)?;
        let target = self.bytes.get_mut(range).ok_or(NorFlashErrorKind::OutOfBounds)?;
        for (cell, byte) in target.iter_mut().zip(bytes) {
            *cell &= byte;
        }
        Ok(())
    }
}
