//! Camera and film: the camera's frame and field of view (positions relative to the render
//! origin), image size and pixel filter, then the film's time axis, gate and colour channels
//! (`mono`, `rgb`, or `auto` from the colours and parameters of the scene).

use super::context::{Ctx, count, time_width};
use super::desc::{CameraDesc, Channels, FilmDesc, FilterType, GateType, NameOr, SceneDesc, Triple};
use super::error::{item_field, table_field};
use super::limits::{MAX_FILTER_WIDTH, MIN_FILTER_WIDTH, number};
use super::{Camera, FilmSpec, Param, ParamKind, PixelFilter, SceneError};
use crate::temporal::{Gate, TimeAxis};
use glam::{DVec3, Vec3};

/// Largest accepted image side and bin count.
pub const MAX_RESOLUTION: i64 = 16384;
pub const MAX_BINS: i64 = 1 << 24;

/// The camera, its position and target relative to the render origin (subtracted in f64).
pub(super) fn camera(d: &CameraDesc, origin: DVec3, ctx: &Ctx) -> Result<(Camera, u32, u32, PixelFilter), SceneError> {
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
    // 32-bit arithmetic squares the distance: past sqrt(f32::MAX) ≈ 1.8e19 m it is infinite
    // (and glam's normalize gives zero, which the up check below took for a parallel up)
    if !view.length_squared().is_finite() {
        let (p, l) = (DVec3::from(d.position) - origin, DVec3::from(d.look_at) - origin);
        // the one farther from the render origin (look_at when they are as far)
        let (field, value, other) = if p.length() > l.length() {
            ("position", d.position, "look_at")
        } else {
            ("look_at", d.look_at, "position")
        };
        return Err(ctx.invalid(
            at(field),
            format!(
                "{value:?} is {:e} m from camera.{other}, too far for 32-bit arithmetic (it squares that distance); expected the two within {:.1e} m of each other",
                (DVec3::from(d.look_at) - DVec3::from(d.position)).length(),
                f32::MAX.sqrt()
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
                radius: filter_width(ctx, at("filter.radius"), radius.unwrap_or(1.0))?,
            }
        }
        FilterType::Gaussian => PixelFilter::Gaussian {
            sigma: filter_width(ctx, at("filter.sigma"), sigma.unwrap_or(0.5))?,
            radius: filter_width(ctx, at("filter.radius"), radius.unwrap_or(1.5))?,
        },
    })
}

/// A filter's radius or σ in pixels, within [`MIN_FILTER_WIDTH`, `MAX_FILTER_WIDTH`].
fn filter_width(ctx: &Ctx, at: String, v: f32) -> Result<f32, SceneError> {
    if (MIN_FILTER_WIDTH..=MAX_FILTER_WIDTH).contains(&(v as f64)) {
        return Ok(v);
    }
    Err(ctx.invalid(
        at,
        format!(
            "must be in [{MIN_FILTER_WIDTH}, {MAX_FILTER_WIDTH}] pixels (got {}): a narrower filter is the pixel's centre alone, \
             and a wider one reaches past what a pixel filter is for (blur the image after rendering instead)",
            number(v)
        ),
    ))
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
                sigma_opl: time_width(ctx, at("gate.sigma_opl"), s)?,
            },
            None => {
                return Err(ctx.invalid(at("gate.sigma_opl"), "missing: a gaussian gate needs sigma_opl > 0"));
            }
        },
    })
}

pub(super) fn film(
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
    // the time plot of --preview and the kernel's window bound hold it as a 32-bit float too
    if (bin_width_opl as f32) < f32::MIN_POSITIVE {
        return Err(ctx.invalid(
            at("bin_width_opl"),
            format!(
                "must be at least {:e}, the smallest normal 32-bit float (got {bin_width_opl:e}): the time axis is also held in 32-bit floats, where a narrower bin is zero wide",
                f32::MIN_POSITIVE
            ),
        ));
    }
    let bins = count(ctx, at("bins"), d.bins, 1, MAX_BINS)? as usize;
    let end = d.start_opl + bin_width_opl * bins as f64;
    if !((end as f32).is_finite()) {
        return Err(ctx.invalid(
            at("bins"),
            format!("the time axis ends at OPL {end:e}, beyond the range of 32-bit floats"),
        ));
    }
    // Every bin must end after it starts. The edges start + l·w are spaced most coarsely (in
    // ulps) at the end farthest from 0: the first bin or the last.
    let last_start = d.start_opl + bin_width_opl * (bins - 1) as f64;
    if !(d.start_opl + bin_width_opl > d.start_opl && end > last_start) {
        let ulp = d.start_opl.abs().max(end.abs()) * f64::EPSILON;
        return Err(ctx.invalid(
            at("bin_width_opl"),
            format!(
                "{bin_width_opl:e} m is too narrow for a time axis from OPL {}: a bin ends where it starts in 64-bit floats; expected a width of more than about {ulp:.1e} m there (or film.start_opl nearer 0)",
                d.start_opl
            ),
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

/// 1 or 3: `mono` refuses unequal triples, `auto` picks RGB if there is one (or a param acts
/// on a single channel).
pub(super) fn channels(desc: &SceneDesc, params: &[Param], ctx: &Ctx) -> Result<usize, SceneError> {
    let mut colours: Vec<(String, Triple)> = Vec::new();
    // every coloured input of a material: a diffuse albedo, a conductor's tint and complex
    // index (a gold conductor in a grey scene was rendered mono, with red's Fresnel only)
    for (i, m) in desc.material.iter().enumerate() {
        for (field, value) in [
            ("albedo", m.albedo),
            ("specular_reflectance", m.specular_reflectance),
            ("eta", m.eta),
            ("k", m.k),
        ] {
            if let Some(a) = value {
                colours.push((item_field("material", i, &m.name, field), a));
            }
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
        // a conductor's tint and complex index are colours too: "auto" makes the film rgb,
        // "mono" refuses them (before, a gold conductor in a grey scene rendered mono, with
        // red's Fresnel only)
        for (field, value) in [
            ("specular_reflectance", "[1.0, 0.9, 0.5]"),
            ("eta", "[0.2, 0.4, 1.4]\nk = 3.0"),
            ("k", "[3.6, 2.4, 1.8]\neta = 0.3"),
        ] {
            let conductor = |channels: &str| {
                mini_with("bins = 10", &format!("bins = 10\nchannels = \"{channels}\"")).replacen(
                    "type = \"diffuse\"\nalbedo = 0.5",
                    &format!("type = \"conductor\"\n{field} = {value}"),
                    1,
                )
            };
            let auto = load_text("auto.toml", &conductor("auto"), &[], &[]).unwrap();
            assert_eq!(auto.film.channels, 3, "{field}");
            expect_err(
                "mono.toml",
                &conductor("mono"),
                &[],
                &[&format!("material[0] \"white\": field '{field}'"), "unequal channels"],
            );
        }
        let text = mini_with("bins = 10", "bins = 10\nchannels = \"grey\"");
        expect_err(
            "ch.toml",
            &text,
            &[],
            &["film: field 'channels'", "'mono', 'rgb', 'auto'"],
        );
    }
}
