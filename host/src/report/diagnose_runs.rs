//! The report of several runs diagnosed together: each run's report, one line each in the text,
//! and what the runs show together.
use super::diagnose::DiagnoseReport;
use crate::diagnose::kinks::KinksCheck;
use crate::diagnose::non_masing::NonMasingCheck;
use crate::diagnose::rates_across::RateVerdict;
use crate::diagnose::runs::{Across, RunVerdict};
use crate::prepare::OriginSource;
use serde::Serialize;
use std::fmt::Write;

/// Every run's report, in the order given, and what they show together (JSON and text).
#[derive(Clone, Debug, Serialize)]
pub struct RunsReport {
    pub runs: Vec<DiagnoseReport>,
    pub across: Across,
}

impl RunsReport {
    /// The report printed for a person: one line per run, then the runs together.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{} runs, each diagnosed alone from its own start, then together\n", self.runs.len());
        for (k, run) in self.runs.iter().enumerate() {
            let zero = run.origin.map_or("θ0 not read (no rest)".to_string(), |o| {
                let fitted = if o.source == OriginSource::Fitted { " (fitted: no rest)" } else { "" };
                format!("θ0 {:+.4} mrad{fitted}", 1e3 * o.zero_rad)
            });
            let form = run.model_form.as_ref().map_or(String::new(), |f| format!("; form: {}", f.model));
            let mut kept: Vec<String> = run.findings.iter().map(|f| f.effect.to_string()).collect();
            kept.extend(run.undecided.iter().map(|u| format!("{} or {}", u.effects[0], u.effects[1])));
            let named = if kept.is_empty() { "no effect named".to_string() } else { kept.join(", ") };
            let held = run
                .held_out
                .as_ref()
                .map_or(String::new(), |h| format!("; held-out RMS {:.4} → {:.4} N·m", h.rms_before, h.rms_after));
            let left = run
                .unexplained
                .as_ref()
                .map_or(String::new(), |u| format!("; structure remains: {:.1}× the noise", u.rms / u.noise_rms));
            let unknown = match run.start_state_samples {
                0 => String::new(),
                count => format!(", the first {count} before its extremes not fitted"),
            };
            let samples = run.baseline.n + run.start_state_samples;
            let _ = writeln!(s, "run {}: {} ({samples} samples{unknown})", k + 1, run.input);
            let active = if run.passivity.as_ref().is_some_and(|p| p.active) {
                "; active loop: energy no passive gear gives back (see its full report)"
            } else {
                ""
            };
            let _ = writeln!(s, "  {zero}{form}; {named}{held}{left}{active}");
        }
        let across = &self.across;
        let _ = writeln!(s, "\nthe runs together");
        if let Some(zero) = &across.zero {
            let count = zero.runs.iter().filter(|z| z.is_some()).count();
            let read = if count == 1 { "1 run".to_string() } else { format!("{count} runs") };
            let words = match zero.pooled {
                Some([mean, error]) if mean.abs() > 3.0 * error => format!(
                    "the encoder's zero is off the gear's (deflection_offset), one zero in the {read} read at \
                     rest: {:+.4} ± {:.4} mrad",
                    1e3 * mean,
                    1e3 * error
                ),
                Some([mean, error]) => format!(
                    "one zero in the {read} read at rest, at the encoder's within its error: {:+.4} ± {:.4} mrad",
                    1e3 * mean,
                    1e3 * error
                ),
                None if zero.one_zero => format!("one zero in the {read} read at rest"),
                None => format!(
                    "moves between the {read} read at rest, over {:+.4} … {:+.4} mrad, beyond the error of \
                     each reading: each run is measured from its own (the remanence of the loops before it, or a \
                     zero that moves), as `fit` places each run",
                    1e3 * zero.range[0],
                    1e3 * zero.range[1]
                ),
            };
            let _ = writeln!(s, "  - deflection zero: {words}");
        } else {
            let _ = writeln!(
                s,
                "  - deflection zero: not read: no run starts at rest, so each is measured from the encoders' zero \
                 (or from a zero fitted where its motion is centred off it); record the gear standing still before the \
                 motion to read it"
            );
        }
        let _ = writeln!(s, "  - asymmetry: {}", across.asymmetry.words);
        let tested = self.runs.iter().filter(|run| matches!(run.stiffness_kinks, KinksCheck::Yes(_))).count();
        let kinked: Vec<String> = self
            .runs
            .iter()
            .enumerate()
            .filter_map(|(k, run)| {
                let found = run.stiffness_kinks.named()?;
                let mut kinks: Vec<_> = found.kinks.iter().collect();
                kinks.sort_by(|a, b| a.at_rad.total_cmp(&b.at_rad));
                let each: Vec<String> = kinks
                    .iter()
                    .map(|kink| format!("{:+.3} mrad by {:+.0}", 1e3 * kink.at_rad, kink.step_nm_per_rad()))
                    .collect();
                Some(format!("run {}: {} N·m/rad", k + 1, each.join(", ")))
            })
            .collect();
        let kinks = match (kinked.is_empty(), tested) {
            (_, 0) => "not tested on any run (see each run's report)".to_string(),
            (true, _) => format!("named in none of the {tested} runs tested"),
            (false, _) => format!("named in {} of the {tested} runs tested ({})", kinked.len(), kinked.join("; ")),
        };
        let _ = writeln!(s, "  - stiffness_kinks: {kinks}");
        let masing = match &across.non_masing {
            NonMasingCheck::No { why } => format!("not tested: {why}"),
            NonMasingCheck::Yes(found) => {
                let held = found.held_out_rms.map_or(String::new(), |[m, f]| {
                    format!("; the runs held out, each fitted on the others: {m:.4} (Masing's) and {f:.4} N·m (free)")
                });
                let started = match found.remanent_starts {
                    0 => String::new(),
                    n => format!(
                        "; both forms estimate the start state of the {n} run{} that start{} at a standstill \
                         found in the data (a remanence the motion before may have left)",
                        if n == 1 { "" } else { "s" },
                        if n == 1 { "s" } else { "" }
                    ),
                };
                let figures = format!(
                    "the free form misses Masing's by {:.4} N·m RMS, ΔBIC {:.0}, explains {:.2} % of Masing's \
                     residual, leaves {:.1}× the noise{held}{started}",
                    found.magnitude_nm,
                    found.delta_bic,
                    100.0 * found.explained,
                    found.free_to_noise
                );
                match &found.rejected {
                    None => format!("the loops of the runs do not follow Masing's rule (named): {figures}"),
                    Some(why) => format!("not named: {why} ({figures})"),
                }
            }
        };
        let _ = writeln!(s, "  - non_masing: {masing}");
        if let Some(rate) = &across.rate {
            let hz: Vec<String> = rate
                .frequencies
                .iter()
                .map(|f| f.map_or("?".to_string(), |w| format!("{:.3}", w / std::f64::consts::TAU)))
                .collect();
            let at = format!("the runs at {} Hz", hz.join(", "));
            let words = match &rate.verdict {
                RateVerdict::Named { effect, magnitude, error, delta_bic, explained, slow_fast: [slow, fast] } => {
                    format!(
                        "{effect} named across {at}: {magnitude:.4e} ± {error:.1e} {unit} (ΔBIC {delta_bic:.0}, \
                         explains {:.0} % of the rate-independent form's residual; fitted on the slower runs alone \
                         {slow:.4e} and on the faster alone {fast:.4e}, which agree: at one rate the form takes part \
                         of the opening as its own, so these read low)",
                        100.0 * explained,
                        unit = effect.unit()
                    )
                }
                RateVerdict::Undecided { effects, magnitudes, .. } => format!(
                    "{at} open their loops with the rate, but {} ({:.4e} {}) and {} ({:.4e} {}) fit alike: the \
                     mechanism cannot be told",
                    effects[0],
                    magnitudes[0],
                    effects[0].unit(),
                    effects[1],
                    magnitudes[1],
                    effects[1].unit()
                ),
                RateVerdict::Refused { effect, magnitude, why } => {
                    format!("none named across {at}: the best, {effect} ({magnitude:.4e} {}), {why}", effect.unit())
                }
                RateVerdict::Untested { why } => format!("not tested: {why}"),
            };
            let _ = writeln!(s, "  - rate effects: {words}");
        }
        for effect in &across.effects {
            let each: Vec<String> = effect
                .runs
                .iter()
                .enumerate()
                .map(|(k, v)| {
                    let what = match *v {
                        RunVerdict::Named { magnitude, error: Some(error) } => {
                            format!("named {magnitude:.4e} ± {error:.1e}")
                        }
                        RunVerdict::Named { magnitude, error: None } => format!("named {magnitude:.4e}"),
                        RunVerdict::Undecided { magnitude } => format!("either of two, {magnitude:.4e}"),
                        RunVerdict::Refused { magnitude, .. } => format!("refused ({magnitude:.4e})"),
                        RunVerdict::CannotTell => "cannot tell".to_string(),
                    };
                    format!("run {}: {what}", k + 1)
                })
                .collect();
            let refused = effect.runs.iter().filter(|v| matches!(v, RunVerdict::Refused { .. })).count();
            let of = effect.runs.len();
            let others = if refused > 0 { format!(", refused in {refused}") } else { String::new() };
            let verdict = match (effect.named_in, effect.pooled) {
                (0, _) => format!("kept as either of two only{others}"),
                (1, _) => format!("named in 1 of {of} runs{others}"),
                (n, Some([mean, error])) => format!(
                    "named in {n} of {of} runs{others}; the {n} agree: {mean:.4e} ± {error:.1e} {}",
                    effect.unit
                ),
                (n, None) if effect.agree => format!("named in {n} of {of} runs{others}; the {n} agree"),
                (n, None) => format!("named in {n} of {of} runs{others}; the {n} disagree on its magnitude"),
            };
            // The unit once: after the pooled figure, or before the runs' figures without one.
            let pooled_shown = effect.named_in > 1 && effect.pooled.is_some();
            let unit = if pooled_shown { String::new() } else { format!("{}; ", effect.unit) };
            let _ = writeln!(s, "  - {}: {verdict} ({unit}{})", effect.effect, each.join(", "));
        }
        let _ = writeln!(s, "\neach run's full report: `swg-host diagnose RUN`, or `--json` (its `runs`)");
        s
    }
}
