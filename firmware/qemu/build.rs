//! Puts this board's `memory.x` (the mps2-an386 memory map; the repository's top-level
//! `memory.x` is a symlink to it) where cortex-m-rt's `link.x` looks for it, and an empty
//! `device.x`, which `link.x` includes with cortex-m-rt's `device` feature: the board's own
//! interrupt vectors (`__INTERRUPTS` in src/lib.rs) name their handler directly, so there is
//! nothing to provide.
use std::{env, error::Error, fs, path::PathBuf};

fn main() -> Result<(), Box<dyn Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("OUT_DIR not set (cargo sets it for build scripts)")?);
    fs::copy("memory.x", out.join("memory.x")).map_err(|error| format!("memory.x: {error}"))?;
    fs::write(out.join("device.x"), "/* The QEMU board's interrupt vectors: see src/lib.rs. */\n")
        .map_err(|error| format!("device.x: {error}"))?;
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    Ok(())
}
