use super::*;
use crate::temporal::{Correlation, TimeAxis};

/// A square of side `side` centred on `centre` in the plane y = `centre.y`, emitting
/// downwards (−y), as two triangles.
fn square(centre: DVec3, side: f64) -> Vec<[DVec3; 3]> {
    let h = 0.5 * side;
    let c = |dx: f64, dz: f64| centre + DVec3::new(dx, 0.0, dz);
    // wound so that (b − a) × (c − a) points down
    vec![[c(-h, -h), c(h, -h), c(h, h)], [c(-h, -h), c(h, h), c(-h, h)]]
}

fn edges_for(polygons: Vec<Polygon>, pulse: Pulse, axis: TimeAxis, offset: f64) -> TimeEdges {
    TimeEdges {
        emitters: vec![EmitterPolygons::new(0, 0, polygons, [1.0; 3]).unwrap()],
        slot: vec![Some(0)],
        spreads: vec![Spread::of(pulse, axis.bin_width_opl)],
        first: vec![axis.start_opl - offset],
        width: axis.bin_width_opl,
        edges: axis.bins + 1,
        always: false,
        emitters_move: false,
    }
}

/// The tests' light: a 0.5 m square at y = 2 centred on (0.1, −0.2) in x, z.
fn test_light() -> Vec<[DVec3; 3]> {
    square(DVec3::new(0.1, 2.0, -0.2), 0.5)
}

/// Calls `f(point, cell area)` at the midpoints of an n × n grid over [`test_light`].
fn light_grid(n: usize, mut f: impl FnMut(DVec3, f64)) {
    let cell = 0.5 / n as f64;
    for i in 0..n {
        for j in 0..n {
            let y = DVec3::new(
                0.1 - 0.25 + (i as f64 + 0.5) * cell,
                2.0,
                -0.2 - 0.25 + (j as f64 + 0.5) * cell,
            );
            f(y, cell * cell);
        }
    }
}

/// A small counter-based generator for the tests' numbers.
fn uniform(key: u64) -> f64 {
    crate::kernel::hash_to_unit(key) as f64
}

#[test]
fn a_quad_light_is_one_polygon_and_other_meshes_stay_triangles() {
    let quad = polygons(&square(DVec3::new(0.3, 2.0, -0.1), 0.5));
    assert_eq!(quad.len(), 1);
    assert_eq!(quad[0].corners.len(), 4);
    assert!((quad[0].area - 0.25).abs() < 1e-12, "{}", quad[0].area);
    assert!((quad[0].normal - DVec3::NEG_Y).length() < 1e-12, "{}", quad[0].normal);
    // an L of three unit squares' worth of triangles is not convex: one polygon per triangle
    let o = DVec3::ZERO;
    let p = |x: f64, z: f64| o + DVec3::new(x, 0.0, z);
    let l_shape = vec![
        [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)],
        [p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)],
        [p(1.0, 0.0), p(2.0, 0.0), p(2.0, 1.0)],
        [p(1.0, 0.0), p(2.0, 1.0), p(1.0, 1.0)],
        [p(0.0, 1.0), p(1.0, 1.0), p(1.0, 2.0)],
        [p(0.0, 1.0), p(1.0, 2.0), p(0.0, 2.0)],
    ];
    assert_eq!(polygons(&l_shape).len(), 6);
    // two triangles at an angle (a folded quad): per triangle
    let mut folded = square(DVec3::ZERO, 1.0);
    folded[1][2].y += 0.1;
    assert_eq!(polygons(&folded).len(), 2);
}

/// A regular hexagon of circumradius 0.6 in the plane y = 1, emitting downwards, as a fan of
/// six triangles (one polygon of six sides: the sides' angles take two vector calls).
fn hexagon() -> Vec<[DVec3; 3]> {
    let corner = |i: usize| {
        let a = i as f64 * std::f64::consts::TAU / 6.0;
        DVec3::new(0.6 * a.cos(), 1.0, -0.6 * a.sin())
    };
    let centre = DVec3::new(0.0, 1.0, 0.0);
    (0..6).map(|i| [centre, corner(i), corner(i + 1)]).collect()
}

