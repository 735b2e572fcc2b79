//! The plan of an identification experiment as a file (JSON), and the plan a user gets without
//! one: what `swg-host simulate --motion plan` plays. The plan itself, its checks and its player
//! are the protocol's (`swg_protocol::plan`), the ones the joint's experiment will run.
//!
//! ```json
//! {
//!   "channel": "deflection",
//!   "limits": { "torque_nm": 60, "deflection_rad": 0.0015 },
//!   "segments": [
//!     { "sine": { "amplitude": 0.0005, "frequency_hz": 0.5, "cycles": 3 } },
//!     { "ramp": { "to": 0.0006, "seconds": 2 } },
//!     { "hold": { "seconds": 4, "dither_amplitude": 0.00002, "dither_hz": 5 } },
//!     { "ramp": { "to": 0, "seconds": 2 } }
//!   ]
//! }
//! ```
use super::table::read_text;
use super::InputError;
use serde::Deserialize;
use serde_json::value::RawValue;
use std::path::Path;
use swg_protocol::plan::{Channel, Limits, Plan, PlanError, Segment, SegmentFault, PLAN_SEGMENTS};

/// A plan as its file gives it: checked at a tick rate by [`PlanSpec::at_rate`], since what a
/// segment may do (its frequency) depends on the rate it is played at.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanSpec {
    pub channel: Channel,
    pub limits: Limits,
    pub segments: Vec<Segment>,
    /// Where each segment starts in its file (line, column), for errors; none for a plan made
    /// here.
    positions: Vec<(usize, usize)>,
    /// Where the limits and the segments' list start in the file, for the errors of the plan as
    /// a whole.
    limits_at: Option<(usize, usize)>,
    segments_at: Option<(usize, usize)>,
    /// The file, for errors.
    source: String,
}

/// A plan file's fields: the segments kept as written, to point at the one an error is in.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlanFile<'a> {
    channel: Channel,
    #[serde(borrow)]
    limits: &'a RawValue,
    #[serde(borrow)]
    segments: &'a RawValue,
}

/// Line and column (1-based, in characters) of byte `offset` of `text`.
fn position(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset).unwrap_or(text);
    (before.matches('\n').count() + 1, before.rsplit('\n').next().unwrap_or_default().chars().count() + 1)
}

/// Reads a plan file: JSON with `channel` (`deflection` or `torque`), `limits` {torque_nm,
/// deflection_rad} and `segments` (`ramp` {to, seconds}, `sine` {amplitude, frequency_hz,
/// cycles}, `hold` {seconds, dither_amplitude, dither_hz}); errors name file:line:column.
pub fn read_plan(path: &Path) -> Result<PlanSpec, InputError> {
    parse_plan(path, &read_text(path)?)
}

