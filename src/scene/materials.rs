//! Materials: each `[[material]]` becomes a named material of its `type`:
//!
//! | type | fields |
//! |---|---|
//! | `diffuse` | `albedo` in [0, 1] (required) |
//! | `roughconductor` | `roughness` (GGX α in (0, 1], required), `specular_reflectance` in [0, 1] (default 1), `eta` and `k` ≥ 0 (complex index per channel, both or neither; without them the Fresnel term is 1) |
//! | `conductor` | the same without `roughness` (a smooth mirror) |
//! | `roughdielectric` | `roughness`, `int_ior` > 0 (required), `exterior` (optional) |
//! | `dielectric` | the same without `roughness` (smooth glass) |
//!
//! Media: a dielectric's shape separates its interior (index `int_ior`, the side its normals
//! point away from) from its exterior, which is the scene's medium (`[medium] eta`) unless
//! `exterior` names another dielectric material whose interior surrounds this one (a liquid
//! inside a glass: the liquid's surface has `exterior = "glass"`). Each segment's OPL is the
//! index of the medium it crosses times its length. A chain of `exterior` names that returns
//! to where it began, an `exterior` naming a material that is not a dielectric, and a
//! dielectric on an open shape (a rectangle, `shapes.rs`) are refused: they leave which medium
//! a ray is in undefined.

use super::context::{Ctx, check_colour, no_such};
use super::desc::{MaterialDesc, MaterialType, Triple};
use super::error::item_field;
use super::{Material, NamedMaterial, SceneError};

pub(super) fn materials(list: &[MaterialDesc], ctx: &Ctx) -> Result<Vec<NamedMaterial>, SceneError> {
    let names: Vec<String> = list.iter().map(|m| m.name.clone()).collect();
    list.iter()
        .enumerate()
        .map(|(i, m)| {
            Ok(NamedMaterial {
                name: m.name.clone(),
                material: material(list, &names, i, m, ctx)?,
            })
        })
        .collect()
}

fn material(
    list: &[MaterialDesc],
    names: &[String],
    i: usize,
    m: &MaterialDesc,
    ctx: &Ctx,
) -> Result<Material, SceneError> {
    let at = |f: &str| item_field("material", i, &m.name, f);
    let ty = m.ty.as_str();
    let given = [
        ("albedo", m.albedo.is_some()),
        ("roughness", m.roughness.is_some()),
        ("specular_reflectance", m.specular_reflectance.is_some()),
        ("eta", m.eta.is_some()),
        ("k", m.k.is_some()),
        ("int_ior", m.int_ior.is_some()),
        ("exterior", m.exterior.is_some()),
    ];
    for (field, is_set) in given {
        if is_set && !m.ty.fields().contains(&field) {
            return Err(ctx.invalid(
                at(field),
                format!("does not apply to type {ty} (it takes: {})", m.ty.fields().join(", ")),
            ));
        }
    }
    let roughness = || -> Result<f32, SceneError> {
        match m.roughness {
            Some(a) if a > 0.0 && a <= 1.0 => Ok(a),
            Some(a) => Err(ctx.invalid(
                at("roughness"),
                format!("must be in (0, 1] (got {a}); for roughness 0 use type conductor or dielectric"),
            )),
            None => Err(ctx.invalid(
                at("roughness"),
                format!("missing: type {ty} needs roughness = GGX α in (0, 1]"),
            )),
        }
    };
    let smooth = |rough: bool| -> Result<f32, SceneError> { if rough { roughness() } else { Ok(0.0) } };
    match m.ty {
        MaterialType::Diffuse => {
            let albedo = match m.albedo {
                Some(a) => check_colour(ctx, at("albedo"), a, 0.0, 1.0)?,
                None => {
                    return Err(ctx.invalid(
                        at("albedo"),
                        "missing: a diffuse material needs albedo = scalar or [r, g, b], each in [0, 1]",
                    ));
                }
            };
            Ok(Material::Diffuse { albedo })
        }
        MaterialType::Roughconductor | MaterialType::Conductor => {
            let roughness = smooth(m.ty == MaterialType::Roughconductor)?;
            let specular = check_colour(
                ctx,
                at("specular_reflectance"),
                m.specular_reflectance.unwrap_or(Triple::Scalar(1.0)),
                0.0,
                1.0,
            )?;
            let ior = match (m.eta, m.k) {
                (None, None) => None,
                (Some(e), Some(k)) => Some((
                    check_colour(ctx, at("eta"), e, 0.0, f32::INFINITY)?,
                    check_colour(ctx, at("k"), k, 0.0, f32::INFINITY)?,
                )),
                (Some(_), None) => {
                    return Err(ctx.invalid(at("k"), "missing: eta needs k (the complex index is eta + i k)"));
                }
                (None, Some(_)) => {
                    return Err(ctx.invalid(at("eta"), "missing: k needs eta (the complex index is eta + i k)"));
                }
            };
            Ok(Material::Conductor {
                roughness,
                specular,
                ior,
            })
        }
        MaterialType::Roughdielectric | MaterialType::Dielectric => {
            let roughness = smooth(m.ty == MaterialType::Roughdielectric)?;
            let int_ior = match m.int_ior {
                Some(v) if v > 0.0 && v.is_finite() => v,
                Some(v) => return Err(ctx.invalid(at("int_ior"), format!("must be a finite number > 0 (got {v})"))),
                None => {
                    return Err(ctx.invalid(
                        at("int_ior"),
                        format!("missing: type {ty} needs int_ior = the refractive index inside"),
                    ));
                }
            };
            let exterior = match &m.exterior {
                None => None,
                Some(e) => Some(exterior(list, names, i, e, ctx)?),
            };
            Ok(Material::Dielectric {
                roughness,
                int_ior,
                exterior,
            })
        }
    }
}

/// The material named by `exterior` of material `i`: a dielectric other than `i`, whose own
/// chain of exteriors ends in the scene's medium.
fn exterior(list: &[MaterialDesc], names: &[String], i: usize, e: &str, ctx: &Ctx) -> Result<u32, SceneError> {
    let at = item_field("material", i, &list[i].name, "exterior");
    let j = names
        .iter()
        .position(|n| n == e)
        .ok_or_else(|| ctx.invalid(at.clone(), no_such("material", "materials", e, names)))?;
    if !list[j].ty.is_dielectric() {
        return Err(ctx.invalid(
            at,
            format!(
                "material {e:?} is of type {}: an exterior must be a dielectric (its interior index surrounds this one)",
                list[j].ty.as_str()
            ),
        ));
    }
    let mut chain = vec![list[i].name.clone()];
    let mut k = j;
    loop {
        chain.push(list[k].name.clone());
        if k == i {
            return Err(ctx.invalid(
                at,
                format!(
                    "ambiguous media: the exteriors form a loop ({}), so no medium surrounds them",
                    chain.join(" -> ")
                ),
            ));
        }
        match list[k]
            .exterior
            .as_deref()
            .and_then(|n| names.iter().position(|x| x == n))
        {
            Some(next) if chain.len() <= list.len() + 1 => k = next,
            _ => return Ok(j as u32),
        }
    }
}
