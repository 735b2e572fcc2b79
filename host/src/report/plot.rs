//! SVG pictures of a fit: the torque–deflection loop with the data, the fitted model and the
//! baselines, and the model's residuals below it.
use crate::diagnose::non_masing::NonMasingCheck;
use crate::diagnose::ratcheting::RatchetingCheck;
use crate::diagnose::{Diagnosis, ExtendedFit, Observed};
use crate::fit::baselines::{BranchLine, ThreeSegment};
use crate::input::Branch;
use crate::prepare::FitData;
use model_core::{Direction, Model};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// Why a picture could not be drawn.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    #[error("the model cannot be evaluated for the {picture}: {source}")]
    Model {
        picture: &'static str,
        #[source]
        source: model_core::Error,
    },
    /// plotters' own error, as text: its error type borrows the drawing backend.
    #[error("drawing the {picture} failed: {message}")]
    Draw { picture: &'static str, message: String },
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn drawn(picture: &'static str, result: DrawResult) -> Result<(), PlotError> {
    result.map_err(|e| PlotError::Draw { picture, message: e.to_string() })
}

pub struct LoopPlot<'a> {
    pub title: &'a str,
    pub data: &'a FitData,
    pub branch: &'a [Branch],
    pub model: &'a Model<f64>,
    /// Amplitude at which the model's loop is drawn, rad.
    pub amplitude: f64,
    pub lines: &'a [BranchLine],
    pub three_segment: Option<&'a ThreeSegment>,
}

/// Most points drawn per series; longer recordings are thinned evenly.
const MAX_POINTS: usize = 4000;
const MRAD: f64 = 1e3;

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let pad = 0.05 * (hi - lo).max(1e-12);
    (lo - pad, hi + pad)
}

type LoopChart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart of the pictures' common layout: caption, margins, axes and their labels.
#[allow(clippy::too_many_arguments)]
fn new_chart<'a, 'b>(
    area: &'a DrawingArea<SVGBackend<'b>, plotters::coord::Shift>,
    caption: impl AsRef<str>,
    caption_size: u32,
    x: (f64, f64),
    y: (f64, f64),
    x_desc: impl AsRef<str>,
    y_desc: impl AsRef<str>,
) -> Result<LoopChart<'a, 'b>, Box<dyn std::error::Error>> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption.as_ref(), ("sans-serif", caption_size))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    chart.configure_mesh().x_desc(x_desc.as_ref()).y_desc(y_desc.as_ref()).draw()?;
    Ok(chart)
}

/// The legend of a loop chart, in its upper left corner.
fn draw_legend<'a, 'b: 'a>(chart: &mut LoopChart<'a, 'b>) -> DrawResult {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// Renders the picture as an SVG document.
pub fn loop_svg(plot: &LoopPlot) -> Result<String, PlotError> {
    const PICTURE: &str = "loop picture";
    let residuals =
        crate::fit::residuals(plot.model, plot.data).map_err(|source| PlotError::Model { picture: PICTURE, source })?;
    let mut svg = String::new();
    drawn(PICTURE, draw(plot, &residuals, &mut svg))?;
    Ok(svg)
}

