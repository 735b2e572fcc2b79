//! The deflection the bench drives: today's sine, and motions that start at rest and leave
//! the symmetric loop (a bias, nested reversals, random, a held load, a file, a plan).
use crate::input::plan::PlanSpec;
use crate::input::table::{read_text, Table};
use crate::input::InputError;
use rand::{Rng, SeedableRng};
use std::f64::consts::TAU;
use std::path::Path;
use swg_protocol::plan::Channel;
// The ramp from rest, s(u) = 10u³ − 15u⁴ + 6u⁵ (zero slope and curvature at both ends): the
// plans' own, one copy.
pub use swg_protocol::plan::{smoothstep, smoothstep_slope};

/// The motion of the deflection x(t). A is `--amplitude`, f the frequency of the block being
/// played (the frequencies play in turn, `cycles` periods each), φ = 2π·f·(time in the block).
#[derive(Clone, Debug, PartialEq, Default)]
pub enum Motion {
    /// x = A·sin φ (the symmetric loop; starts at x = 0 moving up).
    #[default]
    Sine,
    /// A held load with an oscillation about it: a ramp from rest over one period T of the first
    /// frequency, x = (b − 0.15·A)·s(t/T), then x = b − 0.15·A·cos φ (no jump in the rate).
    /// `None`: b = 0.6·A.
    Biased { bias_rad: Option<f64> },
    /// Small reversals inside big ones: x = A·(0.75·sin φ + 0.25·sin 9φ), from rest; every
    /// ninth-harmonic wiggle reverses the motion, so minor loops form at many levels.
    Nested,
    /// Band-limited random motion: 20 sines with seeded random frequencies (uniform in
    /// [0.1·f_min, 3·f_max]) and phases, faded in over the first period 1/f_min by s, scaled
    /// to a peak of exactly A over the recording.
    Random,
    /// A ramp to the load L like `Biased`, then a dither: x = L − 0.02·A·cos 10φ. `None`: L = 0.6·A.
    Hold { load_rad: Option<f64> },
    /// Deflections at given times (`time_s,deflection_rad`), reached from rest.
    File(Trajectory),
    /// An experiment's plan of the deflection, played at the sample rate by the joint's own
    /// player (`swg_protocol::plan`): a plan file, or the default plan.
    Plan(PlanSpec),
}

/// Oscillation amplitude of `biased`, and the dither of `hold`, relative to A.
pub const BIAS_SWING: f64 = 0.15;
pub const HOLD_DITHER: f64 = 0.02;
/// Default bias of `biased` and load of `hold`, relative to A.
pub const DEFAULT_BIAS: f64 = 0.6;
/// Components of `random`, and its band relative to the frequencies.
pub const RANDOM_COMPONENTS: usize = 20;
pub const RANDOM_BAND: (f64, f64) = (0.1, 3.0);
/// Harmonic and shares of `nested`.
pub const NESTED_HARMONIC: f64 = 9.0;
pub const NESTED_SHARES: (f64, f64) = (0.75, 0.25);
/// Dither frequency of `hold`, relative to the block's frequency.
pub const HOLD_DITHER_HARMONIC: f64 = 10.0;

impl Motion {
    /// The name `--motion` takes (`file` for a trajectory).
    pub fn name(&self) -> &'static str {
        match self {
            Motion::Sine => "sine",
            Motion::Biased { .. } => "biased",
            Motion::Nested => "nested",
            Motion::Random => "random",
            Motion::Hold { .. } => "hold",
            Motion::File(_) => "file",
            Motion::Plan(_) => "plan",
        }
    }
}

/// A deflection trajectory: strictly increasing finite times, finite deflections.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    name: String,
    time: Vec<f64>,
    deflection: Vec<f64>,
}

/// A trajectory that is not one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("motion trajectory: {0}")]
pub struct TrajectoryError(pub String);

