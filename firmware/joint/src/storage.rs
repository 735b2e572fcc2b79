//! The parameter set in flash, as two slots with a sequence number and a CRC.
//!
//! A commit erases the older slot, writes the record without its CRC, then the CRC, and reads
//! it back byte for byte. Power lost at any point leaves the older slot intact, and the slot being written either
//! without a matching CRC (ignored) or complete, so the newest valid record is always the
//! old or the new set. Records that no longer validate (another model version) are ignored.
//!
//! A record, from the start of its slot:
//!
//! | bytes | what |
//! | --- | --- |
//! | 0..4 | magic `SWGP` |
//! | 4..8 | sequence number, u32 LE |
//! | 8..10 | payload length n, u16 LE (≤ 384) |
//! | 10 | record format, [`RECORD_FORMAT`] |
//! | 11 | reserved, 0xFF |
//! | 12..12 + n | the parameter set, postcard-encoded (format 5: [`JointParams`] as on the link of protocol 8) |
//! | then | 0xFF up to a multiple of 8 bytes, then the CRC-32 (ISO-HDLC, LE) of bytes 0..12 + n, in an 8-byte block |
//!
//! The formats this firmware reads:
//!
//! - **5** (written now): the payload is [`JointParams`] of model version 2 (θ0, the free-form
//!   spring, the kind's hysteresis: [`swg_protocol::GearModel`]), any kind, the Preisach kind
//!   included. The longest, a Preisach set with 17 knots and 36 weights, is 325 bytes at most: a
//!   record of 344 bytes with its CRC block.
//! - **4** and **3**: the same encoding before the Preisach kind (protocol 7) and before the
//!   Bouc–Wen kind (protocol 6), whose bytes format 5 keeps (a kind is its index, and each new
//!   kind took the next). They load as they are. Older firmware refuses a newer record by its
//!   format byte instead of misreading a kind it does not know.
//! - **2**: the payload is protocol 2–5's [`JointParams`] of model version 1 (the odd polynomial
//!   spring, the genetic kind or the micro-slip kind on a log grid: [`LegacyJointParamsV2`]); it
//!   loads as today's model with the same torque (model-core's `legacy` upgrade).
//! - **1**, and **0xFF** (firmware 0.1.0 wrote no format byte: it left byte 10, reserved then,
//!   erased, in the layout that became format 1): the payload is protocol 1's parameter set,
//!   genetic only ([`LegacyJointParams`]); it loads as the paper's model with the same
//!   numbers.
//!
//! So parameters stored before an update survive it; the next commit writes format 5.
//!
//! A slot whose format byte is another value is not read ([`SlotFault::UnknownFormat`]).
use embedded_storage::nor_flash::NorFlash;
use model_core::legacy::GearModelV1;
use model_core::Params;
use serde::Deserialize;
use swg_protocol::{ErrorReply, JointParams, MODEL_VERSION};

const MAGIC: [u8; 4] = *b"SWGP";
/// The record format this firmware writes (header byte 10). A change of the record's layout
/// or of the payload's encoding takes the next number; the loader then refuses records of
/// formats it does not know instead of misreading them.
pub const RECORD_FORMAT: u8 = 5;
/// Records of protocol 7's parameter sets (no Preisach kind), read as format 5.
pub const FORMAT_4: u8 = 4;
/// Records of protocol 6's parameter sets (no Bouc–Wen kind), read as format 5.
pub const FORMAT_3: u8 = 3;
/// Records of model version 1's parameter sets, either kind ([`LegacyJointParamsV2`]).
pub const FORMAT_2: u8 = 2;
/// Records of protocol 1's parameter set, genetic only ([`LegacyJointParams`]).
pub const LEGACY_FORMAT: u8 = 1;
/// Header byte 10 of records written before the format byte existed: read as format 1.
const UNVERSIONED_FORMAT: u8 = 0xFF;
/// Magic, sequence number (u32 LE), payload length (u16 LE), record format, 1 byte reserved.
const HEADER_LEN: usize = 12;
const FORMAT_AT: usize = 10;
/// Writes are padded to this; every supported flash's WRITE_SIZE divides it.
const ALIGN: usize = 8;
/// Room for the longest payload of every format (325 bytes: a Preisach set with 17 knots, 36
/// weights and a three-byte model version) and some growth. Changing it changes no record's
/// bytes.
const MAX_PAYLOAD_LEN: usize = 384;
const MAX_BODY_LEN: usize = (HEADER_LEN + MAX_PAYLOAD_LEN).div_ceil(ALIGN) * ALIGN;
/// The longest record: body and CRC block.
const RECORD_LEN: usize = MAX_BODY_LEN + ALIGN;

