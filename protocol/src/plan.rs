//! An identification experiment's plan: segments the joint plays one after another, each a
//! reference of one channel (deflection, or joint torque) from the level the last one left,
//! and the limits the experiment must stay within. The host checks a plan before sending it,
//! the board again before it moves; [`Player`] is the one copy of what a plan plays, tick by
//! tick: the board's experiment and `swg-host simulate --motion plan` step the same code.
//!
//! Every segment starts and ends at rest at its level (a ramp eases in and out; a sine or a
//! dither fades in over its first period and out over its last), so the reference and its rate
//! are continuous: a motor asked for a step of rate jerks the gear.
use core::fmt;
use model_core::Real;
use num_traits::ToPrimitive;
use serde::{Deserialize, Serialize};

/// Segments a plan holds at most.
pub const PLAN_SEGMENTS: usize = 12;
/// A plan plays this long at most, s.
pub const MAX_PLAN_SECONDS: f32 = 600.0;
/// A segment's frequencies stay below this fraction of the tick rate: twenty ticks a period.
pub const MAX_FREQUENCY_PER_RATE: f32 = 0.05;
/// A ramp, or a hold without dither, lasts at least this many ticks (a ramp over fewer is a
/// step of rate).
pub const MIN_TICKS: f32 = 20.0;

/// What a plan's references are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[serde(rename_all = "snake_case")]
pub enum Channel {
    /// The deflection θ = θ_in/N − θ_out, rad.
    Deflection,
    /// The joint torque, N·m.
    Torque,
}

impl Channel {
    /// The channel's unit, for messages.
    pub fn unit(self) -> &'static str {
        match self {
            Channel::Deflection => "rad",
            Channel::Torque => "N·m",
        }
    }
}

/// One part of a plan, in its channel's unit, from the level the segments before it left (0,
/// rest, for the first).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Segment {
    /// From the level to `to` in `seconds`, eased in and out (s(u) = 10u³ − 15u⁴ + 6u⁵).
    Ramp { to: f32, seconds: f32 },
    /// `cycles` periods of the level + a·sin 2πft, a faded in over the first period and out over
    /// the last (at least 3: one at full amplitude).
    Sine { amplitude: f32, frequency_hz: f32, cycles: u16 },
    /// The level held for `seconds` with a dither a·sin 2πft, faded in and out over one period
    /// each (at least three periods).
    Hold { seconds: f32, dither_amplitude: f32, dither_hz: f32 },
}

impl Segment {
    /// Its length, s.
    pub fn seconds(&self) -> f32 {
        match *self {
            Segment::Ramp { seconds, .. } | Segment::Hold { seconds, .. } => seconds,
            Segment::Sine { frequency_hz, cycles, .. } => f32::from(cycles) / frequency_hz,
        }
    }

    /// Its oscillation's frequency, Hz (none for a ramp).
    fn frequency_hz(&self) -> Option<f32> {
        match *self {
            Segment::Ramp { .. } => None,
            Segment::Sine { frequency_hz, .. } => Some(frequency_hz),
            Segment::Hold { dither_amplitude, dither_hz, .. } => (dither_amplitude > 0.0).then_some(dither_hz),
        }
    }

