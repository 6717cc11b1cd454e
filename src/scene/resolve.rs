//! Description → [`Scene`]: names, overrides and parameters, then every range and reference
//! check, then the flat arrays.
//!
//! This file runs the steps in order and checks what belongs to no entry: the integrator
//! settings and the medium. Each kind of entry is resolved in a file of its own:
//! `camera_film.rs` (camera, pixel filter, film, gate, channels), `materials.rs`,
//! `emitters.rs` (emitters and their pulses), `shapes.rs` (meshes and world geometry) and
//! `crate::params::resolve` (parameters and `--set` overrides); `context.rs` holds what they share.

use super::context::{Ctx, Names, count, index_names};
use super::desc::SceneDesc;
use super::described::Described;
use super::error::{item_field, table_field};
use super::shapes::LocalMesh;
use super::{IntegratorSpec, Scene, SceneError, camera_film, emitters, materials};
use std::path::Path;
use std::sync::Arc;

/// Largest accepted bounce count.
pub const MAX_BOUNCES: i64 = 1024;

/// Resolves `described` (its description with the overrides of `described.params` applied)
/// into a [`Scene`] that keeps `described`, with its meshes, for [`Scene::set_params`].
pub(crate) fn resolve(described: Described, path: &Path) -> Result<Scene, SceneError> {
    let mut desc: SceneDesc = described.desc.clone();
    let overrides = described.params.as_slice();
    let mut ctx = Ctx::new(path);
    let names = Names {
        materials: index_names(&ctx, "material", desc.material.iter().map(|m| &m.name))?,
        shapes: index_names(&ctx, "shape", desc.shape.iter().map(|s| &s.name))?,
        emitters: index_names(&ctx, "emitter", desc.emitter.iter().map(|e| &e.name))?,
        params: index_names(&ctx, "param", desc.param.iter().map(|p| &p.name))?,
    };
    // The scene as the file describes it (params at their file values), for the origin.
    let mut as_written = desc.clone();
    let written_ok =
        crate::params::resolve::apply_params(&mut as_written, &names, &mut Ctx::new(path), &[], &[]).is_ok();
    let overridden = crate::params::resolve::apply_overrides(&mut desc, overrides, &names, path)?;
    let params = crate::params::resolve::apply_params(&mut desc, &names, &mut ctx, &overridden, &described.fields)?;
    // The meshes depend on no parameter (types, files and sphere subdivisions only).
    let meshes: Arc<[LocalMesh]> = match &described.meshes {
        Some(m) => m.clone(),
        None => super::shapes::local_meshes(&desc, &ctx)?.into(),
    };
    let extent = super::shapes::world_extent(if written_ok { &as_written } else { &desc }, &meshes, &ctx);
    let origin = super::origin::choose(extent.as_ref());
    let bounds = extent.map(|e| (e.lo, e.hi));
    let offset_scale = super::origin::offset_scale(bounds);

    let integrator = integrator(&desc, &ctx)?;
    let eta = desc.medium.eta;
    if eta < super::limits::MIN_INDEX as f32 || eta.is_nan() {
        let min = super::limits::MIN_INDEX;
        return Err(ctx.invalid(
            table_field("medium", "eta"),
            format!(
                "must be at least {min:e} (got {}): smaller indices leave the range of 32-bit floats",
                super::limits::number(eta)
            ),
        ));
    }
    let (camera, width, height, filter) = camera_film::camera(&desc.camera, origin, &ctx)?;
    let materials = materials::materials(&desc.material, &ctx)?;
    let emitters = emitters::emitters(&desc, &names, origin, &ctx)?;
    let channels = camera_film::channels(&desc, &params, &ctx)?;
    let mut film = camera_film::film(&desc.film, width, height, channels, filter, &ctx)?;
    let (mut shapes, mut geometry) = super::shapes::build(&desc, &names, &emitters, &ctx, &meshes, origin)?;
    // (Embree refused it after the load as an internal failure: "the mesh has no triangles")
    if geometry.tri_shape.is_empty() {
        return Err(ctx.invalid(
            "shape",
            "the scene has no surface: no [[shape]] has a triangle; a render needs at least one (a light \
             needs something to reach, and area lights are shapes)",
        ));
    }
    refuse_overflowing_opl(&desc, bounds, &integrator, &materials, &ctx)?;
    refuse_camera_on_a_surface(&camera, &shapes, &geometry, offset_scale, &ctx)?;
    let flush_emitters = super::flush::flush_emitters(&shapes, &geometry, offset_scale);
    for (light, other, within) in super::flush::facing_emitters(&shapes, &geometry, offset_scale) {
        let (light, other) = (&shapes[light].name, &shapes[other].name);
        super::warnings::warn_once(format!(
            "{}: shape {other:?} has a face on the emitting side of {light:?}, closer than rays can tell apart \
             ({within:.1e} m): the loader lifts the emitter in front of it so that its light wins, so {other:?} \
             does not shade {light:?} there; move {other:?} off the light (by a millimetre, say) if it should",
            path.display()
        ));
    }
    let lifted_emitters = super::flush::lift_flush_emitters(&mut shapes, &mut geometry, offset_scale);
    for pair in flush_emitters {
        let (front, behind) = super::flush::front_of(&geometry, pair);
        let (front, behind) = (&shapes[front].name, &shapes[behind].name);
        super::warnings::warn_once(format!(
            "{}: the emitting shapes {front:?} and {behind:?} have faces in one plane, facing the same way, that \
             overlap: the loader lifts an emitter off a surface in its plane so that its light wins, but here both \
             emit, so {front:?} now lies in front and covers {behind:?}, whose light is lost where they overlap; move \
             one off the other (by a millimetre, say), or make the two one shape",
            path.display()
        ));
    }
    if let Some((d, o, delta)) = super::flush::flush_dielectric(&shapes, &geometry, &materials, offset_scale) {
        let (name, other) = (&shapes[d].name, &shapes[o].name);
        let index = names.shapes.iter().position(|n| n == name).unwrap_or(d);
        return Err(ctx.invalid(
            item_field("shape", index, name, "translate"),
            format!(
                "the dielectric shape {name:?} lies flush on shape {other:?} (a face of each in one plane, \
                 overlapping, closer than {delta:.1e} m): which of the two a ray meets there is left to \
                 rounding, so whether a path enters the dielectric is undefined; leave a gap of more than \
                 {delta:.1e} m between them (e.g. 1 mm of air)"
            ),
        ));
    }
    for (a, b) in super::flush::flush_surfaces(&shapes, &geometry, &materials, offset_scale) {
        super::warnings::warn_once(format!(
            "{}: shapes {:?} and {:?} have faces in one plane, facing the same way, that overlap: which of the two a ray meets there is left to rounding, so the picture shows a speckled mix of both materials, and a derivative that moves either is refused; move one off the other (by a millimetre, say)",
            path.display(),
            shapes[a].name,
            shapes[b].name
        ));
    }
    if let Some(w) = super::warnings::narrow_gate(path, &film, &emitters) {
        super::warnings::warn_once(w);
    }
    let nlos = super::nlos::resolve(
        &desc,
        &names,
        &emitters,
        &shapes,
        &geometry,
        &materials,
        camera.position,
        origin,
        &ctx,
    )?;
    if let Some(n) = &nlos {
        (film.width, film.height) = n.film_size();
    }

    Ok(Scene {
        source: path.to_path_buf(),
        inputs: std::iter::once(path.to_path_buf())
            .chain(
                desc.shape
                    .iter()
                    .filter_map(|d| d.file.as_deref())
                    .map(|f| super::shapes::obj_path(path, f)),
            )
            .collect(),
        shapes,
        geometry,
        materials,
        emitters,
        camera,
        film,
        eta,
        integrator,
        params,
        render_origin: origin.to_array(),
        offset_scale,
        lifted_emitters,
        nlos,
        described: Arc::new(Described {
            meshes: Some(meshes),
            ..described
        }),
    })
}

