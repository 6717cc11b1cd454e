//! `<bsdf>` → a `[[material]]` (without its name): diffuse, (rough) conductor and (rough)
//! dielectric, through a `twosided` wrapper or not. A bare diffuse or conductor is black
//! from behind in Mitsuba, so it becomes `one_sided = true`; inside `twosided` it reflects on
//! both sides (our default). Dielectrics are two-sided in both renderers.

use super::ImportError;
use super::xml::{Colour, Doc, Props};
use roxmltree::Node;
use std::collections::HashMap;
use toml::{Table, Value};

/// The named indices of refraction Mitsuba knows (Hecht, Optics, 4th edition, about 589 nm).
const IOR_PRESETS: [(&str, f64); 23] = [
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

/// The largest exterior index taken as vacuum (air, 1.000277, is; its OPL differs by 0.03%).
const EXT_IOR_AS_VACUUM: f64 = 1.0003;

/// A converted BSDF: the material's fields (`type` and its values).
pub(crate) struct Material {
    pub table: Table,
    pub dielectric: bool,
}

pub(crate) fn colour_value(c: Colour) -> Value {
    match c {
        Colour::Scalar(x) => Value::Float(x),
        Colour::Rgb(v) => Value::Array(v.iter().map(|x| Value::Float(*x)).collect()),
    }
}

/// The top-level `<bsdf id>` elements of the scene (and of the files it includes), each with
/// the document it is in: what a `<ref id>` may name.
pub(crate) type BsdfIds<'d, 'a, 'input> = HashMap<String, (&'d Doc<'a, 'input>, Node<'a, 'input>)>;

/// Converts a `<bsdf>` element; a `<ref id>` inside `twosided` is looked up in `ids`
/// (`through`: the ids followed to get here, so that a cycle is refused).
pub(crate) fn material(doc: &Doc, node: Node, ids: &BsdfIds, through: &[&str]) -> Result<Material, ImportError> {
    let ty = doc.req_attr(node, "type")?;
    let p = doc.props(node);
    if ty == "twosided" {
        let inner = p.nested("bsdf");
        let refs = p.refs();
        let (m, at) = match (inner.as_slice(), refs.as_slice()) {
            ([b], []) => (material(doc, *b, ids, through)?, *b),
            ([], [r]) => {
                let id = doc.req_attr(*r, "id")?;
                if through.contains(&id.as_str()) || doc.attr(node, "id")?.as_deref() == Some(id.as_str()) {
                    return Err(doc.err(
                        *r,
                        format!("<ref id={id:?}> refers back to itself (a cycle of twosided BSDFs)"),
                    ));
                }
                let &(d, b) = ids
                    .get(&id)
                    .ok_or_else(|| doc.err(*r, format!("no <bsdf id={id:?}> in this file")))?;
                let mut through = through.to_vec();
                through.push(&id);
                (material(d, b, ids, &through)?, *r)
            }
            _ => {
                return Err(doc.err(
                    node,
                    format!(
                        "twosided takes exactly one nested <bsdf> or <ref id=...> (got {}); two different sides \
                         are not supported",
                        inner.len() + refs.len()
                    ),
                ));
            }
        };
        p.finish(doc, "one nested <bsdf> or <ref id=...>")?;
        if m.dielectric {
            return Err(doc.err(at, "a dielectric cannot be two-sided (Mitsuba refuses it too)"));
        }
        let mut m = m;
        m.table.remove("one_sided");
        return Ok(m);
    }
    let mut t = Table::new();
    let dielectric = matches!(ty.as_str(), "dielectric" | "roughdielectric");
    let supported = match ty.as_str() {
        "diffuse" => {
            t.insert("type".into(), "diffuse".into());
            let albedo = p.colour(doc, "reflectance")?.unwrap_or(Colour::Scalar(0.5));
            t.insert("albedo".into(), colour_value(albedo));
            "reflectance"
        }
        "conductor" | "roughconductor" => {
            t.insert("type".into(), ty.as_str().into());
            conductor(doc, &p, &mut t)?;
            if ty == "roughconductor" {
                roughness(doc, &p, &mut t)?;
                "material (none, Ag, Al, Au, Cr, Cu), eta, k, specular_reflectance, distribution (ggx), alpha, sample_visible"
            } else {
                "material (none, Ag, Al, Au, Cr, Cu), eta, k, specular_reflectance"
            }
        }
        "dielectric" | "roughdielectric" => {
            t.insert("type".into(), ty.as_str().into());
            let int_ior = ior(doc, &p, "int_ior", "bk7")?;
            let ext_ior = ior(doc, &p, "ext_ior", "air")?;
            if !(1.0..=EXT_IOR_AS_VACUUM).contains(&ext_ior) {
                let at = p.get(doc, "ext_ior")?.unwrap_or(node);
                return Err(doc.err(
                    at,
                    format!(
                        "ext_ior {ext_ior}: only vacuum or air (taken as 1) outside a dielectric is supported; \
                         for nested media write the TOML `exterior` field"
                    ),
                ));
            }
            t.insert("int_ior".into(), Value::Float(int_ior));
            for k in ["specular_reflectance", "specular_transmittance"] {
                if let Some(c) = p.colour(doc, k)?
                    && c != Colour::Scalar(1.0)
                    && c != Colour::Rgb([1.0; 3])
                {
                    let at = p.get(doc, k)?.unwrap_or(node);
                    return Err(doc.err(at, format!("{k} other than 1 is not supported on dielectrics")));
                }
            }
            if ty == "roughdielectric" {
                roughness(doc, &p, &mut t)?;
                "int_ior, ext_ior (vacuum or air), distribution (ggx), alpha, sample_visible"
            } else {
                "int_ior, ext_ior (vacuum or air)"
            }
        }
        "thindielectric" => {
            return Err(doc.err(
                node,
                "thindielectric is not supported (use dielectric on a closed shape)",
            ));
        }
        other => {
            return Err(doc.err(
                node,
                format!(
                    "bsdf type {other:?} is not supported (supported: diffuse, conductor, roughconductor, \
                     dielectric, roughdielectric, twosided)"
                ),
            ));
        }
    };
    p.finish(doc, supported)?;
    if !dielectric {
        t.insert("one_sided".into(), Value::Boolean(true));
    }
    Ok(Material { table: t, dielectric })
}

