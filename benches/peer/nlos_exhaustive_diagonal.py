#!/usr/bin/env python3
"""Does each renderer's exhaustive capture hold its confocal capture on its diagonal?

An exhaustive scan lights every laser point for every sensor point; its entries with laser point
= sensor point are what the confocal scan of the same grid measures, in expectation. This renders
benches/peer/nlos_peer.toml at an 8 x 8 grid both ways, with dtr and with mitransient (the scene
and conversion of compare_nlos.py; mitransient with and without its hidden-geometry sampling),
and prints per grid point the ratio of the time-summed diagonal entry to the confocal one (rows
y, columns x). Expect 1 within noise (about 2 % per point here). Run as
`benches/peer/run.sh nlos-diagonal` (the peer venv). Optional, not in CI.
"""
import importlib, os, sys, tomllib
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
SPP, SEEDS, GRID = 256, 4, 8


def captures(scan):
    """(dtr's capture, {hidden-geometry sampling: mitransient's converted capture}), seed means."""
    os.environ["PEER_SCAN"], os.environ["PEER_GRID"] = scan, str(GRID)
    import compare_nlos
    importlib.reload(compare_nlos)  # its module constants follow PEER_SCAN
    import mitsuba as mi
    os.makedirs(compare_nlos.OUT, exist_ok=True)
    d = tomllib.load(open(compare_nlos.SCENE, "rb"))
    ours = np.mean([compare_nlos.run_dtr(SPP, 1 + s, os.path.join(compare_nlos.OUT, f"diag{s}"))[0]
                    for s in range(SEEDS)], axis=0)
    theirs = {}
    for hg in (True, False):
        sc = compare_nlos.mitsuba_scene(d)
        sc["integrator"]["nlos_hidden_geometry_sampling"] = hg
        scene = mi.load_dict(sc)
        f = compare_nlos.laser_factor(d)
        theirs[hg] = np.mean([compare_nlos.converted(np.array(mi.render(scene, spp=SPP, seed=1 + s)[1])[..., 0], f)
                              for s in range(SEEDS)], axis=0)
    return ours, theirs


def main():
    conf, exh = captures("confocal"), captures("exhaustive")
    n = GRID * GRID
    diag = lambda e: e[np.arange(n), np.arange(n)].sum(-1)
    ratio = lambda e, c: (diag(e) / c.reshape(n, -1).sum(-1)).reshape(GRID, GRID)
    np.set_printoptions(precision=2, suppress=True)
    print("dtr: exhaustive diagonal / confocal\n", ratio(exh[0], conf[0]))
    for hg in (True, False):
        print(f"mitransient (hidden-geometry sampling {hg}): exhaustive diagonal / confocal\n",
              ratio(exh[1][hg], conf[1][hg]))


if __name__ == "__main__":
    main()
