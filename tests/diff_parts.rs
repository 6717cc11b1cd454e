//! `render_diff` is the sum of named parts (`render_diff_parts`): the interior (Algorithm 1),
//! primary and secondary boundary films, each from its own estimator and samples. Each part
//! equals what the estimator modes render on their own (each boundary term alone too), and
//! the parts sum to `render_diff`.

use crate::common;
use difftransient::render::{BoundaryMode, render_diff_parts};
use difftransient::{RenderOptions, render_diff};

#[test]
fn the_gradient_is_interior_plus_primary_plus_secondary() {
    // a hidden occluder's shadow (secondary edges only) and a sliding cube's silhouette
    check("shadow_hidden_occluder.toml", &["occluder_x", "light_x"], false);
    check("silhouette_slide.toml", &["cube_x"], true);
}

fn check(name: &str, params: &[&str], seen: bool) {
    let mut scene = common::load(name);
    scene.film.width = 16;
    scene.film.height = 16;
    let params: Vec<String> = params.iter().map(|p| p.to_string()).collect();
    let n = params.len();
    let opts = RenderOptions {
        spp: Some(2),
        seed: Some(3),
        threads: Some(2),
        ..Default::default()
    };
    let parts = render_diff_parts(&scene, &params, &opts).unwrap();
    assert_eq!(parts.interior.len(), n);
    assert_eq!(parts.primary.len(), n);
    assert_eq!(parts.secondary.len(), n);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let (primal, grad, _) = render_diff(&scene, &params, &opts).unwrap();
    assert_eq!(bits(&primal.data), bits(&parts.primal.data));
    let sum = parts.sum();
    for k in 0..n {
        assert_eq!(bits(&grad[k].data), bits(&sum[k].data), "parameter {k}");
    }
    let only = |mode| {
        let o = RenderOptions {
            boundary: mode,
            ..opts.clone()
        };
        render_diff(&scene, &params, &o).unwrap().1
    };
    let interior = only(BoundaryMode::InteriorOnly);
    let boundary = only(BoundaryMode::BoundaryOnly);
    // each boundary term alone (`--estimators primary|secondary`) is its part of the sum,
    // from the same samples
    let primary = only(BoundaryMode::PrimaryOnly);
    let secondary = only(BoundaryMode::SecondaryOnly);
    for k in 0..n {
        assert_eq!(bits(&interior[k].data), bits(&parts.interior[k].data), "interior {k}");
        assert_eq!(bits(&primary[k].data), bits(&parts.primary[k].data), "primary {k}");
        assert_eq!(
            bits(&secondary[k].data),
            bits(&parts.secondary[k].data),
            "secondary {k}"
        );
        let b: Vec<f32> = parts.primary[k]
            .data
            .iter()
            .zip(&parts.secondary[k].data)
            .map(|(a, b)| a + b)
            .collect();
        // boundary-only films are 0 + (primary + secondary)
        assert_eq!(bits(&boundary[k].data), bits(&b), "boundary {k}");
        // the part each scene is about is not empty (the camera sees the cube, never the
        // occluder)
        let nonzero = |t: &difftransient::Transient| t.data.iter().any(|&v| v != 0.0);
        match seen {
            true => assert!(nonzero(&parts.primary[k]), "{name}: primary {k}"),
            false => assert!(nonzero(&parts.secondary[k]), "{name}: secondary {k}"),
        }
    }
}
