use super::*;

const AXIS: TimeAxis = TimeAxis {
    start_opl: 1.0,
    bin_width_opl: 0.1,
    bins: 40,
};

fn pulses() -> Vec<Pulse> {
    vec![
        Pulse::Delta,
        Pulse::Gaussian { sigma_opl: 0.03 },
        Pulse::Box { width_opl: 0.07 },
    ]
}
fn gates() -> Vec<Gate> {
    vec![Gate::Box, Gate::Gaussian { sigma_opl: 0.05 }]
}

/// The correlation integral by brute-force quadrature (midpoint rule on a fine grid; deltas
/// evaluated exactly), in f64.
fn quadrature(c: &Correlation, l: usize, d: f64) -> f64 {
    let u = d + c.offset;
    let w = AXIS.bin_width_opl;
    let (a, b) = (AXIS.bin_start(l), AXIS.bin_start(l) + w);
    let gate = |s: f64| match c.gate {
        Gate::Box => {
            if a <= s && s < b {
                1.0
            } else {
                0.0
            }
        }
        Gate::Gaussian { sigma_opl } => {
            let sg = sigma_opl as f64;
            w * (-(s - (a + 0.5 * w)).powi(2) / (2.0 * sg * sg)).exp() / (sg * (2.0 * std::f64::consts::PI).sqrt())
        }
    };
    match c.pulse {
        Pulse::Delta => gate(u),
        Pulse::Gaussian { sigma_opl } => {
            let s = sigma_opl as f64;
            let n = 200_000;
            let (lo, hi) = (u - 8.0 * s, u + 8.0 * s);
            let h = (hi - lo) / n as f64;
            (0..n)
                .map(|i| {
                    let t = lo + (i as f64 + 0.5) * h;
                    let p = (-(t - u).powi(2) / (2.0 * s * s)).exp() / (s * (2.0 * std::f64::consts::PI).sqrt());
                    p * gate(t) * h
                })
                .sum()
        }
        Pulse::Box { width_opl } => {
            let wp = width_opl as f64;
            let n = 200_000;
            let h = wp / n as f64;
            (0..n).map(|i| gate(u - 0.5 * wp + (i as f64 + 0.5) * h) * h / wp).sum()
        }
    }
}

#[test]
fn closed_forms_match_quadrature() {
    for p in pulses() {
        for g in gates() {
            let c = Correlation::new(AXIS, p, 0.02, g).unwrap();
            for k in 0..60 {
                let d = 1.3 + k as f64 * 0.0137; // crosses several bin edges
                for l in 0..AXIS.bins {
                    let q = quadrature(&c, l, d);
                    let e = c.eval(l, d);
                    // midpoint quadrature of a discontinuous integrand: error ≤ one cell (h/width)
                    let tol = 2e-4 + 1e-4 * q.abs();
                    if matches!((p, g), (Pulse::Delta, Gate::Box)) && ((d + 0.02 - 1.0) / 0.1).fract().abs() < 1e-4 {
                        continue; // exactly on an edge: both sides are right
                    }
                    assert!(
                        (q - e).abs() <= tol,
                        "{p:?} {g:?} bin {l} d {d}: closed {e} vs quadrature {q}"
                    );
                }
            }
        }
    }
}

#[test]
fn derivatives_match_central_differences() {
    for p in pulses() {
        for g in gates() {
            let c = Correlation::new(AXIS, p, 0.0, g).unwrap();
            if c.derivative_is_distribution() {
                continue;
            }
            for k in 0..80 {
                let u = 1.5 + k as f64 * 0.00731;
                for l in c.range(u) {
                    let h = 1e-5;
                    let fd = (c.eval_pair(l, u + h).0 - c.eval_pair(l, u - h).0) / (2.0 * h);
                    let an = c.eval_pair(l, u).1;
                    // skip points within h of a kink of the box ⋆ box trapezoid
                    if let (Pulse::Box { width_opl }, Gate::Box) = (p, g) {
                        let a = AXIS.bin_start(l);
                        let kinks = [
                            a - 0.5 * width_opl as f64,
                            a + 0.5 * width_opl as f64,
                            a + 0.1 - 0.5 * width_opl as f64,
                            a + 0.1 + 0.5 * width_opl as f64,
                        ];
                        if kinks.iter().any(|&kk| (u - kk).abs() < 2.0 * h) {
                            continue;
                        }
                    }
                    // central-difference truncation error: h²/6 · |S'''| ≤ h² / σ⁴ here
                    let tol = 1e-5 * (1.0 + an.abs()) + h * h / 0.03f64.powi(4);
                    assert!(
                        (fd - an).abs() <= tol,
                        "{p:?} {g:?} bin {l} u {u}: analytic {an} vs fd {fd}"
                    );
                }
            }
        }
    }
}

