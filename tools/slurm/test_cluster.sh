#!/usr/bin/env bash
# Renders a scene as 4 shards on a real one-node Slurm cluster (started here on loopback
# by local_cluster.sh), merges them in a dependent job, and compares the merge with one
# process rendering the same scene: equal up to float reordering (src/cli/shard_set.rs).
# Run by tools/test; needs `local_cluster.sh install` (as root) and target/release/dtr.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
here=$root/tools/slurm
export DTR=$root/target/release/dtr
[ -x "$DTR" ] || { echo "test_cluster: build dtr first (cargo build --release)" >&2; exit 1; }
if ! command -v slurmctld >/dev/null; then
  echo "test_cluster: Slurm is not installed (tools/slurm/local_cluster.sh install)" >&2
  exit 1
fi
dir=$(mktemp -d /tmp/dtr-slurm.XXXXXX)
chmod 755 "$dir"   # munged wants every folder above its socket searchable by all
"$here/local_cluster.sh" start "$dir/cluster" >/dev/null
trap '"$here/local_cluster.sh" stop "$dir/cluster" >/dev/null; rm -rf "$dir"' EXIT
# shellcheck disable=SC1091
source "$dir/cluster/env.sh"
cd "$dir"
scene=$root/scenes/silhouette_slide.toml
opts=(--spp 8 --spp-boundary 2 --diff cube_x)
read -r array merge < <("$here/submit.sh" "$scene" 4 shards merged "${opts[@]}")
for _ in $(seq 600); do
  [ -z "$(squeue -h -o %i)" ] && break
  sleep 0.2
done
[ -z "$(squeue -h -o %i)" ] || { echo "test_cluster: jobs still queued after 120 s" >&2; squeue >&2; exit 1; }
state=$(scontrol show job "$merge" | grep -o 'JobState=[A-Z]*')
if [ "$state" != "JobState=COMPLETED" ] || [ ! -e merged.json ]; then
  echo "test_cluster: merge job $merge: $state" >&2
  cat shards/slurm-* >&2 || true
  exit 1
fi
"$DTR" render "$scene" "${opts[@]}" -o single -q
"$root/.venv/bin/python" - <<'PY'
import json, numpy as np
for f in ["npy", "d_cube_x.npy"]:
    a, b = np.load("single." + f), np.load("merged." + f)
    assert a.shape == b.shape, f
    scale = np.abs(a).max()
    assert scale > 0, f + " is empty"
    err = np.abs(a - b).max() / scale
    assert err <= 1e-5, f"{f}: merged differs from the single render by {err:.2e} of its largest value"
m = json.load(open("merged.json"))
assert len(m["merged"]["shards"]) == 4
assert m["paths"] == json.load(open("single.json"))["paths"]
PY
echo "slurm: array job $array (4 shards) + merge job $merge == one render: OK"
