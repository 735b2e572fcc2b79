//! A finding of form: whether the spring's stiffness steps at some deflections (`stiffness_kinks`),
//! as a catalogue's three-segment curve does at T1 and T2, where a smooth curve would not.
//!
//! The micro-slip form, with the accepted torque effects beside it (and a torque offset where
//! none was accepted), is scanned for steps of stiffness beside its knot rule's spring
//! ([`scan_kinks`]): a kink is a step at one deflection, on every branch alike. A step is named
//! when it is a kink, not curvature (it fits better sharp than spread over [`WIDE`] times the
//! scan's resolution), not a misfit of the hysteresis (the same on both branches), not a wiggle
//! (the spring's stiffness across it changes the way it steps), and passes the tests an effect
//! must pass: it dropped the information criterion by more than [`MIN_BIC_DROP`] when added and
//! steps by at least [`MIN_STEP`] of the loop's secant stiffness; together the kinks explain at
//! least [`MIN_EXPLAINED`] of the rule's weighted residual; the form with them leaves at most
//! [`STRUCTURE_FACTOR`] times the noise (a wrong hysteresis form leaves structure that a step may
//! stand in for); and the two independent parts of the recording, each fitted alone, show every
//! step with the same sign and magnitudes within [`MAX_HALF_SPREAD`] of their mean.
//!
//! Where: x = θ − θ0 (from the zero read at rest, or the encoders' own where there is none: a
//! kink's place moves with the zero, its test does not), to the scan's resolution, and the mean
//! measured torque there. Its magnitude is the step of stiffness outwards, which is identified;
//! the stiffness on each side is the spring's share of the loop's, which is not (slip elements
//! wider than the motion stand in for a spring), so it is reported beside it in the JSON only.
use super::effects::{backlash, Effect};
use super::extended::{kinematic_at, ExtendedFit};
use super::form::{torque_column, STRUCTURE_FACTOR};
use super::observed::Observed;
use super::{share_below, MAX_HALF_SPREAD, MIN_BIC_DROP, MIN_EXPLAINED};
use crate::fit::motion::{scan_kinks, Kink, KINK_PARAMETERS, WIDE};
use crate::prepare::reversals;
use serde::Serialize;

/// The smallest step named, over the loop's secant stiffness (the torque's range over the
/// deflection's): a smaller one changes a feed-forward by less than a gear's spread.
pub const MIN_STEP: f64 = 0.1;

/// The spring's kinks, measured and tested.
#[derive(Clone, Debug, Serialize)]
pub struct StiffnessKinks {
    /// The kinks found, in the order the scan added them.
    pub kinks: Vec<Kink>,
    /// The mean measured torque within half the scan's resolution of each kink, N·m.
    pub torque_nm: Vec<f64>,
    /// The loop's secant stiffness, the torque's range over the deflection's, N·m/rad: what the
    /// steps are measured against.
    pub secant_nm_per_rad: f64,
    /// How finely the kinks are placed: the scan's grid step, or 10σθ where wider, rad.
    pub resolution_rad: f64,
    /// The best further kink the criterion refused.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refused: Option<Kink>,
    /// Samples the scan fitted (a subsample spread over the recording).
    pub samples: usize,
    /// Drop of the information criterion from the knot rule's spring to the one with the kinks.
    pub delta_bic: f64,
    /// Share of the rule's weighted residual the kinks explain.
    pub explained: f64,
    /// The form with the kinks: its weighted residual against the noise's (1: the noise alone).
    pub form_to_noise: f64,
    /// Each kink's step (N·m/rad) fitted on each independent part alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub halves: Option<[Vec<f64>; 2]>,
    /// Why they are not named; `None` when they are.
    pub rejected: Option<String>,
}

/// Whether the kinks were tested, and what they showed.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "tested", rename_all = "snake_case")]
pub enum KinksCheck {
    /// Tested: named when `rejected` is `None`.
    Yes(Box<StiffnessKinks>),
    /// Not tested, and why.
    No { why: String },
}

impl KinksCheck {
    /// The kinks, when they were tested and named.
    pub fn named(&self) -> Option<&StiffnessKinks> {
        match self {
            KinksCheck::Yes(kinks) if kinks.rejected.is_none() => Some(kinks),
            _ => None,
        }
    }
}

