#!/usr/bin/env bash
# Instruction counts of a frame's pixel loop, the steady measure behind "close to the tracer's limit"
# (seconds on these VMs move by ±5 % between runs; instruction counts of these deterministic renders do not):
# callgrind over `cuticle::render::render_tiles` only, one thread, twice — once whole, once with Embree's queries
# (`rtcIntersect1`, `rtcOccluded1`) toggled off inside it — and prints the total, Embree's part, cuticle's own
# part (with libm) and Embree's share, the instruction-count analogue of `cuticle bench replay`'s ratio.
#
#   scripts/instructions.sh [SCENE] [extra render arguments...]
#
# Default: scenes/furball-peer.toml at RES=64x64, SPP=4 (about 1.5 min per pass on this machine class; set RES
# and SPP in the environment to change them: `cuticle render` refuses an option given twice). Extra arguments go to
# `cuticle render` (e.g. `--curves flat`).
# Needs valgrind and ../shared/data for the scenes that read it.
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-scenes/furball-peer.toml}
shift || true
cargo build --release --quiet
bin=$PWD/target/release/cuticle
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

collected() {
  # The "Collected : N" line of a callgrind run (valgrind's own log on stderr).
  valgrind --tool=callgrind --callgrind-out-file="$work/out" --collect-atstart=no \
    --toggle-collect='cuticle::render::render_tiles' "$@" 2>&1 | sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}

args=(render "$scene" --res "${RES:-64x64}" --spp "${SPP:-4}" --threads 1 --quiet -o "$work/frame.exr" "$@")
total=$(collected "$bin" "${args[@]}")
own=$(collected --toggle-collect='rtcIntersect1' --toggle-collect='rtcOccluded1' "$bin" "${args[@]}")
[ -n "$total" ] && [ -n "$own" ] || { echo "callgrind gave no count" >&2; exit 1; }
python3 - "$total" "$own" <<'EOF'
import sys
total, own = (int(x) for x in sys.argv[1:])
embree = total - own
print(f"pixel loop {total / 1e6:.2f} M instructions: Embree {embree / 1e6:.2f} M, cuticle and libm {own / 1e6:.2f} M")
print(f"Embree's share {embree / total:.3f} (the target is 0.8 of the clock; own at most {embree / 4e6:.1f} M)")
EOF
