//! How requested parameters move the scene: the derivative lanes the kernel fills.
//!
//! A primal render has no parameters and this is empty; the plain kernel never reads it.

use crate::kernel::{Real, Spectrum};
use glam::{Mat3, Vec3};

/// Affine velocity field `v(x) = A·x + b` of one shape under one parameter.
#[derive(Clone, Copy, Debug)]
pub struct Velocity {
    pub a: Mat3,
    pub b: Vec3,
}

/// The derivative lanes requested for a render, in lane order.
#[derive(Clone, Debug, Default)]
pub struct Motion {
    /// `fields[k]`: (shape index, velocity) pairs moved by parameter k.
    pub fields: Vec<Vec<(usize, Velocity)>>,
    /// `albedo[k]`: (material index, channel mask) whose albedo is parameter k.
    pub albedo: Vec<Vec<(usize, [bool; 3])>>,
    /// `radiance[k]`: (emitter index, channel mask) whose emission is parameter k.
    pub radiance: Vec<Vec<(usize, [bool; 3])>>,
    /// `eta[k]`: parameter k is the medium's η.
    pub eta: Vec<bool>,
    /// `pulse_offset[k]`: parameter k is this emitter's pulse offset τ (∂S_e/∂τ = ∂S_e/∂d).
    pub pulse_offset: Vec<Option<usize>>,
    /// `roughness[k]`: parameter k is this material's GGX α.
    pub roughness: Vec<Option<u32>>,
    /// `ior[k]`: parameter k is this dielectric's interior index.
    pub ior: Vec<Option<u32>>,
    /// `names[k]`: the `[[param]]` name of parameter k (for messages).
    pub names: Vec<String>,
    /// `table[k * shapes + s]`: summed velocity field of shape s under parameter k (zero where
    /// it does not move), for O(1) lookups in the vertex gather.
    table: Vec<Velocity>,
    shapes: usize,
}

impl Motion {
    pub fn none() -> Self {
        Self::default()
    }

    /// Velocity of world point `x` of `shape` under parameter `k`.
    #[inline]
    pub fn velocity(&self, k: usize, shape: usize, x: Vec3) -> Vec3 {
        match self.table.get(k * self.shapes + shape) {
            Some(v) => v.a * x + v.b,
            None => Vec3::ZERO,
        }
    }

    /// Sets the derivative lanes of a gathered albedo: ∂albedo/∂θ_k is 1 on the channels that
    /// parameter k controls. `prim` indexes `tri_material` (each triangle's material, the
    /// render context's).
    pub fn albedo_derivs<R: Real, const C: usize>(
        &self,
        prim: &[u32; 8],
        tri_material: &[u32],
        s: &mut Spectrum<R, C>,
    ) {
        for (k, targets) in self.albedo.iter().enumerate().take(R::DERIVS) {
            for c in 0..C {
                let mut d = [0.0f32; 8];
                for (i, di) in d.iter_mut().enumerate().take(R::LANES) {
                    let t = prim[i].min(tri_material.len() as u32 - 1) as usize;
                    let m = tri_material[t] as usize;
                    if targets.iter().any(|(tm, ch)| *tm == m && ch[c]) {
                        *di = 1.0;
                    }
                }
                s.0[c] = s.0[c].with_deriv_lanes(k, &d);
            }
        }
    }
}

/// Cross-product matrix [e]× of a unit axis: [e]× v = e × v.
fn cross_matrix(e: Vec3) -> Mat3 {
    Mat3::from_cols(e.cross(Vec3::X), e.cross(Vec3::Y), e.cross(Vec3::Z))
}

