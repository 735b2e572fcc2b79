//! Passivity: a gear stores and dissipates energy, it never hands any back over a closed loop,
//! so ∮T dθ ≥ 0 for every closed loop: the torque is higher while θ rises than while it falls.
//! A loop that runs the other way (∮ < 0 beyond the noise) points at the measurement: branch
//! labels swapped, or a torque channel sampled late or early relative to the angles.
use crate::input::{Branch, LoopTable, Recording};
use crate::prepare::{NoiseModel, TurningPoint};
use serde::Serialize;

/// A loop table's loop counts as active when its energy is below −this share of the work
/// ∫|T| dθ over the overlap of its branches: the table gives no noise to judge by.
pub const TABLE_TOLERANCE: f64 = 0.01;
/// A recording's loops count as active when their mean energy is below −this many standard
/// errors.
pub const ACTIVE_SIGMAS: f64 = 3.0;

/// The energy the gear takes per closed loop.
#[derive(Clone, Debug, Serialize)]
pub struct Passivity {
    /// ∮T dθ of each closed loop, J (N·m·rad), in order.
    pub energy_per_cycle_j: Vec<f64>,
    /// Their mean, J; none without a closed loop.
    pub mean_energy_j: Option<f64>,
    /// The mean's standard error from the noise (recordings), or the table's tolerance, J.
    pub uncertainty_j: Option<f64>,
    /// The loop gives energy back beyond the noise.
    pub active: bool,
    /// The delay of the torque channel relative to the angles that would make the loops
    /// passive (∮ = 0), s; positive: the torque was sampled late. Recordings only.
    pub passive_delay_s: Option<f64>,
    pub words: String,
}

/// The closed loops of a recording: from each maximum of the deflection to the next, or from
/// each minimum to the next where that closes more loops. A path that does not return to the
/// same extreme is not integrated: its ∫T dθ is the energy stored, not dissipated (a bench's
/// ramp cycle from rest, run to the end of the file, read "active" on a passive spring). With no
/// closed loop it says so, and gives no verdict.
pub fn of_recording(recording: &Recording, turning_points: &[TurningPoint], noise: &NoiseModel) -> Passivity {
    let (t, theta, torque) = (&recording.time, &recording.deflection, &recording.torque);
    let at = |maximum: bool| -> Vec<usize> {
        turning_points.iter().filter(|tp| tp.is_maximum == maximum).map(|tp| tp.index).collect()
    };
    let (maxima, minima) = (at(true), at(false));
    let cycle_ends = if minima.len() > maxima.len() { minima } else { maxima };
    if cycle_ends.len() < 2 {
        return Passivity {
            energy_per_cycle_j: Vec::new(),
            mean_energy_j: None,
            uncertainty_j: None,
            active: false,
            passive_delay_s: None,
            words: format!(
                "no closed cycle (from a turning point to the next at the same extreme; this recording has {} \
                 turning points): no verdict on passivity",
                turning_points.len()
            ),
        };
    }
    let mut energies = Vec::new();
    let mut rates = Vec::new();
    let mut variance = 0.0;
    for pair in cycle_ends.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let (mut energy, mut rate_work, mut var) = (0.0, 0.0, 0.0);
        for i in a..b {
            let dtheta = theta[i + 1] - theta[i];
            energy += 0.5 * (torque[i] + torque[i + 1]) * dtheta;
            var += (noise.torque_nm * dtheta).powi(2) + (noise.deflection_rad * (torque[i + 1] - torque[i])).powi(2);
            // ∮ (dT/dt) dθ: how the energy changes per second of delay in the torque channel.
            let dt = t[i + 1] - t[i];
            if dt > 0.0 {
                rate_work += (torque[i + 1] - torque[i]) / dt * dtheta;
            }
        }
        energies.push(energy);
        rates.push(rate_work);
        variance += var;
    }
    let cycles = energies.len() as f64;
    let mean = energies.iter().sum::<f64>() / cycles;
    let analytic = variance.sqrt() / cycles;
    let spread = if energies.len() >= 3 {
        (energies.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (cycles - 1.0)).sqrt() / cycles.sqrt()
    } else {
        0.0
    };
    let uncertainty = analytic.max(spread);
    let active = mean < -ACTIVE_SIGMAS * uncertainty;
    // E(τ) ≈ E + τ·∮(dT/dt)dθ for a torque sampled τ late: τ that brings E to 0.
    let rate_work = rates.iter().sum::<f64>() / cycles;
    let passive_delay_s = (rate_work.abs() > 0.0).then(|| -mean / rate_work).filter(|d| d.is_finite());
    let words = if active {
        format!(
            "the loop runs the active way: ∮T dθ = {mean:.4e} J per cycle over {} cycles (±{uncertainty:.1e} J), \
             energy no passive gear gives back. Likely causes: the torque channel lags or leads the angles{}, or \
             the torque's sign or the deflection's is swapped; or, in a simulated recording, a model whose loop \
             runs the active way (the paper's published parameters, `swg-host simulate`'s default, do: h > 0)",
            energies.len(),
            passive_delay_s.map_or(String::new(), |d| format!(" (a delay of {d:.3e} s would make it passive)"))
        )
    } else if mean < 0.0 {
        // Below 0 but within the uncertainty: no energy shown given back, none shown taken.
        format!(
            "passive within the uncertainty: ∮T dθ = {mean:.4e} J per cycle over {} cycles (±{uncertainty:.1e} J), \
             within {ACTIVE_SIGMAS} standard errors of 0: a loop too thin to show the energy it takes",
            energies.len()
        )
    } else {
        format!(
            "passive: ∮T dθ = {mean:.4e} J per cycle over {} cycles (±{uncertainty:.1e} J), the energy the gear \
             dissipates",
            energies.len()
        )
    };
    Passivity {
        energy_per_cycle_j: energies,
        mean_energy_j: Some(mean),
        uncertainty_j: Some(uncertainty),
        active,
        passive_delay_s,
        words,
    }
}

