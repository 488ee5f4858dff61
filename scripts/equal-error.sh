#!/usr/bin/env bash
# Equal error, not only equal samples: cuticle against Blender Cycles and Mitsuba 3 on the peer scene at
# 256², 2 threads. Each renderer renders its own converged reference, then a sweep of sample counts with other seeds,
# cuticle and Cycles taking turns at each point; every image's RMSE is measured against its own renderer's reference.
# Writes docs/measured/equal-error/equal-error.csv, a log-log chart RMSE vs wall time (equal-error.png/.svg, drawn by
# `cuticle plot-csv`) and prints the time each renderer needs to reach RMSE 0.07, 0.05, 0.04, 0.03.
#
# Run from the project root after `cargo build --release`:
#   scripts/equal-error.sh
# Environment:
#   REF_SPP (1024)                reference samples per pixel (lower it for a quick trial, e.g. REF_SPP=128)
#   SPPS ("4 8 16 32 64 128 256") the sweep
#   OUT (docs/measured/equal-error)        where the CSV and chart go
#   WORK (mktemp -d)              renders, logs and times
#   BIN (./target/release/cuticle)
#   CHART_ONLY=1                  no renders: redraw the chart and the read-out from $OUT/equal-error.csv
#   REUSE_REFS=1                  keep references already in $WORK (ref_NAME.exr, .t, .r from an earlier run with the
#                                 same REF_SPP and code), e.g. when only the sweep is to be redone
#   UNBIASED=1 (default)          also render "cycles-unbiased": Cycles with Clamp Indirect 0 and Filter Glossy 0,
#                                 Blender's two biased noise reductions off (its own reference cannot see their bias,
#                                 cuticle has neither on); UNBIASED=0 for Blender's defaults only
#   MITSUBA=1 (default)           also render "mitsuba": Mitsuba 3's llvm_ad_rgb variant (MITSUBA=0 to leave it out;
#                                 set-up in ../shared/peers/SETUP.md)
#
# Scene: cuticle `scenes/furball-peer.toml --res 256x256`; Cycles `../shared/peers/cycles_furball.py --res 256
# --shape thick --bounces 1 --sun --offset -2`; Mitsuba `../shared/peers/mitsuba_furball.py --res 256 --max-depth 3
# --variant llvm_ad_rgb --tilt 2` (the scene's cuticle scale tilt α = +2° is Cycles' Offset −2° and Mitsuba's
# scale_tilt +2), each with the harness' material and lights (docs/measured/peers.md maps each setting).
# Metric: RMS error over the beauty R, G, B of the whole image (every pixel, alpha and AOVs dropped: `oiiotool --ch
# R,G,B`), both sides linear float EXRs (cuticle's beauty channels; Cycles' `--out *.exr`, 32-bit float, scene-linear,
# not the view transform), computed by `oiiotool REF --ch R,G,B IMG --ch R,G,B --diff`.
# Times: wall_s is the whole process (`/usr/bin/time -f %e`: Blender's start-up and hair conversion, cuticle's load
# and BVH build included); render_s is each renderer's own render time (cuticle's `render X s` on stderr, Cycles'
# CYCLES_RENDER_SECONDS: sync + BVH + sampling).
set -euo pipefail
REF_SPP=${REF_SPP:-1024}
SPPS=${SPPS:-"4 8 16 32 64 128 256"}
OUT=${OUT:-docs/measured/equal-error}
BIN=${BIN:-./target/release/cuticle}
PEERS=../shared/peers
HAIR=../shared/data/hair/furball.hair
SCENE=scenes/furball-peer.toml
CSV=$OUT/equal-error.csv
REF_SEED=1000   # the sweep uses seeds 1, 2, ...: never the reference's
RENDERERS="cuticle cycles"
[ "${UNBIASED:-1}" = 1 ] && RENDERERS="$RENDERERS cycles-unbiased"
[ "${MITSUBA:-1}" = 1 ] && RENDERERS="$RENDERERS mitsuba"
mkdir -p "$OUT"

