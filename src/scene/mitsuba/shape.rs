//! `<shape>` → a `[[shape]]` (geometry and transform): rectangle, cube, sphere, obj, ply.
//! Mitsuba's rectangle ([-1, 1]² in z = 0, normal +z) and cube ([-1, 1]³) are ours, so they
//! keep their vertices; a sphere (`center`, `radius`) becomes our icosphere at
//! [`SPHERE_SUBDIVISIONS`], an approximation (its facets lie inside the true sphere by at
//! most 0.0072% of the radius).

use super::ImportError;
use super::transform::{self, Op, Trs};
use super::xml::{Doc, Props};
use roxmltree::Node;
use toml::{Table, Value};

/// Icosphere level of an imported sphere: 20·4⁶ = 81920 triangles. At level 4 (5120) the
/// facets lie up to 0.11% of the radius inside the sphere, and the first light off a 0.35 m
/// sphere arrived measurably late against mitransient's analytic sphere (a third of one
/// 8 cm bin's onset moved to the next bin, z = −7 over 12 seeds); level 6 and 7 agree.
pub(crate) const SPHERE_SUBDIVISIONS: i64 = 6;

/// A converted shape: its `[[shape]]` fields besides name and material, and how its front
/// side compares with Mitsuba's (which only matters where a side is told apart: area
/// emitters, one-sided materials and dielectrics).
pub(crate) struct Geometry {
    pub table: Table,
    /// Mitsuba's front is the side our shape's front is not (`flip_normals` makes them one).
    pub front_flipped: bool,
    /// The shape's `flip_normals` (for a mesh whose front Mitsuba takes from the file's
    /// normals: `mesh_front.rs`).
    pub flip_normals: bool,
    /// A mesh Mitsuba shades with interpolated vertex normals (`face_normals` not true);
    /// we shade every mesh with its face normals.
    pub smooth_in_mitsuba: bool,
}

pub(crate) fn geometry(doc: &Doc, p: &Props) -> Result<Geometry, ImportError> {
    let node = p.node;
    let ty = doc.req_attr(node, "type")?;
    let (to_world, t_node) = match p.transform(doc, "to_world")? {
        Some(t) => (transform::parse(doc, t)?, t),
        None => (Vec::new(), node),
    };
    let flip_normals = p.boolean(doc, "flip_normals")?.unwrap_or(false);
    let mut t = Table::new();
    let det_negative = |ops: &[Op]| -> Result<bool, ImportError> {
        let m = transform::compose(ops).map_err(|m| doc.err(t_node, m))?;
        Ok(m.determinant() < 0.0)
    };
    let mut smooth = false;
    // Mitsuba's front side against ours (a mirror keeps our front: scene/shapes.rs)
    let (ops, flip_z, front_flipped, supported) = match ty.as_str() {
        // an analytic shape in Mitsuba: its normal is transformed as a normal, and
        // flip_normals is a mirror of local z (exact: z = 0 on the rectangle)
        "rectangle" => (to_world, flip_normals, false, "to_world, flip_normals"),
        // Mitsuba builds its cube with vertex normals, which a mirror keeps outward (helper
        // 41: a mirrored cube emitter shines outward there; this importer turned it until
        // the forty-fourth session)
        "cube" => (to_world, false, flip_normals, "to_world, flip_normals"),
        "obj" | "ply" => {
            let (file, _) = p
                .string(doc, "filename")?
                .ok_or_else(|| doc.err(node, format!("a {ty} shape needs <string name=\"filename\" ...>")))?;
            t.insert("file".into(), file.into());
            // we shade with face normals always; texture coordinates are not used
            smooth = p.boolean(doc, "face_normals")? != Some(true);
            p.ignore(doc, &["flip_tex_coords"])?;
            // with face normals (or none in the file) Mitsuba's front follows the world-space
            // winding, which a mirror reverses; else the file's normals (`mesh_front.rs`)
            let flipped = det_negative(&to_world)? != flip_normals;
            (
                to_world,
                false,
                flipped,
                "filename, to_world, flip_normals, face_normals",
            )
        }
        "sphere" => {
            let center = p.point(doc, "center")?.unwrap_or([0.0; 3]);
            let radius = p.float(doc, "radius")?.unwrap_or(1.0);
            if !(radius > 0.0) {
                let at = p.get(doc, "radius")?.unwrap_or(node);
                return Err(doc.err(at, format!("radius must be > 0 (got {radius})")));
            }
            let mut ops = Vec::new();
            if radius != 1.0 {
                ops.push(Op::Scale([radius; 3]));
            }
            if center != [0.0; 3] {
                ops.push(Op::Translate(center));
            }
            ops.extend(to_world);
            t.insert("subdivisions".into(), SPHERE_SUBDIVISIONS.into());
            // Mitsuba's sphere faces (p − centre)/radius, turned inward by a negative scale
            // (helper 41; only an even scale reaches here, so a mirror is a scale of −r)
            let flipped = det_negative(&ops)? != flip_normals;
            (ops, false, flipped, "center, radius, to_world, flip_normals")
        }
        other => {
            return Err(doc.err(
                node,
                format!("shape type {other:?} is not supported (rectangle, cube, sphere, obj, ply)"),
            ));
        }
    };
    t.insert("type".into(), ty.as_str().into());
    let trs = transform::to_trs(&ops, flip_z).map_err(|m| doc.err(t_node, m))?;
    let [a, b, c] = trs.scale;
    let uneven = |x: f64, y: f64| (x - y).abs() > 1e-9 * x.abs().max(y.abs());
    if ty == "sphere" && (uneven(a, b) || uneven(a, c)) {
        // until the forty-third session this became an ellipsoid without a word (helper 39)
        return Err(doc.err(
            t_node,
            format!(
                "this sphere's to_world scales it unevenly ({a}, {b}, {c}): Mitsuba 3 keeps a sphere round \
                 (its radius from one axis of the transform), this importer would make an ellipsoid; scale it \
                 evenly, or give the ellipsoid as a mesh (obj, ply)"
            ),
        ));
    }
    write_trs(&mut t, &trs);
    p.finish(
        doc,
        &format!("{supported}, one <bsdf> or <ref>, one <emitter type=\"area\">"),
    )?;
    Ok(Geometry {
        table: t,
        front_flipped,
        flip_normals,
        smooth_in_mitsuba: smooth,
    })
}

