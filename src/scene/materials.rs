//! Materials: each `[[material]]` becomes a named diffuse material, its albedo in [0, 1].

use super::context::{Ctx, check_colour};
use super::desc::{MaterialDesc, MaterialType};
use super::error::item_field;
use super::{Material, NamedMaterial, SceneError};

pub(super) fn materials(list: &[MaterialDesc], ctx: &Ctx) -> Result<Vec<NamedMaterial>, SceneError> {
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