#[test]
fn arcs_are_the_circle_inside_the_polygon() {
    for (name, tris) in [
        ("square", square(DVec3::new(0.0, 1.0, 0.0), 1.0)),
        ("hexagon", hexagon()),
    ] {
        let polys = polygons(&tris);
        assert_eq!(polys.len(), 1, "{name}");
        arcs_of(name, &polys[0]);
    }
}

fn arcs_of(name: &str, poly: &Polygon) {
    let inside = |q: DVec2| poly.sides.iter().all(|&(m, k)| m.dot(q) <= k);
    // distance of q from the nearest side's line
    let off_sides = |q: DVec2| {
        poly.sides
            .iter()
            .map(|&(m, k)| (m.dot(q) - k).abs())
            .fold(f64::MAX, f64::min)
    };
    let n = 20_000;
    for case in 0..40u64 {
        let c = DVec2::new(uniform(case * 3) * 1.6 - 0.8, uniform(case * 3 + 1) * 1.6 - 0.8);
        let rho = 0.02 + uniform(case * 3 + 2) * 1.2;
        let mut arcs = [(0.0, 0.0); MAX_SIDES];
        let (k, theta) = poly.arcs(c, rho, &mut arcs);
        let hits = (0..n)
            .filter(|&i| {
                let phi = (i as f64 + 0.5) / n as f64 * std::f64::consts::TAU;
                inside(c + DVec2::new(phi.cos(), phi.sin()) * rho)
            })
            .count();
        let dense = hits as f64 / n as f64 * std::f64::consts::TAU;
        assert!((theta - dense).abs() < 1e-3, "{name} case {case}: Θ {theta} vs {dense}");
        // each arc's midpoint lies inside, and its ends on a side (but where an arc runs
        // through φ = 0, which the intervals split at)
        let at = |phi: f64| c + DVec2::new(phi.cos(), phi.sin()) * rho;
        for &(a, b) in &arcs[..k] {
            let m = 0.5 * (a + b);
            assert!(inside(at(m)), "{name} case {case}: arc ({a}, {b})");
            for end in [a, b].into_iter().filter(|&e| e != 0.0 && e != std::f64::consts::TAU) {
                let off = off_sides(at(end));
                assert!(
                    off < 1e-13,
                    "{name} case {case}: arc end {end} lies {off:e} off every side"
                );
            }
        }
    }
}

/// ∫ over the light of ∂S_e(l, D(y))/∂D dA(y) for every bin l, by the draws (mean and
/// standard error over `plans` vertices' worth of draws) and by a midpoint rule on a fine grid.
fn draws_against_quadrature(pulse: Pulse, x: DVec3, d_p: f64, eta: f64, plans: u64) {
    let axis = TimeAxis {
        start_opl: 4.0,
        bin_width_opl: 0.06,
        bins: 40,
    };
    let offset = 0.05;
    let light = test_light();
    let te = edges_for(polygons(&light), pulse, axis, offset);
    let corr = Correlation::new(axis, pulse, offset, Gate::Box).unwrap();
    let opl = |y: DVec3| d_p + eta * (y - x).length();
    // the reference: a 1500 × 1500 midpoint grid over the square
    let mut reference = vec![0.0f64; axis.bins];
    light_grid(1500, |y, da| corr.for_each(opl(y), |l, _, ds| reference[l] += ds * da));
    let mut sum = vec![0.0f64; axis.bins];
    let mut sum2 = vec![0.0f64; axis.bins];
    let mut draws = 0usize;
    for k in 0..plans {
        let key = k * 64;
        let Some(plan) = te.plan(x, d_p, eta, uniform(key), uniform(key + 1)) else {
            continue;
        };
        let mut one = vec![0.0f64; axis.bins];
        for slot in 0..plan.slots {
            let xi = uniform(key + 2 + 2 * slot as u64);
            let v = uniform(key + 3 + 2 * slot as u64);
            if let Some(d) = te.draw(&plan, slot, xi, v) {
                assert!((d.y.y - 2.0).abs() < 1e-9, "the draw leaves the light: {}", d.y);
                assert!(
                    (d.y.x - 0.1).abs() <= 0.25 + 1e-9 && (d.y.z + 0.2).abs() <= 0.25 + 1e-9,
                    "{}",
                    d.y
                );
                corr.for_each(opl(d.y), |l, _, ds| one[l] += ds * d.weight);
                draws += 1;
            }
        }
        for l in 0..axis.bins {
            sum[l] += one[l];
            sum2[l] += one[l] * one[l];
        }
    }
    let m = plans as f64;
    let scale = reference.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(scale > 0.0 && draws > 0);
    let mut chi2 = 0.0;
    let mut used = 0;
    for l in 0..axis.bins {
        let mean = sum[l] / m;
        let se = ((sum2[l] / m - mean * mean).max(0.0) / (m - 1.0)).sqrt();
        if reference[l].abs() < 1e-6 * scale && se == 0.0 {
            continue;
        }
        // the grid's own error: a fraction of a per cent of the largest bin
        let z = (mean - reference[l]) / (se * se + (2e-3 * scale).powi(2)).sqrt();
        assert!(
            z.abs() < 4.5,
            "{pulse:?} bin {l}: draws {mean:.5} ± {se:.1e}, quadrature {:.5}",
            reference[l]
        );
        chi2 += z * z;
        used += 1;
    }
    assert!(used >= 3, "{used} bins reached");
    assert!(chi2 / (used as f64) < 2.0, "{pulse:?}: mean z² {}", chi2 / used as f64);
}

