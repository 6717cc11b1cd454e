#!/usr/bin/env python3
"""Peer comparison against mitransient (Mitsuba 3, LLVM backend, CPU). Optional, not in CI.

Setup and run with benches/peer/run.sh. It renders scenes/cornell_box.toml (or PEER_SCENE, a file
in scenes/ made of rectangles and cubes: e.g. cornell_gold.toml, whose rough conductor maps to
Mitsuba's `roughconductor` with the GGX distribution, or cornell_glass.toml, whose rough glass
block maps to `roughdielectric`) with `dtr` (PEER_DTR, default target/release/dtr) and the
same scene, rebuilt from the TOML, with mitransient's transient_path integrator at equal
settings (resolution, bins, bin width, start, max depth = max_bounces + 1, Russian roulette
off, box pixel filter, camera segment counted). It checks first that the two transients agree
within noise (per-bin totals and 8x8 blocks of the time-summed image, z-scores of the
difference of means over PEER_SEEDS independent seeds per renderer; it stops if they
disagree), then times warm renders only, interleaved (ours, theirs, ours, ...; PEER_REPEATS each, after
one untimed warm-up render of each at the timed spp: Dr.Jit compiles a kernel per sample count,
so a warm-up at another spp leaves the first timed render compiling), each renderer's CPU
seconds from its own accounting (ours: the run JSON's interior cpu_seconds; theirs: process
time around mi.render), and reports medians with their ranges:
  - our paths per CPU-second / theirs (ratio of medians, and the range of the per-pair ratios),
  - our error at equal CPU time / theirs (errors against a high-spp dtr reference, scaled to
    equal time by error ∝ 1/√time, with the median CPU times).
"""
import json, math, os, subprocess, sys, time, tomllib
import numpy as np
import mitsuba as mi
import drjit as dr

mi.set_variant("llvm_ad_rgb")
import mitransient as mitr  # noqa: E402,F401

import agreement  # noqa: E402  (beside this script)
from agreement import rel_l2  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENE = os.path.join(ROOT, "scenes", os.environ.get("PEER_SCENE", "cornell_box.toml"))
DTR = os.environ.get("PEER_DTR", os.path.join(ROOT, "target", "release", "dtr"))
SPP = int(os.environ.get("PEER_SPP", "64"))
# independent seeds per renderer for the agreement test (standard errors from their spread)
SEEDS = int(os.environ.get("PEER_SEEDS", "6"))
REF_SPP = int(os.environ.get("PEER_REF_SPP", "1024"))
# interleaved timed renders per renderer (after the agreement renders and a warm-up each)
REPEATS = int(os.environ.get("PEER_REPEATS", "5"))
# extra `dtr render` options, e.g. PEER_DTR_ARGS=--fast-traversal (Embree's non-watertight
# mode, as Mitsuba traces)
DTR_ARGS = os.environ.get("PEER_DTR_ARGS", "").split()
# options of the reference render only, e.g. PEER_REF_ARGS="--sampler sobol" (an unbiased
# reference with less noise of its own; tests/sobol_sampler.rs checks its expectation)
REF_ARGS = os.environ.get("PEER_REF_ARGS", "").split()
# mitransient's sampler: "independent" (default), or one of Mitsuba's stratified ones
# ("multijitter", "ldsampler", "orthogonal", "stratified") to compare like with like
MI_SAMPLER = os.environ.get("PEER_MI_SAMPLER", "independent")
# threads for both renderers (default: every core)
THREADS = int(os.environ.get("PEER_THREADS", "0"))
OUT = os.path.join(ROOT, "bench-out", "peer")


def rgb(v):
    return [float(v)] * 3 if isinstance(v, (int, float)) else [float(x) for x in v]


def to_world(s):
    T = mi.ScalarTransform4f
    t = s.get("translate", [0, 0, 0])
    r = s.get("rotate", [0, 0, 0])
    sc = s.get("scale", 1.0)
    sc = [sc] * 3 if isinstance(sc, (int, float)) else sc
    # ours: x_world = t + Rz·Ry·Rx·(s ∘ x), X applied first
    return (T().translate(t) @ T().rotate([0, 0, 1], r[2]) @ T().rotate([0, 1, 0], r[1])
            @ T().rotate([1, 0, 0], r[0]) @ T().scale(sc))