/// Largest optical path length a path may reach: a render adds OPLs and their derivatives
/// in f32, whose largest value is 3.4·10³⁸; a margin of 2¹⁰ keeps their sums finite.
const OPL_CAP: f64 = f32::MAX as f64 / 1024.0;

/// Refuses a camera closer to a surface than the rays' offset: which side of it the camera is
/// on cannot be told (`super::surface_distance`).
fn refuse_camera_on_a_surface(
    camera: &super::Camera,
    shapes: &[super::Shape],
    geo: &super::Geometry,
    offset_scale: f32,
    ctx: &Ctx,
) -> Result<(), SceneError> {
    let p = camera.position;
    let at = crate::kernel::V3::<f32>::new(p.x, p.y, p.z);
    let eps = crate::integrator::surface::self_intersection_eps(&at, offset_scale) as f64;
    match super::surface_distance::nearest_within(geo, p, eps) {
        None => Ok(()),
        Some((t, d)) => Err(ctx.invalid(
            table_field("camera", "position"),
            format!(
                "lies {d:.1e} m from shape {:?}, within the rays' offset ({eps:.1e} m): which side of it the camera \
                 is on cannot be told, so light would pass it (BDPT's connections to the camera stop short of it) or \
                 nothing be seen; move the camera more than {eps:.1e} m off it",
                shapes[geo.tri_shape[t] as usize].name
            ),
        )),
    }
}

