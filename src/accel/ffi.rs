//! Raw Embree 3.13 declarations: only what we call. Layouts follow `/usr/include/embree3`
//! (RTC_MAX_INSTANCE_LEVEL_COUNT = 1, RTC_MIN_WIDTH = 0) and are checked by the size
//! assertions below.
#![allow(non_camel_case_types, non_snake_case, dead_code)]

use std::ffi::{c_char, c_int, c_uint, c_void};

pub type RTCDevice = *mut c_void;
pub type RTCScene = *mut c_void;
pub type RTCGeometry = *mut c_void;

pub const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;
pub const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
pub const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
pub const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
pub const RTC_FORMAT_UINT3: c_uint = 0x5003;
pub const RTC_FORMAT_FLOAT3: c_uint = 0x9003;
pub const RTC_SCENE_FLAG_ROBUST: c_uint = 1 << 2;
pub const RTC_BUILD_QUALITY_HIGH: c_uint = 2;
pub const RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: c_uint = 0;
pub const RTC_INTERSECT_CONTEXT_FLAG_COHERENT: c_uint = 1;

#[repr(C)]
pub struct RTCIntersectContext {
    pub flags: c_uint,
    pub filter: Option<unsafe extern "C" fn(*const c_void)>,
    pub instID: [c_uint; 1],
}

#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
pub struct RTCRay {
    pub org_x: f32,
    pub org_y: f32,
    pub org_z: f32,
    pub tnear: f32,
    pub dir_x: f32,
    pub dir_y: f32,
    pub dir_z: f32,
    pub time: f32,
    pub tfar: f32,
    pub mask: u32,
    pub id: u32,
    pub flags: u32,
}

#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
pub struct RTCHit {
    pub Ng_x: f32,
    pub Ng_y: f32,
    pub Ng_z: f32,
    pub u: f32,
    pub v: f32,
    pub primID: u32,
    pub geomID: u32,
    pub instID: [u32; 1],
}

#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
pub struct RTCRayHit {
    pub ray: RTCRay,
    pub hit: RTCHit,
}

#[repr(C, align(32))]
#[derive(Clone, Copy, Default)]
pub struct RTCRay8 {
    pub org_x: [f32; 8],
    pub org_y: [f32; 8],
    pub org_z: [f32; 8],
    pub tnear: [f32; 8],
    pub dir_x: [f32; 8],
    pub dir_y: [f32; 8],
    pub dir_z: [f32; 8],
    pub time: [f32; 8],
    pub tfar: [f32; 8],
    pub mask: [u32; 8],
    pub id: [u32; 8],
    pub flags: [u32; 8],
}

#[repr(C, align(32))]
#[derive(Clone, Copy, Default)]
pub struct RTCHit8 {
    pub Ng_x: [f32; 8],
    pub Ng_y: [f32; 8],
    pub Ng_z: [f32; 8],
    pub u: [f32; 8],
    pub v: [f32; 8],
    pub primID: [u32; 8],
    pub geomID: [u32; 8],
    pub instID: [[u32; 8]; 1],
}

#[repr(C, align(32))]
#[derive(Clone, Copy, Default)]
pub struct RTCRayHit8 {
    pub ray: RTCRay8,
    pub hit: RTCHit8,
}

/// The valid mask of an 8-wide query: -1 active, 0 inactive, 32-byte aligned.
#[repr(C, align(32))]
#[derive(Clone, Copy)]
pub struct Valid8(pub [i32; 8]);

const _: () = {
    assert!(std::mem::size_of::<RTCRay>() == 48);
    assert!(std::mem::size_of::<RTCHit>() == 32);
    assert!(std::mem::size_of::<RTCRayHit>() == 80);
    assert!(std::mem::size_of::<RTCRay8>() == 384);
    assert!(std::mem::size_of::<RTCHit8>() == 256);
    assert!(std::mem::size_of::<RTCRayHit8>() == 640);
    assert!(std::mem::align_of::<RTCRayHit8>() == 32);
    assert!(std::mem::align_of::<Valid8>() == 32);
    assert!(std::mem::size_of::<RTCIntersectContext>() == 24);
};

#[link(name = "embree3")]
unsafe extern "C" {
    pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
    pub fn rtcRetainDevice(device: RTCDevice);
    pub fn rtcReleaseDevice(device: RTCDevice);
    pub fn rtcGetDeviceError(device: RTCDevice) -> c_uint;
    pub fn rtcNewScene(device: RTCDevice) -> RTCScene;
    pub fn rtcReleaseScene(scene: RTCScene);
    pub fn rtcSetSceneFlags(scene: RTCScene, flags: c_uint);
    pub fn rtcSetSceneBuildQuality(scene: RTCScene, quality: c_uint);
    pub fn rtcCommitScene(scene: RTCScene);
    pub fn rtcNewGeometry(device: RTCDevice, ty: c_uint) -> RTCGeometry;
    pub fn rtcReleaseGeometry(geometry: RTCGeometry);
    pub fn rtcSetNewGeometryBuffer(
        geometry: RTCGeometry,
        ty: c_uint,
        slot: c_uint,
        format: c_uint,
        byte_stride: usize,
        item_count: usize,
    ) -> *mut c_void;
    pub fn rtcCommitGeometry(geometry: RTCGeometry);
    pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;
    pub fn rtcIntersect1(
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        rayhit: *mut RTCRayHit,
    );
    pub fn rtcOccluded1(scene: RTCScene, context: *mut RTCIntersectContext, ray: *mut RTCRay);
    pub fn rtcIntersect8(
        valid: *const c_int,
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        rayhit: *mut RTCRayHit8,
    );
    pub fn rtcOccluded8(
        valid: *const c_int,
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        ray: *mut RTCRay8,
    );
}

/// `rtcInitIntersectContext` is inline in `rtcore_common.h`; this is its body for our
/// configuration (one instance level, no minimum width).
#[inline(always)]
pub fn init_intersect_context(coherent: bool) -> RTCIntersectContext {
    RTCIntersectContext {
        flags: if coherent {
            RTC_INTERSECT_CONTEXT_FLAG_COHERENT
        } else {
            RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT
        },
        filter: None,
        instID: [RTC_INVALID_GEOMETRY_ID],
    }
}
