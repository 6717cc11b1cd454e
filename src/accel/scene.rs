//! A committed triangle scene and its ray queries.

use super::device::{AccelError, Device};
use super::ffi;
use super::packet::{Hit8, Ray8};

/// A plain hit: distance along the ray, the triangle's index in the input index array, and
/// Embree's barycentrics (p = (1 − u − v)·p0 + u·p1 + v·p2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// One triangle mesh in a committed Embree scene (robust traversal). Holds its own device
/// reference, so it has no lifetime; queries are thread-safe.
pub struct Accel {
    device: ffi::RTCDevice,
    scene: ffi::RTCScene,
    triangles: usize,
}

// SAFETY: after rtcCommitScene, Embree allows concurrent rtcIntersect*/rtcOccluded* calls.
unsafe impl Send for Accel {}
unsafe impl Sync for Accel {}

impl Accel {
    /// Builds the BVH. Rejects empty meshes, non-finite coordinates and out-of-range indices.
    pub fn build(
        device: &Device,
        positions: &[[f32; 3]],
        indices: &[[u32; 3]],
    ) -> Result<Self, AccelError> {
        if indices.is_empty() {
            return Err(AccelError::InvalidMesh("the scene has no triangles".into()));
        }
        if let Some(i) = positions
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return Err(AccelError::InvalidMesh(format!(
                "vertex {i} has a non-finite coordinate {:?}",
                positions[i]
            )));
        }
        let n = positions.len() as u32;
        if let Some(t) = indices.iter().position(|t| t.iter().any(|&i| i >= n)) {
            return Err(AccelError::InvalidMesh(format!(
                "triangle {t} indexes vertex {:?}, but there are {n} vertices",
                indices[t]
            )));
        }
        // SAFETY: every pointer comes from Embree and is checked; buffers are written within
        // the item counts Embree allocated.
        unsafe {
            ffi::rtcRetainDevice(device.raw);
            let me = Self {
                device: device.raw,
                scene: ffi::rtcNewScene(device.raw),
                triangles: indices.len(),
            };
            if me.scene.is_null() {
                device.check("creating the scene")?;
                return Err(AccelError::InvalidMesh("rtcNewScene returned null".into()));
            }
            ffi::rtcSetSceneFlags(me.scene, ffi::RTC_SCENE_FLAG_ROBUST);
            ffi::rtcSetSceneBuildQuality(me.scene, ffi::RTC_BUILD_QUALITY_HIGH);
            let geom = ffi::rtcNewGeometry(device.raw, ffi::RTC_GEOMETRY_TYPE_TRIANGLE);
            device.check("creating the triangle geometry")?;
            let vb = ffi::rtcSetNewGeometryBuffer(
                geom,
                ffi::RTC_BUFFER_TYPE_VERTEX,
                0,
                ffi::RTC_FORMAT_FLOAT3,
                12,
                positions.len(),
            ) as *mut [f32; 3];
            let ib = ffi::rtcSetNewGeometryBuffer(
                geom,
                ffi::RTC_BUFFER_TYPE_INDEX,
                0,
                ffi::RTC_FORMAT_UINT3,
                12,
                indices.len(),
            ) as *mut [u32; 3];
            if vb.is_null() || ib.is_null() {
                ffi::rtcReleaseGeometry(geom);
                device.check("allocating geometry buffers")?;
                return Err(AccelError::InvalidMesh(
                    "Embree could not allocate the geometry buffers".into(),
                ));
            }
            std::ptr::copy_nonoverlapping(positions.as_ptr(), vb, positions.len());
            std::ptr::copy_nonoverlapping(indices.as_ptr(), ib, indices.len());
            ffi::rtcCommitGeometry(geom);
            ffi::rtcAttachGeometry(me.scene, geom);
            ffi::rtcReleaseGeometry(geom);
            ffi::rtcCommitScene(me.scene);
            device.check("building the BVH")?;
            Ok(me)
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// Closest hit along `org + t·dir`, `t ∈ [tnear, tfar]`.
    #[inline]
    pub fn intersect1(&self, org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> Option<Hit> {
        let mut rh = ffi::RTCRayHit {
            ray: ray1(org, dir, tnear, tfar),
            hit: ffi::RTCHit::default(),
        };
        rh.hit.geomID = ffi::RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = ffi::RTC_INVALID_GEOMETRY_ID;
        let mut ctx = ffi::init_intersect_context(false);
        // SAFETY: the scene is committed; rh and ctx are valid for the call.
        unsafe { ffi::rtcIntersect1(self.scene, &mut ctx, &mut rh) };
        (rh.hit.geomID != ffi::RTC_INVALID_GEOMETRY_ID).then_some(Hit {
            t: rh.ray.tfar,
            prim: rh.hit.primID,
            u: rh.hit.u,
            v: rh.hit.v,
        })
    }

    /// True if anything blocks `org + t·dir`, `t ∈ [tnear, tfar]`.
    #[inline]
    pub fn occluded1(&self, org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> bool {
        let mut r = ray1(org, dir, tnear, tfar);
        let mut ctx = ffi::init_intersect_context(false);
        // SAFETY: as above.
        unsafe { ffi::rtcOccluded1(self.scene, &mut ctx, &mut r) };
        r.tfar == f32::NEG_INFINITY
    }

    /// Closest hits of the active lanes; inactive lanes report a miss.
    #[inline]
    pub fn intersect8(&self, rays: &Ray8, active: [bool; 8], coherent: bool) -> Hit8 {
        let valid = valid8(active);
        let mut rh = ffi::RTCRayHit8 {
            ray: ray8(rays),
            hit: ffi::RTCHit8::default(),
        };
        rh.hit.geomID = [ffi::RTC_INVALID_GEOMETRY_ID; 8];
        let mut ctx = ffi::init_intersect_context(coherent);
        // SAFETY: valid and rh are 32-byte aligned (repr(align(32))); the scene is committed.
        unsafe { ffi::rtcIntersect8(valid.0.as_ptr(), self.scene, &mut ctx, &mut rh) };
        let mut out = Hit8::default();
        for i in 0..8 {
            if active[i] && rh.hit.geomID[i] != ffi::RTC_INVALID_GEOMETRY_ID {
                out.t[i] = rh.ray.tfar[i];
                out.prim[i] = rh.hit.primID[i];
                out.u[i] = rh.hit.u[i];
                out.v[i] = rh.hit.v[i];
            }
        }
        out
    }

    /// Per lane: true if blocked. Inactive lanes report false.
    #[inline]
    pub fn occluded8(&self, rays: &Ray8, active: [bool; 8], coherent: bool) -> [bool; 8] {
        let valid = valid8(active);
        let mut r = ray8(rays);
        let mut ctx = ffi::init_intersect_context(coherent);
        // SAFETY: as for intersect8.
        unsafe { ffi::rtcOccluded8(valid.0.as_ptr(), self.scene, &mut ctx, &mut r) };
        std::array::from_fn(|i| active[i] && r.tfar[i] == f32::NEG_INFINITY)
    }

    /// Bare Embree, for benchmarks: `rtcIntersect1` on every lane of every packet, with no
    /// conversion of results. Returns the number of hits.
    pub fn raw_intersect1_batch(&self, rays: &[Ray8]) -> usize {
        let mut hits = 0;
        let mut ctx = ffi::init_intersect_context(false);
        for p in rays {
            for i in 0..8 {
                let mut rh = ffi::RTCRayHit {
                    ray: ray1(
                        [p.org_x[i], p.org_y[i], p.org_z[i]],
                        [p.dir_x[i], p.dir_y[i], p.dir_z[i]],
                        p.tnear[i],
                        p.tfar[i],
                    ),
                    hit: ffi::RTCHit {
                        geomID: ffi::RTC_INVALID_GEOMETRY_ID,
                        ..Default::default()
                    },
                };
                // SAFETY: as for intersect1.
                unsafe { ffi::rtcIntersect1(self.scene, &mut ctx, &mut rh) };
                hits += (rh.hit.geomID != ffi::RTC_INVALID_GEOMETRY_ID) as usize;
            }
        }
        hits
    }

    /// Bare Embree, for benchmarks: `rtcIntersect8` on each packet, all lanes active.
    pub fn raw_intersect8_batch(&self, rays: &[Ray8], coherent: bool) -> usize {
        let valid = valid8([true; 8]);
        let mut hits = 0;
        let mut ctx = ffi::init_intersect_context(coherent);
        for p in rays {
            let mut rh = ffi::RTCRayHit8 {
                ray: ray8(p),
                hit: ffi::RTCHit8::default(),
            };
            rh.hit.geomID = [ffi::RTC_INVALID_GEOMETRY_ID; 8];
            // SAFETY: as for intersect8.
            unsafe { ffi::rtcIntersect8(valid.0.as_ptr(), self.scene, &mut ctx, &mut rh) };
            hits += rh
                .hit
                .geomID
                .iter()
                .filter(|&&g| g != ffi::RTC_INVALID_GEOMETRY_ID)
                .count();
        }
        hits
    }

    /// Bare Embree, for benchmarks: `rtcOccluded8` on each packet. Returns blocked lanes.
    pub fn raw_occluded8_batch(&self, rays: &[Ray8], coherent: bool) -> usize {
        let valid = valid8([true; 8]);
        let mut blocked = 0;
        let mut ctx = ffi::init_intersect_context(coherent);
        for p in rays {
            let mut r = ray8(p);
            // SAFETY: as for occluded8.
            unsafe { ffi::rtcOccluded8(valid.0.as_ptr(), self.scene, &mut ctx, &mut r) };
            blocked += r.tfar.iter().filter(|&&t| t == f32::NEG_INFINITY).count();
        }
        blocked
    }
}

impl Drop for Accel {
    fn drop(&mut self) {
        // SAFETY: we own one reference to each.
        unsafe {
            ffi::rtcReleaseScene(self.scene);
            ffi::rtcReleaseDevice(self.device);
        }
    }
}

#[inline(always)]
fn ray1(org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> ffi::RTCRay {
    ffi::RTCRay {
        org_x: org[0],
        org_y: org[1],
        org_z: org[2],
        tnear,
        dir_x: dir[0],
        dir_y: dir[1],
        dir_z: dir[2],
        time: 0.0,
        tfar,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

#[inline(always)]
fn ray8(r: &Ray8) -> ffi::RTCRay8 {
    ffi::RTCRay8 {
        org_x: r.org_x,
        org_y: r.org_y,
        org_z: r.org_z,
        tnear: r.tnear,
        dir_x: r.dir_x,
        dir_y: r.dir_y,
        dir_z: r.dir_z,
        time: [0.0; 8],
        tfar: r.tfar,
        mask: [u32::MAX; 8],
        id: [0; 8],
        flags: [0; 8],
    }
}

#[inline(always)]
fn valid8(active: [bool; 8]) -> ffi::Valid8 {
    ffi::Valid8(active.map(|a| if a { -1 } else { 0 }))
}
