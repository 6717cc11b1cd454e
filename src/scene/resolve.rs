//! Description → [`Scene`]: names, overrides and parameters, then every range and reference
//! check, then the flat arrays.

use super::context::{Ctx, Names, no_such};
use super::desc::{
    CameraDesc, Channels, EmitterDesc, EmitterType, FilmDesc, FilterType, GateType, MaterialDesc, MaterialType, NameOr,
    PulseType, SceneDesc, Triple,
};
use super::error::{item, item_field, table_field};
use super::{
    Camera, Emitter, EmitterKind, FilmSpec, IntegratorSpec, Material, NamedMaterial, Param, ParamKind, PixelFilter,
    Scene, SceneError,
};
use crate::temporal::{Gate, Pulse, TimeAxis};
use glam::{DVec3, Vec3};
use std::collections::HashMap;
use std::path::Path;

/// Largest accepted image side, bin count and bounce count.
pub const MAX_RESOLUTION: i64 = 16384;
pub const MAX_BINS: i64 = 1 << 24;
pub const MAX_BOUNCES: i64 = 1024;

fn index_names<'a>(
    ctx: &Ctx,
    section: &str,
    names: impl Iterator<Item = &'a String>,
) -> Result<Vec<String>, SceneError> {
    let mut out: Vec<String> = Vec::new();
    for (i, n) in names.enumerate() {
        if n.trim().is_empty() {
            return Err(ctx.invalid(format!("{}: field 'name'", item(section, i, None)), "must not be empty"));
        }
        if let Some(j) = out.iter().position(|m| m == n) {
            return Err(ctx.invalid(
                item_field(section, i, n, "name"),
                format!("duplicate name: {section}[{j}] is already called {n:?}; names must be unique"),
            ));
        }
        out.push(n.clone());
    }
    Ok(out)
}

pub(crate) fn resolve(mut desc: SceneDesc, path: &Path, overrides: &[(String, f64)]) -> Result<Scene, SceneError> {
    let mut ctx = Ctx {
        path,
        set_by: HashMap::new(),
    };
    let names = Names {
        materials: index_names(&ctx, "material", desc.material.iter().map(|m| &m.name))?,
        shapes: index_names(&ctx, "shape", desc.shape.iter().map(|s| &s.name))?,
        emitters: index_names(&ctx, "emitter", desc.emitter.iter().map(|e| &e.name))?,
        params: index_names(&ctx, "param", desc.param.iter().map(|p| &p.name))?,
    };
    // The scene as the file describes it (params at their file values), for the origin.
    let mut as_written = desc.clone();
    let written_ok = super::params::apply_params(
        &mut as_written,
        &names,
        &mut Ctx {
            path,
            set_by: HashMap::new(),
        },
        &[],
    )
    .is_ok();
    let overridden = super::params::apply_overrides(&mut desc, overrides, &names, path)?;
    let params = super::params::apply_params(&mut desc, &names, &mut ctx, &overridden)?;
    let meshes = super::shapes::local_meshes(&desc, &ctx)?;
    let origin = super::origin::choose(super::shapes::world_bounds(
        if written_ok { &as_written } else { &desc },
        &meshes,
        &ctx,
    ));

    let integrator = integrator(&desc, &ctx)?;
    let eta = desc.medium.eta;
    if eta <= 0.0 {
        return Err(ctx.invalid(table_field("medium", "eta"), format!("must be > 0 (got {eta})")));
    }
    let (camera, width, height, filter) = camera(&desc.camera, origin, &ctx)?;
    let materials = materials(&desc.material, &ctx)?;
    let emitters = emitters(&desc, &names, origin, &ctx)?;
    let channels = channels(&desc, &params, &ctx)?;
    let film = film(&desc.film, width, height, channels, filter, &ctx)?;
    let (mut shapes, mut geometry) = super::shapes::build(&desc, &names, &emitters, &ctx, meshes, origin)?;
    let lifted_emitters = super::flush::lift_flush_emitters(&mut shapes, &mut geometry);

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
        lifted_emitters,
    })
}

