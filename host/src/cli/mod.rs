//! Command-line interface: one module per subcommand, shared options flattened.
mod diagnose;
mod fit;
mod flash;
mod hil;
mod predict;
mod push;
mod record;
mod replay;
mod simulate;

use clap::{Args, Parser, Subcommand};

#[derive(Parser)]
#[command(name = "swg-host", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fit the hysteresis stiffness model to a loop table or a bench recording.
    Fit(fit::FitArgs),
    /// Run fitted parameters along a recording from rest (hysteresis with memory).
    Predict(predict::PredictArgs),
    /// Write a bench recording (format v1) from the model.
    Simulate(simulate::SimulateArgs),
    /// Find where the model and a recording disagree and which physics the model misses.
    Diagnose(diagnose::DiagnoseArgs),
    /// Run an identification plan on a joint and write what it measured as a recording.
    Record(record::RecordArgs),
    /// Send parameters to a joint: check versions, write, read back, store in flash.
    Push(push::PushArgs),
    /// Stream a recording through the joint firmware; compare its T_ff and K with the host model.
    Replay(replay::ReplayArgs),
    /// Write a firmware ELF to a joint board through a debug probe (probe-rs).
    Flash(flash::FlashArgs),
    /// Run the joint firmware against a simulated joint in lockstep; score each controller mode.
    Hil(hil::HilArgs),
}

impl Cli {
    pub fn run(self) -> anyhow::Result<()> {
        match self.command {
            Command::Fit(args) => fit::run(args),
            Command::Predict(args) => predict::run(args),
            Command::Simulate(args) => simulate::run(args),
            Command::Diagnose(args) => diagnose::run(args),
            Command::Record(args) => record::run(args),
            Command::Push(args) => push::run(args),
            Command::Replay(args) => replay::run(args),
            Command::Flash(args) => flash::run(args),
            Command::Hil(args) => hil::run(args),
        }
    }
}

/// Writes the command's `report` to standard output, then commits its `outputs`. A report that
/// cannot be written (`> /dev/full`: no space) fails the command before any output is written,
/// as any other failure does; `println!` panicked there, after the outputs were written. A reader
/// that stops early (`| head`) is a normal end: the rest of the report is dropped and the
/// outputs are written.
pub fn print_then_commit(report: &str, outputs: swg_host::report::output::Outputs) -> anyhow::Result<()> {
    print_report(report)?;
    outputs.commit()?;
    Ok(())
}

/// Writes `report` to standard output; a closed pipe ends it quietly ([`print_then_commit`]).
pub fn print_report(report: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    match stdout.write_all(report.as_bytes()).and_then(|()| stdout.flush()) {
        Err(error) if error.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(anyhow::Error::new(error).context("cannot write the report to standard output"))
        }
        _ => Ok(()),
    }
}

/// The message of `error` and each of its causes, once: `a: b: c`. Library errors write their
/// cause into their own message (so `to_string` alone is whole) and also give it as their
/// `source`; a cause whose text the message above it already holds is not repeated.
pub fn error_chain(error: &anyhow::Error) -> String {
    let mut text = String::new();
    let mut above = String::new();
    for cause in error.chain() {
        let message = cause.to_string();
        if text.is_empty() {
            text.push_str(&message);
        } else if !above.contains(&message) {
            text.push_str(": ");
            text.push_str(&message);
        }
        above = message;
    }
    text
}

/// How to read a recording; shared by every subcommand that takes one.
#[derive(Args, Clone, Debug, Default)]
pub struct InputOptions {
    /// Gear reduction ratio N; overrides the recording's `# ratio:` line.
    #[arg(long, value_name = "N")]
    pub ratio: Option<f64>,
}

impl InputOptions {
    /// Reads a loop table or a recording with enough points to fit the model.
    pub fn read_to_fit(&self, path: &std::path::Path) -> anyhow::Result<swg_host::input::Dataset> {
        use swg_host::fit::MIN_POINTS;
        let dataset = swg_host::input::read(path, self.ratio)?;
        let n = dataset.len();
        if n < MIN_POINTS {
            anyhow::bail!("{}: {n} points, fewer than the {MIN_POINTS} needed to fit the model", path.display());
        }
        if let Some(torque) = dataset.constant_torque() {
            anyhow::bail!(
                "{}: the torque is {torque} N·m on every sample: a constant torque has no stiffness or \
                 hysteresis to fit (is torque_nm the sensor's column?)",
                path.display()
            );
        }
        Ok(dataset)
    }
}