#[test]
fn box_gate_is_a_partition_of_unity() {
    for p in pulses() {
        let c = Correlation::new(AXIS, p, 0.0, Gate::Box).unwrap();
        for k in 0..100 {
            let d = 1.5 + k as f32 * 0.0213;
            let mut sum = 0.0f64;
            c.for_each(d as f64, |_, s, _| sum += s);
            assert!((sum - 1.0).abs() < 1e-5, "{p:?} d {d}: Σ S_e = {sum}");
        }
    }
    // Gaussian gates spaced w apart sum to 1 up to a ripple of 2·exp(−2π²σ²/w²) (Poisson
    // summation), plus the 8σ truncation (< 2e-15).
    for sigma in [0.05f32, 0.07, 0.1] {
        let c = Correlation::new(AXIS, Pulse::Delta, 0.0, Gate::Gaussian { sigma_opl: sigma }).unwrap();
        let ripple = 2.0 * (-2.0 * std::f64::consts::PI.powi(2) * (sigma as f64 / 0.1).powi(2)).exp();
        for k in 0..100 {
            let d = 2.0 + k as f32 * 0.0113;
            let mut sum = 0.0f64;
            c.for_each(d as f64, |_, s, _| sum += s);
            assert!(
                (sum - 1.0).abs() <= ripple * 1.01 + 1e-6,
                "gaussian gate σ {sigma} d {d}: Σ S_e = {sum}"
            );
        }
    }
}

#[test]
fn range_covers_every_nonzero_bin_and_is_empty_outside() {
    for p in pulses() {
        for g in gates() {
            let c = Correlation::new(AXIS, p, 0.01, g).unwrap();
            for k in 0..400 {
                let d = 0.5 + k as f32 * 0.0127;
                let r = c.range(d as f64);
                for l in 0..AXIS.bins {
                    let (s, ds) = c.eval_pair(l, d as f64 + 0.01);
                    let significant = s.abs() > 1e-7 || ds.abs() > 1e-5;
                    assert!(
                        !significant || r.contains(&l),
                        "{p:?} {g:?} d {d}: bin {l} has S {s} but range {r:?}"
                    );
                }
            }
            assert!(c.range(-50.0).is_empty() && c.range(50.0).is_empty());
        }
    }
}

#[test]
fn extreme_inputs_stay_finite() {
    for p in [
        Pulse::Gaussian { sigma_opl: 1e-7 },
        Pulse::Box { width_opl: 1e-7 },
        Pulse::Delta,
    ] {
        for g in [Gate::Box, Gate::Gaussian { sigma_opl: 1e-6 }] {
            let axis = TimeAxis {
                start_opl: 0.0,
                bin_width_opl: 0.001,
                bins: 1000,
            };
            let c = Correlation::new(axis, p, 0.0, g).unwrap();
            for d in [0.0f32, -1.0, 1e6, 0.5, 0.0005, 0.999_999, f32::MAX, f32::NAN] {
                c.for_each(d as f64, |_, s, ds| {
                    assert!(s.is_finite() && ds.is_finite(), "{p:?} {g:?} d {d}")
                });
            }
        }
    }
}

#[test]
fn bad_settings_name_the_field() {
    let e = Correlation::new(AXIS, Pulse::Gaussian { sigma_opl: 0.0 }, 0.0, Gate::Box).unwrap_err();
    assert!(e.to_string().contains("sigma_opl"));
    let e = Correlation::new(TimeAxis { bins: 0, ..AXIS }, Pulse::Delta, 0.0, Gate::Box).unwrap_err();
    assert!(e.to_string().contains("film.bins"));
}

