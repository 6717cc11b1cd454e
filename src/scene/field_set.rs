//! `--set PATH=VALUE` for any number in a scene description, not only `[[param]]` values: the
//! film window (`film.start_opl`, `film.bins`), the camera (`camera.fov`,
//! `camera.resolution.0`), the integrator (`integrator.spp`, `integrator.max_bounces`) or a
//! field of a named entry (`material.white.albedo.1`, `shape.box.translate.2`,
//! `emitter.lamp.radiance`).
//!
//! A path is dotted: table keys, then for the arrays of entries (`material`, `shape`,
//! `emitter`, `param`, ...) the entry's `name`, then for arrays of numbers an index. The value
//! replaces the number there (an integer field takes integers only); a missing key of an
//! existing table is added, so optional fields can be set too (`integrator.rr_depth`). The
//! description is then checked as if the file said so: a bad value is reported like a bad value
//! in the file. A name without a dot is a `[[param]]` (`params::resolve`).
//!
//! Values other than numbers ([`apply_text`]) are written as in a TOML file: a word
//! (`--set nlos.scan=exhaustive`, `--set film.channels=rgb`), a quoted string, `true` or
//! `false`, a list (`--set 'nlos.hidden_shapes=["box"]'`, `--set 'nlos.grid=[8, 8]'`) or an
//! inline table (`--set 'film.gate={ type = "box", width_opl = 0.05 }'`). They replace the
//! whole value there, and the description's own checks say whether it fits.

use super::SceneError;
use super::error::Seg;
use serde_json::{Map, Value};
use std::path::Path;

/// Whether `name` addresses a field (a dotted path) rather than a `[[param]]`.
pub(crate) fn is_field_path(name: &str) -> bool {
    name.contains('.')
}

/// Sets each `(path, value)` of `sets` in the description tree `raw`.
pub(crate) fn apply(raw: &mut Value, sets: &[(String, f64)], source: &Path) -> Result<(), SceneError> {
    for (name, value) in sets {
        let err = override_error(source, name);
        super::f32_value::check_override_value(*value).map_err(err)?;
        let slot = find(raw, &segments(name).map_err(err)?).map_err(err)?;
        *slot = number(slot, *value).map_err(err)?;
    }
    Ok(())
}

/// The error about override `name` of the scene at `source`, with a message.
fn override_error<'a>(source: &'a Path, name: &'a str) -> impl Fn(String) -> SceneError + Copy + 'a {
    move |message| SceneError::Override {
        path: source.to_path_buf(),
        name: name.to_string(),
        message,
    }
}

/// The steps of dotted path `name` (none empty).
fn segments(name: &str) -> Result<Vec<&str>, String> {
    let segs: Vec<&str> = name.split('.').collect();
    if segs.iter().any(|s| s.is_empty()) {
        return Err("expected a dotted path such as film.bins or nlos.scan".into());
    }
    Ok(segs)
}

/// Sets each `(path, text)` of `sets` in the description tree `raw`: the value the text is
/// in TOML (module docs), a bare word as a string.
pub(crate) fn apply_text(raw: &mut Value, sets: &[(String, String)], source: &Path) -> Result<(), SceneError> {
    for (name, text) in sets {
        let err = override_error(source, name);
        if !is_field_path(name) {
            return Err(err(format!(
                "{text:?} is not a number: a [[param]] takes numbers; other values set a field of the description, named by its dotted path (nlos.scan, film.gate)"
            )));
        }
        let segs = segments(name).map_err(err)?;
        let value = text_value(text).map_err(err)?;
        *find(raw, &segs).map_err(err)? = value;
    }
    Ok(())
}

