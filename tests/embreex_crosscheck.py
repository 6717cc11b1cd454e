"""Reference side of tests/embree_crosscheck.rs: trace the test's rays with PyPI `embreex`.

Usage: python embreex_crosscheck.py DIR

Reads from DIR (all .npy, little-endian, C order):
  verts.npy  float32 [V, 3]   mesh vertices
  tris.npy   int32   [T, 3]   triangle vertex indices
  org.npy    float32 [R, 3]   ray origins
  dir.npy    float32 [R, 3]   ray directions (not normalised)
  tfar.npy   float32 [R]      ray ends, finite or +inf (tnear is 0: embreex fixes it)
Writes to DIR:
  ref_t.npy    float32 [R]  closest hit distance, +inf on a miss
  ref_prim.npy int32   [R]  primitive id of the hit, -1 on a miss
  ref_occ.npy  int32   [R]  1 if blocked within [0, tfar], else 0

embreex 4.4.0.post1 (Embree 4.4) facts this relies on, checked below where possible:
`EmbreeScene(robust=True)` sets RTC_SCENE_FLAG_ROBUST (watertight traversal, as our wrapper
does); `run` traces one ray at a time with tnear = 0, mask all-ones and tfar from `dists`,
which it overwrites in place (so it gets a copy). With `output=1` it returns tfar, primID and
geomID per ray; a miss leaves tfar as given and sets primID = geomID = -1 (tfar = 1e37 only
when `dists` is omitted). The OCCLUDED query returns 0 when blocked and -1 when free.

Exit status 3 means embreex or numpy cannot be imported; 4 means embreex broke one of the
facts above.
"""

import sys

try:
    import numpy as np
    from embreex import mesh_construction, rtcore_scene
except ImportError as e:  # reported by the Rust test with instructions
    sys.stderr.write(f"cannot import embreex/numpy: {e}\n")
    sys.exit(3)


def fail(msg: str) -> None:
    sys.stderr.write(f"embreex does not behave as tests/embreex_crosscheck.py expects: {msg}\n")
    sys.exit(4)


def main(d: str) -> None:
    verts = np.ascontiguousarray(np.load(f"{d}/verts.npy"), dtype=np.float32)
    tris = np.ascontiguousarray(np.load(f"{d}/tris.npy"), dtype=np.int32)
    org = np.ascontiguousarray(np.load(f"{d}/org.npy"), dtype=np.float32)
    dirs = np.ascontiguousarray(np.load(f"{d}/dir.npy"), dtype=np.float32)
    tfar = np.ascontiguousarray(np.load(f"{d}/tfar.npy"), dtype=np.float32)
    assert verts.ndim == 2 and verts.shape[1] == 3, verts.shape
    assert tris.ndim == 2 and tris.shape[1] == 3, tris.shape
    assert org.shape == dirs.shape and org.shape == (tfar.shape[0], 3), (org.shape, dirs.shape, tfar.shape)

    scene = rtcore_scene.EmbreeScene(robust=True)
    mesh_construction.TriangleMesh(scene, verts, tris)

    res = scene.run(org, dirs, dists=tfar.copy(), query="INTERSECT", output=1)
    prim = np.asarray(res["primID"], dtype=np.int32)
    geom = np.asarray(res["geomID"], dtype=np.int32)
    t_out = np.asarray(res["tfar"], dtype=np.float32)
    hit = prim >= 0
    if not np.array_equal(hit, geom == 0) or not np.all(geom[~hit] == -1):
        fail("geomID is not 0 on hits and -1 on misses")
    if not np.array_equal(t_out[~hit], tfar[~hit]):
        fail("a miss changed tfar")
    if np.any(t_out[hit] > tfar[hit]) or np.any(t_out[hit] < 0):
        fail("a hit distance lies outside [0, tfar]")
    t = np.where(hit, t_out, np.float32(np.inf))

    occ = np.asarray(scene.run(org, dirs, dists=tfar.copy(), query="OCCLUDED"))
    if not np.all((occ == 0) | (occ == -1)):
        fail(f"OCCLUDED returned values other than 0 and -1: {np.unique(occ)}")
    blocked = (occ == 0).astype(np.int32)

    try:
        from importlib.metadata import version

        ver = version("embreex")
    except Exception:  # not installed as a distribution: only informative
        ver = "unknown version"
    print(f"embreex {ver}, numpy {np.__version__}, {len(tris)} triangles, {len(org)} rays, {int(hit.sum())} hits")

    np.save(f"{d}/ref_t.npy", t.astype("<f4"))
    np.save(f"{d}/ref_prim.npy", prim.astype("<i4"))
    np.save(f"{d}/ref_occ.npy", blocked.astype("<i4"))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.stderr.write(__doc__)
        sys.exit(2)
    main(sys.argv[1])
