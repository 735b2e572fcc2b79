//! Direction of motion and loop amplitude of a recorded deflection, robust against encoder
//! quantisation and noise: a zigzag with a noise band finds the turning points, a local
//! parabola refines their deflection, and each leg between two turning points gets the
//! larger of their magnitudes as its amplitude A.
use crate::gear::Reversals;
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

/// The deflection noise σ of a recording, rad: from second differences, and at least the
/// step/√12 of a quantising encoder (a staircase from a coarse encoder has few non-zero second
/// differences, whatever they say).
pub fn deflection_noise(deflection: &[f64]) -> f64 {
    noise_from_second_differences(deflection).max(typical_step(deflection) / 12f64.sqrt())
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
    let TurningBand { band, noise, range } = TurningBand::of(deflection);
    let extremes = zigzag(deflection, band);
    if extremes.is_empty() {
        return Err(SegmentError::NoReversal { range, band });
    }
    let turning_points: Vec<TurningPoint> = extremes
        .iter()
        .enumerate()
        .map(|(k, &(index, is_maximum))| {
            let previous = k.checked_sub(1).map_or(0, |p| extremes[p].0);
            let next = extremes.get(k + 1).map_or(n - 1, |e| e.0);
            TurningPoint {
                index,
                deflection: refine_extreme(time, deflection, index, (previous, next), is_maximum, noise),
                is_maximum,
            }
        })
        .collect();

    // Legs run from one turning point to the next; the partial legs at the ends are bounded by
    // the first and last samples. A leg's amplitude is the larger magnitude of its two ends.
    let mut direction = Vec::with_capacity(n);
    let mut amplitude = Vec::with_capacity(n);
    for leg in 0..=turning_points.len() {
        let start = match leg.checked_sub(1) {
            Some(p) => turning_points[p].deflection.abs(),
            None => deflection[0].abs(),
        };
        let (end, end_index, leg_direction) = match turning_points.get(leg) {
            Some(tp) => {
                (tp.deflection.abs(), tp.index + 1, if tp.is_maximum { Direction::Rising } else { Direction::Falling })
            }
            None => {
                let last = turning_points[leg - 1];
                (deflection[n - 1].abs(), n, if last.is_maximum { Direction::Falling } else { Direction::Rising })
            }
        };
        direction.resize(end_index, leg_direction);
        amplitude.resize(end_index, start.max(end));
    }
    // A leg's samples can lie beyond its refined turning deflections by the noise; never
    // let the amplitude be zero.
    let floor = band.max(f64::MIN_POSITIVE);
    for a in &mut amplitude {
        *a = a.max(floor);
    }
    Ok(Segmentation { direction, amplitude, turning_points, noise, band })
}

/// The smallest reversal the segmentation takes for motion, and what it is made of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TurningBand {
    /// Reversals smaller than this are noise, rad.
    pub band: f64,
    /// The deflection noise σ, rad ([`deflection_noise`]).
    pub noise: f64,
    /// The deflection's range, max − min, rad.
    pub range: f64,
}

impl TurningBand {
    pub fn of(deflection: &[f64]) -> TurningBand {
        let step = typical_step(deflection);
        let noise = deflection_noise(deflection);
        let (lo, hi) = extent(deflection);
        let range = hi - lo;
        // Ten σ keeps Gaussian noise from ever spanning the band near a slow turning point; two
        // quantisation steps keep a dithering encoder from doing so.
        TurningBand { band: (10.0 * noise).max(2.0 * step).max(1e-9 * range), noise, range }
    }
}

/// (min, max) of `x`; (∞, −∞) when empty.
fn extent(x: &[f64]) -> (f64, f64) {
    x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)))
}

impl Segmentation {
    /// The turning points' sample indices, as the offline model follows them.
    pub fn reversals(&self) -> Reversals {
        Reversals {
            indices: self.turning_points.iter().map(|tp| tp.index).collect(),
            rising_first: self.turning_points.first().is_some_and(|tp| tp.is_maximum),
        }
    }
}

