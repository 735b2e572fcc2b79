//! The truth physics of a simulated gear: what the recording's torque comes from. Besides the
//! genetic model of the params file, four physics that are NOT the model a fit will use, so
//! that a test which fits a model to them is not circular: a smooth Bouc–Wen gear, a
//! Maxwell-slip (Iwan) gear with hundreds of slip elements on a continuous distribution, a
//! harmonic-drive catalogue gear (a kinked three-segment spring with such elements), and a
//! gear whose slip elements grip harder on one side (a Preisach density that is not Masing).
use crate::input::table::read_text;
use crate::input::InputError;
use model_core::bouc_wen::BoucWenState;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which physics makes the torque.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum Physics {
    /// The params file's model, of any kind (the genetic seed fit by default; its symmetric loop
    /// rule under `sine`).
    #[default]
    Model,
    /// Maxwell-slip / Iwan: many spring–slider elements and a linear + cubic spring.
    MicroSlip(MicroSlip),
    /// Bouc–Wen, n = 1, with a cubic spring.
    BoucWen(BoucWen),
    /// A catalogue's three-segment spring with Maxwell-slip elements.
    Catalogue(Catalogue),
    /// Slip elements whose grip depends on where they slip: loops that depend on where they sit.
    Preisach(Preisach),
}

impl Physics {
    /// The name `--physics` takes (`genetic` for the params file's model: the seed fit's kind,
    /// and what the flag has always been called).
    pub fn name(&self) -> &'static str {
        match self {
            Physics::Model => "genetic",
            Physics::MicroSlip(_) => "micro-slip",
            Physics::BoucWen(_) => "bouc-wen",
            Physics::Catalogue(_) => "catalogue",
            Physics::Preisach(_) => "preisach",
        }
    }

    /// The physics' gear at rest, with its state; `None` for [`Physics::Model`], whose state
    /// is the model's evaluator.
    pub fn gear(&self) -> Result<Option<Box<dyn Gear>>, PhysicsParamError> {
        Ok(match self {
            Physics::Model => None,
            Physics::MicroSlip(params) => Some(Box::new(MicroSlipGear::new(*params)?)),
            Physics::BoucWen(params) => Some(Box::new(BoucWenGear::new(*params)?)),
            Physics::Catalogue(params) => Some(Box::new(CatalogueGear::new(*params)?)),
            Physics::Preisach(params) => Some(Box::new(PreisachGear::new(*params)?)),
        })
    }

    /// The truth's tangent stiffness dT/dθ, N·m/rad, at each deflection of `deflection` (rad),
    /// stepped from rest: what a model's stiffness is scored against. `None` where the state
    /// does not fix it: the params file's model (its evaluator has its own) and Bouc–Wen, whose
    /// tangent depends on the direction of the next step.
    pub fn tangent_along(&self, deflection: &[f64]) -> Result<Option<Vec<f64>>, PhysicsParamError> {
        let Some(mut gear) = self.gear()? else { return Ok(None) };
        Ok(deflection
            .iter()
            .map(|&theta| {
                gear.step(theta);
                gear.tangent()
            })
            .collect())
    }
}

/// Bouc–Wen: T = a·k·θ + k3·θ³ + (1 − a)·k·z with
/// dz = dθ·(A_bw − |z|ⁿ·(β_bw·sign(dθ·z) + γ_bw)), z in rad, z = 0 at rest.
///
/// Rate-independent (z depends on the path of θ, not on time) and smooth along a branch; no
/// exact return-point memory (small reversals drift), which is part of this physics. z is
/// model-core's [`model_core::bouc_wen`]: integrated exactly per sample for n = 1, by RK4
/// sub-steps of a stated error otherwise.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoucWen {
    /// Initial (virgin) stiffness k, N·m/rad.
    pub k: f64,
    /// Post-yield stiffness ratio a, 0 ≤ a < 1.
    pub a: f64,
    /// Cubic spring coefficient k3, N·m/rad³ (0 gives the textbook model).
    pub k3: f64,
    /// A_bw, dimensionless (> 0).
    pub a_bw: f64,
    /// β_bw, rad⁻ⁿ (> 0).
    pub beta_bw: f64,
    /// γ_bw, rad⁻ⁿ (> −β_bw).
    pub gamma_bw: f64,
    /// n, ≥ 1 (OpenSees' BoucWen calls it n too).
    pub n: f64,
}

impl Default for BoucWen {
    fn default() -> Self {
        // The seed fit's small-angle stiffness c1 ≈ 9000 N·m/rad; z saturates at
        // A_bw/(β_bw + γ_bw) = 0.4 mrad; the loop at A = 1.168 mrad peaks at 28.6 N·m and is
        // 0.92 N·m wide at θ = 0 (3.2 % of the peak).
        BoucWen { k: 9000.0, a: 0.85, k3: 1.2e10, a_bw: 1.0, beta_bw: 1250.0, gamma_bw: 1250.0, n: 1.0 }
    }
}

/// Maxwell-slip / Iwan gear: T = k1·θ + k3·θ³ + Σ k_e·s_i, element i a spring k_e in series
/// with a slider that slips at deflection d_i: s_i ← clamp(s_i + Δθ, −d_i, d_i), s_i = 0 at rest.
///
/// The M slip deflections are the quantiles (i + ½)/M of a power-law density
/// p(d) ∝ d^p on [d_min, d_max] (p = 0: uniform; p = −1: log-uniform), all elements with the
/// same stiffness k_e = K_slip/M. Madelung's rules hold exactly.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MicroSlip {
    /// Linear spring k1, N·m/rad.
    pub k1: f64,
    /// Cubic spring k3, N·m/rad³.
    pub k3: f64,
    /// Number of slip elements M.
    pub elements: usize,
    /// Total stiffness of the slip elements K_slip = M·k_e, N·m/rad.
    pub slip_stiffness: f64,
    /// Smallest and largest slip deflection d_min, d_max, rad.
    pub min_slip_rad: f64,
    pub max_slip_rad: f64,
    /// Exponent p of the slip-deflection density p(d) ∝ d^p.
    pub slip_exponent: f64,
}

