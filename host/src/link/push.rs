//! Pushing a parameter set to a joint: check versions, write, read back, commit.
use super::{Link, LinkError};
use model_core::{Params, MODEL_VERSION};
use std::time::{Duration, Instant};
use swg_protocol::{DeviceInfo, ErrorReply, JointParams, PROTOCOL_VERSION};

/// How the joint applies the model, pushed with it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointSettings {
    /// Gear reduction ratio N.
    pub gear_ratio: f64,
    /// |T_ff| limit, N·m.
    pub torque_limit: f64,
    /// Direction band against encoder noise, rad.
    pub direction_band: f64,
}

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PushError {
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error("device speaks protocol version {device}, this tool {PROTOCOL_VERSION}: update the firmware or swg-host")]
    ProtocolMismatch { device: u16 },
    #[error(
        "device runs model version {device}, these parameters are for {MODEL_VERSION}: update the firmware or refit"
    )]
    ModelMismatch { device: u16 },
    #[error("{name} = {value} does not fit the device's f32")]
    NotRepresentable { name: &'static str, value: f64 },
    #[error("parameters rejected before sending: {0}")]
    Invalid(ErrorReply),
    #[error("read-back differs from what was written: wrote {written:?}, read {read:?}")]
    ReadBack { written: Box<JointParams>, read: Box<Option<JointParams>> },
}

/// The set as the device will hold it (f32), validated here with the device's own rules.
pub fn joint_params(params: &Params<f64>, settings: &JointSettings) -> Result<JointParams, PushError> {
    let narrow = |name: &'static str, value: f64| {
        let narrowed = value as f32;
        if value.is_finite() && !narrowed.is_finite() {
            Err(PushError::NotRepresentable { name, value })
        } else {
            Ok(narrowed)
        }
    };
    let joint = JointParams {
        model_version: MODEL_VERSION,
        model: params.try_map(|name, value| narrow(name.as_str(), value))?,
        gear_ratio: narrow("gear ratio", settings.gear_ratio)?,
        torque_limit: narrow("torque limit", settings.torque_limit)?,
        direction_band: narrow("direction band", settings.direction_band)?,
    };
    joint.validate().map_err(PushError::Invalid)?;
    Ok(joint)
}

/// What a push did.
#[derive(Clone, Debug, PartialEq)]
pub struct PushReport {
    pub device: DeviceInfo,
    /// The set active before, if any.
    pub previous: Option<JointParams>,
    pub written: JointParams,
    /// Flash record sequence number of the commit.
    pub sequence: u32,
    /// Version check, write, read-back and commit.
    pub elapsed: Duration,
}

/// Checks the device's versions, writes `params`, reads them back and compares, commits.
pub fn push(link: &mut Link, params: &JointParams) -> Result<PushReport, PushError> {
    let start = Instant::now();
    let device = link.device_info().map_err(|error| match error {
        LinkError::Refused(ErrorReply::UnsupportedProtocol { supported, .. }) => {
            PushError::ProtocolMismatch { device: supported }
        }
        error => error.into(),
    })?;
    if device.protocol_version != PROTOCOL_VERSION {
        return Err(PushError::ProtocolMismatch { device: device.protocol_version });
    }
    if device.model_version != params.model_version {
        return Err(PushError::ModelMismatch { device: device.model_version });
    }
    let previous = link.read_params()?;
    link.write_params(params)?;
    let read = link.read_params()?;
    if read != Some(*params) {
        return Err(PushError::ReadBack { written: Box::new(*params), read: Box::new(read) });
    }
    let sequence = link.commit()?;
    Ok(PushReport { device, previous, written: *params, sequence, elapsed: start.elapsed() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::fake::FakeDevice;
    use swg_protocol::{ParamFault, ParamField};

    const SEED: Params<f64> = Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 68.0, beta: -2.298, omega: 1.0 };
    const SETTINGS: JointSettings = JointSettings { gear_ratio: 50.0, torque_limit: 30.0, direction_band: 1.0e-5 };

    #[test]
    fn push_writes_verifies_and_commits() {
        let mut link = FakeDevice::new().link();
        let params = joint_params(&SEED, &SETTINGS).unwrap();
        let report = push(&mut link, &params).unwrap();
        assert_eq!((report.previous, report.sequence), (None, 1));
        assert_eq!(report.device.protocol_version, PROTOCOL_VERSION);
        let again = push(&mut link, &params).unwrap();
        assert_eq!((again.previous, again.sequence), (Some(params), 2));
    }

    #[test]
    fn bad_values_are_caught_before_sending() {
        let huge = Params { c3: 1e300, ..SEED };
        assert!(matches!(joint_params(&huge, &SETTINGS), Err(PushError::NotRepresentable { name: "c3", .. })));
        let no_ratio = JointSettings { gear_ratio: 0.0, ..SETTINGS };
        assert!(matches!(
            joint_params(&SEED, &no_ratio),
            Err(PushError::Invalid(ErrorReply::InvalidParam {
                field: ParamField::GearRatio,
                fault: ParamFault::OutOfRange
            }))
        ));
    }

    #[test]
    fn the_device_refusing_a_set_is_reported() {
        let mut link = FakeDevice::new().link();
        // Past the host's check (validated with the same rules), so corrupt it afterwards.
        let mut params = joint_params(&SEED, &SETTINGS).unwrap();
        params.direction_band = 1.0;
        let error = push(&mut link, &params).unwrap_err();
        assert_eq!(error.to_string(), "device refused the request: parameter direction_band is out of range");
        params.model_version += 1;
        let error = push(&mut link, &params).unwrap_err();
        assert!(matches!(error, PushError::ModelMismatch { device: MODEL_VERSION }), "{error}");
    }
}
