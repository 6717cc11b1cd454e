//! PLY meshes (the Stanford polygon format, ASCII or binary) read with `ply-rs-bw`: the
//! `vertex` element's `x`, `y`, `z` and the `face` element's `vertex_indices` (or
//! `vertex_index`) lists; polygons are split into triangles (`polygon::triangulate`: fans where
//! convex, ear clipping where not), every other element and property is ignored.

use glam::DVec3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};
use std::path::Path;

/// The largest PLY file read (as for OBJ).
pub(crate) const MAX_PLY_BYTES: u64 = 2 << 30;

/// A mesh as read: vertex positions and triangles (indices into them).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyMesh {
    /// The `vertex` element's (`x`, `y`, `z`), in the file's units, f64.
    pub positions: Vec<DVec3>,
    /// Triangles (faces split by `polygon::triangulate`), indices into `positions`.
    pub tris: Vec<[u32; 3]>,
}

/// Reads a PLY file; errors say what is wrong with it (the caller names the scene and field).
pub fn load_ply(path: &Path) -> Result<PlyMesh, String> {
    let bytes = super::read::read_regular_bytes(path, MAX_PLY_BYTES).map_err(|e| format!("cannot read it: {e}"))?;
    parse_ply(&bytes)
}

/// [`load_ply`] for bytes already read.
pub fn parse_ply(bytes: &[u8]) -> Result<PlyMesh, String> {
    let parsed = std::panic::catch_unwind(|| {
        // the cursor itself as the parser's reader (`read_ply` reads through a buffer of its
        // own), so its position says where the elements end
        let mut reader = ply_rs_bw::parser::Reader::new(std::io::Cursor::new(bytes));
        let parser = Parser::<DefaultElement>::new();
        let header = parser.read_header(&mut reader)?;
        let payload = parser.read_payload(&mut reader, &header)?;
        Ok::<_, ply_rs_bw::parser::ParseError>((payload, reader.get_ref().position() as usize))
    })
    .map_err(|_| "the PLY parser failed on this file".to_string())?;
    let (payload, read) = parsed.map_err(|e| format!("cannot parse it: {e}"))?;
    // bytes past the elements the header declares: a header that counts too few faces (the
    // rest were dropped silently), or another file appended
    let rest = &bytes[read.min(bytes.len())..];
    if !rest.iter().all(u8::is_ascii_whitespace) {
        return Err(format!(
            "{} bytes follow the elements its header declares (does the header count every vertex and face?)",
            rest.len()
        ));
    }
    let vertices = payload.get("vertex").ok_or("no vertex element")?;
    let mut mesh = PlyMesh::default();
    for (i, v) in vertices.iter().enumerate() {
        let coord = |k: &str| -> Result<f64, String> {
            let c = match v.get(k) {
                Some(Property::Float(x)) => *x as f64,
                Some(Property::Double(x)) => *x,
                Some(p) => scalar(p).ok_or_else(|| format!("vertex {i}: {k} is a list"))?,
                None => return Err(format!("vertex {i} has no {k} property")),
            };
            if !(c as f32).is_finite() {
                return Err(format!("vertex {i}: {k} = {c} is not finite"));
            }
            Ok(c)
        };
        mesh.positions.push(DVec3::new(coord("x")?, coord("y")?, coord("z")?));
    }
    let n = mesh.positions.len();
    let faces = payload.get("face").map(Vec::as_slice).unwrap_or_default();
    for (f, face) in faces.iter().enumerate() {
        let list = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .ok_or_else(|| format!("face {f} has no vertex_indices list"))?;
        let idx = indices(list).ok_or_else(|| format!("face {f}: vertex_indices is not a list of integers"))?;
        if let Some(&bad) = idx.iter().find(|&&k| k < 0 || k as usize >= n) {
            return Err(format!("face {f} names vertex {bad}, but there are {n} vertices"));
        }
        let corners: Vec<DVec3> = idx.iter().map(|&k| mesh.positions[k as usize]).collect();
        let tris = super::polygon::triangulate(&corners).map_err(|e| format!("face {f}: {e}"))?;
        mesh.tris.extend(tris.iter().map(|t| t.map(|k| idx[k] as u32)));
    }
    if mesh.tris.is_empty() {
        return Err("empty mesh: it has no faces with 3 or more vertices".to_string());
    }
    Ok(mesh)
}

