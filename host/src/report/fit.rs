//! What `fit` reports: the JSON document (also the parameter file) and the human summary.
use crate::fit::baselines::{BranchLine, ThreeSegment};
use crate::fit::{Fit, Identified, MotionFit, RunOutcome, SearchSummary};
use crate::prepare::{NoiseModel, OriginSource, RunOrigin};
use model_core::preisach::{self, Preisach};
use model_core::{GearModel, Hysteresis, ParamName, MODEL_VERSION};
use serde::Serialize;
use std::fmt::Write;

#[derive(Clone, Debug, Serialize)]
pub struct FitReport {
    pub model: &'static str,
    pub model_version: u16,
    pub input: InputSummary,
    /// Each recording fitted, in the order given.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub runs: Vec<RunReport>,
    /// The kind's parameters by name (canonical genetic ones have ω = 1).
    #[serde(serialize_with = "GearModel::serialize_params")]
    pub params: GearModel<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identifiable: Option<IdentifiableReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub convention: Option<&'static str>,
    /// Unweighted residual sum of squares over the samples fitted, (N·m)².
    pub rss: f64,
    /// Unweighted RMS residual over the samples fitted, N·m.
    pub rms: f64,
    /// The samples fitted (of recordings: every scored sample).
    pub n: usize,
    /// Noise the residuals were weighted by; absent for a plain least-squares fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseModel>,
    pub baselines: Vec<BaselineReport>,
    /// Parameter sets given with `--compare`, evaluated on the same data.
    pub compared: Vec<ComparedReport>,
    /// How the stateful models found a recording's reversals: `offline`, over the whole
    /// recording (recordings).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reversals: Option<&'static str>,
    /// The samples held out of the fits that chose the kind (`--model auto`), how they were
    /// chosen, and the chosen kind's error on them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out: Option<HeldOutReport>,
    /// Every model kind fitted to the recordings: with `auto`, without the held-out samples and
    /// judged on them (the held-out table); the chosen kind is then refitted on every sample.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub candidates: Vec<CandidateReport>,
    /// Kinds `auto` could not fit without the held-out samples, with why: not judged.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_judged: Vec<NotJudgedReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub search: Option<SearchSummary>,
}

