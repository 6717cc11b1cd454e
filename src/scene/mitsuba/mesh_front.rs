//! The front side Mitsuba 3 gives an OBJ or PLY mesh that it shades with vertex normals
//! (`face_normals` not true): a face is front on the side its vertex normals point to
//! (Mitsuba's emitters and one-sided BSDFs take their cosines in the shading frame), and
//! those normals turn with `to_world` as normals, so a mirror keeps them. A file without
//! normals gets them from its world-space winding, as with `face_normals`. Ours is always the
//! winding's side (`scene/shapes.rs`), so the importer reads the file's normals to set
//! `flip_normals` where a side matters (until the forty-fourth session a mesh whose normals
//! point against its winding emitted and reflected on the other side than in Mitsuba:
//! helper 41).

use crate::scene::ply::{indices, scalar};
use crate::scene::shapes::face_arities;
use glam::DVec3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::DefaultElement;
use std::path::Path;

/// How a mesh file's vertex normals lie against its faces' winding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StoredNormals {
    /// The file has none.
    None,
    /// Every face's normals point to its winding's side.
    WithWinding,
    /// Every face's point to the other side.
    AgainstWinding,
    /// `against` of `faces` point to the other side.
    Mixed { against: usize, faces: usize },
}

/// The stored normals of the OBJ (`ply` false) or PLY file at `path`, against its faces'
/// winding (Newell's normal of each polygon against the sum of its corners' normals). An
/// error says why the file could not be read; the scene loader reports that too.
pub(crate) fn stored_normals(path: &Path, ply: bool) -> Result<StoredNormals, String> {
    use crate::scene::{ply::MAX_PLY_BYTES, read, shapes::MAX_OBJ_BYTES};
    let read = if ply {
        read::read_regular_bytes(path, MAX_PLY_BYTES).map_err(|e| e.to_string())?
    } else {
        read::read_regular_file(path, MAX_OBJ_BYTES)
            .map_err(|e| e.to_string())?
            .into_bytes()
    };
    // (the parsers may panic on a malformed file, as `ply.rs` says)
    let (positions, normals, faces) = std::panic::catch_unwind(|| if ply { read_ply(&read) } else { read_obj(&read) })
        .map_err(|_| "the parser failed on this file".to_string())??;
    if normals.is_empty() {
        return Ok(StoredNormals::None);
    }
    let mut against = 0;
    for face in &faces {
        let mut winding = DVec3::ZERO;
        let mut stored = DVec3::ZERO;
        for (k, &i) in face.iter().enumerate() {
            let (a, b) = (positions[i], positions[face[(k + 1) % face.len()]]);
            winding += a.cross(b);
            stored += normals[i];
        }
        if winding.dot(stored) < 0.0 {
            against += 1;
        }
    }
    Ok(match against {
        0 => StoredNormals::WithWinding,
        n if n == faces.len() => StoredNormals::AgainstWinding,
        n => StoredNormals::Mixed {
            against: n,
            faces: faces.len(),
        },
    })
}

/// Positions, normals (empty when absent) and faces (indices into both) of a mesh file.
type Faces = (Vec<DVec3>, Vec<DVec3>, Vec<Vec<usize>>);

fn read_ply(bytes: &[u8]) -> Result<Faces, String> {
    let mut reader = ply_rs_bw::parser::Reader::new(std::io::Cursor::new(bytes));
    let parser = Parser::<DefaultElement>::new();
    let header = parser.read_header(&mut reader).map_err(|e| e.to_string())?;
    let payload = parser.read_payload(&mut reader, &header).map_err(|e| e.to_string())?;
    let vertices = payload.get("vertex").ok_or("no vertex element")?;
    let xyz = |v: &DefaultElement, k: [&str; 3]| {
        let c = |i: usize| v.get(k[i]).and_then(scalar);
        Some(DVec3::new(c(0)?, c(1)?, c(2)?))
    };
    let positions: Option<Vec<DVec3>> = vertices.iter().map(|v| xyz(v, ["x", "y", "z"])).collect();
    let positions = positions.ok_or("a vertex without x, y, z")?;
    let normals: Vec<DVec3> = vertices.iter().filter_map(|v| xyz(v, ["nx", "ny", "nz"])).collect();
    let normals = if normals.len() == positions.len() {
        normals
    } else {
        Vec::new()
    };
    let mut faces = Vec::new();
    for face in payload.get("face").map(Vec::as_slice).unwrap_or_default() {
        let idx = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .and_then(indices)
            .ok_or("a face without a vertex_indices list")?;
        faces.push(checked(&idx, positions.len())?);
    }
    Ok((positions, normals, faces))
}