/// Refuses a refractive index (above 1) so large that a path's OPL (the index times its
/// length) could pass [`OPL_CAP`] within the scene: each of the path's `max_bounces + 1` segments is at
/// most the diagonal of the box holding the geometry and the camera. Such a render came out
/// all zeros, every sample dropped as not finite (`medium.eta = 3e38`), with exit 0.
fn refuse_overflowing_opl(
    desc: &SceneDesc,
    bounds: Option<(glam::DVec3, glam::DVec3)>,
    integrator: &IntegratorSpec,
    materials: &[super::NamedMaterial],
    ctx: &Ctx,
) -> Result<(), SceneError> {
    let camera = glam::DVec3::from_array(desc.camera.position);
    let (lo, hi) = bounds.map_or((camera, camera), |(lo, hi)| (lo.min(camera), hi.max(camera)));
    let reach = (hi - lo).length() * (integrator.max_bounces as f64 + 1.0);
    let indices = std::iter::once((table_field("medium", "eta"), desc.medium.eta)).chain(
        materials.iter().enumerate().filter_map(|(i, m)| match m.material {
            super::Material::Dielectric { int_ior, .. } => {
                Some((item_field("material", i, &m.name, "int_ior"), int_ior))
            }
            _ => None,
        }),
    );
    // an index of 1 or less is the scene's size, not the index (the shapes refuse geometry
    // beyond 32-bit floats; a path that still overflows is counted and said as dropped)
    for (field, index) in indices {
        if index > 1.0 && index as f64 * reach > OPL_CAP {
            return Err(ctx.invalid(
                field,
                format!(
                    "{index:e} is too large: a path of {} segments across this scene ({:.3e} m corner to corner) \
                     would reach an optical path length of {:.1e} m, past the {OPL_CAP:.1e} m a render adds up in \
                     32-bit floats",
                    integrator.max_bounces + 1,
                    (hi - lo).length(),
                    index as f64 * reach
                ),
            ));
        }
    }
    Ok(())
}

