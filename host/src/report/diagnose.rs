//! What `diagnose` reports: the JSON document and the text for a person.
use crate::diagnose::asymmetry::{Asymmetry, AsymmetryCheck, MIN_ASYMMETRY};
use crate::diagnose::form::{ModelForm, Unexplained};
use crate::diagnose::kinks::{KinksCheck, StiffnessKinks, MIN_STEP};
use crate::diagnose::non_masing::{NonMasing, NonMasingCheck};
use crate::diagnose::passivity::Passivity;
use crate::diagnose::ratcheting::{Ratcheting, RatchetingCheck};
use crate::diagnose::{
    DiagnoseOutcome, Effect, ExtendedFit, FinalForm, Finding, Observation, Rejection, Undecided, MAX_HALF_SPREAD,
    MIN_BIC_DROP, MIN_EXPLAINED, MIN_HALF_Z,
};
use crate::prepare::{NoiseModel, OriginSource, RunOrigin};
use crate::report::params::ModelFile;
use model_core::{GearModel, Params};
use serde::Serialize;
use std::fmt::Write;

#[derive(Clone, Debug, Serialize)]
pub struct DiagnoseReport {
    pub input: String,
    pub kind: &'static str,
    pub baseline: ModelSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseModel>,
    /// The deflection's zero θ0 which the deflection was measured from: read in the recording's
    /// rest window (`source` "rest_window"), or fitted where it has none ("fitted").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub origin: Option<RunOrigin>,
    /// The torque read at rest, N·m, where the rest lasts long enough to read it (a declared
    /// rest that the motion leaves at once gives θ0 from its first sample and no torque).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rest_torque_nm: Option<f64>,
    /// Samples of a recording that does not say `# start: rest` before its motion's extremes
    /// wiped out the unknown start state between them: run through, in no fit (as `fit` reports them).
    pub start_state_samples: usize,
    pub locate: Vec<Observation>,
    /// The effects the data can reveal: searched for, and each named or refused.
    pub revealable: Vec<Effect>,
    /// The effects it cannot, and why: the data lack a column or a motion, or the named form
    /// cannot tell them from its own hysteresis.
    pub not_revealable: Vec<NotRevealable>,
    pub findings: Vec<Finding>,
    /// Torques the final model keeps whose mechanism the data cannot tell (either of two).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub undecided: Vec<Undecided>,
    /// The baseline's form is what the recording disagrees with; no effect is named then.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model_form: Option<ModelForm>,
    /// Structure left that nothing in the vocabulary explains.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unexplained: Option<Unexplained>,
    /// Whether the spring's two sides differ (a finding of form), or why it was not tested.
    pub asymmetry: AsymmetryCheck,
    /// Whether the spring's stiffness steps at some deflections (a finding of form), or why it
    /// was not tested.
    pub stiffness_kinks: KinksCheck,
    /// Whether the small loops are what the large loop implies under Masing's rule (a finding of
    /// form), or why it was not tested.
    pub non_masing: NonMasingCheck,
    /// Whether loops run over and over drift (a finding of form), or why it was not tested.
    pub ratcheting: RatchetingCheck,
    /// ∮T dθ per closed loop; `active` flags a loop that gives energy back.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub passivity: Option<Passivity>,
    pub rejected: Vec<Rejection>,
    #[serde(rename = "final")]
    pub final_model: ModelSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out: Option<HeldOut>,
    pub criteria: Criteria,
}