impl Trajectory {
    /// `name` is what the recording's metadata calls it.
    pub fn new(name: impl Into<String>, time: Vec<f64>, deflection: Vec<f64>) -> Result<Self, TrajectoryError> {
        if time.is_empty() {
            return Err(TrajectoryError("no samples".into()));
        }
        if time.len() != deflection.len() {
            return Err(TrajectoryError(format!("{} times but {} deflections", time.len(), deflection.len())));
        }
        if let Some(i) = time.iter().chain(&deflection).position(|v| !v.is_finite()) {
            return Err(TrajectoryError(format!("value {i} is not finite")));
        }
        if let Some(i) = time.windows(2).position(|w| w[1] <= w[0]) {
            return Err(TrajectoryError(format!("time {} at sample {} is not after {}", time[i + 1], i + 1, time[i])));
        }
        Ok(Trajectory { name: name.into(), time, deflection })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn time(&self) -> &[f64] {
        &self.time
    }

    pub fn deflection(&self) -> &[f64] {
        &self.deflection
    }

    /// dx/dt at sample `i`: central difference inside, one-sided at the ends, 0 for one sample.
    fn rate(&self, i: usize) -> f64 {
        let last = self.time.len() - 1;
        let (a, b) = (i.saturating_sub(1), (i + 1).min(last));
        if a == b {
            0.0
        } else {
            (self.deflection[b] - self.deflection[a]) / (self.time[b] - self.time[a])
        }
    }
}

/// Reads a motion file: CSV with the columns `time_s` (s, strictly increasing) and
/// `deflection_rad` (rad), `#` comments, other columns ignored; errors name file:line:column.
pub fn read_trajectory(path: &Path) -> Result<Trajectory, InputError> {
    let text = read_text(path)?;
    let table = Table::parse(path, &text)?;
    let time_col = table.required_column("time_s", "sample time, s")?;
    let deflection_col = table.required_column("deflection_rad", "torsional deflection, rad")?;
    let (mut time, mut deflection) = (Vec::new(), Vec::new());
    table.for_each_row(|row| {
        let t = table.number(row, time_col)?;
        if let Some(&previous) = time.last() {
            if t <= previous {
                return Err(table.cell_error(
                    row,
                    time_col,
                    format!("time must increase: {t} is not after {previous}"),
                ));
            }
        }
        time.push(t);
        deflection.push(table.number(row, deflection_col)?);
        Ok(())
    })?;
    if time.is_empty() {
        return Err(InputError::at_line(path, table.header_line, "no data rows after the header"));
    }
    Trajectory::new(path.display().to_string(), time, deflection).map_err(|e| InputError::file(path, e.0))
}

/// One sample of the played motion: time, deflection x and its rate dx/dt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Sample {
    pub t: f64,
    pub x: f64,
    pub rate: f64,
}

/// What is needed to play a motion: the sampling and its shape.
pub(crate) struct Played<'a> {
    shape: Shape<'a>,
    /// Samples to write.
    pub len: usize,
    sample_rate_hz: f64,
    /// (start time, frequency) of each block, after the ramp.
    blocks: Vec<(f64, f64)>,
    /// Length of the ramp from rest (0 without one), s.
    ramp: f64,
    amplitude: f64,
}

enum Shape<'a> {
    Sine,
    Biased {
        bias: f64,
        swing: f64,
    },
    Nested,
    Random {
        components: Vec<(f64, f64)>,
        window: f64,
        scale: f64,
    },
    Hold {
        load: f64,
        dither: f64,
    },
    File(&'a Trajectory),
    /// Each sample's deflection and rate, as the plan's player made them.
    Plan(Vec<(f64, f64)>),
}

/// Why a motion cannot be played.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum PlayError {
    /// It would take this many samples, more than allowed.
    TooLong(f64),
    /// Its plan cannot be played at the sample rate, or is not one of the deflection.
    Plan(InputError),
}

/// Parameters of the played motion that the sampling depends on.
pub(crate) struct Timing<'a> {
    pub amplitude: f64,
    pub frequencies_hz: &'a [f64],
    pub cycles: u32,
    pub sample_rate_hz: f64,
    pub seed: u64,
}

/// Samples in a recording of `duration` s, or `Err(samples)` beyond `max`.
fn sample_count(duration: f64, rate: f64, max: f64) -> Result<usize, f64> {
    let samples = (duration * rate).floor();
    if samples > max {
        Err(samples)
    } else {
        Ok(samples as usize + 1)
    }
}

