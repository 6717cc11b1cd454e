//! Helpers for the integrator's unit tests: scenes from text at chosen parameter values, the
//! loader's own vertex positions a step either side of a parameter's value (the reference
//! for derivatives of geometry), and the χ² p-value of the sampling tests.

use crate::scene::testutil::header;
use crate::scene::{Format, ParamKind, Scene};
use glam::Vec3;
use std::path::Path;

/// A shape posed away from the world origin (the render origin, which positions and
/// transforms are relative to, is then not the world's) with a rotation about all three axes
/// and an unequal scale, and a mirrored plate (negative scale: the loader flips its winding).
/// Every pose component of both is a parameter, at the value the shape states.
pub const POSED: &str = concat!(
    header!(),
    r#"
[[shape]]
name = "box"
type = "cube"
material = "white"
translate = [10.3, -0.4, 0.7]
rotate = [25.0, -40.0, 15.0]
scale = [1.25, 0.625, 0.875]

[[shape]]
name = "plate"
type = "rectangle"
material = "white"
translate = [9.0, 1.5, -0.5]
rotate = [-70.0, 20.0, 10.0]
scale = [-0.75, 1.125, 1.0]

[[emitter]]
name = "lamp"
type = "point"
position = [10.0, 3.0, 3.0]
intensity = 1.0

[[param]]
name = "tx"
kind = "translate"
shape = "box"
axis = "x"
value = 10.3

[[param]]
name = "ty"
kind = "translate"
shape = "box"
axis = "y"
value = -0.4

[[param]]
name = "rx"
kind = "rotate"
shape = "box"
axis = "x"
value = 25.0

[[param]]
name = "ry"
kind = "rotate"
shape = "box"
axis = "y"
value = -40.0

[[param]]
name = "rz"
kind = "rotate"
shape = "box"
axis = "z"
value = 15.0

[[param]]
name = "sx"
kind = "scale"
shape = "box"
axis = "x"
value = 1.25

[[param]]
name = "sy"
kind = "scale"
shape = "box"
axis = "y"
value = 0.625

[[param]]
name = "sz"
kind = "scale"
shape = "box"
axis = "z"
value = 0.875

[[param]]
name = "plate_sx"
kind = "scale"
shape = "plate"
axis = "x"
value = -0.75

[[param]]
name = "plate_ry"
kind = "rotate"
shape = "plate"
axis = "y"
value = 20.0
"#
);

/// Parameters of [`POSED`] (the dual number's derivative lanes in the tests).
pub const POSED_PARAMS: usize = 10;

/// Loads scene `text` with `--set` overrides.
pub fn load(text: &str, overrides: &[(String, f64)]) -> Scene {
    Scene::from_str(text, Format::Toml, Path::new("unit_test.toml"), overrides).unwrap_or_else(|e| panic!("{e}"))
}

/// Every parameter's name, in file order.
pub fn param_names(scene: &Scene) -> Vec<String> {
    scene.params.iter().map(|p| p.name.clone()).collect()
}

/// The central-difference step of a pose parameter, a power of two so that value ± step is
/// exact in the f32 the loader keeps (the values of [`POSED`] are exact in f32 too). Positions
/// are linear in a translation and in a scale factor, so the step only has to keep the f32
/// rounding of the loaded positions (≤ 2⁻²⁴ of a coordinate) small against the move: 2⁻⁷
/// m or 2⁻⁷ leaves about 10⁻⁵. In a rotation they are sinusoids of the angle: 0.125° =
/// 2.2·10⁻³ rad leaves a truncation error of (2.2·10⁻³)²/6 ≈ 8·10⁻⁷ of the derivative.
pub fn step(kind: &ParamKind) -> f64 {
    match kind {
        ParamKind::Rotate { .. } => 0.125,
        _ => 1.0 / 128.0,
    }
}