/// Before + inside + after the axis is the whole unit mass of S_e: exactly for box gates
/// (their bins tile time), up to the ripple of Σ_l g_l for a Gaussian gate; `tails` is `None`
/// only when nothing falls outside.
#[test]
fn tails_and_bins_add_up_to_the_whole_pulse() {
    let (start, end) = (AXIS.start_opl, AXIS.end_opl());
    for pulse in pulses() {
        for gate in gates() {
            let c = Correlation::new(AXIS, pulse, 0.02, gate).unwrap();
            let tol = match gate {
                Gate::Box => 1e-9,
                Gate::Gaussian { sigma_opl } => {
                    // Poisson summation: |Σ_l g_l − 1| ≤ 2 Σ_k exp(−2π²k²σ²/w²)
                    let r = sigma_opl as f64 / AXIS.bin_width_opl;
                    (1..6)
                        .map(|k| 2.0 * (-2.0 * std::f64::consts::PI.powi(2) * (k * k) as f64 * r * r).exp())
                        .sum::<f64>()
                        + 1e-9
                }
            };
            for i in 0..4000 {
                let d = start - 1.0 + (end - start + 2.0) * i as f64 / 4000.0;
                let inside: f64 = c.range(d).map(|l| c.eval(l, d)).sum();
                let (before, after) = c.tails(d).unwrap_or((0.0, 0.0));
                let total = before + inside + after;
                assert!(
                    (total - 1.0).abs() <= tol + 1e-12,
                    "{pulse:?} {gate:?} d = {d}: {before} + {inside} + {after} = {total}"
                );
                if c.tails(d).is_none() {
                    assert!((inside - 1.0).abs() <= tol + 1e-12);
                }
            }
            // far outside, everything is on one side
            let (b, a) = c.tails(start - 5.0).unwrap();
            assert!((b - 1.0).abs() <= tol && a == 0.0, "{pulse:?} {gate:?}: {b} {a}");
            let (b, a) = c.tails(end + 5.0).unwrap();
            assert!((a - 1.0).abs() <= tol && b == 0.0, "{pulse:?} {gate:?}: {b} {a}");
        }
    }
}

/// A Gaussian gate wide against its bins has its tails summed in blocks (`TAIL_BINS`): within
/// 10⁻⁴ of the tail summed bin by bin, for every pulse, at a path inside the axis, near its
/// ends and beyond them. A gate of 10⁶ m over 0.1 m bins (an input a user can give) used to
/// take 1.6·10⁸ evaluations per path, and one of 3·10³⁸ m (the largest f32) 1.8·10¹⁹ (the
/// count saturated): it never finished. Their tails now split the whole mass evenly about a
/// path in the middle of the axis (a box pulse's under the widest gate underflows to 0).
#[test]
fn a_wide_gaussian_gates_tails_are_summed_in_blocks() {
    let (start, end) = (AXIS.start_opl, AXIS.end_opl());
    for pulse in pulses() {
        for sigma in [2.5f32, 30.0, 100.0] {
            let c = Correlation::new(AXIS, pulse, 0.02, Gate::Gaussian { sigma_opl: sigma }).unwrap();
            let w = AXIS.bin_width_opl;
            for d in [start + 0.3, 0.5 * (start + end), end - 0.05, end + 3.0, start - 40.0] {
                let u = d + c.offset;
                let x = (u - start) / w;
                let lo = (x - c.reach / w - 0.5).ceil();
                let hi = (x + c.reach / w - 0.5).floor();
                let exact = |a: f64, b: f64| {
                    let (a, b) = (a.max(lo) as i64, b.min(hi) as i64);
                    (a..=b).map(|l| c.eval_at(l as f64, u).0).sum::<f64>()
                };
                let want = (exact(lo, -1.0), exact(AXIS.bins as f64, hi));
                let got = c.tails(d).unwrap();
                for (g, e) in [(got.0, want.0), (got.1, want.1)] {
                    assert!(
                        (g - e).abs() <= 1e-4 * e.max(1e-3),
                        "{pulse:?} σ {sigma} d {d}: {g} vs {e}"
                    );
                }
            }
        }
        for sigma in [1e6f32, 3e38] {
            let c = Correlation::new(AXIS, pulse, 0.02, Gate::Gaussian { sigma_opl: sigma }).unwrap();
            let (before, after) = c.tails(0.5 * (start + end) - 0.02).unwrap();
            // at 3·10³⁸ m a box pulse's mass under one bin of the gate underflows to 0
            let split = (before - 0.5).abs() < 1e-3 && (after - 0.5).abs() < 1e-3;
            let underflow = sigma > 1e30 && matches!(pulse, Pulse::Box { .. }) && before == 0.0 && after == 0.0;
            assert!(split || underflow, "{pulse:?} σ {sigma}: {before} {after}");
        }
    }
}

