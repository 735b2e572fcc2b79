extern crate std;
use super::*;
use crate::flash::RamFlash;
use embedded_storage::nor_flash::{ErrorType, NorFlashErrorKind, ReadNorFlash};
use model_core::{Params, MODEL_VERSION};

type Flash = RamFlash<4096>;

fn params(c1: f32) -> JointParams {
    JointParams {
        model_version: MODEL_VERSION,
        model: Params { c1, c2: 1.2e10, c3: 0.0, alpha: 2.0, beta: -2.3, omega: 1.0 },
        gear_ratio: 100.0,
        torque_limit: 50.0,
        direction_band: 2.0e-5,
    }
}

/// Flash that loses power after `steps` word writes or word erases: the step in progress
/// and everything after it never happen.
struct PowerCut {
    flash: Flash,
    steps: usize,
}

impl PowerCut {
    fn step(&mut self) -> Result<(), NorFlashErrorKind> {
        self.steps = self.steps.checked_sub(1).ok_or(NorFlashErrorKind::Other)?;
        Ok(())
    }
}

impl ErrorType for PowerCut {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for PowerCut {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.flash.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl NorFlash for PowerCut {
    const WRITE_SIZE: usize = Flash::WRITE_SIZE;
    const ERASE_SIZE: usize = Flash::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        // Erase runs word by word here, so a cut leaves the page partly erased, partly old.
        let word = Self::WRITE_SIZE;
        let mut old = std::vec![0u8; (to - from) as usize];
        self.flash.read(from, &mut old)?;
        let words = old.len() / word;
        let erased_words = (0..words).take_while(|_| self.step().is_ok()).count();
        self.flash.erase(from, to)?;
        if erased_words < words {
            let kept = erased_words * word;
            self.flash.write(from + kept as u32, &old[kept..])?;
            return Err(NorFlashErrorKind::Other);
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        for (index, chunk) in bytes.chunks(Self::WRITE_SIZE).enumerate() {
            self.step()?;
            self.flash.write(offset + (index * Self::WRITE_SIZE) as u32, chunk)?;
        }
        Ok(())
    }
}

fn load(flash: Flash) -> Option<Stored> {
    ParamStore::new(flash).unwrap().load()
}

#[test]
fn empty_flash_has_no_parameters() {
    assert_eq!(load(Flash::new()), None);
}

#[test]
fn saves_alternate_slots_and_the_newest_wins() {
    let mut store = ParamStore::new(Flash::new()).unwrap();
    for (round, c1) in [1.0e3f32, 2.0e3, 3.0e3, 4.0e3, 5.0e3].into_iter().enumerate() {
        let sequence = store.save(&params(c1)).unwrap();
        assert_eq!(sequence, round as u32 + 1);
        assert_eq!(store.load(), Some(Stored { params: params(c1), sequence }));
    }
}

#[test]
fn power_lost_at_any_step_leaves_the_old_or_the_new_set() {
    let old = params(1.0e3);
    let new = params(9.0e3);
    // Both starting states: only one slot used, and both slots used.
    for earlier_saves in [1, 2] {
        let mut start = ParamStore::new(Flash::new()).unwrap();
        for _ in 0..earlier_saves {
            start.save(&old).unwrap();
        }
        let start = start.into_flash();
        let mut interrupted = 0;
        for steps in 0.. {
            let mut store = ParamStore::new(PowerCut { flash: start.clone(), steps }).unwrap();
            let result = store.save(&new);
            let after_reboot = load(store.into_flash().flash).map(|stored| stored.params);
            match result {
                Ok(_) => {
                    assert_eq!(after_reboot, Some(new));
                    break;
                }
                Err(error) => {
                    assert_eq!(error, StorageError::Flash);
                    assert!(
                        after_reboot == Some(old) || after_reboot == Some(new),
                        "cut after {steps} steps: {after_reboot:?}"
                    );
                    interrupted += 1;
                }
            }
        }
        // One erase of 256 words plus the record's words: every one of them was cut.
        assert!(interrupted > 256, "{interrupted}");
    }
}

#[test]
fn a_corrupted_record_is_ignored() {
    let mut store = ParamStore::new(Flash::new()).unwrap();
    store.save(&params(1.0e3)).unwrap();
    store.save(&params(2.0e3)).unwrap();
    let mut flash = store.into_flash();
    // Clear bits in the newest record's payload (slot 1 starts at 2048).
    flash.write(2048 + 12, &[0x00; 4]).unwrap();
    assert_eq!(load(flash).map(|stored| stored.params), Some(params(1.0e3)));
}

#[test]
fn sequence_numbers_wrap_around() {
    let mut store = ParamStore::new(Flash::new()).unwrap();
    store.save(&params(1.0e3)).unwrap();
    // Forge slot 0 at u32::MAX by rewriting its record with that sequence.
    let mut flash = store.into_flash();
    flash.erase(0, 1024).unwrap();
    let mut store = ParamStore::new(flash).unwrap();
    store.save(&params(1.0e3)).unwrap();
    let mut flash = store.into_flash();
    let mut record = [0u8; 64];
    flash.read(0, &mut record).unwrap();
    record[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
    let payload_len = u16::from_le_bytes([record[8], record[9]]) as usize;
    let crc = CRC.checksum(&record[..HEADER_LEN + payload_len]);
    let body_len = (HEADER_LEN + payload_len).div_ceil(ALIGN) * ALIGN;
    record[body_len..body_len + 4].copy_from_slice(&crc.to_le_bytes());
    flash.erase(0, 1024).unwrap();
    flash.write(0, &record).unwrap();

    let mut store = ParamStore::new(flash).unwrap();
    assert_eq!(store.load().map(|stored| stored.sequence), Some(u32::MAX));
    assert_eq!(store.save(&params(2.0e3)), Ok(0));
    assert_eq!(store.load(), Some(Stored { params: params(2.0e3), sequence: 0 }));
}

/// Flash whose writes are acknowledged but never land, like a write-protected sector.
struct WriteProtected(Flash);

impl ErrorType for WriteProtected {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for WriteProtected {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

impl NorFlash for WriteProtected {
    const WRITE_SIZE: usize = Flash::WRITE_SIZE;
    const ERASE_SIZE: usize = Flash::ERASE_SIZE;
    fn erase(&mut self, _: u32, _: u32) -> Result<(), Self::Error> {
        Ok(())
    }
    fn write(&mut self, _: u32, _: &[u8]) -> Result<(), Self::Error> {
        Ok(())
    }
}

#[test]
fn a_write_that_does_not_land_is_an_error() {
    let mut store = ParamStore::new(WriteProtected(Flash::new())).unwrap();
    assert_eq!(store.save(&params(1.0e3)), Err(StorageError::Verify));
    assert_eq!(store.load(), None);
}

#[test]
fn too_small_a_flash_is_refused() {
    assert!(matches!(ParamStore::new(RamFlash::<1024>::new()), Err(StorageError::Geometry)));
}
