#!/bin/sh
# Lays out an Embree 4 that cuticle can build against on Debian 12 (which ships only Embree 3.13.5), to test the
# Embree 4 code path (`cfg(embree4)`); it is not an install for users (README, "Embree 4"; docs/guide.md).
#
#   sh scripts/embree4.sh DIR     then   EMBREE_DIR=DIR cargo build --release
#
# - The library: Embree 4.4.0 and its TBB, from PyPI's `embreex` 4.4.0.post1 wheel (`embreex.libs/`), fetched with
#   curl (no pip or python needed), checked against a pinned sha256, opened with unzip.
# - The headers: the crates.io package `embree4-sys` 0.0.12 (`lib/embree4/`), pinned by sha256. They are Embree
#   4.2.0's, the newest any version of that crate carries (0.0.1-0.0.12 all ship 4.x <= 4.2); 4.3 and 4.4 added
#   fields for instance arrays, which the Rust side allows for (`src/sys/embree/query.rs`).
# Result: DIR/include/embree4/*.h, DIR/lib/libembree4.so -> the wheel's libembree4-<hash>.so.4 (its soname) and
# its libtbb-<hash>.so.12 beside it (the library's RPATH is $ORIGIN). Cached: what is already in DIR is checked,
# not fetched again. Any failure (no network, wrong checksum, wrong version) exits non-zero.
set -eu

[ $# -eq 1 ] || { echo "usage: $0 DIR" >&2; exit 2; }
mkdir -p "$1"
DIR=$(cd "$1" && pwd)

WHEEL=embreex-4.4.0.post1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl
WHEEL_SHA256=2cd0f7d5c6342e6247e31f700761689cae7829454d8c6de0c41e62124a023e1f
WHEEL_URL=https://files.pythonhosted.org/packages/26/60/3d959f55100ce829620c132cc5c5413e71d2fbcc2ffdede251c269a5a9ef/$WHEEL
CRATE=embree4-sys-0.0.12
CRATE_SHA256=a1c23ca437f91a52068a03088b80395115c87a669874e54120f4552f1bedaf67
EMBREE_VERSION=4.4.0
HEADER_VERSION=4.2.0

die() { echo "embree4.sh: $*" >&2; exit 1; }
have_sha() { [ -f "$1" ] && [ "$(sha256sum "$1" | cut -d' ' -f1)" = "$2" ]; }

fetch() { # fetch FILE SHA256 URL
    if have_sha "$DIR/$1" "$2"; then echo "embree4.sh: cached $1"; return; fi
    echo "embree4.sh: downloading $3"
    curl -sSfL --retry 3 -o "$DIR/$1.part" "$3" || die "download failed: $3"
    have_sha "$DIR/$1.part" "$2" || die "$1: sha256 is $(sha256sum "$DIR/$1.part" | cut -d' ' -f1), expected $2"
    mv "$DIR/$1.part" "$DIR/$1"
}

# The wheel's permanent URL on PyPI's file host (from PyPI's simple index for embreex), checked by its sha256.
fetch "$WHEEL" "$WHEEL_SHA256" "$WHEEL_URL"
fetch "$CRATE.crate" "$CRATE_SHA256" "https://static.crates.io/crates/embree4-sys/$CRATE.crate"

# Headers.
rm -rf "$DIR/include.tmp"
mkdir -p "$DIR/include.tmp"
tar -xzf "$DIR/$CRATE.crate" -C "$DIR/include.tmp" "$CRATE/lib/embree4"
rm -rf "$DIR/include"
mkdir -p "$DIR/include"
mv "$DIR/include.tmp/$CRATE/lib/embree4" "$DIR/include/embree4"
rm -rf "$DIR/include.tmp"
got=$(sed -n 's/^#define RTC_VERSION_STRING "\(.*\)"/\1/p' "$DIR/include/embree4/rtcore_config.h")
[ "$got" = "$HEADER_VERSION" ] || die "headers are Embree '$got', expected $HEADER_VERSION"

# Library: every file of embreex.libs/ (libembree4-<hash>.so.4 and libtbb-<hash>.so.12).
rm -rf "$DIR/wheel" "$DIR/lib"
# A wheel is a zip: `unzip` (scripts/setup-debian.sh installs it; a fresh Debian 12 has neither it nor python3), or
# python3's zipfile where there is no unzip.
if command -v unzip >/dev/null 2>&1; then
    unzip -q "$DIR/$WHEEL" 'embreex.libs/*' -d "$DIR/wheel"
elif command -v python3 >/dev/null 2>&1; then
    python3 -m zipfile -e "$DIR/$WHEEL" "$DIR/wheel"
else
    die "neither unzip nor python3 to open $WHEEL (apt-get install unzip)"
fi
mkdir -p "$DIR/lib"
mv "$DIR"/wheel/embreex.libs/* "$DIR/lib/"
rm -rf "$DIR/wheel"
set -- "$DIR"/lib/libembree4-*.so.4
[ $# -eq 1 ] && [ -f "$1" ] || die "expected one libembree4-*.so.4 in the wheel, found: $*"
embree=$(basename "$1")
ln -s "$embree" "$DIR/lib/libembree4.so"
grep -q "$EMBREE_VERSION" "$DIR/lib/$embree" || die "$embree does not name version $EMBREE_VERSION"

echo "embree4.sh: Embree $EMBREE_VERSION library ($embree, $(cd "$DIR/lib" && ls libtbb-*)) from $WHEEL"
echo "embree4.sh: Embree $HEADER_VERSION headers from crates.io $CRATE"
echo "embree4.sh: build with EMBREE_DIR=$DIR"