/// [`read_plan`] of a text already read.
pub fn parse_plan(path: &Path, text: &str) -> Result<PlanSpec, InputError> {
    let at = |line: usize, column: usize, message: String| {
        InputError::at_line(path, line as u64, format!("column {column}: {message}"))
    };
    // serde_json's message without its own " at line L column C": the position leads instead.
    let syntax = |e: serde_json::Error, (line, column): (usize, usize)| {
        // serde's Rust type names in words: the file holds numbers, not f32s.
        let message = e
            .to_string()
            .split(" at line ")
            .next()
            .unwrap_or_default()
            .replace("expected f32", "expected a number")
            .replace("expected u16", "expected a whole number from 0 to 65535");
        let (line, column) = if e.line() <= 1 {
            (line, column + e.column().saturating_sub(1))
        } else {
            (line + e.line() - 1, e.column())
        };
        at(line, column, format!("{message} (a plan: {{\"channel\", \"limits\", \"segments\"}}, see README)"))
    };
    let body = text.trim_start_matches('\u{feff}');
    // A recording or a table given for the plan: say what was expected, not serde's "expected
    // ident".
    let blank = body.len() - body.trim_start().len();
    if !body[blank..].starts_with('{') {
        let (line, column) = position(body, blank);
        let first: String = body[blank..].lines().next().unwrap_or_default().chars().take(40).collect();
        let found = if first.is_empty() { "nothing".to_owned() } else { format!("{first:?}") };
        return Err(at(
            line,
            column,
            format!("expected a plan, a JSON object {{\"channel\", \"limits\", \"segments\"}}; found {found}"),
        ));
    }
    let file: PlanFile = serde_json::from_str(body).map_err(|e| syntax(e, (1, 1)))?;
    // Where a part of the file starts: the raw values are slices of `body`.
    let start_of = |raw: &RawValue| position(body, raw.get().as_ptr() as usize - body.as_ptr() as usize);
    let limits: Limits = serde_json::from_str(file.limits.get()).map_err(|e| syntax(e, start_of(file.limits)))?;
    let raw_segments: Vec<&RawValue> =
        serde_json::from_str(file.segments.get()).map_err(|e| syntax(e, start_of(file.segments)))?;
    let segments_at = start_of(file.segments);
    if raw_segments.len() > PLAN_SEGMENTS {
        let (line, column) = segments_at;
        return Err(at(line, column, PlanError::TooManySegments(raw_segments.len()).to_string()));
    }
    let mut segments = Vec::with_capacity(raw_segments.len());
    let mut positions = Vec::with_capacity(raw_segments.len());
    for raw in raw_segments {
        let start = start_of(raw);
        segments.push(serde_json::from_str::<Segment>(raw.get()).map_err(|e| syntax(e, start))?);
        positions.push(start);
    }
    Ok(PlanSpec {
        channel: file.channel,
        limits,
        segments,
        positions,
        limits_at: Some(start_of(file.limits)),
        segments_at: Some(segments_at),
        source: path.display().to_string(),
    })
}

impl PlanSpec {
    /// The plan played at `rate_hz`, checked (`Plan::new`); an error names the place in its file
    /// of the segment or the part it is about.
    pub fn at_rate(&self, rate_hz: f64) -> Result<Plan, InputError> {
        Plan::new(self.channel, self.limits, rate_hz as f32, &self.segments).map_err(|error| {
            let (place, name) = match error {
                PlanError::Segment { index, .. } | PlanError::BeyondLimit { index, .. } => {
                    let name = self.segments.get(index).map_or("", Segment::name);
                    (self.positions.get(index).copied(), name)
                }
                PlanError::Limits => (self.limits_at, ""),
                PlanError::Empty | PlanError::TooManySegments(_) | PlanError::TooLong { .. } => (self.segments_at, ""),
                _ => (None, ""),
            };
            let mut message = error.to_string();
            if !name.is_empty() {
                message += &format!(" ({name})");
            }
            if matches!(error, PlanError::Segment { fault: SegmentFault::Frequency { .. }, .. }) {
                message += &format!("; played at {rate_hz} samples a second");
                if self.positions.is_empty() {
                    message += ": the default plan plays at 4·f and dithers at 10·f (f = the first --frequency); lower it or raise --rate";
                }
            }
            let path = Path::new(&self.source);
            match place {
                Some((line, column)) => InputError::at_line(path, line as u64, format!("column {column}: {message}")),
                None => InputError::file(path, message),
            }
        })
    }

    /// Where the plan comes from: its file, or "the default plan".
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The channel and segments in one line, for a recording's metadata: "deflection (rad): sine
    /// 0.0005 at 0.5 Hz × 3; ramp to 0.0006 in 2 s; hold 4 s, dither 0.00002 at 5 Hz".
    pub fn describe(&self) -> String {
        let segments: Vec<String> = self
            .segments
            .iter()
            .map(|segment| match *segment {
                Segment::Ramp { to, seconds } => format!("ramp to {to} in {seconds} s"),
                Segment::Sine { amplitude, frequency_hz, cycles } => {
                    format!("sine {amplitude} at {frequency_hz} Hz × {cycles}")
                }
                Segment::Hold { seconds, dither_amplitude, dither_hz } => {
                    format!("hold {seconds} s, dither {dither_amplitude} at {dither_hz} Hz")
                }
            })
            .collect();
        let channel = match self.channel {
            Channel::Deflection => "deflection",
            Channel::Torque => "torque",
        };
        format!("{channel} ({}): {}", self.channel.unit(), segments.join("; "))
    }