fn count(ctx: &Ctx, at: String, v: i64, min: i64, max: i64) -> Result<i64, SceneError> {
    if v < min {
        Err(ctx.invalid(at, format!("must be at least {min} (got {v})")))
    } else if v > max {
        Err(ctx.invalid(at, format!("must be at most {max} (got {v})")))
    } else {
        Ok(v)
    }
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
    })
}

/// The camera, its position and target relative to the render origin (subtracted in f64).
fn camera(d: &CameraDesc, origin: DVec3, ctx: &Ctx) -> Result<(Camera, u32, u32, PixelFilter), SceneError> {
    let at = |f: &str| table_field("camera", f);
    let position = (DVec3::from(d.position) - origin).as_vec3();
    let look_at = (DVec3::from(d.look_at) - origin).as_vec3();
    let up = Vec3::from(d.up);
    let view = look_at - position;
    if DVec3::from(d.look_at) == DVec3::from(d.position) {
        return Err(ctx.invalid(
            at("look_at"),
            format!(
                "must differ from camera.position (both are {:?}): the camera needs a view direction",
                d.position
            ),
        ));
    }
    if view == Vec3::ZERO || !view.normalize().is_finite() {
        return Err(ctx.invalid(
            at("look_at"),
            "is too close to or too far from camera.position for 32-bit arithmetic",
        ));
    }
    if up == Vec3::ZERO {
        return Err(ctx.invalid(at("up"), "must be a nonzero vector"));
    }
    let up_dir = up / up.abs().max_element();
    if view.normalize().cross(up_dir.normalize()).length() < 1e-6 {
        return Err(ctx.invalid(
            at("up"),
            format!(
                "{:?} is parallel to the view direction (look_at - position = {:?}); choose an up vector that is not",
                d.up,
                view.to_array()
            ),
        ));
    }
    let camera = Camera {
        position,
        look_at,
        up,
        fov_y_deg: d.fov,
    };
    let (r, u, f) = camera.frame();
    if !(r.is_finite() && u.is_finite() && f.is_finite()) {
        return Err(ctx.invalid(
            at("up"),
            format!(
                "{:?} is too small or too large for 32-bit arithmetic; use a vector of length about 1",
                d.up
            ),
        ));
    }
    if !(d.fov > 0.0 && d.fov < 180.0) {
        return Err(ctx.invalid(
            at("fov"),
            format!("must be in (0, 180) degrees, exclusive (got {})", d.fov),
        ));
    }
    let w = count(ctx, at("resolution[0]"), d.resolution[0], 1, MAX_RESOLUTION)? as u32;
    let h = count(ctx, at("resolution[1]"), d.resolution[1], 1, MAX_RESOLUTION)? as u32;
    let filter = pixel_filter(&d.filter, ctx)?;
    Ok((
        Camera {
            position,
            look_at,
            up,
            fov_y_deg: d.fov,
        },
        w,
        h,
        filter,
    ))
}

fn positive(ctx: &Ctx, at: String, v: f32) -> Result<f32, SceneError> {
    if v > 0.0 {
        Ok(v)
    } else {
        Err(ctx.invalid(at, format!("must be > 0 (got {v})")))
    }
}