/// Tests the spring of `observed` for kinks, the final model's accepted effects beside the form,
/// with the search's `weights` (1/σ² of each sample's noise).
pub fn check(observed: &Observed, weights: &[f64], final_fit: &ExtendedFit) -> KinksCheck {
    let active = &final_fit.active;
    let untested = |why: String| KinksCheck::No { why };
    let Some(noise) = observed.noise else {
        return untested("the data give no noise estimate to judge it by".to_string());
    };
    let data = &observed.data;
    // The deflection as the final model sees it, moved by the deflection effects it accepted: a
    // backlash's dead band is a step of stiffness at ±w/2, which the backlash already names
    // (`simulate --effect backlash=0.0003` on the micro-slip gear: steps at ±0.155 mrad beside a
    // backlash of 0.307 mrad).
    let moved: Option<Vec<f64>> = active.iter().any(|e| e.moves_deflection()).then(|| {
        let state = &final_fit.state;
        (0..data.theta.len())
            .map(|i| backlash(data.theta[i] + kinematic_at(state, observed, i), state.backlash))
            .collect()
    });
    let theta: &[f64] = moved.as_deref().unwrap_or(&data.theta);
    let (lo, hi) = theta.iter().fold((0.0f64, 0.0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    // A kink needs a stretch of stiffness on each of its sides, as the knot rule asks of a segment.
    let needed = 2.0 * crate::fit::spring::KNOT_SPACING_IN_NOISE * noise.deflection_rad;
    if !((-lo).max(hi) > needed) {
        return untested(format!(
            "the motion reaches {:.3} mrad from the zero at most, not beyond the {:.3} mrad (two segments of {} \
             times the deflection's noise) a step of stiffness needs: record a larger amplitude",
            1e3 * (-lo).max(hi),
            1e3 * needed,
            crate::fit::spring::KNOT_SPACING_IN_NOISE
        ));
    }
    let (t_lo, t_hi) = data.torque.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| (a.min(t), b.max(t)));
    let secant = (t_hi - t_lo) / (hi - lo);
    if !(secant > 0.0) {
        return untested("the torque does not rise with the deflection: no stiffness to measure a step by".to_string());
    }
    // A torque offset beside them always: the form cannot tell one from its misfit without the
    // torque read at rest, and a step stood in for an offset the search had left out (a genetic
    // gear fitted to micro-slip data, 18-bit encoders: +9060 N·m/rad at +0.14 mrad, 9 % explained;
    // `host/tests/diagnose_cli.rs`).
    let columns: Vec<Vec<f64>> = active.iter().filter_map(|&effect| torque_column(observed, effect)).collect();
    let extra: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
    let scan = match scan_kinks(
        theta,
        &data.torque,
        &reversals(theta),
        noise,
        weights,
        &extra,
        !active.contains(&Effect::TorqueOffset),
        &observed.parts,
        MIN_BIC_DROP,
        MIN_STEP * secant,
    ) {
        Ok(scan) => scan,
        Err(_) => return untested("the micro-slip form cannot be fitted to this data".to_string()),
    };
    let n = scan.samples as f64;
    let [rule, kinked] = scan.chi2;
    let variance = kinked / (n - scan.parameters[1] as f64).max(1.0);
    let delta_bic = (rule - kinked) / variance - (KINK_PARAMETERS * scan.kinks.len()) as f64 * n.ln();
    let explained = if rule > 0.0 { (rule - kinked) / rule } else { 0.0 };
    // A part that does not run through a kink, a resolution either side, does not measure its
    // step (a one-cycle run's parts are its legs).
    let reach = scan.resolution_rad;
    let runs_through = |part: &Vec<usize>, kink: &Kink| {
        let along = |i: &usize| theta[*i] * kink.at_rad.signum();
        part.iter().any(|i| along(i) > kink.at_rad.abs() + reach)
            && part.iter().any(|i| along(i) < kink.at_rad.abs() - reach)
    };
    let not_run_through = scan.kinks.iter().find(|kink| !observed.parts.iter().all(|part| runs_through(part, kink)));
    let halves = <[Option<Vec<f64>>; 2]>::try_from(scan.parts.clone())
        .ok()
        .and_then(|[a, b]| Some([a?, b?]))
        .filter(|_| not_run_through.is_none());
    // A step that fits as well sharp as spread out, or whose spread twin does not fit in the
    // range, is what this data cannot tell from a gradual change: said so, not refused (which
    // read as "no kink").
    let best_step = scan.refused.as_ref().filter(|best| scan.kinks.is_empty() && best.delta_bic > MIN_BIC_DROP);
    if let Some(best) = best_step {
        let step = format!(
            "the best step, {:+.0} N·m/rad at {:+.3} mrad, drops the information criterion by {:.1}",
            best.step_nm_per_rad(),
            1e3 * best.at_rad,
            best.delta_bic
        );
        let wide = 1e3 * WIDE * scan.resolution_rad;
        match best.sharpness {
            None => {
                return untested(format!(
                    "{step}, but the same change spread over {WIDE} times the scan's resolution ({wide:.3} mrad) does \
                     not fit inside the range, so it cannot be told from a gradual change of stiffness"
                ))
            }
            Some(sharpness) if sharpness.abs() <= MIN_BIC_DROP => {
                let (way, by) = if sharpness >= 0.0 { ("lower", sharpness) } else { ("higher", -sharpness) };
                return untested(format!(
                    "{step}, and fits as well spread over {wide:.3} mrad (sharp, its χ² is {way} by {by:.1}, within \
                     {MIN_BIC_DROP}), so it cannot be told from a gradual change of stiffness"
                ));
            }
            Some(_) => {}
        }
    }
    let rejected = if scan.kinks.is_empty() {
        Some(match &scan.refused {
            Some(best) if best.delta_bic > MIN_BIC_DROP => {
                let step = format!(
                    "the best step, {:+.0} N·m/rad at {:+.3} mrad, drops the information criterion by {:.1}",
                    best.step_nm_per_rad(),
                    1e3 * best.at_rad,
                    best.delta_bic
                );
                match (best.sharpness, best.branches) {
                    (Some(sharpness), _) if sharpness < -MIN_BIC_DROP => format!(
                        "{step} but fits worse sharp than spread over {:.3} mrad (χ² higher by {:.1}, more than \
                         {MIN_BIC_DROP}): a gradual change of stiffness, not a kink",
                        1e3 * WIDE * scan.resolution_rad,
                        -sharpness
                    ),
                    (_, None) => format!("{step}, but its two branches cannot be fitted apart to compare"),
                    (_, Some(branches)) => format!(
                        "{step} but differently on the rising and the falling branches (a step of its own on each \
                         lowers χ² by {branches:.1}, more than {MIN_BIC_DROP}): a spring's step is the same on both, \
                         a misfit of the hysteresis or of the encoders' steps is not"
                    ),
                }
            }
            Some(best) => format!(
                "no step of the stiffness drops the information criterion by more than {MIN_BIC_DROP} (the best, \
                 {:+.0} N·m/rad at {:+.3} mrad: {:.1})",
                best.step_nm_per_rad(),
                1e3 * best.at_rad,
                best.delta_bic
            ),
            None => format!(
                "no step of the stiffness by {:.0} % of the loop's secant stiffness ({secant:.0} N·m/rad) or more \
                 fits the data",
                100.0 * MIN_STEP
            ),
        })
    } else if !(variance <= STRUCTURE_FACTOR * STRUCTURE_FACTOR) {
        Some(format!(
            "with them the micro-slip form still leaves {:.1}× the noise, so a step may stand in for its misfit of \
             the loop's shape",
            variance.sqrt()
        ))
    } else if !(explained >= MIN_EXPLAINED) {
        Some(format!(
            "they explain {} % of the smooth spring's residual, less than {:.0} %",
            share_below(explained, MIN_EXPLAINED),
            100.0 * MIN_EXPLAINED
        ))
    } else {
        match (&halves, not_run_through) {
            (_, Some(kink)) => Some(format!(
                "its two parts (alternate cycles) do not each run through the step at {:+.3} mrad, so whether they \
                 agree cannot be checked: record several cycles",
                1e3 * kink.at_rad
            )),
            (None, None) => Some("the two parts of the recording cannot each be fitted alone".to_string()),
            (Some([a, b]), None) => scan.kinks.iter().zip(a.iter().zip(b)).find_map(|(kink, (&p, &q))| {
                let whole = kink.step_nm_per_rad();
                let disagree = p.signum() != whole.signum()
                    || q.signum() != whole.signum()
                    || (p - q).abs() > MAX_HALF_SPREAD * (0.5 * (p + q)).abs();
                disagree.then(|| {
                    format!(
                        "the two parts disagree on the step at {:+.3} mrad: {p:+.0} and {q:+.0} N·m/rad",
                        1e3 * kink.at_rad
                    )
                })
            }),
        }
    };
    let torque_nm = scan
        .kinks
        .iter()
        .map(|kink| {
            let (sum, count) = theta
                .iter()
                .zip(&data.torque)
                .filter(|(&x, _)| (x - kink.at_rad).abs() <= 0.5 * reach)
                .fold((0.0, 0usize), |(sum, count), (_, &t)| (sum + t, count + 1));
            sum / count.max(1) as f64
        })
        .collect();
    KinksCheck::Yes(Box::new(StiffnessKinks {
        kinks: scan.kinks,
        torque_nm,
        secant_nm_per_rad: secant,
        resolution_rad: scan.resolution_rad,
        refused: scan.refused,
        samples: scan.samples,
        delta_bic,
        explained,
        form_to_noise: variance.sqrt(),
        halves,
        rejected,
    }))
}
