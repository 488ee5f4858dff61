#!/usr/bin/env bash
# Opt-in test of contrib/slurm/ against a real single-node Slurm (Debian's slurm-wlm): installs slurm-wlm and munge
# if missing, starts munged, slurmctld and slurmd on localhost with a minimal slurm.conf, submits a 4-tile frame
# through contrib/slurm/render-tiles.sh, waits for the merge job, and checks the merged frame against a
# single-machine render (`idiff -a`, zero tolerance). Needs root. Leaves the daemons it started stopped.
#
#   scripts/slurm-test.sh [CUTICLE]     # default: target/release/cuticle (built if missing)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/cuticle}")
[ -x "$bin" ] || { cargo build --release --quiet; bin=$(realpath target/release/cuticle); }
command -v slurmctld >/dev/null || DEBIAN_FRONTEND=noninteractive apt-get install -y -q slurm-wlm munge >/dev/null
work=$(mktemp -d /tmp/cuticle-slurm.XXXXXX)
conf=$work/etc; mkdir -p "$conf" "$work/state" "$work/spool" "$work/out"
host=$(hostname -s); cpus=$(nproc)
mem=$(awk '/MemTotal/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)

# munge: a key of our own, its daemon on a socket of our own.
mkdir -p /etc/munge /var/run/munge /var/log/munge /var/lib/munge
[ -s /etc/munge/munge.key ] || { dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 2>/dev/null; }
chown -R munge:munge /etc/munge /var/run/munge /var/log/munge /var/lib/munge 2>/dev/null || true
chmod 400 /etc/munge/munge.key
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  [ -f /var/run/munge/cuticle-test.pid ] && kill "$(cat /var/run/munge/cuticle-test.pid)" 2>/dev/null || true
}
trap cleanup EXIT
if ! munge -n >/dev/null 2>&1; then
  runuser -u munge -- /usr/sbin/munged --pid-file=/var/run/munge/cuticle-test.pid 2>/dev/null || /usr/sbin/munged -f --pid-file=/var/run/munge/cuticle-test.pid
  sleep 1
fi
munge -n | unmunge >/dev/null

cat >"$conf/slurm.conf" <<CONF
ClusterName=cuticle-test
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=render Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$conf/slurm.conf
/usr/sbin/slurmctld -D -f "$SLURM_CONF" >"$work/slurmctld.out" 2>&1 & pids+=($!)
sleep 2
/usr/sbin/slurmd -D -f "$SLURM_CONF" >"$work/slurmd.out" 2>&1 & pids+=($!)
for _ in $(seq 30); do sinfo -h -o %T 2>/dev/null | grep -q idle && break; sleep 1; done
sinfo

args=(--res 96x72 --spp 4)
ids=$(SLURM_CPUS_PER_TASK=1 contrib/slurm/render-tiles.sh -n 4 -c "$bin" scenes/furball.toml "$work/out/frame.exr" -- "${args[@]}")
echo "$ids"
merge=$(awk '/^merge/ {print $2}' <<<"$ids")
for _ in $(seq 600); do
  state=$(scontrol show job "$merge" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p')
  case $state in COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY) break ;; esac
  sleep 1
done
echo "merge job $merge: $state"
squeue; cat "$work"/out/logs/*.log || true
[ "$state" = COMPLETED ] || { echo "FAIL: merge job $state (logs in $work)"; exit 1; }
"$bin" render scenes/furball.toml -q -o "$work/single.exr" --threads 2 "${args[@]}"
if idiff -a "$work/single.exr" "$work/out/frame.exr"; then
  echo "PASS: the 4 Slurm tiles merged equal the single-machine render bit for bit ($work)"
else
  echo "FAIL: merged frame differs from the single-machine render ($work)"; exit 1
fi