fn conductor(doc: &Doc, p: &Props, t: &mut Table) -> Result<(), ImportError> {
    let eta = p.colour(doc, "eta")?;
    let k = p.colour(doc, "k")?;
    let preset = p.string(doc, "material")?;
    match (eta, k) {
        (Some(eta), Some(k)) => {
            if let Some((_, n)) = preset {
                return Err(doc.err(n, "give either a material preset or eta and k, not both"));
            }
            t.insert("eta".into(), colour_value(eta));
            t.insert("k".into(), colour_value(k));
        }
        (None, None) => match preset {
            None => {}
            Some((m, _)) if m == "none" => {}
            Some((m, n)) => {
                let (eta, k) = super::conductors::preset(&m).ok_or_else(|| {
                    let names: Vec<&str> = super::conductors::CONDUCTOR_PRESETS.iter().map(|p| p.0).collect();
                    doc.err(
                        n,
                        format!(
                            "conductor material preset {m:?} is not built in (built in: {}, none): give eta and \
                             k as <rgb>",
                            names.join(", ")
                        ),
                    )
                })?;
                t.insert("eta".into(), colour_value(Colour::Rgb(eta)));
                t.insert("k".into(), colour_value(Colour::Rgb(k)));
            }
        },
        _ => {
            let at = p.get(doc, "eta")?.or(p.get(doc, "k")?).unwrap_or(p.node);
            return Err(doc.err(at, "give both eta and k (or neither)"));
        }
    }
    if let Some(r) = p.colour(doc, "specular_reflectance")? {
        t.insert("specular_reflectance".into(), colour_value(r));
    }
    Ok(())
}

/// GGX α: `distribution` must be "ggx" (Mitsuba's default is Beckmann, which we lack);
/// `alpha`, or `alpha_u` = `alpha_v` (isotropic only); Mitsuba's default α is 0.1.
fn roughness(doc: &Doc, p: &Props, t: &mut Table) -> Result<(), ImportError> {
    match p.string(doc, "distribution")? {
        Some((d, _)) if d == "ggx" => {}
        Some((d, n)) => {
            return Err(doc.err(
                n,
                format!("microfacet distribution {d:?} is not supported (only \"ggx\")"),
            ));
        }
        None => {
            return Err(doc.err(
                p.node,
                "Mitsuba's default microfacet distribution is Beckmann, which is not supported: \
                 add <string name=\"distribution\" value=\"ggx\"/>",
            ));
        }
    }
    let alpha = match (
        p.float(doc, "alpha")?,
        p.float(doc, "alpha_u")?,
        p.float(doc, "alpha_v")?,
    ) {
        (Some(a), None, None) => a,
        (None, Some(u), Some(v)) if u == v => u,
        (None, None, None) => 0.1,
        _ => {
            return Err(doc.err(
                p.node,
                "anisotropic roughness is not supported: give alpha (or alpha_u equal to alpha_v)",
            ));
        }
    };
    if let Some(n) = p.nested("texture").first() {
        return Err(doc.err(*n, "textured roughness is not supported"));
    }
    // visible-normal sampling changes only the noise
    p.ignore(doc, &["sample_visible"])?;
    t.insert("roughness".into(), Value::Float(alpha));
    Ok(())
}

/// An index of refraction: a number or one of Mitsuba's named presets.
fn ior(doc: &Doc, p: &Props, name: &str, default: &str) -> Result<f64, ImportError> {
    let (text, node) = match p.get(doc, name)? {
        None => (default.to_string(), None),
        Some(n) => (doc.req_attr(n, "value")?, Some(n)),
    };
    // a number as <float>, a name as <string> (Mitsuba looks a string up by name only: a
    // <string value="1.6"> is an unknown name there, and was 1.6 here until the
    // forty-fourth session, helper 41)
    match node.map(|n| n.tag_name().name()) {
        Some("float" | "integer") => return doc.number(node.unwrap_or(p.node), &text),
        Some("string") | None => {}
        Some(other) => {
            return Err(doc.err(
                node.unwrap_or(p.node),
                format!("'{name}' must be a <float> or a <string> naming a material (got <{other}>)"),
            ));
        }
    }
    let key = text.trim().to_ascii_lowercase();
    IOR_PRESETS
        .iter()
        .find(|(n, _)| *n == key)
        .map(|(_, v)| *v)
        .ok_or_else(|| {
            let names: Vec<&str> = IOR_PRESETS.iter().map(|(n, _)| *n).collect();
            doc.err(
                node.unwrap_or(p.node),
                format!(
                    "unknown index of refraction {text:?} (a number or one of: {})",
                    names.join(", ")
                ),
            )
        })
}
