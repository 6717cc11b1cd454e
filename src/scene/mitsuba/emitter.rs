//! `<emitter>`: `area` (inside a shape: its radiance) and `point` (position, intensity),
//! both emitting a delta pulse at time 0 as mitransient's emitters do. Everything else is
//! refused by name.

use super::ImportError;
use super::bsdf::colour_value;
use super::transform;
use super::xml::{Colour, Doc};
use roxmltree::Node;
use toml::{Table, Value};

/// The emitter types that are refused, with what to do instead.
fn refusal(ty: &str) -> String {
    let hint = match ty {
        "spot" | "projector" => {
            ": for a laser beam write our TOML `laser` emitter (a delta beam: position, direction, power)"
        }
        "constant" | "envmap" | "directional" => ": distant light has no finite time of flight here",
        _ => "",
    };
    format!("emitter type {ty:?} is not supported (area inside a shape, point){hint}")
}

/// An `area` emitter inside a shape: `[[emitter]]` fields besides `name` and `shape`.
pub(crate) fn area(doc: &Doc, node: Node) -> Result<Table, ImportError> {
    let ty = doc.req_attr(node, "type")?;
    if ty == "point" {
        return Err(doc.err(
            node,
            "a point emitter inside a shape: only an area emitter goes inside a <shape>; give the point \
             emitter at the scene's top level",
        ));
    }
    if ty != "area" {
        return Err(doc.err(node, refusal(&ty)));
    }
    let p = doc.props(node);
    let radiance = p
        .emission(doc, "radiance")?
        .ok_or_else(|| doc.err(node, "an area emitter needs its radiance (<rgb name=\"radiance\" ...>)"))?;
    p.finish(doc, "radiance")?;
    let mut t = Table::new();
    t.insert("type".into(), "area".into());
    t.insert("radiance".into(), colour_value(radiance));
    Ok(t)
}

/// A top-level emitter: only `point` (an area emitter belongs inside its shape).
pub(crate) fn top_level(doc: &Doc, node: Node) -> Result<Table, ImportError> {
    let ty = doc.req_attr(node, "type")?;
    match ty.as_str() {
        "point" => {}
        "area" => return Err(doc.err(node, "an area emitter must be nested inside the <shape> it covers")),
        other => return Err(doc.err(node, refusal(other))),
    }
    let p = doc.props(node);
    let intensity = p.emission(doc, "intensity")?.unwrap_or(Colour::Scalar(1.0));
    let position = match (p.point(doc, "position")?, p.transform(doc, "to_world")?) {
        (Some(x), None) => x,
        (None, Some(t)) => {
            let ops = transform::parse(doc, t)?;
            let m = transform::compose(&ops).map_err(|m| doc.err(t, m))?;
            m.w_axis.truncate().to_array()
        }
        (None, None) => [0.0; 3],
        (Some(_), Some(t)) => return Err(doc.err(t, "give either position or to_world, not both")),
    };
    p.finish(doc, "position or to_world, intensity")?;
    let mut t = Table::new();
    t.insert("type".into(), "point".into());
    t.insert(
        "position".into(),
        Value::Array(position.iter().map(|x| Value::Float(*x)).collect()),
    );
    t.insert("intensity".into(), colour_value(intensity));
    Ok(t)
}
