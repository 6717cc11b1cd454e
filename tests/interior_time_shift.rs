//! η shifts every path in time: OPL = η × length. On the confocal plane (one bounce), the
//! transient's mean arrival OPL scales exactly with η, its peak bin moves by the predicted
//! number of bins, and the η-derivative predicts the move. Also: a time-shifting parameter
//! with a delta pulse and box gate is refused, and unknown names list the parameters.

use crate::common;
use difftransient::scene::IntegratorKind;
use difftransient::temporal::Pulse;
use difftransient::{RenderOptions, Scene, Transient, render, render_diff};

fn scene(eta: f32) -> Scene {
    let mut s = Scene::load(
        &common::scene_path("confocal_plane.toml"),
        &[("eta".into(), eta as f64)],
    )
    .unwrap();
    s.emitters[0].pulse = Pulse::Gaussian { sigma_opl: 0.01 };
    s
}

fn opts(seed: u64) -> RenderOptions {
    opts_with(seed, IntegratorKind::Path)
}

fn opts_with(seed: u64, integrator: IntegratorKind) -> RenderOptions {
    RenderOptions {
        spp: Some(4),
        seed: Some(seed),
        threads: Some(2),
        integrator: Some(integrator),
        ..Default::default()
    }
}

/// (Σ I, Σ t·I) over the whole image, t = bin centre OPL.
fn moments(t: &Transient) -> (f64, f64) {
    let totals = t.bin_totals();
    let s0: f64 = totals.iter().map(|&v| v as f64).sum();
    let s1: f64 = totals
        .iter()
        .enumerate()
        .map(|(l, &v)| (t.axis.bin_centre(l)) * v as f64)
        .sum();
    (s0, s1)
}

#[test]
fn eta_moves_the_peak_as_predicted_and_the_derivative_predicts_it() {
    eta_shift(IntegratorKind::Path);
}

/// The same with BDPT: every strategy carries its OPL derivative (light tracing included:
/// the confocal plane's point light is sampled by the light subpath too).
#[test]
fn bdpt_eta_moves_the_peak_as_predicted_and_the_derivative_predicts_it() {
    eta_shift(IntegratorKind::Bdpt);
}

fn eta_shift(integrator: IntegratorKind) {
    let opts = |seed| opts_with(seed, integrator);
    let k = 8;
    let (eta0, eta1) = (1.0f32, 1.05f32);
    let mut means0 = Vec::new();
    let mut means1 = Vec::new();
    let mut dmeans = Vec::new();
    let mut peaks = (0usize, 0usize);
    for seed in 0..k {
        let (t0, d, _) = render_diff(&scene(eta0), &["eta".to_string()], &opts(seed)).unwrap();
        let (t1, _) = render(&scene(eta1), &opts(seed)).unwrap();
        let (s0, s1) = moments(&t0);
        let (ds0, ds1) = moments(&d[0]);
        let mean0 = s1 / s0;
        means0.push(mean0);
        let (u0, u1) = moments(&t1);
        means1.push(u1 / u0);
        // d(mean)/dη = (Σ t·İ − mean · Σ İ) / Σ I
        dmeans.push((ds1 - mean0 * ds0) / s0);
        let argmax = |t: &Transient| {
            let b = t.bin_totals();
            (0..b.len()).max_by(|&i, &j| b[i].total_cmp(&b[j])).unwrap()
        };
        peaks = (argmax(&t0), argmax(&t1));
    }
    let (m0, se0) = common::mean_se(&means0);
    let (m1, se1) = common::mean_se(&means1);
    let (dm, sed) = common::mean_se(&dmeans);
    // radiance does not depend on η, so every OPL scales by η1/η0
    let predicted = m0 * (eta1 / eta0) as f64;
    let tol = 3.0 * (se0 * (eta1 / eta0) as f64 + se1) + 1e-4;
    assert!(
        (m1 - predicted).abs() <= tol,
        "mean OPL at η={eta1}: {m1} vs predicted {predicted} (tol {tol})"
    );
    // the derivative of the mean arrival with respect to η is mean / η
    let expected = m0 / eta0 as f64;
    common::power::Test::default()
        .one(common::power::Entry {
            scale: 3.0,
            add: 1e-3 * expected,
            ..common::power::Entry::new(dmeans.iter().map(|d| d - expected).collect(), dmeans.clone(), 0.0)
        })
        .power()
        .assert_enough(&format!("eta_shift d(mean OPL)/dη ({integrator:?}, {k} seeds)"));
    assert!(
        (dm - expected).abs() <= 3.0 * sed + 1e-3 * expected,
        "d(mean OPL)/dη = {dm} ± {sed}, expected {expected}"
    );
    // peak bin: predicted move (η1 − η0)·mean / bin width, within one bin of quantisation
    let w = scene(eta0).film.axis.bin_width_opl;
    let moved = peaks.1 as f64 - peaks.0 as f64;
    let want = (eta1 - eta0) as f64 * m0 / w;
    assert!(
        (moved - want).abs() <= 1.5,
        "peak moved {moved} bins, predicted {want:.2}"
    );
    assert!(moved >= 1.0, "the peak must move");
}

#[test]
fn delta_pulse_with_box_gate_refuses_time_shifting_parameters() {
    let s = Scene::load(&common::scene_path("confocal_plane.toml"), &[]).unwrap();
    assert!(matches!(s.emitters[0].pulse, Pulse::Delta));
    let e = render_diff(&s, &["eta".to_string()], &opts(0)).unwrap_err().to_string();
    assert!(
        e.contains("eta") && e.contains("Gaussian") && e.contains("delta"),
        "{e}"
    );
    let e = render_diff(&s, &["plane_z".to_string()], &opts(0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("plane_z") && e.contains("Gaussian"), "{e}");
}

#[test]
fn unknown_parameter_lists_the_available_ones() {
    let s = Scene::load(&common::scene_path("diff_room.toml"), &[]).unwrap();
    let e = render_diff(&s, &["nope".to_string()], &opts(0))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("nope") && e.contains("room_z") && e.contains("albedo"),
        "{e}"
    );
}

#[test]
fn no_parameters_no_derivative_lanes_same_primal() {
    // the primal of a derivative render equals the plain render: derivative lanes never
    // change values
    let s = Scene::load(&common::scene_path("diff_room.toml"), &[]).unwrap();
    let (p, _) = render(&s, &opts(3)).unwrap();
    let (q, d, _) = render_diff(&s, &["albedo".to_string(), "room_z".to_string()], &opts(3)).unwrap();
    assert_eq!(d.len(), 2);
    let total_p: f64 = p.data.iter().map(|&v| v as f64).sum();
    let total_q: f64 = q.data.iter().map(|&v| v as f64).sum();
    assert!((total_p - total_q).abs() <= 1e-5 * total_p, "{total_p} vs {total_q}");
}