fn read_obj(bytes: &[u8]) -> Result<Faces, String> {
    let mut text = std::io::BufReader::new(bytes);
    let (models, _) = tobj::load_obj_buf(&mut text, &crate::scene::shapes::obj_options(), |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| e.to_string())?;
    let (mut positions, mut normals, mut faces) = (Vec::new(), Vec::new(), Vec::new());
    let mut all_have_normals = true;
    for m in &models {
        let base = positions.len();
        let chunks = |v: &[f64]| -> Vec<DVec3> { v.chunks_exact(3).map(DVec3::from_slice).collect() };
        let p = chunks(&m.mesh.positions);
        let n = chunks(&m.mesh.normals);
        all_have_normals &= n.len() == p.len();
        let count = p.len();
        positions.extend(p);
        normals.extend(n);
        let mut start = 0;
        for a in face_arities(&m.mesh) {
            let idx: Vec<i64> = m.mesh.indices[start..start + a].iter().map(|&i| i as i64).collect();
            start += a;
            faces.push(checked(&idx, count)?.into_iter().map(|i| i + base).collect());
        }
    }
    if !all_have_normals {
        normals.clear();
    }
    Ok((positions, normals, faces))
}

/// The indices of a face, each below `n`.
fn checked(idx: &[i64], n: usize) -> Result<Vec<usize>, String> {
    idx.iter()
        .map(|&i| {
            usize::try_from(i)
                .ok()
                .filter(|&i| i < n)
                .ok_or(format!("a face names vertex {i} of {n}"))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str =
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n";

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    /// A square (one quad, counter-clockwise seen from +z) with normals ±z, and two triangles
    /// whose normals disagree; the same as OBJ.
    #[test]
    fn normals_with_against_and_across_the_winding() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let quad = |nz: [f32; 4], faces: &str| {
            let n = "property float nx\nproperty float ny\nproperty float nz\n";
            let mut t = format!(
                "{HEAD}{n}element face {}\nproperty list uchar int vertex_indices\nend_header\n",
                faces.lines().count()
            );
            for (k, (x, y)) in [(0, 0), (1, 0), (1, 1), (0, 1)].iter().enumerate() {
                t += &format!("{x} {y} 0 0 0 {}\n", nz[k]);
            }
            t + faces
        };
        let one = "4 0 1 2 3\n";
        assert_eq!(
            stored_normals(&write(d, "a.ply", &quad([1.0; 4], one)), true),
            Ok(StoredNormals::WithWinding)
        );
        assert_eq!(
            stored_normals(&write(d, "b.ply", &quad([-1.0; 4], one)), true),
            Ok(StoredNormals::AgainstWinding)
        );
        let two = "3 0 1 2\n3 0 2 3\n";
        assert_eq!(
            stored_normals(&write(d, "c.ply", &quad([1.0, 1.0, 1.0, -1.0], two)), true),
            Ok(StoredNormals::WithWinding),
            "a face goes by the sum of its corners' normals"
        );
        assert_eq!(
            stored_normals(
                &write(d, "d.ply", &quad([1.0, 1.0, -1.0, -1.0], "3 0 1 3\n3 1 2 3\n")),
                true
            ),
            Ok(StoredNormals::Mixed { against: 1, faces: 2 })
        );
        let bare = format!(
            "{HEAD}element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n{one}"
        );
        assert_eq!(stored_normals(&write(d, "e.ply", &bare), true), Ok(StoredNormals::None));
        let obj = |vn: &str| format!("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 {vn}\nf 1//1 2//1 3//1 4//1\n");
        assert_eq!(
            stored_normals(&write(d, "f.obj", &obj("1")), false),
            Ok(StoredNormals::WithWinding)
        );
        assert_eq!(
            stored_normals(&write(d, "g.obj", &obj("-1")), false),
            Ok(StoredNormals::AgainstWinding)
        );
        let plain = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n";
        assert_eq!(
            stored_normals(&write(d, "h.obj", plain), false),
            Ok(StoredNormals::None)
        );
    }
}