/// A kind `auto` did not judge.
#[derive(Clone, Debug, Serialize)]
pub struct NotJudgedReport {
    pub model: &'static str,
    /// Why its fit without the held-out samples failed.
    pub why: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct HeldOutReport {
    /// The rule, in words.
    pub rule: String,
    pub samples: usize,
    /// RMS residual on them of the chosen kind fitted without them (pooled over the folds),
    /// N·m.
    pub rms: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct CandidateReport {
    pub model: &'static str,
    /// Parameters the kind's fit identifies.
    pub parameters: usize,
    /// The samples it was fitted to (with `auto`: the mean over its fits, one per fold).
    pub n: usize,
    /// Unweighted RSS and RMS on the samples it was fitted to (with `auto`: the RSS the mean
    /// over the folds, the RMS pooled over them).
    pub rss: f64,
    pub rms: f64,
    /// RMS on the held-out samples, N·m.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_rms: Option<f64>,
    /// The θ0 this kind fitted, rad (with `auto`: on its first fold), where a run's is fitted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fitted_zero_rad: Option<f64>,
    pub chosen: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct InputSummary {
    /// The input's path (several recordings: their paths, comma-separated).
    pub path: String,
    pub kind: &'static str,
    /// Turning points found (over every recording).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub turning_points: Option<usize>,
}

/// One recording of a fit.
#[derive(Clone, Debug, Serialize)]
pub struct RunReport {
    pub path: String,
    pub samples: usize,
    pub turning_points: usize,
    /// Samples before the motion had visited both its extremes in a recording that does not say
    /// it starts at rest: run through from rest, neither fitted nor scored.
    pub start_state_samples: usize,
    /// The fold (1-based) of `auto`'s fits that held this run out whole (it is fitted in the
    /// others), when whole runs were held out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_fold: Option<usize>,
    /// Its samples held out of `auto`'s fits (a run's interleaved cycles, or all of a run held
    /// out).
    pub held_out_samples: usize,
    /// Its θ0 and torque offset, and how they were found.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub origin: Option<RunOrigin>,
}

impl RunReport {
    /// The report of `run`, read from `path`.
    pub fn new(path: String, run: &RunOutcome) -> RunReport {
        RunReport {
            path,
            samples: run.samples,
            turning_points: run.offline.reversals.indices.len(),
            start_state_samples: run.offline.unscored(),
            held_out_fold: run.held_out_fold.map(|fold| fold + 1),
            held_out_samples: run.held_out_samples,
            origin: None,
        }
    }
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct IdentifiableReport {
    /// h = A·α/(ω(1 + r²)), N·m.
    pub h: f64,
    /// r = β/ω.
    pub r: f64,
    /// The A that h refers to, rad.
    pub amplitude_rad: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct BaselineReport {
    pub name: &'static str,
    pub params: serde_json::Value,
    pub rss: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct ComparedReport {
    pub path: String,
    pub model: &'static str,
    #[serde(serialize_with = "GearModel::serialize_params")]
    pub params: GearModel<f64>,
    pub rss: f64,
}

/// How a genetic model fitted to a motion is written.
pub const MEMORY_CONVENTION: &str = "genetic model with Madelung's rules: every branch between two turning points is the paper's loop of the branch's half-width w with h = w*alpha/(omega*(1 + r^2)); params are the point with omega = 1";

pub const CONVENTION: &str = "only h and r are identifiable: (s*alpha, s*beta, s*omega) gives the same torque for any s != 0; params are the point with omega = 1";

impl FitReport {
    /// Where the kinds tried fitted θ0 apart: "; the kinds tried place it over a … b mrad (each
    /// below)", beside the chosen kind's own uncertainty, which is its misfit profile alone.
    fn kinds_zero_spread(&self) -> String {
        let zeros: Vec<f64> = self.candidates.iter().filter_map(|c| c.fitted_zero_rad).collect();
        let (lo, hi) = zeros.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &z| (lo.min(z), hi.max(z)));
        if zeros.len() < 2 || hi <= lo {
            return String::new();
        }
        format!("; the {} kinds tried place it over {:.4} … {:.4} mrad (each below)", zeros.len(), lo * 1e3, hi * 1e3)
    }

    pub fn new(
        input: InputSummary,
        runs: Vec<RunReport>,
        identified: &Identified,
        lines: Vec<BranchLine>,
        three_segment: Option<ThreeSegment>,
        compared: Vec<ComparedReport>,
    ) -> FitReport {
        let mut baselines = vec![BaselineReport {
            name: "line_per_branch",
            rss: lines.iter().map(|l| l.rss).sum(),
            params: serde_json::json!(lines),
        }];
        if let Some(curve) = three_segment {
            baselines.push(BaselineReport { name: "three_segment", rss: curve.rss, params: serde_json::json!(curve) });
        }
        match identified {
            Identified::Loop(fit) => FitReport { runs, ..FitReport::of_loop(input, fit, baselines, compared) },
            Identified::Motion(outcome) => {
                let runs = runs
                    .into_iter()
                    .zip(outcome.origins.iter().map(Some).chain(std::iter::repeat(None)))
                    .map(|(run, origin)| RunReport { origin: origin.copied(), ..run })
                    .collect();
                let chosen = &outcome.chosen;
                let model = chosen.model;
                let identifiable = model.identifiable(outcome.reference_amplitude).map(|id| IdentifiableReport {
                    h: id.h,
                    r: id.r,
                    amplitude_rad: outcome.reference_amplitude,
                });
                let candidate = |(fit, zero): (&MotionFit, &Option<f64>)| CandidateReport {
                    model: fit.model.kind().name(),
                    parameters: fit.parameters,
                    n: fit.n,
                    rss: fit.rss,
                    rms: fit.rms,
                    held_out_rms: fit.held_out_rms,
                    fitted_zero_rad: *zero,
                    chosen: fit.model.kind() == model.kind(),
                };
                let held_out =
                    outcome.held_out_rule.as_ref().zip(outcome.chosen_candidate()).and_then(|(rule, fit)| {
                        Some(HeldOutReport {
                            rule: rule.describe(),
                            samples: fit.held_out_samples,
                            rms: fit.held_out_rms?,
                        })
                    });
                FitReport {
                    model: model.kind().name(),
                    model_version: MODEL_VERSION,
                    input,
                    runs,
                    params: model,
                    identifiable,
                    // Where only part of the parameters is identifiable, the point written.
                    convention: identifiable.is_some().then_some(MEMORY_CONVENTION),
                    rss: chosen.rss,
                    rms: chosen.rms,
                    n: chosen.n,
                    noise: outcome.noise,
                    baselines,
                    compared,
                    reversals: Some("offline"),
                    held_out,
                    candidates: outcome.candidates.iter().zip(&outcome.candidate_zeros).map(candidate).collect(),
                    not_judged: outcome
                        .not_judged
                        .iter()
                        .map(|(kind, why)| NotJudgedReport { model: kind.name(), why: why.to_string() })
                        .collect(),
                    search: None,
                }
            }
        }
    }

    fn of_loop(input: InputSummary, fit: &Fit, baselines: Vec<BaselineReport>, compared: Vec<ComparedReport>) -> Self {
        FitReport {
            model: model_core::MODEL_NAME,
            model_version: MODEL_VERSION,
            input,
            params: GearModel::paper(fit.params),
            identifiable: Some(IdentifiableReport {
                h: fit.identifiable.h,
                r: fit.identifiable.r,
                amplitude_rad: fit.reference_amplitude,
            }),
            convention: Some(CONVENTION),
            rss: fit.rss,
            rms: fit.rms,
            n: fit.n,
            noise: fit.noise,
            baselines,
            compared,
            runs: Vec::new(),
            reversals: None,
            held_out: None,
            candidates: Vec::new(),
            not_judged: Vec::new(),
            search: Some(fit.search.clone()),
        }
    }

    /// The summary printed for a person.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let samples = if self.runs.is_empty() { self.n } else { self.runs.iter().map(|r| r.samples).sum() };
        let _ = write!(s, "{} ({}, {samples} samples", self.input.path, self.input.kind.replace('_', " "));
        if let Some(tp) = self.input.turning_points {
            let _ = write!(s, ", {tp} turning points");
        }
        let _ = writeln!(s, ")");
        let _ = writeln!(s, "model {} v{}: {}", self.model, self.model_version, self.params.kind().equation());
        write_parameters(&mut s, &self.params);
        match (&self.identifiable, self.reversals) {
            (Some(id), None) => {
                let _ = writeln!(
                    s,
                    "  hysteresis, identifiable: h = {:.5} N·m, r = β/ω = {:.5}  (at A = {:.4} mrad); any (sα, sβ, sω) \
                     fits the same, the parameters are the point with ω = 1",
                    id.h,
                    id.r,
                    id.amplitude_rad * 1e3
                );
            }
            (Some(id), Some(_)) => {
                let _ = writeln!(
                    s,
                    "  on a loop of A = {:.4} mrad (half the range): h = {:.5} N·m, r = β/ω = {:.5}",
                    id.amplitude_rad * 1e3,
                    id.h,
                    id.r
                );
            }
            (None, _) => {}
        }
        if let Some(noise) = &self.noise {
            let _ = writeln!(
                s,
                "  residuals weighted by total noise: torque {:.3e} N·m, deflection {:.3e} rad",
                noise.torque_nm, noise.deflection_rad
            );
        }
        if self.reversals.is_some() {
            let _ = writeln!(
                s,
                "  run from rest along each recording, following the turning points found over the whole recording"
            );
        }
        if !self.runs.is_empty() {
            let _ = writeln!(s, "runs ({} sharing one parameter set)", self.runs.len());
            for run in &self.runs {
                let held = match (run.held_out_fold, run.held_out_samples) {
                    (Some(fold), _) => format!("held out whole in fold {fold}, fitted in the others"),
                    (None, 0) => "fitted".to_string(),
                    (None, held) => format!("fitted, {held} samples of cycles held out"),
                };
                let _ = writeln!(
                    s,
                    "  {}: {} samples, {} turning points, {held}",
                    run.path, run.samples, run.turning_points
                );
                if let Some(origin) = &run.origin {
                    let se = origin.zero_se_rad.map_or(String::new(), |se| format!(" ± {:.4}", se * 1e3));
                    let _ = match origin.source {
                        OriginSource::RestWindow => writeln!(
                            s,
                            "    θ0 {:.4}{se} mrad and torque offset {:.4} N·m, read at rest at its start",
                            origin.zero_rad * 1e3,
                            origin.torque_offset_nm
                        ),
                        OriginSource::Fitted => writeln!(
                            s,
                            "    θ0 {:.4}{se} mrad fitted (where the spring's torque is 0; no rest at its start), torque \
                             offset taken as 0{}",
                            origin.zero_rad * 1e3,
                            self.kinds_zero_spread()
                        ),
                    };
                }
                if run.start_state_samples > 0 {
                    let _ = writeln!(
                        s,
                        "    {} samples before the motion's extremes wiped out the unknown start state between them (no `# start: \
                         rest`): run through, not fitted or scored",
                        run.start_state_samples
                    );
                }
            }
        }
        if let Some(held) = &self.held_out {
            let _ = writeln!(
                s,
                "model kinds tried, each fitted without the held-out samples and judged on them ({} in all; {}; samples \
                 fitted: the mean over the folds); the chosen kind is then refitted on every sample",
                held.samples, held.rule
            );
        } else if !self.candidates.is_empty() {
            let _ = writeln!(s, "model kind named: fitted on every sample");
        }
        if !self.candidates.is_empty() {
            // Each kind's own θ0 where it is fitted: where the data do not fix the zero, the
            // kinds place it apart, and the chosen one's uncertainty (its misfit profile) does
            // not show that.
            let zeros = self.candidates.iter().any(|c| c.fitted_zero_rad.is_some());
            let zero_head = if zeros { format!(" {:>14}", "θ0 mrad") } else { String::new() };
            let _ = writeln!(
                s,
                "  {:<20} {:>10} {:>12} {:>14} {:>14}{zero_head}",
                "model", "parameters", "samples", "training RMS", "held-out RMS"
            );
            for c in &self.candidates {
                let held_out = c.held_out_rms.map_or("—".to_string(), |r| format!("{r:.4}"));
                let zero = match (zeros, c.fitted_zero_rad) {
                    (false, _) => String::new(),
                    (true, Some(zero)) => format!(" {:>14.4}", zero * 1e3),
                    (true, None) => format!(" {:>14}", "—"),
                };
                let mark = if c.chosen { "  ← chosen" } else { "" };
                let _ = writeln!(
                    s,
                    "  {:<20} {:>10} {:>12} {:>14.4} {:>14}{zero}{mark}",
                    c.model, c.parameters, c.n, c.rms, held_out
                );
            }
            for n in &self.not_judged {
                let _ =
                    writeln!(s, "  {:<20} not judged: its fit without the held-out samples failed: {}", n.model, n.why);
            }
        }
        let _ = writeln!(s, "fit quality (unweighted torque residuals)");
        let _ = writeln!(s, "  {:<34} {:>12} {:>10}", "model", "RSS (N·m)²", "RMS N·m");
        let rms = |rss: f64| (rss / self.n as f64).sqrt();
        let this = format!("{} (this fit)", self.params.kind().label());
        let _ = writeln!(s, "  {:<34} {:>12.5} {:>10.4}", this, self.rss, self.rms);
        for b in &self.baselines {
            let name = match b.name {
                "line_per_branch" => "one straight line per branch",
                "three_segment" => "catalogue three-segment curve",
                other => other,
            };
            let _ = writeln!(s, "  {:<34} {:>12.5} {:>10.4}", name, b.rss, rms(b.rss));
        }
        for c in &self.compared {
            let _ = writeln!(s, "  {:<34} {:>12.5} {:>10.4}", c.path, c.rss, rms(c.rss));
        }
        s
    }
}

/// `model`'s parameters with their units: θ0, the spring (its range and a table of its knots),
/// then the hysteresis (the micro-slip elements as a table).
fn write_parameters(s: &mut String, model: &GearModel<f64>) {
    let spring = &model.spring;
    let _ = writeln!(s, "  θ0        = {:>12.5e} rad (the deflection's zero; per run below)", model.zero);
    let [lo, hi] = spring.range;
    let _ = writeln!(
        s,
        "  spring over x = θ − θ0 in [{:.4}, {:.4}] mrad; beyond, the line of its stiffness at the edge",
        lo * 1e3,
        hi * 1e3
    );
    if [spring.c1, spring.c2, spring.c3].iter().any(|c| *c != 0.0) {
        let _ = writeln!(
            s,
            "    c1 = {:.5e} N·m/rad, c2 = {:.5e} N·m/rad³, c3 = {:.5e} N·m/rad⁵",
            spring.c1, spring.c2, spring.c3
        );
    }
    let knots = spring.knots();
    if !knots.is_empty() {
        let row = |f: &dyn Fn(&model_core::Knot<f64>) -> String| knots.iter().map(f).collect::<Vec<_>>().join(" ");
        let _ = writeln!(s, "    knot x, mrad       {}", row(&|k| format!("{:>7.3}", k.x * 1e3)));
        let _ = writeln!(s, "    stiffness, N·m/rad {}", row(&|k| format!("{:>7}", Compact(k.stiffness))));
    }
    let elements = model.slip_elements();
    if !elements.is_empty() {
        let row =
            |f: &dyn Fn(&model_core::SlipElement<f64>) -> String| elements.iter().map(f).collect::<Vec<_>>().join(" ");
        let total: f64 = elements.iter().map(|e| e.stiffness).sum();
        let _ = writeln!(s, "  {} slip elements, Σ stiffness {total:.5e} N·m/rad", elements.len());
        let _ = writeln!(s, "    slip, mrad         {}", row(&|e| format!("{:>7.4}", e.slip * 1e3)));
        let _ = writeln!(s, "    stiffness, N·m/rad {}", row(&|e| format!("{:>7}", Compact(e.stiffness))));
    }
    if let Hysteresis::Preisach(density) = &model.hysteresis {
        write_density(s, density);
    }
    let mut lines: Vec<(ParamName, f64)> = Vec::new();
    model.map(|name, value| {
        let spring_part = matches!(
            name,
            ParamName::Zero
                | ParamName::C1
                | ParamName::C2
                | ParamName::C3
                | ParamName::Knot(_)
                | ParamName::KnotStiffness(_)
                | ParamName::RangeMin
                | ParamName::RangeMax
                | ParamName::Slip(_)
                | ParamName::SlipStiffness(_)
                | ParamName::PreisachWeight(_)
        );
        if !spring_part {
            lines.push((name, value));
        }
        value
    });
    for (name, value) in lines {
        // The file's name `stiffness` is the hysteresis' k_h, beside the spring's stiffnesses.
        let meaning = match name {
            ParamName::HysteresisStiffness => " (k_h)",
            _ => "",
        };
        let _ = writeln!(s, "  {:<9} = {value:>12.5e} {}{meaning}", name.as_str(), name.unit());
    }
    if let Hysteresis::BoucWen(term) = &model.hysteresis {
        if term.stiffness == 0.0 {
            let _ = writeln!(
                s,
                "  k_h fitted to 0: this recording shows no Bouc–Wen hysteresis, the model is its spring alone \
                 (A, β, γ and n have no effect)"
            );
        }
    }
}

/// The Preisach density as a triangle: a row per interval of the up threshold α, a column per
/// interval of the down threshold β ≤ α, each cell's weight in N·m (what the torque loses when
/// its relays switch up), blank where no relay lies.
fn write_density(s: &mut String, density: &Preisach<f64>) {
    let h = 2.0 * density.reach / preisach::INTERVALS as f64;
    let edge = |k: usize| (-density.reach + k as f64 * h) * 1e3;
    let _ = writeln!(
        s,
        "  relays over thresholds in [{:.4}, {:.4}] mrad, {} intervals of {:.4} mrad; Σ weight {:.5e} N·m",
        -density.reach * 1e3,
        density.reach * 1e3,
        preisach::INTERVALS,
        h * 1e3,
        density.total()
    );
    let _ = writeln!(s, "    weight, N·m by α (rows) and β (columns) interval, mrad");
    let header: Vec<String> = (0..preisach::INTERVALS).map(|j| format!("{:>7.3}", edge(j))).collect();
    let _ = writeln!(s, "    {:>8} {}", "α \\ β", header.join(" "));
    for i in (0..preisach::INTERVALS).rev() {
        let row: Vec<String> = (0..=i).map(|j| format!("{:>7.4}", density.weights[preisach::cell(i, j)])).collect();
        let _ = writeln!(s, "    {:>8.3} {}", edge(i), row.join(" "));
    }
}

/// A stiffness in 7 columns: 4 significant digits, with k/M suffixes.
struct Compact(f64);

impl std::fmt::Display for Compact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = self.0;
        let text = match v.abs() {
            a if a >= 1e6 => format!("{:.3}M", v / 1e6),
            a if a >= 1e4 => format!("{:.2}k", v / 1e3),
            a if a >= 1e3 => format!("{:.3}k", v / 1e3),
            _ => format!("{v:.1}"),
        };
        f.pad(&text)
    }
}