def bsdf(m, by_name, medium_eta):
    """Mitsuba's BSDF for one [[material]] (diffuse and conductors: the peer's lobes are
    one-sided, ours two-sided, which closed shapes seen from outside do not tell apart).
    Dielectrics: Mitsuba's `int_ior` / `ext_ior` are absolute indices inside and outside, ours
    `int_ior` and the exterior's (the named `exterior` material's `int_ior`, else the scene's
    medium η); both scale transmitted radiance by 1/η'² and count η × length in the path
    length (mitransient multiplies each segment by the product of the sampled relative
    indices, which starts at 1: so the medium's η must be 1 here)."""
    t = m["type"]
    if t in ("roughdielectric", "dielectric"):
        ext = by_name[m["exterior"]]["int_ior"] if "exterior" in m else medium_eta
        b = {"type": t, "int_ior": float(m["int_ior"]), "ext_ior": float(ext)}
        if t == "roughdielectric":
            b.update(distribution="ggx", alpha=float(m["roughness"]))
        return b
    if t == "diffuse":
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb(m["albedo"])}}
    if t in ("roughconductor", "conductor"):
        b = {"type": t, "specular_reflectance": {"type": "rgb", "value": rgb(m.get("specular_reflectance", 1.0))}}
        if t == "roughconductor":
            b.update(distribution="ggx", alpha=float(m["roughness"]))
        if "eta" in m:
            b["eta"] = {"type": "rgb", "value": rgb(m["eta"])}
            b["k"] = {"type": "rgb", "value": rgb(m["k"])}
        else:
            b["material"] = "none"
        return b
    sys.exit(f"material type {t} is not mapped to Mitsuba here")


def mitsuba_scene(d, max_depth):
    cam, film = d["camera"], d["film"]
    w, h = cam.get("resolution", [64, 64])
    pos, at, up = cam["position"], cam["look_at"], cam.get("up", [0, 1, 0])
    sc = {
        "type": "scene",
        "integrator": {"type": "transient_path", "max_depth": max_depth, "rr_depth": 1000, "camera_unwarp": bool(film.get("unwarp", False))},
        "sensor": {
            # Mitsuba's perspective sensor starts each camera ray at the near-clip plane, so
            # the camera segment's OPL is short by near_clip / cos θ (0.01 m by default, a third
            # of a bin here): the agreement test caught it at the light's edges. 1e-5 m keeps
            # that below f32 resolution of the OPL.
            "type": "perspective", "fov_axis": "y", "fov": float(cam.get("fov", 40.0)), "near_clip": 1e-5,
            "to_world": mi.ScalarTransform4f().look_at(origin=pos, target=at, up=up),
            "sampler": {"type": MI_SAMPLER, "sample_count": SPP},
            "film": {"type": "transient_hdr_film", "width": w, "height": h, "rfilter": {"type": "box"},
                     "temporal_bins": int(film["bins"]), "start_opl": float(film.get("start_opl", 0.0)),
                     "bin_width_opl": float(film["bin_width_opl"])},
        },
    }
    medium_eta = float(d.get("medium", {}).get("eta", 1.0))
    if medium_eta != 1.0:
        sys.exit("mitransient's path length starts at index 1: set [medium] eta = 1 for the comparison")
    by_name = {m["name"]: m for m in d["material"]}
    mats = {m["name"]: bsdf(m, by_name, medium_eta) for m in d["material"]}
    emit = {e["shape"]: e for e in d.get("emitter", []) if e["type"] == "area"}
    for s in d["shape"]:
        kind = {"rectangle": "rectangle", "cube": "cube"}[s["type"]]
        shape = {"type": kind, "to_world": to_world(s), "bsdf": mats[s["material"]]}
        if s["name"] in emit:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": rgb(emit[s["name"]]["radiance"])}}
        sc[s["name"]] = shape
    return sc


def run_dtr(spp, seed, prefix, args=None):
    threads = ["--threads", str(THREADS)] if THREADS > 0 else []
    args = DTR_ARGS if args is None else args
    subprocess.run([DTR, "render", SCENE, "--spp", str(spp), "--seed", str(seed), "-o", prefix, "-q", *threads, *args],
                   check=True)
    with open(prefix + ".json") as f:
        return np.load(prefix + ".npy"), json.load(f)


