#!/usr/bin/env python3
"""NLOS peer comparison against mitransient's transient_nlos_path. Optional, not in CI.

Run with `benches/peer/run.sh nlos` (the same venv as compare_mitransient.py). It renders the
confocal relay-wall capture of benches/peer/nlos_peer.toml (PEER_GRID x PEER_GRID sensor
points, default 32; third bounces, max_bounces = 1; relay legs left out of the time of flight; delta pulse,
box bins) with `dtr` and the same scene with mitransient: the relay wall a `rectangle` holding
an `nlos_capture_meter`, the hidden box a `cube`, the laser a `projector` of small field of
view, and transient_nlos_path with capture_type = confocal, laser sampling and hidden-geometry
sampling (its recommended settings for third bounces), box temporal filter,
account_first_and_last_bounces = false.

The two lasers differ, and the script converts before comparing. Ours is a beam of fixed power
P = 1 W: every spot on the wall receives P. mitransient's is a projector of irradiance E = 1 at
1 m on its axis, evaluated as if aimed at each spot: a spot at distance d from it receives
E cos(i) / d² per unit area (i the beam's incidence on the wall), and its point-spot estimator
carries one more factor 1/π. So at sensor point p, ours = theirs × d(p)² / (π cos i(p)): a
known factor per point, no fitted scale. The agreement test (agreement.py: per-bin totals and
8x8 blocks of the time-summed capture, z-scores of the difference of the means over PEER_SEEDS
seeds) runs on the converted capture and stops the script if the two disagree.

PEER_SCAN=exhaustive compares an exhaustive scan instead (every sensor point lit by every laser
point; PEER_GRID defaults to 8 there: 64 x 64 sensor-laser pairs). mitransient then runs
capture_type = exhaustive with its laser grid equal to the sensor grid (laser point i is sensor
point i) and a film of shape [sensor y, sensor x, laser i // GRID, laser i % GRID, bins]; each
laser point's transient goes to its own entries unscaled (only the steady image it returns is
a mean over laser points), so the conversion is d² / (π cos i) at each laser point. Ours has
laser points along rows and sensor points along columns (`dtr info`), both numbered row by row
like the confocal grid. With mitransient 1.3.1 the exhaustive comparison stops at the agreement
test: its exhaustive capture does not hold its own confocal capture on the diagonal
(nlos_exhaustive_diagonal.py; BENCHMARKS.md, "Exhaustive scans").

Then warm renders only, interleaved (ours, theirs, ...; PEER_REPEATS each, after one untimed
warm-up of each at the timed spp), each renderer's CPU seconds from its own accounting, medians
with ranges: paths per CPU-second, and the error at equal CPU time (transient rel. L2 against
a PEER_REF_SPP dtr reference, scaled by error ∝ 1/√time).
"""
import functools, json, math, os, subprocess, sys, time, tomllib
import numpy as np
import mitsuba as mi
import drjit as dr

mi.set_variant("llvm_ad_rgb")
import mitransient as mitr  # noqa: E402,F401

import agreement  # noqa: E402  (beside this script)
from agreement import rel_l2  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENE = os.path.join(ROOT, "benches", "peer", "nlos_peer.toml")
DTR = os.environ.get("PEER_DTR", os.path.join(ROOT, "target", "release", "dtr"))
SCAN = os.environ.get("PEER_SCAN", "confocal")
if SCAN not in ("confocal", "exhaustive"):
    sys.exit(f"PEER_SCAN={SCAN}: expected confocal or exhaustive")
GRID = int(os.environ.get("PEER_GRID", "32" if SCAN == "confocal" else "8"))
SPP = int(os.environ.get("PEER_SPP", "256"))
SEEDS = int(os.environ.get("PEER_SEEDS", "8"))
REF_SPP = int(os.environ.get("PEER_REF_SPP", "16384"))
REPEATS = int(os.environ.get("PEER_REPEATS", "5"))
DTR_ARGS = os.environ.get("PEER_DTR_ARGS", "").split()
MI_SAMPLER = os.environ.get("PEER_MI_SAMPLER", "independent")
THREADS = int(os.environ.get("PEER_THREADS", "1"))
OUT = os.path.join(ROOT, "bench-out", "peer-nlos" if SCAN == "confocal" else "peer-nlos-exhaustive")


@functools.cache
def scene_file():
    """nlos_peer.toml, or a copy of it with the exhaustive scan (strings cannot be `--set`),
    written once."""
    if SCAN == "confocal":
        return SCENE
    with open(SCENE) as f:
        text = f.read()
    if 'scan = "confocal"' not in text:
        sys.exit(f"{SCENE}: expected `scan = \"confocal\"` to turn into the exhaustive scan")
    path = os.path.join(OUT, "nlos_peer_exhaustive.toml")
    with open(path, "w") as f:
        f.write(text.replace('scan = "confocal"', 'scan = "exhaustive"'))
    return path


