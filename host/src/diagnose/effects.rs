//! The physics the genetic hysteresis model leaves out, by the names `diagnose` reports and
//! `simulate --effect` adds.
use std::fmt;
use std::str::FromStr;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Effect {
    /// Lost motion: the elastic deflection is sign(θ)·max(|θ| − w/2, 0).
    Backlash,
    /// T_c·sign(dθ/dt) added to the measured torque.
    CoulombFriction,
    /// c·dθ/dt added to the measured torque.
    ViscousDamping,
    /// Output-angle error periodic in the input angle, 2nd order strongest (+ 4th order).
    KinematicError,
    /// c1 becomes c1·(1 + k·(temperature − temperature at start)).
    ThermalDrift,
    /// Constant zero offset of the torque sensor.
    TorqueOffset,
    /// The torque channel sampled τ later than the angles (τ < 0: earlier), from a sensor
    /// filter or a separate clock: the torque seen at t is the gear's at t − τ, which to first
    /// order is T − τ·dT/dt = T − τ·K·dθ/dt (K the stiffness along the loop). It opens (τ < 0)
    /// or closes (τ > 0) the loop with the rate.
    ChannelDelay,
}

impl Effect {
    pub const ALL: [Effect; 7] = [
        Effect::Backlash,
        Effect::CoulombFriction,
        Effect::ViscousDamping,
        Effect::KinematicError,
        Effect::ThermalDrift,
        Effect::TorqueOffset,
        Effect::ChannelDelay,
    ];

    /// Whether the effect's torque follows the deflection rate (its size, or its sign): it must
    /// then show one magnitude at every rate, when the recording has more than one
    /// ([`crate::diagnose`]'s rate check).
    pub fn is_rate_dependent(self) -> bool {
        matches!(self, Effect::ViscousDamping | Effect::CoulombFriction | Effect::ChannelDelay)
    }

    /// Whether the effect moves the deflection the model runs on (backlash, the kinematic
    /// error) rather than adding torque: it has no torque column, and the micro-slip form takes
    /// it only through the deflection.
    pub fn moves_deflection(self) -> bool {
        matches!(self, Effect::Backlash | Effect::KinematicError)
    }

    /// The effect whose torque has the same form to within the loop's change of stiffness:
    /// damping c·dθ/dt and a channel delay −τ·K·dθ/dt. One is named only when it explains the
    /// recording clearly better than the other ([`crate::diagnose`]'s rival check).
    pub fn rival(self) -> Option<Effect> {
        match self {
            Effect::ViscousDamping => Some(Effect::ChannelDelay),
            Effect::ChannelDelay => Some(Effect::ViscousDamping),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Effect::Backlash => "backlash",
            Effect::CoulombFriction => "coulomb_friction",
            Effect::ViscousDamping => "viscous_damping",
            Effect::KinematicError => "kinematic_error",
            Effect::ThermalDrift => "thermal_drift",
            Effect::TorqueOffset => "torque_offset",
            Effect::ChannelDelay => "channel_delay",
        }
    }

    /// SI unit of the magnitude.
    pub fn unit(self) -> &'static str {
        match self {
            Effect::Backlash => "rad",
            Effect::CoulombFriction | Effect::TorqueOffset => "N·m",
            Effect::ViscousDamping => "N·m·s/rad",
            Effect::KinematicError => "rad",
            Effect::ThermalDrift => "1/K",
            Effect::ChannelDelay => "s",
        }
    }

    /// Whether the effect at `magnitude` gives energy back over a cycle, which no passive gear
    /// does: a damping or a friction below 0 (the simulator draws either sign).
    pub fn gives_energy_back(self, magnitude: f64) -> bool {
        matches!(self, Effect::ViscousDamping | Effect::CoulombFriction) && magnitude < 0.0
    }

    /// What the magnitude is, in words.
    pub fn magnitude_meaning(self) -> &'static str {
        match self {
            Effect::Backlash => "total width of the dead band",
            Effect::CoulombFriction => "friction torque",
            Effect::ViscousDamping => "damping coefficient",
            Effect::KinematicError => "amplitude of the 2nd-order (2 per input revolution) component",
            Effect::ThermalDrift => "relative change of c1 per kelvin",
            Effect::TorqueOffset => "torque sensor zero offset",
            Effect::ChannelDelay => "delay of the torque channel behind the angles (negative: ahead)",
        }
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An effect is written by its name in reports.
impl serde::Serialize for Effect {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl FromStr for Effect {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Effect::ALL.into_iter().find(|e| e.name() == s).ok_or_else(|| {
            let names: Vec<_> = Effect::ALL.iter().map(|e| e.name()).collect();
            format!("unknown effect {s:?}; expected one of {}", names.join(", "))
        })
    }
}

/// An effect with its magnitude in SI units, as `NAME=VALUE`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectValue {
    pub effect: Effect,
    pub value: f64,
}

impl FromStr for EffectValue {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (name, value) = s.split_once('=').ok_or_else(|| format!("expected NAME=VALUE, found {s:?}"))?;
        let effect: Effect = name.trim().parse()?;
        let value: f64 = value
            .trim()
            .parse()
            .map_err(|_| format!("{name}: expected a number in {}, found {value:?}", effect.unit()))?;
        if !value.is_finite() {
            return Err(format!("{name}: the value must be finite"));
        }
        if effect == Effect::Backlash && value < 0.0 {
            return Err("backlash: the dead band width must be >= 0 rad".into());
        }
        Ok(EffectValue { effect, value })
    }
}

/// Kinematic error e(θ_in) = m·cos(2θ_in + p2) + (m/3)·cos(4θ_in + p4), rad.
pub fn kinematic_error(magnitude: f64, phases: (f64, f64), input_angle: f64) -> f64 {
    magnitude * (2.0 * input_angle + phases.0).cos() + magnitude / 3.0 * (4.0 * input_angle + phases.1).cos()
}

/// Elastic deflection behind a dead band of total width `width`.
pub fn backlash(deflection: f64, width: f64) -> f64 {
    (deflection.abs() - width / 2.0).max(0.0).copysign(deflection)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_effects_with_values() {
        let v: EffectValue = "backlash=2.4e-5".parse().unwrap();
        assert_eq!(v, EffectValue { effect: Effect::Backlash, value: 2.4e-5 });
        assert!("friction=1".parse::<EffectValue>().unwrap_err().contains("unknown effect"));
        assert!("coulomb_friction".parse::<EffectValue>().unwrap_err().contains("NAME=VALUE"));
        assert!("backlash=-1e-5".parse::<EffectValue>().is_err());
        for e in Effect::ALL {
            assert_eq!(e.name().parse::<Effect>().unwrap(), e);
        }
    }

    #[test]
    fn backlash_is_a_dead_band() {
        assert_eq!(backlash(1e-6, 4e-6), 0.0);
        assert!((backlash(1e-5, 4e-6) - 8e-6).abs() < 1e-18);
        assert!((backlash(-1e-5, 4e-6) + 8e-6).abs() < 1e-18);
    }
}
