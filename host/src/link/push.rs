//! Pushing a parameter set to a joint: check versions, write, read back, commit.
use super::{Link, LinkError};
use model_core::{GearModel, MODEL_VERSION};
use std::time::{Duration, Instant};
use swg_protocol::{endpoint, DeviceInfo, ErrorReply, FrameError, JointParams, PROTOCOL_VERSION};

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
    NotRepresentable { name: String, value: f64 },
    #[error("parameters rejected before sending: {0}")]
    Invalid(ErrorReply),
    #[error("read-back differs from what was written: wrote {written:?}, read {read:?}")]
    ReadBack { written: Box<JointParams>, read: Box<Option<JointParams>> },
}

/// A value rounded to the device's f32; one that is finite but beyond f32 is refused (rather
/// than sent as infinity), named `name`.
fn narrow(name: &str, value: f64) -> Result<f32, PushError> {
    let narrowed = value as f32;
    if value.is_finite() && !narrowed.is_finite() {
        Err(PushError::NotRepresentable { name: name.to_owned(), value })
    } else {
        Ok(narrowed)
    }
}

/// The model as the device will hold it, f32.
pub fn joint_model(model: &GearModel<f64>) -> Result<GearModel<f32>, PushError> {
    model.try_map(|name, value| narrow(&name.to_string(), value))
}