impl Default for MicroSlip {
    fn default() -> Self {
        // Small-angle stiffness k1 + K_slip = 9000 N·m/rad (the seed fit's c1); the loop at
        // A = 1.168 mrad peaks at 28.6 N·m and is 1.02 N·m wide at θ = 0 (3.6 % of the peak).
        MicroSlip {
            k1: 6000.0,
            k3: 1.2e10,
            elements: 300,
            slip_stiffness: 3000.0,
            min_slip_rad: 0.0,
            max_slip_rad: 2.0e-3,
            slip_exponent: 0.0,
        }
    }
}

/// A harmonic-drive catalogue gear: the catalogue's three-segment torsional stiffness curve in
/// parallel with Maxwell-slip elements like [`MicroSlip`]'s, T = T_s(θ) + Σ k_e·s_i.
///
/// The spring T_s is piecewise linear in θ with kinks where it reaches the torques ±T1, ±T2:
/// stiffness K1 for |T_s| < T1, K2 for T1 ≤ |T_s| < T2, K3 beyond (0 < K1 < K2 < K3, a
/// stiffening gear). On the + side the stiffnesses are σ·K_j (σ = `positive_scale`), on the −
/// side K_j, so the kinks lie at the same torques but at deflections
/// θ1 = T1/K1', θ2 = θ1 + (T2 − T1)/K2' (K_j' = σ·K_j for θ > 0, K_j for θ < 0):
///   T_s(θ) = sign(θ)·{ K1'·|θ|                   for |θ| < θ1,
///                     T1 + K2'·(|θ| − θ1)        for θ1 ≤ |θ| < θ2,
///                     T2 + K3'·(|θ| − θ2)        beyond }.
/// The slip elements: s_i ← clamp(s_i + Δθ, −d_i, d_i), s_i = 0 at rest, k_e = K_slip/M, d_i
/// the quantiles (i + ½)/M of p(d) ∝ d^p on [d_min, d_max], as for [`MicroSlip`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Catalogue {
    /// Stiffness below T1, between T1 and T2, and beyond T2 (− side), N·m/rad.
    pub k1: f64,
    pub k2: f64,
    pub k3: f64,
    /// The torques T1 < T2 where the stiffness steps, N·m.
    pub t1_nm: f64,
    pub t2_nm: f64,
    /// σ: the + side's stiffnesses are σ·K1, σ·K2, σ·K3 (1: point-symmetric).
    pub positive_scale: f64,
    /// Number of slip elements M.
    pub elements: usize,
    /// Total stiffness of the slip elements K_slip = M·k_e, N·m/rad.
    pub slip_stiffness: f64,
    /// Smallest and largest slip deflection d_min, d_max, rad.
    pub min_slip_rad: f64,
    pub max_slip_rad: f64,
    /// Exponent p of the slip-deflection density p(d) ∝ d^p.
    pub slip_exponent: f64,
}

impl Default for Catalogue {
    fn default() -> Self {
        // Steps at 7 and 19 N·m, reached at θ1 = 0.5 mrad and θ2 = 0.96 mrad, both inside the
        // default amplitude 1.168 mrad; the stiffness rises from 16000 N·m/rad at rest (K1 plus
        // the sticking elements) to K3 = 36000. The loop at A = 1.168 mrad peaks at 28.1 N·m and
        // is 0.68 N·m wide at θ = 0 (2.4 % of the peak).
        Catalogue {
            k1: 14_000.0,
            k2: 26_000.0,
            k3: 36_000.0,
            t1_nm: 7.0,
            t2_nm: 19.0,
            positive_scale: 1.0,
            elements: 300,
            slip_stiffness: 2000.0,
            min_slip_rad: 0.0,
            max_slip_rad: 2.0e-3,
            slip_exponent: 0.0,
        }
    }
}

/// A gear of slip elements that grip harder where they slip on one side: the Maxwell-slip gear
/// with each element's friction depending on the centre of its play, a Preisach density over
/// relay centres c = (α + β)/2 that is not uniform, so not Masing (a biased loop is fatter or
/// thinner than a centred one of the same amplitude, and minor loops are not congruent):
///
/// ```text
/// T = k1·θ + k3·θ³ + Σ_i (k_e·θ − Φ(p_i)),   p_i ← clamp(p_i, θ − d_i, θ + d_i),  p_i = 0 at rest
/// Φ(p) = ∫₀ᵖ k_e·(1 + skew·tanh(c/w)) dc = k_e·(p + skew·w·ln cosh(p/w))
/// ```
///
/// p_i is element i's play operator (the centre of its slider's travel); with skew = 0 each
/// term is k_e·(θ − p_i), the Maxwell-slip element of [`MicroSlip`]. The slip deflections d_i
/// and k_e = K_slip/M are as there. Tangent: k1 + 3k3·θ² + Σ k_e − Σ_slipping k_e·(1 + skew·tanh(p_i/w)).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Preisach {
    /// Linear spring k1, N·m/rad.
    pub k1: f64,
    /// Cubic spring k3, N·m/rad³.
    pub k3: f64,
    /// Number of slip elements M.
    pub elements: usize,
    /// Total stiffness of the slip elements K_slip = M·k_e, N·m/rad.
    pub slip_stiffness: f64,
    /// Smallest and largest slip deflection d_min, d_max, rad.
    pub min_slip_rad: f64,
    pub max_slip_rad: f64,
    /// Exponent p of the slip-deflection density p(d) ∝ d^p.
    pub slip_exponent: f64,
    /// How much harder the elements grip where their play sits on the + side, −1 < skew < 1.
    pub skew: f64,
    /// The width w over which the grip changes, rad.
    pub skew_width_rad: f64,
}

impl Default for Preisach {
    fn default() -> Self {
        // The micro-slip gear's spring and elements, gripping 1.53 times as hard at +0.4 mrad as
        // at 0 and half as hard at −0.4 mrad. The loop at A = 1.168 mrad peaks at +28.2 and
        // −29.1 N·m (the + side's harder grip lets go more torque); a loop of ±0.15·A biased to
        // +0.6·A dissipates 4.8 times what one biased to −0.6·A does (the tests measure both).
        Preisach {
            k1: 6000.0,
            k3: 1.2e10,
            elements: 300,
            slip_stiffness: 3000.0,
            min_slip_rad: 0.0,
            max_slip_rad: 2.0e-3,
            slip_exponent: 0.0,
            skew: 0.7,
            skew_width_rad: 0.4e-3,
        }
    }
}

