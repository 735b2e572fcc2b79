//! `swg-host`: from a strain wave gear's bench recording to the joint board's parameters.
mod cli;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = cli::Cli::parse();
    match cli.run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", cli::error_chain(&error));
            std::process::ExitCode::FAILURE
        }
    }
}
