#!/usr/bin/env bash
# Submits a render as N shards (a Slurm job array) and the merge as a job that depends on
# all of them; prints "ARRAY_JOB MERGE_JOB".
#   tools/slurm/submit.sh SCENE N OUTDIR PREFIX [dtr render options...]
# Extra sbatch options (partition, time, cpus per task) go in SBATCH_ARGS, e.g.
#   SBATCH_ARGS="--partition=gpu --cpus-per-task=16 --time=4:00:00"
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
scene=$1 n=$2 out=$3 prefix=$4
shift 4
mkdir -p "$out"
# shellcheck disable=SC2086
array=$(sbatch --parsable ${SBATCH_ARGS:-} --chdir="$PWD" -o "$out/slurm-%A_%a.log" \
  --array=0-$((n - 1)) "$here/render_shard.sbatch" "$scene" "$out" "$@")
array=${array%%;*}
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_ARGS:-} --chdir="$PWD" -o "$out/slurm-merge-%j.log" \
  --dependency="afterok:$array" "$here/merge.sbatch" "$out" "$prefix")
echo "$array ${merge%%;*}"