fn pixel_filter(f: &NameOr<super::desc::FilterTable>, ctx: &Ctx) -> Result<PixelFilter, SceneError> {
    let at = |s: &str| table_field("camera", s);
    let (ty, radius, sigma) = match f {
        NameOr::Name(n) => match n.as_str() {
            "box" => (FilterType::Box, None, None),
            "tent" => (FilterType::Tent, None, None),
            "gaussian" => (FilterType::Gaussian, None, None),
            other => {
                return Err(ctx.invalid(
                    at("filter"),
                    format!("unknown filter {other:?}: expected \"box\", \"tent\" or \"gaussian\" (or a table such as {{ type = \"tent\", radius = 1.0 }})"),
                ));
            }
        },
        NameOr::Table(t) => (t.ty, t.radius, t.sigma),
    };
    Ok(match ty {
        FilterType::Box => {
            if radius.is_some() || sigma.is_some() {
                return Err(ctx.invalid(
                    at("filter"),
                    "the box filter takes no radius or sigma (it covers one pixel)",
                ));
            }
            PixelFilter::Box
        }
        FilterType::Tent => {
            if sigma.is_some() {
                return Err(ctx.invalid(
                    at("filter.sigma"),
                    "does not apply to the tent filter (it takes only radius)",
                ));
            }
            PixelFilter::Tent {
                radius: positive(ctx, at("filter.radius"), radius.unwrap_or(1.0))?,
            }
        }
        FilterType::Gaussian => PixelFilter::Gaussian {
            sigma: positive(ctx, at("filter.sigma"), sigma.unwrap_or(0.5))?,
            radius: positive(ctx, at("filter.radius"), radius.unwrap_or(1.5))?,
        },
    })
}

fn gate(g: &NameOr<super::desc::GateTable>, ctx: &Ctx) -> Result<Gate, SceneError> {
    let at = |s: &str| table_field("film", s);
    let (ty, sigma) = match g {
        NameOr::Name(n) => match n.as_str() {
            "box" => (GateType::Box, None),
            "gaussian" => {
                return Err(ctx.invalid(
                    at("gate"),
                    "a gaussian gate needs its width: write { type = \"gaussian\", sigma_opl = ... }",
                ));
            }
            other => {
                return Err(ctx.invalid(
                    at("gate"),
                    format!("unknown gate {other:?}: expected \"box\" or {{ type = \"gaussian\", sigma_opl = ... }}"),
                ));
            }
        },
        NameOr::Table(t) => (t.ty, t.sigma_opl),
    };
    Ok(match ty {
        GateType::Box => {
            if sigma.is_some() {
                return Err(ctx.invalid(
                    at("gate.sigma_opl"),
                    "does not apply to the box gate (its width is the bin width)",
                ));
            }
            Gate::Box
        }
        GateType::Gaussian => match sigma {
            Some(s) => Gate::Gaussian {
                sigma_opl: positive(ctx, at("gate.sigma_opl"), s)?,
            },
            None => {
                return Err(ctx.invalid(at("gate.sigma_opl"), "missing: a gaussian gate needs sigma_opl > 0"));
            }
        },
    })
}

fn film(
    d: &FilmDesc,
    width: u32,
    height: u32,
    channels: usize,
    filter: PixelFilter,
    ctx: &Ctx,
) -> Result<FilmSpec, SceneError> {
    let at = |f: &str| table_field("film", f);
    // f64 end to end: an f32 would store start_opl = 3.99999995 as 4.0
    let bin_width_opl = d.bin_width_opl;
    if bin_width_opl <= 0.0 || bin_width_opl.is_nan() {
        return Err(ctx.invalid(at("bin_width_opl"), format!("must be > 0 (got {bin_width_opl})")));
    }
    let bins = count(ctx, at("bins"), d.bins, 1, MAX_BINS)? as usize;
    let end = d.start_opl + bin_width_opl * bins as f64;
    if !((end as f32).is_finite()) {
        return Err(ctx.invalid(
            at("bins"),
            format!("the time axis ends at OPL {end:e}, beyond the range of 32-bit floats"),
        ));
    }
    Ok(FilmSpec {
        width,
        height,
        axis: TimeAxis {
            start_opl: d.start_opl,
            bin_width_opl,
            bins,
        },
        gate: gate(&d.gate, ctx)?,
        channels,
        unwarp: d.unwarp,
        filter,
    })
}

