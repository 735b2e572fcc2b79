//! What `fit` reports: the JSON document (also the parameter file) and the human summary.
use crate::fit::baselines::{BranchLine, ThreeSegment};
use crate::fit::{Fit, SearchSummary};
use crate::prepare::NoiseModel;
use model_core::{Params, MODEL_NAME, MODEL_VERSION};
use serde::Serialize;
use std::fmt::Write;

#[derive(Clone, Debug, Serialize)]
pub struct FitReport {
    pub model: &'static str,
    pub model_version: u16,
    pub input: InputSummary,
    /// Canonical parameters (ω = 1).
    pub params: Params<f64>,
    pub identifiable: IdentifiableReport,
    pub convention: &'static str,
    /// Unweighted residual sum of squares, (N·m)².
    pub rss: f64,
    /// Unweighted RMS residual, N·m.
    pub rms: f64,
    pub n: usize,
    /// Noise the residuals were weighted by; `null` for a plain least-squares fit.
    pub noise: Option<NoiseModel>,
    pub baselines: Vec<BaselineReport>,
    /// Parameter sets given with `--compare`, evaluated on the same data.
    pub compared: Vec<ComparedReport>,
    pub search: SearchSummary,
}

#[derive(Clone, Debug, Serialize)]
pub struct InputSummary {
    pub path: String,
    pub kind: &'static str,
    pub turning_points: Option<usize>,
}

#[derive(Clone, Debug, Serialize)]
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
    pub params: Params<f64>,
    pub rss: f64,
}

pub const CONVENTION: &str = "only h and r are identifiable: (s*alpha, s*beta, s*omega) gives the same torque for any s != 0; params are the point with omega = 1";

impl FitReport {
    pub fn new(
        input: InputSummary,
        fit: &Fit,
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
        FitReport {
            model: MODEL_NAME,
            model_version: MODEL_VERSION,
            input,
            params: fit.params,
            identifiable: IdentifiableReport {
                h: fit.identifiable.h,
                r: fit.identifiable.r,
                amplitude_rad: fit.reference_amplitude,
            },
            convention: CONVENTION,
            rss: fit.rss,
            rms: fit.rms,
            n: fit.n,
            noise: fit.noise,
            baselines,
            compared,
            search: fit.search.clone(),
        }
    }

    /// The summary printed for a person.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let p = &self.params;
        let id = &self.identifiable;
        let _ = write!(s, "{} ({}, {} samples", self.input.path, self.input.kind.replace('_', " "), self.n);
        if let Some(tp) = self.input.turning_points {
            let _ = write!(s, ", {tp} turning points");
        }
        let _ = writeln!(s, ")");
        let _ = writeln!(s, "model {} v{}: T = c1·θ + c2·θ³ + c3·θ⁵ + z(θ)", self.model, self.model_version);
        let _ = writeln!(s, "  c1 = {:>12.5e} N·m/rad", p.c1);
        let _ = writeln!(s, "  c2 = {:>12.5e} N·m/rad³", p.c2);
        let _ = writeln!(s, "  c3 = {:>12.5e} N·m/rad⁵", p.c3);
        let _ = writeln!(
            s,
            "  hysteresis, identifiable: h = {:.5} N·m, r = β/ω = {:.5}  (at A = {:.4} mrad)",
            id.h,
            id.r,
            id.amplitude_rad * 1e3
        );
        let _ = writeln!(
            s,
            "  canonical point (ω = 1): α = {:.5e}, β = {:.5}, ω = {}  — any (sα, sβ, sω) fits the same",
            p.alpha, p.beta, p.omega
        );
        if let Some(noise) = &self.noise {
            let _ = writeln!(
                s,
                "  residuals weighted by total noise: torque {:.3e} N·m, deflection {:.3e} rad",
                noise.torque_nm, noise.deflection_rad
            );
        }
        let _ = writeln!(s, "fit quality (unweighted torque residuals)");
        let _ = writeln!(s, "  {:<34} {:>12} {:>10}", "model", "RSS (N·m)²", "RMS N·m");
        let rms = |rss: f64| (rss / self.n as f64).sqrt();
        let _ = writeln!(s, "  {:<34} {:>12.5} {:>10.4}", "genetic hysteresis (this fit)", self.rss, self.rms);
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
