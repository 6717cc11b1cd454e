//! Raw Embree 3.13 declarations: only what we call, nothing more.
//!
//! Layouts follow `/usr/include/embree3` (3.13.5, where `RTC_MAX_INSTANCE_LEVEL_COUNT = 1` and
//! `RTC_MIN_WIDTH = 0`); the `const` block at the end checks every size, alignment and the
//! offsets that matter against the values a C compiler gives for those headers. C enums are
//! `int`-sized, so they are declared as `c_uint` constants here.
//!
//! Moving to Embree 4 changes this file and `scene.rs` only: `rtcIntersect8` loses the context
//! argument (it takes `RTCIntersectArguments`), the coherent flag moves into those arguments,
//! `RTCHit`/`RTCHit8` gain `instPrimID` (4.4), and the default geometry mask becomes 1.
#![allow(non_camel_case_types, non_snake_case, dead_code)]

use std::ffi::{c_char, c_int, c_uint, c_void};
use std::mem::{align_of, offset_of, size_of};

pub type RTCDevice = *mut c_void;
pub type RTCScene = *mut c_void;
pub type RTCGeometry = *mut c_void;

/// `RTCErrorFunction` (rtcore_device.h): `void (*)(void* userPtr, enum RTCError, const char*)`.
pub type RTCErrorFunction = Option<unsafe extern "C" fn(user_ptr: *mut c_void, code: c_uint, message: *const c_char)>;

/// `RTCFilterFunctionN`; we never install one, the argument struct stays opaque.
pub type RTCFilterFunctionN = Option<unsafe extern "C" fn(args: *const c_void)>;

pub const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;

// enum RTCError
pub const RTC_ERROR_NONE: c_uint = 0;
pub const RTC_ERROR_UNKNOWN: c_uint = 1;
pub const RTC_ERROR_INVALID_ARGUMENT: c_uint = 2;
pub const RTC_ERROR_INVALID_OPERATION: c_uint = 3;
pub const RTC_ERROR_OUT_OF_MEMORY: c_uint = 4;
pub const RTC_ERROR_UNSUPPORTED_CPU: c_uint = 5;
pub const RTC_ERROR_CANCELLED: c_uint = 6;

// enum RTCDeviceProperty (subset)
pub const RTC_DEVICE_PROPERTY_VERSION: c_uint = 0;
pub const RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED: c_uint = 33;
pub const RTC_DEVICE_PROPERTY_RAY_MASK_SUPPORTED: c_uint = 64;
pub const RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED: c_uint = 65;
pub const RTC_DEVICE_PROPERTY_IGNORE_INVALID_RAYS_ENABLED: c_uint = 67;

// enum RTCGeometryType, RTCBufferType, RTCFormat (subset)
pub const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
pub const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
pub const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
pub const RTC_FORMAT_UINT3: c_uint = 0x5003;
pub const RTC_FORMAT_FLOAT3: c_uint = 0x9003;

// enum RTCSceneFlags, RTCBuildQuality, RTCIntersectContextFlags
pub const RTC_SCENE_FLAG_NONE: c_uint = 0;
pub const RTC_SCENE_FLAG_ROBUST: c_uint = 1 << 2;
pub const RTC_BUILD_QUALITY_LOW: c_uint = 0;
pub const RTC_BUILD_QUALITY_MEDIUM: c_uint = 1;
pub const RTC_BUILD_QUALITY_HIGH: c_uint = 2;
pub const RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: c_uint = 0;
pub const RTC_INTERSECT_CONTEXT_FLAG_COHERENT: c_uint = 1;