fn draw(plot: &LoopPlot, residuals: &[f64], svg: &mut String) -> DrawResult {
    let data = plot.data;
    let n = data.theta.len();
    let stride = n.div_ceil(MAX_POINTS).max(1);

    let root = SVGBackend::with_string(svg, (960, 820)).into_drawing_area();
    root.fill(&WHITE)?;
    let (upper, lower) = root.split_vertically(560);

    let (x_lo, x_hi) = range(data.theta.iter().map(|t| t * MRAD));
    let (y_lo, y_hi) = range(data.torque.iter().copied());
    let mut chart =
        new_chart(&upper, plot.title, 20, (x_lo, x_hi), (y_lo, y_hi), "deflection θ (mrad)", "torque T (N·m)")?;

    let grey = RGBColor(90, 90, 90);
    // A loop table's few points must stand out; a recording's thousands must not hide the model.
    let (radius, opacity) = if n <= 200 { (4, 0.9) } else { (2, 0.6) };
    chart
        .draw_series(
            (0..n)
                .step_by(stride)
                .map(|i| Circle::new((data.theta[i] * MRAD, data.torque[i]), radius, grey.mix(opacity).filled())),
        )?
        .label("measured")
        .legend(move |(x, y)| Circle::new((x + 10, y), 3, grey.filled()));

    for (direction, color, name) in [
        (Direction::Rising, RGBColor(0, 90, 200), "model, θ rising"),
        (Direction::Falling, RGBColor(210, 60, 0), "model, θ falling"),
    ] {
        let thetas: Vec<f64> = (0..n).filter(|&i| data.direction[i] == direction).map(|i| data.theta[i]).collect();
        if thetas.is_empty() {
            continue;
        }
        let (lo, hi) = thetas.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| (a.min(t), b.max(t)));
        let (lo, hi) = (lo.max(-plot.amplitude), hi.min(plot.amplitude));
        let curve: Vec<(f64, f64)> = (0..=400)
            .filter_map(|k| {
                let theta = lo + (hi - lo) * k as f64 / 400.0;
                plot.model.torque(theta, direction, plot.amplitude).ok().map(|t| (theta * MRAD, t))
            })
            .collect();
        chart
            .draw_series(LineSeries::new(curve, color.stroke_width(2)))?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }

    let line_color = RGBColor(0, 150, 80);
    for (k, line) in plot.lines.iter().enumerate() {
        let thetas: Vec<f64> =
            (0..n).filter(|&i| plot.branch[i].name() == line.branch).map(|i| data.theta[i]).collect();
        let (lo, hi) = thetas.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| (a.min(t), b.max(t)));
        let at = |t: f64| (t * MRAD, line.intercept_nm + line.stiffness_nm_per_rad * t);
        let series = chart.draw_series(LineSeries::new([at(lo), at(hi)], line_color.stroke_width(1)))?;
        if k == 0 {
            series
                .label("one line per branch")
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], line_color));
        }
    }

    if let Some(curve) = plot.three_segment {
        let purple = RGBColor(140, 60, 170);
        let b1 = curve.t1_nm / curve.k1_nm_per_rad;
        let b2 = b1 + (curve.t2_nm - curve.t1_nm) / curve.k2_nm_per_rad;
        let torque = |t: f64| {
            let a = t.abs();
            let v = if a <= b1 {
                curve.k1_nm_per_rad * a
            } else if a <= b2 {
                curve.t1_nm + curve.k2_nm_per_rad * (a - b1)
            } else {
                curve.t2_nm + curve.k3_nm_per_rad * (a - b2)
            };
            v.copysign(t)
        };
        let (lo, hi) = (x_lo / MRAD, x_hi / MRAD);
        let points: Vec<(f64, f64)> =
            (0..=400).map(|k| lo + (hi - lo) * k as f64 / 400.0).map(|t| (t * MRAD, torque(t))).collect();
        chart
            .draw_series(DashedLineSeries::new(points, 6, 4, purple.stroke_width(1)))?
            .label("catalogue three-segment curve")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], purple));
    }
    draw_legend(&mut chart)?;

    let (r_lo, r_hi) = range(residuals.iter().copied().chain([0.0]));
    let r_max = r_lo.abs().max(r_hi.abs());
    let rms = (residuals.iter().map(|r| r * r).sum::<f64>() / n as f64).sqrt();
    let mut below = new_chart(
        &lower,
        format!("residual, measured − model (RMS {rms:.3} N·m)"),
        16,
        (x_lo, x_hi),
        (-r_max, r_max),
        "deflection θ (mrad)",
        "residual (N·m)",
    )?;
    below.draw_series(LineSeries::new([(x_lo, 0.0), (x_hi, 0.0)], BLACK.stroke_width(1)))?;
    below.draw_series((0..n).step_by(stride).map(|i| {
        let color = match data.direction[i] {
            Direction::Rising => RGBColor(0, 90, 200),
            Direction::Falling => RGBColor(210, 60, 0),
        };
        Circle::new((data.theta[i] * MRAD, residuals[i]), radius, color.filled())
    }))?;
    root.present()?;
    Ok(())
}

