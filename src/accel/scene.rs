//! A committed triangle scene and its ray queries.

use super::device::{AccelError, Device};
use super::ffi;
use super::packet::{Hit, Hit8, Ray8, Valid8};

/// BVH build quality (`RTCBuildQuality`). `High` adds spatial splits: slower to build,
/// faster to trace.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildQuality {
    Low,
    Medium,
    #[default]
    High,
}

/// Largest coordinate Embree accepts in a ray (`FLT_LARGE` in its `Ray::valid`).
const FLT_LARGE: f32 = 1.844e18;

/// One triangle mesh (geometry 0) in a committed Embree scene, with robust (watertight)
/// traversal unless built with `robust = false` ([`Accel::build_with`]). Owns a reference to its device, so it has no lifetime.
///
/// Thread-safety: `Accel` is `Send + Sync`. After the commit in [`Accel::build`] the scene
/// is never modified, and Embree allows any number of threads to run `rtcIntersect*` and
/// `rtcOccluded*` on a committed scene at once. Traversal runs on the calling thread (TBB is
/// used only for the build). Set [`set_flush_denormals`](super::set_flush_denormals) on every
/// tracing thread.
///
/// Rays: a lane or ray is *valid* if every origin and direction coordinate is at most 1.844e18
/// in magnitude (so not NaN or infinite), `tnear >= 0` and `tnear <= tfar` (`tfar` may be
/// +inf). Invalid rays are reported as misses (not blocked) and never reach Embree. A zero
/// direction is valid and misses.
pub struct Accel {
    device: ffi::RTCDevice,
    scene: ffi::RTCScene,
    triangles: usize,
    vertices: usize,
}

// SAFETY: see the type's documentation; the raw handles are only released in Drop.
unsafe impl Send for Accel {}
unsafe impl Sync for Accel {}

impl std::fmt::Debug for Accel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Accel")
            .field("triangles", &self.triangles)
            .field("vertices", &self.vertices)
            .finish()
    }
}

/// Releases a geometry handle on every exit path of the build.
struct GeometryRef(ffi::RTCGeometry);

impl Drop for GeometryRef {
    fn drop(&mut self) {
        // SAFETY: we own one reference to a non-null geometry.
        unsafe { ffi::rtcReleaseGeometry(self.0) }
    }
}

impl Accel {
    /// Builds the BVH at [`BuildQuality::High`]. See [`Accel::build_with_quality`].
    pub fn build(device: &Device, positions: &[[f32; 3]], indices: &[[u32; 3]]) -> Result<Self, AccelError> {
        Self::build_with_quality(device, positions, indices, BuildQuality::High)
    }

    /// Builds the BVH of one triangle mesh. Triangle `k` is `indices[k]` into `positions`.
    /// Rejects (never panics on) an empty index array, non-finite coordinates and
    /// out-of-range indices. Degenerate triangles are allowed; they are never hit.
    ///
    /// The build uses Embree's TBB threads (all cores unless the device says `threads=N`).
    /// Traversal is robust (watertight); see [`Accel::build_with`] for the faster default mode.
    pub fn build_with_quality(
        device: &Device,
        positions: &[[f32; 3]],
        indices: &[[u32; 3]],
        quality: BuildQuality,
    ) -> Result<Self, AccelError> {
        Self::build_with(device, positions, indices, quality, true)
    }

