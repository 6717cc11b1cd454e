#!/usr/bin/env python3
"""RGB complex indices of refraction (eta, k) of Mitsuba's named conductors, for the Mitsuba
XML importer's `material` presets (src/scene/mitsuba/conductors.rs).

Mitsuba 3's RGB variants turn each measured spectrum `data/ior/<name>.eta.spd` and
`<name>.k.spd` (Mitsuba's own data files, from the luxpop.com database) into an RGB triple:
the piecewise-linear spectrum is integrated against the CIE 1931 2-degree colour matching
functions at 1000 evenly spaced wavelengths over 360..830 nm, scaled so that a constant
spectrum 1 has luminance Y = 1, converted from XYZ to linear sRGB and clamped at 0. This
script does the same, with the CIE 1931 2-degree tables of the colour-science package.

    pip install colour-science
    python3 tools/conductor_presets.py MITSUBA/data/ior Au Ag Al Cr Cu
"""

import sys
from pathlib import Path

import numpy as np
import colour

# XYZ -> linear sRGB (IEC 61966-2-1, D65), the matrix Mitsuba 3 uses
XYZ_TO_SRGB = np.array([
    [3.240479, -1.537150, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
])
CIE_MIN, CIE_MAX, STEPS = 360.0, 830.0, 1000


def read_spd(path):
    rows = [l.split() for l in Path(path).read_text().splitlines() if l.strip() and not l.startswith("#")]
    w, v = np.array([[float(a), float(b)] for a, b in rows]).T
    return w, v


def to_rgb(w, v, cmfs):
    lam = CIE_MIN + np.arange(STEPS) / (STEPS - 1) * (CIE_MAX - CIE_MIN)
    inside = (lam >= w[0]) & (lam <= w[-1])
    lam = lam[inside]
    values = np.interp(lam, w, v)
    xyz_bar = np.stack([np.interp(lam, cmfs.wavelengths, cmfs.values[:, i]) for i in range(3)], axis=1)
    # the CIE Y integral over the same grid: a constant spectrum 1 has Y = 1
    y_all = np.interp(CIE_MIN + np.arange(STEPS) / (STEPS - 1) * (CIE_MAX - CIE_MIN),
                      cmfs.wavelengths, cmfs.values[:, 1]).sum()
    xyz = (xyz_bar * values[:, None]).sum(axis=0) / y_all
    return np.maximum(XYZ_TO_SRGB @ xyz, 0.0)


def main():
    folder, names = Path(sys.argv[1]), sys.argv[2:]
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    for name in names:
        eta = to_rgb(*read_spd(folder / f"{name}.eta.spd"), cmfs)
        k = to_rgb(*read_spd(folder / f"{name}.k.spd"), cmfs)
        fmt = lambda a: "[" + ", ".join(f"{x:.4f}" for x in a) + "]"
        print(f'    ("{name}", {fmt(eta)}, {fmt(k)}),')


if __name__ == "__main__":
    main()