/// The loader's world vertex positions with parameter `k` of `scene` (loaded from `text`) set
/// to its value − h and + h. Both keep the render origin, so positions compare directly.
pub fn positions_either_side(text: &str, scene: &Scene, k: usize, h: f64) -> [Vec<Vec3>; 2] {
    let p = &scene.params[k];
    [-h, h].map(|s| {
        let moved = load(text, &[(p.name.clone(), p.value + s)]);
        assert_eq!(
            moved.render_origin, scene.render_origin,
            "{}: the render origin moved",
            p.name
        );
        moved.geometry.positions
    })
}

/// P(χ² ≥ `chi2`) for `dof` degrees of freedom: the regularised upper incomplete gamma
/// function Q(dof/2, chi2/2) (series below a + 1, Lentz's continued fraction above;
/// Numerical Recipes §6.2).
pub fn chi2_p_value(chi2: f64, dof: usize) -> f64 {
    let (a, x) = (dof as f64 / 2.0, chi2 / 2.0);
    if x <= 0.0 {
        return 1.0;
    }
    let log_prefix = a * x.ln() - x - libm::lgamma(a);
    if x < a + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        while term.abs() > sum.abs() * 1e-15 {
            n += 1.0;
            term *= x / n;
            sum += term;
        }
        1.0 - sum * log_prefix.exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let (mut c, mut d) = (1.0 / tiny, 1.0 / b);
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            d = if d.abs() < tiny { 1.0 / tiny } else { 1.0 / d };
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        log_prefix.exp() * h
    }
}

/// The χ² test of a sampler: `observed[i]` samples fell in cell i, whose probability the
/// sampler's reported density gives as `probability[i]`. The probabilities must sum to 1
/// within `sum_tol` (the density integrates to 1 over what is sampled), no sample may fall
/// in a cell of probability 0, and Pearson's χ² (one degree of freedom less than the cells:
/// the expected counts are fully specified and sum to the sample count) must have p > 10⁻⁴.
/// The callers' seeds are fixed; a right sampler fails one seed in 10⁴.
pub fn assert_chi2(what: &str, observed: &[u64], probability: &[f64], sum_tol: f64) {
    assert_eq!(observed.len(), probability.len());
    let total: f64 = probability.iter().sum();
    assert!(
        (total - 1.0).abs() < sum_tol,
        "{what}: the reported density integrates to {total}"
    );
    let samples: u64 = observed.iter().sum();
    let (mut chi2, mut cells) = (0.0, 0);
    for (&o, &q) in observed.iter().zip(probability) {
        assert!(q > 0.0 || o == 0, "{what}: {o} samples in a cell of zero probability");
        if q > 0.0 {
            let e = q * samples as f64;
            chi2 += (o as f64 - e).powi(2) / e;
            cells += 1;
        }
    }
    let p = chi2_p_value(chi2, cells - 1);
    eprintln!("{what}: χ² = {chi2:.1} over {cells} cells, p = {p:.3}");
    assert!(p > 1e-4, "{what}: χ² = {chi2:.1} over {cells} cells, p = {p:.2e}");
}

#[test]
fn chi2_p_values_match_closed_forms() {
    // dof 2: Q = exp(−x/2); dof 1: Q = erfc(√(x/2)); both branches of the gamma function
    for x in [0.1, 1.0, 2.5, 7.0, 30.0] {
        let q2 = chi2_p_value(x, 2);
        assert!(
            (q2 - (-x / 2.0).exp()).abs() <= 1e-12 * q2.max(1e-3),
            "dof 2, χ² {x}: {q2}"
        );
        let q1 = chi2_p_value(x, 1);
        let want = libm::erfc((x / 2.0).sqrt());
        assert!(
            (q1 - want).abs() <= 1e-10 * want.max(1e-3),
            "dof 1, χ² {x}: {q1} vs {want}"
        );
    }
    // large dof: the median of χ²_k is about k(1 − 2/(9k))³
    let k = 300;
    let median = k as f64 * (1.0 - 2.0 / (9.0 * k as f64)).powi(3);
    assert!((chi2_p_value(median, k) - 0.5).abs() < 2e-3);
}
