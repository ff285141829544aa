#!/usr/bin/env bash
# Submits a sharded bake of IN.glb into OUT.glb on N Slurm array tasks and
# its merge, and waits for the merge (exit status: the merge's).
#
#   examples/slurm/bake-level.sh N IN.glb OUT.glb [aobake options]
#
# Paths must be absolute (or valid in every task's working directory) and
# on a file system every node sees. AOBAKE names the binary if it is not on
# PATH; AOBAKE_CPUS the cores per task (default 4).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
n=$1
in=$2
out=$3
shift 3
logs=${AOBAKE_LOGS:-$(dirname "$out")}
jid=$(sbatch --parsable --array=0-$((n - 1)) --cpus-per-task="${AOBAKE_CPUS:-4}" \
  --output="$logs/aobake-shard-%a.out" \
  --export=ALL "$here/bake.sbatch" "$in" "$out" "$@")
echo "aobake: shards submitted as array job $jid"
sbatch --wait --parsable --dependency=afterok:"$jid" --kill-on-invalid-dep=yes \
  --output="$logs/aobake-merge.out" --export=ALL "$here/merge.sbatch" "$out"