    /// Its name, for messages.
    pub fn name(&self) -> &'static str {
        match self {
            Segment::Ramp { .. } => "ramp",
            Segment::Sine { .. } => "sine",
            Segment::Hold { .. } => "hold",
        }
    }

    /// The level it ends at, from `level`.
    fn end(&self, level: f32) -> f32 {
        match *self {
            Segment::Ramp { to, .. } => to,
            _ => level,
        }
    }

    /// The largest |reference| it plays from `level`.
    fn peak(&self, level: f32) -> f32 {
        match *self {
            Segment::Ramp { to, .. } => level.abs().max(to.abs()),
            Segment::Sine { amplitude, .. } => level.abs() + amplitude.abs(),
            Segment::Hold { dither_amplitude, .. } => level.abs() + dither_amplitude.abs(),
        }
    }

    /// What is wrong with it on its own, at `rate_hz` ticks a second.
    fn fault(&self, rate_hz: f32) -> Option<SegmentFault> {
        let nyquist = MAX_FREQUENCY_PER_RATE * rate_hz;
        let frequency = |f: f32| !(f.is_finite() && f > 0.0 && f <= nyquist);
        let length = |seconds: f32, min_s: f32| {
            (!(seconds.is_finite() && seconds >= min_s)).then_some(SegmentFault::Seconds { seconds, min_s })
        };
        match *self {
            Segment::Ramp { to, seconds } => {
                if !to.is_finite() {
                    return Some(SegmentFault::NotFinite("to"));
                }
                // Eased over twenty ticks at least: fewer is a step of rate.
                return length(seconds, MIN_TICKS / rate_hz);
            }
            Segment::Sine { amplitude, frequency_hz, cycles } => {
                if !(amplitude.is_finite() && amplitude > 0.0) {
                    return Some(SegmentFault::Amplitude);
                }
                if frequency(frequency_hz) {
                    return Some(SegmentFault::Frequency { hz: frequency_hz, max_hz: nyquist });
                }
                if cycles < 3 {
                    return Some(SegmentFault::Cycles);
                }
            }
            Segment::Hold { seconds, dither_amplitude, dither_hz } => {
                if !(dither_amplitude.is_finite() && dither_amplitude >= 0.0) {
                    return Some(SegmentFault::Amplitude);
                }
                if dither_amplitude == 0.0 {
                    // No dither: its frequency unused.
                    return length(seconds, MIN_TICKS / rate_hz);
                }
                if frequency(dither_hz) {
                    return Some(SegmentFault::Frequency { hz: dither_hz, max_hz: nyquist });
                }
                return length(seconds, 3.0 / dither_hz);
            }
        }
        None
    }
}

/// What the experiment must stay within: beyond either, the joint stops it and its motor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// |joint torque|, N·m.
    pub torque_nm: f32,
    /// |deflection|, rad.
    pub deflection_rad: f32,
}

/// A checked plan ([`Plan::new`]): its channel, limits and segments.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Plan {
    channel: Channel,
    limits: Limits,
    rate_hz: f32,
    #[serde(with = "segment_array")]
    segments: [Segment; PLAN_SEGMENTS],
    count: u8,
}

/// A plan's segments as serde's arrays are (a tuple of [`PLAN_SEGMENTS`]), read in a loop:
/// serde's own impl reads each element in a call of its own, and its twelve copies of a
/// segment's decoding took 2.2 KB of the joint's flash (`bench/firmware.sh`).
mod segment_array {
    use super::{Segment, PLAN_SEGMENTS};
    use core::fmt;
    use serde::de::{Error, SeqAccess, Visitor};
    use serde::{Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(segments: &[Segment; PLAN_SEGMENTS], serializer: S) -> Result<S::Ok, S::Error> {
        segments.serialize(serializer)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<[Segment; PLAN_SEGMENTS], D::Error> {
        struct Segments;
        impl<'de> Visitor<'de> for Segments {
            type Value = [Segment; PLAN_SEGMENTS];

            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "{PLAN_SEGMENTS} segments")
            }

            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
                let mut segments = [Segment::Ramp { to: 0.0, seconds: 0.0 }; PLAN_SEGMENTS];
                for (index, segment) in segments.iter_mut().enumerate() {
                    *segment = seq.next_element()?.ok_or_else(|| A::Error::invalid_length(index, &self))?;
                }
                Ok(segments)
            }
        }
        deserializer.deserialize_tuple(PLAN_SEGMENTS, Segments)
    }
}

/// Why a segment cannot be played.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SegmentFault {
    /// The named field is not a finite number.
    NotFinite(&'static str),
    /// Its length, `seconds`, is not a number of at least `min_s`: [`MIN_TICKS`] ticks for a
    /// ramp or a hold without dither, three dither periods for a hold with one.
    Seconds { seconds: f32, min_s: f32 },
    /// The amplitude is not finite and positive (a dither's: not negative).
    Amplitude,
    /// The frequency `hz` is not positive, or above `max_hz` ([`MAX_FREQUENCY_PER_RATE`] of the
    /// tick rate).
    Frequency { hz: f32, max_hz: f32 },
    /// Fewer than 3 cycles.
    Cycles,
}

