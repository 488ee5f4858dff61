#!/usr/bin/env bash
# No-behaviour-change check for refactors: renders a fixed set of scenes at small size with the
# current release build and compares every EXR bit for bit (`idiff -a`, all channels, zero tolerance) against
# a set recorded before the change.
#
#   scripts/same-images.sh record DIR   # before the change: render the set into DIR
#   scripts/same-images.sh check DIR    # after the change: render again, compare with DIR (non-zero exit on any difference)
#
# Needs ../shared/data (furball, straight.hair, city.exr) and openimageio-tools (idiff).
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:?usage: same-images.sh record|check DIR}
dir=${2:?usage: same-images.sh record|check DIR}
cargo build --release --quiet
bin=target/release/cuticle
out=$dir
if [ "$mode" = check ]; then out=$(mktemp -d); trap 'rm -rf "$out"' EXIT; fi
mkdir -p "$out"

# name | scene ("" = built-in default) | extra arguments
cases=(
  "default||--res 96x72 --spp 4"
  "furball|scenes/furball.toml|--res 96x96 --spp 4"
  "furball-round-dom|scenes/furball-shadows.toml|--res 96x96 --spp 4 --curves round"
  "furball-peer|scenes/furball-peer.toml|--res 96x96 --spp 4"
  "cornell-box|scenes/thesis/cornell-box.toml|--res 64x64 --spp 4"
  "straight-city-marschner|scenes/thesis/straight-city-marschner.toml|--res 60x80 --spp 4"
  "straight-city-ishair|scenes/thesis/straight-city-ishair.toml|--res 60x80 --spp 4 --shadows deep-opacity"
  # --quality auto: the pilots, the decisions and the adaptive rounds (deterministic for any thread count).
  "default-auto||--res 64x48 --quality auto --target 0.1"
  "straight-city-auto|scenes/thesis/straight-city-marschner.toml|--res 64x64 --quality auto --target 0.1"
)
status=0
for c in "${cases[@]}"; do
  IFS='|' read -r name scene args <<<"$c"
  # shellcheck disable=SC2086
  $bin render $scene -o "$out/$name.exr" --threads 2 --quiet $args 2>/dev/null
  if [ "$mode" = check ]; then
    if idiff -q -a "$dir/$name.exr" "$out/$name.exr" >/dev/null 2>&1; then
      echo "same      $name"
    else
      echo "DIFFERENT $name"; idiff -a "$dir/$name.exr" "$out/$name.exr" | tail -5; status=1
    fi
  else
    echo "recorded  $name"
  fi
done
exit $status
