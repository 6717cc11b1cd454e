//! `[[param]]` entries and `--set NAME=VALUE` overrides: the override replaces the param's
//! value, and each param's value then replaces the quantity it controls in the description
//! (before any range check, so a bad value is reported like a bad value in the file).

use super::{Axis, Param, ParamKind};
use crate::scene::SceneError;
use crate::scene::context::{Ctx, Names, no_such};
use crate::scene::desc::{AxisDesc, ChannelDesc, ParamKindDesc, SceneDesc, Triple};
use crate::scene::error::{item_field, table_field};
use std::path::Path;

/// Applies `--set` overrides to the params' values; returns which params were overridden.
pub(crate) fn apply_overrides(
    desc: &mut SceneDesc,
    overrides: &[(String, f64)],
    names: &Names,
    path: &Path,
) -> Result<Vec<bool>, SceneError> {
    let mut overridden = vec![false; desc.param.len()];
    for (name, value) in overrides {
        let err = |message: String| SceneError::Override {
            path: path.to_path_buf(),
            name: name.clone(),
            message,
        };
        let Some(i) = names.params.iter().position(|p| p == name) else {
            return Err(err(if names.params.is_empty() {
                format!("no parameter named {name:?}: the scene has no [[param]] entries")
            } else {
                format!("no parameter named {name:?} (parameters: {})", names.params.join(", "))
            }));
        };
        crate::scene::f32_value::check_override_value(*value).map_err(err)?;
        desc.param[i].value = *value;
        overridden[i] = true;
    }
    Ok(overridden)
}

fn axis(a: AxisDesc) -> Axis {
    match a {
        AxisDesc::X => Axis::X,
        AxisDesc::Y => Axis::Y,
        AxisDesc::Z => Axis::Z,
    }
}

fn channel(c: ChannelDesc) -> usize {
    match c {
        ChannelDesc::R => 0,
        ChannelDesc::G => 1,
        ChannelDesc::B => 2,
    }
}

pub(crate) fn axis_name(a: Axis) -> &'static str {
    ["x", "y", "z"][a as usize]
}

pub(crate) fn channel_name(c: usize) -> &'static str {
    ["r", "g", "b"].get(c).copied().unwrap_or("?")
}

/// Sets one component (or all, `None`) of a scalar-or-triple.
fn set_component(t: Option<Triple>, default: f32, component: Option<usize>, value: f32) -> Triple {
    match component {
        None => Triple::Scalar(value),
        Some(c) => {
            let mut v = t.map_or([default; 3], Triple::to_array);
            v[c] = value;
            Triple::Three(v)
        }
    }
}

