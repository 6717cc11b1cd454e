#!/usr/bin/env python3
"""Boundary-term variance and CPU of two dtr binaries, interleaved seed by seed.

usage: relvar.py OLD NEW SCENE PARAM SPP_BOUNDARY NSEEDS SEED0 [-- extra dtr args]

Each seed renders `--diff PARAM --estimators boundary --spp-boundary SPP_BOUNDARY --spp 1
--threads 1` with each binary, pinned to core 0. Prints, per binary, the edges the secondary
stage drew, the relative variance sum(var) / |mean|^2 of the derivative film over the seeds,
the image total (mean and standard error) and the run JSON's boundary CPU seconds (median,
range), then the ratios new / old and CPU x variance new / old (the work to an equal error).
Needs numpy.
"""
import json, os, subprocess, sys, tempfile

import numpy as np

args = sys.argv[1:]
extra = args[args.index('--') + 1:] if '--' in args else []
args = args[:args.index('--')] if '--' in args else args
if len(args) != 7:
    sys.exit(__doc__)
old, new, scene, param, sppb, ns, s0 = args
ns, s0 = int(ns), int(s0)
bins = {'old': old, 'new': new}
runs = {t: {'films': [], 'cpu': [], 'edges': None} for t in bins}
with tempfile.TemporaryDirectory() as out:
    for s in range(s0, s0 + ns):
        for t, b in bins.items():
            pre = os.path.join(out, t)
            cmd = ['taskset', '-c', '0', b, 'render', scene, '-o', pre, '--diff', param, '--estimators', 'boundary',
                   '--spp-boundary', sppb, '--spp', '1', '--seed', str(s), '--threads', '1', '-q'] + extra
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode:
                sys.exit(f'{" ".join(cmd)}: {r.stderr}')
            runs[t]['films'].append(np.load(f'{pre}.d_{param}.npy').astype(np.float64))
            with open(pre + '.json') as f:
                j = json.load(f)
            runs[t]['cpu'].append(j['boundary']['cpu_seconds'])
            runs[t]['edges'] = j['boundary']['edges']
res = {}
for t in bins:
    f = np.array(runs[t]['films'])
    m = f.mean(0)
    rv = f.var(0, ddof=1).sum() / (m ** 2).sum()
    tot = f.sum(axis=tuple(range(1, f.ndim)))
    c = np.array(runs[t]['cpu'])
    res[t] = (rv, np.median(c))
    print(f'{t}: edges {runs[t]["edges"]}, rel var {rv:.5f}, total {tot.mean():.4f} ± {tot.std(ddof=1) / np.sqrt(ns):.4f}, '
          f'boundary cpu median {np.median(c):.3f} s ({c.min():.3f}-{c.max():.3f})')
(rv_o, c_o), (rv_n, c_n) = res['old'], res['new']
print(f'rel var new/old {rv_n / rv_o:.3f}, cpu new/old {c_n / c_o:.3f}, work to equal error new/old {rv_n * c_n / (rv_o * c_o):.3f}')
