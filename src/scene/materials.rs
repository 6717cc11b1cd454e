//! Materials: each `[[material]]` becomes a named material of its `type`:
//!
//! | type | fields |
//! |---|---|
//! | `diffuse` | `albedo` in [0, 1] (required), `one_sided` (default false) |
//! | `roughconductor` | `roughness` (GGX α in [10⁻⁶, 1], required), `specular_reflectance` in [0, 1] (default 1), `eta` and `k` ≥ 0 (complex index per channel, both or neither; without them the Fresnel term is 1), `one_sided` |
//! | `conductor` | the same without `roughness` (a smooth mirror) |
//!
//! `one_sided = true` (diffuse and conductors) makes a material black from behind, the side
//! its shapes' normals point away from, as a Mitsuba BSDF without a `twosided` wrapper: a
//! path that meets it there ends (`crate::integrator::surface::behind_one_sided`). It still
//! hides what lies behind it. Dielectrics are two-sided.
//! | `roughdielectric` | `roughness` in [10⁻⁶, 1], `int_ior` ≥ 10⁻⁶ (required), `exterior` (optional) |
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
use super::limits::{MIN_INDEX, MIN_ROUGHNESS, number};
use super::{Material, NamedMaterial, SceneError};

pub(super) fn materials(list: &[MaterialDesc], ctx: &Ctx) -> Result<Vec<NamedMaterial>, SceneError> {
    let names: Vec<String> = list.iter().map(|m| m.name.clone()).collect();
    list.iter()
        .enumerate()
        .map(|(i, m)| {
            Ok(NamedMaterial {
                name: m.name.clone(),
                material: material(list, &names, i, m, ctx)?,
                one_sided: m.one_sided.unwrap_or(false),
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
        ("one_sided", m.one_sided.is_some()),
    ];
    for (field, is_set) in given {
        if is_set && !m.ty.fields().contains(&field) {
            let why = match field {
                "one_sided" => " (light crosses a dielectric, so both of its sides are seen: it is two-sided)",
                _ => "",
            };
            return Err(ctx.invalid(
                at(field),
                format!(
                    "does not apply to type {ty}{why} (it takes: {})",
                    m.ty.fields().join(", ")
                ),
            ));
        }
    }
    let roughness = || -> Result<f32, SceneError> {
        match m.roughness {
            Some(a) if a >= MIN_ROUGHNESS as f32 && a <= 1.0 => Ok(a),
            Some(a) => Err(ctx.invalid(
                at("roughness"),
                format!(
                    "must be in [{MIN_ROUGHNESS:e}, 1] (got {}): below {MIN_ROUGHNESS:e} the GGX lobe leaves the range of \
                     32-bit floats; for roughness 0 use type conductor or dielectric",
                    number(a)
                ),
            )),
            None => Err(ctx.invalid(
                at("roughness"),
                format!("missing: type {ty} needs roughness = GGX α in [{MIN_ROUGHNESS:e}, 1]"),
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
                Some(v) if v >= MIN_INDEX as f32 && v.is_finite() => v,
                Some(v) => {
                    return Err(ctx.invalid(
                        at("int_ior"),
                        format!(
                            "must be a finite number of at least {MIN_INDEX:e} (got {}): smaller indices leave the \
                             range of 32-bit floats in the Fresnel terms",
                            number(v)
                        ),
                    ));
                }
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

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::super::{Material, Scene};

    /// `MINI` plus `materials` (TOML) and a cube named "box" of material `box_material`.
    fn with(materials: &str, box_material: &str) -> String {
        format!(
            "{MINI}\n{materials}\n[[shape]]\nname = \"box\"\ntype = \"cube\"\nmaterial = \"{box_material}\"\nscale = 0.2\n"
        )
    }

    const GLASS: &str = "[[material]]\nname = \"glass\"\ntype = \"dielectric\"\nint_ior = 1.5\n";

    #[test]
    fn every_type_loads_with_its_fields() {
        let text = with(
            concat!(
                "[[material]]\nname = \"gold\"\ntype = \"roughconductor\"\nroughness = 0.3\neta = [0.2, 0.4, 1.4]\nk = [3.6, 2.4, 1.8]\n",
                "[[material]]\nname = \"mirror\"\ntype = \"conductor\"\nspecular_reflectance = 0.9\n",
                "[[material]]\nname = \"glass\"\ntype = \"dielectric\"\nint_ior = 1.5\n",
                "[[material]]\nname = \"water\"\ntype = \"roughdielectric\"\nroughness = 0.1\nint_ior = 1.33\nexterior = \"glass\"\n",
            ),
            "water",
        );
        let s: Scene = load_text("all.toml", &text, &[], &[]).unwrap();
        let m = |n: &str| s.materials.iter().find(|m| m.name == n).unwrap().material.clone();
        assert_eq!(
            m("gold"),
            Material::Conductor {
                roughness: 0.3,
                specular: [1.0; 3],
                ior: Some(([0.2, 0.4, 1.4], [3.6, 2.4, 1.8]))
            }
        );
        assert!(m("mirror").is_delta() && m("glass").is_delta() && !m("water").is_delta());
        let glass = s.materials.iter().position(|m| m.name == "glass").unwrap() as u32;
        assert_eq!(
            m("water"),
            Material::Dielectric {
                roughness: 0.1,
                int_ior: 1.33,
                exterior: Some(glass)
            }
        );
        let water = s.materials.iter().position(|m| m.name == "water").unwrap() as u32;
        assert_eq!(s.exterior_eta(water), 1.5, "the water's outside is the glass's inside");
        assert_eq!(s.exterior_eta(glass), s.eta, "the glass's outside is the medium");
        assert!(!s.diffuse_only());
        assert!(s.materials.iter().all(|m| !m.one_sided), "two-sided unless told");
    }

    /// `one_sided` on diffuse and conductors; `flip_normals` turns a shape's front, and is
    /// refused on a dielectric (its inside would be the rest of the scene).
    #[test]
    fn one_sided_materials_and_flipped_shapes() {
        let text = with(
            "[[material]]\nname = \"front\"\ntype = \"conductor\"\none_sided = true\n",
            "front",
        );
        let s: Scene = load_text("s.toml", &text, &[], &[]).unwrap();
        let front = s.materials.iter().find(|m| m.name == "front").unwrap();
        assert!(front.one_sided);
        let flipped = load_text(
            "f.toml",
            &text.replace("scale = 0.2", "scale = 0.2\nflip_normals = true"),
            &[],
            &[],
        )
        .unwrap();
        let b = flipped.shapes.iter().position(|s| s.name == "box").unwrap();
        let (t0, t1) = (s.shapes[b].first_tri as usize, flipped.shapes[b].first_tri as usize);
        let tri = |s: &Scene, t: usize| s.geometry.indices[t];
        assert_eq!(tri(&flipped, t1), [tri(&s, t0)[0], tri(&s, t0)[2], tri(&s, t0)[1]]);
        // the box's outside is its front: from the outside it is lit, from within black
        let t = s.shapes[b].first_tri;
        let towards = s.geometry.positions[s.geometry.indices[t as usize][0] as usize] * 2.0;
        assert!(!s.behind_one_sided(t, towards) && s.behind_one_sided(t, -towards));
        assert!(flipped.behind_one_sided(t, towards) && !flipped.behind_one_sided(t, -towards));
        let glass = with(GLASS, "glass").replace("scale = 0.2", "scale = 0.2\nflip_normals = true");
        expect_err(
            "g.toml",
            &glass,
            &[],
            &["shape[", "\"box\": field 'flip_normals'", "dielectric", "inside it"],
        );
    }

    /// Each mistake names the file, the material and the field, and says what was expected.
    #[test]
    fn material_errors_name_the_field() {
        let cases: &[(&str, &str, &[&str])] = &[
            (
                "[[material]]\nname = \"m\"\ntype = \"roughconductor\"\n",
                "m",
                &["material[1] \"m\": field 'roughness'", "missing", "[1e-6, 1]"],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"roughconductor\"\nroughness = 0\n",
                "m",
                &["field 'roughness'", "[1e-6, 1]", "type conductor"],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"conductor\"\nroughness = 0.2\n",
                "m",
                &["field 'roughness'", "does not apply to type conductor"],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"diffuse\"\nalbedo = 0.5\nint_ior = 1.5\n",
                "m",
                &["field 'int_ior'", "does not apply to type diffuse", "it takes: albedo"],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"conductor\"\neta = 0.2\n",
                "m",
                &["field 'k'", "missing: eta needs k"],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"dielectric\"\n",
                "m",
                &["field 'int_ior'", "missing"],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"dielectric\"\nint_ior = 1.5\none_sided = true\n",
                "m",
                &["field 'one_sided'", "does not apply to type dielectric", "two-sided"],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"dielectric\"\nint_ior = -1\n",
                "m",
                &["field 'int_ior'", "at least 1e-6", "-1"],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"dielectric\"\nint_ior = 1.3\nexterior = \"white\"\n",
                "m",
                &[
                    "field 'exterior'",
                    "\"white\" is of type diffuse",
                    "must be a dielectric",
                ],
            ),
            (
                "[[material]]\nname = \"m\"\ntype = \"dielectric\"\nint_ior = 1.3\nexterior = \"nope\"\n",
                "m",
                &["field 'exterior'", "nope"],
            ),
            (
                "[[material]]\nname = \"a\"\ntype = \"dielectric\"\nint_ior = 1.3\nexterior = \"b\"\n[[material]]\nname = \"b\"\ntype = \"dielectric\"\nint_ior = 1.5\nexterior = \"a\"\n",
                "a",
                &["material[1] \"a\": field 'exterior'", "ambiguous media", "a -> b -> a"],
            ),
        ];
        for (i, (materials, used, parts)) in cases.iter().enumerate() {
            expect_err(&format!("mat{i}.toml"), &with(materials, used), &[], parts);
        }
        // a dielectric on a rectangle has no inside
        let text = format!("{}{GLASS}", mini_with("material = \"white\"", "material = \"glass\""));
        expect_err(
            "flat_glass.toml",
            &text,
            &[],
            &["shape[0] \"quad\": field 'material'", "needs a closed shape"],
        );
    }

    /// Params of the new kinds: roughness and ior set the material's field (and `--set`
    /// overrides them); each refuses a material it does not apply to, naming it.
    #[test]
    fn roughness_and_ior_params() {
        let rough = "[[material]]\nname = \"frost\"\ntype = \"roughdielectric\"\nroughness = 0.2\nint_ior = 1.5\n";
        let params = "[[param]]\nname = \"a\"\nkind = \"roughness\"\nmaterial = \"frost\"\nvalue = 0.25\n[[param]]\nname = \"n\"\nkind = \"ior\"\nmaterial = \"frost\"\nvalue = 1.4\n";
        let text = format!("{}{params}", with(rough, "frost"));
        let s = load_text("params.toml", &text, &[], &[("n".to_string(), 1.45)]).unwrap();
        let m = &s.materials.iter().find(|m| m.name == "frost").unwrap().material;
        assert_eq!(
            *m,
            Material::Dielectric {
                roughness: 0.25,
                int_ior: 1.45,
                exterior: None
            }
        );
        let smooth = format!(
            "{}[[param]]\nname = \"n\"\nkind = \"ior\"\nmaterial = \"glass\"\nvalue = 1.4\n",
            with(GLASS, "glass")
        );
        // a smooth dielectric's index is a parameter too (derivatives through Dirac lobes,
        // `render::check_materials` says when)
        let s = load_text("smooth_ior.toml", &smooth, &[], &[("n".to_string(), 1.45)]).unwrap();
        let m = &s.materials.iter().find(|m| m.name == "glass").unwrap().material;
        assert!(matches!(
            *m,
            Material::Dielectric {
                roughness: 0.0,
                int_ior: 1.45,
                ..
            }
        ));
        let diffuse = format!(
            "{}[[param]]\nname = \"n\"\nkind = \"ior\"\nmaterial = \"white\"\nvalue = 1.4\n",
            with(GLASS, "glass")
        );
        expect_err(
            "diffuse_ior.toml",
            &diffuse,
            &[],
            &[
                "param[0] \"n\": field 'material'",
                "type diffuse",
                "dielectric or roughdielectric",
            ],
        );
        let albedo = format!(
            "{}[[param]]\nname = \"g\"\nkind = \"albedo\"\nmaterial = \"glass\"\nvalue = 0.4\n",
            with(GLASS, "glass")
        );
        expect_err(
            "glass_albedo.toml",
            &albedo,
            &[],
            &[
                "param[0] \"g\": field 'material'",
                "applies to diffuse materials (albedo) and conductors",
            ],
        );
        let bad = format!("{}{params}", with(rough, "frost")).replace("value = 0.25", "value = 1.5");
        expect_err(
            "rough_range.toml",
            &bad,
            &[],
            &["param[0] \"a\": field 'value'", "[1e-6, 1]"],
        );
    }
}