/// The loop of a table: in each quadrant, the area between the branch that raises θ and the
/// one that lowers it, over the deflections both cover.
pub fn of_loop_table(table: &LoopTable) -> Option<Passivity> {
    let branch = |which: Branch| -> Vec<(f64, f64)> {
        let mut points: Vec<(f64, f64)> = (0..table.branch.len())
            .filter(|&i| table.branch[i] == which)
            .map(|i| (table.deflection[i], table.torque[i]))
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        points
    };
    let mut energies = Vec::new();
    let mut work = 0.0;
    let mut overlaps = Vec::new();
    for (rising, falling) in
        [(Branch::ForwardLoading, Branch::ForwardUnloading), (Branch::ReverseUnloading, Branch::ReverseLoading)]
    {
        let (up, down) = (branch(rising), branch(falling));
        let (Some(lo), Some(hi)) = (
            up.first().zip(down.first()).map(|(a, b)| a.0.max(b.0)),
            up.last().zip(down.last()).map(|(a, b)| a.0.min(b.0)),
        ) else {
            continue;
        };
        if !(hi > lo) {
            continue;
        }
        const STEPS: usize = 200;
        let (mut energy, mut quadrant_work) = (0.0, 0.0);
        for k in 0..STEPS {
            let (a, b) = (lo + (hi - lo) * k as f64 / STEPS as f64, lo + (hi - lo) * (k + 1) as f64 / STEPS as f64);
            let gap = |x: f64| interpolate(&up, x) - interpolate(&down, x);
            energy += 0.5 * (gap(a) + gap(b)) * (b - a);
            quadrant_work += 0.5 * (interpolate(&up, a).abs() + interpolate(&up, b).abs()) * (b - a);
        }
        energies.push(energy);
        work += quadrant_work;
        overlaps.push((lo, hi));
    }
    if energies.is_empty() {
        return None;
    }
    let total: f64 = energies.iter().sum();
    let uncertainty = TABLE_TOLERANCE * work;
    let active = total < -uncertainty;
    let range = overlaps.iter().map(|(lo, hi)| format!("{:.3}–{:.3} mrad", lo * 1e3, hi * 1e3)).collect::<Vec<_>>();
    let words = if active {
        format!(
            "the loop runs the active way: over {} the unloading branch carries more torque than the loading \
             branch (∮T dθ = {total:.4e} J, beyond the {:.0} % tolerance of {uncertainty:.1e} J), energy no passive \
             gear gives back. Likely causes: the branch labels are swapped, or the torque was read late or early \
             relative to the deflection",
            range.join(" and "),
            100.0 * TABLE_TOLERANCE
        )
    } else {
        let within =
            if total < 0.0 { format!(" (below 0, within the {uncertainty:.1e} J tolerance)") } else { String::new() };
        format!("passive: ∮T dθ = {total:.4e} J over {} of overlapping branches{within}", range.join(" and "))
    };
    Some(Passivity {
        energy_per_cycle_j: energies,
        mean_energy_j: Some(total),
        uncertainty_j: Some(uncertainty),
        active,
        passive_delay_s: None,
        words,
    })
}