/// `text` as the value a TOML file would give after `key = `; a bare word that is not one
/// is that word as a string. Numbers in it must be finite f32s, as in a file.
pub(crate) fn text_value(text: &str) -> Result<Value, String> {
    let text = text.trim();
    let v = match toml::from_str::<toml::Table>(&format!("v = {text}")) {
        Ok(t) if t.len() != 1 => return Err(format!("{text:?} holds more than one TOML value")),
        Ok(mut t) => t.remove("v").unwrap_or(toml::Value::String(text.to_string())),
        Err(_) => return Ok(Value::String(text.to_string())),
    };
    fn check(v: &toml::Value) -> Result<(), String> {
        match v {
            toml::Value::Float(x) => super::f32_value::check_override_value(*x),
            toml::Value::Integer(i) => super::f32_value::check_override_value(*i as f64),
            toml::Value::Array(a) => a.iter().try_for_each(check),
            toml::Value::Table(t) => t.values().try_for_each(check),
            _ => Ok(()),
        }
    }
    check(&v)?;
    serde_json::to_value(&v).map_err(|e| format!("cannot be read: {e}"))
}

/// The value at `segs` (a missing last key of a table is created as null).
fn find<'a>(root: &'a mut Value, segs: &[&str]) -> Result<&'a mut Value, String> {
    let steps = steps(root, segs)?;
    let mut here = root;
    for step in steps {
        here = match (here, step) {
            (Value::Object(map), Seg::Key(k)) => map.entry(k).or_insert(Value::Null),
            (Value::Array(items), Seg::Index(k)) => &mut items[k],
            _ => unreachable!("steps checked each one"),
        };
    }
    Ok(here)
}

/// The steps from `root` to dotted path `segs`, with entries of a list of tables found by
/// name and elements of other lists by index; the last key of a table may be missing.
pub(super) fn steps(root: &Value, segs: &[&str]) -> Result<Vec<Seg>, String> {
    let mut here = Some(root);
    let mut out = Vec::with_capacity(segs.len());
    for (i, &seg) in segs.iter().enumerate() {
        let last = i + 1 == segs.len();
        let shown = if i == 0 {
            "the scene".to_string()
        } else {
            segs[..i].join(".")
        };
        let step = match here {
            Some(Value::Object(map)) => {
                if !map.contains_key(seg) && !last {
                    return Err(format!("{shown} has no {seg:?} (it has {})", keys(map)));
                }
                Seg::Key(seg.to_string())
            }
            Some(Value::Array(items)) if items.iter().all(Value::is_object) => {
                let names: Vec<&str> = items.iter().filter_map(|e| e.get("name")?.as_str()).collect();
                match names.iter().position(|n| *n == seg) {
                    Some(k) => Seg::Index(k),
                    None => {
                        return Err(format!(
                            "{shown} has no entry named {seg:?} (names: {})",
                            names.join(", ")
                        ));
                    }
                }
            }
            Some(Value::Array(items)) => {
                let n = items.len();
                match seg.parse::<usize>() {
                    Ok(k) if k < n => Seg::Index(k),
                    _ => {
                        return Err(format!(
                            "{shown} is a list of {n}: address an element by index 0 to {}",
                            n.max(1) - 1
                        ));
                    }
                }
            }
            _ => return Err(format!("{shown} is a single value: it has no {seg:?}")),
        };
        here = match (&step, here) {
            (Seg::Key(k), Some(Value::Object(map))) => map.get(k),
            (Seg::Index(k), Some(Value::Array(items))) => items.get(*k),
            _ => None,
        };
        out.push(step);
    }
    Ok(out)
}

/// The `--set NAME=TEXT` of `sets` that set the field at `at` ([`super::load`]'s place of an
/// error, as `at_of` writes a path) or a table or list holding it: that field's type error
/// then names the `--set`.
pub(super) fn set_at<'a>(
    raw: &Value,
    sets: &'a [(String, String)],
    at_of: impl Fn(&[Seg]) -> String,
    at: &str,
) -> Option<&'a (String, String)> {
    sets.iter().find(|(name, _)| {
        segments(name)
            .and_then(|segs| steps(raw, &segs))
            .is_ok_and(|steps| within(at, &at_of(&steps)))
    })
}