impl fmt::Display for SegmentFault {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            SegmentFault::NotFinite(field) => write!(f, "{field} is not a finite number"),
            SegmentFault::Seconds { seconds, min_s } => write!(
                f,
                "it lasts {seconds} s; it must last at least {min_s} s (twenty ticks for a ramp or a hold \
                 without dither, three periods of its dither for a hold with one)"
            ),
            SegmentFault::Amplitude => {
                f.write_str("the amplitude must be finite and positive (a dither's: at least 0)")
            }
            SegmentFault::Frequency { hz, max_hz } => write!(
                f,
                "its frequency, {hz} Hz, must be positive and at most {max_hz} Hz (twenty ticks a period at the rate \
                 the plan is played at)"
            ),
            SegmentFault::Cycles => f.write_str("a sine needs at least 3 cycles: one to fade in, one to fade out"),
        }
    }
}

/// Why a plan cannot be played.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum PlanError {
    /// No segments.
    Empty,
    /// More than [`PLAN_SEGMENTS`].
    TooManySegments(usize),
    /// The tick rate is not finite and positive.
    Rate,
    /// A limit is not finite and positive.
    Limits,
    /// Segment `index` (from 0; messages count from 1) cannot be played.
    Segment { index: usize, fault: SegmentFault },
    /// Segment `index` reaches `peak`, beyond the limit of the plan's channel.
    BeyondLimit { index: usize, peak: f32, limit: f32 },
    /// The plan plays longer than [`MAX_PLAN_SECONDS`].
    TooLong { seconds: f32 },
}

impl fmt::Display for PlanError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            PlanError::Empty => f.write_str("the plan has no segments"),
            PlanError::TooManySegments(n) => write!(f, "{n} segments: a plan holds at most {PLAN_SEGMENTS}"),
            PlanError::Rate => f.write_str("the tick rate must be finite and positive"),
            PlanError::Limits => f.write_str("the torque and deflection limits must be finite and positive"),
            PlanError::Segment { index, fault } => write!(f, "segment {}: {fault}", index + 1),
            PlanError::BeyondLimit { index, peak, limit } => write!(
                f,
                "segment {} reaches {peak:.6} (in size, from the level the segments before it left), beyond the \
                 plan's limit of {limit} in its channel",
                index + 1
            ),
            PlanError::TooLong { seconds } => {
                write!(f, "the plan plays {seconds} s, longer than the {MAX_PLAN_SECONDS} s a plan may")
            }
        }
    }
}

impl Plan {
    /// `segments` of `channel` played at `rate_hz` ticks a second within `limits`: each segment
    /// playable, none beyond the channel's limit, the whole within [`MAX_PLAN_SECONDS`].
    pub fn new(channel: Channel, limits: Limits, rate_hz: f32, segments: &[Segment]) -> Result<Plan, PlanError> {
        let placeholder = Segment::Ramp { to: 0.0, seconds: 0.0 };
        let mut plan = Plan { channel, limits, rate_hz, segments: [placeholder; PLAN_SEGMENTS], count: 0 };
        if segments.len() > PLAN_SEGMENTS {
            return Err(PlanError::TooManySegments(segments.len()));
        }
        for (slot, segment) in plan.segments.iter_mut().zip(segments) {
            *slot = *segment;
        }
        plan.count = segments.len() as u8;
        plan.check()?;
        Ok(plan)
    }

    /// The checks of [`Plan::new`], again: what a board runs on a plan it received.
    #[inline(never)]
    pub fn check(&self) -> Result<(), PlanError> {
        let rate = self.rate_hz;
        if !(rate.is_finite() && rate > 0.0) {
            return Err(PlanError::Rate);
        }
        let Limits { torque_nm, deflection_rad } = self.limits;
        if !(torque_nm.is_finite() && torque_nm > 0.0 && deflection_rad.is_finite() && deflection_rad > 0.0) {
            return Err(PlanError::Limits);
        }
        if self.count as usize > PLAN_SEGMENTS {
            return Err(PlanError::TooManySegments(self.count as usize));
        }
        let segments = self.segments();
        if segments.is_empty() {
            return Err(PlanError::Empty);
        }
        let limit = self.limit();
        let (mut level, mut seconds) = (0.0f32, 0.0f32);
        for (index, segment) in segments.iter().enumerate() {
            if let Some(fault) = segment.fault(rate) {
                return Err(PlanError::Segment { index, fault });
            }
            let peak = segment.peak(level);
            if peak > limit {
                return Err(PlanError::BeyondLimit { index, peak, limit });
            }
            level = segment.end(level);
            seconds += segment.seconds();
        }
        if seconds > MAX_PLAN_SECONDS {
            return Err(PlanError::TooLong { seconds });
        }
        Ok(())
    }

