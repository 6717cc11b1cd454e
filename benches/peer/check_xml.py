#!/usr/bin/env python3
"""Does Mitsuba 3 / mitransient read a Mitsuba XML scene as dtr does? Optional, not in CI.

Renders PEER_XML (default scenes/cornell_box.xml) with `dtr render` (which converts the XML,
src/scene/mitsuba/) and with mitransient (mi.load_file on the same file), PEER_SEEDS
independent seeds each at PEER_SPP, and tests agreement within noise as
compare_mitransient.py does: per-bin totals and 8x8 blocks of the time-summed image, z-scores
of the difference of the two renderers' means. Needs the peer venv (benches/peer/run.sh) and
a release build (target/release/dtr, or DTR=path).
"""
import math, os, subprocess, sys
import numpy as np
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
import mitransient as mitr  # noqa: E402,F401

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
XML = os.environ.get("PEER_XML", os.path.join(ROOT, "scenes", "cornell_box.xml"))
DTR = os.environ.get("DTR", os.path.join(ROOT, "target", "release", "dtr"))
SPP = int(os.environ.get("PEER_SPP", "16"))
SEEDS = int(os.environ.get("PEER_SEEDS", "6"))
OUT = os.path.join(ROOT, "bench-out", "peer-xml")


def main():
    os.makedirs(OUT, exist_ok=True)
    scene = mi.load_file(XML)
    ours, theirs = [], []
    for k in range(SEEDS):
        prefix = os.path.join(OUT, f"ours{k}")
        subprocess.run([DTR, "render", XML, "--spp", str(SPP), "--seed", str(1 + k), "-o", prefix, "-q"], check=True)
        ours.append(np.load(prefix + ".npy"))
        _, transient = mi.render(scene, spp=SPP, seed=1 + k)
        theirs.append(np.array(transient)[..., :3])
    print("shapes: ours", ours[0].shape, "theirs", theirs[0].shape)
    bins = lambda a: a.sum(axis=(0, 1, 3))
    blocks = lambda a: a.sum(axis=(2, 3)).reshape(a.shape[0] // 8, 8, a.shape[1] // 8, 8).sum(axis=(1, 3)).ravel()
    agree = True
    for name, agg in (("per-bin totals", bins), ("8x8 blocks of the time-summed image", blocks)):
        a = np.array([agg(x) for x in ours])
        b = np.array([agg(x) for x in theirs])
        se2 = a.var(axis=0, ddof=1) / SEEDS + b.var(axis=0, ddof=1) / SEEDS
        used = se2 > 0
        z = (a.mean(axis=0) - b.mean(axis=0))[used] / np.sqrt(se2[used])
        n = int(used.sum())
        chi2 = float((z ** 2).sum())
        zmax = float(np.abs(z).max()) if n else 0.0
        var_t = (SEEDS - 1) / (SEEDS - 3) if SEEDS > 3 else 3.0
        ok = chi2 <= n * var_t + 4.0 * math.sqrt(2.0 * n) * var_t and zmax <= 6.0
        agree &= ok
        print(f"{name}: {n} entries, sum z^2 {chi2:.1f} (expected ~{n * var_t:.1f}), max |z| {zmax:.2f}: {'ok' if ok else 'DISAGREE'}")
    print(f"total: ours {np.mean([x.sum() for x in ours]):.4f}, mitransient {np.mean([x.sum() for x in theirs]):.4f}")
    return 0 if agree else 1


if __name__ == "__main__":
    sys.exit(main())
