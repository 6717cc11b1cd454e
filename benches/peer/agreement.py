"""Agreement within noise of two renderers' transients (shared by compare_mitransient.py,
compare_nlos.py and check_xml.py): for per-bin totals and 8x8 blocks of the time-summed image, the difference of
the two renderers' means over independent seeds, in units of its standard error. Under
agreement Σz² ≈ the number of entries (χ²) and no |z| exceeds a Bonferroni-like bound."""
import math
import numpy as np


def rel_l2(a, b):
    """Relative L2 error of a against the reference b."""
    return float(np.sqrt(((a - b) ** 2).sum() / (b ** 2).sum()))


def bins(a):
    return a.sum(axis=(0, 1, 3))


def blocks(a):
    """8x8-pixel blocks of the time-summed image."""
    return a.sum(axis=(2, 3)).reshape(a.shape[0] // 8, 8, a.shape[1] // 8, 8).sum(axis=(1, 3)).ravel()


def agree(ours_runs, theirs_runs):
    """Prints one line per aggregate; True when both agree within noise."""
    seeds = len(ours_runs)
    ok_all = True
    for name, agg in (("per-bin totals", bins), ("8x8 blocks of the time-summed image", blocks)):
        a = np.array([agg(x) for x in ours_runs])
        b = np.array([agg(x) for x in theirs_runs])
        se2 = a.var(axis=0, ddof=1) / seeds + b.var(axis=0, ddof=1) / seeds
        used = se2 > 0
        z = (a.mean(axis=0) - b.mean(axis=0))[used] / np.sqrt(se2[used])
        n = int(used.sum())
        chi2 = float((z ** 2).sum())
        zmax = float(np.abs(z).max()) if n else 0.0
        # Student-t with seeds-1 dof has variance (seeds-1)/(seeds-3); allow 4 sd of the χ² sum
        var_t = (seeds - 1) / (seeds - 3) if seeds > 3 else 3.0
        ok = chi2 <= n * var_t + 4.0 * math.sqrt(2.0 * n) * var_t and zmax <= 6.0
        ok_all &= ok
        print(f"agreement, {name}: {n} entries, sum z^2 {chi2:.1f} (expected ~{n * var_t:.1f}), max |z| {zmax:.2f}: {'ok' if ok else 'DISAGREE'}")
    return ok_all
