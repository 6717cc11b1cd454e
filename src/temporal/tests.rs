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
