#!/usr/bin/env python3
"""Coefficients of `src/temporal/normal.rs` (issue 11): the Mills ratio m(z) = Q(z) / φ(z) of
the standard normal (Q = 1 − Φ, φ its density) as two rational functions, and their error.

    z < 4:  m(z) = P1(z) / Q1(z),                 degrees 8 / 8
    z ≥ 4:  m(z) = P2(s) / (z · Q2(s)), s = 1/z²,  degrees 6 / 6

Each is the rational function of its degrees that interpolates m (or z·m(z) = h(s) in the
tail) at the Chebyshev points of its interval (a linear system, solved in 120-digit
arithmetic; close to the minimax one). The check evaluates the f64 coefficients with f64
arithmetic exactly as the Rust code does (Horner with fused multiply-adds, each rounded once,
emulated here with exact fractions; glibc's exp) on a dense grid of z ∈ [0, 38] and compares with 120-digit values of m and Q. Needs mpmath
(Debian: python3-mpmath). Prints the Rust constants and the errors:

    python3 tools/fit_normal_tail.py
"""

import math
from fractions import Fraction

import mpmath as mp

mp.mp.dps = 120
Z1 = 4
N1, N2 = 8, 6
FRAC_1_SQRT_2PI = 0.3989422804014327


def mills(z):
    z = mp.mpf(z)
    return mp.erfc(z / mp.sqrt(2)) / 2 / (mp.exp(-z * z / 2) / mp.sqrt(2 * mp.pi))


def upper(z):
    return mp.erfc(mp.mpf(z) / mp.sqrt(2)) / 2


def tail_h(s):
    z = 1 / mp.sqrt(s)
    return mills(z) * z


def rational_fit(f, a, b, n):
    """P/Q with P, Q of degree n in monomials of the argument, Q(0) = 1, equal to f at the
    2n + 1 Chebyshev points of [a, b]."""
    k = 2 * n + 1
    pts = [(a + b) / 2 + (b - a) / 2 * mp.cos(mp.pi * (i + mp.mpf(1) / 2) / k) for i in range(k)]
    A = mp.matrix(k, k)
    rhs = mp.matrix(k, 1)
    for i, v in enumerate(pts):
        fi = f(v)
        for j in range(n + 1):
            A[i, j] = v**j
        for j in range(1, n + 1):
            A[i, n + j] = -fi * v**j
        rhs[i] = fi
    sol = mp.lu_solve(A, rhs)
    p = [float(sol[j]) for j in range(n + 1)]
    q = [1.0] + [float(sol[n + j]) for j in range(1, n + 1)]
    return p, q


def fma(a, b, c):
    # int / int true division is correctly rounded, so this is a·b + c rounded once
    return float(Fraction(a) * Fraction(b) + Fraction(c))


def horner(c, x):
    r = c[-1]
    for cc in reversed(c[:-1]):
        r = fma(r, x, cc)
    return r


P1, Q1 = rational_fit(mills, mp.mpf(0), mp.mpf(Z1), N1)
P2, Q2 = rational_fit(tail_h, mp.mpf(0), 1 / mp.mpf(Z1) ** 2, N2)


def mills_f64(z):
    if z < Z1:
        return horner(P1, z) / horner(Q1, z)
    s = 1.0 / (z * z)
    return horner(P2, s) / (z * horner(Q2, s))


def upper_f64(z):
    return math.exp(-0.5 * z * z) * FRAC_1_SQRT_2PI * mills_f64(z)


def rust(name, c):
    body = "".join(f"\n    {v!r}," for v in c)
    return f"const {name}: [f64; {len(c)}] = [{body}\n];"


for name, c in [("P1", P1), ("Q1", Q1), ("P2", P2), ("Q2", Q2)]:
    print(rust(name, c))

steps = 76_000  # z step 5·10⁻⁴
worst_m, worst_q8, worst_q = 0.0, 0.0, 0.0
for i in range(steps + 1):
    z = 38.0 * i / steps
    worst_m = max(worst_m, float(abs(mills_f64(z) / mills(z) - 1)))
    q = upper_f64(z)
    if q > 1e-300:
        e = float(abs(q / upper(z) - 1))
        worst_q = max(worst_q, e / (1 + z * z))
        if z <= 8.5:
            worst_q8 = max(worst_q8, e)
print(f"max relative error of m: {worst_m:.3g}")
print(f"max relative error of Q on [0, 8.5]: {worst_q8:.3g}")
print(f"max relative error of Q / (1 + z²) where Q > 1e-300: {worst_q:.3g}")
