//! Numerical tools with no knowledge of gears: small dense linear algebra, the optimisers,
//! statistics.
pub mod linalg;
pub mod nnls;
pub mod optimize;

/// The arithmetic mean; NaN for no values.
pub fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// The median (upper middle for an even count); NaN for no values.
pub fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut sorted = values.to_vec();
    let mid = sorted.len() / 2;
    *sorted.select_nth_unstable_by(mid, f64::total_cmp).1
}
