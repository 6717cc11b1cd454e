//! Emitters: area emitters (the shape each covers, one per shape, which must have a
//! material), point lights and lasers (positions relative to the render origin, the beam's
//! direction normalised), each with its pulse. A field that only another type takes is refused.

use super::context::{Ctx, Names, beyond_time_opl, check_colour, emission, no_such, number, time_width};
use super::desc::{EmitterDesc, EmitterType, NameOr, PulseType, SceneDesc};
use super::error::item_field;
use super::limits::MAX_TIME_OPL;
use super::{Emitter, EmitterKind, SceneError};
use crate::temporal::Pulse;
use glam::{DVec3, Vec3};
use std::collections::HashMap;

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
                sigma_opl: time_width(ctx, at("pulse.sigma_opl"), s)?,
            }
        }
        PulseType::Box => {
            if sigma.is_some() {
                return Err(unused("sigma_opl", "box"));
            }
            let w =
                width.ok_or_else(|| ctx.invalid(at("pulse.width_opl"), "missing: a box pulse needs width_opl > 0"))?;
            Pulse::Box {
                width_opl: time_width(ctx, at("pulse.width_opl"), w)?,
            }
        }
    })
}

/// The emitters, point and laser positions relative to the render origin (subtracted in f64).
pub(super) fn emitters(desc: &SceneDesc, names: &Names, origin: DVec3, ctx: &Ctx) -> Result<Vec<Emitter>, SceneError> {
    let mut claimed: HashMap<usize, usize> = HashMap::new();
    let mut out = Vec::new();
    for (i, e) in desc.emitter.iter().enumerate() {
        only_for(ctx, i, e)?;
        let at = |f: &str| item_field("emitter", i, &e.name, f);
        let amount_field = e.ty.amount_field();
        let amount = {
            match e.amount() {
                Some(a) => emission(
                    ctx,
                    at(amount_field),
                    check_colour(ctx, at(amount_field), a, 0.0, f32::INFINITY)?,
                )?,
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
        let pulse = pulse(ctx, i, e)?;
        if e.offset_opl.abs() > MAX_TIME_OPL {
            return Err(ctx.invalid(at("offset_opl"), beyond_time_opl(number(e.offset_opl), true)));
        }
        out.push(Emitter {
            name: e.name.clone(),
            kind,
            pulse,
            offset_opl: e.offset_opl,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;

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
}