/// Why the store could not write (or be set up): the step that failed, as the link reports it.
pub use swg_protocol::StorageError;

/// Why a slot holds no usable record ([`ParamStore::slots`]); [`ParamStore::load`] passes
/// over such a slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SlotFault {
    /// The flash driver reported an error reading the slot.
    Flash,
    /// No record starts here: the slot is erased, or power was lost before its header landed.
    Empty,
    /// The record's format byte (the value) is not a format this firmware reads: a record
    /// written by a newer firmware.
    UnknownFormat(u8),
    /// The payload length is out of range or the CRC does not match: a torn or damaged write.
    Corrupt,
    /// The payload does not decode as a parameter set.
    Encoding,
    /// The set decodes but fails [`JointParams::validate`] (e.g. fitted for another model version).
    Invalid(ErrorReply),
}

impl core::fmt::Display for SlotFault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SlotFault::Flash => f.write_str("flash driver error"),
            SlotFault::Empty => f.write_str("no record"),
            SlotFault::UnknownFormat(format) => write!(f, "record format {format} is not supported"),
            SlotFault::Corrupt => f.write_str("record length or CRC wrong"),
            SlotFault::Encoding => f.write_str("record payload is not a parameter set"),
            SlotFault::Invalid(error) => write!(f, "stored parameter set is refused: {error:?}"),
        }
    }
}

/// The parameter set of record format 1 (protocol 1's `JointParams`): the genetic model only.
/// Kept to read records stored by firmware before format 2; never written.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
pub struct LegacyJointParams {
    pub model_version: u16,
    pub model: Params<f32>,
    pub gear_ratio: f32,
    pub torque_limit: f32,
    pub direction_band: f32,
}

/// The parameter set of record format 2 (protocol 2–5's `JointParams`): model version 1 of
/// either kind. Kept to read records stored by firmware before format 3; never written.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
pub struct LegacyJointParamsV2 {
    pub model_version: u16,
    pub model: GearModelV1<f32>,
    pub gear_ratio: f32,
    pub torque_limit: f32,
    pub direction_band: f32,
}

/// A stored set of model version 1 as today's (the same torque), if it was of that version.
fn upgrade(model_version: u16, model: GearModelV1<f32>, joint: [f32; 3]) -> Result<JointParams, SlotFault> {
    const VERSION_1: u16 = 1;
    if model_version != VERSION_1 {
        return Err(SlotFault::Invalid(ErrorReply::ModelVersion { got: model_version, supported: MODEL_VERSION }));
    }
    let model = JointParams::upgrade_model(&model).map_err(|_| SlotFault::Encoding)?;
    let [gear_ratio, torque_limit, direction_band] = joint;
    Ok(JointParams { model_version: MODEL_VERSION, model, gear_ratio, torque_limit, direction_band })
}

/// A stored set and its sequence number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stored {
    pub params: JointParams,
    pub sequence: u32,
}

/// Where the newest valid record is, as far as the store knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Newest {
    /// Not looked for yet.
    Unknown,
    /// Neither slot holds a valid record.
    None,
    /// In this slot, with this sequence number.
    At { slot: u32, sequence: u32 },
}

/// Two slots of `ERASE_SIZE`-aligned halves of `flash`.
pub struct ParamStore<F> {
    flash: F,
    slot_len: u32,
    /// Found by [`ParamStore::load`] (or the first [`ParamStore::save`]) and kept by each save:
    /// nothing else writes the slots, so a commit need not read and decode both again (which
    /// made the link's stack deepest).
    newest: Newest,
}

impl<F: NorFlash> ParamStore<F> {
    pub fn new(flash: F) -> Result<Self, StorageError> {
        let slot_len = (flash.capacity() / 2) / F::ERASE_SIZE * F::ERASE_SIZE;
        if slot_len < RECORD_LEN || ALIGN % F::WRITE_SIZE != 0 {
            return Err(StorageError::Geometry);
        }
        let slot_len = u32::try_from(slot_len).map_err(|_| StorageError::Geometry)?;
        Ok(ParamStore { flash, slot_len, newest: Newest::Unknown })
    }

    /// Gives the flash back, e.g. to simulate a reboot in tests.
    pub fn into_flash(self) -> F {
        self.flash
    }

