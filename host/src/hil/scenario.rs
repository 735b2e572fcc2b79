//! What the joint is asked to do (the torque reference against time) and what it pushes
//! against (the output's inertia and environment).
use super::HilError;
use crate::simulate::motion::smoothstep;
use std::f64::consts::TAU;

/// Errors are scored from this time on, s: the start-up transient (from rest, the first
/// reference step) is not what the comparison is about.
pub const SETTLING_S: f64 = 0.5;
/// A limit cycle is what persists: it is measured on this last fraction of each window of
/// constant reference, once the step's or the ramp's transient (the gravity link swings for
/// about a second after its ramp) has died away.
pub const HOLD_FRACTION: f64 = 0.5;

/// The scenarios of `swg-host hil`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scenario {
    /// 10 N·m at 1 Hz plus 5 N·m at 3.7 Hz against a compliant environment (2000 N·m/rad).
    TorqueSine,
    /// Steps between 6, −4, 12 and 2 N·m, each held a quarter of the run, against the same
    /// environment.
    TorqueSteps,
    /// A free output driven into a stiff wall 0.02 rad away (3 N·m), then pressed with
    /// 8 N·m + 5 N·m at 2 Hz, then held at 8 N·m for the last second.
    Contact,
    /// A pendulum link (m·g·l = 11.8 N·m, 0.37 kg·m², a damped bearing) raised to 40° by a
    /// reference ramped to m·g·l·sin 40° = 7.6 N·m over a second, then held there.
    GravityHold,
}

/// What the output pushes against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Environment {
    /// Output inertia (link, flexspline, load), kg·m².
    pub inertia: f64,
    /// Output bearing's viscous friction, N·m·s/rad.
    pub damping: f64,
    pub kind: EnvironmentKind,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EnvironmentKind {
    /// A compliant environment on both sides of the rest position: k·q + c·q̇.
    Spring { stiffness: f64, damping: f64 },
    /// A one-sided compliant wall at `position`: k·(q − q_w) + c·q̇ while pressed (never
    /// pulling).
    Wall { position: f64, stiffness: f64, damping: f64 },
    /// Gravity on a link hanging at q = 0: m·g·l·sin q.
    Gravity { moment: f64 },
}

impl Environment {
    /// The torque the environment returns on the output at angle `q` and velocity `v`, N·m.
    pub fn reaction(&self, q: f64, v: f64) -> f64 {
        let contact = match self.kind {
            EnvironmentKind::Spring { stiffness, damping } => stiffness * q + damping * v,
            EnvironmentKind::Wall { position, stiffness, damping } if q > position => {
                (stiffness * (q - position) + damping * v).max(0.0)
            }
            EnvironmentKind::Wall { .. } => 0.0,
            EnvironmentKind::Gravity { moment } => moment * q.sin(),
        };
        contact + self.damping * v
    }

    pub fn validate(&self) -> Result<(), HilError> {
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        let fine = self.inertia > 0.0
            && ok(self.inertia)
            && ok(self.damping)
            && match self.kind {
                EnvironmentKind::Spring { stiffness, damping } => ok(stiffness) && ok(damping),
                EnvironmentKind::Wall { position, stiffness, damping } => {
                    position.is_finite() && ok(stiffness) && ok(damping)
                }
                EnvironmentKind::Gravity { moment } => ok(moment),
            };
        if fine {
            Ok(())
        } else {
            Err(HilError::Environment(format!("{self:?}")))
        }
    }
}

/// The gravity link: 4 kg at 0.3 m (m·g·l = 11.8 N·m), J = m·l² + 0.01 kg·m².
const GRAVITY_MOMENT: f64 = 4.0 * 9.81 * 0.3;
const GRAVITY_HOLD_ANGLE: f64 = 40.0 * std::f64::consts::PI / 180.0;

impl Scenario {
    pub const ALL: [Scenario; 4] =
        [Scenario::TorqueSine, Scenario::TorqueSteps, Scenario::Contact, Scenario::GravityHold];