/// Checks each channel of a colour is in `[lo, hi]`.
pub(crate) fn check_colour(ctx: &Ctx, at: String, c: Triple, lo: f32, hi: f32) -> Result<[f32; 3], SceneError> {
    let v = c.to_array();
    if v.iter().any(|&x| !(x >= lo && x <= hi)) {
        let range = if hi.is_finite() {
            format!("in [{lo}, {hi}]")
        } else {
            format!(">= {lo}")
        };
        let got = match c {
            Triple::Scalar(s) => format!("{s}"),
            Triple::Three(t) => format!("{t:?}"),
        };
        return Err(ctx.invalid(at, format!("every channel must be {range} (got {got})")));
    }
    Ok(v)
}

fn materials(list: &[MaterialDesc], ctx: &Ctx) -> Result<Vec<NamedMaterial>, SceneError> {
    list.iter()
        .enumerate()
        .map(|(i, m)| {
            let at = item_field("material", i, &m.name, "albedo");
            let MaterialType::Diffuse = m.ty;
            let albedo = match m.albedo {
                Some(a) => check_colour(ctx, at, a, 0.0, 1.0)?,
                None => {
                    return Err(ctx.invalid(
                        at,
                        "missing: a diffuse material needs albedo = scalar or [r, g, b], each in [0, 1]",
                    ));
                }
            };
            Ok(NamedMaterial {
                name: m.name.clone(),
                material: Material::Diffuse { albedo },
            })
        })
        .collect()
}

/// "a point" / "an area" / "a laser".
fn a_type(t: EmitterType) -> String {
    match t {
        EmitterType::Area => "an area".to_string(),
        other => format!("a {}", other.as_str()),
    }
}