impl Motion {
    /// The derivative lanes for parameters `names`, in that order. Errors name the unknown
    /// parameter and list the available ones.
    pub fn build(scene: &crate::scene::Scene, names: &[String]) -> Result<Self, crate::error::Error> {
        use crate::scene::ParamKind;
        let mut m = Motion::default();
        for name in names {
            let Some(p) = scene.params.iter().find(|p| &p.name == name) else {
                return Err(crate::error::Error::UnknownParameter {
                    path: scene.source.clone(),
                    name: name.clone(),
                    available: scene.params.iter().map(|p| p.name.clone()).collect(),
                });
            };
            m.names.push(name.clone());
            let mut fields = Vec::new();
            let mut albedo = Vec::new();
            let mut radiance = Vec::new();
            let mut eta = false;
            let mut offset = None;
            let (mut roughness, mut ior) = (None, None);
            let channels = |c: Option<usize>| std::array::from_fn(|i| c.is_none_or(|c| c == i));
            match p.kind {
                ParamKind::Translate { shape, axis } => {
                    let mut b = Vec3::ZERO;
                    b[axis as usize] = 1.0;
                    fields.push((shape as usize, Velocity { a: Mat3::ZERO, b }));
                }
                ParamKind::Rotate { shape, axis } => {
                    let tr = scene.shapes[shape as usize].transform;
                    let r = tr.rotate_deg * (std::f32::consts::PI / 180.0);
                    let (rx, ry, rz) = (
                        Mat3::from_rotation_x(r.x),
                        Mat3::from_rotation_y(r.y),
                        Mat3::from_rotation_z(r.z),
                    );
                    // d/dα R_a(α) = [e_a]× R_a(α); R = Rz Ry Rx
                    let dr = match axis {
                        crate::scene::Axis::X => rz * ry * cross_matrix(Vec3::X) * rx,
                        crate::scene::Axis::Y => rz * cross_matrix(Vec3::Y) * ry * rx,
                        crate::scene::Axis::Z => cross_matrix(Vec3::Z) * rz * ry * rx,
                    };
                    // x = t + R S x_l  ⇒  ẋ = Ṙ Rᵀ (x − t), per degree
                    let a = dr * tr.rotation().transpose() * (std::f32::consts::PI / 180.0);
                    fields.push((
                        shape as usize,
                        Velocity {
                            a,
                            b: -(a * tr.translate),
                        },
                    ));
                }
                ParamKind::Scale { shape, axis } => {
                    let tr = scene.shapes[shape as usize].transform;
                    let rot = tr.rotation();
                    let k = axis as usize;
                    let mut ek = Vec3::ZERO;
                    ek[k] = 1.0;
                    // x = t + R S x_l  ⇒  ẋ = R e_k e_kᵀ S⁻¹ Rᵀ (x − t)
                    // e_k e_kᵀ S⁻¹: column k is e_k / s_k, the others zero
                    let mut cols = [Vec3::ZERO; 3];
                    cols[k] = ek / tr.scale[k];
                    let proj = Mat3::from_cols(cols[0], cols[1], cols[2]);
                    let a = rot * proj * rot.transpose();
                    fields.push((
                        shape as usize,
                        Velocity {
                            a,
                            b: -(a * tr.translate),
                        },
                    ));
                }
                ParamKind::Albedo { material, channel } => albedo.push((material as usize, channels(channel))),
                ParamKind::Radiance { emitter, channel } => radiance.push((emitter as usize, channels(channel))),
                ParamKind::Eta => eta = true,
                ParamKind::PulseOffset { emitter } => offset = Some(emitter as usize),
                ParamKind::Roughness { material } => roughness = Some(material),
                ParamKind::Ior { material } => ior = Some(material),
            }
            // a shape lying flush on another is met or not by rounding: no derivative
            if let Some(&(shape, _)) = fields.first()
                && let Some(other) = scene.flush_partner(shape)
            {
                return Err(crate::error::Error::Invalid(format!(
                    "{}: the derivative with respect to {name:?}: shape {:?}, which it moves, lies flush on shape {:?} (faces \
                     in one plane, facing the same way, that overlap): which of the two a ray meets there \
                     is left to rounding, so the render has no derivative with respect to moving either; \
                     move one off the other (by a millimetre, say)",
                    scene.source.display(),
                    scene.shapes[shape].name,
                    scene.shapes[other].name
                )));
            }
            m.fields.push(fields);
            m.albedo.push(albedo);
            m.radiance.push(radiance);
            m.eta.push(eta);
            m.pulse_offset.push(offset);
            m.roughness.push(roughness);
            m.ior.push(ior);
        }
        m.shapes = scene.shapes.len();
        m.table = vec![
            Velocity {
                a: Mat3::ZERO,
                b: Vec3::ZERO
            };
            m.fields.len() * m.shapes
        ];
        for (k, fields) in m.fields.iter().enumerate() {
            for (s, v) in fields {
                let t = &mut m.table[k * m.shapes + s];
                t.a += v.a;
                t.b += v.b;
            }
        }
        Ok(m)
    }

