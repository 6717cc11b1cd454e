//! The Embree device and its errors.

use super::ffi;

/// An Embree failure, by its `RTCError` code, with what we were doing.
#[derive(Debug, thiserror::Error)]
pub enum AccelError {
    #[error("{what}: Embree error {code} ({name})")]
    Embree {
        what: &'static str,
        code: u32,
        name: &'static str,
    },
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
}

pub(crate) fn error_name(code: u32) -> &'static str {
    match code {
        0 => "RTC_ERROR_NONE",
        1 => "RTC_ERROR_UNKNOWN",
        2 => "RTC_ERROR_INVALID_ARGUMENT",
        3 => "RTC_ERROR_INVALID_OPERATION",
        4 => "RTC_ERROR_OUT_OF_MEMORY",
        5 => "RTC_ERROR_UNSUPPORTED_CPU",
        6 => "RTC_ERROR_CANCELLED",
        _ => "unknown code",
    }
}

/// An Embree device (released on drop).
pub struct Device {
    pub(crate) raw: ffi::RTCDevice,
}

// SAFETY: Embree devices are thread-safe objects (reference counted internally).
unsafe impl Send for Device {}
unsafe impl Sync for Device {}

impl Device {
    /// Creates a device with an Embree config string ("" for defaults, e.g. "threads=1").
    pub fn new(config: &str) -> Result<Self, AccelError> {
        let c = std::ffi::CString::new(config)
            .map_err(|_| AccelError::InvalidMesh("device config contains a NUL byte".into()))?;
        // SAFETY: a valid C string; a null result is handled below.
        let raw = unsafe { ffi::rtcNewDevice(c.as_ptr()) };
        if raw.is_null() {
            // SAFETY: rtcGetDeviceError(NULL) returns the thread-local error of device creation.
            let code = unsafe { ffi::rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(AccelError::Embree {
                what: "creating the device",
                code,
                name: error_name(code),
            });
        }
        Ok(Self { raw })
    }

    /// Turns the device's pending error, if any, into an `Err`.
    pub(crate) fn check(&self, what: &'static str) -> Result<(), AccelError> {
        // SAFETY: self.raw is a live device.
        let code = unsafe { ffi::rtcGetDeviceError(self.raw) };
        if code == 0 {
            Ok(())
        } else {
            Err(AccelError::Embree {
                what,
                code,
                name: error_name(code),
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