impl<'a> Played<'a> {
    /// The motion sampled as `timing` says.
    pub fn new(motion: &'a Motion, timing: &Timing, max_samples: f64) -> Result<Self, PlayError> {
        let a = timing.amplitude;
        let frequencies = timing.frequencies_hz;
        let first = frequencies.first().copied().unwrap_or(1.0);
        let ramp = match motion {
            Motion::Biased { .. } | Motion::Hold { .. } => 1.0 / first,
            _ => 0.0,
        };
        let mut blocks = Vec::new();
        let mut start = 0.0;
        for &f in frequencies {
            blocks.push((start, f));
            start += timing.cycles as f64 / f;
        }
        let duration = ramp + start;
        // A plan's samples, as its player makes them.
        let mut planned = Vec::new();
        let len = match motion {
            Motion::File(trajectory) => {
                let len = trajectory.time.len();
                if len as f64 > max_samples {
                    return Err(PlayError::TooLong(len as f64));
                }
                len
            }
            Motion::Plan(spec) => {
                // Counted in f64 first: at an absurd rate the plan's tick count saturates.
                let samples = spec.segments.iter().map(|s| f64::from(s.seconds())).sum::<f64>() * timing.sample_rate_hz;
                if samples > max_samples {
                    return Err(PlayError::TooLong(samples.floor() + 1.0));
                }
                let plan = spec.at_rate(timing.sample_rate_hz).map_err(PlayError::Plan)?;
                if plan.channel() != Channel::Deflection {
                    return Err(PlayError::Plan(InputError::file(
                        std::path::Path::new(spec.source()),
                        "the plan is of the torque (\"channel\": \"torque\"): simulate prescribes the deflection, and \
                         plays deflection plans (the joint plays either)",
                    )));
                }
                let samples: Vec<(f64, f64)> = plan.player::<f64>().map(|s| (s.value, s.slope)).collect();
                let len = samples.len();
                planned = samples;
                len
            }
            _ => sample_count(duration, timing.sample_rate_hz, max_samples).map_err(PlayError::TooLong)?,
        };
        let shape = match motion {
            Motion::Sine => Shape::Sine,
            Motion::Biased { bias_rad } => {
                Shape::Biased { bias: bias_rad.unwrap_or(DEFAULT_BIAS * a), swing: BIAS_SWING * a }
            }
            Motion::Nested => Shape::Nested,
            Motion::Hold { load_rad } => {
                Shape::Hold { load: load_rad.unwrap_or(DEFAULT_BIAS * a), dither: HOLD_DITHER * a }
            }
            Motion::File(trajectory) => Shape::File(trajectory),
            Motion::Plan(_) => Shape::Plan(planned),
            Motion::Random => {
                let lowest = frequencies.iter().copied().fold(f64::INFINITY, f64::min);
                let highest = frequencies.iter().copied().fold(0.0, f64::max);
                let (lo, hi) = (RANDOM_BAND.0 * lowest, RANDOM_BAND.1 * highest);
                // Its own stream, so that the noise of a seed is the same for every motion.
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(timing.seed ^ 0x7261_6e64_6f6d_6d6f);
                let components =
                    (0..RANDOM_COMPONENTS).map(|_| (rng.random_range(lo..hi), rng.random_range(0.0..TAU))).collect();
                let shape = Shape::Random { components, window: 1.0 / lowest, scale: 1.0 };
                let mut played =
                    Played { shape, len, sample_rate_hz: timing.sample_rate_hz, blocks, ramp, amplitude: a };
                let peak = (0..len).map(|i| played.sample(i).x.abs()).fold(0.0, f64::max);
                if let Shape::Random { scale, .. } = &mut played.shape {
                    *scale = if peak > 0.0 { a / peak } else { 0.0 };
                }
                return Ok(played);
            }
        };
        Ok(Played { shape, len, sample_rate_hz: timing.sample_rate_hz, blocks, ramp, amplitude: a })
    }

    /// The block's (frequency, phase φ) at time `t` after the ramp (today's sine's lookup).
    fn phase(&self, t: f64) -> (f64, f64) {
        let &(block_start, f) = self.blocks.iter().rev().find(|(s, _)| *s <= t).unwrap_or(&self.blocks[0]);
        (f, TAU * f * (t - block_start))
    }

    /// Ramp from rest to `level` over the ramp's time, at time t < ramp.
    fn ramp_to(&self, level: f64, t: f64) -> Sample {
        let u = t / self.ramp;
        Sample { t, x: level * smoothstep(u), rate: level * smoothstep_slope(u) / self.ramp }
    }