    /// [`Accel::build_with_quality`], choosing the traversal mode. `robust = true` sets
    /// `RTC_SCENE_FLAG_ROBUST`: watertight triangle tests and conservative traversal, so a ray
    /// through a shared edge or vertex never slips between two triangles. `false` is Embree's
    /// default mode (what Mitsuba 3 uses unless asked otherwise): about 13% faster on the
    /// Cornell box (`cargo bench --bench forward`), and a ray that hits exactly on a shared
    /// edge may very rarely miss both triangles.
    pub fn build_with(
        device: &Device,
        positions: &[[f32; 3]],
        indices: &[[u32; 3]],
        quality: BuildQuality,
        robust: bool,
    ) -> Result<Self, AccelError> {
        validate(positions, indices)?;
        // Drain any stale error of this thread so that checks below report our own.
        let _ = device.check("before building");
        // SAFETY: the device is live; we take a reference that Drop gives back.
        unsafe { ffi::rtcRetainDevice(device.raw) };
        let mut me = Self {
            device: device.raw,
            scene: std::ptr::null_mut(),
            triangles: indices.len(),
            vertices: positions.len(),
        };
        // SAFETY: every handle is checked for null before use; the buffers Embree allocates
        // hold exactly `len` items of 12 bytes (Embree pads vertex buffers for 16-byte loads
        // itself), and we copy exactly that many.
        unsafe {
            me.scene = ffi::rtcNewScene(device.raw);
            if me.scene.is_null() {
                device.check("creating the scene")?;
                return Err(unexpected("rtcNewScene returned null"));
            }
            ffi::rtcSetSceneFlags(
                me.scene,
                if robust {
                    ffi::RTC_SCENE_FLAG_ROBUST
                } else {
                    ffi::RTC_SCENE_FLAG_NONE
                },
            );
            ffi::rtcSetSceneBuildQuality(
                me.scene,
                match quality {
                    BuildQuality::Low => ffi::RTC_BUILD_QUALITY_LOW,
                    BuildQuality::Medium => ffi::RTC_BUILD_QUALITY_MEDIUM,
                    BuildQuality::High => ffi::RTC_BUILD_QUALITY_HIGH,
                },
            );
            device.check("setting scene flags")?;

            let geom = ffi::rtcNewGeometry(device.raw, ffi::RTC_GEOMETRY_TYPE_TRIANGLE);
            if geom.is_null() {
                device.check("creating the triangle geometry")?;
                return Err(unexpected("rtcNewGeometry returned null"));
            }
            let geom = GeometryRef(geom);
            let vb = ffi::rtcSetNewGeometryBuffer(
                geom.0,
                ffi::RTC_BUFFER_TYPE_VERTEX,
                0,
                ffi::RTC_FORMAT_FLOAT3,
                std::mem::size_of::<[f32; 3]>(),
                positions.len(),
            ) as *mut [f32; 3];
            device.check("allocating the vertex buffer")?;
            let ib = ffi::rtcSetNewGeometryBuffer(
                geom.0,
                ffi::RTC_BUFFER_TYPE_INDEX,
                0,
                ffi::RTC_FORMAT_UINT3,
                std::mem::size_of::<[u32; 3]>(),
                indices.len(),
            ) as *mut [u32; 3];
            device.check("allocating the index buffer")?;
            if vb.is_null() || ib.is_null() {
                return Err(unexpected("rtcSetNewGeometryBuffer returned null"));
            }
            std::ptr::copy_nonoverlapping(positions.as_ptr(), vb, positions.len());
            std::ptr::copy_nonoverlapping(indices.as_ptr(), ib, indices.len());
            ffi::rtcCommitGeometry(geom.0);
            device.check("committing the geometry")?;
            let id = ffi::rtcAttachGeometry(me.scene, geom.0);
            device.check("attaching the geometry")?;
            if id != 0 {
                return Err(unexpected("the mesh did not get geometry id 0"));
            }
            drop(geom); // the scene holds its own reference now
            ffi::rtcCommitScene(me.scene);
            device.check("building the BVH")?;
        }
        Ok(me)
    }