#[derive(Clone, Debug, Serialize)]
pub struct ModelSummary {
    /// RSS (N·m)², RMS (N·m) and the number of samples they are over: the scored ones (a
    /// recording that starts mid-motion: from its known state on).
    pub rss: f64,
    pub rms: f64,
    pub n: usize,
    /// The genetic model's parameters: the baseline's, or the final genetic model's with the
    /// effects (beside a `form` too, where the final model is the form's).
    pub params: Params<f64>,
    pub effects: Vec<Effect>,
    /// The model kind the final model is, with the torque effects beside it, where the
    /// diagnosis named that form: `rss` and `rms` are then its.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub form: Option<&'static str>,
    /// That form's model as a parameter file holds it, its θ0 the zero the diagnosis measured
    /// the deflection from, where the final model is the form alone: `predict --keep-zero` runs
    /// it to the final RMS. A parameter file holds no effect, so beside effects there is none
    /// (a backlash named on the form, left out, made the file predict 1.17 N·m where the final
    /// model left 0.13: a new user's trial); `fit --model micro-slip` gives the form's file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub form_model: Option<ModelFile>,
}

#[derive(Clone, Debug, Serialize)]
pub struct NotRevealable {
    pub effect: Effect,
    pub why: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct HeldOut {
    /// RMS residual, N·m, on the held-out samples of the baseline and of the final model, each
    /// refitted without them.
    pub rms_before: f64,
    pub rms_after: f64,
    pub samples: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct Criteria {
    pub min_bic_drop: f64,
    pub min_explained: f64,
    pub min_half_z: f64,
    pub max_half_spread: f64,
    /// The smallest asymmetry named, (k₊ − k₋) over their mean.
    pub min_asymmetry: f64,
    /// The smallest step of stiffness named, over the loop's secant stiffness.
    pub min_kink_step: f64,
}

impl ModelSummary {
    /// The summary of `fit` with `residuals`, or of the `form` with its torque effects where it
    /// is the final model, its θ0 `zero` (rad).
    fn new(fit: &ExtendedFit, residuals: &[f64], form: Option<&FinalForm>, zero: f64) -> ModelSummary {
        let rss: f64 = residuals.iter().map(|r| r * r).sum();
        ModelSummary {
            rss,
            rms: (rss / residuals.len() as f64).sqrt(),
            n: residuals.len(),
            params: fit.params,
            effects: fit.active.clone(),
            form: form.map(|f| f.kind),
            form_model: form
                .filter(|_| fit.active.is_empty())
                .map(|f| ModelFile::of(GearModel { zero, ..f.along.model })),
        }
    }
}

impl DiagnoseReport {
    /// The report for `outcome` of the file `input`.
    pub fn new(input: String, kind: &'static str, outcome: &DiagnoseOutcome) -> DiagnoseReport {
        let DiagnoseOutcome {
            observed,
            diagnosis,
            before,
            after,
            locate,
            passivity,
            origin,
            asymmetry,
            kinks,
            non_masing,
            ratcheting,
            remanent_start: _,
        } = outcome;
        // The figures count the scored samples: before the known state nothing is fitted.
        let from = observed.known_state_from;
        DiagnoseReport {
            input,
            kind,
            baseline: ModelSummary::new(&diagnosis.baseline, before.get(from..).unwrap_or(&[]), None, 0.0),
            noise: observed.noise,
            origin: *origin,
            rest_torque_nm: observed.rest_torque.map(|(torque, _)| torque),
            start_state_samples: from,
            locate: locate.clone(),
            revealable: observed
                .revealable()
                .into_iter()
                .filter(|e| !diagnosis.untellable.iter().any(|u| u.effect == *e))
                .collect(),
            not_revealable: observed
                .cannot_reveal
                .iter()
                .map(|(effect, why)| NotRevealable { effect: *effect, why: why.clone() })
                .chain(diagnosis.untellable.iter().map(|u| NotRevealable { effect: u.effect, why: u.why.to_string() }))
                .collect(),
            findings: diagnosis.findings.clone(),
            undecided: diagnosis.undecided.clone(),
            model_form: diagnosis.model_form.clone(),
            unexplained: diagnosis.unexplained.clone(),
            asymmetry: asymmetry.clone(),
            stiffness_kinks: kinks.clone(),
            non_masing: non_masing.clone(),
            ratcheting: ratcheting.clone(),
            passivity: passivity.clone(),
            rejected: diagnosis.rejected.clone(),
            final_model: ModelSummary::new(
                &diagnosis.final_fit,
                after.get(from..).unwrap_or(&[]),
                diagnosis.final_form.as_ref(),
                origin.map_or(0.0, |o| o.zero_rad),
            ),
            held_out: diagnosis.held_out_rms.map(|(rms_before, rms_after)| HeldOut {
                rms_before,
                rms_after,
                samples: observed.held_out_count(),
            }),
            criteria: Criteria {
                min_bic_drop: MIN_BIC_DROP,
                min_explained: MIN_EXPLAINED,
                min_half_z: MIN_HALF_Z,
                max_half_spread: MAX_HALF_SPREAD,
                min_asymmetry: MIN_ASYMMETRY,
                min_kink_step: MIN_STEP,
            },
        }
    }

    /// Why figures of this report may not be finite, when it can be told: the evidence tests
    /// divide by the residual's variance and by the torque noise, which a noise-free recording
    /// leaves at (nearly) zero.
    pub fn non_finite_cause(&self) -> String {
        let rms = self.baseline.rms;
        match self.noise {
            Some(noise) if !(noise.torque_nm > 0.0) => format!(
                "the torque noise estimates to {:e} N·m (a noise-free or quantised recording), so the evidence \
                 tests have no scale; diagnose a measured recording",
                noise.torque_nm
            ),
            None => "the data give no noise estimate, so the evidence tests have no scale".to_owned(),
            Some(noise) if rms < 1e-3 * noise.torque_nm => format!(
                "the baseline model fits the data exactly (RMS {rms:e} N·m, noise {:e} N·m): a noise-free \
                 recording leaves no residual to judge an effect by; diagnose a measured recording",
                noise.torque_nm
            ),
            Some(_) => "an effect's standard error came out zero, so its evidence has no scale (a noise-free, \
                        simulated recording does this); diagnose a measured recording"
                .to_owned(),
        }
    }

    /// The report printed for a person.
    pub fn human(&self) -> String {
        let report = self;
        let mut s = String::new();
        let b = &report.baseline;
        let samples = b.n + report.start_state_samples;
        let _ = writeln!(s, "{} ({}, {samples} samples)", report.input, report.kind.replace('_', " "));
        if let Some(noise) = &report.noise {
            let _ = writeln!(
                s,
                "measurement noise: torque {:.3e} N·m, deflection {:.3e} rad",
                noise.torque_nm, noise.deflection_rad
            );
        }
        if report.kind == "recording" {
            let _ = writeln!(s, "{}", origin_words(report.origin.as_ref(), report.rest_torque_nm));
        }
        if report.start_state_samples > 0 {
            let _ = writeln!(
                s,
                "{} samples before the motion's extremes wiped out the unknown start state between them (no `# start: rest`): run \
                 through, not fitted, and not in the figures below",
                report.start_state_samples
            );
        }
        let _ = writeln!(s, "baseline model: RSS {:.5} (N·m)², RMS {:.4} N·m", b.rss, b.rms);
        let _ = writeln!(s, "\nwhere the residual concentrates");
        for o in &report.locate {
            let _ = writeln!(s, "  - {}", o.words);
        }
        if let Some(p) = report.passivity.as_ref().filter(|p| p.active) {
            let _ = writeln!(s, "\nactive loop: energy no passive gear gives back");
            let _ = writeln!(s, "  {}", p.words);
        }
        if let Some(form) = &report.model_form {
            let _ = writeln!(s, "\nthe model's form is what is missing");
            let _ = writeln!(s, "  {}", form.words);
            let held = match (form.held_out_before, form.held_out_after) {
                (Some(b), Some(a)) => format!("; held-out RMS {} → {} N·m", torque_figure(b), torque_figure(a)),
                _ => String::new(),
            };
            let _ = writeln!(s, "  RSS {:.5} → {:.5} (N·m)²{held}", form.rss_before, form.rss_after);
        }
        if report.model_form.is_some() && report.findings.is_empty() {
            // The form says what is missing; the effects it withdrew are under "not accepted".
        } else if report.findings.is_empty() && !report.undecided.is_empty() {
            let _ =
                writeln!(s, "\nno effect named: the torque the model lacks is kept, its mechanism undecided (below)");
        } else if report.findings.is_empty() {
            let _ = writeln!(s, "\nno missing physics found: no effect passed the evidence tests");
        } else {
            // Beside a named form, the effects that still pass on top of it.
            let heading = if report.model_form.is_some() {
                "missing physics beside the form, most important first"
            } else {
                "missing physics, most important first"
            };
            let _ = writeln!(s, "\n{heading}");
            for (k, f) in report.findings.iter().enumerate() {
                let _ = writeln!(s, "  {}. {}: {:.4e} {} ({})", k + 1, f.effect, f.magnitude, f.unit, f.meaning);
                let _ = writeln!(s, "     where: {}", f.location);
                if f.active {
                    let _ = writeln!(
                        s,
                        "     active: a negative {} gives energy back every cycle, which no passive gear does: the \
                         measurement, not the gear (the torque channel ahead of the angles, or a sign flipped)",
                        f.meaning
                    );
                }
                let halves = f.evidence.halves.map_or(String::new(), |[a, b]| format!(", halves {a:.4e} / {b:.4e}"));
                let _ = writeln!(
                    s,
                    "     RSS {:.5} → {:.5} (N·m)²; ΔBIC {:.0}, explains {:.0} % of the residual{halves}",
                    f.rss_before,
                    f.rss_after,
                    f.evidence.delta_bic,
                    100.0 * f.evidence.explained
                );
            }
        }
        for u in &report.undecided {
            let [a, b] = u.effects;
            let _ = writeln!(s, "\nkept in the model, mechanism undecided: {a} or {b}");
            let _ = writeln!(
                s,
                "  {a} {:.4e} {} or {b} {:.4e} {}; RSS {:.5} → {:.5} (N·m)²",
                u.magnitudes[0], u.units[0], u.magnitudes[1], u.units[1], u.rss_before, u.rss_after
            );
            let _ = writeln!(s, "  {}", u.words);
        }
        if let Some(u) = &report.unexplained {
            let _ = writeln!(s, "\n{}", u.words);
        }
        if let Some(a) = report.asymmetry.named() {
            let _ = writeln!(s, "\nthe + and − sides differ in stiffness (asymmetry, a finding of form)");
            let _ = writeln!(s, "  {}", asymmetry_words(a));
            let _ = writeln!(
                s,
                "  ΔBIC {:.0}, explains {:.0} % of the symmetric spring's residual; the genetic baseline's spring is \
                 symmetric, every kind of `fit` has the free-form spring that models it",
                a.delta_bic,
                100.0 * a.explained
            );
        }
        if let Some(k) = report.stiffness_kinks.named() {
            let _ = writeln!(s, "\nthe spring's stiffness steps (stiffness_kinks, a finding of form)");
            let _ = writeln!(s, "  {}", kinks_words(k));
            let _ = writeln!(
                s,
                "  ΔBIC {:.0}, explains {:.0} % of the smooth spring's residual; the micro-slip kind of `fit` places a \
                 pair of knots around each step, the other kinds' springs smear it over a segment (the stiffness each \
                 side is not told apart from the slip elements': `--json` gives the spring's share)",
                k.delta_bic,
                100.0 * k.explained
            );
        }
        if let Some(m) = report.non_masing.named() {
            let _ = writeln!(
                s,
                "\nthe loops do not follow Masing's rule, each branch a function of the travel since its reversal \
                 (non_masing, a finding of form)"
            );
            let _ = writeln!(s, "  {}", non_masing_words(m));
            let _ = writeln!(
                s,
                "  ΔBIC {:.0}, explains {:.0} % of Masing's residual; the micro-slip kind follows the rule, the Preisach \
                 kind (`fit --model preisach`) has the cells",
                m.delta_bic,
                100.0 * m.explained
            );
        }
        if let Some(r) = report.ratcheting.named() {
            let _ = writeln!(s, "\nloops run over and over drift (ratcheting, a finding of form)");
            let _ = writeln!(s, "  {}", ratcheting_words(r));
            let sensor = if r.drift_nm_per_cycle > 0.0 {
                "the loops move away from zero torque, where a gear held at one deflection relaxes towards it: a \
                 torque sensor whose offset drifts reads so"
            } else {
                "a torque sensor whose offset drifts towards zero reads alike; held at loads of both signs, its drift \
                 would cancel"
            };
            let _ = writeln!(
                s,
                "  ΔBIC {:.0}, explains {:.0} % of the turning points' scatter; every kind of `fit` has return-point \
                 memory (a loop closes where it started), none follows the drift; {sensor}",
                r.delta_bic,
                100.0 * r.explained
            );
        }
        if let Some(p) = report.passivity.as_ref().filter(|p| !p.active) {
            let _ = writeln!(s, "\nenergy: {}", p.words);
        }
        let fm = &report.final_model;
        let effects = if fm.effects.is_empty() {
            " alone".to_string()
        } else {
            let words = |e: &Effect| match report.undecided.iter().find(|u| u.effects[0] == *e) {
                Some(u) => format!("{} (or {}: undecided)", u.effects[0], u.effects[1]),
                None => e.name().to_owned(),
            };
            format!(" + {}", fm.effects.iter().map(words).collect::<Vec<_>>().join(" + "))
        };
        let base = fm.form.map_or("baseline".to_string(), |form| format!("the {form} model"));
        let _ = writeln!(s, "\nfinal model ({base}{effects}): RSS {:.5} (N·m)², RMS {:.4} N·m", fm.rss, fm.rms);
        if let Some(h) = &report.held_out {
            let _ = writeln!(
                s,
                "held-out error ({} samples not used in the fit): RMS {} → {} N·m",
                h.samples,
                torque_figure(h.rms_before),
                torque_figure(h.rms_after)
            );
        }
        let asymmetry_rejected = match &report.asymmetry {
            AsymmetryCheck::Yes(a) => a.rejected.as_ref().map(|why| (a, why)),
            AsymmetryCheck::No { .. } => None,
        };
        let kinks_rejected = match &report.stiffness_kinks {
            KinksCheck::Yes(k) => k.rejected.as_ref().map(|why| (k, why)),
            KinksCheck::No { .. } => None,
        };
        let non_masing_rejected = match &report.non_masing {
            NonMasingCheck::Yes(m) => m.rejected.as_ref().map(|why| (m, why)),
            NonMasingCheck::No { .. } => None,
        };
        let ratcheting_rejected = match &report.ratcheting {
            RatchetingCheck::Yes(r) => r.rejected.as_ref().map(|why| (r, why)),
            RatchetingCheck::No { .. } => None,
        };
        if !report.rejected.is_empty()
            || asymmetry_rejected.is_some()
            || kinks_rejected.is_some()
            || non_masing_rejected.is_some()
            || ratcheting_rejected.is_some()
        {
            let _ = writeln!(s, "\nnot accepted");
            for r in &report.rejected {
                // The magnitude the test tried, where it has one: the reason alone may not say it.
                let tried = if r.magnitude.is_finite() && r.magnitude != 0.0 {
                    format!(" (tried at {:.4e} {})", r.magnitude, r.effect.unit())
                } else {
                    String::new()
                };
                let _ = writeln!(s, "  - {}{tried}: {}", r.effect, r.reason);
            }
            if let Some((a, why)) = asymmetry_rejected {
                let _ = writeln!(s, "  - asymmetry ({}): {why}", asymmetry_words(a));
            }
            if let Some((k, why)) = kinks_rejected {
                let found = if k.kinks.is_empty() { String::new() } else { format!(" ({})", kinks_words(k)) };
                let _ = writeln!(s, "  - stiffness_kinks{found}: {why}");
            }
            if let Some((m, why)) = non_masing_rejected {
                let _ = writeln!(s, "  - non_masing ({}): {why}", non_masing_words(m));
            }
            if let Some((r, why)) = ratcheting_rejected {
                let _ = writeln!(s, "  - ratcheting ({}): {why}", ratcheting_words(r));
            }
        }
        let asymmetry_untested = match &report.asymmetry {
            AsymmetryCheck::No { why } => Some(why),
            AsymmetryCheck::Yes(_) => None,
        };
        let kinks_untested = match &report.stiffness_kinks {
            KinksCheck::No { why } => Some(why),
            KinksCheck::Yes(_) => None,
        };
        let non_masing_untested = match &report.non_masing {
            NonMasingCheck::No { why } => Some(why),
            NonMasingCheck::Yes(_) => None,
        };
        let ratcheting_untested = match &report.ratcheting {
            RatchetingCheck::No { why } => Some(why),
            RatchetingCheck::Yes(_) => None,
        };
        if !report.not_revealable.is_empty()
            || asymmetry_untested.is_some()
            || kinks_untested.is_some()
            || non_masing_untested.is_some()
            || ratcheting_untested.is_some()
        {
            let _ = writeln!(s, "\ncannot be told from this data");
            if let Some(why) = asymmetry_untested {
                let _ = writeln!(s, "  - asymmetry: {why}");
            }
            if let Some(why) = kinks_untested {
                let _ = writeln!(s, "  - stiffness_kinks: {why}");
            }
            if let Some(why) = non_masing_untested {
                let _ = writeln!(s, "  - non_masing: {why}");
            }
            if let Some(why) = ratcheting_untested {
                let _ = writeln!(s, "  - ratcheting: {why}");
            }
            // Effects refused for one reason share one line.
            let mut shown: Vec<&str> = Vec::new();
            for r in &report.not_revealable {
                if shown.contains(&r.why.as_str()) {
                    continue;
                }
                shown.push(&r.why);
                let same: Vec<&str> =
                    report.not_revealable.iter().filter(|o| o.why == r.why).map(|o| o.effect.name()).collect();
                let _ = writeln!(s, "  - {}: {}", same.join(", "), r.why);
            }
        }
        s
    }
}

/// The spring's two sides, in words.
fn asymmetry_words(a: &Asymmetry) -> String {
    let softer = if a.magnitude < 0.0 { "+" } else { "−" };
    let parts = a.halves.map_or(String::new(), |[p, q]| {
        format!("; each part of the recording alone: {:+.1} %, {:+.1} %", 100.0 * p, 100.0 * q)
    });
    format!(
        "the {softer} side is the softer: secant stiffness k₊ = {:.0} N·m/rad to the loop's tip at +{:.3} mrad, k₋ = \
         {:.0} at −{:.3} mrad; (k₊ − k₋) over their mean {:+.1} %{parts}",
        a.plus_nm_per_rad,
        1e3 * a.extent_rad,
        a.minus_nm_per_rad,
        1e3 * a.extent_rad,
        100.0 * a.magnitude
    )
}

/// The spring's kinks, in words.
fn kinks_words(k: &StiffnessKinks) -> String {
    let mut kinks: Vec<_> = k.kinks.iter().zip(&k.torque_nm).enumerate().collect();
    kinks.sort_by(|(_, (a, _)), (_, (b, _))| a.at_rad.total_cmp(&b.at_rad));
    let each: Vec<String> = kinks
        .iter()
        .map(|(j, (kink, torque))| {
            let parts = k
                .halves
                .as_ref()
                .map_or(String::new(), |[p, q]| format!("; each part alone {:+.0}, {:+.0}", p[*j], q[*j]));
            format!(
                "at {:+.3} mrad ({torque:+.2} N·m measured there) by {:+.0} N·m/rad outwards ({:+.0} % of the \
                 loop's secant{parts})",
                1e3 * kink.at_rad,
                kink.step_nm_per_rad(),
                100.0 * kink.step_nm_per_rad() / k.secant_nm_per_rad,
            )
        })
        .collect();
    format!(
        "{} step{} of the spring's stiffness, placed to ±{:.3} mrad: {}",
        each.len(),
        if each.len() == 1 { "" } else { "s" },
        1e3 * k.resolution_rad,
        each.join("; ")
    )
}

/// A torque in N·m to four decimals, or in scientific notation from 10⁵ N·m on: a model that runs
/// away on held-out samples (the genetic kind on a run cut before its rest) gave 67 digits.
fn torque_figure(nm: f64) -> String {
    if nm.abs() < 1e5 {
        format!("{nm:.4}")
    } else {
        format!("{nm:.3e}")
    }
}

/// The loops against Masing's rule, in words.
fn non_masing_words(m: &NonMasing) -> String {
    let held_out = m.held_out_rms.map_or(String::new(), |[masing, free]| {
        format!("; held-out cycles {free:.4} N·m against Masing's {masing:.4}")
    });
    let parts = m.halves.map_or(String::new(), |[p, q]| {
        format!(
            "; each part of the recording alone: ΔBIC {:.0} and {:.0}, explained {:.1} % and {:.1} %",
            p[0],
            q[0],
            100.0 * p[1],
            100.0 * q[1]
        )
    });
    format!(
        "the free form (Preisach cells beside the slip elements) departs from Masing's by {:.4} N·m RMS and leaves \
         {:.1}× the noise{held_out}{parts}",
        m.magnitude_nm, m.free_to_noise
    )
}

/// The drift of repeated loops, in words.
fn ratcheting_words(r: &Ratcheting) -> String {
    format!(
        "the torque at the turning points of {} cycles in {} run{} of one loop drifts by {:+.3e} ± {:.1e} N·m per cycle \
         along the torque held (maxima {:+.3e}, minima {:+.3e})",
        r.cycles,
        r.runs,
        if r.runs == 1 { "" } else { "s" },
        r.drift_nm_per_cycle,
        r.drift_se,
        r.ends[0],
        r.ends[1]
    )
}

/// The recording's deflection zero, in words, and the torque read at rest where it was.
fn origin_words(origin: Option<&RunOrigin>, rest_torque: Option<f64>) -> String {
    let torque = match rest_torque {
        Some(torque) => format!("the torque there, {torque:.4} N·m, is left to the torque_offset test"),
        None => "the motion leaves rest at once, too soon to read the torque there".into(),
    };
    match origin {
        Some(origin) if origin.source == OriginSource::Fitted => format!(
            "deflection zero θ0: {:.4} ± {:.4} mrad, fitted, as `fit` places a run without a rest (where the \
             better fitting of the genetic and the micro-slip kind fits best, the encoders' zero unless another is \
             clearly better); the deflection is measured from it",
            1e3 * origin.zero_rad,
            1e3 * origin.zero_se_rad.unwrap_or(0.0),
        ),
        Some(origin) => format!(
            "deflection zero θ0: {:.4} ± {:.4} mrad, read at rest before the motion; the deflection is measured from it \
             ({torque})",
            1e3 * origin.zero_rad,
            1e3 * origin.zero_se_rad.unwrap_or(0.0),
        ),
        None => "deflection zero: no rest at the start to read it, so the encoders' zero is taken for the gear's".into(),
    }
}