/// Q(z) = 1 − Φ(z) at exact f64 points, from 60-digit arithmetic (mpmath's erfc), rounded to f64.
const UPPER_TAIL: [(f64, f64); 24] = [
    (0.0, 0.5),
    (0.125, 0.4502617751698871),
    (0.5, 0.3085375387259869),
    (1.0, 0.15865525393145705),
    (1.5, 0.06680720126885807),
    (2.0, 0.02275013194817921),
    (2.5, 0.006209665325776135),
    (3.0, 0.0013498980316300946),
    (3.5, 0.00023262907903552504),
    (3.999755859375, 3.170393118675793e-05),
    (4.0, 3.1671241833119924e-05),
    (4.5, 3.3976731247300603e-06),
    (5.0, 2.866515718791939e-07),
    (6.0, 9.86587645037698e-10),
    (7.0, 1.279812543885835e-12),
    (8.0, 6.220960574271784e-16),
    (8.5, 9.479534822203318e-18),
    (10.0, 7.619853024160525e-24),
    (12.0, 1.776482112077679e-33),
    (16.0, 6.388754400538087e-58),
    (20.0, 2.7536241186062337e-89),
    (26.0, 2.4760633155033892e-149),
    (30.0, 4.906713927148187e-198),
    (37.0, 5.725571222524577e-300),
];

/// The error bound of `normal.rs` (relative, of the smaller tail Q(|x|)): 4·10⁻¹⁵ to 8.5σ,
/// 4·10⁻¹⁶·(1 + z²) beyond, plus the f64 rounding of the reference value.
fn tail_bound(z: f64) -> f64 {
    if z <= 8.5 {
        4e-15
    } else {
        4e-16 * (1.0 + z * z) + 1.2e-16
    }
}

#[test]
fn normal_cdf_matches_high_precision_values() {
    for (z, q) in UPPER_TAIL {
        for x in [z, -z] {
            let n = normal::Normal::at(x);
            let (small, large) = if x < 0.0 {
                (n.lower, n.upper)
            } else {
                (n.upper, n.lower)
            };
            let rel = (small / q - 1.0).abs();
            assert!(rel <= tail_bound(z), "x {x}: Q {small} vs {q}: relative error {rel:e}");
            assert!(
                (large - (1.0 - q)).abs() <= 2.3e-16,
                "x {x}: 1 − Q {large} vs {}",
                1.0 - q
            );
            assert_eq!(n.pdf, (-0.5 * x * x).exp() * 0.398_942_280_401_432_7);
        }
    }
    for (x, lower) in [
        (f64::NEG_INFINITY, 0.0),
        (f64::INFINITY, 1.0),
        (-1e200, 0.0),
        (1e200, 1.0),
        (-40.0, 0.0),
    ] {
        let n = normal::Normal::at(x);
        assert_eq!((n.lower, n.upper, n.pdf), (lower, 1.0 - lower, 0.0), "x {x}");
    }
    assert!(normal::Normal::at(f64::NAN).lower.is_nan());
}

/// Φ(x) through `libm::erfc`, the f64 reference the fast CDF replaced.
fn libm_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x * std::f64::consts::FRAC_1_SQRT_2)
}

/// Against `libm::erfc` on a grid of step 10⁻⁴ over |x| ≤ 40 (past the 8σ cut and past where
/// Q underflows): the smaller tail within the bound above plus libm's own error, whose input
/// x/√2 is rounded (2 ulps relative of x/√2 move erfc by 2z²·2⁻⁵³ relative); the larger side
/// within an ulp of 1.
#[test]
fn normal_cdf_matches_libm_erfc_over_both_tails() {
    let (mut worst_abs, mut worst_rel_cut) = (0.0f64, 0.0f64);
    for i in -400_000..=400_000 {
        let x = i as f64 * 1e-4;
        let z = x.abs();
        let n = normal::Normal::at(x);
        let reference = libm_cdf(x);
        let abs = (n.lower - reference).abs();
        worst_abs = worst_abs.max(abs);
        assert!(abs <= 2.3e-16, "x {x}: Φ {} vs libm {reference}", n.lower);
        let (small, small_ref) = if x < 0.0 {
            (n.lower, reference)
        } else {
            (n.upper, libm_cdf(-x))
        };
        if small_ref > 1e-300 {
            let rel = (small / small_ref - 1.0).abs();
            if z <= GAUSSIAN_CUTOFF_SIGMAS {
                worst_rel_cut = worst_rel_cut.max(rel);
            }
            let libm_error = 2.3e-16 * (1.0 + z * z) + 2.3e-16;
            assert!(
                rel <= tail_bound(z) + libm_error,
                "x {x}: Q {small} vs libm {small_ref}: relative error {rel:e}"
            );
        }
    }
    eprintln!("against libm::erfc: max |ΔΦ| {worst_abs:e}, max relative ΔQ within 8σ {worst_rel_cut:e}");
}