def run_dtr(spp, seed, prefix, args=None):
    args = DTR_ARGS if args is None else args
    grid = ["--set", f"nlos.grid.0={GRID}", "--set", f"nlos.grid.1={GRID}"]
    threads = ["--threads", str(THREADS)] if THREADS > 0 else []
    subprocess.run([DTR, "render", scene_file(), "--spp", str(spp), "--seed", str(seed), "-o", prefix, "-q",
                    *grid, *threads, *args], check=True)
    with open(prefix + ".json") as f:
        return np.load(prefix + ".npy")[..., 0], json.load(f)


def mitsuba_scene(d):
    """The scene of nlos_peer.toml for mitransient. The wall must be the default rectangle
    ([-1, 1]² in the plane z = 0, facing +z), so that both grids put their points at the
    cell centres of that square with x along columns and y along rows."""
    shapes = {s["name"]: s for s in d["shape"]}
    mats = {m["name"]: m for m in d["material"]}
    nlos, cam, film = d["nlos"], d["camera"], d["film"]
    wall = shapes[nlos["wall"]]
    if wall["type"] != "rectangle" or any(k in wall for k in ("translate", "rotate", "scale")):
        sys.exit("the conversion assumes the relay wall is the untransformed default rectangle")
    laser = next(e for e in d["emitter"] if e["name"] == nlos["laser"])
    if "pulse" in laser or "gate" in film or nlos.get("scan", "confocal") != "confocal":
        sys.exit("the comparison needs a delta pulse, plain box bins and (in the file) a confocal scan")
    exhaustive = {"exhaustive_scan": True, "laser_scan_width": GRID, "laser_scan_height": GRID} if SCAN == "exhaustive" else {}
    diffuse = lambda m: {"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(mats[m]["albedo"])] * 3}}
    from compare_mitransient import to_world  # the same transform convention as the Cornell box
    sc = {
        "type": "scene",
        "integrator": {
            # our NLOS paths count the bounces between the sensor point and the laser spot;
            # Mitsuba's depth counts the SPAD's segment, the sensor point and the spot too
            "type": "transient_nlos_path", "max_depth": int(d["integrator"]["max_bounces"]) + 3,
            "rr_depth": 1000, "capture_type": SCAN, "nlos_laser_sampling": True,
            "nlos_hidden_geometry_sampling": True, "nlos_hidden_geometry_sampling_includes_relay_wall": False,
            "temporal_filter": "box", "account_first_and_last_bounces": False,
        },
        "relay_wall": {
            "type": "rectangle", "id": "relay_wall", "bsdf": diffuse(wall["material"]),
            "nlos_sensor": {
                "type": "nlos_capture_meter", "sensor_origin": [float(x) for x in cam["position"]],
                "sampler": {"type": MI_SAMPLER, "sample_count": SPP},
                "film": {"type": "transient_hdr_film", "width": GRID, "height": GRID, "rfilter": {"type": "box"},
                         "temporal_bins": int(film["bins"]), "start_opl": float(film["start_opl"]),
                         "bin_width_opl": float(film["bin_width_opl"]), **exhaustive},
            },
        },
        "laser": {
            "type": "projector", "id": "laser", "irradiance": {"type": "rgb", "value": [float(laser["power"])] * 3},
            "fov": 0.2,
            "to_world": mi.ScalarTransform4f().look_at(origin=laser["position"], target=[0, 0, 0], up=[0, 1, 0]),
        },
    }
    for name, s in shapes.items():
        if name == nlos["wall"]:
            continue
        kind = {"rectangle": "rectangle", "cube": "cube"}[s["type"]]
        sc[name] = {"type": kind, "to_world": to_world(s), "bsdf": diffuse(s["material"])}
    return sc


def laser_factor(d):
    """ours / theirs at each sensor point, [GRID, GRID] (rows y, columns x): d² / (π cos i)."""
    c = (np.arange(GRID) + 0.5) / GRID * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    lx, ly, lz = (float(v) for v in next(e for e in d["emitter"] if e["type"] == "laser")["position"])
    dist = np.sqrt((x - lx) ** 2 + (y - ly) ** 2 + lz ** 2)
    cos_i = lz / dist
    return dist ** 2 / (math.pi * cos_i)


def converted(capture, factor):
    """mitransient's capture in our layout and units: confocal [y, x, bin] times the factor per
    sensor point; exhaustive [laser, sensor, bin] (laser and sensor numbered row by row) times
    the factor per laser point."""
    if SCAN == "confocal":
        return capture * factor[:, :, None]
    n = GRID * GRID
    c = capture.reshape(n, n, capture.shape[-1])  # [sensor, laser, bin]
    return c.transpose(1, 0, 2) * factor.reshape(n)[:, None, None]


def main():
    os.makedirs(OUT, exist_ok=True)
    with open(SCENE, "rb") as f:
        d = tomllib.load(f)
    if THREADS > 0:
        dr.set_thread_count(THREADS)
    ref, _ = run_dtr(REF_SPP, 777, os.path.join(OUT, "ref"), ["--sampler", "sobol"])
    scene = mi.load_dict(mitsuba_scene(d))
    factor = laser_factor(d)
    theirs = lambda seed: converted(np.array(mi.render(scene, spp=SPP, seed=seed)[1])[..., 0], factor)
    theirs(10_000)  # warm-ups at the timed spp: Dr.Jit compiles one kernel per sample count
    run_dtr(SPP, 10_000, os.path.join(OUT, "warmup"))
    ours_runs = [run_dtr(SPP, 1 + k, os.path.join(OUT, f"ours{k}"))[0][..., None] for k in range(SEEDS)]
    theirs_runs = [theirs(1 + k)[..., None] for k in range(SEEDS)]
    for k, r in enumerate(theirs_runs):
        np.save(os.path.join(OUT, f"theirs{k}.npy"), r)  # converted, for a closer look
    if not agreement.agree(ours_runs, theirs_runs):
        print("the two captures disagree beyond noise: find out why before comparing speeds")
        return 1
    cpu_ours, cpu_theirs = [], []
    for k in range(REPEATS):
        cpu_ours.append(run_dtr(SPP, 100 + k, os.path.join(OUT, f"timed{k}"))[1]["cpu_seconds"])
        c0 = time.process_time()
        np.array(mi.render(scene, spp=SPP, seed=100 + k)[1])  # evaluate: Dr.Jit is lazy
        cpu_theirs.append(time.process_time() - c0)
    paths = GRID * GRID * SPP
    med = lambda v: float(np.median(v))
    tot = lambda runs: float(np.mean([r.sum() for r in runs]))
    print(f"{GRID}x{GRID} {SCAN}, {SPP} spp, {THREADS or 'all'} thread(s); dtr {' '.join(DTR_ARGS) or '(defaults)'}, "
          f"mitransient sampler {MI_SAMPLER}")
    print(f"total (converted): ours {tot(ours_runs):.5f}, mitransient {tot(theirs_runs):.5f}, reference {float(ref.sum()):.5f}")
    rms = lambda runs: math.sqrt(sum(rel_l2(r[..., 0], ref) ** 2 for r in runs) / len(runs))
    bins = lambda a: a.sum(axis=(0, 1))
    rms_bins = lambda runs: math.sqrt(sum(rel_l2(bins(r[..., 0]), bins(ref)) ** 2 for r in runs) / len(runs))
    e_ours, e_theirs = rms(ours_runs), rms(theirs_runs)
    print(f"capture rel. L2 vs {REF_SPP}-spp reference (rms over {SEEDS} renders): ours {e_ours:.4f}, "
          f"mitransient {e_theirs:.4f}; per-bin totals: ours {rms_bins(ours_runs):.4f}, mitransient {rms_bins(theirs_runs):.4f}")
    ppc_ours = [paths / c for c in cpu_ours]
    ppc_theirs = [paths / c for c in cpu_theirs]
    pairs = [a / b for a, b in zip(ppc_ours, ppc_theirs)]
    print(f"CPU seconds per render: ours {' '.join(f'{c:.3f}' for c in cpu_ours)}; "
          f"mitransient {' '.join(f'{c:.3f}' for c in cpu_theirs)}")
    print(f"paths per CPU-second, median (range): ours {med(ppc_ours):.3e} ({min(ppc_ours):.3e}..{max(ppc_ours):.3e}), "
          f"mitransient {med(ppc_theirs):.3e} ({min(ppc_theirs):.3e}..{max(ppc_theirs):.3e})")
    print(f"ratio ours/theirs paths per CPU-second: {med(ppc_ours) / med(ppc_theirs):.2f} "
          f"(per interleaved pair {min(pairs):.2f}..{max(pairs):.2f})")
    eq = (e_ours * math.sqrt(med(cpu_ours))) / (e_theirs * math.sqrt(med(cpu_theirs)))
    print(f"error at equal CPU time, ours/theirs: {eq:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
