//! The run's energy report against the film's time window (`RenderStats::energy`): what fell
//! before, inside and after the window adds up to the whole image, and matches the bins of a
//! render whose window holds every path (same seed, so the same paths).

use crate::common;
use difftransient::film::SteadyMode;
use difftransient::temporal::{Gate, Pulse};
use difftransient::{RenderOptions, Scene, render};

/// The small Cornell box (4 bounces: every OPL < 40 m) with the given pulse and gate and a
/// window of `bins` bins of 0.1 m from `start`.
fn cornell(pulse: Pulse, gate: Gate, start: f64, bins: usize) -> Scene {
    let mut s = common::load("cornell_box.toml");
    s.film.width = 16;
    s.film.height = 16;
    s.integrator.max_bounces = 4;
    s.film.axis.start_opl = start;
    s.film.axis.bin_width_opl = 0.1;
    s.film.axis.bins = bins;
    s.film.gate = gate;
    for e in &mut s.emitters {
        e.pulse = pulse;
    }
    s
}

#[test]
fn before_inside_after_match_the_bins_of_a_window_holding_everything() {
    // every path traced to its end (no window cut), so that both windows see the same paths
    let opts = RenderOptions {
        spp: Some(4),
        seed: Some(5),
        threads: Some(2),
        steady: SteadyMode::Full,
        ..Default::default()
    };
    let cases = [
        (Pulse::Delta, Gate::Box),
        (Pulse::Gaussian { sigma_opl: 0.05 }, Gate::Box),
        (Pulse::Box { width_opl: 0.25 }, Gate::Box),
        (Pulse::Delta, Gate::Gaussian { sigma_opl: 0.1 }),
    ];
    for (pulse, gate) in cases {
        // [−1, 45] m holds every path with its pulse and gate; [5, 8] m cuts both ends
        let (full, fs) = render(&cornell(pulse, gate, -1.0, 460), &opts).unwrap();
        let (_, ns) = render(&cornell(pulse, gate, 5.0, 30), &opts).unwrap();
        let what = format!("{pulse:?} / {gate:?}");
        let e = &fs.energy;
        assert!(e.total > 0.0, "{what}: nothing rendered");
        assert!(
            e.before == 0.0 && e.after <= 1e-9 * e.total,
            "{what}: wide window {e:?}"
        );
        let bins = full.bin_totals();
        let sum = |r: std::ops::Range<usize>| bins[r].iter().map(|&v| v as f64).sum::<f64>();
        // bins 0..60 of the wide window end at 5 m, 60..90 are [5, 8) m
        let (before, inside, after) = (sum(0..60), sum(60..90), sum(90..460));
        let n = &ns.energy;
        // the same paths: equal up to f32 film rounding
        let tol = 1e-5 * e.total;
        for (name, got, want) in [
            ("total", n.total, e.total),
            ("before", n.before, before),
            ("inside", n.inside, inside),
            ("after", n.after, after),
            ("before + inside + after", n.before + n.inside + n.after, e.total),
        ] {
            assert!((got - want).abs() <= tol, "{what}: {name} {got} vs {want} (tol {tol})");
        }
        assert!(n.before > 0.1 * e.total && n.after > 0.01 * e.total, "{what}: {n:?}");
        assert!((n.inside_fraction - n.inside / n.total).abs() < 1e-12);
    }
}