/// Residuals of the baseline (grey) and of the final model (blue) against deflection, time,
/// deflection rate and input angle: the pictures `diagnose --plot` writes.
pub fn residuals_svg(observed: &Observed, before: &[f64], after: &[f64]) -> Result<String, PlotError> {
    let mut svg = String::new();
    drawn("residual picture", draw_residuals(observed, before, after, &mut svg))?;
    Ok(svg)
}

fn draw_residuals(observed: &Observed, before: &[f64], after: &[f64], svg: &mut String) -> DrawResult {
    let n = before.len();
    let stride = n.div_ceil(MAX_POINTS).max(1);
    let root = SVGBackend::with_string(svg, (1200, 860)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        "residual torque, measured − model: baseline (grey), with the effects found (blue)",
        ("sans-serif", 20),
    )?;
    let panels = root.split_evenly((2, 2));
    let theta: Vec<f64> = observed.data.theta.iter().map(|t| t * MRAD).collect();
    let rate: Option<Vec<f64>> = observed.rate.as_ref().map(|r| r.iter().map(|v| v * MRAD).collect());
    let angle: Option<Vec<f64>> =
        observed.input_angle.as_ref().map(|a| a.iter().map(|v| v.rem_euclid(std::f64::consts::TAU)).collect());
    let axes: [(&str, Option<&[f64]>, &str); 4] = [
        ("against deflection", Some(&theta), "deflection θ (mrad)"),
        ("against time", observed.time.as_deref(), "time (s)"),
        ("against deflection rate", rate.as_deref(), "dθ/dt (mrad/s)"),
        ("against input angle", angle.as_deref(), "input angle mod 2π (rad)"),
    ];
    let (r_lo, r_hi) = range(before.iter().chain(after).copied().chain([0.0]));
    let r_max = r_lo.abs().max(r_hi.abs());
    for (area, (title, xs, label)) in panels.iter().zip(axes) {
        let Some(xs) = xs else {
            area.draw(&Text::new(format!("{title}: not in this data"), (40, 60), ("sans-serif", 16)))?;
            continue;
        };
        let (x_lo, x_hi) = range(xs.iter().copied());
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(60)
            .build_cartesian_2d(x_lo..x_hi, -r_max..r_max)?;
        chart.configure_mesh().x_desc(label).y_desc("residual (N·m)").draw()?;
        let grey = RGBColor(150, 150, 150);
        let blue = RGBColor(0, 90, 200);
        chart
            .draw_series((0..n).step_by(stride).map(|i| Circle::new((xs[i], before[i]), 2, grey.mix(0.5).filled())))?;
        chart.draw_series((0..n).step_by(stride).map(|i| Circle::new((xs[i], after[i]), 2, blue.mix(0.7).filled())))?;
    }
    root.present()?;
    Ok(())
}

/// The loop with the baseline model's and the final model's torque at every sample.
/// With `mirrored`, the measured samples point-mirrored, (−θ, −T), are drawn beside them: a spring
/// whose two sides differ shows as a mirror that leaves the loop.
pub fn diagnosis_loop_svg(
    observed: &Observed,
    diagnosis: &Diagnosis,
    mirrored: bool,
    kinks: &[f64],
) -> Result<String, PlotError> {
    const PICTURE: &str = "diagnosis loop picture";
    let d = &observed.data;
    let stride = d.theta.len().div_ceil(MAX_POINTS).max(1);
    let shown: Vec<usize> = (0..d.theta.len()).step_by(stride).collect();
    let predicted = |fit: &ExtendedFit| -> Result<Vec<f64>, PlotError> {
        let residuals =
            fit.residuals(observed, &shown).map_err(|source| PlotError::Model { picture: PICTURE, source })?;
        Ok(shown.iter().zip(residuals).map(|(&i, r)| d.torque[i] - r).collect())
    };
    let (baseline, final_model) = (predicted(&diagnosis.baseline)?, predicted(&diagnosis.final_fit)?);
    let mut svg = String::new();
    drawn(
        PICTURE,
        draw_diagnosis_loop(observed, diagnosis, &shown, [baseline, final_model], mirrored, kinks, &mut svg),
    )?;
    Ok(svg)
}