/// Whether place `at` is place `outer` or inside it, as `error::location` writes places:
/// `film: field 'gate.sigma_opl'` and `camera: field 'resolution[1]'` are inside
/// `film: field 'gate'` and `camera: field 'resolution'`; `shape[7] "box": field 'scale'`
/// is inside `shape[7] "box"`.
fn within(at: &str, outer: &str) -> bool {
    if at == outer {
        return true;
    }
    match outer.strip_suffix('\'') {
        Some(stem) => at
            .strip_prefix(stem)
            .is_some_and(|rest| rest.starts_with('.') || rest.starts_with('[')),
        None => at.strip_prefix(outer).is_some_and(|rest| rest.starts_with(':')),
    }
}

fn keys(map: &Map<String, Value>) -> String {
    map.keys().map(String::as_str).collect::<Vec<_>>().join(", ")
}

/// `value` in the type of the number it replaces (integers stay integers; new keys take
/// integers when `value` is one). A word, a flag or a table takes the number in its place, and
/// the description's own checks say what the field takes (before: "only numbers can be set",
/// for `--set film.channels=5`, where words can be set too).
fn number(old: &Value, value: f64) -> Result<Value, String> {
    // 2⁵³ itself is exact too (`cli::parse_sets` sends larger whole numbers as text)
    let integral = value.fract() == 0.0 && value.abs() <= 2f64.powi(53);
    match old {
        Value::Number(n) if n.is_f64() => Ok(Value::from(value)),
        Value::Array(a) => Err(format!(
            "is a list of {}: set one element (append .0 to .{})",
            a.len(),
            a.len() - 1
        )),
        Value::Number(_) if !integral => Err(format!("expected a whole number, got {value}")),
        _ if integral => Ok(if value < 0.0 {
            Value::from(value as i64)
        } else {
            Value::from(value as u64)
        }),
        _ => Ok(Value::from(value)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_place_is_within_itself_and_its_tables_and_lists() {
        for (at, outer) in [
            ("film: field 'gate'", "film: field 'gate'"),
            ("film: field 'gate.sigma_opl'", "film: field 'gate'"),
            ("camera: field 'resolution[1]'", "camera: field 'resolution'"),
            ("shape[7] \"box\": field 'scale'", "shape[7] \"box\""),
        ] {
            assert!(within(at, outer), "{at} in {outer}");
        }
        for (at, outer) in [
            ("film: field 'gates'", "film: field 'gate'"),
            ("film: field 'bins'", "film: field 'gate'"),
            ("shape[71] \"x\"", "shape[7] \"box\""),
            ("camera: field 'fov'", "film: field 'fov'"),
        ] {
            assert!(!within(at, outer), "{at} not in {outer}");
        }
    }
    use serde_json::json;

    fn set(v: &mut Value, name: &str, x: f64) -> Result<(), String> {
        apply(v, &[(name.to_string(), x)], Path::new("s.toml")).map_err(|e| e.to_string())
    }

    #[test]
    fn paths_reach_tables_named_entries_and_list_elements() {
        let mut v = json!({
            "film": {"bins": 200, "start_opl": 3.6},
            "camera": {"resolution": [64, 64], "fov": 39.3},
            "material": [{"name": "white", "albedo": [0.7, 0.7, 0.7]}, {"name": "red", "albedo": 0.5}],
            "integrator": {"spp": 16}
        });
        set(&mut v, "film.bins", 50.0).unwrap();
        set(&mut v, "film.start_opl", 4.0).unwrap();
        set(&mut v, "camera.resolution.1", 32.0).unwrap();
        set(&mut v, "material.white.albedo.2", 0.25).unwrap();
        set(&mut v, "material.red.albedo", 0.125).unwrap();
        set(&mut v, "integrator.rr_depth", 3.0).unwrap();
        assert_eq!(v["film"]["bins"], json!(50));
        assert_eq!(v["film"]["start_opl"], json!(4.0));
        assert_eq!(v["camera"]["resolution"], json!([64, 32]));
        assert_eq!(v["material"][0]["albedo"], json!([0.7, 0.7, 0.25]));
        assert_eq!(v["material"][1]["albedo"], json!(0.125));
        assert_eq!(v["integrator"]["rr_depth"], json!(3));
    }

    fn set_text(v: &mut Value, name: &str, text: &str) -> Result<(), String> {
        apply_text(v, &[(name.to_string(), text.to_string())], Path::new("s.toml")).map_err(|e| e.to_string())
    }

    #[test]
    fn text_values_are_read_as_toml() {
        let mut v = json!({
            "film": {"channels": "mono", "gate": {"type": "gaussian", "sigma_opl": 0.02}},
            "nlos": {"scan": "confocal", "grid": [16, 16]},
            "material": [{"name": "white", "albedo": 0.7}]
        });
        set_text(&mut v, "nlos.scan", "exhaustive").unwrap();
        set_text(&mut v, "film.channels", "\"rgb\"").unwrap();
        set_text(&mut v, "nlos.grid", "[8, 4]").unwrap();
        set_text(&mut v, "nlos.hidden_shapes", "[\"box\"]").unwrap();
        set_text(&mut v, "film.gate", "{ type = \"box\", width_opl = 0.05 }").unwrap();
        set_text(&mut v, "film.unwarp", "true").unwrap();
        set_text(&mut v, "material.white.type", "diffuse").unwrap();
        assert_eq!(v["nlos"]["scan"], json!("exhaustive"));
        assert_eq!(v["film"]["channels"], json!("rgb"));
        assert_eq!(v["nlos"]["grid"], json!([8, 4]));
        assert_eq!(v["nlos"]["hidden_shapes"], json!(["box"]));
        assert_eq!(v["film"]["gate"], json!({"type": "box", "width_opl": 0.05}));
        assert_eq!(v["film"]["unwarp"], json!(true));
        assert_eq!(v["material"][0]["type"], json!("diffuse"));
    }

    #[test]
    fn bad_text_values_are_refused_by_name() {
        let mut v = json!({"film": {"channels": "mono"}, "nlos": {"grid": [16, 16]}});
        let e = set_text(&mut v, "hidden_x", "left").unwrap_err();
        assert!(e.contains("hidden_x") && e.contains("[[param]] takes numbers"), "{e}");
        let e = set_text(&mut v, "nlos.grid", "[8, inf]").unwrap_err();
        assert!(e.contains("nlos.grid") && e.contains("finite"), "{e}");
        let e = set_text(&mut v, "nlos.grid", "[8, 1e39]").unwrap_err();
        assert!(e.contains("finite"), "{e}");
        let e = set_text(&mut v, "film.channels", "\"rgb\"\nbins = 3").unwrap_err();
        assert!(e.contains("more than one TOML value"), "{e}");
        let e = set_text(&mut v, "flim.channels", "rgb").unwrap_err();
        assert!(e.contains("has no \"flim\""), "{e}");
        assert_eq!(v["film"]["channels"], json!("mono"));
    }

    #[test]
    fn bad_paths_say_what_is_there() {
        let mut v = json!({"film": {"bins": 200}, "camera": {"resolution": [64, 64]},
                           "material": [{"name": "white", "albedo": 0.7}]});
        let e = set(&mut v, "flim.bins", 1.0).unwrap_err();
        assert!(e.contains("has no \"flim\"") && e.contains("film"), "{e}");
        let e = set(&mut v, "material.black.albedo", 1.0).unwrap_err();
        assert!(e.contains("no entry named \"black\"") && e.contains("white"), "{e}");
        let e = set(&mut v, "camera.resolution", 32.0).unwrap_err();
        assert!(e.contains("list of 2"), "{e}");
        let e = set(&mut v, "camera.resolution.2", 32.0).unwrap_err();
        assert!(e.contains("index 0 to 1"), "{e}");
        let e = set(&mut v, "film.bins", 2.5).unwrap_err();
        assert!(e.contains("whole number"), "{e}");
        let e = set(&mut v, "film.bins", f64::NAN).unwrap_err();
        assert!(e.contains("finite"), "{e}");
        let e = set(&mut v, "film..bins", 1.0).unwrap_err();
        assert!(e.contains("dotted path"), "{e}");
        assert!(e.contains("s.toml") && e.contains("film..bins"), "{e}");
    }
}