    /// Number of derivative lanes.
    pub fn len(&self) -> usize {
        self.fields.len()
    }

    pub fn is_empty(&self) -> bool {
        self.fields.is_empty()
    }

    /// Whether any lane moves geometry.
    pub fn moves_geometry(&self) -> bool {
        self.fields.iter().any(|f| !f.is_empty())
    }

    /// Whether parameter `k` shifts paths in time (geometry, η, an interior index or pulse
    /// offset).
    pub fn shifts_time(&self, k: usize) -> bool {
        !self.fields[k].is_empty() || self.eta[k] || self.ior[k].is_some() || self.pulse_offset[k].is_some()
    }

    /// Sets the derivative lanes of a material gather: ∂α/∂θ_k = 1 on lanes whose material
    /// (`mats`, per lane) is parameter k's roughness, ∂η_int/∂θ_k = 1 where it is parameter
    /// k's ior, and ∂η_ext/∂θ_k = 1 where the exterior medium is: the interior of parameter
    /// k's material, or the scene's medium under an `eta` parameter.
    pub fn material_derivs<R: Real>(
        &self,
        scene: &crate::scene::Scene,
        mats: &[u32; 8],
        alpha: &mut R,
        eta_int: &mut R,
        eta_ext: &mut R,
    ) {
        // per lane: None off dielectrics, Some(exterior material or None for the medium)
        let exterior: [Option<Option<u32>>; 8] = std::array::from_fn(|i| match scene.materials.get(mats[i] as usize) {
            Some(m) => match m.material {
                crate::scene::Material::Dielectric { exterior, .. } => Some(exterior),
                _ => None,
            },
            None => None,
        });
        for k in 0..self.len().min(R::DERIVS) {
            let lanes = |f: &dyn Fn(usize) -> bool| -> [f32; 8] { std::array::from_fn(|i| f(i) as u32 as f32) };
            if let Some(m) = self.roughness[k] {
                *alpha = alpha.with_deriv_lanes(k, &lanes(&|i| mats[i] == m)[..R::LANES]);
            }
            if let Some(m) = self.ior[k] {
                *eta_int = eta_int.with_deriv_lanes(k, &lanes(&|i| mats[i] == m)[..R::LANES]);
            }
            if self.ior[k].is_some() || self.eta[k] {
                let ext = lanes(&|i| match exterior[i] {
                    Some(Some(e)) => self.ior[k] == Some(e),
                    Some(None) => self.eta[k],
                    None => false,
                });
                *eta_ext = eta_ext.with_deriv_lanes(k, &ext[..R::LANES]);
            }
        }
    }

    /// Sets the derivative lanes of an emitted radiance: ∂L/∂θ_k = 1 on the channels of the
    /// emitter that parameter k controls.
    pub fn radiance_derivs<R: Real, const C: usize>(&self, emitter: &[u32; 8], s: &mut Spectrum<R, C>) {
        for (k, targets) in self.radiance.iter().enumerate().take(R::DERIVS) {
            if targets.is_empty() {
                continue;
            }
            for c in 0..C {
                let mut d = [0.0f32; 8];
                for (i, di) in d.iter_mut().enumerate().take(R::LANES) {
                    if targets.iter().any(|(e, ch)| *e as u32 == emitter[i] && ch[c]) {
                        *di = 1.0;
                    }
                }
                s.0[c] = s.0[c].with_deriv_lanes(k, &d);
            }
        }
    }

