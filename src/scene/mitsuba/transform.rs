//! Mitsuba's `<transform>`: its operations composed in Mitsuba's order (each one applied
//! after the ones before it: `M = op_n · … · op_1`), and the two ways a composed transform
//! becomes ours: a shape's `translate + Rz·Ry·Rx·(scale ∘ x)` and a camera's position,
//! target and up.

use super::ImportError;
use super::xml::Doc;
use glam::{DMat3, DMat4, DVec3, DVec4};
use roxmltree::Node;

/// One operation of a `<transform>`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Op {
    Translate([f64; 3]),
    /// About the unit vector `axis` (checked when parsed) by `angle` degrees, right-handed.
    Rotate {
        axis: [f64; 3],
        angle: f64,
    },
    Scale([f64; 3]),
    /// The full 4×4 matrix (a 3×3 one is the linear part).
    Matrix(DMat4),
    LookAt {
        origin: [f64; 3],
        target: [f64; 3],
        up: [f64; 3],
    },
}

/// The operations of a `<transform>` element, in the order written.
pub(crate) fn parse(doc: &Doc, node: Node) -> Result<Vec<Op>, ImportError> {
    let mut ops = Vec::new();
    for c in doc.children(node) {
        let op = match c.tag_name().name() {
            "translate" => Op::Translate(doc.vector3(c, Some(0.0))?),
            "scale" => Op::Scale(doc.vector3(c, Some(1.0))?),
            "rotate" => {
                let axis = doc.vector3(c, Some(0.0))?;
                if axis == [0.0; 3] {
                    return Err(doc.err(
                        c,
                        "rotate needs an axis: x=\"1\", y=\"1\", z=\"1\" or value=\"x, y, z\"",
                    ));
                }
                // Mitsuba 3 uses the axis as written (Rodrigues' formula without normalising),
                // so a longer axis gives a matrix that is not a rotation
                if (DVec3::from(axis).length_squared() - 1.0).abs() > 1e-6 {
                    return Err(doc.err(
                        c,
                        format!(
                            "the rotation axis {axis:?} is not a unit vector: Mitsuba 3 does not normalise it, so \
                             its transform is not a rotation; write a unit axis"
                        ),
                    ));
                }
                let angle = doc.number(c, &doc.req_attr(c, "angle")?)?;
                Op::Rotate { axis, angle }
            }
            "matrix" => {
                let v = doc.numbers(c, &doc.req_attr(c, "value")?)?;
                match v.len() {
                    // row-major in the file
                    16 => Op::Matrix(DMat4::from_cols_array(&v.try_into().unwrap_or([0.0; 16])).transpose()),
                    9 => Op::Matrix(DMat4::from_mat3(
                        DMat3::from_cols_array(&v.try_into().unwrap_or([0.0; 9])).transpose(),
                    )),
                    n => return Err(doc.err(c, format!("a matrix needs 16 (or 9) numbers, got {n}"))),
                }
            }
            "lookat" => {
                let p = |k: &str| -> Result<[f64; 3], ImportError> {
                    let v = doc.numbers(c, &doc.req_attr(c, k)?)?;
                    v.try_into()
                        .map_err(|v: Vec<f64>| doc.err(c, format!("'{k}' needs 3 numbers, got {}", v.len())))
                };
                Op::LookAt {
                    origin: p("origin")?,
                    target: p("target")?,
                    up: p("up")?,
                }
            }
            other => {
                return Err(doc.err(
                    c,
                    format!(
                        "unknown transform operation <{other}> (supported: translate, rotate, scale, matrix, lookat)"
                    ),
                ));
            }
        };
        ops.push(op);
    }
    Ok(ops)
}

impl Op {
    /// This operation as a matrix (`Err` for a degenerate look-at).
    pub fn matrix(&self) -> Result<DMat4, String> {
        Ok(match *self {
            Op::Translate(t) => DMat4::from_translation(DVec3::from(t)),
            Op::Scale(s) => DMat4::from_scale(DVec3::from(s)),
            Op::Rotate { axis, angle } => DMat4::from_axis_angle(DVec3::from(axis).normalize(), angle.to_radians()),
            Op::Matrix(m) => m,
            Op::LookAt { origin, target, up } => look_at(origin, target, up)?,
        })
    }
}

