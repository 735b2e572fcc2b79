# Sourced by the test and bench scripts: makes `thumb_cargo ARGS…` build for
# thumbv7em-none-eabihf. Normal path: rustup's target. Fallback where rustup cannot download
# it: Debian's Rust with the standard library's source builds `core` itself
# (see shared/TOOLCHAIN.md).
THUMB_TARGET=thumbv7em-none-eabihf

thumb_apt_install() {
    local missing=()
    for package in "$@"; do
        dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package")
    done
    if ((${#missing[@]})); then
        local sudo=""
        [ "$(id -u)" -eq 0 ] || sudo="sudo"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
    fi
}

if command -v rustup >/dev/null && rustup target add "$THUMB_TARGET" >/dev/null 2>&1; then
    THUMB_ROUTE=rustup
    thumb_cargo() { cargo "$@" --target "$THUMB_TARGET"; }
else
    echo "rustup cannot add $THUMB_TARGET here; using Debian's Rust with build-std" >&2
    thumb_apt_install rustc-web cargo-web rust-web-src binutils-arm-none-eabi
    THUMB_ROUTE=debian
    thumb_cargo() {
        RUSTC_BOOTSTRAP=1 RUSTC=/usr/bin/rustc CARGO_TARGET_DIR=target/debian-rust \
            /usr/bin/cargo "$@" --target "$THUMB_TARGET" -Z build-std=core
    }
fi
export THUMB_ROUTE

# For firmware builds, run from the repository root: QEMU and binutils, the Debian route's
# linker, and FIRMWARE_ELF_DIR, where the release ELFs land.
thumb_firmware_setup() {
    thumb_apt_install qemu-system-arm gcc-arm-none-eabi
    if [ "$THUMB_ROUTE" = debian ]; then
        # Debian's Rust has no rust-lld: link with binutils' ld (see shared/TOOLCHAIN.md).
        export CARGO_TARGET_THUMBV7EM_NONE_EABIHF_LINKER=arm-none-eabi-ld
        # Added to the link scripts of firmware/.cargo/config.toml (cargo merges the two).
        export CARGO_TARGET_THUMBV7EM_NONE_EABIHF_RUSTFLAGS="-C linker-flavor=ld"
        FIRMWARE_ELF_DIR="$PWD/firmware/target/debian-rust/$THUMB_TARGET/release"
    else
        FIRMWARE_ELF_DIR="$PWD/firmware/target/$THUMB_TARGET/release"
    fi
}