    pub fn channel(&self) -> Channel {
        self.channel
    }

    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// The limit of the plan's own channel, its unit: what every segment must stay within.
    pub fn limit(&self) -> f32 {
        match self.channel {
            Channel::Deflection => self.limits.deflection_rad,
            Channel::Torque => self.limits.torque_nm,
        }
    }

    /// Ticks a second the plan is played at.
    pub fn rate_hz(&self) -> f32 {
        self.rate_hz
    }

    pub fn segments(&self) -> &[Segment] {
        self.segments.get(..usize::from(self.count)).unwrap_or(&[])
    }

    /// The largest |reference| the plan plays, its channel's unit.
    pub fn peak(&self) -> f32 {
        let (mut level, mut peak) = (0.0f32, 0.0f32);
        for segment in self.segments() {
            peak = peak.max(segment.peak(level));
            level = segment.end(level);
        }
        peak
    }

    /// Ticks the plan plays, the first at rest included.
    pub fn ticks(&self) -> u32 {
        self.segments().iter().fold(1u32, |ticks, s| ticks.saturating_add(segment_ticks(s, self.rate_hz)))
    }

    /// The plan played from its first tick, in `F`.
    pub fn player<F: Real>(&self) -> Player<F> {
        Player { plan: *self, segment: 0, tick: 0, level: F::zero(), cycle: F::zero(), started: false }
    }
}

/// A segment's ticks at `rate_hz`: its length rounded to whole ticks.
fn segment_ticks(segment: &Segment, rate_hz: f32) -> u32 {
    // Rounded to the nearest tick; `as` saturates (a checked plan stays far within u32).
    (segment.seconds() * rate_hz + 0.5) as u32
}

/// A plan's reference at one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setpoint<F> {
    /// In the plan's channel's unit.
    pub value: F,
    /// Its rate, the unit per second.
    pub slope: F,
    /// The segment playing (from 0).
    pub segment: usize,
}

/// A plan played tick by tick: [`Iterator::next`] gives the reference of the next tick, the
/// first at rest (0), and `None` once the last segment has played.
#[derive(Clone, Debug)]
pub struct Player<F> {
    plan: Plan,
    segment: usize,
    /// Ticks into the segment.
    tick: u32,
    /// The level the segments before this one left.
    level: F,
    /// The oscillation's phase in cycles, in [0, 1): advanced by f/rate a tick and wrapped, so
    /// that it keeps its resolution through a long segment (2π·f·t in f32 steps by 0.016 rad
    /// after 600 s at 50 Hz).
    cycle: F,
    started: bool,
}

impl<F: Real> Iterator for Player<F> {
    type Item = Setpoint<F>;

    fn next(&mut self) -> Option<Setpoint<F>> {
        if !self.started {
            self.started = true;
            return Some(Setpoint { value: F::zero(), slope: F::zero(), segment: 0 });
        }
        let rate = self.plan.rate_hz;
        loop {
            let segment = *self.plan.segments().get(self.segment)?;
            let ticks = segment_ticks(&segment, rate);
            if self.tick < ticks {
                self.tick += 1;
                let rate = of::<F>(rate);
                let t = of::<F>(self.tick) / rate;
                if let Some(f) = segment.frequency_hz() {
                    self.cycle = self.cycle + of::<F>(f) / rate;
                    if self.cycle >= F::one() {
                        self.cycle = self.cycle - F::one();
                    }
                }
                let (value, slope) = play(&segment, self.level, of::<F>(ticks) / rate, t, self.cycle);
                return Some(Setpoint { value, slope, segment: self.segment });
            }
            if let Segment::Ramp { to, .. } = segment {
                self.level = of(to);
            }
            self.segment += 1;
            self.tick = 0;
            self.cycle = F::zero();
        }
    }
}

/// `value` in `F`: exact for every f32 and u32 in f64, and converted without a detour through
/// f64 in f32 (which the M4F has no instructions for: its soft-float calls took 180 of a tick's
/// instructions while a plan played, `bench/firmware.sh`).
fn of<F: Real>(value: impl ToPrimitive) -> F {
    F::from(value).unwrap_or_else(F::nan)
}

