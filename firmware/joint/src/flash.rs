//! Flash adapters: a window onto part of a chip's flash, and flash held in RAM for boards
//! without a flash driver (QEMU) and for tests.
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};

/// The sectors `[start, start + len)` of `flash`, addressed from 0: keeps the parameter store
/// away from the program in the same flash.
pub struct Region<F> {
    flash: F,
    start: u32,
    len: u32,
}

impl<F: NorFlash> Region<F> {
    /// `None` unless the window is erase-aligned and inside the flash.
    pub fn new(flash: F, start: u32, len: u32) -> Option<Self> {
        let erase = u32::try_from(F::ERASE_SIZE).ok()?;
        let end = start.checked_add(len)?;
        let aligned = start % erase == 0 && len % erase == 0;
        (aligned && end as usize <= flash.capacity()).then_some(Region { flash, start, len })
    }

    fn offset(&self, offset: u32, len: usize) -> Result<u32, NorFlashErrorKind> {
        let len = u32::try_from(len).map_err(|_| NorFlashErrorKind::OutOfBounds)?;
        match offset.checked_add(len) {
            Some(end) if end <= self.len => Ok(self.start + offset),
            _ => Err(NorFlashErrorKind::OutOfBounds),
        }
    }
}

impl<F: NorFlash> ErrorType for Region<F> {
    type Error = NorFlashErrorKind;
}

impl<F: NorFlash> ReadNorFlash for Region<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let at = self.offset(offset, bytes.len())?;
        self.flash.read(at, bytes).map_err(|e| e.kind())
    }

    fn capacity(&self) -> usize {
        self.len as usize
    }
}

impl<F: NorFlash> NorFlash for Region<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let len = to.checked_sub(from).ok_or(NorFlashErrorKind::OutOfBounds)?;
        let at = self.offset(from, len as usize)?;
        self.flash.erase(at, at + len).map_err(|e| e.kind())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let at = self.offset(offset, bytes.len())?;
        self.flash.write(at, bytes).map_err(|e| e.kind())
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_region_stays_inside_its_window() {
        assert!(Region::new(RamFlash::<4096>::new(), 512, 1024).is_none(), "unaligned");
        assert!(Region::new(RamFlash::<4096>::new(), 3072, 2048).is_none(), "past the end");
        let mut region = Region::new(RamFlash::<4096>::new(), 2048, 2048).unwrap();
        assert_eq!(region.capacity(), 2048);
        region.write(0, &[1, 2, 3, 4]).unwrap();
        assert_eq!(region.write(2048, &[0; 4]), Err(NorFlashErrorKind::OutOfBounds));
        let mut flash = region.flash.clone();
        let mut bytes = [0u8; 4];
        flash.read(2048, &mut bytes).unwrap();
        assert_eq!(bytes, [1, 2, 3, 4]);
        flash.read(0, &mut bytes).unwrap();
        assert_eq!(bytes, [0xFF; 4], "nothing below the window was touched");
    }
}