    /// The name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Scenario::TorqueSine => "torque-sine",
            Scenario::TorqueSteps => "torque-steps",
            Scenario::Contact => "contact",
            Scenario::GravityHold => "gravity-hold",
        }
    }

    /// Seconds of simulated time a run lasts unless told otherwise.
    pub const DEFAULT_SECONDS: f64 = 4.0;

    /// The output side.
    pub fn environment(self) -> Environment {
        // A light link (0.05 kg·m²) with a sealed bearing.
        let (inertia, damping) = (0.05, 0.5);
        match self {
            Scenario::TorqueSine | Scenario::TorqueSteps => {
                Environment { inertia, damping, kind: EnvironmentKind::Spring { stiffness: 2000.0, damping: 5.0 } }
            }
            Scenario::Contact => Environment {
                inertia,
                damping,
                kind: EnvironmentKind::Wall { position: 0.02, stiffness: 3000.0, damping: 5.0 },
            },
            Scenario::GravityHold => Environment {
                inertia: 4.0 * 0.3 * 0.3 + 0.01,
                // A damped link bearing (3 N·m·s/rad, ζ ≈ 0.8 on the pendulum): the hold is
                // about the torque loop, not about a link left swinging.
                damping: 3.0,
                kind: EnvironmentKind::Gravity { moment: GRAVITY_MOMENT },
            },
        }
    }

    /// T_ref at time `t` of a run of `seconds`, N·m.
    pub fn reference(self, t: f64, seconds: f64) -> f64 {
        match self {
            Scenario::TorqueSine => 10.0 * (TAU * t).sin() + 5.0 * (TAU * 3.7 * t).sin(),
            Scenario::TorqueSteps => {
                const LEVELS: [f64; 4] = [6.0, -4.0, 12.0, 2.0];
                let index = ((4.0 * t / seconds).floor() as usize).min(3);
                LEVELS[index]
            }
            Scenario::Contact => {
                let hold = (seconds - 1.0).max(0.5);
                if t < 0.3 {
                    3.0
                } else if t < 0.5 {
                    3.0 + 5.0 * smoothstep((t - 0.3) / 0.2)
                } else if t < hold {
                    8.0 + 5.0 * (TAU * 2.0 * (t - 0.5)).sin()
                } else {
                    8.0
                }
            }
            Scenario::GravityHold => GRAVITY_MOMENT * GRAVITY_HOLD_ANGLE.sin() * smoothstep(t.min(1.0)),
        }
    }

    /// The windows [start, end) of a run of `seconds` where the limit cycle is measured: the
    /// last [`HOLD_FRACTION`] of each window of constant reference. Empty for the sine.
    pub fn holds(self, seconds: f64) -> Vec<(f64, f64)> {
        let windows: Vec<(f64, f64)> = match self {
            Scenario::TorqueSine => Vec::new(),
            Scenario::TorqueSteps => {
                (0..4).map(|i| (i as f64 * seconds / 4.0, (i + 1) as f64 * seconds / 4.0)).collect()
            }
            Scenario::Contact => vec![((seconds - 1.0).max(0.5), seconds)],
            Scenario::GravityHold => vec![(1.0, seconds)],
        };
        windows
            .into_iter()
            .map(|(start, end)| (end - HOLD_FRACTION * (end - start), end))
            .filter(|(start, end)| start < end)
            .collect()
    }
}

impl std::str::FromStr for Scenario {
    type Err = String;
    fn from_str(name: &str) -> Result<Self, String> {
        Scenario::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown scenario {name:?}: torque-sine, torque-steps, contact or gravity-hold"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn references_are_continuous_where_they_should_be_and_hold_where_stated() {
        let seconds = 3.0;
        for scenario in Scenario::ALL {
            for (start, end) in scenario.holds(seconds) {
                let first = scenario.reference(start, seconds);
                let mut t = start;
                while t < end {
                    assert_eq!(scenario.reference(t, seconds), first, "{scenario:?} at {t}");
                    t += 1.0e-3;
                }
            }
        }
        assert!(Scenario::TorqueSine.holds(seconds).is_empty());
        assert_eq!(Scenario::TorqueSteps.holds(seconds).len(), 4);
        // The contact's press is continuous into the hold after whole cycles.
        let before = Scenario::Contact.reference(2.0 - 1.0e-9, seconds);
        assert!((before - 8.0).abs() < 1e-6, "{before}");
        let peak = Scenario::GravityHold.reference(2.0, seconds);
        assert!((peak - 7.567).abs() < 1e-3, "{peak}");
    }

    #[test]
    fn a_wall_only_pushes() {
        let Environment { kind, .. } = Scenario::Contact.environment();
        let wall = Environment { inertia: 1.0, damping: 0.0, kind };
        assert_eq!(wall.reaction(0.0, 1.0), 0.0);
        assert!((wall.reaction(0.03, 0.0) - 30.0).abs() < 1e-9);
        // Leaving fast: the damper would pull, the wall does not.
        assert_eq!(wall.reaction(0.0201, -10.0), 0.0);
        assert_eq!("contact".parse::<Scenario>(), Ok(Scenario::Contact));
        assert!("wall".parse::<Scenario>().is_err());
    }
}