/// A physics parameter out of its range: which, what was expected, what it was.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{physics} parameter {name} must be {expected}, got {value}")]
pub struct PhysicsParamError {
    pub physics: &'static str,
    pub name: &'static str,
    pub expected: &'static str,
    pub value: f64,
}

fn require(
    physics: &'static str,
    name: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), PhysicsParamError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(PhysicsParamError { physics, name, expected, value })
    }
}

impl BoucWen {
    pub fn validate(&self) -> Result<(), PhysicsParamError> {
        let p = "bouc-wen";
        require(p, "k", self.k, self.k > 0.0, "> 0 N·m/rad")?;
        require(p, "a", self.a, (0.0..1.0).contains(&self.a), "in [0, 1)")?;
        require(p, "k3", self.k3, true, "finite")?;
        require(p, "a_bw", self.a_bw, self.a_bw > 0.0, "> 0")?;
        require(p, "beta_bw", self.beta_bw, self.beta_bw > 0.0, "> 0 1/rad")?;
        require(p, "gamma_bw", self.gamma_bw, self.gamma_bw > -self.beta_bw, "> -beta_bw 1/rad")?;
        require(p, "n", self.n, self.n >= 1.0, ">= 1")
    }
}

impl MicroSlip {
    pub fn validate(&self) -> Result<(), PhysicsParamError> {
        let p = "micro-slip";
        require(p, "k1", self.k1, true, "finite")?;
        require(p, "k3", self.k3, true, "finite")?;
        self.distribution().validate(p)
    }

    /// The M slip deflections d_i, ascending.
    pub fn slips(&self) -> Vec<f64> {
        self.distribution().slips()
    }

    fn distribution(&self) -> SlipDistribution {
        SlipDistribution {
            elements: self.elements,
            stiffness: self.slip_stiffness,
            min_rad: self.min_slip_rad,
            max_rad: self.max_slip_rad,
            exponent: self.slip_exponent,
        }
    }
}

impl Preisach {
    pub fn validate(&self) -> Result<(), PhysicsParamError> {
        let p = "preisach";
        require(p, "k1", self.k1, true, "finite")?;
        require(p, "k3", self.k3, true, "finite")?;
        require(p, "skew", self.skew, self.skew.abs() < 1.0, "in (-1, 1) (a grip that stays > 0)")?;
        require(p, "skew_width_rad", self.skew_width_rad, self.skew_width_rad > 0.0, "> 0 rad")?;
        self.distribution().validate(p)
    }

    fn distribution(&self) -> SlipDistribution {
        SlipDistribution {
            elements: self.elements,
            stiffness: self.slip_stiffness,
            min_rad: self.min_slip_rad,
            max_rad: self.max_slip_rad,
            exponent: self.slip_exponent,
        }
    }

    /// Φ(p)/k_e, rad: what the relays of one element's line below its play p have let go.
    fn released(&self, p: f64) -> f64 {
        let w = self.skew_width_rad;
        // ln cosh(v) = |v| + ln(1 + e^(−2|v|)) − ln 2, finite for any v.
        let v = (p / w).abs();
        p + self.skew * w * (v + (-2.0 * v).exp().ln_1p() - std::f64::consts::LN_2)
    }

    /// The grip at play p, 1 + skew·tanh(p/w): dΦ/dp over k_e.
    fn grip(&self, p: f64) -> f64 {
        1.0 + self.skew * (p / self.skew_width_rad).tanh()
    }
}

impl Catalogue {
    pub fn validate(&self) -> Result<(), PhysicsParamError> {
        let p = "catalogue";
        require(p, "k1", self.k1, self.k1 > 0.0, "> 0 N·m/rad")?;
        require(p, "k2", self.k2, self.k2 > self.k1, "> k1 N·m/rad (a stiffening gear)")?;
        require(p, "k3", self.k3, self.k3 > self.k2, "> k2 N·m/rad (a stiffening gear)")?;
        require(p, "t1_nm", self.t1_nm, self.t1_nm > 0.0, "> 0 N·m")?;
        require(p, "t2_nm", self.t2_nm, self.t2_nm > self.t1_nm, "> t1_nm N·m")?;
        require(p, "positive_scale", self.positive_scale, self.positive_scale > 0.0, "> 0")?;
        self.distribution().validate(p)
    }

    /// The spring's torque T_s(θ), N·m.
    pub fn spring_torque(&self, theta: f64) -> f64 {
        let ([k1, k2, k3], [theta1, theta2]) = self.side(theta);
        let u = theta.abs();
        let torque = if u < theta1 {
            k1 * u
        } else if u < theta2 {
            self.t1_nm + k2 * (u - theta1)
        } else {
            self.t2_nm + k3 * (u - theta2)
        };
        theta.signum() * torque
    }

    /// The spring's stiffness dT_s/dθ at θ (the higher segment's at a kink), N·m/rad.
    pub fn spring_stiffness(&self, theta: f64) -> f64 {
        let ([k1, k2, k3], [theta1, theta2]) = self.side(theta);
        let u = theta.abs();
        if u < theta1 {
            k1
        } else if u < theta2 {
            k2
        } else {
            k3
        }
    }

    /// The deflections of the kinks on θ's side, |θ1| < |θ2|, signed like θ (+ at θ = 0).
    pub fn kinks(&self, theta: f64) -> [f64; 2] {
        let sign = if theta < 0.0 { -1.0 } else { 1.0 };
        self.side(theta).1.map(|u| sign * u)
    }

    /// The stiffnesses [K1', K2', K3'] of θ's side and its kinks' |θ1|, |θ2|.
    fn side(&self, theta: f64) -> ([f64; 3], [f64; 2]) {
        let scale = if theta < 0.0 { 1.0 } else { self.positive_scale };
        let k = [self.k1, self.k2, self.k3].map(|k| scale * k);
        let theta1 = self.t1_nm / k[0];
        (k, [theta1, theta1 + (self.t2_nm - self.t1_nm) / k[1]])
    }

