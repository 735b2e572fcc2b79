//! The two input formats: the paper's loop table and the bench recording (format v1).
pub mod plan;
pub mod table;

use model_core::Direction;
use std::fmt;
use std::path::Path;
pub use table::InputError;
use table::{Row, Table};

/// The four branches of a loading cycle, as named in loop tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Branch {
    ForwardLoading,
    ForwardUnloading,
    ReverseLoading,
    ReverseUnloading,
}

impl Branch {
    pub const ALL: [Branch; 4] =
        [Branch::ForwardLoading, Branch::ForwardUnloading, Branch::ReverseLoading, Branch::ReverseUnloading];

    pub fn name(self) -> &'static str {
        match self {
            Branch::ForwardLoading => "forward_loading",
            Branch::ForwardUnloading => "forward_unloading",
            Branch::ReverseLoading => "reverse_loading",
            Branch::ReverseUnloading => "reverse_unloading",
        }
    }

    /// Forward loading and reverse unloading raise the deflection; the others lower it.
    pub fn direction(self) -> Direction {
        match self {
            Branch::ForwardLoading | Branch::ReverseUnloading => Direction::Rising,
            Branch::ForwardUnloading | Branch::ReverseLoading => Direction::Falling,
        }
    }

    /// The branch a sample of a recording lies on, from its direction and side of zero.
    pub fn of(direction: Direction, deflection: f64) -> Branch {
        match (direction, deflection >= 0.0) {
            (Direction::Rising, true) => Branch::ForwardLoading,
            (Direction::Falling, true) => Branch::ForwardUnloading,
            (Direction::Falling, false) => Branch::ReverseLoading,
            (Direction::Rising, false) => Branch::ReverseUnloading,
        }
    }
}

impl fmt::Display for Branch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A loop table: `branch,torque_nm,deflection_rad`, one measured point a row.
#[derive(Clone, Debug, PartialEq)]
pub struct LoopTable {
    pub branch: Vec<Branch>,
    pub torque: Vec<f64>,
    pub deflection: Vec<f64>,
}

/// A bench recording, format v1.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Recording {
    /// Gear reduction ratio N.
    pub ratio: f64,
    /// `# key: value` lines before the header, in order.
    pub metadata: Vec<(String, String)>,
    pub time: Vec<f64>,
    /// Input (wave generator) and output angles, rad, when the recording has them.
    pub angles: Option<Angles>,
    /// θ = θ_in/N − θ_out, rad.
    pub deflection: Vec<f64>,
    pub torque: Vec<f64>,
    pub temperature: Option<Vec<f64>>,
}

#[derive(Clone, Debug, PartialEq, Default)]
pub struct Angles {
    pub input: Vec<f64>,
    pub output: Vec<f64>,
}

/// What `read` found in a file.
#[derive(Clone, Debug, PartialEq)]
pub enum Dataset {
    LoopTable(LoopTable),
    Recording(Recording),
}