/// `struct RTCIntersectContext` for one instance level and no minimum width.
#[repr(C)]
pub struct RTCIntersectContext {
    pub flags: c_uint,
    pub filter: RTCFilterFunctionN,
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

#[repr(C, align(64))]
#[derive(Clone, Copy)]
pub struct RTCRay16 {
    pub org_x: [f32; 16],
    pub org_y: [f32; 16],
    pub org_z: [f32; 16],
    pub tnear: [f32; 16],
    pub dir_x: [f32; 16],
    pub dir_y: [f32; 16],
    pub dir_z: [f32; 16],
    pub time: [f32; 16],
    pub tfar: [f32; 16],
    pub mask: [u32; 16],
    pub id: [u32; 16],
    pub flags: [u32; 16],
}

#[repr(C, align(64))]
#[derive(Clone, Copy)]
pub struct RTCHit16 {
    pub Ng_x: [f32; 16],
    pub Ng_y: [f32; 16],
    pub Ng_z: [f32; 16],
    pub u: [f32; 16],
    pub v: [f32; 16],
    pub primID: [u32; 16],
    pub geomID: [u32; 16],
    pub instID: [[u32; 16]; 1],
}

#[repr(C, align(64))]
#[derive(Clone, Copy)]
pub struct RTCRayHit16 {
    pub ray: RTCRay16,
    pub hit: RTCHit16,
}

// Measured with gcc on /usr/include/embree3 (sizeof, _Alignof, offsetof).
const _: () = {
    assert!(size_of::<RTCRay>() == 48 && align_of::<RTCRay>() == 16);
    assert!(size_of::<RTCHit>() == 32 && align_of::<RTCHit>() == 16);
    assert!(size_of::<RTCRayHit>() == 80 && align_of::<RTCRayHit>() == 16);
    assert!(offset_of!(RTCRayHit, hit) == 48);
    assert!(offset_of!(RTCHit, geomID) == 24);
    assert!(offset_of!(RTCRay, tfar) == 32);
    assert!(size_of::<RTCRay8>() == 384 && align_of::<RTCRay8>() == 32);
    assert!(size_of::<RTCHit8>() == 256 && align_of::<RTCHit8>() == 32);
    assert!(size_of::<RTCRayHit8>() == 640 && align_of::<RTCRayHit8>() == 32);
    assert!(offset_of!(RTCRayHit8, hit) == 384);
    assert!(offset_of!(RTCHit8, geomID) == 192);
    assert!(offset_of!(RTCRay8, tfar) == 256);
    assert!(size_of::<RTCRay16>() == 768 && align_of::<RTCRay16>() == 64);
    assert!(size_of::<RTCHit16>() == 512 && align_of::<RTCHit16>() == 64);
    assert!(size_of::<RTCRayHit16>() == 1280 && offset_of!(RTCRayHit16, hit) == 768);
    assert!(offset_of!(RTCHit16, geomID) == 384 && offset_of!(RTCRay16, tfar) == 512);
    assert!(size_of::<RTCIntersectContext>() == 24 && align_of::<RTCIntersectContext>() == 8);
    assert!(offset_of!(RTCIntersectContext, filter) == 8);
    assert!(offset_of!(RTCIntersectContext, instID) == 16);
};

#[link(name = "embree3")]
unsafe extern "C" {
    pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
    pub fn rtcRetainDevice(device: RTCDevice);
    pub fn rtcReleaseDevice(device: RTCDevice);
    pub fn rtcGetDeviceError(device: RTCDevice) -> c_uint;
    pub fn rtcGetDeviceProperty(device: RTCDevice, prop: c_uint) -> isize;
    pub fn rtcSetDeviceErrorFunction(device: RTCDevice, error: RTCErrorFunction, user_ptr: *mut c_void);

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
    pub fn rtcSetSharedGeometryBuffer(
        geometry: RTCGeometry,
        ty: c_uint,
        slot: c_uint,
        format: c_uint,
        ptr: *const c_void,
        byte_offset: usize,
        byte_stride: usize,
        item_count: usize,
    );
    pub fn rtcCommitGeometry(geometry: RTCGeometry);
    pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;

    pub fn rtcIntersect1(scene: RTCScene, context: *mut RTCIntersectContext, rayhit: *mut RTCRayHit);
    pub fn rtcOccluded1(scene: RTCScene, context: *mut RTCIntersectContext, ray: *mut RTCRay);
    /// `valid` points to 8 `int`s (-1 active, 0 inactive), 32-byte aligned like `rayhit`.
    pub fn rtcIntersect8(
        valid: *const c_int,
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        rayhit: *mut RTCRayHit8,
    );
    /// As [`rtcIntersect8`]; a blocked lane comes back with `tfar = -inf`.
    pub fn rtcOccluded8(valid: *const c_int, scene: RTCScene, context: *mut RTCIntersectContext, ray: *mut RTCRay8);
    /// `valid` points to 16 `int`s, 64-byte aligned like `rayhit`.
    pub fn rtcIntersect16(
        valid: *const c_int,
        scene: RTCScene,
        context: *mut RTCIntersectContext,
        rayhit: *mut RTCRayHit16,
    );
    /// As [`rtcIntersect16`]; a blocked lane comes back with `tfar = -inf`.
    pub fn rtcOccluded16(valid: *const c_int, scene: RTCScene, context: *mut RTCIntersectContext, ray: *mut RTCRay16);
}

/// `rtcInitIntersectContext` is `RTC_FORCEINLINE` in `rtcore_ray.h`, not an exported symbol;
/// this is its body for our configuration (one instance level, no minimum width), with the
/// coherence flag set as callers usually do right after.
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