/// Fields of an emitter that only some types take.
fn only_for(ctx: &Ctx, i: usize, e: &EmitterDesc) -> Result<(), SceneError> {
    let present: [(&str, bool, &[EmitterType]); 6] = [
        ("shape", e.shape.is_some(), &[EmitterType::Area]),
        ("radiance", e.radiance.is_some(), &[EmitterType::Area]),
        (
            "position",
            e.position.is_some(),
            &[EmitterType::Point, EmitterType::Laser],
        ),
        ("intensity", e.intensity.is_some(), &[EmitterType::Point]),
        ("direction", e.direction.is_some(), &[EmitterType::Laser]),
        ("power", e.power.is_some(), &[EmitterType::Laser]),
    ];
    for (field, is_set, types) in present {
        if is_set && !types.contains(&e.ty) {
            let takes: Vec<&str> = types.iter().map(|t| t.as_str()).collect();
            return Err(ctx.invalid(
                item_field("emitter", i, &e.name, field),
                format!(
                    "does not apply to {} emitter (only to: {})",
                    a_type(e.ty),
                    takes.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

fn pulse(ctx: &Ctx, i: usize, e: &EmitterDesc) -> Result<Pulse, SceneError> {
    let at = |f: &str| item_field("emitter", i, &e.name, f);
    let (ty, sigma, width) = match &e.pulse {
        NameOr::Name(n) => match n.as_str() {
            "delta" => (PulseType::Delta, None, None),
            "gaussian" | "box" => {
                let field = if n == "box" { "width_opl" } else { "sigma_opl" };
                return Err(ctx.invalid(
                    at("pulse"),
                    format!("a {n} pulse needs its width: write {{ type = \"{n}\", {field} = ... }}"),
                ));
            }
            other => {
                return Err(ctx.invalid(
                    at("pulse"),
                    format!("unknown pulse {other:?}: expected \"delta\", {{ type = \"gaussian\", sigma_opl = ... }} or {{ type = \"box\", width_opl = ... }}"),
                ));
            }
        },
        NameOr::Table(t) => (t.ty, t.sigma_opl, t.width_opl),
    };
    let unused =
        |f: &str, name: &str| ctx.invalid(at(&format!("pulse.{f}")), format!("does not apply to a {name} pulse"));
    Ok(match ty {
        PulseType::Delta => {
            if sigma.is_some() {
                return Err(unused("sigma_opl", "delta"));
            }
            if width.is_some() {
                return Err(unused("width_opl", "delta"));
            }
            Pulse::Delta
        }
        PulseType::Gaussian => {
            if width.is_some() {
                return Err(unused("width_opl", "gaussian"));
            }
            let s = sigma
                .ok_or_else(|| ctx.invalid(at("pulse.sigma_opl"), "missing: a gaussian pulse needs sigma_opl > 0"))?;
            Pulse::Gaussian {
                sigma_opl: positive(ctx, at("pulse.sigma_opl"), s)?,
            }
        }
        PulseType::Box => {
            if sigma.is_some() {
                return Err(unused("sigma_opl", "box"));
            }
            let w =
                width.ok_or_else(|| ctx.invalid(at("pulse.width_opl"), "missing: a box pulse needs width_opl > 0"))?;
            Pulse::Box {
                width_opl: positive(ctx, at("pulse.width_opl"), w)?,
            }
        }
    })
}

/// The emitters, point and laser positions relative to the render origin (subtracted in f64).
fn emitters(desc: &SceneDesc, names: &Names, origin: DVec3, ctx: &Ctx) -> Result<Vec<Emitter>, SceneError> {
    let mut claimed: HashMap<usize, usize> = HashMap::new();
    let mut out = Vec::new();
    for (i, e) in desc.emitter.iter().enumerate() {
        only_for(ctx, i, e)?;
        let at = |f: &str| item_field("emitter", i, &e.name, f);
        let amount_field = e.ty.amount_field();
        let amount = {
            match e.amount() {
                Some(a) => check_colour(ctx, at(amount_field), a, 0.0, f32::INFINITY)?,
                None => {
                    return Err(ctx.invalid(
                        at(amount_field),
                        format!(
                            "missing: {} emitter needs {amount_field} = scalar or [r, g, b], each >= 0",
                            a_type(e.ty)
                        ),
                    ));
                }
            }
        };
        let need_position = || {
            e.position.map(|p| (DVec3::from(p) - origin).as_vec3()).ok_or_else(|| {
                ctx.invalid(
                    at("position"),
                    format!("missing: a {} emitter needs position = [x, y, z]", e.ty.as_str()),
                )
            })
        };
        let kind = match e.ty {
            EmitterType::Area => {
                let Some(shape_name) = &e.shape else {
                    return Err(ctx.invalid(
                        at("shape"),
                        format!(
                            "missing: an area emitter needs the name of the shape it covers (shapes: {})",
                            names.shapes.join(", ")
                        ),
                    ));
                };
                let Some(s) = names.shape(shape_name) else {
                    return Err(ctx.invalid(at("shape"), no_such("shape", "shapes", shape_name, &names.shapes)));
                };
                if let Some(j) = claimed.insert(s, i) {
                    return Err(ctx.invalid(
                        at("shape"),
                        format!(
                            "shape {shape_name:?} is already the area emitter {:?}; a shape can carry one area emitter",
                            desc.emitter[j].name
                        ),
                    ));
                }
                if desc.shape[s].material.is_none() {
                    return Err(ctx.invalid(
                        item_field("shape", s, shape_name, "material"),
                        format!(
                            "missing: shape {shape_name:?} is the area emitter {:?} and every shape, emitting or not, needs a material (materials: {})",
                            e.name,
                            names.materials.join(", ")
                        ),
                    ));
                }
                EmitterKind::Area {
                    shape: s as u32,
                    radiance: amount,
                }
            }
            EmitterType::Point => EmitterKind::Point {
                position: need_position()?,
                intensity: amount,
            },
            EmitterType::Laser => {
                let position = need_position()?;
                let Some(d) = e.direction else {
                    return Err(ctx.invalid(
                        at("direction"),
                        "missing: a laser needs direction = [x, y, z] (nonzero)",
                    ));
                };
                let d = Vec3::from(d);
                // scaled first so that huge or tiny (but nonzero) vectors normalise too
                let n = (d / d.abs().max_element()).normalize_or_zero();
                if n == Vec3::ZERO || !n.is_finite() {
                    return Err(ctx.invalid(
                        at("direction"),
                        format!("must be a nonzero vector (got {:?})", d.to_array()),
                    ));
                }
                EmitterKind::Laser {
                    position,
                    direction: n,
                    power: amount,
                }
            }
        };
        out.push(Emitter {
            name: e.name.clone(),
            kind,
            pulse: pulse(ctx, i, e)?,
            offset_opl: e.offset_opl,
        });
    }
    Ok(out)
}

/// 1 or 3: `mono` refuses unequal triples, `auto` picks RGB if there is one (or a param acts
/// on a single channel).
fn channels(desc: &SceneDesc, params: &[Param], ctx: &Ctx) -> Result<usize, SceneError> {
    let mut colours: Vec<(String, Triple)> = Vec::new();
    for (i, m) in desc.material.iter().enumerate() {
        if let Some(a) = m.albedo {
            colours.push((item_field("material", i, &m.name, "albedo"), a));
        }
    }
    for (i, e) in desc.emitter.iter().enumerate() {
        if let Some(a) = e.amount() {
            colours.push((item_field("emitter", i, &e.name, e.ty.amount_field()), a));
        }
    }
    let channel_param = params.iter().enumerate().find(|(_, p)| {
        matches!(
            p.kind,
            ParamKind::Albedo { channel: Some(_), .. } | ParamKind::Radiance { channel: Some(_), .. }
        )
    });
    match desc.film.channels {
        Channels::Rgb => Ok(3),
        Channels::Mono => {
            if let Some((i, p)) = channel_param {
                return Err(ctx.invalid(
                    item_field("param", i, &p.name, "channel"),
                    "a per-channel param needs film.channels = \"rgb\" or \"auto\" (the film is \"mono\")",
                ));
            }
            if let Some((at, c)) = colours.iter().find(|(_, c)| c.is_unequal()) {
                return Err(ctx.invalid(
                    at.clone(),
                    format!(
                        "{:?} has unequal channels but film.channels = \"mono\": use a scalar, or channels = \"rgb\" / \"auto\"",
                        c.to_array()
                    ),
                ));
            }
            Ok(1)
        }
        Channels::Auto => Ok(
            if colours.iter().any(|(_, c)| c.is_unequal()) || channel_param.is_some() {
                3
            } else {
                1
            },
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;

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
    fn duplicate_names_are_refused() {
        let text = format!("{MINI}\n[[shape]]\nname = \"quad\"\ntype = \"cube\"\nmaterial = \"white\"\n");
        expect_err(
            "dup.toml",
            &text,
            &[],
            &[
                "shape[1] \"quad\": field 'name'",
                "duplicate name",
                "shape[0]",
                "unique",
            ],
        );
        let text = format!("{MINI}\n[[material]]\nname = \"white\"\ntype = \"diffuse\"\nalbedo = 0.1\n");
        expect_err(
            "dupm.toml",
            &text,
            &[],
            &["material[1] \"white\": field 'name'", "duplicate name"],
        );
        let text = format!(
            "{MINI}\n[[param]]\nname = \"p\"\nkind = \"eta\"\nvalue = 1\n[[param]]\nname = \"p\"\nkind = \"eta\"\nvalue = 1\n"
        );
        expect_err(
            "dupp.toml",
            &text,
            &[],
            &["param[1] \"p\": field 'name'", "duplicate name"],
        );
        let text = mini_with("name = \"quad\"", "name = \"\"");
        expect_err(
            "empty.toml",
            &text,
            &[],
            &["shape[0]: field 'name'", "must not be empty"],
        );
    }

    #[test]
    fn unknown_references_list_what_exists() {
        let text = format!("{MINI}\n[[material]]\nname = \"red\"\ntype = \"diffuse\"\nalbedo = 0.1\n").replacen(
            "material = \"white\"",
            "material = \"whte\"",
            1,
        );
        expect_err(
            "ref.toml",
            &text,
            &[],
            &[
                "shape[0] \"quad\": field 'material'",
                "no material named \"whte\" (materials: white, red)",
            ],
        );
        let text = format!("{MINI}\n[[emitter]]\nname = \"area\"\ntype = \"area\"\nshape = \"qaud\"\nradiance = 1\n");
        expect_err(
            "eref.toml",
            &text,
            &[],
            &[
                "emitter[1] \"area\": field 'shape'",
                "no shape named \"qaud\" (shapes: quad)",
            ],
        );
        let text = mini_with("material = \"white\"\n", "");
        expect_err(
            "nomat.toml",
            &text,
            &[],
            &["shape[0] \"quad\": field 'material'", "missing", "materials: white"],
        );
    }

    #[test]
    fn area_emitter_on_a_shape_without_material() {
        let text = mini_with("material = \"white\"\n", "")
            + "\n[[emitter]]\nname = \"glow\"\ntype = \"area\"\nshape = \"quad\"\nradiance = 1\n";
        expect_err(
            "areamat.toml",
            &text,
            &[],
            &[
                "shape[0] \"quad\": field 'material'",
                "area emitter \"glow\"",
                "needs a material",
            ],
        );
    }

    #[test]
    fn area_emitter_fields() {
        let text =
            format!("{MINI}\n[[emitter]]\nname = \"glow\"\ntype = \"area\"\nshape = \"quad\"\nradiance = [1, 2, 3]\n");
        let s = load_text("area.toml", &text, &[], &[]).unwrap();
        assert_eq!(
            s.emitters[1].kind,
            EmitterKind::Area {
                shape: 0,
                radiance: [1.0, 2.0, 3.0]
            }
        );
        assert_eq!(s.shapes[0].emitter, Some(1));
        assert_eq!(s.film.channels, 3, "auto picks RGB for an unequal triple");
        let twice = format!("{text}\n[[emitter]]\nname = \"glow2\"\ntype = \"area\"\nshape = \"quad\"\nradiance = 1\n");
        expect_err(
            "twice.toml",
            &twice,
            &[],
            &[
                "emitter[2] \"glow2\": field 'shape'",
                "already the area emitter \"glow\"",
            ],
        );
        let text = format!("{MINI}\n[[emitter]]\nname = \"glow\"\ntype = \"area\"\nshape = \"quad\"\n");
        expect_err(
            "norad.toml",
            &text,
            &[],
            &["emitter[1] \"glow\": field 'radiance'", "missing"],
        );
        let text = mini_with("intensity = 1.0", "intensity = 1.0\nradiance = 2.0");
        expect_err(
            "wrongfield.toml",
            &text,
            &[],
            &[
                "emitter[0] \"lamp\": field 'radiance'",
                "does not apply to a point emitter",
            ],
        );
        let text = mini_with("intensity = 1.0", "intensity = -1.0");
        expect_err(
            "neg.toml",
            &text,
            &[],
            &["emitter[0] \"lamp\": field 'intensity'", ">= 0"],
        );
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
    fn camera_checks() {
        for fov in ["0", "180", "200", "-5"] {
            let text = mini_with(
                "look_at = [0.0, 0.0, 0.0]",
                &format!("look_at = [0.0, 0.0, 0.0]\nfov = {fov}"),
            );
            expect_err(
                "fov.toml",
                &text,
                &[],
                &["camera: field 'fov'", "must be in (0, 180)", &format!("got {fov}")],
            );
        }
        let text = mini_with("look_at = [0.0, 0.0, 0.0]", "look_at = [0.0, 0.0, 3.0]");
        expect_err(
            "same.toml",
            &text,
            &[],
            &["camera: field 'look_at'", "must differ from camera.position"],
        );
        let text = mini_with(
            "look_at = [0.0, 0.0, 0.0]",
            "look_at = [0.0, 0.0, 0.0]\nup = [0, 0, -2]",
        );
        expect_err(
            "up.toml",
            &text,
            &[],
            &["camera: field 'up'", "parallel to the view direction"],
        );
        let text = mini_with("look_at = [0.0, 0.0, 0.0]", "look_at = [0.0, 0.0, 0.0]\nup = [0, 0, 0]");
        expect_err("up0.toml", &text, &[], &["camera: field 'up'", "nonzero"]);
        let text = mini_with(
            "look_at = [0.0, 0.0, 0.0]",
            "look_at = [0.0, 0.0, 0.0]\nup = [0, 1e-30, 0]",
        );
        expect_err(
            "tinyup.toml",
            &text,
            &[],
            &["camera: field 'up'", "too small or too large"],
        );
        let text = mini_with("position = [0.0, 0.0, 3.0]", "position = [0.0, 0.0, 3e38]").replacen(
            "look_at = [0.0, 0.0, 0.0]",
            "look_at = [0.0, 0.0, -3e38]",
            1,
        );
        expect_err("far.toml", &text, &[], &["camera: field 'look_at'", "too far"]);
        // a huge but nonzero up vector is fine (only its direction matters)
        let text = mini_with(
            "look_at = [0.0, 0.0, 0.0]",
            "look_at = [0.0, 0.0, 0.0]\nup = [0, 1e30, 0]",
        );
        load_text("bigup.toml", &text, &[], &[]).unwrap();
    }

    #[test]
    fn laser_direction_is_normalised_and_must_be_nonzero() {
        let laser = "\n[[emitter]]\nname = \"beam\"\ntype = \"laser\"\nposition = [0, 0, 2]\ndirection = [0, 0, -4]\npower = 2\n";
        let s = load_text("laser.toml", &format!("{MINI}{laser}"), &[], &[]).unwrap();
        assert_eq!(
            s.emitters[1].kind,
            EmitterKind::Laser {
                position: Vec3::new(0.0, 0.0, 2.0),
                direction: Vec3::new(0.0, 0.0, -1.0),
                power: [2.0; 3]
            }
        );
        let text = format!("{MINI}{}", laser.replace("[0, 0, -4]", "[0, 0, -1e30]"));
        let s = load_text("hugedir.toml", &text, &[], &[]).unwrap();
        assert!(matches!(s.emitters[1].kind, EmitterKind::Laser { direction, .. } if direction == Vec3::NEG_Z));
        let text = format!("{MINI}{}", laser.replace("[0, 0, -4]", "[0, 0, 0]"));
        expect_err(
            "zerodir.toml",
            &text,
            &[],
            &["emitter[1] \"beam\": field 'direction'", "must be a nonzero vector"],
        );
        let text = format!("{MINI}{}", laser.replace("direction = [0, 0, -4]\n", ""));
        expect_err(
            "nodir.toml",
            &text,
            &[],
            &["emitter[1] \"beam\": field 'direction'", "missing"],
        );
    }

    #[test]
    fn eta_and_albedo_ranges() {
        let text = format!("[medium]\neta = 0\n{MINI}");
        expect_err("eta.toml", &text, &[], &["medium: field 'eta'", "must be > 0"]);
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

    #[test]
    fn mono_refuses_unequal_channels() {
        let text = mini_with("bins = 10", "bins = 10\nchannels = \"mono\"").replacen(
            "albedo = 0.5",
            "albedo = [0.5, 0.2, 0.5]",
            1,
        );
        expect_err(
            "mono.toml",
            &text,
            &[],
            &["material[0] \"white\": field 'albedo'", "unequal channels", "\"mono\""],
        );
        let text = mini_with("bins = 10", "bins = 10\nchannels = \"mono\"").replacen(
            "albedo = 0.5",
            "albedo = [0.5, 0.5, 0.5]",
            1,
        );
        assert_eq!(load_text("mono_ok.toml", &text, &[], &[]).unwrap().film.channels, 1);
        let text = mini_with("bins = 10", "bins = 10\nchannels = \"rgb\"");
        assert_eq!(load_text("rgb.toml", &text, &[], &[]).unwrap().film.channels, 3);
        let text = mini_with("bins = 10", "bins = 10\nchannels = \"grey\"");
        expect_err(
            "ch.toml",
            &text,
            &[],
            &["film: field 'channels'", "'mono', 'rgb', 'auto'"],
        );
    }
}