    fn distribution(&self) -> SlipDistribution {
        SlipDistribution {
            elements: self.elements,
            stiffness: self.slip_stiffness,
            min_rad: self.min_slip_rad,
            max_rad: self.max_slip_rad,
            exponent: self.slip_exponent,
        }
    }
}

/// M Maxwell-slip elements of equal stiffness k_e = K_slip/M whose slip deflections d_i are
/// the quantiles (i + ½)/M of p(d) ∝ d^p on [d_min, d_max]: the hysteresis of the micro-slip
/// and catalogue gears.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SlipDistribution {
    elements: usize,
    stiffness: f64,
    min_rad: f64,
    max_rad: f64,
    exponent: f64,
}

impl SlipDistribution {
    /// At most this many elements (each is updated every sample).
    const MAX_ELEMENTS: usize = 100_000;

    fn validate(&self, p: &'static str) -> Result<(), PhysicsParamError> {
        let m = self.elements as f64;
        require(p, "elements", m, (1..=Self::MAX_ELEMENTS).contains(&self.elements), "1 to 100000")?;
        require(p, "slip_stiffness", self.stiffness, self.stiffness >= 0.0, ">= 0 N·m/rad")?;
        require(p, "min_slip_rad", self.min_rad, self.min_rad >= 0.0, ">= 0 rad")?;
        require(p, "max_slip_rad", self.max_rad, self.max_rad > self.min_rad, "> min_slip_rad")?;
        let positive_min = self.exponent > -1.0 || self.min_rad > 0.0;
        require(p, "slip_exponent", self.exponent, positive_min, "> -1 unless min_slip_rad > 0")
    }

    /// The M slip deflections d_i, ascending.
    fn slips(&self) -> Vec<f64> {
        let (lo, hi, p) = (self.min_rad, self.max_rad, self.exponent);
        let m = self.elements;
        (0..m)
            .map(|i| {
                let u = (i as f64 + 0.5) / m as f64;
                if (p + 1.0).abs() < 1e-12 {
                    (lo.ln() + u * (hi.ln() - lo.ln())).exp()
                } else {
                    let q = p + 1.0;
                    (lo.powf(q) + u * (hi.powf(q) - lo.powf(q))).powf(q.recip())
                }
            })
            .collect()
    }
}

/// Slip elements with their state s_i (rad), every one unstressed at rest.
#[derive(Clone, Debug)]
struct SlipElements {
    element_stiffness: f64,
    slips: Vec<f64>,
    state: Vec<f64>,
}

impl SlipElements {
    fn at_rest(distribution: SlipDistribution) -> Self {
        let slips = distribution.slips();
        SlipElements {
            element_stiffness: distribution.stiffness / distribution.elements as f64,
            state: vec![0.0; slips.len()],
            slips,
        }
    }

    /// Moves every element by Δθ, each slipping at its d_i; returns Σ k_e·s_i, N·m.
    fn step(&mut self, delta: f64) -> f64 {
        let mut sum = 0.0;
        for (s, &d) in self.state.iter_mut().zip(&self.slips) {
            *s = (*s + delta).clamp(-d, d);
            sum += *s;
        }
        self.element_stiffness * sum
    }

    /// The sticking elements' stiffness, N·m/rad.
    fn stiffness(&self) -> f64 {
        let sticking = self.state.iter().zip(&self.slips).filter(|(s, d)| s.abs() < **d).count();
        self.element_stiffness * sticking as f64
    }
}

/// A truth physics with its state: torque from the deflection path, starting at rest.
pub trait Gear {
    /// Moves to deflection `theta` (rad) from the previous one; returns the torque, N·m.
    fn step(&mut self, theta: f64) -> f64;
    /// The linear stiffness that `thermal_drift` scales, N·m/rad.
    fn linear_stiffness(&self) -> f64;
    /// The tangent stiffness at the present state, N·m/rad, where the state fixes it (the
    /// sticking slip elements' plus the spring's; `None` for Bouc–Wen, see
    /// [`Physics::tangent_along`]).
    fn tangent(&self) -> Option<f64>;
}

/// A Bouc–Wen gear and its state.
#[derive(Clone, Debug)]
pub struct BoucWenGear {
    params: BoucWen,
    hysteresis: BoucWenState<f64>,
}

impl BoucWenGear {
    /// At rest: θ = 0, z = 0.
    pub fn new(params: BoucWen) -> Result<Self, PhysicsParamError> {
        params.validate()?;
        let hysteresis =
            model_core::bouc_wen::BoucWen { a: params.a_bw, beta: params.beta_bw, gamma: params.gamma_bw, n: params.n };
        // `validate` asks what model-core does and names the parameter at fault: past it, this
        // cannot fail.
        let hysteresis = BoucWenState::new(hysteresis).map_err(|_| PhysicsParamError {
            physics: "bouc-wen",
            name: "gamma_bw",
            expected: "> -beta_bw 1/rad, with a_bw > 0, beta_bw > 0 and n >= 1",
            value: params.gamma_bw,
        })?;
        Ok(BoucWenGear { params, hysteresis })
    }
}

impl Gear for BoucWenGear {
    fn step(&mut self, theta: f64) -> f64 {
        let p = &self.params;
        // A simulated path is finite; a non-finite θ keeps z where it was.
        let z = self.hysteresis.step(theta).unwrap_or(self.hysteresis.z());
        p.a * p.k * theta + p.k3 * theta.powi(3) + (1.0 - p.a) * p.k * z
    }

    fn linear_stiffness(&self) -> f64 {
        self.params.a * self.params.k
    }

    fn tangent(&self) -> Option<f64> {
        None
    }
}

/// A Maxwell-slip gear and its state.
#[derive(Clone, Debug)]
pub struct MicroSlipGear {
    params: MicroSlip,
    elements: SlipElements,
    theta: f64,
}

impl MicroSlipGear {
    /// At rest: θ = 0, every element unstressed.
    pub fn new(params: MicroSlip) -> Result<Self, PhysicsParamError> {
        params.validate()?;
        Ok(MicroSlipGear { params, elements: SlipElements::at_rest(params.distribution()), theta: 0.0 })
    }