/// Writes the fields that differ from the defaults.
fn write_trs(t: &mut Table, trs: &Trs) {
    let arr = |v: [f64; 3]| Value::Array(v.iter().map(|x| Value::Float(*x)).collect());
    if trs.translate != [0.0; 3] {
        t.insert("translate".into(), arr(trs.translate));
    }
    if trs.rotate != [0.0; 3] {
        t.insert("rotate".into(), arr(trs.rotate));
    }
    if trs.scale != [1.0; 3] {
        let [a, b, c] = trs.scale;
        let v = if a == b && b == c {
            Value::Float(a)
        } else {
            arr(trs.scale)
        };
        t.insert("scale".into(), v);
    }
}

/// The `<shape>` element's BSDF: an inline `<bsdf>`, a `<ref id>`, or none (Mitsuba's
/// default, a diffuse reflectance of 0.5, or 0 on a shape that emits).
pub(crate) enum BsdfSource<'a, 'input> {
    Inline(Node<'a, 'input>),
    Ref(String, Node<'a, 'input>),
    Default,
}

pub(crate) fn bsdf_source<'a, 'input>(doc: &Doc, p: &Props<'a, 'input>) -> Result<BsdfSource<'a, 'input>, ImportError> {
    let inline = p.nested("bsdf");
    let refs = p.refs();
    match (inline.as_slice(), refs.as_slice()) {
        ([], []) => Ok(BsdfSource::Default),
        ([b], []) => Ok(BsdfSource::Inline(*b)),
        ([], [r]) => {
            if let Some(name) = doc.attr(*r, "name")?
                && name != "bsdf"
            {
                return Err(doc.err(
                    *r,
                    format!("a <ref> named {name:?} in a shape: only BSDFs can be referenced"),
                ));
            }
            Ok(BsdfSource::Ref(doc.req_attr(*r, "id")?, *r))
        }
        _ => Err(doc.err(p.node, "a shape takes one BSDF (an inline <bsdf> or a <ref id=...>)")),
    }
}

#[cfg(test)]
mod tests {
    use super::super::transform::{Op, to_trs};

    #[test]
    fn the_icosphere_of_an_imported_sphere_is_within_its_stated_error() {
        let m = crate::scene::shapes::icosphere(super::SPHERE_SUBDIVISIONS as u32);
        assert_eq!(m.tris.len(), 81920);
        let deepest = m
            .tris
            .iter()
            .map(|t| 1.0 - (t.map(|i| m.positions[i as usize]).iter().sum::<glam::Vec3>() / 3.0).length())
            .fold(0.0f32, f32::max);
        assert!(deepest > 5e-5 && deepest < 7.3e-5, "{deepest}");
    }

    #[test]
    fn sphere_center_and_radius_become_scale_and_translate() {
        let ops = [Op::Scale([0.5; 3]), Op::Translate([1.0, 2.0, 3.0])];
        let t = to_trs(&ops, false).unwrap();
        assert_eq!((t.scale, t.translate, t.rotate), ([0.5; 3], [1.0, 2.0, 3.0], [0.0; 3]));
    }
}
