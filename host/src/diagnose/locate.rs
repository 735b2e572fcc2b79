//! Where the baseline's residuals concentrate, in numbers and words.
use super::observed::Observed;
use model_core::Direction;
use serde::Serialize;

/// One pattern in the baseline residuals, in numbers and words.
#[derive(Clone, Debug, Serialize)]
pub struct Observation {
    pub pattern: &'static str,
    pub value: f64,
    pub unit: &'static str,
    pub words: String,
}

/// Where the baseline residuals concentrate, over the scored samples ([`Observed::scored`]).
pub fn locate(observed: &Observed, residuals: &[f64]) -> Vec<Observation> {
    let d = &observed.data;
    let n = residuals.len();
    let from = observed.scored().start.min(n);
    let rms_of = |keep: &dyn Fn(usize) -> bool| {
        let (sum, count) =
            (from..n).filter(|&i| keep(i)).fold((0.0, 0usize), |(s, c), i| (s + residuals[i] * residuals[i], c + 1));
        if count == 0 {
            f64::NAN
        } else {
            (sum / count as f64).sqrt()
        }
    };
    let mut out = Vec::new();

    let near = |i: usize| d.theta[i].abs() >= 0.9 * d.amplitude[i];
    let (near_rms, far_rms) = (rms_of(&near), rms_of(&|i| !near(i)));
    if near_rms.is_finite() && far_rms.is_finite() {
        out.push(Observation {
            pattern: "turning_points",
            value: near_rms / far_rms,
            unit: "ratio",
            words: format!(
                "near the turning points (|θ| ≥ 0.9·A) the residual RMS is {} N·m, {}× the {} N·m elsewhere",
                torque(near_rms),
                ratio(near_rms / far_rms),
                torque(far_rms)
            ),
        });
    }

    let peak = d.torque.iter().map(|t| t.abs()).fold(0.0, f64::max);
    let low = |i: usize| d.torque[i].abs() < 0.1 * peak;
    let (low_rms, high_rms) = (rms_of(&low), rms_of(&|i| !low(i)));
    if low_rms.is_finite() && high_rms.is_finite() {
        out.push(Observation {
            pattern: "zero_torque",
            value: low_rms / high_rms,
            unit: "ratio",
            words: format!(
                "around zero torque (|T| < 10 % of the peak) the residual RMS is {} N·m, {}× the {} N·m at load",
                torque(low_rms),
                ratio(low_rms / high_rms),
                torque(high_rms)
            ),
        });
    }

    let mean_of = |keep: &dyn Fn(usize) -> bool| {
        let (sum, count) = (from..n).filter(|&i| keep(i)).fold((0.0, 0usize), |(s, c), i| (s + residuals[i], c + 1));
        if count == 0 {
            0.0
        } else {
            sum / count as f64
        }
    };
    let gap = mean_of(&|i| d.direction[i] == Direction::Rising) - mean_of(&|i| d.direction[i] == Direction::Falling);
    out.push(Observation {
        pattern: "direction",
        value: gap,
        unit: "N·m",
        words: format!(
            "by direction: the residual averages {}{} N·m more while the deflection rises than while it falls",
            if gap >= 0.0 { "+" } else { "" },
            torque(gap)
        ),
    });

    if let Some(rate) = &observed.rate {
        let slope = regression_slope(&rate[from..], &residuals[from..]);
        let peak_rate = rate[from..].iter().map(|r| r.abs()).fold(0.0, f64::max);
        out.push(Observation {
            pattern: "rate",
            value: slope,
            unit: "N·m·s/rad",
            words: format!(
                "with rate: the residual {} by {:.4e} N·m per rad/s of deflection rate ({} N·m at the fastest {peak_rate:.3e} rad/s)",
                if slope >= 0.0 { "grows" } else { "falls" },
                slope.abs(),
                torque(slope * peak_rate)
            ),
        });
    }

    if let Some(angle) = &observed.input_angle {
        let (order, amplitude) = (1..=6)
            .map(|k| {
                let (mut c, mut s, mut cc, mut ss) = (0.0, 0.0, 0.0, 0.0);
                for i in from..n {
                    let (cos, sin) = ((k as f64 * angle[i]).cos(), (k as f64 * angle[i]).sin());
                    c += cos * residuals[i];
                    s += sin * residuals[i];
                    cc += cos * cos;
                    ss += sin * sin;
                }
                (k, (c / cc).hypot(s / ss))
            })
            .fold((0, 0.0), |best, x| if x.1 > best.1 { x } else { best });
        out.push(Observation {
            pattern: "input_angle",
            value: amplitude,
            unit: "N·m",
            words: format!(
                "periodic in the input angle: strongest at {order} cycle{} per input revolution, {} N·m",
                if order == 1 { "" } else { "s" },
                torque(amplitude)
            ),
        });
    }

    if let Some(time) = &observed.time {
        let time = &time[from..];
        let slope = regression_slope(time, &residuals[from..]);
        let span = time.last().copied().unwrap_or(0.0) - time.first().copied().unwrap_or(0.0);
        out.push(Observation {
            pattern: "time",
            value: slope,
            unit: "N·m/s",
            words: format!(
                "over time: the residual drifts by {} N·m over the {span:.1} s scored",
                torque(slope * span)
            ),
        });
    }
    if let Some(warming) = &observed.warming {
        let load: Vec<f64> = (from..n).map(|i| warming[i] * d.theta[i]).collect();
        let slope = regression_slope(&load, &residuals[from..]);
        out.push(Observation {
            pattern: "temperature",
            value: slope,
            unit: "N·m/(rad·K)",
            words: format!("with temperature: the loop's slope changes by {slope:.4e} N·m/rad per kelvin of warming"),
        });
    }
    out
}

/// A ratio for the report: one decimal, two significant digits below 0.1 (not 0.0×).
fn ratio(value: f64) -> String {
    if value >= 0.095 {
        format!("{value:.1}")
    } else {
        format!("{value:.2}")
    }
}

/// A torque in N·m for the report: four decimals, or four significant digits when smaller
/// (a noise-free recording's residuals are micro-newton-metres, not 0.0000).
pub(super) fn torque(value: f64) -> String {
    if value == 0.0 || value.abs() >= 0.01 {
        format!("{value:.4}")
    } else {
        format!("{value:.3e}")
    }
}

fn regression_slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
    }
    if sxx > 0.0 {
        sxy / sxx
    } else {
        0.0
    }
}
