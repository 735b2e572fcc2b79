//! Everything of the joint firmware that does not touch a register, so that it runs and is
//! tested on the host: the boards only move bytes and encoder readings in and out. The one
//! exception, `systick` (compiled for the Cortex-M only), is the SysTick set-up and tick
//! timing both boards share.
//!
//! Per control tick ([`Compensator::tick`]): deflection θ = θ_in/N − θ_out, then one step of
//! the installed model's stateful evaluator from model-core (`GeneticMemory`: the genetic model
//! with Madelung's rules, a reversal band against encoder noise; or `MicroSlip`) giving T_ff
//! and K — with libm, or for the genetic kind by the fast path's elementary functions
//! ([`fast::FastMath`]) — clamped to the torque limit. The torque controller
//! ([`controller::Controller`]) closes its loop on that T_ff (or on one stiffness) and hands the
//! motor command to the board's [`MotorDrive`].
//!
//! A board runs two halves at two priorities: the control tick ([`Joint`]: compensator and
//! controller) in its timer interrupt, and the link ([`Server`]: frames, requests, replies,
//! flash commits) below it, handing work to the tick through the lock-free [`handoff`].
//! [`Device`] runs both in one thread for tests.
//!
//! Lints: the workspace's (firmware/Cargo.toml and firmware/clippy.toml).
#![no_std]

pub mod as5047p;
pub mod budget;
mod compensator;
pub mod controller;
pub mod direct;
pub mod drive;
pub mod experiment;
pub mod fast;
pub mod flash;
pub mod handoff;
pub mod handover;
pub mod sensor;
mod server;
pub mod storage;
#[cfg(target_arch = "arm")]
pub mod systick;
#[cfg(test)]
mod test_support;
mod tick;

pub use compensator::{Compensator, Stager, Ticker, MAX_DEFLECTION};
pub use controller::Controller;
pub use drive::{MotorDrive, NoDrive};
pub use experiment::Readings;
pub use fast::FastModel;
pub use sensor::AngleSensor;
pub use server::{Device, Server};
pub use tick::{Joint, TickStart};

use swg_protocol::Version;

/// This firmware's version, reported in [`swg_protocol::DeviceInfo`].
pub const FIRMWARE_VERSION: Version = Version { major: 0, minor: 1, patch: 0 };

/// `value` limited to [`low`, `high`] by comparisons (`f32::max`/`min` become calls to
/// `fmaxf`/`fminf` on the Cortex-M4F, which has no `vmaxnm` before Armv8); NaN stays NaN.
#[inline(always)]
pub(crate) fn limit(value: f32, low: f32, high: f32) -> f32 {
    if value < low {
        low
    } else if value > high {
        high
    } else {
        value
    }
}

/// Makes a single-turn angle multi-turn by counting the wraps between readings; valid while
/// the shaft turns less than half a revolution per reading.
#[derive(Clone, Copy, Debug, Default)]
pub struct TurnCounter {
    last: Option<f32>,
    total: f32,
}

impl TurnCounter {
    /// Feeds a reading in [0, 2π) rad; returns the accumulated angle, rad.
    pub fn update(&mut self, angle: f32) -> f32 {
        use core::f32::consts::{PI, TAU};
        match self.last {
            None => self.total = angle,
            Some(last) => {
                let mut step = angle - last;
                if step > PI {
                    step -= TAU;
                } else if step < -PI {
                    step += TAU;
                }
                self.total += step;
            }
        }
        self.last = Some(angle);
        self.total
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn firmware_version_is_the_crate_version() {
        let text = std::format!("{FIRMWARE_VERSION}");
        assert_eq!(text, env!("CARGO_PKG_VERSION"));
    }

    #[test]
    fn turn_counter_follows_wraps_both_ways() {
        let mut counter = TurnCounter::default();
        let tau = core::f32::consts::TAU;
        let mut expected = 6.0;
        assert_eq!(counter.update(6.0), 6.0);
        // Forward across 2π three times, then back across 0 five times.
        for step in [0.5f32; 40].into_iter().chain([-0.5f32; 100]) {
            expected += step;
            let got = counter.update(expected.rem_euclid(tau));
            assert!((got - expected).abs() < 1e-3, "{got} vs {expected}");
        }
    }
}