/// A Gaussian factor's bins (S_e) with the fast CDF against the same closed form through
/// `libm::erfc`, and ∂S_e/∂d unchanged to the bit, for bins wide and narrow against σ (the
/// opl_precision test's 3 nm pulse in 1 nm bins among them). A bin is a difference of two
/// tails Q ≤ ½ (times w/w_p ≤ 1.5 for a box pulse): within 2·1.5·(½·4·10⁻¹⁵ + libm's share)
/// < 10⁻¹⁴ of the unit pulse mass, far below any Monte Carlo noise and below an f32 film's
/// resolution (6·10⁻⁸ of a bin).
#[test]
fn gaussian_bins_match_the_libm_erfc_closed_form() {
    let libm_diff = |a: f64, b: f64| {
        if a > 0.0 {
            libm_cdf(-a) - libm_cdf(-b)
        } else {
            libm_cdf(b) - libm_cdf(a)
        }
    };
    // the density truncated at the cut, and mass between edges clamped to it
    let cut = GAUSSIAN_CUTOFF_SIGMAS;
    let phi = |x: f64| {
        if x.abs() > cut {
            0.0
        } else {
            (-0.5 * x * x).exp() * 0.398_942_280_401_432_7
        }
    };
    let libm_diff = |a: f64, b: f64| libm_diff(a.clamp(-cut, cut), b.clamp(-cut, cut));
    let nano = TimeAxis {
        start_opl: 3.99999997,
        bin_width_opl: 1e-9,
        bins: 260,
    };
    let cases = [
        (AXIS, Pulse::Gaussian { sigma_opl: 0.03 }, Gate::Box),
        (AXIS, Pulse::Gaussian { sigma_opl: 0.003 }, Gate::Box),
        (AXIS, Pulse::Gaussian { sigma_opl: 1.0 }, Gate::Box),
        (AXIS, Pulse::Box { width_opl: 0.07 }, Gate::Gaussian { sigma_opl: 0.05 }),
        (AXIS, Pulse::Box { width_opl: 0.5 }, Gate::Gaussian { sigma_opl: 0.01 }),
        (nano, Pulse::Gaussian { sigma_opl: 3e-9 }, Gate::Box),
    ];
    let mut worst = 0.0f64;
    for (axis, pulse, gate) in cases {
        let c = Correlation::new(axis, pulse, 0.0, gate).unwrap();
        let w = axis.bin_width_opl;
        let span = axis.end_opl() - axis.start_opl;
        for k in 0..2000 {
            let u = axis.start_opl - 0.1 * span + 1.2 * span * (k as f64 + 0.37) / 2000.0;
            let r0 = axis.start_opl - u;
            let lo = c.range(u).start as i64 - 2;
            for l in lo..lo + c.range(u).len() as i64 + 4 {
                let l = l as f64;
                let (a, b, centre) = (r0 + l * w, r0 + (l + 1.0) * w, r0 + (l + 0.5) * w);
                let reference = match (pulse, gate) {
                    (Pulse::Gaussian { sigma_opl }, Gate::Box) => {
                        let s = sigma_opl as f64;
                        (libm_diff(a / s, b / s), (phi(a / s) - phi(b / s)) / s)
                    }
                    (Pulse::Box { width_opl }, Gate::Gaussian { sigma_opl }) => {
                        let (wp, s) = (width_opl as f64, sigma_opl as f64);
                        let (za, zb) = ((-0.5 * wp - centre) / s, (0.5 * wp - centre) / s);
                        (w / wp * libm_diff(za, zb), w / wp * (phi(zb) - phi(za)) / s)
                    }
                    _ => unreachable!(),
                };
                let (s, ds) = c.eval_at(l, u);
                worst = worst.max((s - reference.0).abs());
                assert!(
                    (s - reference.0).abs() <= 1e-14,
                    "{pulse:?} {gate:?} u {u} bin {l}: S_e {s} vs libm {}",
                    reference.0
                );
                assert_eq!(ds, reference.1, "{pulse:?} {gate:?} u {u} bin {l}: ∂S_e/∂d");
            }
        }
    }
    eprintln!("S_e against libm::erfc: max |ΔS_e| {worst:e} of a unit pulse");
}