fn draw_diagnosis_loop(
    observed: &Observed,
    diagnosis: &Diagnosis,
    all: &[usize],
    [baseline, final_model]: [Vec<f64>; 2],
    mirrored: bool,
    kinks: &[f64],
    svg: &mut String,
) -> DrawResult {
    let d = &observed.data;
    // The loop is nearly a straight line; removing its mean stiffness shows the hysteresis.
    let mean_stiffness = d.theta.iter().zip(&d.torque).map(|(t, q)| t * q).sum::<f64>()
        / d.theta.iter().map(|t| t * t).sum::<f64>().max(f64::MIN_POSITIVE);
    let detrend = |values: Vec<f64>| -> Vec<f64> {
        all.iter().zip(values).map(|(&i, v)| v - mean_stiffness * d.theta[i]).collect()
    };
    let (baseline, final_model) = (detrend(baseline), detrend(final_model));
    let measured = detrend(all.iter().map(|&i| d.torque[i]).collect());
    let root = SVGBackend::with_string(svg, (960, 640)).into_drawing_area();
    root.fill(&WHITE)?;
    let sign = if mirrored { -1.0 } else { 1.0 };
    let (x_lo, x_hi) = range(d.theta.iter().flat_map(|t| [t * MRAD, sign * t * MRAD]));
    let (y_lo, y_hi) = range(measured.iter().flat_map(|&t| [t, sign * t]));
    let effects: Vec<&str> = diagnosis.final_fit.active.iter().map(|e| e.name()).collect();
    let title = if effects.is_empty() {
        "loop, mean stiffness removed: the baseline, no torque effect named".to_string()
    } else {
        format!("loop, mean stiffness removed: baseline vs with {}", effects.join(" + "))
    };
    let mut chart = new_chart(
        &root,
        title,
        20,
        (x_lo, x_hi),
        (y_lo, y_hi),
        "deflection θ (mrad)",
        format!("torque − {mean_stiffness:.4e} N·m/rad · θ (N·m)"),
    )?;
    let grey = RGBColor(120, 120, 120);
    let orange = RGBColor(230, 120, 0);
    let blue = RGBColor(0, 90, 200);
    chart
        .draw_series(
            all.iter().zip(&measured).map(|(&i, &t)| Circle::new((d.theta[i] * MRAD, t), 2, grey.mix(0.5).filled())),
        )?
        .label("measured")
        .legend(move |(x, y)| Circle::new((x + 10, y), 3, grey.filled()));
    if mirrored {
        let green = RGBColor(0, 150, 70);
        chart
            .draw_series(
                all.iter()
                    .zip(&measured)
                    .map(|(&i, &t)| Circle::new((-d.theta[i] * MRAD, -t), 1, green.mix(0.6).filled())),
            )?
            .label("measured, point-mirrored (−θ, −T): off the loop where the spring's sides differ")
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, green.filled()));
    }
    chart
        .draw_series(all.iter().zip(&baseline).map(|(&i, &t)| Circle::new((d.theta[i] * MRAD, t), 1, orange.filled())))?
        .label("baseline model")
        .legend(move |(x, y)| Circle::new((x + 10, y), 3, orange.filled()));
    chart
        .draw_series(
            all.iter().zip(&final_model).map(|(&i, &t)| Circle::new((d.theta[i] * MRAD, t), 1, blue.filled())),
        )?
        .label("with the effects found")
        .legend(move |(x, y)| Circle::new((x + 10, y), 3, blue.filled()));
    if !kinks.is_empty() {
        let red = RGBColor(200, 30, 30);
        chart
            .draw_series(
                kinks.iter().map(|&x| PathElement::new(vec![(x * MRAD, y_lo), (x * MRAD, y_hi)], red.stroke_width(1))),
            )?
            .label("where the spring's stiffness steps (stiffness_kinks)")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], red.stroke_width(2)));
    }
    draw_legend(&mut chart)?;
    root.present()?;
    Ok(())
}

