//! Direction of motion and loop amplitude of a recorded deflection, robust against encoder
//! quantisation and noise: a zigzag with a noise band finds the turning points, a local
//! parabola refines their deflection, and each leg between two turning points gets the
//! larger of their magnitudes as its amplitude A.
use model_core::Direction;

/// A reversal of the deflection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TurningPoint {
    /// Sample index of the extreme.
    pub index: usize,
    /// Deflection at the turning point, refined by a local parabola, rad.
    pub deflection: f64,
    /// True for a maximum (rising → falling).
    pub is_maximum: bool,
}

/// Direction and amplitude for every sample.
#[derive(Clone, Debug, PartialEq)]
pub struct Segmentation {
    pub direction: Vec<Direction>,
    pub amplitude: Vec<f64>,
    pub turning_points: Vec<TurningPoint>,
    /// Estimated deflection noise (standard deviation), rad.
    pub noise: f64,
    /// Reversals smaller than this are taken as noise, rad.
    pub band: f64,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SegmentError {
    #[error("the deflection never reverses (range {range:.3e} rad, noise band {band:.3e} rad): the hysteresis model needs loading and unloading")]
    NoReversal { range: f64, band: f64 },
    #[error("too few samples ({0}) to find the direction of motion")]
    TooShort(usize),
}

/// Noise standard deviation of a slowly varying signal, from its second differences: white
/// noise of σ gives second differences of variance 6σ². The RMS (not the median) is used on
/// purpose: quantised signals have mostly zero differences and rare one-step jumps.
pub fn noise_from_second_differences(x: &[f64]) -> f64 {
    let n = x.len().saturating_sub(2);
    if n == 0 {
        return 0.0;
    }
    let sum: f64 = x.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).powi(2)).sum();
    (sum / n as f64 / 6.0).sqrt()
}

/// Median of the non-zero sample-to-sample steps: the quantisation step of a staircase.
fn typical_step(x: &[f64]) -> f64 {
    let mut steps: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|d| *d > 0.0).collect();
    if steps.is_empty() {
        return 0.0;
    }
    let mid = steps.len() / 2;
    *steps.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Finds turning points, direction and amplitude of `deflection` sampled at `time`.
pub fn segment(time: &[f64], deflection: &[f64]) -> Result<Segmentation, SegmentError> {
    let n = deflection.len();
    if n < 3 {
        return Err(SegmentError::TooShort(n));
    }
    let noise = noise_from_second_differences(deflection);
    let (lo, hi) = deflection.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let range = hi - lo;
    // Ten σ keeps Gaussian noise from ever spanning the band near a slow turning point; two
    // quantisation steps keep a dithering encoder from doing so.
    let band = (10.0 * noise).max(2.0 * typical_step(deflection)).max(1e-9 * range);

    let extremes = zigzag(deflection, band);
    if extremes.is_empty() {
        return Err(SegmentError::NoReversal { range, band });
    }
    let turning_points: Vec<TurningPoint> = extremes
        .iter()
        .map(|&(index, is_maximum)| TurningPoint {
            index,
            deflection: refine_extreme(time, deflection, index, is_maximum, band),
            is_maximum,
        })
        .collect();

    let mut direction = Vec::with_capacity(n);
    let mut amplitude = Vec::with_capacity(n);
    for (k, tp) in turning_points.iter().enumerate() {
        let leg_direction = if tp.is_maximum { Direction::Rising } else { Direction::Falling };
        let previous = k.checked_sub(1).map(|p| turning_points[p].deflection.abs());
        let leg_amplitude = previous.map_or(tp.deflection.abs(), |p| p.max(tp.deflection.abs()));
        direction.resize(tp.index + 1, leg_direction);
        amplitude.resize(tp.index + 1, leg_amplitude);
    }
    // After the last turning point: moving away from it, on its amplitude.
    if let Some(last) = turning_points.last() {
        let tail_direction = if last.is_maximum { Direction::Falling } else { Direction::Rising };
        direction.resize(n, tail_direction);
        amplitude.resize(n, last.deflection.abs());
    }
    // A leg's samples can lie beyond its refined turning deflections by the noise; never
    // let the amplitude be zero.
    let floor = band.max(f64::MIN_POSITIVE);
    for a in &mut amplitude {
        *a = a.max(floor);
    }
    Ok(Segmentation { direction, amplitude, turning_points, noise, band })
}

/// Indices of the extremes between reversals larger than `band`, with `true` for maxima.
fn zigzag(x: &[f64], band: f64) -> Vec<(usize, bool)> {
    let mut extremes = Vec::new();
    let (mut max_index, mut min_index) = (0, 0);
    // None until the signal has moved by more than the band from its start.
    let mut rising: Option<bool> = None;
    for (i, &v) in x.iter().enumerate() {
        if v > x[max_index] {
            max_index = i;
        }
        if v < x[min_index] {
            min_index = i;
        }
        match rising {
            None => {
                if v - x[min_index] > band {
                    rising = Some(true);
                    max_index = i;
                } else if x[max_index] - v > band {
                    rising = Some(false);
                    min_index = i;
                }
            }
            Some(true) => {
                if x[max_index] - v > band {
                    extremes.push((max_index, true));
                    rising = Some(false);
                    min_index = i;
                }
            }
            Some(false) => {
                if v - x[min_index] > band {
                    extremes.push((min_index, false));
                    rising = Some(true);
                    max_index = i;
                }
            }
        }
    }
    extremes
}

