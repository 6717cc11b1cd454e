//! The Embree device and its errors.

use super::ffi;
use std::cell::RefCell;
use std::ffi::{CStr, c_char, c_uint, c_void};

/// Why an acceleration structure could not be made.
#[derive(Debug, thiserror::Error)]
pub enum AccelError {
    /// Embree reported an `RTCError` (by code and name), with its message if it gave one.
    #[error("{what}: Embree error {code} ({name}){}", fmt_message(.message))]
    Embree {
        what: &'static str,
        code: u32,
        name: &'static str,
        message: Option<String>,
    },
    /// The mesh handed to [`Accel::build`](super::Accel::build) is unusable.
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// The device configuration string is unusable.
    #[error("invalid Embree device config {config:?}: {reason}")]
    InvalidConfig { config: String, reason: String },
}

fn fmt_message(m: &Option<String>) -> String {
    m.as_deref().map(|m| format!(": {m}")).unwrap_or_default()
}

/// The name of an `RTCError` code.
pub fn error_name(code: u32) -> &'static str {
    match code {
        ffi::RTC_ERROR_NONE => "RTC_ERROR_NONE",
        ffi::RTC_ERROR_UNKNOWN => "RTC_ERROR_UNKNOWN",
        ffi::RTC_ERROR_INVALID_ARGUMENT => "RTC_ERROR_INVALID_ARGUMENT",
        ffi::RTC_ERROR_INVALID_OPERATION => "RTC_ERROR_INVALID_OPERATION",
        ffi::RTC_ERROR_OUT_OF_MEMORY => "RTC_ERROR_OUT_OF_MEMORY",
        ffi::RTC_ERROR_UNSUPPORTED_CPU => "RTC_ERROR_UNSUPPORTED_CPU",
        ffi::RTC_ERROR_CANCELLED => "RTC_ERROR_CANCELLED",
        _ => "unknown RTCError code",
    }
}

thread_local! {
    /// The last message Embree's error callback gave on this thread, with its device.
    static LAST_MESSAGE: RefCell<Option<(usize, String)>> = const { RefCell::new(None) };
}

/// Embree calls this on the thread where the error happened, before the API call returns.
/// It must not unwind (a panic here aborts: `extern "C"`); it only stores the text.
unsafe extern "C" fn record_error(user_ptr: *mut c_void, _code: c_uint, message: *const c_char) {
    if message.is_null() {
        return;
    }
    // SAFETY: Embree passes a NUL-terminated string valid for the duration of the call.
    let text = unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned();
    let _ = LAST_MESSAGE.try_with(|m| {
        if let Ok(mut m) = m.try_borrow_mut() {
            *m = Some((user_ptr as usize, text));
        }
    });
}

/// An Embree device: the context every scene belongs to. Released on drop; an [`Accel`]
/// keeps its own reference, so a device may be dropped while its scenes live on.
///
/// Thread-safety: `Device` is `Send + Sync`. Embree API calls on distinct objects may run
/// concurrently, and the device is reference counted internally. Error codes are kept per
/// thread, which is what `Device::check` relies on.
///
/// [`Accel`]: super::Accel
pub struct Device {
    pub(crate) raw: ffi::RTCDevice,
}

// SAFETY: Embree devices are internally synchronised, reference-counted objects; error
// state is thread-local inside Embree.
unsafe impl Send for Device {}
unsafe impl Sync for Device {}

impl Device {
    /// Creates a device from an Embree config string: `""` for defaults, `"threads=1"` to keep
    /// BVH builds on one TBB thread, `"verbose=1"` for diagnostics. Unknown keys are ignored by
    /// Embree; malformed values are an error.
    pub fn new(config: &str) -> Result<Self, AccelError> {
        let c = std::ffi::CString::new(config).map_err(|_| AccelError::InvalidConfig {
            config: config.into(),
            reason: "contains a NUL byte".into(),
        })?;
        // SAFETY: a valid C string; a null result is handled below.
        let raw = unsafe { ffi::rtcNewDevice(c.as_ptr()) };
        if raw.is_null() {
            // SAFETY: rtcGetDeviceError(NULL) returns the thread-local error of device creation.
            let code = unsafe { ffi::rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(AccelError::InvalidConfig {
                config: config.into(),
                reason: format!("rtcNewDevice failed with {}", error_name(code)),
            });
        }
        // SAFETY: raw is a live device; the callback only touches a thread-local and never
        // unwinds. The user pointer identifies the device in the stored message.
        unsafe { ffi::rtcSetDeviceErrorFunction(raw, Some(record_error), raw) };
        Ok(Self { raw })
    }

    /// Embree's `RTC_DEVICE_PROPERTY_*` query (e.g. version 31305 for 3.13.5).
    pub fn property(&self, prop: u32) -> isize {
        // SAFETY: self.raw is a live device; unknown properties set an error and return 0.
        let v = unsafe { ffi::rtcGetDeviceProperty(self.raw, prop) };
        let _ = self.check("reading a device property");
        v
    }

    /// Takes the device's pending error on this thread, if any, as an `Err`.
    pub(crate) fn check(&self, what: &'static str) -> Result<(), AccelError> {
        // SAFETY: self.raw is a live device.
        let code = unsafe { ffi::rtcGetDeviceError(self.raw) };
        let message = LAST_MESSAGE
            .try_with(|m| m.try_borrow_mut().ok().and_then(|mut m| m.take()))
            .ok()
            .flatten()
            .filter(|(dev, _)| *dev == self.raw as usize)
            .map(|(_, text)| text);
        if code == ffi::RTC_ERROR_NONE {
            Ok(())
        } else {
            Err(AccelError::Embree {
                what,
                code,
                name: error_name(code),
                message,
            })
        }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: we own one reference.
        unsafe { ffi::rtcReleaseDevice(self.raw) }
    }
}
