//! `swg-host`: from a strain wave gear's bench recording to the joint board's parameters.
mod cli;

use clap::Parser;

fn main() -> std::process::ExitCode {
    return_large_buffers();
    let cli = cli::Cli::parse();
    match cli.run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", cli::error_chain(&error));
            std::process::ExitCode::FAILURE
        }
    }
}

/// Buffers of 128 KiB and more come straight from the OS and go back to it when freed. glibc
/// otherwise raises its mmap threshold after the first large buffer is freed (up to 32 MiB) and
/// keeps later ones in its heaps and the worker threads' arenas: `diagnose` at 2 M samples peaked
/// at 205 MB resident against 176 MB with the threshold fixed (`bash bench/scale.sh 2000000`),
/// for 7 % more time there (each fresh buffer's pages are faulted in) and none at 60 k samples.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn return_large_buffers() {
    // SAFETY: mallopt only sets an allocator parameter; called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 * 1024);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn return_large_buffers() {}
