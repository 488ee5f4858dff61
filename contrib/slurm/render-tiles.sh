#!/usr/bin/env bash
# Renders one frame split into N tiles on a Slurm cluster: a job array of N tasks (one `cuticle render --tile I/N`
# each) and a merge job that starts only when every task succeeded (`--dependency=afterok`). Nothing here is
# specific to one cluster: partitions, accounts, time limits and modules come from the usual SBATCH_* environment
# variables or sbatch's own defaults (e.g. SBATCH_PARTITION=render).
#
#   contrib/slurm/render-tiles.sh [-n TILES] [-f A..B] [-c CUTICLE] SCENE.toml OUT.exr [-- RENDER-ARGS...]
#
# With -f, every frame of A..B gets its own N tiles (one array task per frame × tile) and its own merge, all
# from one array. OUT's directory must be shared by the nodes (tiles are written to OUT's directory/tiles/).
# Prints the job ids: "array <id>" and "merge <id>".
set -euo pipefail
tiles=4; frames=""; bin=cuticle; threads=${SLURM_CPUS_PER_TASK:-}
while getopts "n:f:c:" o; do
  case $o in
    n) tiles=$OPTARG ;;
    f) frames=$OPTARG ;;
    c) bin=$OPTARG ;;
    *) echo "usage: $0 [-n TILES] [-f A..B] [-c CUTICLE] SCENE OUT.exr [-- RENDER-ARGS...]" >&2; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
scene=${1:?usage: render-tiles.sh [-n TILES] [-f A..B] [-c CUTICLE] SCENE OUT.exr [-- RENDER-ARGS...]}
out=${2:?usage: render-tiles.sh [-n TILES] [-f A..B] [-c CUTICLE] SCENE OUT.exr [-- RENDER-ARGS...]}
shift 2
[ "${1:-}" = "--" ] && shift
extra=("$@")
scene=$(realpath "$scene"); outdir=$(realpath "$(dirname "$out")"); name=$(basename "$out" .exr)
bin=$(command -v "$bin" || realpath "$bin")
mkdir -p "$outdir/tiles" "$outdir/logs"

if [ -n "$frames" ]; then first=${frames%..*}; last=${frames#*..}; else first=0; last=0; fi
count=$(( (last - first + 1) * tiles ))

# One task: its frame and tile from SLURM_ARRAY_TASK_ID (frame-major).
task=$(cat <<SCRIPT
#!/usr/bin/env bash
set -euo pipefail
id=\${SLURM_ARRAY_TASK_ID:?}
frame=\$(( $first + id / $tiles )); tile=\$(( id % $tiles ))
frame_args=(); suffix=""
if [ -n "$frames" ]; then frame_args=(--frames "\$frame..\$frame"); suffix=".\$(printf %04d "\$frame")"; fi
exec "$bin" render "$scene" -q ${threads:+--threads $threads} --tile "\$tile/$tiles" "\${frame_args[@]}" \
  -o "$outdir/tiles/$name.tile\$(printf %03d "\$tile").exr" $(printf '%q ' "${extra[@]}")
SCRIPT
)
array=$(printf '%s\n' "$task" | sbatch --parsable --job-name="cuticle-$name" --array="0-$((count - 1))" \
  --output="$outdir/logs/$name-%A_%a.log")
array=${array%%;*}

# The merge: one per frame, after every tile task succeeded.
merge=$(cat <<SCRIPT
#!/usr/bin/env bash
set -euo pipefail
for frame in \$(seq $first $last); do
  suffix=""; [ -n "$frames" ] && suffix=".\$(printf %04d "\$frame")"
  tiles=(); for t in \$(seq 0 $((tiles - 1))); do tiles+=("$outdir/tiles/$name.tile\$(printf %03d "\$t")\$suffix.exr"); done
  "$bin" merge -o "$outdir/$name\$suffix.exr" "\${tiles[@]}"
done
SCRIPT
)
merge_id=$(printf '%s\n' "$merge" | sbatch --parsable --job-name="cuticle-$name-merge" \
  --dependency="afterok:$array" --kill-on-invalid-dep=yes --output="$outdir/logs/$name-merge-%j.log")
merge_id=${merge_id%%;*}
echo "array $array"
echo "merge $merge_id"
