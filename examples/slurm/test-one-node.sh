#!/usr/bin/env bash
# CI test: a real one-node Slurm cluster (slurmctld + slurmd in the
# foreground, auth/none, every path in a temporary directory; recipe from
# shared/notes/slurm-single-node.md) runs bake-level.sh on the bundled
# Cornell box in 3 array tasks and the dependent merge, and the merged file
# must equal a bake in one process byte for byte.
#
#   examples/slurm/test-one-node.sh PATH/TO/aobake
#
# Needs Debian's slurm-wlm (.ci/run installs it) and root.
set -euo pipefail
bin=$(realpath "$1")
repo=$(cd "$(dirname "$0")/../.." && pwd)
d=$(mktemp -d)
mkdir -p "$d/state" "$d/spool" "$d/out"
host=$(hostname)
cat > "$d/slurm.conf" <<CONF
ClusterName=local
SlurmctldHost=$host
AuthType=auth/none
CredType=cred/none
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$d/state
SlurmdSpoolDir=$d/spool
SlurmctldPidFile=$d/slurmctld.pid
SlurmdPidFile=$d/slurmd.pid
SlurmctldLogFile=$d/slurmctld.log
SlurmdLogFile=$d/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
NodeName=$host CPUs=$(nproc) RealMemory=8000 State=UNKNOWN
PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$d/slurm.conf
slurmctld -D -f "$SLURM_CONF" & ctld=$!
slurmd -D -f "$SLURM_CONF" & sd=$!
cleanup() { kill "$ctld" "$sd" 2>/dev/null || true; wait 2>/dev/null || true; rm -rf "$d"; }
trap cleanup EXIT
for _ in $(seq 60); do [ "$(sinfo -h -o %T 2>/dev/null)" = idle ] && break; sleep 1; done
[ "$(sinfo -h -o %T)" = idle ] || { echo "slurm test: the node never came up"; cat "$d"/*.log; exit 1; }

in=$repo/assets/cornell_box.glb
opts=(--texel-density 0.2 --page-size 128 --quality 16)
"$bin" "$in" "$d/out/single.glb" "${opts[@]}" -q
AOBAKE=$bin AOBAKE_CPUS=1 AOBAKE_LOGS=$d/out \
  "$repo/examples/slurm/bake-level.sh" 3 "$in" "$d/out/level.glb" "${opts[@]}"
ls "$d/out"
test "$(ls "$d"/out/level.glb.shard-*-of-3 | wc -l)" = 3
cmp "$d/out/single.glb" "$d/out/level.glb"
echo "slurm test: 3 array tasks and the merge through sbatch: merged file byte-identical to one process"