/// Mitsuba's look-at frame: columns (left, up', forward, origin) with forward towards the
/// target, left = up × forward, up' = forward × left.
pub(crate) fn look_at(origin: [f64; 3], target: [f64; 3], up: [f64; 3]) -> Result<DMat4, String> {
    let (o, t, u) = (DVec3::from(origin), DVec3::from(target), DVec3::from(up));
    let dir = (t - o).normalize_or_zero();
    if dir == DVec3::ZERO {
        return Err("lookat: origin and target are the same point".into());
    }
    let left = u.cross(dir).normalize_or_zero();
    if left == DVec3::ZERO {
        return Err("lookat: up is zero or parallel to the viewing direction".into());
    }
    let new_up = dir.cross(left);
    Ok(DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        o.extend(1.0),
    ))
}

/// The composed matrix: `op_n · … · op_1` (the first operation written is applied first).
pub(crate) fn compose(ops: &[Op]) -> Result<DMat4, String> {
    ops.iter().try_fold(DMat4::IDENTITY, |m, op| Ok(op.matrix()? * m))
}

/// A shape transform in our terms: `x_world = translate + Rz·Ry·Rx·(scale ∘ x)`, rotations
/// in degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Trs {
    pub translate: [f64; 3],
    pub rotate: [f64; 3],
    pub scale: [f64; 3],
}

/// The operations as our shape transform, after a mirror of local z when `flip_z` (a
/// rectangle's `flip_normals`). Transforms written in our order (a scale, then rotations
/// about x, y and z, then a translation, each at most once) are copied value for value, so
/// the shape is built from the same numbers as the equivalent TOML. Anything else is
/// composed in f64 and decomposed; a transform with shear (a non-uniform scale after a
/// rotation) has no such decomposition and is refused.
pub(crate) fn to_trs(ops: &[Op], flip_z: bool) -> Result<Trs, String> {
    let z = if flip_z { -1.0 } else { 1.0 };
    if let Some(t) = in_our_order(ops) {
        return Ok(Trs {
            scale: [t.scale[0], t.scale[1], t.scale[2] * z],
            ..t
        });
    }
    let m = compose(ops)? * DMat4::from_scale(DVec3::new(1.0, 1.0, z));
    decompose(&m)
}

/// Copies the values of a transform written as scale, rotate x, rotate y, rotate z,
/// translate (each optional, at most once, in this order).
fn in_our_order(ops: &[Op]) -> Option<Trs> {
    let mut t = Trs {
        translate: [0.0; 3],
        rotate: [0.0; 3],
        scale: [1.0; 3],
    };
    // stages: 0 scale, 1..=3 rotations about x, y, z, 4 translate; strictly increasing
    let mut next_allowed = 0;
    for op in ops {
        let stage = match *op {
            Op::Scale(s) => {
                t.scale = s;
                0
            }
            Op::Rotate { axis, angle } => {
                let nonzero: Vec<usize> = (0..3).filter(|&i| axis[i] != 0.0).collect();
                let [i] = nonzero.as_slice() else { return None };
                t.rotate[*i] = if axis[*i] > 0.0 { angle } else { -angle };
                1 + *i
            }
            Op::Translate(v) => {
                t.translate = v;
                4
            }
            _ => return None,
        };
        if stage < next_allowed {
            return None;
        }
        next_allowed = stage + 1;
    }
    Some(t)
}

