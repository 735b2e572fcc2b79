use crate::larger;
use model_core::Direction;

/// Smallest loop amplitude reported, rad: keeps θ/A defined before θ has moved at all.
pub const MIN_AMPLITUDE: f32 = 1.0e-7;

/// Follows the direction of the deflection θ and the amplitude of the current loop.
///
/// The direction flips only once θ has moved back by more than `band` from its extreme in
/// the current direction, so encoder noise smaller than the band cannot chatter between the
/// branches at a turning point. The extreme where it flipped is a turning point; the
/// amplitude is the largest |θ| among the last two turning points and the current segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionTracker {
    band: f32,
    direction: Direction,
    /// Max of θ while rising, min while falling, since the last turning point.
    extreme: Option<f32>,
    /// |θ| at the last two turning points, newest first.
    turns: [f32; 2],
}

impl DirectionTracker {
    /// `band` in rad; negative or NaN counts as 0.
    pub fn new(band: f32) -> Self {
        DirectionTracker { band: larger(band, 0.0), direction: Direction::Rising, extreme: None, turns: [0.0; 2] }
    }

    /// Changes the band without losing the loop being tracked.
    pub fn set_band(&mut self, band: f32) {
        self.band = larger(band, 0.0);
    }

    pub fn direction(&self) -> Direction {
        self.direction
    }

    /// Feeds one finite deflection; returns the branch and the loop amplitude (≥
    /// [`MIN_AMPLITUDE`]) to evaluate it on.
    pub fn update(&mut self, theta: f32) -> (Direction, f32) {
        let extreme = match self.extreme {
            None => theta,
            Some(extreme) => match self.direction {
                Direction::Rising if theta > extreme => theta,
                Direction::Falling if theta < extreme => theta,
                Direction::Rising if theta < extreme - self.band => self.turn(extreme, theta),
                Direction::Falling if theta > extreme + self.band => self.turn(extreme, theta),
                _ => extreme,
            },
        };
        self.extreme = Some(extreme);
        let amplitude =
            larger(larger(self.turns[0], self.turns[1]), larger(larger(extreme.abs(), theta.abs()), MIN_AMPLITUDE));
        (self.direction, amplitude)
    }

    /// Records the turning point `extreme`; returns the new segment's extreme.
    fn turn(&mut self, extreme: f32, theta: f32) -> f32 {
        self.turns = [extreme.abs(), self.turns[0]];
        self.direction = match self.direction {
            Direction::Rising => Direction::Falling,
            Direction::Falling => Direction::Rising,
        };
        theta
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// θ = A·sin(2π t/T) plus deterministic noise of ±noise (a fixed pseudo-random sequence).
    fn noisy_sine(amplitude: f32, noise: f32, samples_per_period: usize, periods: usize) -> Vec<f32> {
        let mut state = 0x1234_5678u32;
        (0..samples_per_period * periods)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                let unit = (state as f32 / u32::MAX as f32) * 2.0 - 1.0;
                let phase = core::f32::consts::TAU * i as f32 / samples_per_period as f32;
                amplitude * libm::sinf(phase) + noise * unit
            })
            .collect()
    }

    fn flips(tracker: &mut DirectionTracker, thetas: &[f32]) -> usize {
        let mut last = tracker.direction();
        let mut count = 0;
        for &theta in thetas {
            let (direction, _) = tracker.update(theta);
            if direction != last {
                count += 1;
                last = direction;
            }
        }
        count
    }

    #[test]
    fn noise_inside_the_band_flips_exactly_at_each_turning_point() {
        let thetas = noisy_sine(1.0e-3, 2.0e-6, 2000, 5);
        let mut tracker = DirectionTracker::new(5.0e-6);
        // Five periods from θ = 0 rising: five peaks and five valleys, one flip at each.
        assert_eq!(flips(&mut tracker, &thetas), 10);
    }

    #[test]
    fn without_a_band_the_same_noise_chatters() {
        let thetas = noisy_sine(1.0e-3, 2.0e-6, 2000, 5);
        let mut tracker = DirectionTracker::new(0.0);
        assert!(flips(&mut tracker, &thetas) > 100, "the band test above must mean something");
    }

    #[test]
    fn amplitude_comes_from_the_turning_points() {
        let mut tracker = DirectionTracker::new(1.0e-6);
        for theta in noisy_sine(1.0e-3, 0.0, 1000, 2) {
            tracker.update(theta);
        }
        // Now the loop shrinks to 0.5 mrad: after two new turning points A follows.
        let mut amplitude = 0.0;
        for theta in noisy_sine(0.5e-3, 0.0, 1000, 2) {
            amplitude = tracker.update(theta).1;
        }
        assert!((amplitude - 0.5e-3).abs() < 1.0e-6, "{amplitude}");
        // θ never exceeds A, so θ/A stays in [−1, 1] without clamping.
        let mut tracker = DirectionTracker::new(1.0e-6);
        for theta in noisy_sine(0.8e-3, 0.0, 1000, 3) {
            let (_, amplitude) = tracker.update(theta);
            assert!(theta.abs() <= amplitude);
        }
    }

    #[test]
    fn amplitude_is_positive_at_rest() {
        let mut tracker = DirectionTracker::new(1.0e-6);
        assert_eq!(tracker.update(0.0), (Direction::Rising, MIN_AMPLITUDE));
    }
}
