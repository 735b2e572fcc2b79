//! Absolute angle sensors, with errors after embedded-hal's convention: a driver's error type
//! says what kind of failure it was ([`Error::kind`]), so that the board-independent tick can
//! count and report it without knowing the driver.
pub use swg_protocol::SensorErrorKind as ErrorKind;

/// A sensor's error.
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

/// A sensor's error type.
pub trait ErrorType {
    type Error: Error;
}

/// An absolute angle sensor on a shaft.
pub trait AngleSensor: ErrorType {
    /// The shaft angle in [0, 2π) rad.
    fn read_angle(&mut self) -> Result<f32, Self::Error>;
}