    pub fn sample(&self, i: usize) -> Sample {
        let t = match &self.shape {
            Shape::File(trajectory) => trajectory.time[i],
            _ => i as f64 / self.sample_rate_hz,
        };
        let a = self.amplitude;
        match &self.shape {
            Shape::Sine => {
                let (f, phase) = self.phase(t);
                Sample { t, x: a * phase.sin(), rate: a * TAU * f * phase.cos() }
            }
            Shape::Nested => {
                let (f, phase) = self.phase(t);
                let (big, small) = NESTED_SHARES;
                let k = NESTED_HARMONIC;
                let x = a * (big * phase.sin() + small * (k * phase).sin());
                let rate = a * TAU * f * (big * phase.cos() + small * k * (k * phase).cos());
                Sample { t, x, rate }
            }
            &Shape::Biased { bias: level, swing: amplitude } | &Shape::Hold { load: level, dither: amplitude } => {
                // Up to the oscillation's lowest point, where it starts at rest: x and dx/dt continuous.
                if t < self.ramp {
                    return self.ramp_to(level - amplitude, t);
                }
                let (f, phase) = self.phase(t - self.ramp);
                let k = if matches!(self.shape, Shape::Hold { .. }) { HOLD_DITHER_HARMONIC } else { 1.0 };
                Sample {
                    t,
                    x: level - amplitude * (k * phase).cos(),
                    rate: amplitude * k * TAU * f * (k * phase).sin(),
                }
            }
            Shape::Random { components, window, scale } => {
                let (mut sum, mut slope) = (0.0, 0.0);
                for &(f, phase) in components {
                    let angle = TAU * f * t + phase;
                    sum += angle.sin();
                    slope += TAU * f * angle.cos();
                }
                let u = t / window;
                let (w, dw) = (smoothstep(u), smoothstep_slope(u) / window);
                Sample { t, x: scale * w * sum, rate: scale * (dw * sum + w * slope) }
            }
            Shape::File(trajectory) => Sample { t, x: trajectory.deflection[i], rate: trajectory.rate(i) },
            Shape::Plan(samples) => {
                let (x, rate) = samples[i];
                Sample { t, x, rate }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: f64 = 1.168e-3;

    fn play(motion: &Motion, seed: u64) -> Vec<Sample> {
        let timing = Timing { amplitude: A, frequencies_hz: &[0.5], cycles: 4, sample_rate_hz: 1000.0, seed };
        let played = Played::new(motion, &timing, 1e9).unwrap();
        (0..played.len).map(|i| played.sample(i)).collect()
    }

    /// Turning points of x (sign changes of Δx).
    fn reversals(samples: &[Sample]) -> Vec<usize> {
        let dx: Vec<f64> = samples.windows(2).map(|w| w[1].x - w[0].x).collect();
        (1..dx.len()).filter(|&i| dx[i] * dx[i - 1] < 0.0).collect()
    }

    #[test]
    fn every_rate_is_the_derivative_of_its_deflection() {
        for motion in [
            Motion::Sine,
            Motion::Biased { bias_rad: None },
            Motion::Nested,
            Motion::Random,
            Motion::Hold { load_rad: None },
        ] {
            let s = play(&motion, 3);
            for i in 1..s.len() - 1 {
                let numeric = (s[i + 1].x - s[i - 1].x) / (s[i + 1].t - s[i - 1].t);
                // Central differences are off by O(h·x''), which jumps where the ramp ends.
                let curvature = (s[i + 1].x - 2.0 * s[i].x + s[i - 1].x).abs() / (s[i + 1].t - s[i].t);
                let scale = s[i].rate.abs().max(A);
                assert!(
                    (numeric - s[i].rate).abs() < 2e-3 * scale + curvature,
                    "{motion:?} at {}: {numeric} vs {}",
                    s[i].t,
                    s[i].rate
                );
            }
        }
    }

    #[test]
    fn all_but_sine_start_at_rest_and_stay_within_their_range() {
        for motion in
            [Motion::Biased { bias_rad: None }, Motion::Nested, Motion::Random, Motion::Hold { load_rad: None }]
        {
            let s = play(&motion, 3);
            assert_eq!(s[0].x, 0.0, "{motion:?}");
            let peak = s.iter().map(|s| s.x.abs()).fold(0.0, f64::max);
            assert!(peak <= A * (1.0 + 1e-12), "{motion:?}: {peak}");
        }
        let sine = play(&Motion::Sine, 1);
        assert_eq!(sine.len(), 8001);
        assert_eq!(sine[250].x, A * (TAU * 0.5 * 0.25f64).sin());
    }

    #[test]
    fn biased_oscillates_about_its_bias_after_a_smooth_ramp() {
        let s = play(&Motion::Biased { bias_rad: None }, 1);
        // One period of ramp (2 s) and four cycles.
        assert_eq!(s.len(), 10_001);
        assert_eq!((s[0].x, s[0].rate), (0.0, 0.0));
        assert!((s[2000].x - 0.45 * A).abs() < 1e-15 && s[2000].rate == 0.0);
        let after = &s[2000..10_000];
        let mean = after.iter().map(|s| s.x).sum::<f64>() / after.len() as f64;
        assert!((mean - 0.6 * A).abs() < 1e-3 * A, "mean {mean}");
        let (lo, hi) = after.iter().fold((f64::MAX, f64::MIN), |(lo, hi), s| (lo.min(s.x), hi.max(s.x)));
        assert!((hi - 0.75 * A).abs() < 1e-6 * A && (lo - 0.45 * A).abs() < 1e-6 * A, "{lo} {hi}");
        assert!(s[..2000].windows(2).all(|w| w[1].x >= w[0].x), "the ramp is monotone");
        let custom = play(&Motion::Biased { bias_rad: Some(-0.3e-3) }, 1);
        assert!((custom[2000].x - (-0.3e-3 - 0.15 * A)).abs() < 1e-15);
    }

    #[test]
    fn nested_reverses_inside_the_big_swing() {
        let s = play(&Motion::Nested, 1);
        let turns = reversals(&s);
        // Per cycle: 9 wiggles, each reversing twice, of which two are the big swing's ends.
        assert_eq!(turns.len(), 4 * 18);
        let inner = turns.iter().filter(|&&i| s[i].x.abs() < 0.9 * A).count();
        assert!(inner >= 4 * 14, "{inner} reversals inside");
        // Minor loops at many levels: the inner reversals spread over most of ±A.
        let levels: Vec<f64> = turns.iter().map(|&i| s[i].x / A).collect();
        assert!(levels.iter().any(|&l| l > 0.3 && l < 0.6) && levels.iter().any(|&l| l < -0.3 && l > -0.6));
        let peak = s.iter().map(|s| s.x.abs()).fold(0.0, f64::max);
        assert!((peak - A).abs() < 1e-9 * A);
    }

    #[test]
    fn random_is_band_limited_reproducible_and_seeded() {
        let a = play(&Motion::Random, 5);
        assert_eq!(a, play(&Motion::Random, 5));
        let b = play(&Motion::Random, 6);
        assert!(a.iter().zip(&b).filter(|(a, b)| a.x != b.x).count() > a.len() / 2);
        for s in [&a, &b] {
            let peak = s.iter().map(|s| s.x.abs()).fold(0.0, f64::max);
            assert!((peak - A).abs() < 1e-12 * A);
            // Up to 3·f = 1.5 Hz: at most ~2·1.5 reversals a second (8 s), more than a slow sine's.
            let turns = reversals(s).len();
            assert!((6..=30).contains(&turns), "{turns} reversals");
        }
    }

    #[test]
    fn hold_stays_near_its_load() {
        let s = play(&Motion::Hold { load_rad: None }, 1);
        assert!(s[2000..].iter().all(|s| (s.x - 0.6 * A).abs() <= 0.02 * A * (1.0 + 1e-12)));
        assert!(reversals(&s[2000..]).len() >= 4 * 19, "the dither reverses");
    }

    #[test]
    fn a_trajectory_is_played_at_its_times() {
        let trajectory = Trajectory::new("t", vec![0.0, 0.5, 0.75], vec![1e-4, 3e-4, 2e-4]).unwrap();
        let s = play(&Motion::File(trajectory), 1);
        assert_eq!(s.iter().map(|s| (s.t, s.x)).collect::<Vec<_>>(), [(0.0, 1e-4), (0.5, 3e-4), (0.75, 2e-4)]);
        assert!((s[0].rate - 4e-4).abs() < 1e-15);
        assert!((s[1].rate - 1e-4 / 0.75).abs() < 1e-15);
        assert!(Trajectory::new("t", vec![0.0, 0.0], vec![0.0, 0.0]).is_err());
        assert!(Trajectory::new("t", vec![], vec![]).is_err());
        assert!(Trajectory::new("t", vec![0.0], vec![f64::NAN]).is_err());
    }

    #[test]
    fn trajectory_files_name_the_bad_cell() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.csv");
        std::fs::write(&path, "# motion\ntime_s,deflection_rad\n0,0\n0.1,1e-4\n0.2,x\n").unwrap();
        let e = read_trajectory(&path).unwrap_err();
        assert_eq!((e.line, e.column.clone()), (Some(5), Some((2, "deflection_rad".into()))));
        std::fs::write(&path, "time_s,deflection_rad\n0,0\n0.1,1e-4\n0.1,2e-4\n").unwrap();
        let e = read_trajectory(&path).unwrap_err();
        assert_eq!((e.line, e.column.clone()), (Some(4), Some((1, "time_s".into()))));
        std::fs::write(&path, "time_s,theta\n0,0\n").unwrap();
        assert!(read_trajectory(&path).unwrap_err().to_string().contains("missing column `deflection_rad`"));
        std::fs::write(&path, "deflection_rad,extra,time_s\n1e-4,a,0\n2e-4,b,1\n").unwrap();
        assert_eq!(read_trajectory(&path).unwrap().deflection(), [1e-4, 2e-4]);
    }
}