    /// The newest valid record, if any.
    pub fn load(&mut self) -> Option<Stored> {
        self.locate();
        match self.newest {
            Newest::At { slot, .. } => self.read_slot(slot).ok(),
            Newest::None | Newest::Unknown => None,
        }
    }

    /// Stores `params` in the slot not holding the newest record; returns its sequence.
    pub fn save(&mut self, params: &JointParams) -> Result<u32, StorageError> {
        if self.newest == Newest::Unknown {
            self.locate();
        }
        let (slot, sequence) = match self.newest {
            Newest::At { slot, sequence } => (1 - slot, sequence.wrapping_add(1)),
            Newest::None | Newest::Unknown => (0, 1),
        };
        self.write(slot, sequence, params)?;
        self.newest = Newest::At { slot, sequence };
        Ok(sequence)
    }

    /// Writes the record of `params` with `sequence` into `slot` (erased first) and reads it
    /// back. Not inlined: its buffer is on the stack only while it runs.
    #[inline(never)]
    fn write(&mut self, slot: u32, sequence: u32, params: &JointParams) -> Result<(), StorageError> {
        let mut body = [0xFFu8; MAX_BODY_LEN];
        let (header, payload_area) = body.split_at_mut(HEADER_LEN);
        let payload_len = params
            .to_postcard(payload_area.get_mut(..MAX_PAYLOAD_LEN).ok_or(StorageError::Encoding)?)
            .map_err(|_| StorageError::Encoding)?;
        header.copy_from_slice(&header_bytes(sequence, payload_len as u16));
        let body_len = (HEADER_LEN + payload_len).div_ceil(ALIGN) * ALIGN;
        let crc = swg_protocol::crc32(body.get(..HEADER_LEN + payload_len).ok_or(StorageError::Encoding)?);
        let mut crc_block = [0xFFu8; ALIGN];
        crc_block.get_mut(..4).ok_or(StorageError::Encoding)?.copy_from_slice(&crc.to_le_bytes());

        let start = slot * self.slot_len;
        let flash = &mut self.flash;
        flash.erase(start, start + self.slot_len).map_err(|_| StorageError::Erase)?;
        let body = body.get(..body_len).ok_or(StorageError::Encoding)?;
        flash.write(start, body).map_err(|_| StorageError::Write)?;
        flash.write(start + body_len as u32, &crc_block).map_err(|_| StorageError::Write)?;
        // Read back: the slot holds exactly the bytes written, so it decodes to `params` (the
        // bytes compared, not the decoded set: cheaper in flash than comparing every field), a
        // block at a time (no second record's buffer on the stack).
        let mut written = [0u8; ALIGN];
        for (at, expected) in (start..).step_by(ALIGN).zip(body.chunks(ALIGN).chain([&crc_block[..]])) {
            let written = written.get_mut(..expected.len()).ok_or(StorageError::Verify)?;
            flash.read(at, written).map_err(|_| StorageError::Verify)?;
            if written != expected {
                return Err(StorageError::Verify);
            }
        }
        Ok(())
    }

    /// What each of the two slots holds, or why it is not usable (for diagnostics; [`load`]
    /// picks the newer of the usable ones).
    ///
    /// [`load`]: ParamStore::load
    pub fn slots(&mut self) -> [Result<Stored, SlotFault>; 2] {
        [self.read_slot(0), self.read_slot(1)]
    }

    /// Finds the newest valid record's slot and sequence. Each slot is decoded and checked in
    /// full (a record that no longer validates does not count), but only its sequence is kept:
    /// one record at a time on the stack, in frames of their own.
    #[inline(never)]
    fn locate(&mut self) {
        let sequence = |store: &mut Self, slot| store.read_slot(slot).map(|stored| stored.sequence).ok();
        let (first, second) = (sequence(self, 0), sequence(self, 1));
        self.newest = match (first, second) {
            // Sequence numbers compare modulo 2³² so that wrapping around is harmless.
            (Some(a), Some(b)) if (b.wrapping_sub(a) as i32) > 0 => Newest::At { slot: 1, sequence: b },
            (Some(a), _) => Newest::At { slot: 0, sequence: a },
            (None, Some(b)) => Newest::At { slot: 1, sequence: b },
            (None, None) => Newest::None,
        };
    }

