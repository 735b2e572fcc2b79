//! Where a board sends the motor torque command, with errors after embedded-hal's convention:
//! a driver's error type says what kind of failure it was ([`Error::kind`]), so that the
//! board-independent tick can report it without knowing the driver.
pub use swg_protocol::DriveErrorKind as ErrorKind;

/// A motor drive's error.
pub trait Error: core::fmt::Debug {
    /// What kind of failure this is.
    fn kind(&self) -> ErrorKind;
}

impl Error for core::convert::Infallible {
    fn kind(&self) -> ErrorKind {
        match *self {}
    }
}

impl Error for ErrorKind {
    fn kind(&self) -> ErrorKind {
        *self
    }
}

/// A drive's error type.
pub trait ErrorType {
    type Error: Error;
}

/// Where a board sends the motor torque command.
pub trait MotorDrive: ErrorType {
    /// Applies `torque`, N·m at the motor shaft: finite and within the configured limit.
    fn apply(&mut self, torque: f32) -> Result<(), Self::Error>;
}

/// A drive that applies nothing: for links that only replay (the host's tests).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoDrive;

impl ErrorType for NoDrive {
    type Error = core::convert::Infallible;
}

impl MotorDrive for NoDrive {
    fn apply(&mut self, _torque: f32) -> Result<(), Self::Error> {
        Ok(())
    }
}
