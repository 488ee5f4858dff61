#!/bin/sh
# Installs what cuticle needs on a fresh Debian 12 (or Ubuntu 22.04+) machine or container:
#   - the native libraries: Embree 3 (curves), OpenImageIO (images), clang/libclang (bindgen), pkg-config, a C++
#     compiler, openimageio-tools (oiiotool/idiff, used by the tests) and unzip (scripts/embree4.sh, CI's Embree 4
#     step);
#   - a Rust toolchain >= the crate's rust-version (1.88) through rustup, unless one is already on PATH or in
#     ~/.cargo/bin (Debian 12's own rustc is 1.63, too old);
#   - Intel Open Image Denoise 2.5.1 for `render --denoise`, in ${XDG_DATA_HOME:-~/.local/share}/cuticle/oidn
#     (scripts/oidn.sh: Debian 12 has no package; cuticle loads it only when asked to denoise).
# Works as root without sudo (a container) or as a user with sudo. Safe to run again.
set -eu

if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
# A fresh machine or container has no package lists yet.
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends \
    ca-certificates curl git build-essential pkg-config clang libclang-dev \
    libembree-dev libopenimageio-dev openimageio-tools unzip >/dev/null

need="1.88"
PATH="$HOME/.cargo/bin:$PATH"
have=$(cargo --version 2>/dev/null | sed -n 's/^cargo \([0-9]*\.[0-9]*\).*/\1/p')
if [ -n "$have" ] && [ "$(printf '%s\n%s\n' "$need" "$have" | sort -V | head -n1)" = "$need" ]; then
    echo "setup: using cargo $have"
else
    echo "setup: installing Rust with rustup (found: ${have:-none}, need >= $need)"
    installer=$(mktemp)
    # Downloaded first, so a network failure stops here instead of piping nothing into sh.
    curl --proto '=https' --tlsv1.2 -sSf -o "$installer" https://sh.rustup.rs
    sh "$installer" -y --profile minimal
    rm -f "$installer"
fi
cargo --version >/dev/null 2>&1 || { echo "setup: no cargo on PATH or in ~/.cargo/bin" >&2; exit 1; }
sh "$(dirname "$0")/oidn.sh" "${XDG_DATA_HOME:-$HOME/.local/share}/cuticle/oidn"
echo "setup: done ($(cargo --version); rustup installs into ~/.cargo/bin)"