/// `for_each` (which takes a Gaussian pulse's CDF once per bin edge) gives every pair's bins
/// exactly as `eval` and `eval_deriv` do, and leaves out only bins where both are 0.
#[test]
fn for_each_equals_eval_to_the_bit() {
    let nano = TimeAxis {
        start_opl: 3.99999997,
        bin_width_opl: 1e-9,
        bins: 260,
    };
    let mut cases: Vec<(TimeAxis, Pulse, Gate)> = Vec::new();
    for p in pulses() {
        for g in gates() {
            cases.push((AXIS, p, g));
        }
    }
    cases.push((nano, Pulse::Gaussian { sigma_opl: 3e-9 }, Gate::Box));
    cases.push((AXIS, Pulse::Gaussian { sigma_opl: 1e-4 }, Gate::Box));
    for (axis, pulse, gate) in cases {
        let c = Correlation::new(axis, pulse, 0.013, gate).unwrap();
        let span = axis.end_opl() - axis.start_opl;
        for k in 0..3000 {
            let d = axis.start_opl - 0.1 * span + 1.2 * span * (k as f64 + 0.29) / 3000.0;
            let mut seen = Vec::new();
            c.for_each(d, |l, s, ds| {
                assert_eq!(
                    (s, ds),
                    (c.eval(l, d), c.eval_deriv(l, d)),
                    "{pulse:?} {gate:?} d {d} bin {l}"
                );
                seen.push(l);
            });
            for l in c.range(d).filter(|l| !seen.contains(l)) {
                assert_eq!(
                    (c.eval(l, d), c.eval_deriv(l, d)),
                    (0.0, 0.0),
                    "{pulse:?} {gate:?} d {d} bin {l}"
                );
            }
        }
    }
}

/// The 8σ cut leaves S_e continuous in d and ∂S_e/∂d all of its derivative, for every pair
/// with a Gaussian factor: across the d where bin l leaves the support, S_e(d₂) − S_e(d₁) is
/// the integral of `eval_deriv` over [d₁, d₂] (Simpson, 4000 intervals; ∂S_e/∂d jumps at
/// the cut, which costs the rule about 3·10⁻⁵ of S_e(d₁) here: the bound is 10⁻³). With a
/// jump in S_e at the cut the difference was −S_e(d₁), the bin's whole far-tail value, which
/// the derivative does not see.
#[test]
fn the_gaussian_cut_leaves_s_e_continuous() {
    let pairs = [
        (Pulse::Gaussian { sigma_opl: 0.03 }, Gate::Box),
        (Pulse::Delta, Gate::Gaussian { sigma_opl: 0.05 }),
        (Pulse::Gaussian { sigma_opl: 0.03 }, Gate::Gaussian { sigma_opl: 0.05 }),
        (Pulse::Box { width_opl: 0.07 }, Gate::Gaussian { sigma_opl: 0.05 }),
    ];
    let l = 9;
    for (pulse, gate) in pairs {
        let c = Correlation::new(AXIS, pulse, 0.0, gate).unwrap();
        // the d where bin l leaves the support on its early side: past its end (box gate) or
        // its centre (Gaussian gate) by the reach
        let last = match gate {
            Gate::Box => AXIS.bin_start(l + 1),
            Gate::Gaussian { .. } => AXIS.bin_start(l) + 0.5 * AXIS.bin_width_opl,
        } + c.reach();
        for (d1, d2) in [(last - 0.01, last + 0.01), (last - 0.005, last - 0.001)] {
            let n = 4000;
            let step = (d2 - d1) / n as f64;
            let integral = (0..=n)
                .map(|k| {
                    let w = if k == 0 || k == n { 1.0 } else { [2.0, 4.0][k % 2] };
                    w * c.eval_deriv(l, d1 + k as f64 * step)
                })
                .sum::<f64>()
                * step
                / 3.0;
            let (s1, s2) = (c.eval(l, d1), c.eval(l, d2));
            assert!(s1 > 0.0, "{pulse:?} {gate:?}: bin {l} is inside the support at {d1}");
            assert!(
                (s2 - s1 - integral).abs() <= 1e-3 * s1,
                "{pulse:?} {gate:?} on [{d1}, {d2}]: ΔS_e {:e}, ∫∂S_e/∂d {integral:e}",
                s2 - s1
            );
        }
    }
}