if [ "${CHART_ONLY:-0}" != 1 ]; then
  WORK=${WORK:-$(mktemp -d /tmp/equal-XXXXXX)}
  mkdir -p "$WORK"
  for f in "$BIN" "$SCENE" "$HAIR" "$PEERS/cycles_furball.py"; do
    [ -e "$f" ] || { echo "missing $f (run from the project root after cargo build --release)" >&2; exit 2; }
  done
  echo "renders and logs in $WORK; $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"

  # Mitsuba writes its curve file beside the hair it reads: a copy in $WORK.
  [[ " $RENDERERS " == *" mitsuba "* ]] && cp "$HAIR" "$WORK/furball.hair"
  # render NAME RENDERER SPP SEED: one image, its whole-process and own render times in $WORK/NAME.{t,log}.
  render() {
    local name=$1 who=$2 spp=$3 seed=$4
    if [ "$who" = cuticle ]; then
      /usr/bin/time -f %e -o "$WORK/$name.t" "$BIN" render "$SCENE" --res 256x256 --spp "$spp" --seed "$seed" \
        --threads 2 --quiet -o "$WORK/$name.exr" > "$WORK/$name.log" 2>&1
      sed -n 's/.*render \([0-9.]*\) s.*/\1/p' "$WORK/$name.log" | tail -1 > "$WORK/$name.r"
    elif [ "$who" = mitsuba ]; then
      /usr/bin/time -f %e -o "$WORK/$name.t" python3 "$PEERS/mitsuba_furball.py" --hair "$WORK/furball.hair" \
        --res 256 --spp "$spp" --seed "$seed" --max-depth 3 --variant llvm_ad_rgb --threads 2 --tilt 2 \
        --exr "$WORK/$name.exr" --out "$WORK/$name.png" > "$WORK/$name.log" 2>&1
      sed -n 's/^MITSUBA_RENDER_SECONDS=//p' "$WORK/$name.log" | tail -1 > "$WORK/$name.r"
    else
      local extra=()
      [ "$who" = cycles-unbiased ] && extra=(--clamp-indirect 0 --blur-glossy 0)
      /usr/bin/time -f %e -o "$WORK/$name.t" blender -b --factory-startup --python "$PEERS/cycles_furball.py" -- \
        --hair "$HAIR" --res 256 --spp "$spp" --seed "$seed" --shape thick --bounces 1 --sun --offset -2 --threads 2 \
        "${extra[@]}" --out "$WORK/$name.exr" > "$WORK/$name.log" 2>&1
      sed -n 's/^CYCLES_RENDER_SECONDS=//p' "$WORK/$name.log" | tail -1 > "$WORK/$name.r"
    fi
    [ -s "$WORK/$name.r" ] && [ -f "$WORK/$name.exr" ] || { echo "$name failed: see $WORK/$name.log" >&2; exit 2; }
    echo "  $name: wall $(tail -1 "$WORK/$name.t") s, render $(cat "$WORK/$name.r") s"
  }
  # rmse REF IMG: RMS error over R, G, B of every pixel.
  rmse() {  # (oiiotool --diff exits 1 when the images differ, as they do)
    { oiiotool "$1" --ch R,G,B "$2" --ch R,G,B --diff 2>&1 || true; } | sed -n 's/.*RMS error = \([0-9.eE+-]*\).*/\1/p' | head -1
  }

  echo "references, $REF_SPP spp, seed $REF_SEED"
  for who in $RENDERERS; do
    if [ "${REUSE_REFS:-0}" = 1 ] && [ -s "$WORK/ref_$who.exr" ] && [ -s "$WORK/ref_$who.t" ] && [ -s "$WORK/ref_$who.r" ]; then
      echo "  ref_$who: reused from $WORK"; continue
    fi
    render "ref_$who" "$who" "$REF_SPP" "$REF_SEED"
  done
  TMP_CSV=$WORK/equal-error.csv
  echo "renderer,spp,seed,wall_s,render_s,rmse" > "$TMP_CSV"
  for who in $RENDERERS; do
    echo "$who,$REF_SPP,$REF_SEED,$(tail -1 "$WORK/ref_$who.t"),$(cat "$WORK/ref_$who.r")," >> "$TMP_CSV"
  done
  echo "sweep: $SPPS spp"
  seed=0
  for spp in $SPPS; do
    seed=$((seed + 1))
    for who in $RENDERERS; do
      name="${who}_$spp"
      render "$name" "$who" "$spp" "$seed"
      e=$(rmse "$WORK/ref_$who.exr" "$WORK/$name.exr")
      [ -n "$e" ] || { echo "no RMS error for $name" >&2; exit 2; }
      echo "    rmse $e"
      echo "$who,$spp,$seed,$(tail -1 "$WORK/$name.t"),$(cat "$WORK/$name.r"),$e" >> "$TMP_CSV"
    done
  done
  cp "$TMP_CSV" "$CSV"
  echo "wrote $CSV; load $(cut -d' ' -f1-3 /proc/loadavg)"
fi

# The chart: the sweep rows only (the references have no RMSE), from the CSV.
"$BIN" plot-csv "$CSV" --x wall_s --y rmse --by renderer --point-label spp --log-x --log-y \
  --title "Fur ball 256², 2 threads: RMSE against each renderer's own reference" \
  --x-label "wall time, whole process (s)" --y-label "RMSE (linear RGB)" -o "$OUT" --stem equal-error

# The read-out: time (and samples) to reach each RMSE, interpolated log-log between neighbouring sweep points.
python3 - "$CSV" <<'EOF'
import csv, math, sys
rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["rmse"]]
def time_to(who, col, target):
    pts = sorted((int(r["spp"]), float(r[col]), float(r["rmse"])) for r in rows if r["renderer"] == who)
    for (_, t0, e0), (_, t1, e1) in zip(pts, pts[1:]):
        if min(e0, e1) <= target <= max(e0, e1) and e0 != e1:
            f = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
    return None  # outside the sweep
fmt = lambda t: "n/a" if t is None else f"{t:.2f}"
# Samples per pixel needed as well: the sampling's share, free of this shared machine's timing noise.
for col, what in (("wall_s", "wall time, whole process, s"), ("render_s", "own render time, s"),
                  ("spp", "samples per pixel")):
    peers = [w for w in ("cycles", "cycles-unbiased", "mitsuba") if any(r["renderer"] == w for r in rows)]
    print(f"\nto reach RMSE ({what}; targets: cuticle / mitsuba <= 0.6, cuticle / cycles <= 0.5):")
    print("| RMSE | cuticle | " + " | ".join(peers) + " | " + " | ".join(f"cuticle / {p}" for p in peers) + " |")
    print("|---:" * (2 + 2 * len(peers)) + "|")
    for target in (0.07, 0.05, 0.04, 0.03):
        a = time_to("cuticle", col, target)
        bs = [time_to(p, col, target) for p in peers]
        ratios = ["n/a" if a is None or b is None else f"{a / b:.2f}" for b in bs]
        print(f"| {target} | {fmt(a)} | " + " | ".join(fmt(b) for b in bs) + " | " + " | ".join(ratios) + " |")
EOF