    /// What fit and diagnose need of a gear with loops of amplitude `amplitude` (its channel's
    /// unit): a rest of one slow period first (the zero and the torque sensor's offset are read
    /// there), then three amplitudes (¼, ½ and all of it), each at a slow rate `slow_hz` and four
    /// times faster (a rate effect shows as a change between the two, Coulomb friction and
    /// hysteresis as none), three cycles each; then a held load of 0.6 of it with a dither of 0.02
    /// of it at ten times the slow rate (a gear without return-point memory drifts there) for ten
    /// dither periods, eased to and from; `limits` must allow the amplitude. Deflection plans are
    /// played by `simulate`; the board plays either channel.
    pub fn default_plan(channel: Channel, amplitude: f64, slow_hz: f64, limits: Limits) -> PlanSpec {
        // Each figure formed in f64 and rounded once: the file's numbers, as a user would write them.
        let of = |value: f64| value as f32;
        let period = 1.0 / slow_hz;
        let mut segments = vec![Segment::Hold { seconds: of(period), dither_amplitude: 0.0, dither_hz: 0.0 }];
        for share in [0.25, 0.5, 1.0] {
            for frequency_hz in [slow_hz, 4.0 * slow_hz] {
                segments.push(Segment::Sine {
                    amplitude: of(share * amplitude),
                    frequency_hz: of(frequency_hz),
                    cycles: 3,
                });
            }
        }
        let dither_hz = 10.0 * slow_hz;
        segments.extend([
            Segment::Ramp { to: of(0.6 * amplitude), seconds: of(period) },
            Segment::Hold {
                seconds: of(10.0 / dither_hz),
                dither_amplitude: of(0.02 * amplitude),
                dither_hz: of(dither_hz),
            },
            Segment::Ramp { to: 0.0, seconds: of(period) },
        ]);
        PlanSpec {
            channel,
            limits,
            segments,
            positions: Vec::new(),
            limits_at: None,
            segments_at: None,
            source: "the default plan".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"{
  "channel": "deflection",
  "limits": { "torque_nm": 60, "deflection_rad": 0.0015 },
  "segments": [
    { "sine": { "amplitude": 0.0005, "frequency_hz": 0.5, "cycles": 3 } },
    { "ramp": { "to": 0.0006, "seconds": 2 } },
    { "hold": { "seconds": 4, "dither_amplitude": 0.00002, "dither_hz": 5 } },
    { "ramp": { "to": 0, "seconds": 2 } }
  ]
}"#;

    fn error(text: &str, rate: f64) -> String {
        match parse_plan(Path::new("p.json"), text).and_then(|spec| spec.at_rate(rate)) {
            Ok(plan) => panic!("accepted: {plan:?}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn a_plan_file_is_read_and_played_at_the_rate_given() {
        let spec = parse_plan(Path::new("p.json"), GOOD).unwrap();
        assert_eq!(spec.segments.len(), 4);
        let plan = spec.at_rate(1000.0).unwrap();
        assert_eq!(plan.ticks(), 1 + 6000 + 2000 + 4000 + 2000);
        assert_eq!(plan.segments()[2], Segment::Hold { seconds: 4.0, dither_amplitude: 2e-5, dither_hz: 5.0 });
    }

    #[test]
    fn a_bad_plan_names_file_line_and_column() {
        // A misspelt field: where it is, and what was expected.
        let misspelt = GOOD.replace("\"cycles\": 3", "\"cycle\": 3");
        assert_eq!(
            error(&misspelt, 1000.0),
            "p.json:5: column 65: unknown field `cycle`, expected one of `amplitude`, `frequency_hz`, `cycles` (a \
             plan: {\"channel\", \"limits\", \"segments\"}, see README)"
        );
        // Beyond the limit: the segment's own line.
        let beyond = GOOD.replace("\"to\": 0.0006", "\"to\": 0.0016");
        let message = error(&beyond, 1000.0);
        assert!(message.starts_with("p.json:6: column 5: segment 2 reaches 0.001600"), "{message}");
        assert!(message.ends_with("(ramp)"), "{message}");
        // A dither too fast for the rate it is played at.
        assert_eq!(
            error(GOOD, 50.0),
            "p.json:7: column 5: segment 3: its frequency, 5 Hz, must be positive and at most 2.5 Hz (twenty ticks a \
             period at the rate the plan is played at) (hold); played at 50 samples a second"
        );
        // A number where a number belongs, in words; the plan's parts at their own lines.
        let text = GOOD.replace("\"cycles\": 3", "\"cycles\": 3.5");
        assert!(error(&text, 1000.0).contains("expected a whole number from 0 to 65535"), "{}", error(&text, 1000.0));
        let text = GOOD.replace("\"torque_nm\": 60", "\"torque_nm\": 0");
        assert!(error(&text, 1000.0).starts_with("p.json:3: column 13: the torque and deflection limits"));
        let text = GOOD.replace("\"seconds\": 4,", "\"seconds\": 700,");
        assert!(
            error(&text, 1000.0).starts_with("p.json:4: column 15: the plan plays 710 s"),
            "{}",
            error(&text, 1000.0)
        );
        // Not a plan at all, and an unknown segment.
        assert_eq!(
            error("time_s,deflection_rad\n0,0\n", 1000.0),
            "p.json:1: column 1: expected a plan, a JSON object {\"channel\", \"limits\", \"segments\"}; found \
             \"time_s,deflection_rad\""
        );
        let unknown = GOOD.replace("\"ramp\": { \"to\": 0,", "\"step\": { \"to\": 0,");
        let message = error(&unknown, 1000.0);
        assert!(
            message.starts_with("p.json:8: column 12: unknown variant `step`, expected one of `ramp`, `sine`, `hold`"),
            "{message}"
        );
    }

    #[test]
    fn the_default_plan_plays_three_amplitudes_at_two_rates_and_a_dithered_hold() {
        let limits = Limits { torque_nm: 100.0, deflection_rad: 1.5e-3 };
        let plan = PlanSpec::default_plan(Channel::Deflection, 1.0e-3, 0.5, limits).at_rate(1000.0).unwrap();
        let sines: Vec<(f32, f32)> = plan
            .segments()
            .iter()
            .filter_map(|s| match *s {
                Segment::Sine { amplitude, frequency_hz, .. } => Some((amplitude, frequency_hz)),
                _ => None,
            })
            .collect();
        assert_eq!(sines, [(2.5e-4, 0.5), (2.5e-4, 2.0), (5e-4, 0.5), (5e-4, 2.0), (1e-3, 0.5), (1e-3, 2.0)]);
        assert!(plan.segments().iter().any(|s| matches!(s, Segment::Hold { dither_hz, .. } if *dither_hz == 5.0)));
        // A rest of one slow period first, where the zero and the torque's offset are read.
        assert_eq!(plan.segments()[0], Segment::Hold { seconds: 2.0, dither_amplitude: 0.0, dither_hz: 0.0 });
        // 2 s at rest, three times 6 + 1.5 s of sines, 2 s ramps to and from a 2 s hold: half a
        // minute at 0.5 Hz.
        let seconds = plan.segments().iter().map(Segment::seconds).sum::<f32>();
        assert_eq!(seconds, 30.5);
        // Its figures as a user would write them (each rounded once from f64).
        assert_eq!(plan.segments()[7], Segment::Ramp { to: 6e-4, seconds: 2.0 });
    }
}