/// A Gaussian S_e's bins carry φ from bin to bin (`Correlation::gaussian_bins`): every value
/// and derivative stays within 10⁻¹² (relative) of the closed form `eval_at`, over runs from
/// a bin or two (σ below the bin width) to hundreds of bins (σ of 40 bins, where the
/// recurrence restarts every `GAUSSIAN_RUN` bins), for delta and Gaussian pulses, and every
/// bin the closed form finds nonzero is visited.
#[test]
fn gaussian_bins_match_the_closed_form() {
    let mut worst = 0.0f64;
    for (bins, width, sigma_gate) in [
        (40, 0.1, 0.03f32),
        (40, 0.1, 0.05),
        (200, 0.01, 0.1),
        (3000, 0.001, 0.04),
    ] {
        let axis = TimeAxis {
            start_opl: 1.0,
            bin_width_opl: width,
            bins,
        };
        for pulse in [Pulse::Delta, Pulse::Gaussian { sigma_opl: 0.02 }] {
            let c = Correlation::new(axis, pulse, 0.013, Gate::Gaussian { sigma_opl: sigma_gate }).unwrap();
            let span = axis.end_opl() - axis.start_opl;
            for k in 0..400 {
                let d = axis.start_opl - 0.1 * span + 1.2 * span * (k as f64 + 0.37) / 400.0;
                let u = d + 0.013;
                let mut seen = vec![false; bins];
                c.for_each(d, |l, s, ds| {
                    let (s0, ds0) = c.eval_at(l as f64, u);
                    let (es, eds) = ((s - s0).abs() / s0.abs(), (ds - ds0).abs() / ds0.abs().max(1e-300));
                    if s0.abs() > 1e-9 {
                        worst = worst.max(es);
                    }
                    assert!(
                        es <= 1e-12 || (s - s0).abs() <= 1e-25,
                        "{pulse:?} σ {sigma_gate} d {d} bin {l}: S_e {s} against {s0}"
                    );
                    assert!(
                        eds <= 1e-12 || (ds - ds0).abs() <= 1e-25,
                        "{pulse:?} σ {sigma_gate} d {d} bin {l}: ∂S_e {ds} against {ds0}"
                    );
                    seen[l] = true;
                });
                for l in c.range(d) {
                    assert!(
                        seen[l] || c.eval_at(l as f64, u) == (0.0, 0.0),
                        "{pulse:?} d {d}: bin {l} left out"
                    );
                }
            }
        }
    }
    eprintln!("Gaussian S_e by recurrence: worst relative error {worst:e}");
}

/// `Truncated::at` is the standard normal at x clamped to the cut, with its density zero beyond
/// the cut, to the bit: the two values beyond the cut are taken once, not at every edge.
#[test]
fn truncated_ends_taken_once_equal_the_clamped_normal() {
    let c = GAUSSIAN_CUTOFF_SIGMAS;
    let t = normal::Truncated::new(c);
    let mut xs = vec![
        -1e6,
        -40.0,
        -c - 1e-9,
        -c,
        -c + 1e-12,
        -3.0,
        -0.0,
        0.0,
        1e-300,
        2.5,
        c - 1e-12,
        c,
        c + 1e-9,
        40.0,
        1e6,
    ];
    xs.extend((0..2001).map(|i| -10.0 + 0.01 * i as f64));
    for x in xs {
        let mut want = normal::Normal::at(x.clamp(-c, c));
        if x.abs() > c {
            want.pdf = 0.0;
        }
        let got = t.at(x);
        for (g, w, what) in [
            (got.x, want.x, "x"),
            (got.pdf, want.pdf, "pdf"),
            (got.lower, want.lower, "lower"),
            (got.upper, want.upper, "upper"),
        ] {
            assert_eq!(g.to_bits(), w.to_bits(), "{what} at x = {x}: {g} against {w}");
        }
    }
}
