#!/bin/bash
# A/B of two dtr binaries on one render, interleaved: medians and ranges of the interior's
# wall seconds (the run JSON's wall_seconds), peak RSS, and whether the outputs are the same
# bytes. Used for BENCHMARKS.md, "Large films".
#
# usage: benches/ab/render_ab.sh OLD_DTR NEW_DTR REPEATS -- RENDER_ARGS...
# e.g.   benches/ab/render_ab.sh old/dtr target/release/dtr 3 -- scenes/cornell_box.toml \
#          --spp 16 --set camera.resolution.0=256 --set camera.resolution.1=256 \
#          --set film.bins=2000 --seed 1 --threads 2
set -euo pipefail
old=$1 new=$2 repeats=$3
shift 3
[ "${1:-}" = "--" ] && shift
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for r in $(seq "$repeats"); do
  for side in old new; do
    bin=$old
    [ $side = new ] && bin=$new
    /usr/bin/time -f %M -o "$out/$side.rss" "$bin" render "$@" -q -o "$out/$side" > /dev/null
    python3 - "$out/$side.json" "$out/$side.rss" "$side" >> "$out/rows" <<'PY'
import json, sys
print(sys.argv[3], json.load(open(sys.argv[1]))["wall_seconds"], open(sys.argv[2]).read().split()[-1])
PY
  done
done
python3 - "$out/rows" <<'PY'
import statistics, sys
rows = {}
for line in open(sys.argv[1]):
    side, wall, rss = line.split()
    rows.setdefault(side, []).append((float(wall), int(rss)))
for side in ("old", "new"):
    w = [x[0] for x in rows[side]]
    print(f"{side}: wall s median {statistics.median(w):.3f} ({min(w):.3f}-{max(w):.3f}), "
          f"peak RSS {max(x[1] for x in rows[side]) // 1024} MB")
PY
same=yes
for f in "$out"/old*.npy; do
  name=$(basename "$f")
  cmp -s "$f" "$out/new${name#old}" || same=no
done
echo "same bytes (every .npy): $same"