    /// Tangent stiffness at the present state, N·m/rad: the spring's plus the sticking elements'.
    pub fn stiffness(&self) -> f64 {
        self.params.k1 + 3.0 * self.params.k3 * self.theta.powi(2) + self.elements.stiffness()
    }
}

impl Gear for MicroSlipGear {
    fn step(&mut self, theta: f64) -> f64 {
        let slip_torque = self.elements.step(theta - self.theta);
        self.theta = theta;
        self.params.k1 * theta + self.params.k3 * theta.powi(3) + slip_torque
    }

    fn linear_stiffness(&self) -> f64 {
        self.params.k1
    }

    fn tangent(&self) -> Option<f64> {
        Some(self.stiffness())
    }
}

/// A catalogue gear and its state.
#[derive(Clone, Debug)]
pub struct CatalogueGear {
    params: Catalogue,
    elements: SlipElements,
    theta: f64,
}

impl CatalogueGear {
    /// At rest: θ = 0, every element unstressed.
    pub fn new(params: Catalogue) -> Result<Self, PhysicsParamError> {
        params.validate()?;
        Ok(CatalogueGear { params, elements: SlipElements::at_rest(params.distribution()), theta: 0.0 })
    }

    /// Tangent stiffness at the present state, N·m/rad: the spring's plus the sticking elements'.
    pub fn stiffness(&self) -> f64 {
        self.params.spring_stiffness(self.theta) + self.elements.stiffness()
    }
}

impl Gear for CatalogueGear {
    fn step(&mut self, theta: f64) -> f64 {
        let slip_torque = self.elements.step(theta - self.theta);
        self.theta = theta;
        self.params.spring_torque(theta) + slip_torque
    }

    /// K1 of the − side (the + side's is σ·K1).
    fn linear_stiffness(&self) -> f64 {
        self.params.k1
    }

    fn tangent(&self) -> Option<f64> {
        Some(self.stiffness())
    }
}

/// A gear of slip elements whose grip depends on where they slip, and its state.
#[derive(Clone, Debug)]
pub struct PreisachGear {
    params: Preisach,
    element_stiffness: f64,
    slips: Vec<f64>,
    /// Each element's play operator p_i, rad.
    plays: Vec<f64>,
    /// Whether each element's play sits at an end of its travel, θ ∓ d_i as the step computed
    /// them (slipping while the motion goes on that way; θ − p = ±d is not exact in floats).
    at_limit: Vec<bool>,
    theta: f64,
}

impl PreisachGear {
    /// At rest: θ = 0, every play at 0.
    pub fn new(params: Preisach) -> Result<Self, PhysicsParamError> {
        params.validate()?;
        let distribution = params.distribution();
        let slips = distribution.slips();
        Ok(PreisachGear {
            params,
            element_stiffness: distribution.stiffness / distribution.elements as f64,
            plays: vec![0.0; slips.len()],
            at_limit: vec![false; slips.len()],
            slips,
            theta: 0.0,
        })
    }
}

impl Gear for PreisachGear {
    fn step(&mut self, theta: f64) -> f64 {
        let p = &self.params;
        let mut released = 0.0;
        for ((play, at_limit), &d) in self.plays.iter_mut().zip(&mut self.at_limit).zip(&self.slips) {
            let (low, high) = (theta - d, theta + d);
            *play = play.clamp(low, high);
            *at_limit = *play == low || *play == high;
            released += p.released(*play);
        }
        self.theta = theta;
        let elements = self.slips.len() as f64;
        p.k1 * theta + p.k3 * theta.powi(3) + self.element_stiffness * (elements * theta - released)
    }

    fn linear_stiffness(&self) -> f64 {
        self.params.k1
    }

    /// The spring's, every element's k_e, less the grip of those at the end of their travel
    /// (their play moves with θ while the motion goes on).
    fn tangent(&self) -> Option<f64> {
        let p = &self.params;
        let gripping: f64 = self
            .plays
            .iter()
            .zip(&self.at_limit)
            .filter(|(_, at_limit)| **at_limit)
            .map(|(play, _)| p.grip(*play))
            .sum();
        let elements = self.slips.len() as f64;
        Some(p.k1 + 3.0 * p.k3 * self.theta.powi(2) + self.element_stiffness * (elements - gripping))
    }
}

/// Reads a physics parameter file (`--physics-params`): a JSON object with the fields of
/// [`BoucWen`], [`MicroSlip`], [`Catalogue`] or [`Preisach`], each optional (missing ones keep their defaults), no others.
pub fn read_physics_params<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T, InputError> {
    let text = read_text(path)?;
    serde_json::from_str(&text).map_err(|e| {
        let message = format!("column {}: {}", e.column(), strip_position(&e.to_string()));
        if e.line() > 0 {
            InputError::at_line(path, e.line() as u64, message)
        } else {
            InputError::file(path, strip_position(&e.to_string()))
        }
    })
}