/// `segment`'s reference and its rate at time `t` of its `length` s, from `level`, its
/// oscillation at phase `cycle` (cycles).
fn play<F: Real>(segment: &Segment, level: F, length: F, t: F, cycle: F) -> (F, F) {
    match *segment {
        Segment::Ramp { to, .. } => {
            let u = t / length;
            let rise = of::<F>(to) - level;
            (level + rise * smoothstep(u), rise * smoothstep_slope(u) / length)
        }
        Segment::Sine { amplitude: a, frequency_hz: f, .. }
        | Segment::Hold { dither_amplitude: a, dither_hz: f, .. } => {
            let (a, f) = (of::<F>(a), of::<F>(f));
            // Faded in over the first period and out over the last: w rises from 0 to 1 and
            // back, with zero slope at both ends.
            let fade = F::one() / f;
            let (rise, fall) = (t / fade, (length - t) / fade);
            let (w, dw) = if rise < F::one() {
                (smoothstep(rise), smoothstep_slope(rise) / fade)
            } else if fall < F::one() {
                (smoothstep(fall), -smoothstep_slope(fall) / fade)
            } else {
                (F::one(), F::zero())
            };
            let (sin, cos) = turn(cycle);
            (level + a * w * sin, a * (dw * sin + w * F::TAU() * f * cos))
        }
    }
}

/// 1 − x²/k₁·(1 − x²/k₂·(1 − …)): the Taylor series of sin x / x or cos x in Horner's form,
/// from the ratios k of its successive terms, written out so that each 1/k is a constant of `F`.
macro_rules! series {
    ($x2:expr; $k:expr) => { F::one() - $x2 * of::<F>(1.0 / $k) };
    ($x2:expr; $k:expr, $($rest:expr),+) => { F::one() - $x2 * of::<F>(1.0 / $k) * series!($x2; $($rest),+) };
}

/// sin and cos of 2π·`cycle`, `cycle` in [0, 1): the nearest quarter turn leaves an angle x in
/// [−π/4, π/4], where the Taylor series to x⁹ (f32) or x¹⁷ (f64) is exact to `F`'s rounding
/// (the first term left out is below 3·10⁻⁸ or 2·10⁻¹⁸). Written out rather than libm's
/// `sinf`/`cosf`, whose reduction of any angle (`rem_pio2f`, and their kernels in f64,
/// soft-float on the M4F) took 5.6 KB of the joint's flash.
fn turn<F: Real>(cycle: F) -> (F, F) {
    let quarters = cycle * of::<F>(4.0);
    // cycle ∈ [0, 1): `quarters + ½` is not negative, so truncation is the floor.
    let nearest = (quarters + of::<F>(0.5)).to_u32().unwrap_or(0);
    let x = (quarters - of::<F>(nearest)) * F::FRAC_PI_2();
    let x2 = x * x;
    let (sin, cos) = if F::epsilon() > of::<F>(1.0e-10) {
        (series!(x2; 6.0, 20.0, 42.0, 72.0), series!(x2; 2.0, 12.0, 30.0, 56.0))
    } else {
        (
            series!(x2; 6.0, 20.0, 42.0, 72.0, 110.0, 156.0, 210.0, 272.0),
            series!(x2; 2.0, 12.0, 30.0, 56.0, 90.0, 132.0, 182.0, 240.0),
        )
    };
    let sin = x * sin;
    match nearest % 4 {
        0 => (sin, cos),
        1 => (cos, -sin),
        2 => (-sin, -cos),
        _ => (-cos, sin),
    }
}

/// s(u) = 10u³ − 15u⁴ + 6u⁵ on [0, 1] (0 and 1 beyond): zero slope and curvature at both ends.
pub fn smoothstep<F: Real>(u: F) -> F {
    // By comparisons: `max`/`min` are calls on the M4F (`fmaxf`/`fminf`), in the tick.
    let u = if u < F::zero() {
        F::zero()
    } else if u > F::one() {
        F::one()
    } else {
        u
    };
    u * u * u * (of::<F>(10.0) + u * (of::<F>(-15.0) + of::<F>(6.0) * u))
}