/// `m = T · Rz·Ry·Rx · S` for an affine `m` whose linear part has orthogonal columns.
pub(crate) fn decompose(m: &DMat4) -> Result<Trs, String> {
    if m.row(3) != DVec4::new(0.0, 0.0, 0.0, 1.0) {
        return Err("the matrix is projective (its last row is not 0, 0, 0, 1)".into());
    }
    let a = DMat3::from_mat4(*m);
    let cols = [a.x_axis, a.y_axis, a.z_axis];
    let mut s = cols.map(|c| c.length());
    if s.iter().any(|&x| !(x > 0.0)) {
        return Err("the transform collapses a direction (a zero scale)".into());
    }
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        if cols[i].dot(cols[j]).abs() > 1e-6 * s[i] * s[j] {
            return Err(
                "the transform shears (a non-uniform scale applied after a rotation): our shapes take scale, rotation and translation only"
                    .into(),
            );
        }
    }
    if a.determinant() < 0.0 {
        s[0] = -s[0];
    }
    let r = DMat3::from_cols(cols[0] / s[0], cols[1] / s[1], cols[2] / s[2]);
    // R = Rz(c)·Ry(b)·Rx(a): R[2][0] = -sin b, R[2][1] = cos b sin a, R[2][2] = cos b cos a,
    // R[1][0] = cos b sin c, R[0][0] = cos b cos c (R[i][j] = row i, column j)
    let at = |i: usize, j: usize| r.col(j)[i];
    let sb = (-at(2, 0)).clamp(-1.0, 1.0);
    let (ax, by, cz) = if sb.abs() > 1.0 - 1e-12 {
        // gimbal lock: fold the z rotation into x
        (f64::atan2(-at(1, 2), at(1, 1)), sb.asin(), 0.0)
    } else {
        (
            f64::atan2(at(2, 1), at(2, 2)),
            sb.asin(),
            f64::atan2(at(1, 0), at(0, 0)),
        )
    };
    let t = m.w_axis.truncate();
    Ok(Trs {
        translate: t.to_array(),
        rotate: [ax.to_degrees(), by.to_degrees(), cz.to_degrees()],
        scale: s,
    })
}