    /// Number of triangles (valid `prim` values are `0..triangle_count()`).
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertices
    }

    /// Closest hit along `org + t·dir`, `t ∈ [tnear, tfar]`; `None` on a miss or an invalid ray.
    #[inline]
    pub fn intersect1(&self, org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> Option<Hit> {
        if !ray_ok(org, dir, tnear, tfar) {
            return None;
        }
        let mut rh = rayhit1(org, dir, tnear, tfar);
        let mut ctx = ffi::init_intersect_context(false);
        // SAFETY: the scene is committed and immutable; rh (16-aligned) and ctx live across
        // the call.
        unsafe { ffi::rtcIntersect1(self.scene, &mut ctx, &mut rh) };
        (rh.hit.geomID != ffi::RTC_INVALID_GEOMETRY_ID).then_some(Hit {
            t: rh.ray.tfar,
            prim: rh.hit.primID,
            u: rh.hit.u,
            v: rh.hit.v,
        })
    }

    /// True if anything blocks `org + t·dir`, `t ∈ [tnear, tfar]` (false for an invalid ray).
    #[inline]
    pub fn occluded1(&self, org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> bool {
        if !ray_ok(org, dir, tnear, tfar) {
            return false;
        }
        let mut r = ray1(org, dir, tnear, tfar);
        let mut ctx = ffi::init_intersect_context(false);
        // SAFETY: as in intersect1.
        unsafe { ffi::rtcOccluded1(self.scene, &mut ctx, &mut r) };
        r.tfar == f32::NEG_INFINITY
    }

    /// Closest hits of the active, valid lanes; other lanes report a miss. `coherent` tells
    /// Embree the rays are coherent (e.g. camera rays), which only changes speed.
    #[inline]
    pub fn intersect8(&self, rays: &Ray8, active: [bool; 8], coherent: bool) -> Hit8 {
        let valid = valid_lanes(rays, active);
        if valid.0 == [0; 8] {
            return Hit8::default();
        }
        let mut rh = rayhit8(rays);
        let mut ctx = ffi::init_intersect_context(coherent);
        // SAFETY: valid and rh are 32-byte aligned (repr(align(32))), as Embree requires; the
        // scene is committed. Inactive lanes are not read or written by Embree.
        unsafe { ffi::rtcIntersect8(valid.0.as_ptr(), self.scene, &mut ctx, &mut rh) };
        // Branch-free per lane, so it vectorises: a lane hit if it was valid and got a geometry.
        let hit: [bool; 8] =
            std::array::from_fn(|i| (valid.0[i] != 0) & (rh.hit.geomID[i] != ffi::RTC_INVALID_GEOMETRY_ID));
        Hit8 {
            t: std::array::from_fn(|i| if hit[i] { rh.ray.tfar[i] } else { f32::INFINITY }),
            prim: std::array::from_fn(|i| if hit[i] { rh.hit.primID[i] } else { u32::MAX }),
            u: std::array::from_fn(|i| if hit[i] { rh.hit.u[i] } else { 0.0 }),
            v: std::array::from_fn(|i| if hit[i] { rh.hit.v[i] } else { 0.0 }),
        }
    }

    /// Per lane: true if blocked within `[tnear, tfar]`. Inactive or invalid lanes: false.
    #[inline]
    pub fn occluded8(&self, rays: &Ray8, active: [bool; 8], coherent: bool) -> [bool; 8] {
        let valid = valid_lanes(rays, active);
        if valid.0 == [0; 8] {
            return [false; 8];
        }
        let mut r = ray8(rays);
        let mut ctx = ffi::init_intersect_context(coherent);
        // SAFETY: as in intersect8.
        unsafe { ffi::rtcOccluded8(valid.0.as_ptr(), self.scene, &mut ctx, &mut r) };
        std::array::from_fn(|i| valid.0[i] != 0 && r.tfar[i] == f32::NEG_INFINITY)
    }

    // ---- Bare Embree, for benchmarks -------------------------------------------------------
    //
    // These run Embree on every lane of every packet with no validation and no conversion of
    // results beyond counting, so a benchmark can compare our wrapper with Embree itself on
    // the exact same rays. The only work besides Embree is building its ray structs from
    // `Ray8` (as any caller must) and counting. Rays must be valid (see the type docs).

    /// `rtcIntersect1` on each lane of each packet (incoherent context). Returns the hits.
    pub fn raw_intersect1_batch(&self, rays: &[Ray8]) -> usize {
        let mut hits = 0;
        let mut ctx = ffi::init_intersect_context(false);
        for p in rays {
            for i in 0..8 {
                let (o, d, tn, tf) = p.lane(i);
                let mut rh = rayhit1(o, d, tn, tf);
                // SAFETY: as in intersect1.
                unsafe { ffi::rtcIntersect1(self.scene, &mut ctx, &mut rh) };
                hits += (rh.hit.geomID != ffi::RTC_INVALID_GEOMETRY_ID) as usize;
            }
        }
        hits
    }

    /// `rtcOccluded1` on each lane of each packet (incoherent context). Returns blocked rays.
    pub fn raw_occluded1_batch(&self, rays: &[Ray8]) -> usize {
        let mut blocked = 0;
        let mut ctx = ffi::init_intersect_context(false);
        for p in rays {
            for i in 0..8 {
                let (o, d, tn, tf) = p.lane(i);
                let mut r = ray1(o, d, tn, tf);
                // SAFETY: as in occluded1.
                unsafe { ffi::rtcOccluded1(self.scene, &mut ctx, &mut r) };
                blocked += (r.tfar == f32::NEG_INFINITY) as usize;
            }
        }
        blocked
    }

    /// `rtcIntersect8` on each packet, all lanes active. Returns the hits.
    pub fn raw_intersect8_batch(&self, rays: &[Ray8], coherent: bool) -> usize {
        let valid = Valid8::from([true; 8]);
        let mut hits = 0;
        let mut ctx = ffi::init_intersect_context(coherent);
        for p in rays {
            let mut rh = rayhit8(p);
            // SAFETY: as in intersect8.
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

    /// `rtcIntersect16` on each pair of packets, all lanes active. Returns the hits.
    pub fn raw_intersect16_batch(&self, rays: &[Ray8], coherent: bool) -> usize {
        #[repr(C, align(64))]
        struct V([i32; 16]);
        let valid = V([-1; 16]);
        let mut hits = 0;
        let mut ctx = ffi::init_intersect_context(coherent);
        for p in rays.chunks_exact(2) {
            let mut rh = rayhit16(&p[0], &p[1]);
            // SAFETY: valid and rh are 64-byte aligned, as Embree requires.
            unsafe { ffi::rtcIntersect16(valid.0.as_ptr(), self.scene, &mut ctx, &mut rh) };
            hits += rh
                .hit
                .geomID
                .iter()
                .filter(|&&g| g != ffi::RTC_INVALID_GEOMETRY_ID)
                .count();
        }
        hits
    }

    /// `rtcOccluded16` on each pair of packets, all lanes active. Returns blocked rays.
    pub fn raw_occluded16_batch(&self, rays: &[Ray8], coherent: bool) -> usize {
        #[repr(C, align(64))]
        struct V([i32; 16]);
        let valid = V([-1; 16]);
        let mut blocked = 0;
        let mut ctx = ffi::init_intersect_context(coherent);
        for p in rays.chunks_exact(2) {
            let mut r = rayhit16(&p[0], &p[1]).ray;
            // SAFETY: as above.
            unsafe { ffi::rtcOccluded16(valid.0.as_ptr(), self.scene, &mut ctx, &mut r) };
            blocked += r.tfar.iter().filter(|&&t| t == f32::NEG_INFINITY).count();
        }
        blocked
    }

    /// `rtcOccluded8` on each packet, all lanes active. Returns blocked rays.
    pub fn raw_occluded8_batch(&self, rays: &[Ray8], coherent: bool) -> usize {
        let valid = Valid8::from([true; 8]);
        let mut blocked = 0;
        let mut ctx = ffi::init_intersect_context(coherent);
        for p in rays {
            let mut r = ray8(p);
            // SAFETY: as in occluded8.
            unsafe { ffi::rtcOccluded8(valid.0.as_ptr(), self.scene, &mut ctx, &mut r) };
            blocked += r.tfar.iter().filter(|&&t| t == f32::NEG_INFINITY).count();
        }
        blocked
    }
}

impl Drop for Accel {
    fn drop(&mut self) {
        // SAFETY: we own one reference to the device and, if non-null, one to the scene.
        unsafe {
            if !self.scene.is_null() {
                ffi::rtcReleaseScene(self.scene);
            }
            ffi::rtcReleaseDevice(self.device);
        }
    }
}

fn unexpected(what: &str) -> AccelError {
    AccelError::Embree {
        what: "building the scene",
        code: ffi::RTC_ERROR_UNKNOWN,
        name: "RTC_ERROR_UNKNOWN",
        message: Some(what.into()),
    }
}

fn validate(positions: &[[f32; 3]], indices: &[[u32; 3]]) -> Result<(), AccelError> {
    if indices.is_empty() {
        return Err(AccelError::InvalidMesh("the mesh has no triangles".into()));
    }
    if indices.len() > u32::MAX as usize - 1 {
        return Err(AccelError::InvalidMesh(format!(
            "{} triangles is more than Embree can index",
            indices.len()
        )));
    }
    if let Some(i) = positions.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(AccelError::InvalidMesh(format!(
            "vertex {i} has a non-finite coordinate {:?}",
            positions[i]
        )));
    }
    let n = positions.len() as u64;
    if let Some(t) = indices.iter().position(|t| t.iter().any(|&i| u64::from(i) >= n)) {
        return Err(AccelError::InvalidMesh(format!(
            "triangle {t} indexes vertex {:?}, but there are {n} vertices",
            indices[t]
        )));
    }
    Ok(())
}

#[inline(always)]
fn ray_ok(org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> bool {
    // Written with `&` (not `&&`) so it compiles to straight-line compares; NaN fails all.
    (org[0].abs() <= FLT_LARGE)
        & (org[1].abs() <= FLT_LARGE)
        & (org[2].abs() <= FLT_LARGE)
        & (dir[0].abs() <= FLT_LARGE)
        & (dir[1].abs() <= FLT_LARGE)
        & (dir[2].abs() <= FLT_LARGE)
        & (tnear >= 0.0)
        & (tnear <= tfar)
}

/// `active & ray_ok` per lane, eight lanes at once.
#[inline(always)]
fn valid_lanes(r: &Ray8, active: [bool; 8]) -> Valid8 {
    use wide::f32x8;
    let big = f32x8::splat(FLT_LARGE);
    let fin = |a: &[f32; 8]| f32x8::from(*a).abs().simd_le(big);
    let (tn, tf) = (f32x8::from(r.tnear), f32x8::from(r.tfar));
    let ok = fin(&r.org_x)
        & fin(&r.org_y)
        & fin(&r.org_z)
        & fin(&r.dir_x)
        & fin(&r.dir_y)
        & fin(&r.dir_z)
        & tn.simd_ge(f32x8::ZERO)
        & tn.simd_le(tf);
    let bits = ok.to_bitmask();
    Valid8(std::array::from_fn(|i| {
        if active[i] { -(((bits >> i) & 1) as i32) } else { 0 }
    }))
}

/// An `RTCRay` with mask all-ones (a zero mask misses everything: ray masks are compiled
/// into Debian's Embree).
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

/// An `RTCRayHit` whose hit says "no geometry" until Embree writes one.
#[inline(always)]
fn rayhit1(org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> ffi::RTCRayHit {
    ffi::RTCRayHit {
        ray: ray1(org, dir, tnear, tfar),
        hit: ffi::RTCHit {
            primID: ffi::RTC_INVALID_GEOMETRY_ID,
            geomID: ffi::RTC_INVALID_GEOMETRY_ID,
            instID: [ffi::RTC_INVALID_GEOMETRY_ID],
            ..Default::default()
        },
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
fn rayhit8(r: &Ray8) -> ffi::RTCRayHit8 {
    ffi::RTCRayHit8 {
        ray: ray8(r),
        hit: ffi::RTCHit8 {
            primID: [ffi::RTC_INVALID_GEOMETRY_ID; 8],
            geomID: [ffi::RTC_INVALID_GEOMETRY_ID; 8],
            instID: [[ffi::RTC_INVALID_GEOMETRY_ID; 8]],
            ..Default::default()
        },
    }
}

#[inline(always)]
fn rayhit16(a: &Ray8, b: &Ray8) -> ffi::RTCRayHit16 {
    let cat =
        |x: &[f32; 8], y: &[f32; 8]| -> [f32; 16] { std::array::from_fn(|i| if i < 8 { x[i] } else { y[i - 8] }) };
    ffi::RTCRayHit16 {
        ray: ffi::RTCRay16 {
            org_x: cat(&a.org_x, &b.org_x),
            org_y: cat(&a.org_y, &b.org_y),
            org_z: cat(&a.org_z, &b.org_z),
            tnear: cat(&a.tnear, &b.tnear),
            dir_x: cat(&a.dir_x, &b.dir_x),
            dir_y: cat(&a.dir_y, &b.dir_y),
            dir_z: cat(&a.dir_z, &b.dir_z),
            time: [0.0; 16],
            tfar: cat(&a.tfar, &b.tfar),
            mask: [u32::MAX; 16],
            id: [0; 16],
            flags: [0; 16],
        },
        hit: ffi::RTCHit16 {
            Ng_x: [0.0; 16],
            Ng_y: [0.0; 16],
            Ng_z: [0.0; 16],
            u: [0.0; 16],
            v: [0.0; 16],
            primID: [ffi::RTC_INVALID_GEOMETRY_ID; 16],
            geomID: [ffi::RTC_INVALID_GEOMETRY_ID; 16],
            instID: [[ffi::RTC_INVALID_GEOMETRY_ID; 16]],
        },
    }
}
