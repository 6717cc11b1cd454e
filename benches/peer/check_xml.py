#!/usr/bin/env python3
"""Does Mitsuba 3 / mitransient read a Mitsuba XML scene as dtr does? Optional, not in CI.

Renders PEER_XML (default scenes/cornell_box.xml) with `dtr render` (which converts the XML,
src/scene/mitsuba/) and with mitransient (mi.load_file on the same file), PEER_SEEDS
independent seeds each at PEER_SPP, and tests agreement within noise as
compare_mitransient.py does: per-bin totals and 8x8 blocks of the time-summed image, z-scores
of the difference of the two renderers' means (agreement.py). Needs the peer venv that
benches/peer/run.sh sets up and a release build (target/release/dtr, or DTR=path):
  bench-out/peer-venv/bin/python benches/peer/check_xml.py
(with DRJIT_LIBLLVM_PATH as run.sh sets it where Dr.Jit's default LLVM is too old).
"""
import os, subprocess, sys
import numpy as np
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
import mitransient as mitr  # noqa: E402,F401

import agreement  # noqa: E402  (beside this script)

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
    ok = agreement.agree(ours, theirs)
    print(f"total: ours {np.mean([x.sum() for x in ours]):.4f}, mitransient {np.mean([x.sum() for x in theirs]):.4f}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
