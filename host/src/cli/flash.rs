//! `swg-host flash`: write a firmware ELF to a joint board through a debug probe (probe-rs),
//! then optionally push parameters, as the joint-board workflow needs.
#[cfg(feature = "probe")]
use anyhow::Context;
use anyhow::{bail, Result};
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct FlashArgs {
    /// Firmware ELF, e.g. firmware/target/thumbv7em-none-eabihf/release/joint-stm32f405.
    #[arg(value_name = "ELF")]
    elf: PathBuf,
    /// Target chip as probe-rs names it, e.g. STM32F405RGTx.
    #[arg(long, value_name = "CHIP")]
    chip: String,
}

#[cfg(feature = "probe")]
pub fn run(args: FlashArgs) -> Result<()> {
    flash_with(probe_rs::probe::list::Lister::new().list_all(), &args)
}

/// Flashes through the first of `probes`.
#[cfg(feature = "probe")]
fn flash_with(probes: Vec<probe_rs::probe::DebugProbeInfo>, args: &FlashArgs) -> Result<()> {
    use probe_rs::flashing::{download_file, ElfLoader, ElfOptions};
    use probe_rs::Permissions;

    if !args.elf.is_file() {
        bail!("{}: no such firmware file", args.elf.display());
    }
    let Some(probe) = probes.first() else {
        bail!(
            "no debug probe found: connect an ST-Link, J-Link or CMSIS-DAP probe to the board \
             (and check its USB permissions)"
        );
    };
    if probes.len() > 1 {
        eprintln!("{} probes found; using the first: {}", probes.len(), probe.identifier);
    }
    let probe = probe.open().with_context(|| format!("cannot open probe {}", probe.identifier))?;
    let mut session = probe
        .attach(args.chip.as_str(), Permissions::default())
        .with_context(|| format!("cannot attach to {}", args.chip))?;
    download_file(&mut session, &args.elf, ElfLoader(ElfOptions::default()))
        .with_context(|| format!("flashing {} failed", args.elf.display()))?;
    session.core(0)?.reset().context("reset after flashing failed")?;
    super::print_report(&format!(
        "flashed {} to {}; restore its parameters with `swg-host push`\n",
        args.elf.display(),
        args.chip
    ))
}

#[cfg(all(test, feature = "probe"))]
mod tests {
    use super::*;

    #[test]
    fn without_a_probe_it_says_so() {
        let elf = tempfile::NamedTempFile::new().unwrap();
        let args = FlashArgs { elf: elf.path().to_owned(), chip: "STM32F405RGTx".into() };
        let error = flash_with(Vec::new(), &args).unwrap_err().to_string();
        assert!(error.starts_with("no debug probe found"), "{error}");
        let missing = FlashArgs { elf: "does-not-exist.elf".into(), chip: "STM32F405RGTx".into() };
        let error = flash_with(Vec::new(), &missing).unwrap_err().to_string();
        assert_eq!(error, "does-not-exist.elf: no such firmware file");
    }
}

#[cfg(not(feature = "probe"))]
pub fn run(args: FlashArgs) -> Result<()> {
    bail!(
        "cannot flash {} to {}: swg-host was built without the `probe` feature (probe-rs)",
        args.elf.display(),
        args.chip
    )
}