fn integrator(desc: &SceneDesc, ctx: &Ctx) -> Result<IntegratorSpec, SceneError> {
    let d = &desc.integrator;
    let at = |f: &str| table_field("integrator", f);
    let max_bounces = count(ctx, at("max_bounces"), d.max_bounces, 1, MAX_BOUNCES)? as u32;
    let spp = count(ctx, at("spp"), d.spp, 1, u32::MAX as i64)? as u32;
    let rr_depth = match d.rr_depth {
        Some(r) => Some(count(ctx, at("rr_depth"), r, 1, u32::MAX as i64)? as u32),
        None => None,
    };
    Ok(IntegratorSpec {
        kind: d.kind,
        max_bounces,
        spp,
        seed: d.seed,
        rr_depth,
        sampler: match d.sampler {
            super::desc::SamplerName::Independent => crate::kernel::SampleSequence::Independent,
            super::desc::SamplerName::Sobol => crate::kernel::SampleSequence::Sobol,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::super::PixelFilter;
    use super::super::testutil::*;
    use crate::temporal::{Gate, Pulse, TimeAxis};

    #[test]
    fn defaults_fill_in() {
        let s = load_text("mini.toml", MINI, &[], &[]).unwrap();
        assert_eq!(s.integrator.max_bounces, 8);
        assert_eq!(s.integrator.spp, 16);
        assert_eq!(s.integrator.rr_depth, None);
        assert_eq!(s.eta, 1.0);
        assert_eq!((s.film.width, s.film.height), (64, 64));
        assert_eq!(s.camera.fov_y_deg, 40.0);
        assert_eq!(s.film.filter, PixelFilter::Box);
        assert_eq!(s.film.gate, Gate::Box);
        assert_eq!(s.film.channels, 1);
        assert_eq!(s.emitters[0].pulse, Pulse::Delta);
        assert_eq!(
            s.film.axis,
            TimeAxis {
                start_opl: 0.0,
                bin_width_opl: 0.1,
                bins: 10
            }
        );
    }

    #[test]
    fn filters_gates_and_pulses_parse() {
        let text = mini_with(
            "bins = 10",
            "bins = 10\ngate = { type = \"gaussian\", sigma_opl = 0.02 }",
        )
        .replacen(
            "look_at = [0.0, 0.0, 0.0]",
            "look_at = [0.0, 0.0, 0.0]\nfilter = \"gaussian\"",
            1,
        )
        .replacen(
            "intensity = 1.0",
            "intensity = 1.0\npulse = { type = \"box\", width_opl = 0.05 }\noffset_opl = 0.5",
            1,
        );
        let s = load_text("f.toml", &text, &[], &[]).unwrap();
        assert_eq!(
            s.film.filter,
            PixelFilter::Gaussian {
                sigma: 0.5,
                radius: 1.5
            }
        );
        assert_eq!(s.film.gate, Gate::Gaussian { sigma_opl: 0.02 });
        assert_eq!(s.emitters[0].pulse, Pulse::Box { width_opl: 0.05 });
        assert_eq!(s.emitters[0].offset_opl, 0.5);
        let text = mini_with(
            "look_at = [0.0, 0.0, 0.0]",
            "look_at = [0.0, 0.0, 0.0]\nfilter = { type = \"tent\", radius = 2 }",
        );
        assert_eq!(
            load_text("t.toml", &text, &[], &[]).unwrap().film.filter,
            PixelFilter::Tent { radius: 2.0 }
        );
        let text = mini_with(
            "look_at = [0.0, 0.0, 0.0]",
            "look_at = [0.0, 0.0, 0.0]\nfilter = \"tnt\"",
        );
        expect_err(
            "badfilter.toml",
            &text,
            &[],
            &[
                "camera: field 'filter'",
                "unknown filter \"tnt\"",
                "\"box\", \"tent\" or \"gaussian\"",
            ],
        );
        let text = mini_with("intensity = 1.0", "intensity = 1.0\npulse = \"gaussian\"");
        expect_err(
            "badpulse.toml",
            &text,
            &[],
            &["emitter[0] \"lamp\": field 'pulse'", "sigma_opl"],
        );
        let text = mini_with(
            "intensity = 1.0",
            "intensity = 1.0\npulse = { type = \"gaussian\", sigma_opl = 0.0 }",
        );
        expect_err(
            "zeropulse.toml",
            &text,
            &[],
            &["emitter[0] \"lamp\": field 'pulse.sigma_opl'", "must be > 0"],
        );
        let text = mini_with("bins = 10", "bins = 10\ngate = { type = \"gaussian\" }");
        expect_err("gate.toml", &text, &[], &["film: field 'gate.sigma_opl'", "missing"]);
    }

    #[test]
    fn spp_bounces_and_counts_must_be_positive() {
        for spp in ["0", "-3"] {
            let text = format!("[integrator]\nspp = {spp}\n{MINI}");
            expect_err(
                "spp.toml",
                &text,
                &[],
                &["integrator: field 'spp'", "must be at least 1", &format!("got {spp}")],
            );
        }
        let text = format!("[integrator]\nmax_bounces = 0\n{MINI}");
        expect_err(
            "mb.toml",
            &text,
            &[],
            &["integrator: field 'max_bounces'", "must be at least 1"],
        );
        let text = format!("[integrator]\nrr_depth = 0\n{MINI}");
        expect_err(
            "rr.toml",
            &text,
            &[],
            &["integrator: field 'rr_depth'", "must be at least 1"],
        );
        let text = format!("[integrator]\nkind = \"volpath\"\n{MINI}");
        expect_err(
            "kind.toml",
            &text,
            &[],
            &[
                "integrator: field 'kind'",
                "unknown variant 'volpath'",
                "'path'",
                "'bdpt'",
            ],
        );
        let text = mini_with("bins = 10", "bins = 0");
        expect_err(
            "bins.toml",
            &text,
            &[],
            &["film: field 'bins'", "must be at least 1 (got 0)"],
        );
        for w in ["0.0", "-0.1"] {
            let text = mini_with("bin_width_opl = 0.1", &format!("bin_width_opl = {w}"));
            expect_err("bw.toml", &text, &[], &["film: field 'bin_width_opl'", "must be > 0"]);
        }
        let text = mini_with(
            "look_at = [0.0, 0.0, 0.0]",
            "look_at = [0.0, 0.0, 0.0]\nresolution = [0, 4]",
        );
        expect_err(
            "res.toml",
            &text,
            &[],
            &["camera: field 'resolution[0]'", "must be at least 1"],
        );
    }

    #[test]
    fn eta_and_albedo_ranges() {
        let text = format!("[medium]\neta = 0\n{MINI}");
        expect_err(
            "eta.toml",
            &text,
            &[],
            &["medium: field 'eta'", "must be at least 1e-6"],
        );
        let text = mini_with("albedo = 0.5", "albedo = [0.5, 1.5, 0.5]");
        expect_err(
            "alb.toml",
            &text,
            &[],
            &["material[0] \"white\": field 'albedo'", "in [0, 1]", "[0.5, 1.5, 0.5]"],
        );
        let text = mini_with("albedo = 0.5\n", "");
        expect_err(
            "noalb.toml",
            &text,
            &[],
            &["material[0] \"white\": field 'albedo'", "missing"],
        );
    }
}