/// A picture of a test that was not run: its title and why, wrapped to the picture's width.
fn draw_untested(root: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>, title: &str, why: &str) -> DrawResult {
    /// Characters a line holds at 14 px on the 960 px picture.
    const LINE: usize = 110;
    root.draw(&Text::new(title.to_string(), (40, 40), ("sans-serif", 20)))?;
    let mut lines: Vec<String> = Vec::new();
    for word in why.split(' ') {
        match lines.last_mut() {
            Some(line) if line.chars().count() + 1 + word.chars().count() <= LINE => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    for (k, line) in lines.iter().enumerate() {
        root.draw(&Text::new(line.clone(), (40, 80 + 22 * k as i32), ("sans-serif", 14)))?;
    }
    root.present()?;
    Ok(())
}

/// Where on the loop Masing's rule misses (`diagnose --plot`'s masing.svg): against the
/// deflection, the measured torque less Masing's form and the free form less Masing's, each
/// fitted on every sample; or why the loops were not tested.
pub fn masing_svg(observed: &Observed, check: &NonMasingCheck) -> Result<String, PlotError> {
    let mut svg = String::new();
    drawn("Masing picture", draw_masing(observed, check, &mut svg))?;
    Ok(svg)
}

fn draw_masing(observed: &Observed, check: &NonMasingCheck, svg: &mut String) -> DrawResult {
    let root = SVGBackend::with_string(svg, (960, 640)).into_drawing_area();
    root.fill(&WHITE)?;
    let found = match check {
        NonMasingCheck::Yes(found) => found,
        NonMasingCheck::No { why } => {
            return draw_untested(&root, "Masing's rule: not tested", why);
        }
    };
    let d = &observed.data;
    let [masing, free] = &found.torque;
    let stride = d.theta.len().div_ceil(MAX_POINTS).max(1);
    let shown: Vec<usize> = (0..d.theta.len().min(masing.len()).min(free.len())).step_by(stride).collect();
    let missed: Vec<f64> = shown.iter().map(|&i| d.torque[i] - masing[i]).collect();
    let cells: Vec<f64> = shown.iter().map(|&i| free[i] - masing[i]).collect();
    let (x_lo, x_hi) = range(shown.iter().map(|&i| d.theta[i] * MRAD));
    let (y_lo, y_hi) = range(missed.iter().chain(&cells).copied().chain([0.0]));
    let verdict = if found.rejected.is_none() { "named" } else { "not named" };
    let mut chart = new_chart(
        &root,
        format!("Masing's rule ({verdict}): what its form leaves, and what the Preisach cells add"),
        20,
        (x_lo, x_hi),
        (y_lo, y_hi),
        "deflection θ (mrad)",
        "torque (N·m)",
    )?;
    let grey = RGBColor(120, 120, 120);
    let blue = RGBColor(0, 90, 200);
    chart
        .draw_series(
            shown.iter().zip(&missed).map(|(&i, &t)| Circle::new((d.theta[i] * MRAD, t), 1, grey.mix(0.5).filled())),
        )?
        .label("measured − Masing's form")
        .legend(move |(x, y)| Circle::new((x + 10, y), 3, grey.filled()));
    chart
        .draw_series(shown.iter().zip(&cells).map(|(&i, &t)| Circle::new((d.theta[i] * MRAD, t), 1, blue.filled())))?
        .label("free form − Masing's form: what Masing's rule cannot follow")
        .legend(move |(x, y)| Circle::new((x + 10, y), 3, blue.filled()));
    draw_legend(&mut chart)?;
    root.present()?;
    Ok(())
}

/// Whether loops run over and over drift (`diagnose --plot`'s drift.svg): the final model's
/// residual at their turning points against the cycle, with the drift fitted; or why they were
/// not tested.
pub fn drift_svg(check: &RatchetingCheck) -> Result<String, PlotError> {
    let mut svg = String::new();
    drawn("drift picture", draw_drift(check, &mut svg))?;
    Ok(svg)
}

fn draw_drift(check: &RatchetingCheck, svg: &mut String) -> DrawResult {
    let root = SVGBackend::with_string(svg, (960, 640)).into_drawing_area();
    root.fill(&WHITE)?;
    let found = match check {
        RatchetingCheck::Yes(found) => found,
        RatchetingCheck::No { why } => {
            return draw_untested(&root, "loops that drift: not tested", why);
        }
    };
    let (x_lo, x_hi) = range(found.points.iter().map(|p| p.0 as f64).chain([0.0]));
    let (y_lo, y_hi) = range(found.points.iter().map(|p| p.1));
    let verdict = if found.rejected.is_none() { "named" } else { "not named" };
    let mut chart = new_chart(
        &root,
        format!(
            "loops run over and over ({verdict}): drift {:+.2e} N·m per cycle at their turning points",
            found.drift_nm_per_cycle
        ),
        20,
        (x_lo, x_hi),
        (y_lo, y_hi),
        "cycle of the repeated loop",
        "final model's residual at the turning point (N·m)",
    )?;
    let blue = RGBColor(0, 90, 200);
    let orange = RGBColor(230, 120, 0);
    for (maximum, colour, label) in [(true, blue, "at the loops' maxima"), (false, orange, "at the loops' minima")] {
        chart
            .draw_series(
                found
                    .points
                    .iter()
                    .filter(|p| p.2 == maximum)
                    .map(|&(k, r, _)| Circle::new((k as f64, r), 3, colour.filled())),
            )?
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
    }
    draw_legend(&mut chart)?;
    root.present()?;
    Ok(())
}

/// A model run along a recording: its torque at every sample.
pub struct MotionSeries<'a> {
    pub label: &'a str,
    pub torque: &'a [f64],
}

/// The measured loop of a motion with models run along it (each a line through its samples in
/// time order, so inner loops show), with the mean stiffness removed so that the hysteresis
/// is visible, and every model's residual against time below.
pub fn motion_svg(
    title: &str,
    time: &[f64],
    theta: &[f64],
    measured: &[f64],
    models: &[MotionSeries],
) -> Result<String, PlotError> {
    let mut svg = String::new();
    drawn("motion picture", draw_motion(title, time, theta, measured, models, &mut svg))?;
    Ok(svg)
}

fn draw_motion(
    title: &str,
    time: &[f64],
    theta: &[f64],
    measured: &[f64],
    models: &[MotionSeries],
    svg: &mut String,
) -> DrawResult {
    const COLORS: [RGBColor; 3] = [RGBColor(0, 90, 200), RGBColor(210, 60, 0), RGBColor(0, 150, 80)];
    // Fewer points than the loop picture: every model is a line as well.
    const POINTS: usize = 2000;
    let n = theta.len();
    let stride = n.div_ceil(POINTS).max(1);
    let shown: Vec<usize> = (0..n).step_by(stride).collect();
    let stiffness = theta.iter().zip(measured).map(|(t, q)| t * q).sum::<f64>()
        / theta.iter().map(|t| t * t).sum::<f64>().max(f64::MIN_POSITIVE);
    let detrend = |values: &[f64]| -> Vec<(f64, f64)> {
        shown.iter().map(|&i| (theta[i] * MRAD, values[i] - stiffness * theta[i])).collect()
    };
    let root = SVGBackend::with_string(svg, (960, 820)).into_drawing_area();
    root.fill(&WHITE)?;
    let (upper, lower) = root.split_vertically(560);
    let measured_points = detrend(measured);
    let (x_lo, x_hi) = range(measured_points.iter().map(|p| p.0));
    let (y_lo, y_hi) = range(measured_points.iter().map(|p| p.1));
    let mut chart = new_chart(
        &upper,
        title,
        20,
        (x_lo, x_hi),
        (y_lo, y_hi),
        "deflection θ (mrad)",
        format!("T − {stiffness:.0} N·m/rad · θ (N·m)"),
    )?;
    let grey = RGBColor(90, 90, 90);
    chart
        .draw_series(measured_points.iter().map(|&p| Circle::new(p, 2, grey.mix(0.4).filled())))?
        .label("measured")
        .legend(move |(x, y)| Circle::new((x + 10, y), 3, grey.filled()));
    for (model, color) in models.iter().zip(COLORS.iter().cycle()) {
        let color = *color;
        chart
            .draw_series(LineSeries::new(detrend(model.torque), color.stroke_width(1)))?
            .label(model.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    draw_legend(&mut chart)?;

    let residuals: Vec<Vec<f64>> =
        models.iter().map(|m| measured.iter().zip(m.torque).map(|(q, p)| q - p).collect()).collect();
    let (r_lo, r_hi) = range(residuals.iter().flatten().copied().chain([0.0]));
    let r_max = r_lo.abs().max(r_hi.abs());
    let (t_lo, t_hi) = range(time.iter().copied());
    let mut below = new_chart(
        &lower,
        "residual, measured − model",
        16,
        (t_lo, t_hi),
        (-r_max, r_max),
        "time (s)",
        "residual (N·m)",
    )?;
    below.draw_series(LineSeries::new([(t_lo, 0.0), (t_hi, 0.0)], BLACK.stroke_width(1)))?;
    for ((model, residual), color) in models.iter().zip(&residuals).zip(COLORS.iter().cycle()) {
        let color = *color;
        let rms = (residual.iter().map(|r| r * r).sum::<f64>() / n.max(1) as f64).sqrt();
        below
            .draw_series(shown.iter().map(|&i| Circle::new((time[i], residual[i]), 1, color.filled())))?
            .label(format!("{} (RMS {rms:.3} N·m)", model.label))
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, color.filled()));
    }
    below
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// One controller mode's run for [`control_svg`]: per control tick, the time, the true torque
/// error against the reference, and the true deflection and torque.
pub struct ControlSeries<'a> {
    pub label: &'a str,
    /// s.
    pub time: &'a [f64],
    /// T_true − T_ref, N·m.
    pub error: &'a [f64],
    /// rad.
    pub deflection: &'a [f64],
    /// N·m.
    pub torque: &'a [f64],
}

/// The torque error against time for each mode (above), and the torque loop each mode drove
/// the gear through, T against θ (below).
pub fn control_svg(title: &str, runs: &[ControlSeries]) -> Result<String, PlotError> {
    let mut svg = String::new();
    drawn("control picture", draw_control(title, runs, &mut svg))?;
    Ok(svg)
}

fn draw_control(title: &str, runs: &[ControlSeries], svg: &mut String) -> DrawResult {
    const COLORS: [RGBColor; 3] = [RGBColor(120, 120, 120), RGBColor(210, 60, 0), RGBColor(0, 90, 200)];
    const POINTS: usize = 3000;
    let root = SVGBackend::with_string(svg, (960, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let (upper, lower) = root.split_vertically(450);
    let thinned =
        |values: &[f64]| -> Vec<usize> { (0..values.len()).step_by(values.len().div_ceil(POINTS).max(1)).collect() };
    let (t_lo, t_hi) = range(runs.iter().flat_map(|r| r.time.iter().copied()));
    let (e_lo, e_hi) = range(runs.iter().flat_map(|r| r.error.iter().copied()).chain([0.0]));
    let mut chart = new_chart(&upper, title, 20, (t_lo, t_hi), (e_lo, e_hi), "time (s)", "T_true − T_ref (N·m)")?;
    for (run, color) in runs.iter().zip(COLORS.iter().cycle()) {
        let color = *color;
        let shown = thinned(run.time);
        chart
            .draw_series(LineSeries::new(shown.iter().map(|&i| (run.time[i], run.error[i])), color.stroke_width(1)))?
            .label(run.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    draw_legend(&mut chart)?;
    let (x_lo, x_hi) = range(runs.iter().flat_map(|r| r.deflection.iter().map(|d| d * MRAD)));
    let (y_lo, y_hi) = range(runs.iter().flat_map(|r| r.torque.iter().copied()));
    let mut below = new_chart(
        &lower,
        "the torque loop: true torque against deflection",
        16,
        (x_lo, x_hi),
        (y_lo, y_hi),
        "deflection θ (mrad)",
        "T_true (N·m)",
    )?;
    for (run, color) in runs.iter().zip(COLORS.iter().cycle()) {
        let color = *color;
        let shown = thinned(run.deflection);
        below
            .draw_series(LineSeries::new(
                shown.iter().map(|&i| (run.deflection[i] * MRAD, run.torque[i])),
                color.stroke_width(1),
            ))?
            .label(run.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    draw_legend(&mut below)?;
    root.present()?;
    Ok(())
}
