//! The parameter set in flash, as two slots with a sequence number and a CRC.
//!
//! A commit erases the older slot, writes the record without its CRC, then the CRC, and reads
//! it back. Power lost at any point leaves the older slot intact, and the slot being written either
//! without a matching CRC (ignored) or complete, so the newest valid record is always the
//! old or the new set. Records that no longer validate (another model version) are ignored.
use embedded_storage::nor_flash::NorFlash;
use swg_protocol::JointParams;

const MAGIC: [u8; 4] = *b"SWGP";
/// Magic, sequence number (u32 LE), payload length (u16 LE), 2 bytes reserved.
const HEADER_LEN: usize = 12;
/// Writes are padded to this; every supported flash's WRITE_SIZE divides it.
const ALIGN: usize = 8;
const MAX_PAYLOAD_LEN: usize = 64;
const MAX_BODY_LEN: usize = (HEADER_LEN + MAX_PAYLOAD_LEN).div_ceil(ALIGN) * ALIGN;
const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Why the store could not read or write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StorageError {
    /// The flash cannot hold two slots, or its write size does not divide 8 bytes.
    Geometry,
    /// The flash driver reported an error.
    Flash,
    /// The parameter set did not serialize into a record.
    Encoding,
    /// The record read back differs from what was written (worn or protected flash).
    Verify,
}

impl core::fmt::Display for StorageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StorageError::Geometry => f.write_str("flash region too small or write size unsupported"),
            StorageError::Flash => f.write_str("flash driver error"),
            StorageError::Encoding => f.write_str("parameter set does not fit a record"),
            StorageError::Verify => f.write_str("flash read back differs from what was written"),
        }
    }
}

/// A stored set and its sequence number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stored {
    pub params: JointParams,
    pub sequence: u32,
}

/// Two slots of `ERASE_SIZE`-aligned halves of `flash`.
pub struct ParamStore<F> {
    flash: F,
    slot_len: u32,
}

impl<F: NorFlash> ParamStore<F> {
    pub fn new(flash: F) -> Result<Self, StorageError> {
        let slot_len = (flash.capacity() / 2) / F::ERASE_SIZE * F::ERASE_SIZE;
        let record_len = MAX_BODY_LEN + ALIGN;
        if slot_len < record_len || ALIGN % F::WRITE_SIZE != 0 {
            return Err(StorageError::Geometry);
        }
        let slot_len = u32::try_from(slot_len).map_err(|_| StorageError::Geometry)?;
        Ok(ParamStore { flash, slot_len })
    }

    /// Gives the flash back, e.g. to simulate a reboot in tests.
    pub fn into_flash(self) -> F {
        self.flash
    }

    /// The newest valid record, if any.
    pub fn load(&mut self) -> Option<Stored> {
        self.newest().map(|(_, stored)| stored)
    }

    /// Stores `params` in the slot not holding the newest record; returns its sequence.
    pub fn save(&mut self, params: &JointParams) -> Result<u32, StorageError> {
        let (slot, sequence) = match self.newest() {
            Some((slot, stored)) => (1 - slot, stored.sequence.wrapping_add(1)),
            None => (0, 1),
        };
        let mut body = [0xFFu8; MAX_BODY_LEN];
        let (header, payload_area) = body.split_at_mut(HEADER_LEN);
        let payload_len =
            postcard::to_slice(params, payload_area.get_mut(..MAX_PAYLOAD_LEN).ok_or(StorageError::Encoding)?)
                .map_err(|_| StorageError::Encoding)?
                .len();
        header.copy_from_slice(&header_bytes(sequence, payload_len as u16));
        let body_len = (HEADER_LEN + payload_len).div_ceil(ALIGN) * ALIGN;
        let crc = CRC.checksum(body.get(..HEADER_LEN + payload_len).ok_or(StorageError::Encoding)?);
        let mut crc_block = [0xFFu8; ALIGN];
        crc_block.get_mut(..4).ok_or(StorageError::Encoding)?.copy_from_slice(&crc.to_le_bytes());

        let start = slot * self.slot_len;
        let flash = &mut self.flash;
        flash.erase(start, start + self.slot_len).map_err(|_| StorageError::Flash)?;
        let body = body.get(..body_len).ok_or(StorageError::Encoding)?;
        flash.write(start, body).map_err(|_| StorageError::Flash)?;
        flash.write(start + body_len as u32, &crc_block).map_err(|_| StorageError::Flash)?;
        match self.read_slot(slot) {
            Some(stored) if stored == (Stored { params: *params, sequence }) => Ok(sequence),
            _ => Err(StorageError::Verify),
        }
    }

    fn newest(&mut self) -> Option<(u32, Stored)> {
        let first = self.read_slot(0);
        let second = self.read_slot(1);
        match (first, second) {
            (Some(a), Some(b)) => {
                // Sequence numbers compare modulo 2³² so that wrapping around is harmless.
                if (b.sequence.wrapping_sub(a.sequence) as i32) > 0 {
                    Some((1, b))
                } else {
                    Some((0, a))
                }
            }
            (Some(a), None) => Some((0, a)),
            (None, Some(b)) => Some((1, b)),
            (None, None) => None,
        }
    }

    fn read_slot(&mut self, slot: u32) -> Option<Stored> {
        let start = slot * self.slot_len;
        let mut record = [0u8; MAX_BODY_LEN + ALIGN];
        self.flash.read(start, &mut record).ok()?;
        let (header, rest) = record.split_at(HEADER_LEN);
        if header.get(..4)? != MAGIC {
            return None;
        }
        let sequence = u32::from_le_bytes(header.get(4..8)?.try_into().ok()?);
        let payload_len = usize::from(u16::from_le_bytes(header.get(8..10)?.try_into().ok()?));
        if payload_len > MAX_PAYLOAD_LEN {
            return None;
        }
        let body_len = (HEADER_LEN + payload_len).div_ceil(ALIGN) * ALIGN;
        let crc_at = record.get(body_len..body_len + 4)?;
        let crc = CRC.checksum(record.get(..HEADER_LEN + payload_len)?);
        if crc_at != crc.to_le_bytes() {
            return None;
        }
        let params: JointParams = postcard::from_bytes(rest.get(..payload_len)?).ok()?;
        params.validate().ok()?;
        Some(Stored { params, sequence })
    }
}

fn header_bytes(sequence: u32, payload_len: u16) -> [u8; HEADER_LEN] {
    let mut header = [0xFFu8; HEADER_LEN];
    let (magic, rest) = header.split_at_mut(4);
    magic.copy_from_slice(&MAGIC);
    let (seq, rest) = rest.split_at_mut(4);
    seq.copy_from_slice(&sequence.to_le_bytes());
    if let Some(len) = rest.get_mut(..2) {
        len.copy_from_slice(&payload_len.to_le_bytes());
    }
    header
}

#[cfg(test)]
mod tests;