/// The vertex of a parabola fitted to the samples within 3 bands of the extreme, or the
/// extreme sample itself where the parabola is not a clear cap (or cup).
fn refine_extreme(time: &[f64], x: &[f64], index: usize, is_maximum: bool, band: f64) -> f64 {
    let peak = x[index];
    let near = |i: usize| (x[i] - peak).abs() <= 3.0 * band;
    let mut first = index;
    while first > 0 && near(first - 1) {
        first -= 1;
    }
    let mut last = index;
    while last + 1 < x.len() && near(last + 1) {
        last += 1;
    }
    if last - first < 4 {
        return peak;
    }
    // Least squares for x = a + b·τ + c·τ², τ = t − t_peak scaled to the window.
    let t0 = time[index];
    let span = (time[last] - time[first]).max(f64::MIN_POSITIVE);
    let mut s = [0.0f64; 5];
    let mut r = [0.0f64; 3];
    for i in first..=last {
        let tau = (time[i] - t0) / span;
        let mut p = 1.0;
        for (k, sk) in s.iter_mut().enumerate() {
            *sk += p;
            if k < 3 {
                r[k] += p * x[i];
            }
            p *= tau;
        }
    }
    let m = [[s[0], s[1], s[2]], [s[1], s[2], s[3]], [s[2], s[3], s[4]]];
    let Some([a, b, c]) = crate::linalg::solve_spd(m, r) else {
        return peak;
    };
    let vertex_tau = -b / (2.0 * c);
    let cap = if is_maximum { c < 0.0 } else { c > 0.0 };
    let lo = (time[first] - t0) / span;
    let hi = (time[last] - t0) / span;
    if cap && vertex_tau >= lo && vertex_tau <= hi {
        a - b * b / (4.0 * c)
    } else {
        peak
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn quantise(v: f64, step: f64) -> f64 {
        (v / step).round() * step
    }

    /// 10 cycles of a sine with Gaussian noise of 2 % of A, then quantised: exactly the 19
    /// reversals, at the right times, no spurious flips near the turning points.
    #[test]
    fn finds_every_reversal_in_noisy_quantised_data() {
        for seed in 0..20 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let amplitude = 1.2e-3;
            let noise = Normal::new(0.0, 0.02 * amplitude).unwrap();
            let step = 2.0 * std::f64::consts::PI / (1u64 << 19) as f64; // ≈ 12 µrad
            let n = 20_000;
            let time: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
            let clean: Vec<f64> = time.iter().map(|t| amplitude * (2.0 * std::f64::consts::PI * 0.5 * t).sin()).collect();
            let measured: Vec<f64> = clean.iter().map(|v| quantise(v + noise.sample(&mut rng), step)).collect();
            let seg = segment(&time, &measured).unwrap();
            assert_eq!(seg.turning_points.len(), 19, "seed {seed}");
            for (k, tp) in seg.turning_points.iter().enumerate() {
                let true_time = (0.5 + k as f64) * 1.0; // extremes of sin(πt) at t = 0.5, 1.5, …
                assert_eq!(tp.is_maximum, k % 2 == 0);
                assert!((time[tp.index] - true_time).abs() < 0.1, "seed {seed} tp {k}: {}", time[tp.index]);
                // The parabola averages the noise: A within 1 % (the raw extreme is ≈ 3σ = 6 % high).
                assert!((tp.deflection.abs() - amplitude).abs() < 0.01 * amplitude, "seed {seed}: {}", tp.deflection);
            }
            // Direction flips only at the turning points.
            let flips = seg.direction.windows(2).filter(|w| w[0] != w[1]).count();
            assert_eq!(flips, 19);
            // Far from the turning points the direction is the true one.
            for (i, t) in time.iter().enumerate() {
                let phase = (t * 0.5 * 2.0 * std::f64::consts::PI).cos();
                if phase.abs() > 0.3 {
                    let expected = if phase > 0.0 { Direction::Rising } else { Direction::Falling };
                    assert_eq!(seg.direction[i], expected, "seed {seed} t={t}");
                }
            }
        }
    }

    #[test]
    fn a_dithering_encoder_at_rest_is_not_a_reversal() {
        let step = 1e-5;
        let mut x: Vec<f64> = (0..1000).map(|i| quantise(i as f64 * 1e-6, step)).collect();
        // Parked at the top for a while, flipping between two counts.
        let top = *x.last().unwrap();
        x.extend((0..500).map(|i| if i % 3 == 0 { top - step } else { top }));
        x.extend((0..1000).map(|i| quantise(top - i as f64 * 1e-6, step)));
        let time: Vec<f64> = (0..x.len()).map(|i| i as f64).collect();
        let seg = segment(&time, &x).unwrap();
        assert_eq!(seg.turning_points.len(), 1);
        assert!(seg.turning_points[0].is_maximum);
    }

    #[test]
    fn a_monotonic_recording_is_an_error() {
        let x: Vec<f64> = (0..100).map(|i| i as f64 * 1e-5).collect();
        let time: Vec<f64> = (0..100).map(|i| i as f64).collect();
        assert!(matches!(segment(&time, &x), Err(SegmentError::NoReversal { .. })));
    }

    #[test]
    fn unipolar_cycles_take_the_larger_turning_point_as_amplitude() {
        // 0 → 1 mrad → 0.2 mrad → 1 mrad, as the paper's forward-only cycle.
        let mut x: Vec<f64> = (0..=100).map(|i| i as f64 * 1e-5).collect();
        x.extend((1..=80).map(|i| 1e-3 - i as f64 * 1e-5));
        x.extend((1..=80).map(|i| 0.2e-3 + i as f64 * 1e-5));
        let time: Vec<f64> = (0..x.len()).map(|i| i as f64).collect();
        let seg = segment(&time, &x).unwrap();
        assert_eq!(seg.turning_points.len(), 2);
        assert!(seg.amplitude.iter().all(|&a| (a - 1e-3).abs() < 1e-9), "{:?}", &seg.amplitude[95..105]);
    }
}
