//! How a run is judged: the true transmitted torque against the reference.
use super::lockstep::Tick;
use super::scenario::SETTLING_S;

/// A run's figures, N·m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Score {
    /// RMS of T_true − T_ref from [`SETTLING_S`] on.
    pub rms_nm: f64,
    /// Largest |T_true − T_ref| from [`SETTLING_S`] on.
    pub max_nm: f64,
    /// Peak-to-peak of T_true inside the constant-reference windows (the largest over them);
    /// `None` for a scenario without one.
    pub limit_cycle_nm: Option<f64>,
}

/// Scores `ticks` (in time order); `holds` are the windows [start, end) of constant reference.
pub fn score(ticks: &[Tick], holds: &[(f64, f64)]) -> Score {
    let errors: Vec<f64> = ticks.iter().filter(|t| t.time >= SETTLING_S).map(|t| t.torque - t.reference).collect();
    let n = errors.len().max(1) as f64;
    let rms_nm = (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
    let max_nm = errors.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let limit_cycle_nm = holds
        .iter()
        .filter_map(|&(start, end)| {
            let inside = ticks.iter().filter(|t| t.time >= start && t.time < end).map(|t| t.torque);
            let (low, high) = inside.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(x), h.max(x)));
            (low <= high).then_some(high - low)
        })
        .reduce(f64::max);
    Score { rms_nm, max_nm, limit_cycle_nm }
}

#[cfg(test)]
mod tests {
    use super::*;
    use swg_protocol::ControlMode;

    fn tick(time: f64, reference: f64, torque: f64) -> Tick {
        Tick { time, reference, torque, deflection: 0.0, command: 0.0, estimate: 0.0, mode: ControlMode::Model }
    }

    #[test]
    fn errors_after_settling_and_the_peak_to_peak_in_holds() {
        let ticks: Vec<Tick> = (0..2000)
            .map(|i| {
                let t = i as f64 * 1.0e-3;
                // A large start-up error, then ±0.1 alternating about the reference 5.
                let torque = if t < SETTLING_S {
                    50.0
                } else if i % 2 == 0 {
                    5.1
                } else {
                    4.9
                };
                tick(t, 5.0, torque)
            })
            .collect();
        let score = score(&ticks, &[(1.0, 1.5), (1.5, 2.0)]);
        assert!((score.rms_nm - 0.1).abs() < 1e-9, "{score:?}");
        assert!((score.max_nm - 0.1).abs() < 1e-9, "{score:?}");
        assert!((score.limit_cycle_nm.unwrap() - 0.2).abs() < 1e-9, "{score:?}");
        assert_eq!(super::score(&ticks, &[]).limit_cycle_nm, None);
    }
}