    /// The record in `slot`, checked and decoded. Not inlined: the record and the set it holds
    /// are on the stack only while it runs.
    #[inline(never)]
    fn read_slot(&mut self, slot: u32) -> Result<Stored, SlotFault> {
        let start = slot * self.slot_len;
        let mut record = [0u8; RECORD_LEN];
        self.flash.read(start, &mut record).map_err(|_| SlotFault::Flash)?;
        decode(&record)
    }
}

/// The record at the start of a slot, checked and decoded. Not inlined: inside the commit path
/// (and with it the firmware's main loop) its frame made the stack's high-water mark 164 B deeper
/// (bench/firmware.sh).
#[inline(never)]
fn decode(record: &[u8; RECORD_LEN]) -> Result<Stored, SlotFault> {
    let (header, rest) = record.split_at(HEADER_LEN);
    if header.get(..4) != Some(&MAGIC[..]) {
        return Err(SlotFault::Empty);
    }
    // Before anything else of the layout: another format may place it differently.
    let format = match header.get(FORMAT_AT).copied() {
        Some(format @ (RECORD_FORMAT | FORMAT_4 | FORMAT_3 | FORMAT_2 | LEGACY_FORMAT | UNVERSIONED_FORMAT)) => format,
        Some(format) => return Err(SlotFault::UnknownFormat(format)),
        None => return Err(SlotFault::Corrupt),
    };
    let field = |range: core::ops::Range<usize>| header.get(range).ok_or(SlotFault::Corrupt);
    let sequence = u32::from_le_bytes(field(4..8)?.try_into().map_err(|_| SlotFault::Corrupt)?);
    let payload_len = usize::from(u16::from_le_bytes(field(8..10)?.try_into().map_err(|_| SlotFault::Corrupt)?));
    if payload_len > MAX_PAYLOAD_LEN {
        return Err(SlotFault::Corrupt);
    }
    let body_len = (HEADER_LEN + payload_len).div_ceil(ALIGN) * ALIGN;
    let crc_at = record.get(body_len..body_len + 4).ok_or(SlotFault::Corrupt)?;
    let crc = swg_protocol::crc32(record.get(..HEADER_LEN + payload_len).ok_or(SlotFault::Corrupt)?);
    if crc_at != crc.to_le_bytes() {
        return Err(SlotFault::Corrupt);
    }
    let payload = rest.get(..payload_len).ok_or(SlotFault::Corrupt)?;
    let params = match format {
        RECORD_FORMAT | FORMAT_4 | FORMAT_3 => decode_format_5(payload)?,
        FORMAT_2 => decode_format_2(payload)?,
        _ => decode_format_1(payload)?,
    };
    params.validate().map_err(SlotFault::Invalid)?;
    Ok(Stored { params, sequence })
}

// One function per format, none inlined: the stack then holds one format's temporaries at a
// time, not all of theirs.

/// The payload of a format 5 (or 4, or 3) record.
#[inline(never)]
fn decode_format_5(payload: &[u8]) -> Result<JointParams, SlotFault> {
    JointParams::from_postcard(payload).map_err(|_| SlotFault::Encoding)
}

/// The payload of a format 2 record, upgraded.
#[inline(never)]
fn decode_format_2(payload: &[u8]) -> Result<JointParams, SlotFault> {
    let v2: LegacyJointParamsV2 = postcard::from_bytes(payload).map_err(|_| SlotFault::Encoding)?;
    upgrade(v2.model_version, v2.model, [v2.gear_ratio, v2.torque_limit, v2.direction_band])
}

/// The payload of a format 1 (or unversioned) record, upgraded.
#[inline(never)]
fn decode_format_1(payload: &[u8]) -> Result<JointParams, SlotFault> {
    let v1: LegacyJointParams = postcard::from_bytes(payload).map_err(|_| SlotFault::Encoding)?;
    upgrade(v1.model_version, GearModelV1::Genetic(v1.model), [v1.gear_ratio, v1.torque_limit, v1.direction_band])
}

fn header_bytes(sequence: u32, payload_len: u16) -> [u8; HEADER_LEN] {
    let mut header = [0xFFu8; HEADER_LEN];
    let (magic, rest) = header.split_at_mut(4);
    magic.copy_from_slice(&MAGIC);
    let (seq, rest) = rest.split_at_mut(4);
    seq.copy_from_slice(&sequence.to_le_bytes());
    let (len, rest) = rest.split_at_mut(2);
    len.copy_from_slice(&payload_len.to_le_bytes());
    if let Some(format) = rest.first_mut() {
        *format = RECORD_FORMAT;
    }
    header
}

#[cfg(test)]
mod tests;