/// ds/du.
pub fn smoothstep_slope<F: Real>(u: F) -> F {
    if u < F::zero() || u > F::one() {
        return F::zero();
    }
    let v = F::one() - u;
    of::<F>(30.0) * u * u * v * v
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    #[test]
    fn a_turn_is_sin_and_cos_to_the_rounding_of_each_type() {
        for k in 0..=4096 {
            let cycle = k as f64 / 4097.0;
            let (sin, cos) = turn(cycle);
            let exact = (core::f64::consts::TAU * cycle).sin_cos();
            // A few units in the last place of each: the reference's 2π·cycle is rounded too.
            assert!((sin - exact.0).abs() < 1e-15 && (cos - exact.1).abs() < 1e-15, "{cycle}");
            let (sin, cos) = turn(cycle as f32);
            let exact = (core::f64::consts::TAU * f64::from(cycle as f32)).sin_cos();
            let errors = (f64::from(sin) - exact.0, f64::from(cos) - exact.1);
            assert!(errors.0.abs() < 2.5e-7 && errors.1.abs() < 2.5e-7, "{cycle} {errors:?}");
        }
    }

    const LIMITS: Limits = Limits { torque_nm: 50.0, deflection_rad: 2.0e-3 };
    const A: f32 = 1.0e-3;

    /// Up, a sine and a dithered hold there, a sine about 0 after the ramp back.
    fn segments() -> [Segment; 5] {
        [
            Segment::Ramp { to: 0.5 * A, seconds: 0.5 },
            Segment::Sine { amplitude: 0.5 * A, frequency_hz: 2.0, cycles: 4 },
            Segment::Hold { seconds: 1.0, dither_amplitude: 0.05 * A, dither_hz: 10.0 },
            Segment::Ramp { to: 0.0, seconds: 0.5 },
            Segment::Sine { amplitude: A, frequency_hz: 1.0, cycles: 3 },
        ]
    }

    fn plan() -> Plan {
        Plan::new(Channel::Deflection, LIMITS, 1000.0, &segments()).unwrap()
    }

    #[test]
    fn a_plan_plays_from_rest_to_rest_with_its_rate_continuous() {
        let plan = plan();
        let played: Vec<Setpoint<f64>> = plan.player().collect();
        assert_eq!(played.len() as u32, plan.ticks());
        let (first, last) = (played[0], played[played.len() - 1]);
        assert_eq!((first.value, first.slope), (0.0, 0.0));
        assert!(last.value.abs() < 1e-12 && last.slope.abs() < 1e-9, "{last:?}");
        let dt = 1.0 / 1000.0;
        let steepest = played.iter().map(|s| s.slope.abs()).fold(0.0, f64::max);
        for pair in played.windows(2) {
            // The value moves by its rate; the rate itself by no more than a tick's worth of the
            // steepest curvature (2π·f·rate), so no step in it.
            let moved = pair[1].value - pair[0].value;
            let mean_rate = 0.5 * (pair[0].slope + pair[1].slope);
            assert!((moved - mean_rate * dt).abs() <= 2e-3 * steepest * dt, "{pair:?}");
            assert!((pair[1].slope - pair[0].slope).abs() <= 0.05 * steepest, "{pair:?}");
        }
        // Each segment reaches what it says, within the limit.
        let peak =
            |segment: usize| played.iter().filter(|s| s.segment == segment).map(|s| s.value).fold(f64::MIN, f64::max);
        assert!((peak(1) - f64::from(A)).abs() < 1e-3 * f64::from(A), "{}", peak(1));
        assert!((peak(2) - 0.55 * f64::from(A)).abs() < 1e-3 * f64::from(A), "{}", peak(2));
        assert!((peak(4) - f64::from(A)).abs() < 1e-3 * f64::from(A), "{}", peak(4));
        assert!(played.iter().all(|s| s.value.abs() <= f64::from(LIMITS.deflection_rad)));
    }

    /// The board's f32 phase gains at most half an f32 step of 1 cycle a tick on the host's:
    /// over this plan's 2,500 oscillating ticks, 1.5·10⁻⁴ cycles, 10⁻³ of the amplitude.
    #[test]
    fn the_board_plays_in_f32_what_the_host_plays_in_f64() {
        let (host, board): (Vec<Setpoint<f64>>, Vec<Setpoint<f32>>) =
            (plan().player().collect(), plan().player().collect());
        assert_eq!(host.len(), board.len());
        let worst = host.iter().zip(&board).map(|(h, b)| (h.value - f64::from(b.value)).abs()).fold(0.0, f64::max);
        assert!(worst <= 1e-3 * f64::from(A), "{worst}");
        assert!(host.iter().zip(&board).all(|(h, b)| h.segment == b.segment));
    }

    #[test]
    fn a_plan_that_cannot_be_played_is_refused_with_the_segment_and_the_reason() {
        let with = |segment: Segment| {
            let mut all = segments();
            all[1] = segment;
            Plan::new(Channel::Deflection, LIMITS, 1000.0, &all)
        };
        let fault = |result: Result<Plan, PlanError>| match result {
            Err(PlanError::Segment { index: 1, fault }) => fault,
            other => panic!("{other:?}"),
        };
        assert_eq!(fault(with(Segment::Sine { amplitude: A, frequency_hz: 2.0, cycles: 2 })), SegmentFault::Cycles);
        assert_eq!(
            fault(with(Segment::Sine { amplitude: A, frequency_hz: 60.0, cycles: 3 })),
            SegmentFault::Frequency { hz: 60.0, max_hz: 50.0 }
        );
        assert_eq!(
            fault(with(Segment::Sine { amplitude: f32::NAN, frequency_hz: 2.0, cycles: 3 })),
            SegmentFault::Amplitude
        );
        assert_eq!(fault(with(Segment::Ramp { to: f32::INFINITY, seconds: 1.0 })), SegmentFault::NotFinite("to"));
        assert_eq!(
            fault(with(Segment::Ramp { to: 0.0, seconds: 0.019 })),
            SegmentFault::Seconds { seconds: 0.019, min_s: 0.02 }
        );
        assert_eq!(
            fault(with(Segment::Hold { seconds: 0.2, dither_amplitude: 1e-5, dither_hz: 10.0 })),
            SegmentFault::Seconds { seconds: 0.2, min_s: 0.3 }
        );
        // Without a dither its frequency is unused, and the level is held.
        let still = Segment::Hold { seconds: 0.5, dither_amplitude: 0.0, dither_hz: 0.0 };
        let plan = with(still).unwrap();
        assert!(plan
            .player::<f64>()
            .filter(|s| s.segment == 1)
            .all(|s| s.value == f64::from(0.5 * A) && s.slope == 0.0));
        // From the 0.5·A the ramp left, a sine of 1.6·A reaches 2.1·A, beyond the 2 mrad limit.
        match with(Segment::Sine { amplitude: 1.6 * A, frequency_hz: 2.0, cycles: 3 }) {
            Err(PlanError::BeyondLimit { index: 1, peak, limit }) => {
                assert_eq!((peak, limit), (0.5 * A + 1.6 * A, 2.0e-3))
            }
            other => panic!("{other:?}"),
        }
        let long = [Segment::Hold { seconds: 601.0, dither_amplitude: 0.0, dither_hz: 1.0 }];
        assert!(matches!(Plan::new(Channel::Deflection, LIMITS, 1000.0, &long), Err(PlanError::TooLong { .. })));
        assert_eq!(Plan::new(Channel::Torque, LIMITS, 1000.0, &[]), Err(PlanError::Empty));
        assert_eq!(Plan::new(Channel::Torque, LIMITS, 0.0, &segments()), Err(PlanError::Rate));
        let no_limit = Limits { torque_nm: 0.0, ..LIMITS };
        assert_eq!(Plan::new(Channel::Torque, no_limit, 1000.0, &segments()), Err(PlanError::Limits));
        assert_eq!(
            Plan::new(Channel::Torque, LIMITS, 1000.0, &[segments()[0]; PLAN_SEGMENTS + 1]),
            Err(PlanError::TooManySegments(PLAN_SEGMENTS + 1))
        );
    }

    /// What the board receives is checked again: a plan decoded from bytes is refused as
    /// `Plan::new` would refuse it.
    #[test]
    fn a_received_plan_is_checked_again() {
        let mut bytes = [0u8; 512];
        let used = postcard::to_slice(&plan(), &mut bytes).unwrap().len();
        let back: Plan = postcard::from_bytes(&bytes[..used]).unwrap();
        assert_eq!(back, plan());
        assert_eq!(back.check(), Ok(()));
        let mut beyond = plan();
        beyond.limits.deflection_rad = 0.5 * A;
        assert!(matches!(beyond.check(), Err(PlanError::BeyondLimit { index: 1, .. })));
    }
}