/// serde_json's message without its trailing " at line L column C".
fn strip_position(message: &str) -> String {
    match message.rfind(" at line ") {
        Some(at) => message[..at].to_owned(),
        None => message.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    const A: f64 = 1.168e-3;

    /// (θ, T) over `cycles` sine cycles of amplitude `amplitude`, `n` samples a cycle, from rest.
    fn sine(gear: &mut dyn Gear, amplitude: f64, cycles: usize, n: usize) -> Vec<(f64, f64)> {
        (0..=cycles * n)
            .map(|i| {
                let theta = amplitude * (TAU * i as f64 / n as f64).sin();
                (theta, gear.step(theta))
            })
            .collect()
    }

    /// ∮T dθ over the samples (trapezoids).
    fn work(path: &[(f64, f64)]) -> f64 {
        path.windows(2).map(|w| 0.5 * (w[0].1 + w[1].1) * (w[1].0 - w[0].0)).sum()
    }

    /// Rising minus falling torque at θ = 0 on the last cycle of `path` (n samples a cycle):
    /// at samples 0 (rising through 0) and n/2 (falling through 0).
    fn width_at_zero(path: &[(f64, f64)], n: usize) -> (f64, f64) {
        let last = &path[path.len() - 1 - n..];
        let peak = last.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
        (last[0].1 - last[n / 2].1, peak)
    }

    #[test]
    fn the_physics_loops_are_passive_hysteretic_and_a_few_percent_wide() {
        let n = 2400;
        let gears: [(&str, Box<dyn Gear>); 4] = [
            ("bouc-wen", Box::new(BoucWenGear::new(BoucWen::default()).unwrap())),
            ("micro-slip", Box::new(MicroSlipGear::new(MicroSlip::default()).unwrap())),
            ("catalogue", Box::new(CatalogueGear::new(Catalogue::default()).unwrap())),
            ("preisach", Box::new(PreisachGear::new(Preisach::default()).unwrap())),
        ];
        for (name, mut gear) in gears {
            let path = sine(gear.as_mut(), A, 3, n);
            assert!(path.iter().all(|p| p.1.is_finite()));
            let cycle = &path[path.len() - 1 - n..];
            let dissipated = work(cycle);
            let (width, peak) = width_at_zero(&path, n);
            assert!(dissipated > 0.0, "{name}: ∮T dθ = {dissipated}");
            assert!((25.0..32.0).contains(&peak), "{name}: peak {peak}");
            assert!((0.02..0.05).contains(&(width / peak)), "{name}: width {width} of {peak}");
            // Falling below rising at mid deflection ±A/2, too: θ = A·sin(2πk/n) is +A/2 at
            // k = n/12 (rising) and 5n/12 (falling), −A/2 at 11n/12 (rising) and 7n/12 (falling).
            for (rising, falling) in [(n / 12, 5 * n / 12), (11 * n / 12, 7 * n / 12)] {
                let (r, f) = (cycle[rising], cycle[falling]);
                assert!((r.0 - f.0).abs() < 1e-12, "{name}: {r:?} {f:?}");
                assert!(r.1 - f.1 > 0.01 * peak, "{name}: rising {r:?} not above falling {f:?}");
            }
        }
    }

    #[test]
    fn micro_slip_has_return_point_memory_and_wipes_out() {
        let mut gear = MicroSlipGear::new(MicroSlip::default()).unwrap();
        gear.step(A);
        gear.step(-A);
        let top = gear.step(0.7e-3);
        // An inner loop down to 0.2 mrad and back up closes where it started …
        let bottom = gear.step(0.2e-3);
        assert!((gear.step(0.7e-3) - top).abs() < 1e-12);
        assert!(top - bottom > 0.0);
        // … and going on up continues the outer branch, as if the inner loop never happened.
        let continued = gear.step(0.9e-3);
        let mut outer = MicroSlipGear::new(MicroSlip::default()).unwrap();
        outer.step(A);
        outer.step(-A);
        assert!((outer.step(0.9e-3) - continued).abs() < 1e-12);
    }

    #[test]
    fn bouc_wen_drifts_on_small_reversals() {
        // The physics' own behaviour (no exact return-point memory), small but there.
        let mut gear = BoucWenGear::new(BoucWen::default()).unwrap();
        gear.step(A);
        gear.step(-A);
        let top = gear.step(0.7e-3);
        gear.step(0.2e-3);
        let drift = gear.step(0.7e-3) - top;
        assert!(drift.abs() > 1e-3 && drift.abs() < 0.5, "{drift}");
    }

    #[test]
    fn bouc_wen_is_smooth_along_a_branch_and_micro_slip_is_a_fine_staircase() {
        let n = 4000;
        let mut bouc = BoucWenGear::new(BoucWen::default()).unwrap();
        let path = sine(&mut bouc, A, 2, n);
        // The incremental stiffness of the hysteretic part (T − k3·θ³) along the last rising
        // branch (−A → A) changes by less than 0.5 % of k between neighbouring samples: no kinks.
        let k3 = BoucWen::default().k3;
        let branch = &path[path.len() - 1 - n / 4 - n / 2..path.len() - n / 4];
        let slopes: Vec<f64> = branch
            .windows(2)
            .map(|w| ((w[1].1 - k3 * w[1].0.powi(3)) - (w[0].1 - k3 * w[0].0.powi(3))) / (w[1].0 - w[0].0))
            .collect();
        let inner = &slopes[20..slopes.len() - 20];
        let jump = inner.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0, f64::max);
        assert!(jump < 0.005 * BoucWen::default().k, "largest stiffness jump {jump}");
        // Micro-slip's stiffness falls in steps of k_e = K_slip/M as elements start to slip.
        let mut slip = MicroSlipGear::new(MicroSlip::default()).unwrap();
        let k0 = slip.stiffness();
        slip.step(0.5e-3);
        let k_e = MicroSlip::default().slip_stiffness / 300.0;
        let dropped = (k0 - slip.stiffness() + 3.0 * 1.2e10 * 0.25e-6) / k_e;
        assert!((dropped - dropped.round()).abs() < 1e-6 && dropped > 50.0, "{dropped}");
    }

    #[test]
    fn slip_deflections_follow_their_distribution() {
        let uniform = MicroSlip::default().slips();
        assert_eq!(uniform.len(), 300);
        assert!((uniform[0] - 2e-3 * 0.5 / 300.0).abs() < 1e-15);
        assert!((uniform[299] - 2e-3 * 299.5 / 300.0).abs() < 1e-15);
        let log = MicroSlip {
            min_slip_rad: 1e-5,
            max_slip_rad: 1e-3,
            slip_exponent: -1.0,
            elements: 4,
            ..MicroSlip::default()
        };
        let d = log.slips();
        let ratios: Vec<f64> = d.windows(2).map(|w| w[1] / w[0]).collect();
        assert!(ratios.iter().all(|r| (r - 10f64.sqrt()).abs() < 1e-9), "{ratios:?}");
        let power = MicroSlip { slip_exponent: 1.0, elements: 2, max_slip_rad: 1.0, ..MicroSlip::default() };
        assert!((power.slips()[0] - 0.25f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn the_catalogue_spring_kinks_at_its_torques_with_each_sides_stiffness() {
        for scale in [1.0, 0.8] {
            let params = Catalogue { positive_scale: scale, ..Catalogue::default() };
            for sign in [1.0, -1.0] {
                let side = if sign > 0.0 { scale } else { 1.0 };
                let k = [params.k1, params.k2, params.k3].map(|k| side * k);
                let kinks = params.kinks(sign);
                let eps = 1e-8;
                for (j, (&kink, torque)) in kinks.iter().zip([params.t1_nm, params.t2_nm]).enumerate() {
                    assert!((params.spring_torque(kink) - sign * torque).abs() < 1e-12, "{scale} {sign} kink {j}");
                    // The secant stiffness just inside and just outside the kink.
                    let (inner, outer) = (kink - sign * eps, kink + sign * eps);
                    let below = (params.spring_torque(kink) - params.spring_torque(inner)) / (kink - inner);
                    let above = (params.spring_torque(outer) - params.spring_torque(kink)) / (outer - kink);
                    assert!((below - k[j]).abs() < 1e-6 * k[j], "{scale} {sign} kink {j}: {below} vs {}", k[j]);
                    assert!((above - k[j + 1]).abs() < 1e-6 * k[j + 1], "{scale} {sign} kink {j}: {above}");
                    assert_eq!(params.spring_stiffness(inner), k[j]);
                    assert_eq!(params.spring_stiffness(outer), k[j + 1]);
                }
                // Continuous everywhere: no step beyond the steepest slope over a fine grid to 3 mrad.
                let grid: Vec<f64> = (0..=30_000).map(|i| sign * i as f64 * 1e-7).collect();
                let worst = grid
                    .windows(2)
                    .map(|w| (params.spring_torque(w[1]) - params.spring_torque(w[0])).abs() / 1e-7)
                    .fold(0.0, f64::max);
                assert!(worst <= k[2] * (1.0 + 1e-6), "{scale} {sign}: slope {worst}");
            }
            // The + side's kinks lie at the same torques, 1/σ times further out.
            let (plus, minus) = (params.kinks(1.0), params.kinks(-1.0));
            assert!((plus[0] + minus[0] / scale).abs() < 1e-15 && (plus[1] + minus[1] / scale).abs() < 1e-15);
        }
        let symmetric = Catalogue::default();
        assert_eq!(symmetric.spring_torque(0.0), 0.0);
        assert_eq!(symmetric.spring_torque(-1.1e-3), -symmetric.spring_torque(1.1e-3));
    }

    #[test]
    fn the_catalogue_gear_stiffens_at_the_kinks_and_its_slip_elements_add_their_own() {
        let params = Catalogue::default();
        let [theta1, theta2] = params.kinks(1.0);
        let k_e = params.slip_stiffness / params.elements as f64;
        let mut gear = CatalogueGear::new(params).unwrap();
        assert_eq!(gear.stiffness(), params.k1 + params.slip_stiffness);
        for (kink, jump) in [(theta1, params.k2 - params.k1), (theta2, params.k3 - params.k2)] {
            gear.step(kink - 1e-9);
            let before = gear.stiffness();
            gear.step(kink + 1e-9);
            // Within one element that may start slipping on the way.
            assert!((gear.stiffness() - before - jump).abs() <= k_e * 1.000001, "{}", gear.stiffness() - before);
        }
    }

    /// The largest gap between the tangent `tangent_along` gives after each sample of `path` and
    /// the secant of a 1 nrad step on from there in the same direction.
    fn tangent_against_secant<G: Gear + Clone>(physics: &Physics, mut gear: G, path: &[f64]) -> f64 {
        let tangent = physics.tangent_along(path).unwrap().expect("a tangent");
        let mut worst: f64 = 0.0;
        for (i, (&theta, &k)) in path.iter().zip(&tangent).enumerate().skip(1) {
            let at = gear.step(theta);
            let step = 1e-9 * (theta - path[i - 1]).signum();
            let secant = (gear.clone().step(theta + step) - at) / step;
            worst = worst.max((secant - k).abs());
        }
        worst
    }

    #[test]
    fn the_truths_tangent_is_the_slope_of_its_next_small_step() {
        // A sine from rest, then an inner reversal: within one element that starts slipping on
        // the probe's step (k_e), or a kink crossed by it (the secant then mixes two sides').
        let mut path: Vec<f64> = (0..=1500).map(|i| A * (TAU * i as f64 / 1200.0).sin()).collect();
        path.extend((0..=400).map(|i| A - 0.3e-3 * (TAU * i as f64 / 800.0).sin()));
        let catalogue = Catalogue::default();
        let k_e = catalogue.slip_stiffness / catalogue.elements as f64;
        let worst =
            tangent_against_secant(&Physics::Catalogue(catalogue), CatalogueGear::new(catalogue).unwrap(), &path);
        assert!(worst <= k_e * 1.000001, "catalogue: {worst}");
        let micro_slip = MicroSlip::default();
        let worst =
            tangent_against_secant(&Physics::MicroSlip(micro_slip), MicroSlipGear::new(micro_slip).unwrap(), &path);
        // Plus the cubic spring's curvature over the probe's step, 3·k3·θ·1 nrad < 0.05 N·m/rad.
        assert!(worst <= micro_slip.slip_stiffness / micro_slip.elements as f64 + 0.05, "micro-slip: {worst}");
        let preisach = Preisach::default();
        let worst = tangent_against_secant(&Physics::Preisach(preisach), PreisachGear::new(preisach).unwrap(), &path);
        // An element that starts slipping on the probe's step takes up to k_e·(1 + skew).
        let k_e = preisach.slip_stiffness / preisach.elements as f64;
        assert!(worst <= k_e * (1.0 + preisach.skew) + 0.05, "preisach: {worst}");
        assert_eq!(Physics::BoucWen(BoucWen::default()).tangent_along(&path).unwrap(), None);
        assert_eq!(Physics::Model.tangent_along(&path).unwrap(), None);
    }

    #[test]
    fn the_catalogue_gears_default_loop() {
        // At the default amplitude: peak 28.09 N·m, 0.682 N·m (2.43 %) wide at θ = 0.
        let n = 2400;
        let mut gear = CatalogueGear::new(Catalogue::default()).unwrap();
        let path = sine(&mut gear, A, 3, n);
        let (width, peak) = width_at_zero(&path, n);
        println!("catalogue at A = {A} rad: peak {peak:.3} N·m, width {width:.3} N·m ({:.2} %)", 100.0 * width / peak);
        assert!((peak - 28.09).abs() < 0.01, "peak {peak}");
        assert!((width - 0.682).abs() < 0.001, "width {width}");
        // The width is the slip elements' alone: without them the loop closes.
        let mut spring = CatalogueGear::new(Catalogue { slip_stiffness: 0.0, ..Catalogue::default() }).unwrap();
        assert!(width_at_zero(&sine(&mut spring, A, 3, n), n).0.abs() < 1e-9);
    }

    /// Without skew it is the micro-slip gear; with it a loop biased to the + side is fatter
    /// than one biased to the − side, and the sine's loop peaks higher on the + side.
    #[test]
    fn the_preisach_gear_is_micro_slip_gripping_harder_on_one_side() {
        let n = 2400;
        let plain = Preisach { skew: 0.0, ..Preisach::default() };
        let (mut gear, mut slip) =
            (PreisachGear::new(plain).unwrap(), MicroSlipGear::new(MicroSlip::default()).unwrap());
        for (a, b) in sine(&mut gear, A, 2, n).iter().zip(sine(&mut slip, A, 2, n)) {
            assert!((a.1 - b.1).abs() < 1e-9, "{a:?} vs {b:?}");
        }
        let mut gear = PreisachGear::new(Preisach::default()).unwrap();
        let path = sine(&mut gear, A, 3, n);
        let last = &path[path.len() - 1 - n..];
        let (lowest, highest) = last.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| (lo.min(p.1), hi.max(p.1)));
        // A loop of ±0.15·A about a bias, after a ramp from rest: ∮T dθ on its second lap.
        let loop_work = |bias: f64| {
            let mut gear = PreisachGear::new(Preisach::default()).unwrap();
            let mut path: Vec<f64> = (1..=400).map(|k| bias * f64::from(k) / 400.0).collect();
            path.extend((1..=2 * n).map(|k| bias + 0.15 * A * (TAU * k as f64 / n as f64).sin()));
            let torque: Vec<(f64, f64)> = path.iter().map(|&x| (x, gear.step(x))).collect();
            work(&torque[torque.len() - 1 - n..])
        };
        let (plus, minus) = (loop_work(0.6 * A), loop_work(-0.6 * A));
        println!(
            "preisach at A = {A} rad: peaks {highest:.2} / {lowest:.2} N·m; ±0.15·A loops at ±0.6·A: {:.3e} / {:.3e} J ({:.2}×)",
            plus,
            minus,
            plus / minus
        );
        assert!((highest - 28.16).abs() < 0.01 && (lowest + 29.05).abs() < 0.01, "peaks {highest} {lowest}");
        assert!((plus / minus - 4.84).abs() < 0.01, "{plus} vs {minus}");
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = BoucWenGear::new(BoucWen { a: 1.0, ..BoucWen::default() }).unwrap_err();
        assert_eq!(e.to_string(), "bouc-wen parameter a must be in [0, 1), got 1");
        let e = MicroSlipGear::new(MicroSlip { elements: 0, ..MicroSlip::default() }).unwrap_err();
        assert_eq!(e.name, "elements");
        let e = MicroSlip { slip_exponent: -2.0, ..MicroSlip::default() }.validate().unwrap_err();
        assert_eq!(e.name, "slip_exponent");
        assert!(BoucWen { gamma_bw: -1250.0, ..BoucWen::default() }.validate().is_err());
        assert!(BoucWen { n: 0.9, ..BoucWen::default() }.validate().is_err());
        let catalogue = |params: Catalogue| CatalogueGear::new(params).unwrap_err().to_string();
        assert_eq!(
            catalogue(Catalogue { k2: 14_000.0, ..Catalogue::default() }),
            "catalogue parameter k2 must be > k1 N·m/rad (a stiffening gear), got 14000"
        );
        assert_eq!(
            catalogue(Catalogue { k3: 20_000.0, ..Catalogue::default() }),
            "catalogue parameter k3 must be > k2 N·m/rad (a stiffening gear), got 20000"
        );
        assert_eq!(
            catalogue(Catalogue { t2_nm: 7.0, ..Catalogue::default() }),
            "catalogue parameter t2_nm must be > t1_nm N·m, got 7"
        );
        assert_eq!(
            catalogue(Catalogue { positive_scale: 0.0, ..Catalogue::default() }),
            "catalogue parameter positive_scale must be > 0, got 0"
        );
        assert_eq!(
            catalogue(Catalogue { elements: 0, ..Catalogue::default() }),
            "catalogue parameter elements must be 1 to 100000, got 0"
        );
        assert!(catalogue(Catalogue { t1_nm: f64::NAN, ..Catalogue::default() }).contains("t1_nm"));
    }

    #[test]
    fn parameter_files_override_some_fields_and_reject_unknown_ones() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.json");
        std::fs::write(&path, r#"{"elements": 50, "k3": 0}"#).unwrap();
        let read: MicroSlip = read_physics_params(&path).unwrap();
        assert_eq!(read, MicroSlip { elements: 50, k3: 0.0, ..MicroSlip::default() });
        std::fs::write(&path, "{\n  \"k\": 1,\n  \"beta\": 2\n}").unwrap();
        let e = read_physics_params::<BoucWen>(&path).unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(e.to_string().contains("unknown field `beta`"), "{e}");
        std::fs::write(&path, r#"{"positive_scale": 0.8, "t2_nm": 20, "elements": 40}"#).unwrap();
        let read: Catalogue = read_physics_params(&path).unwrap();
        assert_eq!(read, Catalogue { positive_scale: 0.8, t2_nm: 20.0, elements: 40, ..Catalogue::default() });
        std::fs::write(&path, "{\"k1\": 1e4,\n \"k4\": 5e4}").unwrap();
        let e = read_physics_params::<Catalogue>(&path).unwrap_err();
        assert_eq!(e.line, Some(2));
        assert!(e.to_string().contains("unknown field `k4`"), "{e}");
    }
}
