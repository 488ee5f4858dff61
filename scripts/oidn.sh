#!/bin/sh
# Lays out Intel Open Image Denoise 2.5.1 for `cuticle render --denoise` (Debian 12 has no package for it):
#
#   sh scripts/oidn.sh DIR      (scripts/setup-debian.sh runs it with DIR = ~/.local/share/cuticle/oidn)
#
# - The library: the CPU build of OIDN 2.5.1 and the oneTBB it was built against, from PyPI's `pyoidn` 2.5.1.0
#   wheel (`pyoidn/oidn/lib/`), fetched with curl, checked against a pinned sha256, opened with unzip (or python3).
#   Only what the CPU device needs is kept: libOpenImageDenoise.so.2, its _core (the trained weights) and
#   _device_cpu, and libtbb.so.12 (their RPATH is $ORIGIN/../lib, so they find each other in DIR/lib).
# - cuticle loads DIR/lib/libOpenImageDenoise.so.2 when --denoise asks for it (src/sys/oidn.rs), nothing earlier:
#   without it every other command works as before, and --denoise says where it looked.
# Cached: a wheel already in DIR with the right checksum is not fetched again. Any failure exits non-zero.
set -eu

[ $# -eq 1 ] || { echo "usage: $0 DIR" >&2; exit 2; }
mkdir -p "$1"
DIR=$(cd "$1" && pwd)

WHEEL=pyoidn-2.5.1.0-py3-none-manylinux2014_x86_64.whl
WHEEL_SHA256=32ad13368f8de1ef63001942ad05b02a00cd732d1206d97f352d3a3f606d823e
WHEEL_URL=https://files.pythonhosted.org/packages/80/f7/40c72360d5ee831ad1048427202b4c7bca41b28c7caffea0df4d2dc8158e/$WHEEL
KEEP="libOpenImageDenoise.so.2 libOpenImageDenoise.so.2.5.1 libOpenImageDenoise_core.so.2.5.1
libOpenImageDenoise_device_cpu.so.2.5.1 libtbb.so.12 libtbb.so.12.19"

die() { echo "oidn.sh: $*" >&2; exit 1; }
have_sha() { [ -f "$1" ] && [ "$(sha256sum "$1" | cut -d' ' -f1)" = "$2" ]; }

if have_sha "$DIR/$WHEEL" "$WHEEL_SHA256"; then
    echo "oidn.sh: cached $WHEEL"
else
    echo "oidn.sh: downloading $WHEEL_URL"
    curl -sSfL --retry 3 -o "$DIR/$WHEEL.part" "$WHEEL_URL" || die "download failed: $WHEEL_URL"
    have_sha "$DIR/$WHEEL.part" "$WHEEL_SHA256" ||
        die "$WHEEL: sha256 is $(sha256sum "$DIR/$WHEEL.part" | cut -d' ' -f1), expected $WHEEL_SHA256"
    mv "$DIR/$WHEEL.part" "$DIR/$WHEEL"
fi

rm -rf "$DIR/wheel" "$DIR/lib.tmp"
mkdir -p "$DIR/wheel" "$DIR/lib.tmp"
if command -v unzip >/dev/null 2>&1; then
    unzip -q "$DIR/$WHEEL" 'pyoidn/oidn/lib/*' -d "$DIR/wheel"
elif command -v python3 >/dev/null 2>&1; then
    python3 -m zipfile -e "$DIR/$WHEEL" "$DIR/wheel"
else
    die "neither unzip nor python3 to open $WHEEL (apt-get install unzip)"
fi
for f in $KEEP; do
    [ -f "$DIR/wheel/pyoidn/oidn/lib/$f" ] || die "$WHEEL has no pyoidn/oidn/lib/$f"
    mv "$DIR/wheel/pyoidn/oidn/lib/$f" "$DIR/lib.tmp/$f"
done
rm -rf "$DIR/wheel" "$DIR/lib"
mv "$DIR/lib.tmp" "$DIR/lib"
echo "oidn.sh: Open Image Denoise 2.5.1 (CPU) in $DIR/lib"
