//! Numbers a scene description can hold: finite 32-bit floats. The loader's scan of the
//! file (`super::load`) and both kinds of `--set` override check their values here, so the
//! two give the same message.

/// What is wrong with `f` as a number of the description ("nan", "1e39, which is outside the
/// range of 32-bit floats", "1e-310, which rounds to 0 as a 32-bit float"), or `None` when it
/// is a finite 32-bit float that is 0 only where `f` is. A value that rounded to 0 was
/// refused as 0 ("fov … (got 0)" for a file's 1e-310) or taken as 0 (a time window's start
/// of 1e-320 printed with 330 digits).
pub(crate) fn not_finite_f32(f: f64) -> Option<String> {
    if f != 0.0 && f as f32 == 0.0 {
        return Some(format!("{f:e}, which rounds to 0 as a 32-bit float"));
    }
    if (f as f32).is_finite() {
        return None;
    }
    Some(if f.is_nan() {
        "nan".to_string()
    } else if f.is_infinite() {
        if f > 0.0 { "inf".to_string() } else { "-inf".to_string() }
    } else {
        format!("{f:e}, which is outside the range of 32-bit floats")
    })
}

/// Refuses a `--set` value the file could not hold either (a number that is not a finite
/// 32-bit float), with the message the file's value would get: both kinds of override
/// (`super::field_set`, `crate::params::resolve`) check their values here.
pub(crate) fn check_override_value(value: f64) -> Result<(), String> {
    match not_finite_f32(value) {
        Some(got) => Err(format!("expected a finite number, got {got}")),
        None => Ok(()),
    }
}