/// Resolves every param's target, applies its value onto `desc`, and records in `ctx` which
/// locations got their value from a param (so later range errors say so).
pub(crate) fn apply_params(
    desc: &mut SceneDesc,
    names: &Names,
    ctx: &mut Ctx,
    overridden: &[bool],
    fields: &[(String, f64)],
) -> Result<Vec<Param>, SceneError> {
    let mut out: Vec<Param> = Vec::new();
    // (quantity, component) pairs already claimed, with the index of the param claiming it.
    let mut claimed: Vec<(String, usize, usize)> = Vec::new();
    for i in 0..desc.param.len() {
        let p = desc.param[i].clone();
        let at = |f: &str| item_field("param", i, &p.name, f);
        let kind_name = p.kind.as_str();
        let origin = if overridden.get(i).copied().unwrap_or(false) {
            format!("value from param {:?}, set with --set {}={}", p.name, p.name, p.value)
        } else {
            format!("value from param {:?}", p.name)
        };
        let bad_value = |message: String| {
            let message = if overridden.get(i).copied().unwrap_or(false) {
                format!("{message} (set with --set {}={})", p.name, p.value)
            } else {
                message
            };
            SceneError::Invalid {
                path: ctx.path.to_path_buf(),
                at: at("value"),
                message,
            }
        };

        // Which of the optional fields this kind takes.
        let (takes, target_field): (&[&str], Option<&str>) = match p.kind {
            ParamKindDesc::Translate | ParamKindDesc::Rotate | ParamKindDesc::Scale => {
                (&["shape", "axis"], Some("shape"))
            }
            ParamKindDesc::Albedo => (&["material", "channel"], Some("material")),
            ParamKindDesc::Radiance => (&["emitter", "channel"], Some("emitter")),
            ParamKindDesc::Eta => (&[], None),
            ParamKindDesc::Roughness | ParamKindDesc::Ior => (&["material"], Some("material")),
            ParamKindDesc::PulseOffset => (&["emitter"], Some("emitter")),
        };
        let given = [
            ("shape", p.shape.is_some()),
            ("material", p.material.is_some()),
            ("emitter", p.emitter.is_some()),
            ("axis", p.axis.is_some()),
            ("channel", p.channel.is_some()),
        ];
        for (field, is_set) in given {
            if is_set && !takes.contains(&field) {
                let takes = if takes.is_empty() {
                    "none".to_string()
                } else {
                    takes.join(", ")
                };
                return Err(ctx.invalid(
                    at(field),
                    format!("does not apply to kind {kind_name} (it takes: {takes})"),
                ));
            }
        }
        let needs_axis = || {
            p.axis.map(axis).ok_or_else(|| {
                ctx.invalid(
                    at("axis"),
                    format!("missing: kind {kind_name} needs axis = \"x\", \"y\" or \"z\""),
                )
            })
        };
        let target = |list: &[String], what: &str, plural: &str, given: &Option<String>| -> Result<usize, SceneError> {
            let field = target_field.unwrap_or(what);
            match given {
                None => Err(ctx.invalid(
                    at(field),
                    format!(
                        "missing: kind {kind_name} needs the name of {} {what} ({plural}: {})",
                        if what == "emitter" { "an" } else { "a" },
                        list.join(", ")
                    ),
                )),
                Some(n) => list
                    .iter()
                    .position(|x| x == n)
                    .ok_or_else(|| ctx.invalid(at(field), no_such(what, plural, n, list))),
            }
        };
        let v = p.value;
        // (kind, location of the controlled field, quantity name for conflicts, components)
        // (kind, location of the controlled field, quantity name for conflicts, components,
        // the field's dotted path as `--set` names it)
        let (kind, loc, quantity, components, path): (ParamKind, String, String, Vec<usize>, String) = match p.kind {
            ParamKindDesc::Translate | ParamKindDesc::Rotate | ParamKindDesc::Scale => {
                let s = target(&names.shapes, "shape", "shapes", &p.shape)?;
                let a = needs_axis()?;
                let shape = &mut desc.shape[s];
                let (kind, field) = match p.kind {
                    ParamKindDesc::Translate => {
                        shape.translate.get_or_insert([0.0; 3])[a as usize] = v;
                        (
                            ParamKind::Translate {
                                shape: s as u32,
                                axis: a,
                            },
                            "translate",
                        )
                    }
                    ParamKindDesc::Rotate => {
                        shape.rotate.get_or_insert([0.0; 3])[a as usize] = v as f32;
                        (
                            ParamKind::Rotate {
                                shape: s as u32,
                                axis: a,
                            },
                            "rotate",
                        )
                    }
                    _ => {
                        if v == 0.0 {
                            return Err(bad_value("a scale factor must be nonzero (got 0)".to_string()));
                        }
                        shape.scale = Some(set_component(shape.scale, 1.0, Some(a as usize), v as f32));
                        (
                            ParamKind::Scale {
                                shape: s as u32,
                                axis: a,
                            },
                            "scale",
                        )
                    }
                };
                let loc = item_field("shape", s, &shape.name, field);
                (
                    kind,
                    loc,
                    format!("shape {:?} {field}", shape.name),
                    vec![a as usize],
                    format!("shape.{}.{field}", shape.name),
                )
            }
            ParamKindDesc::Albedo => {
                let m = target(&names.materials, "material", "materials", &p.material)?;
                use crate::scene::desc::MaterialType;
                // a diffuse albedo, or a (rough or smooth) conductor's specular reflectance
                let field = match desc.material[m].ty {
                    MaterialType::Diffuse => "albedo",
                    MaterialType::Roughconductor | MaterialType::Conductor => "specular_reflectance",
                    ty => {
                        return Err(ctx.invalid(
                            at("material"),
                            format!(
                                "material {:?} is of type {}; kind albedo applies to diffuse materials (albedo) and conductors (specular_reflectance)",
                                desc.material[m].name,
                                ty.as_str()
                            ),
                        ));
                    }
                };
                let c = p.channel.map(channel);
                let mat = &mut desc.material[m];
                let (slot, default) = match field {
                    "albedo" => (&mut mat.albedo, 0.0),
                    _ => (&mut mat.specular_reflectance, 1.0),
                };
                if c.is_none() || slot.is_some() || default == 1.0 {
                    *slot = Some(set_component(*slot, default, c, v as f32));
                }
                let loc = item_field("material", m, &mat.name, field);
                (
                    ParamKind::Albedo {
                        material: m as u32,
                        channel: c,
                    },
                    loc,
                    format!("material {:?} {field}", mat.name),
                    c.map_or(vec![0, 1, 2], |c| vec![c]),
                    format!("material.{}.{field}", mat.name),
                )
            }
            ParamKindDesc::Radiance => {
                let e = target(&names.emitters, "emitter", "emitters", &p.emitter)?;
                let c = p.channel.map(channel);
                let em = &mut desc.emitter[e];
                let field = em.ty.amount_field();
                let amount = em.amount_mut();
                if c.is_none() || amount.is_some() {
                    *amount = Some(set_component(*amount, 0.0, c, v as f32));
                }
                let loc = item_field("emitter", e, &em.name, field);
                (
                    ParamKind::Radiance {
                        emitter: e as u32,
                        channel: c,
                    },
                    loc,
                    format!("emitter {:?} {field}", em.name),
                    c.map_or(vec![0, 1, 2], |c| vec![c]),
                    format!("emitter.{}.{field}", em.name),
                )
            }
            ParamKindDesc::Eta => {
                desc.medium.eta = v as f32;
                (
                    ParamKind::Eta,
                    table_field("medium", "eta"),
                    "medium eta".to_string(),
                    vec![0],
                    "medium.eta".to_string(),
                )
            }
            ParamKindDesc::Roughness | ParamKindDesc::Ior => {
                use crate::scene::desc::MaterialType;
                let m = target(&names.materials, "material", "materials", &p.material)?;
                let mat = &mut desc.material[m];
                let (field, fits) = match p.kind {
                    ParamKindDesc::Roughness => (
                        "roughness",
                        matches!(mat.ty, MaterialType::Roughconductor | MaterialType::Roughdielectric),
                    ),
                    _ => (
                        "int_ior",
                        matches!(mat.ty, MaterialType::Dielectric | MaterialType::Roughdielectric),
                    ),
                };
                if !fits {
                    let types = match p.kind {
                        ParamKindDesc::Roughness => "roughconductor or roughdielectric",
                        _ => "dielectric or roughdielectric",
                    };
                    return Err(ctx.invalid(
                        at("material"),
                        format!(
                            "material {:?} is of type {}; kind {kind_name} applies to {types}",
                            mat.name,
                            mat.ty.as_str()
                        ),
                    ));
                }
                let kind = match p.kind {
                    ParamKindDesc::Roughness => {
                        mat.roughness = Some(v as f32);
                        ParamKind::Roughness { material: m as u32 }
                    }
                    _ => {
                        mat.int_ior = Some(v as f32);
                        ParamKind::Ior { material: m as u32 }
                    }
                };
                let loc = item_field("material", m, &mat.name, field);
                (
                    kind,
                    loc,
                    format!("material {:?} {field}", mat.name),
                    vec![0],
                    format!("material.{}.{field}", mat.name),
                )
            }
            ParamKindDesc::PulseOffset => {
                let e = target(&names.emitters, "emitter", "emitters", &p.emitter)?;
                let em = &mut desc.emitter[e];
                em.offset_opl = v;
                let loc = item_field("emitter", e, &em.name, "offset_opl");
                (
                    ParamKind::PulseOffset { emitter: e as u32 },
                    loc,
                    format!("emitter {:?} offset_opl", em.name),
                    vec![0],
                    format!("emitter.{}.offset_opl", em.name),
                )
            }
        };
        // the kind's range (`ParamKind::domain`; a scale factor's 0 is refused above)
        let (domain, what) = kind.domain(v);
        if !domain.contains(v) {
            return Err(bad_value(format!(
                "{what} must be {domain} (got {})",
                crate::scene::limits::number(v)
            )));
        }
        for c in &components {
            if let Some((_, _, j)) = claimed.iter().find(|(q, k, _)| *q == quantity && k == c) {
                return Err(ctx.invalid(
                    at("kind"),
                    format!(
                        "controls the same quantity ({quantity}) as param[{j}] {:?}; each quantity can have one param",
                        out[*j].name
                    ),
                ));
            }
        }
        claimed.extend(components.iter().map(|&c| (quantity.clone(), c, i)));
        // a `--set` of the field (or of a component) this param sets: the param's value would
        // replace it without a word (`--set material.wall.albedo=0.4` rendered the param's 0.6)
        let same_field = |f: &str| {
            f == path
                || f.strip_prefix(path.as_str())
                    .and_then(|r| r.strip_prefix('.'))
                    .and_then(|i| i.parse::<usize>().ok())
                    .is_some_and(|i| components.contains(&i))
        };
        if let Some((f, _)) = fields.iter().find(|(f, _)| same_field(f)) {
            return Err(SceneError::Override {
                path: ctx.path.to_path_buf(),
                name: f.clone(),
                message: format!(
                    "param[{i}] {:?} sets this field ({quantity}) and its value would replace yours; set the \
                     param instead (--set {}=VALUE)",
                    p.name, p.name
                ),
            });
        }
        // a field whose components several params set (rotate.x and rotate.y) names them all
        match ctx.set_by.get_mut(&loc) {
            Some(note) => {
                note.push_str("; ");
                note.push_str(&origin);
            }
            None => {
                ctx.set_by.insert(loc, origin);
            }
        }
        out.push(Param {
            name: p.name.clone(),
            kind,
            value: v,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use crate::scene::testutil::*;
    use crate::scene::{EmitterKind, Material, Scene};
    use glam::Vec3;

    fn set(name: &str, v: f64) -> Vec<(String, f64)> {
        vec![(name.to_string(), v)]
    }

    #[test]
    fn translate_override_moves_vertices_by_the_delta() {
        let base = load_scene("occluder_shadow.toml");
        let path = scenes_dir().join("occluder_shadow.toml");
        let moved = Scene::load(&path, &set("occluder_x", 0.35)).unwrap();
        let i = base.shapes.iter().position(|s| s.name == "occluder").unwrap();
        let (a, b) = (&base.shapes[i], &moved.shapes[i]);
        assert_eq!(
            a.transform.translate.x, 0.1,
            "the param's value overrides the file's translate"
        );
        assert_eq!(b.transform.translate.x, 0.35);
        assert_eq!(
            (a.transform.translate.y, a.transform.translate.z),
            (b.transform.translate.y, b.transform.translate.z)
        );
        assert_eq!(moved.params[0].value, 0.35);
        for k in 0..a.vertex_count as usize {
            let pa = base.geometry.positions[a.first_vertex as usize + k];
            let pb = moved.geometry.positions[b.first_vertex as usize + k];
            let d = pb - pa;
            assert!((d - Vec3::new(0.25, 0.0, 0.0)).abs().max_element() < 1e-6, "{d}");
            // world vertices are built in f64 (origin.rs), then rounded once
            let f32_apply = b.transform.apply(b.local_positions[k]);
            assert!((pb - f32_apply).abs().max_element() <= 1e-6, "{pb} {f32_apply}");
        }
        // every other shape is untouched
        for (j, s) in base.shapes.iter().enumerate().filter(|(j, _)| *j != i) {
            let r = s.first_vertex as usize..(s.first_vertex + s.vertex_count) as usize;
            assert_eq!(
                base.geometry.positions[r.clone()],
                moved.geometry.positions[r],
                "shape {j}"
            );
        }
    }

    #[test]
    fn eta_override_changes_eta() {
        let path = scenes_dir().join("confocal_plane.toml");
        assert_eq!(Scene::load(&path, &[]).unwrap().eta, 1.0);
        assert_eq!(Scene::load(&path, &set("eta", 1.33)).unwrap().eta, 1.33);
        expect_err_set(
            "e.toml",
            &scene_text("confocal_plane.toml"),
            &[],
            &set("eta", 0.0),
            &["param[0] \"eta\": field 'value'", "must be >= 1e-6", "--set eta=0"],
        );
    }

    #[test]
    fn rotate_and_scale_params_act_on_the_obj() {
        let path = scenes_dir().join("obj_mesh.toml");
        let s = Scene::load(&path, &[]).unwrap();
        let m = s.shapes.iter().find(|s| s.name == "pyramid").unwrap();
        assert_eq!(m.transform.scale, Vec3::new(0.5, 0.6, 0.5));
        assert_eq!(m.transform.rotate_deg, Vec3::new(0.0, 30.0, 0.0));
        let s2 = Scene::load(&path, &[("pyramid_yaw".into(), 75.0), ("pyramid_height".into(), 1.2)]).unwrap();
        let m2 = s2.shapes.iter().find(|s| s.name == "pyramid").unwrap();
        assert_eq!(m2.transform.rotate_deg.y, 75.0);
        assert_eq!(m2.transform.scale, Vec3::new(0.5, 1.2, 0.5));
        // apex (0, 1.5, 0) sits at height 1.5 * scale.y whatever the yaw
        let top = |s: &Scene, m: &crate::scene::Shape| {
            (0..m.vertex_count as usize)
                .map(|k| s.geometry.positions[m.first_vertex as usize + k].y)
                .fold(f32::MIN, f32::max)
        };
        assert!((top(&s, m) - 0.9).abs() < 1e-6);
        assert!((top(&s2, m2) - 1.8).abs() < 1e-6);
    }

    #[test]
    fn albedo_and_radiance_params_set_channels() {
        let text = format!(
            "{MINI}\n[[param]]\nname = \"a\"\nkind = \"albedo\"\nmaterial = \"white\"\nchannel = \"g\"\nvalue = 0.25\n\
             [[param]]\nname = \"i\"\nkind = \"radiance\"\nemitter = \"lamp\"\nvalue = 3\n\
             [[param]]\nname = \"t\"\nkind = \"pulse_offset\"\nemitter = \"lamp\"\nvalue = 0.2\n"
        );
        let s = load_text("p.toml", &text, &[], &[]).unwrap();
        assert_eq!(
            s.materials[0].material,
            Material::Diffuse {
                albedo: [0.5, 0.25, 0.5]
            }
        );
        assert!(matches!(
            s.emitters[0].kind,
            EmitterKind::Point {
                intensity: [3.0, 3.0, 3.0],
                ..
            }
        ));
        assert_eq!(s.emitters[0].offset_opl, 0.2);
        assert_eq!(s.film.channels, 3, "a per-channel param makes an auto film RGB");
        let s = load_text("p.toml", &text, &[], &set("i", 7.0)).unwrap();
        assert!(matches!(
            s.emitters[0].kind,
            EmitterKind::Point {
                intensity: [7.0, 7.0, 7.0],
                ..
            }
        ));
        let mono = text.replacen("bins = 10", "bins = 10\nchannels = \"mono\"", 1);
        expect_err(
            "mono.toml",
            &mono,
            &[],
            &["param[0] \"a\": field 'channel'", "\"mono\""],
        );
        expect_err_set(
            "alb.toml",
            &text,
            &[],
            &set("a", 2.0),
            &["param[0] \"a\": field 'value'", "[0, 1]", "--set a=2"],
        );
    }

    #[test]
    fn unknown_set_name_lists_the_params() {
        let text = scene_text("obj_mesh.toml").replace(
            "meshes/pyramid.obj",
            &scenes_dir().join("meshes/pyramid.obj").display().to_string(),
        );
        expect_err_set(
            "o.toml",
            &text,
            &[],
            &set("pyramid_roll", 1.0),
            &[
                "--set pyramid_roll",
                "no parameter named \"pyramid_roll\"",
                "(parameters: pyramid_yaw, pyramid_height)",
            ],
        );
        expect_err_set(
            "m.toml",
            MINI,
            &[],
            &set("x", 1.0),
            &["--set x", "no [[param]] entries"],
        );
        expect_err_set(
            "o.toml",
            &text,
            &[],
            &set("pyramid_yaw", f64::NAN),
            &["--set pyramid_yaw", "finite"],
        );
        expect_err_set(
            "o.toml",
            &text,
            &[],
            &set("pyramid_yaw", f64::INFINITY),
            &["--set pyramid_yaw", "finite"],
        );
    }

    #[test]
    fn param_target_errors() {
        let p = |body: &str| format!("{MINI}\n[[param]]\nname = \"p\"\n{body}\nvalue = 0.5\n");
        expect_err(
            "t1.toml",
            &p("kind = \"translate\"\nshape = \"qaud\"\naxis = \"x\""),
            &[],
            &[
                "param[0] \"p\": field 'shape'",
                "no shape named \"qaud\" (shapes: quad)",
            ],
        );
        expect_err(
            "t2.toml",
            &p("kind = \"translate\"\naxis = \"x\""),
            &[],
            &["param[0] \"p\": field 'shape'", "missing", "shapes: quad"],
        );
        expect_err(
            "t3.toml",
            &p("kind = \"rotate\"\nshape = \"quad\""),
            &[],
            &["param[0] \"p\": field 'axis'", "missing", "\"x\", \"y\" or \"z\""],
        );
        expect_err(
            "t4.toml",
            &p("kind = \"scale\"\nshape = \"quad\"\naxis = \"w\""),
            &[],
            &["param[0] \"p\": field 'axis'", "unknown variant 'w'", "'x', 'y', 'z'"],
        );
        expect_err(
            "t5.toml",
            &p("kind = \"albedo\"\nmaterial = \"red\""),
            &[],
            &[
                "param[0] \"p\": field 'material'",
                "no material named \"red\" (materials: white)",
            ],
        );
        expect_err(
            "t6.toml",
            &p("kind = \"radiance\"\nemitter = \"sun\""),
            &[],
            &[
                "param[0] \"p\": field 'emitter'",
                "no emitter named \"sun\" (emitters: lamp)",
            ],
        );
        expect_err(
            "t7.toml",
            &p("kind = \"eta\"\naxis = \"x\""),
            &[],
            &["param[0] \"p\": field 'axis'", "does not apply to kind eta"],
        );
        expect_err(
            "t8.toml",
            &p("kind = \"warp\""),
            &[],
            &["param[0] \"p\": field 'kind'", "unknown variant 'warp'"],
        );
        expect_err(
            "t9.toml",
            &p("kind = \"pulse_offset\""),
            &[],
            &["param[0] \"p\": field 'emitter'", "missing"],
        );
        let no_value = format!("{MINI}\n[[param]]\nname = \"p\"\nkind = \"eta\"\n");
        expect_err("t10.toml", &no_value, &[], &["param[0] \"p\"", "missing field 'value'"]);
        let two = format!(
            "{MINI}\n[[param]]\nname = \"a\"\nkind = \"eta\"\nvalue = 1\n[[param]]\nname = \"b\"\nkind = \"eta\"\nvalue = 1\n"
        );
        expect_err(
            "t11.toml",
            &two,
            &[],
            &["param[1] \"b\"", "same quantity", "param[0] \"a\""],
        );
        let zero = p("kind = \"scale\"\nshape = \"quad\"\naxis = \"x\"").replace("value = 0.5", "value = 0");
        expect_err("t12.toml", &zero, &[], &["param[0] \"p\": field 'value'", "nonzero"]);
    }
}
