//! Fakes shared by the crate's tests.
extern crate std;
use crate::drive::{self, MotorDrive};
use std::vec::Vec;
use swg_protocol::DriveErrorKind;

/// A drive that records what it was given, and refuses with `refuse`'s kind while it is set.
#[derive(Default)]
pub struct Recorder {
    pub applied: Vec<f32>,
    pub refuse: Option<DriveErrorKind>,
}

impl drive::ErrorType for Recorder {
    type Error = DriveErrorKind;
}

impl MotorDrive for Recorder {
    fn apply(&mut self, torque: f32) -> Result<(), DriveErrorKind> {
        if let Some(kind) = self.refuse {
            return Err(kind);
        }
        self.applied.push(torque);
        Ok(())
    }
}
