#!/usr/bin/env bash
# End-to-end check of local_cluster.sh: start a cluster in a fresh DIR, run a 4-task
# job array plus a dependent job that gathers its outputs, check the files, stop,
# and check that no daemon is left behind.   Usage: smoke_test.sh [DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
dir=${1:-/tmp/slurm-smoke}
rm -rf "$dir"
"$here/local_cluster.sh" start "$dir"
trap '"$here/local_cluster.sh" stop "$dir"' EXIT
# shellcheck disable=SC1091
source "$dir/env.sh"

work=$dir/jobs   # jobs run as root on this node, so any absolute path works
mkdir -p "$work"
# --chdir: where the job runs (relative out_*.txt land there); -o: Slurm's own log, %A_%a = array/task.
arr=$(sbatch --parsable --chdir="$work" -o "$work/array-%A_%a.log" --array=0-3 \
  --wrap 'echo $SLURM_ARRAY_TASK_ID > out_$SLURM_ARRAY_TASK_ID.txt')
# afterok on the array id waits for all of its tasks; --wait blocks until this job ends
# and returns its exit code (polls slurmctld, no accounting daemon needed).
timeout 120 sbatch --wait --parsable --chdir="$work" -o "$work/gather-%j.log" \
  --dependency="afterok:$arr" --wrap 'cat out_0.txt out_1.txt out_2.txt out_3.txt > all.txt'

[ "$(cat "$work/all.txt")" = "$(printf '0\n1\n2\n3')" ] || { echo "bad all.txt" >&2; exit 1; }
ls "$work"/array-"${arr}"_{0,1,2,3}.log >/dev/null
[ -z "$(squeue -h -o %i)" ] || { echo "queue not empty" >&2; squeue >&2; exit 1; }

trap - EXIT
"$here/local_cluster.sh" stop "$dir"
left=$(grep -lE '^(munged|slurm)' /proc/[0-9]*/comm 2>/dev/null || true)
[ -z "$left" ] || { echo "daemons left running: $left" >&2; exit 1; }
echo "smoke test OK ($dir)"
