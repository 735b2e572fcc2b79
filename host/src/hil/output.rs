//! What `swg-host hil` hands on: the JSON, the text table, the pictures.
use super::lockstep::{HilReport, HilRun};
use super::scenario::{Scenario, HOLD_FRACTION, SETTLING_S};
use crate::report::finite::{to_json, NotFinite};
use crate::report::plot::{control_svg, ControlSeries, PlotError};
use serde::Serialize;
use std::fmt::Write as _;

#[derive(Serialize)]
struct RunJson<'a> {
    scenario: &'a str,
    physics: &'a str,
    mode: &'a str,
    /// Absent when the run diverged.
    rms_nm: Option<f64>,
    max_nm: Option<f64>,
    /// Absent for a scenario without a constant reference, or a run that diverged.
    limit_cycle_nm: Option<f64>,
    diverged: bool,
    /// Ticks where the firmware ran a fallback mode.
    fallback_ticks: usize,
    /// Wall time of the run's lockstep loop per simulated second.
    wall_s_per_simulated_s: f64,
}

#[derive(Serialize)]
struct GainsJson {
    kp: f64,
    ki_per_s: f64,
    damping_nm_s_per_rad: f64,
    torsion_damping_nm_s_per_rad: f64,
    integral_deadband_nm: f64,
    command_limit_nm: f64,
}

#[derive(Serialize)]
struct ReportJson<'a> {
    runs: Vec<RunJson<'a>>,
    seconds: f64,
    rate_hz: f64,
    settling_s: f64,
    /// The limit cycle is measured on this last fraction of each constant-reference window.
    hold_fraction: f64,
    linear_stiffness_nm_per_rad: f64,
    two_counts_nm: f64,
    gains: GainsJson,
    wall_s_per_simulated_s: f64,
}

impl HilReport {
    /// `{"runs": [{"scenario", "physics", "mode", "rms_nm", "max_nm", "limit_cycle_nm", …}], …}`.
    pub fn to_json(&self) -> Result<String, NotFinite> {
        let runs = self
            .runs
            .iter()
            .map(|run| RunJson {
                scenario: run.scenario.name(),
                physics: &run.physics,
                mode: run.mode.as_str(),
                rms_nm: run.score.map(|s| s.rms_nm),
                max_nm: run.score.map(|s| s.max_nm),
                limit_cycle_nm: run.score.and_then(|s| s.limit_cycle_nm),
                diverged: run.score.is_none(),
                fallback_ticks: run.fallbacks,
                wall_s_per_simulated_s: run.wall.as_secs_f64() / (run.ticks.len().max(1) as f64 / self.rate_hz),
            })
            .collect();
        let report = ReportJson {
            runs,
            seconds: self.seconds,
            rate_hz: self.rate_hz,
            settling_s: SETTLING_S,
            hold_fraction: HOLD_FRACTION,
            linear_stiffness_nm_per_rad: self.stiffness,
            two_counts_nm: self.two_counts_nm(),
            gains: GainsJson {
                kp: self.gains.kp,
                ki_per_s: self.gains.ki,
                damping_nm_s_per_rad: self.gains.damping,
                torsion_damping_nm_s_per_rad: self.gains.torsion_damping,
                integral_deadband_nm: self.integral_deadband_nm,
                command_limit_nm: self.gains.command_limit,
            },
            wall_s_per_simulated_s: self.wall_per_simulated_second(),
        };
        to_json("hil report", &report)
    }

    /// The table people read.
    pub fn human(&self) -> String {
        let mut text = String::new();
        let _ = writeln!(
            text,
            "{} s per run at {} Hz; errors of the true torque against the reference from {SETTLING_S} s on; \
             limit cycle = peak-to-peak torque over the last {:.0} % of each window of constant reference",
            self.seconds,
            self.rate_hz,
            100.0 * HOLD_FRACTION
        );
        let _ = writeln!(
            text,
            "gains: kp {} N·m/N·m, ki {} N·m/(N·m·s) (at rest within {:.3} N·m), damping {} and torsion damping {} N·m·s/rad (motor side), |u| ≤ {} N·m; linear stiffness {:.0} N·m/rad; 2 encoder counts = {:.3} N·m",
            self.gains.kp,
            self.gains.ki,
            self.integral_deadband_nm,
            self.gains.damping,
            self.gains.torsion_damping,
            self.gains.command_limit,
            self.stiffness,
            self.two_counts_nm()
        );
        let _ = writeln!(
            text,
            "{:<13} {:<12} {:<10} {:>9} {:>9} {:>16}",
            "scenario", "physics", "mode", "RMS N·m", "max N·m", "limit cycle N·m"
        );
        for run in &self.runs {
            let _ = writeln!(text, "{}", row(run));
        }
        let _ = write!(text, "lockstep: {:.3} s of wall time per simulated second", self.wall_per_simulated_second());
        text
    }

    /// One picture per scenario and physics: `hil-SCENARIO-PHYSICS.svg` and its SVG.
    pub fn pictures(&self) -> Result<Vec<(String, String)>, PlotError> {
        let mut pictures = Vec::new();
        let mut seen: Vec<(Scenario, &str)> = Vec::new();
        for run in &self.runs {
            if seen.contains(&(run.scenario, run.physics.as_str())) {
                continue;
            }
            seen.push((run.scenario, run.physics.as_str()));
            let runs: Vec<&HilRun> =
                self.runs.iter().filter(|r| r.scenario == run.scenario && r.physics == run.physics).collect();
            // Per run: time, error, deflection, torque.
            type Columns = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);
            let columns: Vec<Columns> = runs
                .iter()
                .map(|r| {
                    (
                        r.ticks.iter().map(|t| t.time).collect(),
                        r.ticks.iter().map(|t| t.torque - t.reference).collect(),
                        r.ticks.iter().map(|t| t.deflection).collect(),
                        r.ticks.iter().map(|t| t.torque).collect(),
                    )
                })
                .collect();
            let series: Vec<ControlSeries> = runs
                .iter()
                .zip(&columns)
                .map(|(r, (time, error, deflection, torque))| ControlSeries {
                    label: r.mode.as_str(),
                    time,
                    error,
                    deflection,
                    torque,
                })
                .collect();
            let title = format!("{} on a {} gear: torque error per mode", run.scenario.name(), run.physics);
            let file = picture_name(run.scenario, &run.physics);
            pictures.push((file, control_svg(&title, &series)?));
        }
        Ok(pictures)
    }
}

fn row(run: &HilRun) -> String {
    let (rms, max, cycle) = match run.score {
        Some(score) => (
            format!("{:.3}", score.rms_nm),
            format!("{:.3}", score.max_nm),
            score.limit_cycle_nm.map_or("—".to_owned(), |c| format!("{c:.3}")),
        ),
        None => ("diverged".to_owned(), "—".to_owned(), "—".to_owned()),
    };
    format!(
        "{:<13} {:<12} {:<10} {:>9} {:>9} {:>16}",
        run.scenario.name(),
        run.physics,
        run.mode.as_str(),
        rms,
        max,
        cycle
    )
}

/// The picture of `scenario` on `physics`: `hil-SCENARIO-PHYSICS.svg`, the physics' name with
/// letters, digits and `-` only.
pub fn picture_name(scenario: Scenario, physics: &str) -> String {
    let physics: String =
        physics.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    format!("hil-{}-{physics}.svg", scenario.name())
}