impl Dataset {
    /// Number of samples (rows).
    pub fn len(&self) -> usize {
        match self {
            Dataset::LoopTable(table) => table.torque.len(),
            Dataset::Recording(recording) => recording.time.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The torque, when every sample has the same one while the deflection goes both up and
    /// down (a deflection that never reverses has its own, earlier error).
    pub fn constant_torque(&self) -> Option<f64> {
        let (torque, deflection) = match self {
            Dataset::LoopTable(table) => (&table.torque, &table.deflection),
            Dataset::Recording(recording) => (&recording.torque, &recording.deflection),
        };
        let first = *torque.first()?;
        let rises = deflection.windows(2).any(|w| w[1] > w[0]);
        let falls = deflection.windows(2).any(|w| w[1] < w[0]);
        (rises && falls && torque.iter().all(|&t| t == first)).then_some(first)
    }

    /// `loop_table` or `recording`, as reports name the kind of input.
    pub fn kind(&self) -> &'static str {
        match self {
            Dataset::LoopTable(_) => "loop_table",
            Dataset::Recording(_) => "recording",
        }
    }
}

/// The largest torque any gear could carry, N·m: a value beyond is a reading error.
pub const MAX_TORQUE_NM: f64 = 1e6;
/// The largest torsional deflection, rad: a strain wave gear deflects milliradians.
pub const MAX_DEFLECTION_RAD: f64 = 1.0;
/// The temperatures a bench can record, °C (absolute zero to a gear long past burning).
pub const TEMPERATURE_RANGE_C: (f64, f64) = (-273.15, 1000.0);

/// The torque in cell (`row`, `col`): finite and within ±[`MAX_TORQUE_NM`].
fn torque_at(table: &Table, row: &Row, col: usize) -> Result<f64, InputError> {
    let torque = table.number(row, col)?;
    if torque.abs() > MAX_TORQUE_NM {
        return Err(table.cell_error(row, col, format!("torque of {torque:e} N·m is beyond any gear (|T| ≤ 10⁶ N·m)")));
    }
    Ok(torque)
}

/// Checks a deflection (read from cell `col`, or computed from the angles ending there).
fn check_deflection(table: &Table, row: &Row, col: usize, deflection: f64, what: &str) -> Result<f64, InputError> {
    if !deflection.is_finite() || deflection.abs() > MAX_DEFLECTION_RAD {
        return Err(table.cell_error(
            row,
            col,
            format!(
                "{what} of {deflection:e} rad is beyond any strain wave gear (|θ| ≤ 1 rad; they deflect milliradians)"
            ),
        ));
    }
    Ok(deflection)
}

/// First line of a recording.
pub const RECORDING_MAGIC: &str = "swg-recording v1";

/// Reads a loop table or a recording, telling them apart by the recording's first line.
/// `ratio` overrides a recording's `# ratio:` line.
pub fn read(path: &Path, ratio: Option<f64>) -> Result<Dataset, InputError> {
    dataset(&Table::open(path)?, ratio)
}

/// [`read`] of a file's bytes already in memory; `path` names it in errors.
pub fn parse(path: &Path, bytes: &[u8], ratio: Option<f64>) -> Result<Dataset, InputError> {
    dataset(&Table::parse_bytes(path, bytes)?, ratio)
}

fn dataset(table: &Table, ratio: Option<f64>) -> Result<Dataset, InputError> {
    let path = &table.path;
    let first_comment = table.preamble.first().filter(|(line, _)| *line == 1);
    match first_comment {
        Some((_, comment)) if comment.starts_with("swg-recording") => {
            Ok(Dataset::Recording(recording_from_table(table, ratio)?))
        }
        _ if table.column("branch").is_some() => Ok(Dataset::LoopTable(loop_table_from_table(table)?)),
        _ if table.column("time_s").is_some() => {
            Err(InputError::at_line(path, 1, format!("a recording must start with the line `# {RECORDING_MAGIC}`")))
        }
        _ => Err(InputError::at_line(
            path,
            table.header_line,
            format!(
                "expected a loop table header (branch,torque_nm,deflection_rad) or a recording \
                 starting with `# {RECORDING_MAGIC}`; found header: {}",
                table.header.join(",")
            ),
        )),
    }
}

/// Reads a recording; anything else is an error.
pub fn read_recording(path: &Path, ratio: Option<f64>) -> Result<Recording, InputError> {
    match read(path, ratio)? {
        Dataset::Recording(recording) => Ok(recording),
        Dataset::LoopTable(_) => {
            Err(InputError::file(path, format!("expected a recording (`# {RECORDING_MAGIC}`), found a loop table")))
        }
    }
}

fn loop_table_from_table(table: &Table) -> Result<LoopTable, InputError> {
    let branch_col = table.required_column("branch", "forward_loading, forward_unloading, …")?;
    let torque_col = table.required_column("torque_nm", "torque, N·m")?;
    let deflection_col = table.required_column("deflection_rad", "torsional deflection, rad")?;
    let mut out = LoopTable { branch: Vec::new(), torque: Vec::new(), deflection: Vec::new() };
    table.for_each_row(|row| {
        let name = row.field(branch_col);
        let branch = Branch::ALL.into_iter().find(|b| b.name() == name).ok_or_else(|| {
            let names: Vec<_> = Branch::ALL.iter().map(|b| b.name()).collect();
            table.cell_error(row, branch_col, format!("unknown branch {name:?}; expected one of {}", names.join(", ")))
        })?;
        out.branch.push(branch);
        out.torque.push(torque_at(table, row, torque_col)?);
        let deflection = table.number(row, deflection_col)?;
        out.deflection.push(check_deflection(table, row, deflection_col, deflection, "deflection")?);
        Ok(())
    })?;
    if out.torque.is_empty() {
        return Err(no_rows(table));
    }
    Ok(out)
}

fn recording_from_table(table: &Table, ratio_override: Option<f64>) -> Result<Recording, InputError> {
    let path = &table.path;
    let mut preamble = table.preamble.iter();
    if let Some((line, magic)) = preamble.next() {
        if magic != RECORDING_MAGIC {
            return Err(InputError::at_line(
                path,
                *line,
                format!("unsupported recording version `# {magic}`; this tool reads `# {RECORDING_MAGIC}`"),
            ));
        }
    }
    let mut metadata: Vec<(String, String)> = Vec::new();
    let mut key_lines: Vec<u64> = Vec::new();
    let mut ratio_line = None;
    for (line, comment) in preamble {
        if let Some((key, value)) = comment.split_once(':') {
            let (key, value) = (key.trim().to_owned(), value.trim().to_owned());
            if let Some(first) = metadata.iter().position(|(k, _)| *k == key) {
                let first_line = key_lines.get(first).copied().unwrap_or_default();
                return Err(InputError::at_line(
                    path,
                    *line,
                    format!("metadata key `{key}` appears twice, on lines {first_line} and {line}: keep one"),
                ));
            }
            if key == "ratio" {
                ratio_line = Some((*line, value.clone()));
            }
            metadata.push((key, value));
            key_lines.push(*line);
        }
    }
    let ratio = match (ratio_override, ratio_line) {
        (Some(ratio), _) => check_ratio(ratio).map_err(|m| InputError::file(path, format!("--ratio {m}")))?,
        (None, Some((line, text))) => {
            let value = text
                .parse::<f64>()
                .map_err(|_| InputError::at_line(path, line, format!("ratio: expected a number, found {text:?}")))?;
            check_ratio(value).map_err(|m| InputError::at_line(path, line, format!("ratio {m}")))?
        }
        (None, None) => {
            return Err(InputError::file(
                path,
                "no gear ratio: add a `# ratio: N` line before the header or pass --ratio N",
            ))
        }
    };

    let time_col = table.required_column("time_s", "sample time, s")?;
    let torque_col = table.required_column("torque_nm", "output torque, N·m")?;
    let temperature_col = table.column("temperature_c");
    let deflection_col = table.column("deflection_rad");
    let angle_cols = match (table.column("theta_in_rad"), table.column("theta_out_rad")) {
        (Some(input), Some(output)) => Some((input, output)),
        (None, None) => None,
        (Some(_), None) => {
            table.required_column("theta_out_rad", "output angle, rad")?;
            None
        }
        (None, Some(_)) => {
            table.required_column("theta_in_rad", "input angle, rad")?;
            None
        }
    };
    if angle_cols.is_none() && deflection_col.is_none() {
        return Err(InputError::at_line(
            path,
            table.header_line,
            format!(
                "missing columns: either theta_in_rad and theta_out_rad, or deflection_rad; the header has: {}",
                table.header.join(",")
            ),
        ));
    }

    let mut rec = Recording {
        ratio,
        metadata,
        angles: angle_cols.map(|_| Angles::default()),
        temperature: temperature_col.map(|_| Vec::new()),
        ..Recording::default()
    };
    table.for_each_row(|row| {
        let time = table.number(row, time_col)?;
        if let Some(&previous) = rec.time.last() {
            if time <= previous {
                return Err(table.cell_error(
                    row,
                    time_col,
                    format!("time must increase strictly: {time} s follows {previous} s"),
                ));
            }
        }
        rec.time.push(time);
        rec.torque.push(torque_at(table, row, torque_col)?);
        let deflection = match (angle_cols, rec.angles.as_mut()) {
            (Some((input_col, output_col)), Some(angles)) => {
                let input = table.number(row, input_col)?;
                let output = table.number(row, output_col)?;
                angles.input.push(input);
                angles.output.push(output);
                // Checked only when it is the deflection used (no deflection column).
                let theta = deflection(input, output, ratio);
                match deflection_col {
                    Some(_) => theta,
                    None => check_deflection(table, row, output_col, theta, "deflection θ_in/N − θ_out")?,
                }
            }
            _ => 0.0,
        };
        // An explicit deflection column wins over the angles.
        let deflection = match deflection_col {
            Some(col) => {
                let theta = table.number(row, col)?;
                check_deflection(table, row, col, theta, "deflection")?
            }
            None => deflection,
        };
        rec.deflection.push(deflection);
        if let (Some(col), Some(temps)) = (temperature_col, rec.temperature.as_mut()) {
            let celsius = table.number(row, col)?;
            let (low, high) = TEMPERATURE_RANGE_C;
            if !(low..=high).contains(&celsius) {
                return Err(table.cell_error(
                    row,
                    col,
                    format!("temperature of {celsius:e} °C is beyond any bench ({low} to {high} °C)"),
                ));
            }
            temps.push(celsius);
        }
        Ok(())
    })?;
    if rec.time.is_empty() {
        return Err(no_rows(table));
    }
    if let Some(k) = rec.metadata.iter().position(|(key, value)| key == START_KEY && value == START_AT_REST) {
        check_starts_unloaded(&rec.torque).map_err(|why| InputError::at_line(path, key_lines[k], why))?;
    }
    // The columns grew by doubling: up to 1.7× the samples' room (16.8 M for 10 M samples).
    // Large blocks are remapped in place, so giving the rest back copies nothing.
    for column in [&mut rec.time, &mut rec.deflection, &mut rec.torque]
        .into_iter()
        .chain(rec.angles.as_mut().map(|a| [&mut a.input, &mut a.output]).into_iter().flatten())
        .chain(rec.temperature.as_mut())
    {
        column.shrink_to_fit();
    }
    Ok(rec)
}

/// The share of the torque's reach beyond which a first sample is loaded ([`check_starts_unloaded`]).
const LOADED_START: f64 = 0.25;

/// A recording that says `# start: rest` begins unloaded: its first torque is at most
/// [`LOADED_START`] of the largest |torque| away from zero, or at most that share of the
/// torque's range away from the range's middle (a sensor's offset on a small loop). Cut after it started and keeping the line, a
/// recording that began at −18 N·m on a ±28 N·m loop had its zero and its start state read there
/// ("θ0 read at rest"), and `predict` missed it by 4.5 N·m RMS.
fn check_starts_unloaded(torque: &[f64]) -> Result<(), String> {
    let first = torque[0];
    let (lo, hi) = torque.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    let peak = lo.abs().max(hi.abs());
    let middle = (lo + hi) / 2.0;
    if first.abs() > LOADED_START * peak && (first - middle).abs() > LOADED_START * (hi - lo) {
        return Err(format!(
            "`# {START_KEY}: {START_AT_REST}`, but the first sample carries {first:.4} N·m, {:.0} % of the recording's \
             largest torque: was it cut after the motion began? Remove this line, and the start state is estimated \
             from the motion",
            100.0 * first.abs() / peak
        ));
    }
    Ok(())
}

/// A table whose header no data row follows: every command would have nothing to work on
/// (`predict` wrote an empty prediction with an RSS of −0).
fn no_rows(table: &Table) -> InputError {
    InputError::at_line(&table.path, table.header_line, "no data rows after the header")
}

fn check_ratio(ratio: f64) -> Result<f64, String> {
    if ratio.is_finite() && ratio > 0.0 {
        Ok(ratio)
    } else {
        Err(format!("must be a finite gear ratio > 0, found {ratio}"))
    }
}

/// Torsional deflection θ = θ_in/N − θ_out, rad.
pub fn deflection(theta_in: f64, theta_out: f64, ratio: f64) -> f64 {
    theta_in / ratio - theta_out
}

/// The metadata line `# start: rest`: the gear was unstressed at θ = 0 when the recording began
/// (what `simulate` writes wherever its truth starts at rest, and a board's recording).
pub const START_KEY: &str = "start";
pub const START_AT_REST: &str = "rest";

impl Recording {
    /// Whether the recording says it starts at rest (`# start: rest`). Any other value, or
    /// none, is "not known to start at rest": the hysteresis state at the first sample is
    /// unknown.
    pub fn starts_at_rest(&self) -> bool {
        self.metadata.iter().any(|(key, value)| key == START_KEY && value == START_AT_REST)
    }

