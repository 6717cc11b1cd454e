"""Reference side of tests/embree_crosscheck.rs: trace the test's rays with PyPI `embreex`.

Usage: python embreex_crosscheck.py DIR

Reads from DIR (all .npy, little-endian, C order):
  verts.npy  float32 [V, 3]   mesh vertices
  tris.npy   int32   [T, 3]   triangle vertex indices
  org.npy    float32 [R, 3]   ray origins
  dir.npy    float32 [R, 3]   ray directions (not normalised)
  tfar.npy   float32 [R]      ray ends (tnear is 0: embreex fixes it)
Writes to DIR:
  ref_t.npy    float32 [R]  closest hit distance, +inf on a miss
  ref_prim.npy int32   [R]  primitive id of the hit, -1 on a miss
  ref_occ.npy  int32   [R]  1 if blocked within [0, tfar], else 0

embreex 4.4.0.post1 (Embree 4.4, robust scene by default) facts this relies on: `run` with
output=1 returns tfar and primID per ray; a miss leaves tfar as given and sets primID = -1;
the OCCLUDED query returns 0 when blocked and -1 when free. `dists` is overwritten in place,
so it gets a copy.

Exit status 3 means embreex or numpy cannot be imported.
"""

import sys

try:
    import numpy as np
    from embreex import mesh_construction, rtcore_scene
except ImportError as e:  # reported by the Rust test with instructions
    sys.stderr.write(f"cannot import embreex/numpy: {e}\n")
    sys.exit(3)


def main(d: str) -> None:
    verts = np.load(f"{d}/verts.npy").astype(np.float32)
    tris = np.load(f"{d}/tris.npy").astype(np.int32)
    org = np.ascontiguousarray(np.load(f"{d}/org.npy"), dtype=np.float32)
    dirs = np.ascontiguousarray(np.load(f"{d}/dir.npy"), dtype=np.float32)
    tfar = np.ascontiguousarray(np.load(f"{d}/tfar.npy"), dtype=np.float32)
    assert verts.ndim == 2 and verts.shape[1] == 3, verts.shape
    assert tris.ndim == 2 and tris.shape[1] == 3, tris.shape
    assert org.shape == dirs.shape and org.shape == (tfar.shape[0], 3)

    scene = rtcore_scene.EmbreeScene(robust=True)
    mesh_construction.TriangleMesh(scene, verts, tris)

    res = scene.run(org, dirs, dists=tfar.copy(), query="INTERSECT", output=1)
    prim = np.asarray(res["primID"], dtype=np.int32)
    t = np.where(prim >= 0, np.asarray(res["tfar"], dtype=np.float32), np.float32(np.inf))

    occ = scene.run(org, dirs, dists=tfar.copy(), query="OCCLUDED")
    blocked = (np.asarray(occ) != -1).astype(np.int32)

    np.save(f"{d}/ref_t.npy", t.astype("<f4"))
    np.save(f"{d}/ref_prim.npy", prim.astype("<i4"))
    np.save(f"{d}/ref_occ.npy", blocked.astype("<i4"))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.stderr.write(__doc__)
        sys.exit(2)
    main(sys.argv[1])