/// The turning points of `deflection` as [`segment`] finds them (without refining their
/// deflection, which needs the time): what the offline model follows. A deflection that never
/// reverses by more than the band has none; it rises if it ends above where it started.
pub fn reversals(deflection: &[f64]) -> Reversals {
    reversals_beyond(deflection, TurningBand::of(deflection).band)
}

/// [`reversals`] larger than `band`, rad.
pub fn reversals_beyond(deflection: &[f64], band: f64) -> Reversals {
    let extremes = zigzag(deflection, band);
    let rising_first = match extremes.first() {
        Some(&(_, is_maximum)) => is_maximum,
        None => deflection.last() >= deflection.first(),
    };
    Reversals { indices: extremes.into_iter().map(|(index, _)| index).collect(), rising_first }
}

/// The first sample by which the motion has visited both its extremes (in either order), to
/// within the segmentation's `band`: its largest and its smallest deflection. Before it the
/// hysteresis state left by the motion before the run began can still show (Madelung's
/// rules: an excursion wipes out the memory of smaller ones only once it passes them); from
/// it on, the motion has wiped out any memory inside its own range.
pub fn extremes_visited(deflection: &[f64], band: f64) -> usize {
    let (lo, hi) = extent(deflection);
    let first = |reached: &dyn Fn(f64) -> bool| deflection.iter().position(|&t| reached(t)).unwrap_or(0);
    first(&|t| t >= hi - band).max(first(&|t| t <= lo + band))
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

/// The turning point's deflection: the vertex of a parabola fitted to the samples around
/// it, or the extreme sample itself where the parabola is not a clear cap (or cup).
///
/// The window is ±15 % of the mean distance to the neighbouring turning points (wider, and a
/// sine is no longer a parabola), chosen by time rather than by value so that noise does not
/// pick the samples, and re-centred once on the first vertex because the noisy extreme can
/// sit well off the true one. The noisy extreme overshoots by about σ·(√(2 ln N) + 1) at
/// most; the vertex is kept within that of it, so a sharp (triangular) reversal, which a
/// parabola undercuts, is not pulled in further.
fn refine_extreme(
    time: &[f64],
    x: &[f64],
    index: usize,
    (previous, next): (usize, usize),
    is_maximum: bool,
    noise: f64,
) -> f64 {
    let peak = x[index];
    let reach = ((next - previous) * 15 / 200).max(2);
    let mut center = index;
    let mut estimate = None;
    for _ in 0..2 {
        let first = center.saturating_sub(reach).max(previous);
        let last = (center + reach).min(next);
        let Some((vertex_time, vertex)) = fit_vertex(&time[first..=last], &x[first..=last], is_maximum) else {
            break;
        };
        let count = (last - first + 1) as f64;
        estimate = Some((vertex, count));
        center = first + time[first..=last].partition_point(|&t| t < vertex_time).min(last - first);
    }
    let Some((vertex, count)) = estimate else {
        return peak;
    };
    // The largest of N Gaussian samples lies about σ·√(2 ln N) above their mean.
    let overshoot = noise * ((2.0 * count.ln()).sqrt() + 1.0);
    if is_maximum {
        vertex.clamp(peak - overshoot, peak)
    } else {
        vertex.clamp(peak, peak + overshoot)
    }
}

/// (time, value) of the vertex of the least-squares parabola through the samples, if it is a
/// cap (for a maximum) or a cup (for a minimum) with its vertex inside the samples' span.
///
/// Over the window a sinusoidal excitation A·cos u also has a quartic term A·u⁴/24, which a
/// plain parabola folds into its vertex (a bias of 1.7·10⁻⁴·A, measured to double a small
/// backlash estimate). For a sine the quartic coefficient follows from the quadratic one,
/// d = c²/(6a), so it is subtracted and the parabola refitted; |d| ≤ |c|/2 keeps the
/// correction harmless where the reversal is not sinusoidal.
fn fit_vertex(time: &[f64], x: &[f64], is_maximum: bool) -> Option<(f64, f64)> {
    if x.len() < 5 {
        return None;
    }
    let (t0, t1) = (*time.first()?, *time.last()?);
    let span = (t1 - t0).max(f64::MIN_POSITIVE);
    // τ in [−1, 1] over the window keeps the normal equations well conditioned.
    let tau: Vec<f64> = time.iter().map(|&t| 2.0 * (t - t0) / span - 1.0).collect();
    let mut quartic = 0.0;
    let mut vertex = None;
    for _ in 0..3 {
        let center = vertex.map_or(0.0, |(v, _)| v);
        let mut s = [0.0f64; 5];
        let mut r = [0.0f64; 3];
        for (&t, &v) in tau.iter().zip(x) {
            let y = v - quartic * (t - center).powi(4);
            let mut p = 1.0;
            for (k, sk) in s.iter_mut().enumerate() {
                *sk += p;
                if k < 3 {
                    r[k] += p * y;
                }
                p *= t;
            }
        }
        let m = [[s[0], s[1], s[2]], [s[1], s[2], s[3]], [s[2], s[3], s[4]]];
        let [a, b, c] = crate::numeric::linalg::solve_spd(m, r)?;
        let cap = if is_maximum { c < 0.0 } else { c > 0.0 };
        let vertex_tau = -b / (2.0 * c);
        if !(cap && (-1.0..=1.0).contains(&vertex_tau)) {
            return None;
        }
        let value = a - b * b / (4.0 * c);
        vertex = Some((vertex_tau, value));
        quartic = if value != 0.0 { (c * c / (6.0 * value)).clamp(-c.abs() / 2.0, c.abs() / 2.0) } else { 0.0 };
    }
    vertex.map(|(vertex_tau, value)| (t0 + (vertex_tau + 1.0) * span / 2.0, value))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn quantise(v: f64, step: f64) -> f64 {
        (v / step).round() * step
    }

    /// 10 cycles of a sine with Gaussian noise of 2 % of A, then quantised: exactly the 20
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
            let clean: Vec<f64> =
                time.iter().map(|t| amplitude * (2.0 * std::f64::consts::PI * 0.5 * t).sin()).collect();
            let measured: Vec<f64> = clean.iter().map(|v| quantise(v + noise.sample(&mut rng), step)).collect();
            let seg = segment(&time, &measured).unwrap();
            assert_eq!(seg.turning_points.len(), 20, "seed {seed}");
            for (k, tp) in seg.turning_points.iter().enumerate() {
                let true_time = (0.5 + k as f64) * 1.0; // extremes of sin(πt) at t = 0.5, 1.5, …
                assert_eq!(tp.is_maximum, k % 2 == 0);
                assert!((time[tp.index] - true_time).abs() < 0.1, "seed {seed} tp {k}: {}", time[tp.index]);
                // The parabola averages the noise: A within 1 % (the raw extreme is ≈ 3σ = 6 % high).
                assert!(
                    (tp.deflection.abs() - amplitude).abs() < 0.01 * amplitude,
                    "seed {seed} tp {k} at {}: {} noise {}",
                    tp.index,
                    tp.deflection,
                    seg.noise
                );
            }
            // Direction flips only at the turning points.
            let flips = seg.direction.windows(2).filter(|w| w[0] != w[1]).count();
            assert_eq!(flips, 20);
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
        // Every leg, the one between 1 mrad and 0.2 mrad too, is on the 1 mrad loop; the sharp
        // corner costs at most 5σ of the noise estimate (here the 10 µrad step/√12).
        assert!(seg.amplitude.iter().all(|&a| (a - 1e-3).abs() <= 5.0 * seg.noise), "{:?}", &seg.amplitude[95..105]);
    }
}
