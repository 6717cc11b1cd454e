#!/usr/bin/env python3
"""Patches mitransient 1.3.1's transient_path integrator in a venv so that a next-event
segment's optical path length uses the index of the medium the segment crosses.

Upstream (mitransient/integrators/transientpath.py, TransientPath.sample) adds the emitter
sample at `distance + ds.dist * η`, where η is the index of the medium the path is in *before*
the vertex scatters (it is updated by `η *= bsdf_sample.eta` only after the BSDF sample). When
the emitter is sampled through a refraction (a rough dielectric vertex, the path inside the
glass, the lamp outside), the segment lies in the other medium and is placed (η_in/η_out − 1) ×
its length late. The patch computes the far side's index for transmitted emitter samples from
the BSDF's `eta` attribute (int/ext index ratio of `roughdielectric`) and uses it for the
primal and the forward-mode contributions.

Usage: nee_opl_fix.py <venv>   (edits <venv>'s installed file in place; refuses a file that
does not look like the 1.3.1 source, and does nothing on an already patched file). benches/peer/run.sh
applies it to a copy of the peer venv when PEER_NEE_FIX=1.
"""
import glob, os, re, sys

MARK = "# dtr nee_opl_fix"

# inserted after the emitter sample's contribution is computed (`wo` is the emitter direction
# in the local frame); the index of the medium on the emitter's side of the vertex
INSERT = f"""
            {MARK}: the emitter segment lies in the medium on the side of `wo`
            cos_i = mi.Frame3f.cos_theta(si.wi)
            through = active_em & (cos_i * mi.Frame3f.cos_theta(wo) < 0) \\
                & bsdf.has_attribute("eta", active_em)
            eta_b = bsdf.eval_attribute_1("eta", si, through)
            η_em = dr.select(through, η * dr.select(cos_i > 0, eta_b, dr.rcp(eta_b)), η)
"""

ANCHOR = "                Lr_dir = β * mi.Spectrum(mis_em) * bsdf_value_em * em_weight\n"
# the three emitter-segment distances (primal, backward weight, forward derivative)
OLD = re.compile(r"distance \+ ds\.dist \*\s*η\b")


def patch(path):
    src = open(path, encoding="utf-8").read()
    if MARK in src:
        print(f"{path}: already patched")
        return
    if src.count(ANCHOR) != 1:
        sys.exit(f"{path}: expected one line `{ANCHOR.strip()}` (mitransient 1.3.1); not patched")
    n = len(OLD.findall(src))
    if n != 3:
        sys.exit(f"{path}: expected 3 emitter-segment distances `distance + ds.dist * η`, found {n}; not patched")
    src = src.replace(ANCHOR, ANCHOR + INSERT)
    src = OLD.sub("distance + ds.dist * η_em", src)
    with open(path, "w", encoding="utf-8") as f:
        f.write(src)
    print(f"{path}: patched")


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: nee_opl_fix.py <venv>")
    hits = glob.glob(os.path.join(sys.argv[1], "lib", "python3*", "site-packages", "mitransient",
                                  "integrators", "transientpath.py"))
    if len(hits) != 1:
        sys.exit(f"{sys.argv[1]}: no single mitransient/integrators/transientpath.py in the venv")
    patch(hits[0])


if __name__ == "__main__":
    main()