#[test]
fn draws_estimate_the_time_term_over_a_light_gaussian_pulse() {
    // a vertex 1.7 m below the light, off to one side, prefix OPL 2.5 m in air
    draws_against_quadrature(
        Pulse::Gaussian { sigma_opl: 0.01 },
        DVec3::new(-0.4, 0.3, 0.3),
        2.5,
        1.0,
        20_000,
    );
}

#[test]
fn draws_estimate_the_time_term_over_a_light_box_pulse_in_a_medium() {
    // close under the light's centre (the foot point inside it), in water
    draws_against_quadrature(
        Pulse::Box { width_opl: 0.02 },
        DVec3::new(0.05, 1.6, -0.25),
        3.6,
        1.33,
        20_000,
    );
}

#[test]
fn a_vertex_behind_the_light_or_out_of_reach_draws_nothing() {
    let axis = TimeAxis {
        start_opl: 4.0,
        bin_width_opl: 0.06,
        bins: 40,
    };
    let te = edges_for(
        polygons(&square(DVec3::new(0.0, 2.0, 0.0), 0.5)),
        Pulse::Gaussian { sigma_opl: 0.01 },
        axis,
        0.0,
    );
    // above the light (behind its emitting side)
    assert!(te.plan(DVec3::new(0.0, 2.5, 0.0), 2.5, 1.0, 0.3, 0.3).is_none());
    // OPLs far past the window's end
    assert!(te.plan(DVec3::new(0.0, 0.0, 0.0), 10.0, 1.0, 0.3, 0.3).is_none());
    // in reach: some draws
    let plan = te.plan(DVec3::new(0.0, 0.0, 0.0), 2.5, 1.0, 0.3, 0.3).unwrap();
    assert!(plan.slots >= 1 && plan.slots <= MAX_SLOTS);
}