/// The type of the first of the `vertex` element's `x`, `y`, `z` stored as an integer (`None`
/// when all three are floats, or the header cannot be read: [`load_ply`] says why then).
/// Mitsuba 3 reads integer coordinates otherwise than as metres (its mesh shrinks to nothing:
/// helper 41), so the XML importer refuses them.
pub fn integer_coordinates(path: &Path) -> Option<String> {
    use ply_rs_bw::ply::{PropertyType, ScalarType};
    let file = super::read::open_regular(path).ok()?;
    let header = std::panic::catch_unwind(move || {
        let mut reader = ply_rs_bw::parser::Reader::new(std::io::BufReader::new(file));
        Parser::<DefaultElement>::new().read_header(&mut reader).ok()
    })
    .ok()??;
    let vertex = header.elements.get("vertex")?;
    ["x", "y", "z"]
        .iter()
        .find_map(|k| match &vertex.properties.get(*k)?.data_type {
            PropertyType::Scalar(ScalarType::Float | ScalarType::Double) => None,
            PropertyType::Scalar(t) => Some(format!("{k} is {}", format!("{t:?}").to_lowercase())),
            PropertyType::List(..) => Some(format!("{k} is a list")),
        })
}

/// A scalar property as f64 (`None` for a list).
pub(crate) fn scalar(p: &Property) -> Option<f64> {
    Some(match p {
        Property::Char(v) => *v as f64,
        Property::UChar(v) => *v as f64,
        Property::Short(v) => *v as f64,
        Property::UShort(v) => *v as f64,
        Property::Int(v) => *v as f64,
        Property::UInt(v) => *v as f64,
        Property::Float(v) => *v as f64,
        Property::Double(v) => *v,
        _ => return None,
    })
}

/// An integer list property (a face's `vertex_indices`) as i64s (`None` for anything else).
pub(crate) fn indices(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUChar(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListShort(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUShort(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListInt(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUInt(v) => v.iter().map(|&x| x as i64).collect(),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";

    #[test]
    fn an_ascii_quad_becomes_a_triangle_fan() {
        let m = parse_ply(QUAD.as_bytes()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.tris, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.positions[2], DVec3::new(1.0, 1.0, 0.0));
    }

    #[test]
    fn a_concave_face_is_split_inside_itself() {
        // an L: (0,0) (2,0) (2,1) (1,1) (1,2) (0,2) written from its inner corner, where a fan
        // from the first corner would leave the polygon
        let l = "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n\
            element face 1\nproperty list uchar int vertex_indices\nend_header\n\
            0 0 0\n2 0 0\n2 1 0\n1 1 0\n1 2 0\n0 2 0\n6 2 3 4 5 0 1\n";
        let m = parse_ply(l.as_bytes()).unwrap();
        let area = crate::scene::polygon::area_facing_z(&m.positions, &m.tris);
        assert!((area - 3.0).abs() < 1e-12, "{area}");
    }

    #[test]
    fn a_binary_mesh_reads_like_its_ascii_twin() {
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
            property double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n"
            .to_vec();
        for v in [[0.0f64, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.5]] {
            v.iter().for_each(|c| b.extend(c.to_le_bytes()));
        }
        b.push(3);
        [0u32, 1, 2].iter().for_each(|i| b.extend(i.to_le_bytes()));
        let m = parse_ply(&b).unwrap();
        assert_eq!(m.tris, vec![[0, 1, 2]]);
        // another face after the one the header declares
        let mut longer = b.clone();
        longer.push(3);
        [2u32, 1, 0].iter().for_each(|i| longer.extend(i.to_le_bytes()));
        let e = parse_ply(&longer).unwrap_err();
        assert!(e.contains("13 bytes follow the elements its header declares"), "{e}");
        assert_eq!(m.positions[2], DVec3::new(0.0, 3.0, 0.5));
    }

    #[test]
    fn bad_files_say_what_is_wrong() {
        let e = |t: &str| parse_ply(t.as_bytes()).unwrap_err();
        assert!(e(&QUAD.replace("4 0 1 2 3", "3 0 1 9")).contains("names vertex 9, but there are 4"));
        assert!(e(&QUAD.replace("1 1 0\n", "1 1e40 0\n")).contains("not finite"));
        assert!(e(&QUAD.replace("4 0 1 2 3", "2 0 1")).contains("no faces"));
        assert!(e("not a ply").contains("cannot parse"));
        let bow = QUAD.replace("4 0 1 2 3", "4 0 2 1 3");
        assert!(e(&bow).contains("face 0: its 4 corners do not bound one simple polygon"));
        assert!(e(&QUAD.replace("property float z\n", "").replace(" 0\n", "\n")).contains("no z property"));
        // a header that counts one face too few (the face was dropped silently) or another
        // file appended; trailing whitespace is kept
        let short = QUAD.replace("element face 1", "element face 0");
        assert!(
            e(&short).contains("bytes follow the elements its header declares"),
            "{}",
            e(&short)
        );
        parse_ply(format!("{QUAD}\n\n").as_bytes()).unwrap();
    }
}