/// Linear interpolation in points sorted by x, held at the ends.
fn interpolate(points: &[(f64, f64)], x: f64) -> f64 {
    match points.iter().position(|p| p.0 >= x) {
        Some(0) => points[0].1,
        Some(k) => {
            let ((x0, y0), (x1, y1)) = (points[k - 1], points[k]);
            if x1 > x0 {
                y0 + (y1 - y0) * (x - x0) / (x1 - x0)
            } else {
                y1
            }
        }
        None => points.last().map_or(0.0, |p| p.1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(rows: &[(Branch, f64, f64)]) -> LoopTable {
        LoopTable {
            branch: rows.iter().map(|r| r.0).collect(),
            torque: rows.iter().map(|r| r.1).collect(),
            deflection: rows.iter().map(|r| r.2).collect(),
        }
    }

    /// A passive spring with a loop of `opening` N·m: the torque higher while θ rises, over
    /// `cycles` periods of θ = A·sin(φ + φ0).
    fn recording(cycles: f64, phase: f64) -> Recording {
        let n = (1000.0 * cycles) as usize;
        let time: Vec<f64> = (0..=n).map(|i| i as f64 * 1e-3).collect();
        let phi = |t: f64| std::f64::consts::TAU * t + phase;
        let deflection: Vec<f64> = time.iter().map(|&t| 1e-3 * phi(t).sin()).collect();
        let torque: Vec<f64> = time.iter().map(|&t| 10.0 * phi(t).sin() + 0.5 * phi(t).cos()).collect();
        Recording { ratio: 1.0, metadata: Vec::new(), time, angles: None, deflection, torque, temperature: None }
    }

    fn turning_points(recording: &Recording) -> Vec<TurningPoint> {
        crate::prepare::reversals(&recording.deflection)
            .indices
            .iter()
            .map(|&index| TurningPoint {
                index,
                deflection: recording.deflection[index],
                is_maximum: recording.deflection[index] > 0.0,
            })
            .collect()
    }

    const NOISE: NoiseModel = NoiseModel { torque_nm: 0.01, deflection_rad: 1e-6 };

    #[test]
    fn only_closed_cycles_are_integrated_and_without_one_there_is_no_verdict() {
        // Up, down and back: one maximum and one minimum, no path returns to its extreme (from
        // the maximum to the end, ∫T dθ is energy stored and given back, not a loop's).
        let ramp = recording(1.0, 0.0);
        let open = of_recording(&ramp, &turning_points(&ramp), &NOISE);
        assert!(!open.active && open.mean_energy_j.is_none() && open.energy_per_cycle_j.is_empty(), "{open:?}");
        assert!(open.words.starts_with("no closed cycle"), "{}", open.words);
        // Two and a half periods: three maxima, two minima; the two cycles between maxima, each
        // the loop's area π·A·opening.
        let loops = recording(2.5, 0.0);
        let closed = of_recording(&loops, &turning_points(&loops), &NOISE);
        assert_eq!(closed.energy_per_cycle_j.len(), 2, "{closed:?}");
        let area = std::f64::consts::PI * 1e-3 * 0.5;
        assert!(closed.energy_per_cycle_j.iter().all(|e| (e - area).abs() < 1e-3 * area), "{closed:?}");
        assert!(!closed.active && closed.words.starts_with("passive"));
        // From a maximum: two minima, one maximum after the first: the cycle between the minima.
        let from_top = recording(1.6, std::f64::consts::FRAC_PI_2);
        let tps = turning_points(&from_top);
        assert_eq!(tps.iter().filter(|tp| !tp.is_maximum).count(), 2, "{tps:?}");
        let between_minima = of_recording(&from_top, &tps, &NOISE);
        assert_eq!(between_minima.energy_per_cycle_j.len(), 1, "{between_minima:?}");
        assert!((between_minima.energy_per_cycle_j[0] - area).abs() < 1e-3 * area, "{between_minima:?}");
    }

    #[test]
    fn a_loop_whose_unloading_branch_carries_more_torque_is_active() {
        use Branch::*;
        let passive = table(&[
            (ForwardLoading, 0.0, 0.0),
            (ForwardLoading, 10.0, 1.0),
            (ForwardUnloading, 9.0, 1.0),
            (ForwardUnloading, -1.0, 0.0),
        ]);
        let p = of_loop_table(&passive).unwrap();
        assert!(!p.active && p.mean_energy_j.is_some_and(|e| e > 0.0), "{p:?}");
        // The same points with the branch labels swapped.
        let swapped = table(&[
            (ForwardUnloading, 0.0, 0.0),
            (ForwardUnloading, 10.0, 1.0),
            (ForwardLoading, 9.0, 1.0),
            (ForwardLoading, -1.0, 0.0),
        ]);
        let a = of_loop_table(&swapped).unwrap();
        assert!(a.active && a.words.contains("swapped"), "{a:?}");
    }
}