#[test]
fn delta_draws_measure_each_edge_circle() {
    // Σ of an edge's draws' weights estimates ∫ δ(E_j − D(y)) dA(y): how fast the light's
    // area with D < E grows at E_j, here measured on a 2000² grid over ±5 mm of OPL
    let axis = TimeAxis {
        start_opl: 4.0,
        bin_width_opl: 0.06,
        bins: 40,
    };
    let (x, d_p, eta) = (DVec3::new(-0.4, 0.3, 0.3), 2.5, 1.0);
    let light = test_light();
    let te = edges_for(polygons(&light), Pulse::Delta, axis, 0.0);
    let band = 0.001;
    let mut reference = vec![0.0f64; axis.bins + 1];
    light_grid(4000, |y, da| {
        let d = d_p + eta * (y - x).length();
        let j = ((d - axis.start_opl) / axis.bin_width_opl).round();
        let edge = axis.start_opl + j * axis.bin_width_opl;
        if (d - edge).abs() < band && j >= 0.0 && (j as usize) <= axis.bins {
            reference[j as usize] += da / (2.0 * band);
        }
    });
    let plans = 4000u64;
    let mut sum = vec![0.0f64; axis.bins + 1];
    for k in 0..plans {
        let key = k * 64 + 7;
        let plan = te.plan(x, d_p, eta, uniform(key), uniform(key + 1)).unwrap();
        for slot in 0..plan.slots {
            let d = te.draw(
                &plan,
                slot,
                uniform(key + 2 + 2 * slot as u64),
                uniform(key + 3 + 2 * slot as u64),
            );
            let d = d.expect("a draw on every edge in reach");
            let j = d.edge.expect("a delta draw names its edge") as usize;
            let on = d_p + eta * (d.y - x).length();
            assert!(
                (on - (axis.start_opl + j as f64 * axis.bin_width_opl)).abs() < 1e-9,
                "{on}"
            );
            sum[j] += d.weight;
        }
    }
    let reached = reference.iter().filter(|&&v| v > 0.0).count();
    assert!(reached >= 2, "{reached} edges");
    for j in 0..=axis.bins {
        let est = sum[j] / plans as f64;
        // the draws' only randomness is the angle: the weights are r·Θ, the same for every draw
        // of an edge, so the mean is exact up to the grid's error (0.2 % here; the ±5 mm band
        // of a 2000² grid was 2 % off at the first edge)
        assert!(
            (est - reference[j]).abs() <= 0.005 * reference[j].max(1e-3),
            "edge {j}: draws {est:.5}, grid {:.5}",
            reference[j]
        );
    }
}

/// The logistic's runs of components share one `exp` (`Spread::component_masses`,
/// `Spread::density_at`): every mass and every density stays within 10⁻¹² (relative) of
/// evaluating each component by `Spread::cdf` and `Spread::pdf`, for pulses from a fifth of
/// a bin to six bins wide and OPL ranges that start, end and lie inside the cut.
#[test]
fn carried_logistic_terms_match_each_component_evaluated_alone() {
    let (first, w) = (3.9, 0.05);
    let mut worst = 0.0f64;
    for sigma in [0.01f32, 0.05, 0.3] {
        let spread = Spread::of(Pulse::Gaussian { sigma_opl: sigma }, w);
        let reach = spread.reach();
        for k in 0..200 {
            let d_lo = 3.7 + 0.0131 * k as f64;
            let d_hi = d_lo + 0.002 + 0.0077 * (k % 37) as f64;
            let js = 0..((d_hi + reach - first) / w).floor().max(0.0) as usize + 1;
            let mut got = Vec::new();
            spread.component_masses(first, w, d_lo, d_hi, js.clone(), |i, m| {
                got.push((i, m));
                true
            });
            for (i, j) in js.clone().enumerate() {
                let edge = first + j as f64 * w;
                let (a, b) = ((edge - d_hi).max(-reach), (edge - d_lo).min(reach));
                let want = if a >= b { 0.0 } else { spread.cdf(b) - spread.cdf(a) };
                assert_eq!(got[i].0, i);
                let err = (got[i].1 - want).abs();
                assert!(
                    err <= 1e-12 * want.abs() + 1e-15,
                    "σ {sigma} d {d_lo}..{d_hi} edge {j}: mass {} against {want}",
                    got[i].1
                );
                if want > 1e-6 {
                    worst = worst.max(err / want);
                }
            }
            for d in [d_lo, 0.5 * (d_lo + d_hi), d_hi] {
                let got = spread.density_at(first, w, d, js.clone());
                let want: f64 = js
                    .clone()
                    .map(|j| first + j as f64 * w - d)
                    .filter(|t| t.abs() <= reach)
                    .map(|t| spread.pdf(t))
                    .sum();
                assert!(
                    (got - want).abs() <= 1e-12 * want,
                    "σ {sigma} d {d}: density {got} against {want}"
                );
            }
        }
    }
    eprintln!("carried logistic masses: worst relative error {worst:e}");
}
