//! What `predict` writes: the prediction as CSV, one row per sample.
use crate::predict::Prediction;

/// The columns of a prediction file. `scored` is 0 on the samples before the motion's extremes
/// wiped out an unknown start state (left out of the summary's RSS and RMS), 1 on the others.
pub const COLUMNS: [&str; 5] = ["time_s", "deflection_rad", "torque_nm", "stiffness_nm_per_rad", "scored"];

/// `prediction` as CSV text: a header of [`COLUMNS`], then one row per sample, in order.
pub fn prediction_csv(prediction: &Prediction) -> Result<Vec<u8>, csv::Error> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(COLUMNS)?;
    for i in 0..prediction.torque.len() {
        writer.write_record([
            prediction.time[i].to_string(),
            prediction.deflection[i].to_string(),
            prediction.torque[i].to_string(),
            prediction.stiffness[i].to_string(),
            u8::from(prediction.is_scored(i)).to_string(),
        ])?;
    }
    writer.into_inner().map_err(|e| e.into_error().into())
}