/// Our camera from a sensor's `to_world`: position, target one unit ahead, up. A single
/// `<lookat>` is copied value for value; any other transform must be a rotation and a
/// translation (no scale, no mirror, which would flip the image).
pub(crate) fn camera(ops: &[Op]) -> Result<([f64; 3], [f64; 3], [f64; 3]), String> {
    if let [Op::LookAt { origin, target, up }] = ops {
        look_at(*origin, *target, *up)?;
        return Ok((*origin, *target, *up));
    }
    let m = compose(ops)?;
    let a = DMat3::from_mat4(m);
    if (a.transpose() * a - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .any(|x| x.abs() > 1e-6)
    {
        return Err(
            "a sensor's to_world must be a rotation and a translation (a lookat): scale and shear are not supported"
                .into(),
        );
    }
    if a.determinant() < 0.0 {
        return Err("a sensor's to_world mirrors the image (negative determinant): not supported".into());
    }
    let o = m.w_axis.truncate();
    Ok((o.to_array(), (o + a.z_axis).to_array(), a.y_axis.to_array()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ours(t: &Trs) -> DMat4 {
        let r = t.rotate.map(f64::to_radians);
        DMat4::from_translation(DVec3::from(t.translate))
            * DMat4::from_rotation_z(r[2])
            * DMat4::from_rotation_y(r[1])
            * DMat4::from_rotation_x(r[0])
            * DMat4::from_scale(DVec3::from(t.scale))
    }

    fn close(a: &DMat4, b: &DMat4) -> bool {
        a.abs_diff_eq(*b, 1e-12)
    }

    #[test]
    fn operations_apply_in_the_order_written() {
        // scale first, then rotate, then translate: a point at local x = 1
        let ops = [
            Op::Scale([2.0, 1.0, 1.0]),
            Op::Rotate {
                axis: [0.0, 0.0, 1.0],
                angle: 90.0,
            },
            Op::Translate([0.0, 0.0, 5.0]),
        ];
        let p = compose(&ops).unwrap().transform_point3(DVec3::X);
        assert!(p.abs_diff_eq(DVec3::new(0.0, 2.0, 5.0), 1e-12), "{p}");
        // translate first: the rotation carries the translation with it
        let ops = [
            Op::Translate([1.0, 0.0, 0.0]),
            Op::Rotate {
                axis: [0.0, 0.0, 1.0],
                angle: 90.0,
            },
        ];
        let p = compose(&ops).unwrap().transform_point3(DVec3::ZERO);
        assert!(p.abs_diff_eq(DVec3::Y, 1e-12), "{p}");
    }

    #[test]
    fn rotate_is_right_handed() {
        let m = Op::Rotate {
            axis: [0.0, 1.0, 0.0],
            angle: 90.0,
        }
        .matrix()
        .unwrap();
        // +90° about +y takes +z to +x
        assert!(m.transform_vector3(DVec3::Z).abs_diff_eq(DVec3::X, 1e-12));
    }

    #[test]
    fn our_order_is_copied_exactly() {
        let ops = [
            Op::Scale([0.3, 0.6, 0.3]),
            Op::Rotate {
                axis: [0.0, 1.0, 0.0],
                angle: 17.0,
            },
            Op::Translate([-0.33, 0.6, -0.29]),
        ];
        let t = to_trs(&ops, false).unwrap();
        assert_eq!(
            t,
            Trs {
                translate: [-0.33, 0.6, -0.29],
                rotate: [0.0, 17.0, 0.0],
                scale: [0.3, 0.6, 0.3]
            }
        );
        // a negative axis negates the angle
        let t = to_trs(
            &[Op::Rotate {
                axis: [-1.0, 0.0, 0.0],
                angle: 90.0,
            }],
            false,
        )
        .unwrap();
        assert_eq!(t.rotate, [-90.0, 0.0, 0.0]);
        // flip_z mirrors local z
        assert_eq!(to_trs(&[], true).unwrap().scale, [1.0, 1.0, -1.0]);
    }

    #[test]
    fn other_orders_decompose_to_the_same_matrix() {
        let cases: Vec<Vec<Op>> = vec![
            // z before x: not our order
            vec![
                Op::Rotate {
                    axis: [0.0, 0.0, 1.0],
                    angle: 30.0,
                },
                Op::Rotate {
                    axis: [1.0, 0.0, 0.0],
                    angle: -50.0,
                },
                Op::Translate([1.0, 2.0, 3.0]),
            ],
            // an oblique axis, a uniform scale after it, then a translation before another rotation
            vec![
                Op::Rotate {
                    axis: [0.6, 0.8, 0.0],
                    angle: 40.0,
                },
                Op::Scale([2.0, 2.0, 2.0]),
                Op::Translate([0.5, 0.0, 0.0]),
                Op::Rotate {
                    axis: [0.0, 1.0, 0.0],
                    angle: 120.0,
                },
            ],
            // a mirror
            vec![
                Op::Scale([1.0, -2.0, 3.0]),
                Op::Rotate {
                    axis: [0.0, 0.0, 1.0],
                    angle: 10.0,
                },
            ],
            // gimbal lock
            vec![
                Op::Rotate {
                    axis: [1.0, 0.0, 0.0],
                    angle: 25.0,
                },
                Op::Rotate {
                    axis: [0.0, 1.0, 0.0],
                    angle: 90.0,
                },
            ],
            // a matrix and a lookat
            vec![Op::LookAt {
                origin: [1.0, 2.0, 3.0],
                target: [0.0, 0.0, 0.0],
                up: [0.0, 1.0, 0.0],
            }],
            vec![Op::Matrix(DMat4::from_cols_array(&[
                0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 4.0, 5.0, 6.0, 1.0,
            ]))],
        ];
        for ops in cases {
            let want = compose(&ops).unwrap();
            let t = to_trs(&ops, false).unwrap();
            assert!(close(&ours(&t), &want), "{ops:?}: {t:?}");
        }
    }

    #[test]
    fn shear_is_refused() {
        let ops = [
            Op::Rotate {
                axis: [0.0, 0.0, 1.0],
                angle: 45.0,
            },
            Op::Scale([1.0, 2.0, 1.0]),
        ];
        let e = to_trs(&ops, false).unwrap_err();
        assert!(e.contains("shear"), "{e}");
    }

    #[test]
    fn camera_from_lookat_and_from_a_matrix() {
        let la = Op::LookAt {
            origin: [0.0, 1.0, 3.9],
            target: [0.0, 1.0, 0.0],
            up: [0.0, 1.0, 0.0],
        };
        assert_eq!(
            camera(&[la]).unwrap(),
            ([0.0, 1.0, 3.9], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0])
        );
        // the same frame as a matrix gives the same position, direction and up
        let m = la.matrix().unwrap();
        let (p, t, u) = camera(&[Op::Matrix(m)]).unwrap();
        assert!(DVec3::from(p).abs_diff_eq(DVec3::new(0.0, 1.0, 3.9), 1e-12));
        assert!((DVec3::from(t) - DVec3::from(p)).abs_diff_eq(-DVec3::Z, 1e-12));
        assert!(DVec3::from(u).abs_diff_eq(DVec3::Y, 1e-12));
        // the look-at frame: forward to the target, left = up × forward (-x when looking down -z)
        assert!(m.x_axis.truncate().abs_diff_eq(-DVec3::X, 1e-12));
        let mirrored = [Op::Scale([-1.0, 1.0, 1.0]), la];
        assert!(camera(&mirrored).unwrap_err().contains("mirror"));
    }
}
