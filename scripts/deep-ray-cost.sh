#!/usr/bin/env bash
# What a shadow or material ray costs by the path vertex it leaves, the measurement behind the cost model's `deep`
# weight (`src/quality/cost.rs`): callgrind instruction counts (steady where seconds on these VMs move by
# ±5 %) of one frame at path length 1 and one at path length 2, flat curves, ray-traced shadows, one thread. Prints
# the instructions of a first-vertex light sample (its shadow ray, light sample and BSDF evaluation), of a vertex at
# bounce 1 (one light and one material sample and their two rays: `Integrator::deeper_vertex` at path 1 over its
# calls) and of a vertex at bounce 2 (the difference between the two frames over the vertices it adds), and the
# ratio of the last two.
#
#   scripts/deep-ray-cost.sh SCENE [SPP] [RES]
#
# Default SPP 16, RES 64x64 (about a minute per scene on this machine class). Needs valgrind and ../shared/data for
# the scenes that read it.
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:?usage: deep-ray-cost.sh SCENE [SPP] [RES]}
spp=${2:-16}
res=${3:-64x64}
cargo build --release --quiet
bin=$PWD/target/release/cuticle
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# "instructions calls" of the calls to FUNCTION in a callgrind profile (inclusive, summed over its callers).
calls() {
  callgrind_annotate --inclusive=yes --tree=calling "$1" 2>/dev/null |
    awk -v f="$2" '$0 ~ ">   .*" f " \\(" {
      n = $1; gsub(",", "", n); c = $0; sub(/.*\(/, "", c); sub(/x\).*/, "", c); gsub(",", "", c)
      i += n; k += c
    } END { print i + 0, k + 0 }'
}

for p in 1 2; do
  valgrind --tool=callgrind --callgrind-out-file="$work/p$p" "$bin" render "$scene" --curves flat \
    --shadows raytraced --path-length "$p" --spp "$spp" --res "$res" --threads 1 --aovs none -o "$work/p$p.exr" \
    -q > "$work/p$p.log" 2>&1
done
read -r light light_calls < <(calls "$work/p1" "Integrator::first_vertex_light_sample")
read -r v1 c1 < <(calls "$work/p1" "Integrator::deeper_vertex")
read -r v2 c2 < <(calls "$work/p2" "Integrator::deeper_vertex")
awk -v s="$scene" -v l="$light" -v lc="$light_calls" -v v1="$v1" -v c1="$c1" -v v2="$v2" -v c2="$c2" 'BEGIN {
  b1 = v1 / c1; b2 = (v2 - v1) / (c2 - c1)
  printf "%s: first-vertex light sample %.0f instructions; bounce-1 vertex %.0f (%d); bounce-2 vertex %.0f (%d); bounce 2 / bounce 1 %.2f\n",
    s, l / lc, b1, c1, b2, c2 - c1, b2 / b1
}'