/// The set as the device will hold it (f32), validated here with the device's own rules.
pub fn joint_params(model: &GearModel<f64>, settings: &JointSettings) -> Result<JointParams, PushError> {
    let joint = JointParams {
        model_version: MODEL_VERSION,
        model: joint_model(model)?,
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
    let device = link.call::<endpoint::GetDeviceInfo>(&()).map_err(|error| match error {
        // A device of another protocol answers in frames of its own version.
        LinkError::Frame(FrameError::Version(device)) => PushError::ProtocolMismatch { device },
        error => error.into(),
    })?;
    if device.protocol_version != PROTOCOL_VERSION {
        return Err(PushError::ProtocolMismatch { device: device.protocol_version });
    }
    if device.model_version != params.model_version {
        return Err(PushError::ModelMismatch { device: device.model_version });
    }
    let previous = link.call::<endpoint::ReadParams>(&())?;
    link.call::<endpoint::WriteParams>(params)?;
    let read = link.call::<endpoint::ReadParams>(&())?;
    if read != Some(*params) {
        return Err(PushError::ReadBack { written: Box::new(*params), read: Box::new(read) });
    }
    let sequence = link.call::<endpoint::Commit>(&())?;
    Ok(PushReport { device, previous, written: *params, sequence, elapsed: start.elapsed() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::fake::FakeDevice;
    use model_core::memory::slip_grid;
    use model_core::{ParamName, Params, SlipElement, Spring, SLIP_ELEMENTS};
    use swg_protocol::{ParamFault, ParamField};

    fn seed() -> GearModel<f64> {
        GearModel::paper(Params { c1: 9.0e3, c2: 1.2e10, c3: 0.0, alpha: 68.0, beta: -2.298, omega: 1.0 })
    }

    /// 16 elements of 187.5 N·m/rad on the log grid 20 µrad … 2 mrad, beside a cubic spring.
    fn slip() -> GearModel<f64> {
        let grid = slip_grid::<f64, SLIP_ELEMENTS>(2.0e-5, 2.0e-3).unwrap();
        let elements = grid.map(|slip| SlipElement { slip, stiffness: 187.5 });
        GearModel::micro_slip(0.0, Spring::polynomial(6.0e3, 1.2e10, 0.0), &elements).unwrap()
    }

    const SETTINGS: JointSettings = JointSettings { gear_ratio: 50.0, torque_limit: 30.0, direction_band: 1.0e-5 };

    #[test]
    fn push_writes_verifies_and_commits() {
        let mut link = FakeDevice::new().link();
        let params = joint_params(&seed(), &SETTINGS).unwrap();
        let report = push(&mut link, &params).unwrap();
        assert_eq!((report.previous, report.sequence), (None, 1));
        assert_eq!(report.device.protocol_version, PROTOCOL_VERSION);
        let again = push(&mut link, &params).unwrap();
        assert_eq!((again.previous, again.sequence), (Some(params), 2));
    }

    #[test]
    fn push_sends_a_micro_slip_model() {
        let mut link = FakeDevice::new().link();
        let params = joint_params(&slip(), &SETTINGS).unwrap();
        let elements = params.model.slip_elements();
        assert!(elements.iter().all(|e| e.stiffness == 187.5), "{params:?}");
        assert_eq!((elements[0].slip, elements[15].slip), (2.0e-5, 2.0e-3));
        let report = push(&mut link, &params).unwrap();
        assert_eq!(report.written, params);
        // Replacing it with the genetic kind is an ordinary push.
        let genetic = joint_params(&seed(), &SETTINGS).unwrap();
        assert_eq!(push(&mut link, &genetic).unwrap().previous, Some(params));
    }

    #[test]
    fn bad_values_are_caught_before_sending() {
        let huge = seed().with(ParamName::C3, 1e300);
        assert!(
            matches!(joint_params(&huge, &SETTINGS), Err(PushError::NotRepresentable { ref name, .. }) if name == "c3")
        );
        let error = joint_params(&slip().with(ParamName::SlipStiffness(9), 1e40), &SETTINGS).unwrap_err();
        assert_eq!(
            error.to_string(),
            "stiffness[9] = 10000000000000000000000000000000000000000 does not fit the device's f32"
        );
        // Representable, but refused by the device's rules (the slip deflection rounds to 0 in f32).
        assert!(matches!(
            joint_params(&slip().with(ParamName::Slip(0), 1e-50), &SETTINGS),
            Err(PushError::Invalid(ErrorReply::InvalidParam {
                field: ParamField::Model(ParamName::Slip(0)),
                fault: ParamFault::OutOfRange
            }))
        ));
        let no_ratio = JointSettings { gear_ratio: 0.0, ..SETTINGS };
        assert!(matches!(
            joint_params(&seed(), &no_ratio),
            Err(PushError::Invalid(ErrorReply::InvalidParam {
                field: ParamField::GearRatio,
                fault: ParamFault::OutOfRange
            }))
        ));
    }

    /// Every parameter of both kinds at a 1e38-class value (ω at 1e-38): representable in f32,
    /// but the model would overflow f32 somewhere in the joint's range (or, for the slip range,
    /// lies beyond it). Refused here before sending, naming the parameter, and by the device
    /// with the same reply when sent anyway (its `JointParams::validate`, the same code); the
    /// old set stays active. The reference sets pass both.
    #[test]
    fn sets_that_overflow_in_range_are_refused_by_both_ends_with_the_same_reason() {
        use model_core::checks::{micro_slip_set, PAPER_TABLE_2, SEED_TABLE_FIT};
        let mut link = FakeDevice::new().link();
        let good = joint_params(&GearModel::paper(PAPER_TABLE_2), &SETTINGS).unwrap();
        push(&mut link, &good).unwrap();
        for model in [GearModel::paper(SEED_TABLE_FIT), micro_slip_set().unwrap()] {
            let params = joint_params(&model, &SETTINGS).unwrap();
            link.call::<endpoint::WriteParams>(&params).unwrap();
        }
        link.call::<endpoint::WriteParams>(&good).unwrap();

        let mut cases: Vec<(GearModel<f64>, ParamField)> = Vec::new();
        for base in [GearModel::paper(PAPER_TABLE_2), micro_slip_set().unwrap()] {
            let mut names = Vec::new();
            base.map(|name, value| {
                names.push(name);
                value
            });
            let elements = base.slip_elements().len();
            for name in names {
                let huge = match name {
                    ParamName::Omega => 1e-38,
                    // An element's slip deflection out of order names the next one (the kind's
                    // checks); the last one's lies beyond the travel.
                    ParamName::Slip(i) if usize::from(i) + 1 < elements => continue,
                    ParamName::RangeMin => -1e38,
                    _ => 1e38,
                };
                cases.push((base.with(name, huge), ParamField::Model(name)));
            }
        }
        for (model, field) in cases {
            let reason = ErrorReply::InvalidParam { field, fault: ParamFault::OutOfRange };
            let error = joint_params(&model, &SETTINGS).unwrap_err();
            assert!(matches!(error, PushError::Invalid(r) if r == reason), "{model:?}: {error}");
            assert_eq!(
                error.to_string(),
                format!("parameters rejected before sending: parameter {field} is out of range")
            );
            // Sent anyway: the device refuses it with the same reply, the old set stays.
            let sent = JointParams { model: joint_model(&model).unwrap(), ..good };
            match link.call::<endpoint::WriteParams>(&sent) {
                Err(LinkError::Refused(r)) => assert_eq!(r, reason, "{model:?}"),
                other => panic!("{model:?}: {other:?}"),
            }
            assert_eq!(link.call::<endpoint::ReadParams>(&()).unwrap(), Some(good));
        }
    }

    #[test]
    fn the_device_refusing_a_set_is_reported() {
        let mut link = FakeDevice::new().link();
        // Past the host's check (validated with the same rules), so corrupt it afterwards.
        let mut params = joint_params(&seed(), &SETTINGS).unwrap();
        params.direction_band = 1.0;
        let error = push(&mut link, &params).unwrap_err();
        assert_eq!(error.to_string(), "device refused the request: parameter direction_band is out of range");
        params.model_version += 1;
        let error = push(&mut link, &params).unwrap_err();
        assert!(matches!(error, PushError::ModelMismatch { device: MODEL_VERSION }), "{error}");
    }
}