    /// η as a number carrying ∂η/∂θ_k = 1 on its lane.
    pub fn eta<R: Real>(&self, eta: f32) -> R {
        let mut v = R::splat(eta);
        for (k, &e) in self.eta.iter().enumerate().take(R::DERIVS) {
            if e {
                v = v.with_deriv_lanes(k, &[1.0; 8]);
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::Motion;
    use crate::integrator::testutil::{POSED, POSED_PARAMS, load, param_names, positions_either_side, step};

    /// The velocity field of every pose parameter (translate, rotate, scale; a mirrored
    /// shape's scale) equals the central difference of the loader's own world positions of
    /// every vertex, with the parameter set a step either side by `--set`. So the motion model
    /// and the scene's transform agree on the pivot (the shape's local origin, relative to a
    /// render origin that is not the world's), the order of rotations (Rz·Ry·Rx), degrees,
    /// and scale before rotation; and the other shape does not move.
    ///
    /// Bugs caught: any of those conventions differing between `Motion::build` and
    /// `Transform::apply` (e.g. Rx·Ry·Rz, radians, a pivot at the world origin or at the
    /// file's translate instead of the render-origin-relative one, S⁻¹ on the wrong side),
    /// and a velocity leaking into another shape's entry of the table.
    #[test]
    fn pose_velocities_match_the_loaders_transform() {
        let scene = load(POSED, &[]);
        assert_ne!(
            scene.render_origin, [0.0; 3],
            "the test wants a render origin off the world's"
        );
        let motion = Motion::build(&scene, &param_names(&scene)).unwrap();
        assert_eq!(motion.len(), POSED_PARAMS);
        let eps = f32::EPSILON as f64;
        for (k, p) in scene.params.iter().enumerate() {
            let h = step(&p.kind);
            let [minus, plus] = positions_either_side(POSED, &scene, k, h);
            for (s, shape) in scene.shapes.iter().enumerate() {
                let first = shape.first_vertex as usize;
                for i in first..first + shape.vertex_count as usize {
                    let x = scene.geometry.positions[i];
                    let fd = (plus[i] - minus[i]).as_dvec3() / (2.0 * h);
                    let v = motion.velocity(k, s, x).as_dvec3();
                    // each end is the f64 position rounded to f32 (half an ulp, ≤ 2⁻²⁴·|x|
                    // per coordinate): the difference is off by up to that / h per axis; the
                    // velocity A·x + b itself is good to a few f32 ulps of |A|·|x|
                    let rounding = eps * x.abs().max_element().max(1.0) as f64 * (3f64.sqrt() / h + 8.0);
                    let tol = 1e-4 * fd.length().max(v.length()) + rounding;
                    assert!(
                        (v - fd).length() <= tol,
                        "param {} ({:?}), shape {}, vertex {i} at {x}: velocity {v} vs central difference {fd} (tol {tol:.2e})",
                        p.name,
                        p.kind,
                        shape.name,
                    );
                }
            }
        }
    }

    /// The derivative lanes of a material gather in nested media (scenes/liquid_glass.toml,
    /// params liquid_ior and glass_ior): the liquid's interior index moves with liquid_ior
    /// only, its exterior index (the glass's interior) with glass_ior only; the glass's
    /// interior with glass_ior, its exterior (the scene's medium) with neither; the wall
    /// (diffuse) with none.
    ///
    /// Bugs caught: the exterior lane taken from the material itself or from the medium when
    /// `exterior` names another material, a derivative leaking onto another material's lanes.
    #[test]
    fn nested_media_derivative_lanes() {
        use crate::integrator::testutil::load;
        use crate::kernel::{Dual8, Real};
        let text =
            std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/liquid_glass.toml"))
                .unwrap();
        let scene = load(&text, &[]);
        let motion = Motion::build(&scene, &["liquid_ior".into(), "glass_ior".into()]).unwrap();
        let idx = |n: &str| scene.materials.iter().position(|m| m.name == n).unwrap() as u32;
        let (liquid, glass, wall) = (idx("liquid"), idx("glass"), idx("wall"));
        let mats = [liquid, glass, wall, liquid, glass, wall, liquid, glass];
        let (mut alpha, mut eta_int, mut eta_ext) = (Dual8::<2>::one(), Dual8::<2>::one(), Dual8::<2>::one());
        motion.material_derivs(&scene, &mats, &mut alpha, &mut eta_int, &mut eta_ext);
        for (i, &m) in mats.iter().enumerate() {
            let int = [eta_int.deriv_lane(0, i), eta_int.deriv_lane(1, i)];
            let ext = [eta_ext.deriv_lane(0, i), eta_ext.deriv_lane(1, i)];
            let (want_int, want_ext) = match m {
                m if m == liquid => ([1.0, 0.0], [0.0, 1.0]),
                m if m == glass => ([0.0, 1.0], [0.0, 0.0]),
                _ => ([0.0, 0.0], [0.0, 0.0]),
            };
            assert_eq!((int, ext), (want_int, want_ext), "lane {i} (material {m})");
            assert_eq!([alpha.deriv_lane(0, i), alpha.deriv_lane(1, i)], [0.0, 0.0]);
        }
    }
}