def main():
    os.makedirs(OUT, exist_ok=True)
    with open(SCENE, "rb") as f:
        d = tomllib.load(f)
    max_depth = int(d.get("integrator", {}).get("max_bounces", 8)) + 1
    if THREADS > 0:
        dr.set_thread_count(THREADS)
    ref, _ = run_dtr(REF_SPP, 777, os.path.join(OUT, "ref"), REF_ARGS)
    scene = mi.load_dict(mitsuba_scene(d, max_depth))
    # warm-ups at the timed spp, not timed: Dr.Jit compiles one kernel per sample count
    mi.render(scene, spp=SPP, seed=10_000)
    run_dtr(SPP, 10_000, os.path.join(OUT, "warmup"))
    ours_runs, theirs_runs = [], []
    for k in range(SEEDS):
        ours_runs.append(run_dtr(SPP, 1 + k, os.path.join(OUT, f"ours{k}"))[0])
        _, transient = mi.render(scene, spp=SPP, seed=1 + k)
        theirs_runs.append(np.array(transient)[..., :3])
    # timed, interleaved, warm renders only
    cpu_ours, cpu_theirs, wall_ours, wall_theirs = [], [], [], []
    for k in range(REPEATS):
        _, meta = run_dtr(SPP, 100 + k, os.path.join(OUT, f"timed{k}"))
        cpu_ours.append(meta["cpu_seconds"])
        wall_ours.append(meta["wall_seconds"])
        c0, w0 = time.process_time(), time.perf_counter()
        _, transient = mi.render(scene, spp=SPP, seed=100 + k)
        np.array(transient)  # evaluate: Dr.Jit is lazy
        cpu_theirs.append(time.process_time() - c0)
        wall_theirs.append(time.perf_counter() - w0)
    print("CPU seconds per render, ours:", " ".join(f"{c:.3f}" for c in cpu_ours))
    print("CPU seconds per render, mitransient:", " ".join(f"{c:.3f}" for c in cpu_theirs))
    ours, theirs = ours_runs[0], theirs_runs[0]
    print("shapes: ours", ours.shape, "theirs", theirs.shape)
    paths = ours.shape[0] * ours.shape[1] * SPP

    tot = lambda a: float(a.sum())
    # Agreement within noise, before any speed is compared (agreement.py)
    agree = agreement.agree(ours_runs, theirs_runs)
    if not agree:
        print("the two transients disagree beyond noise: find out why before comparing speeds")
        return 1
    print(f"total energy: ours {tot(ours):.4f}, mitransient {tot(theirs):.4f}, reference {tot(ref):.4f}")
    print(f"per-bin totals rel. L2 vs reference: ours {rel_l2(agreement.bins(ours), agreement.bins(ref)):.4f}, mitransient {rel_l2(agreement.bins(theirs), agreement.bins(ref)):.4f}")
    # root mean square over the seeds' renders
    rms = lambda runs: math.sqrt(sum(rel_l2(r, ref) ** 2 for r in runs) / len(runs))
    e_ours, e_theirs = rms(ours_runs), rms(theirs_runs)
    print(f"transient rel. L2 vs {REF_SPP}-spp reference {' '.join(REF_ARGS)} (rms over {SEEDS} renders): "
          f"ours {e_ours:.4f}, mitransient {e_theirs:.4f}")
    med = lambda v: float(np.median(v))
    ppc_ours = [paths / c for c in cpu_ours]
    ppc_theirs = [paths / c for c in cpu_theirs]
    pairs = [a / b for a, b in zip(ppc_ours, ppc_theirs)]
    print(f"paths per CPU-second (median, range over {REPEATS} warm renders): ours {med(ppc_ours):.3e} "
          f"({min(ppc_ours):.3e}..{max(ppc_ours):.3e}; {med(wall_ours):.2f} s wall), mitransient {med(ppc_theirs):.3e} "
          f"({min(ppc_theirs):.3e}..{max(ppc_theirs):.3e}; {med(wall_theirs):.2f} s wall)")
    print(f"ratio ours/theirs paths per CPU-second: {med(ppc_ours) / med(ppc_theirs):.2f} "
          f"(per interleaved pair {min(pairs):.2f}..{max(pairs):.2f})")
    eq = (e_ours * math.sqrt(med(cpu_ours))) / (e_theirs * math.sqrt(med(cpu_theirs)))
    print(f"error at equal CPU time, ours/theirs: {eq:.2f}")

if __name__ == "__main__":
    sys.exit(main())