    /// The first column holding a number that is not finite, by its name in the file.
    pub fn first_non_finite(&self) -> Option<&'static str> {
        let bad = |values: &[f64]| values.iter().any(|v| !v.is_finite());
        let angles = self.angles.as_ref();
        [
            ("ratio", std::slice::from_ref(&self.ratio)),
            ("time_s", &self.time[..]),
            ("theta_in_rad", angles.map_or(&[][..], |a| &a.input[..])),
            ("theta_out_rad", angles.map_or(&[][..], |a| &a.output[..])),
            ("deflection_rad", &self.deflection[..]),
            ("torque_nm", &self.torque[..]),
            ("temperature_c", self.temperature.as_deref().unwrap_or_default()),
        ]
        .into_iter()
        .find(|(_, values)| bad(values))
        .map(|(name, _)| name)
    }

    /// Writes the recording in format v1 (what `read` reads back exactly).
    pub fn write(&self, mut out: impl std::io::Write) -> std::io::Result<()> {
        writeln!(out, "# {RECORDING_MAGIC}")?;
        writeln!(out, "# ratio: {}", self.ratio)?;
        for (key, value) in self.metadata.iter().filter(|(key, _)| key != "ratio") {
            writeln!(out, "# {key}: {value}")?;
        }
        let mut header = vec!["time_s"];
        if self.angles.is_some() {
            header.extend(["theta_in_rad", "theta_out_rad"]);
        } else {
            header.push("deflection_rad");
        }
        header.push("torque_nm");
        if self.temperature.is_some() {
            header.push("temperature_c");
        }
        writeln!(out, "{}", header.join(","))?;
        for i in 0..self.time.len() {
            write!(out, "{}", self.time[i])?;
            match &self.angles {
                Some(angles) => write!(out, ",{},{}", angles.input[i], angles.output[i])?,
                None => write!(out, ",{}", self.deflection[i])?,
            }
            write!(out, ",{}", self.torque[i])?;
            if let Some(temps) = &self.temperature {
                write!(out, ",{}", temps[i])?;
            }
            writeln!(out)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn recording(preamble: &str) -> Recording {
        let text = format!("# {RECORDING_MAGIC}\n# ratio: 50\n{preamble}time_s,deflection_rad,torque_nm\n0,0,0\n");
        match parse(Path::new("r.csv"), text.as_bytes(), None).unwrap() {
            Dataset::Recording(recording) => recording,
            Dataset::LoopTable(_) => panic!("a loop table"),
        }
    }

    #[test]
    fn a_header_without_rows_is_an_error_at_the_header() {
        let text = format!("# {RECORDING_MAGIC}\n# ratio: 50\ntime_s,deflection_rad,torque_nm\n\n");
        let error = parse(Path::new("r.csv"), text.as_bytes(), None).unwrap_err().to_string();
        assert!(error.contains("r.csv:3: no data rows after the header"), "{error}");
        let table = "branch,torque_nm,deflection_rad\n";
        let error = parse(Path::new("t.csv"), table.as_bytes(), None).unwrap_err().to_string();
        assert!(error.contains("t.csv:1: no data rows after the header"), "{error}");
    }

    /// A recording cut after it started, keeping `# start: rest`, is refused at that line; one
    /// that starts unloaded (or at a sensor's offset on a small loop, or from rest onto a held
    /// load) reads.
    #[test]
    fn a_recording_that_says_it_starts_at_rest_starts_unloaded() {
        let cut = format!(
            "# {RECORDING_MAGIC}\n# ratio: 50\n# start: rest\ntime_s,deflection_rad,torque_nm\n0,-1e-3,-18\n1,0,0\n2,1e-3,28\n"
        );
        let error = parse(Path::new("r.csv"), cut.as_bytes(), None).unwrap_err().to_string();
        assert!(error.starts_with("r.csv:3:") && error.contains("cut after the motion began"), "{error}");
        assert!(check_starts_unloaded(&[-18.0, -10.0, 0.0, 28.0, -28.0]).unwrap_err().contains("cut after"));
        for torque in [[0.01, 10.0, -10.0, 0.0], [0.3, 0.5, 0.1, 0.3], [0.0, 9.0, 11.0, 10.0]] {
            assert!(check_starts_unloaded(&torque).is_ok(), "{torque:?}");
        }
    }

    #[test]
    fn only_start_rest_says_a_recording_starts_at_rest() {
        assert!(recording("# start: rest\n").starts_at_rest());
        assert!(recording("# source: bench\n#start:   rest  \n").starts_at_rest());
        for other in ["", "# start: moving\n", "# start: Rest\n", "# start:\n", "# restart: rest\n", "# start rest\n"] {
            assert!(!recording(other).starts_at_rest(), "{other:?}");
        }
        // A value it does not know is kept, as any metadata is.
        let kept = recording("# start: rest, then moving\n");
        assert_eq!(kept.metadata.last().unwrap(), &("start".to_owned(), "rest, then moving".to_owned()));
    }

    #[test]
    fn start_rest_is_written_back() {
        let mut text = Vec::new();
        recording("# start: rest\n").write(&mut text).unwrap();
        let again = parse(Path::new("again.csv"), &text, None).unwrap();
        assert!(matches!(again, Dataset::Recording(r) if r.starts_at_rest()));
    }
}
