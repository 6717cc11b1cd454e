//! What every resolution step shares: where errors go ([`Ctx`]: the file, and which locations
//! a parameter set), the names of the entries ([`Names`], built by [`index_names`]), which
//! references are checked against ([`no_such`]), and the range checks ([`count`],
//! [`positive`], [`check_colour`]).

use super::SceneError;
use super::desc::Triple;
use super::error::{item, item_field};
pub(crate) use super::limits::number;
use super::limits::{MAX_EMISSION, MAX_TIME_OPL};
use std::collections::HashMap;
use std::path::Path;

/// Where errors go: the file, and which locations got their value from a parameter.
pub(crate) struct Ctx<'a> {
    pub path: &'a Path,
    /// location → note such as `value from param "occluder_x" (--set)`; the notes of several
    /// params that set components of one field are joined by "; ".
    pub set_by: HashMap<String, String>,
}

impl<'a> Ctx<'a> {
    /// Errors of the file at `path`, no location set by a parameter yet.
    pub fn new(path: &'a Path) -> Self {
        Self {
            path,
            set_by: HashMap::new(),
        }
    }

    pub fn invalid(&self, at: impl Into<String>, message: impl Into<String>) -> SceneError {
        let at = at.into();
        let mut message = message.into();
        if let Some(note) = self.set_by.get(&at) {
            message = format!("{message} ({note})");
        }
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            at,
            message,
        }
    }
}

/// Name → index for each kind of named entry.
pub(crate) struct Names {
    pub materials: Vec<String>,
    pub shapes: Vec<String>,
    pub emitters: Vec<String>,
    pub params: Vec<String>,
}

impl Names {
    fn find(list: &[String], name: &str) -> Option<usize> {
        list.iter().position(|n| n == name)
    }
    pub fn material(&self, name: &str) -> Option<usize> {
        Self::find(&self.materials, name)
    }
    pub fn shape(&self, name: &str) -> Option<usize> {
        Self::find(&self.shapes, name)
    }
}

/// `no material named "whte" (materials: white, red, green)`.
pub(crate) fn no_such(what: &str, plural: &str, name: &str, all: &[String]) -> String {
    if all.is_empty() {
        format!("no {what} named {name:?} (the scene has no {plural})")
    } else {
        format!("no {what} named {name:?} ({plural}: {})", all.join(", "))
    }
}

pub(super) fn index_names<'a>(
    ctx: &Ctx,
    section: &str,
    names: impl Iterator<Item = &'a String>,
) -> Result<Vec<String>, SceneError> {
    let mut out: Vec<String> = Vec::new();
    for (i, n) in names.enumerate() {
        if n.trim().is_empty() {
            return Err(ctx.invalid(format!("{}: field 'name'", item(section, i, None)), "must not be empty"));
        }
        if let Some(j) = out.iter().position(|m| m == n) {
            return Err(ctx.invalid(
                item_field(section, i, n, "name"),
                format!("duplicate name: {section}[{j}] is already called {n:?}; names must be unique"),
            ));
        }
        if section == "param"
            && let Some(why) = param_name_problem(n)
        {
            return Err(ctx.invalid(item_field(section, i, n, "name"), why));
        }
        out.push(n.clone());
    }
    Ok(out)
}

/// Why `name` cannot name a parameter, if it cannot. A parameter's name becomes part of file
/// names (`PREFIX.d_NAME.npy`, `.png`, the optimiser's columns) and is written on the command
/// line as `--diff NAME,…` and `--set NAME=VALUE`, so it is limited to letters, digits, `_`
/// and `-`, and may not start with `-`. No `.`: `--set` reads a dotted name as a field of the
/// description (`film.bins`), so a parameter `plate.x` loaded, rendered with `--diff plate.x`
/// and could then be neither set nor optimised ("the scene has no "plate"").
fn param_name_problem(name: &str) -> Option<String> {
    let allowed = |c: char| c.is_alphanumeric() || matches!(c, '_' | '-');
    if let Some(c) = name.chars().find(|&c| !allowed(c)) {
        let why = match c {
            '.' => "--set NAME=VALUE reads a dotted name as a field of the description (film.bins)",
            _ => "it becomes part of output file names (PREFIX.d_NAME.npy) and of --diff NAME,… and --set NAME=VALUE",
        };
        return Some(format!(
            "{c:?} cannot appear in a parameter's name: {why}; use letters, digits, '_' and '-' (e.g. {:?})",
            name.replace(|c: char| !allowed(c), "_")
        ));
    }
    if name.starts_with('-') {
        return Some("a parameter's name may not start with '-' (it would read as an option)".into());
    }
    None
}

pub(super) fn count(ctx: &Ctx, at: String, v: i64, min: i64, max: i64) -> Result<i64, SceneError> {
    if v < min {
        Err(ctx.invalid(at, format!("must be at least {min} (got {v})")))
    } else if v > max {
        Err(ctx.invalid(at, format!("must be at most {max} (got {v})")))
    } else {
        Ok(v)
    }
}

pub(super) fn positive(ctx: &Ctx, at: String, v: f32) -> Result<f32, SceneError> {
    if v > 0.0 {
        Ok(v)
    } else {
        Err(ctx.invalid(at, format!("must be > 0 (got {v})")))
    }
}

/// A pulse's or gate's width: > 0, a normal 32-bit float, and at most [`MAX_TIME_OPL`]. The
/// renderer's threads flush subnormal numbers to zero (`accel::set_flush_denormals`), so a
/// width such as 1e-45 would reach the temporal model there as 0.
pub(super) fn time_width(ctx: &Ctx, at: String, v: f32) -> Result<f32, SceneError> {
    let v = positive(ctx, at.clone(), v)?;
    if v < f32::MIN_POSITIVE {
        return Err(ctx.invalid(
            at,
            format!(
                "must be at least {:e}, the smallest normal 32-bit float (got {v:e}): the renderer flushes smaller numbers to zero",
                f32::MIN_POSITIVE
            ),
        ));
    }
    if v as f64 > MAX_TIME_OPL {
        return Err(ctx.invalid(at, beyond_time_opl(number(v), false)));
    }
    Ok(v)
}

/// Why a width or (`signed`) an offset `v`, metres of OPL, is refused: beyond [`MAX_TIME_OPL`].
/// `got` is the value as [`number`] writes it.
pub(super) fn beyond_time_opl(got: String, signed: bool) -> String {
    let bound = if signed { "within ±" } else { "at most " };
    format!(
        "must be {bound}{MAX_TIME_OPL} m (got {got}): from 2^24 m on, the 32-bit floats the renderer holds OPLs in are 2 m or more apart"
    )
}

/// Refuses an emitted amount `v` (checked >= 0 already) with a channel above [`MAX_EMISSION`].
pub(super) fn emission(ctx: &Ctx, at: String, v: [f32; 3]) -> Result<[f32; 3], SceneError> {
    if v.iter().all(|&x| x as f64 <= MAX_EMISSION) {
        return Ok(v);
    }
    let got = if v[0] == v[1] && v[1] == v[2] {
        number(v[0])
    } else {
        format!("[{}]", v.map(number).join(", "))
    };
    Err(ctx.invalid(
        at,
        format!(
            "every channel must be at most {} (got {got}): a film adds up the emission times each path's factor in \
             32-bit floats, which end at 3.4e38; scale the emission down and the result up",
            number(MAX_EMISSION)
        ),
    ))
}

/// Checks each channel of a colour is in `[lo, hi]`.
pub(crate) fn check_colour(ctx: &Ctx, at: String, c: Triple, lo: f32, hi: f32) -> Result<[f32; 3], SceneError> {
    let v = c.to_array();
    if v.iter().any(|&x| !(x >= lo && x <= hi)) {
        let range = if hi.is_finite() {
            format!("in [{lo}, {}]", number(hi))
        } else {
            format!(">= {lo}")
        };
        let got = match c {
            Triple::Scalar(s) => format!("{s}"),
            Triple::Three(t) => format!("{t:?}"),
        };
        return Err(ctx.invalid(at, format!("every channel must be {range} (got {got})")));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;

    #[test]
    fn duplicate_names_are_refused() {
        let text = format!("{MINI}\n[[shape]]\nname = \"quad\"\ntype = \"cube\"\nmaterial = \"white\"\n");
        expect_err(
            "dup.toml",
            &text,
            &[],
            &[
                "shape[1] \"quad\": field 'name'",
                "duplicate name",
                "shape[0]",
                "unique",
            ],
        );
        let text = format!("{MINI}\n[[material]]\nname = \"white\"\ntype = \"diffuse\"\nalbedo = 0.1\n");
        expect_err(
            "dupm.toml",
            &text,
            &[],
            &["material[1] \"white\": field 'name'", "duplicate name"],
        );
        let text = format!(
            "{MINI}\n[[param]]\nname = \"p\"\nkind = \"eta\"\nvalue = 1\n[[param]]\nname = \"p\"\nkind = \"eta\"\nvalue = 1\n"
        );
        expect_err(
            "dupp.toml",
            &text,
            &[],
            &["param[1] \"p\": field 'name'", "duplicate name"],
        );
        for bad in ["a/b", "a,b", "a=b", "a b", "..", "-x", ".x", "a\\\\b"] {
            let text = format!("{MINI}\n[[param]]\nname = \"{bad}\"\nkind = \"eta\"\nvalue = 1\n");
            expect_err(
                "badname.toml",
                &text,
                &[],
                &["badname.toml", "param[0]", "field 'name'", "parameter's name"],
            );
        }
        // a dotted name: --set reads it as a field path, so it could not be set or optimised
        let text = format!("{MINI}\n[[param]]\nname = \"box.yaw\"\nkind = \"eta\"\nvalue = 1\n");
        expect_err(
            "dotted.toml",
            &text,
            &[],
            &["param[0]", "'.' cannot appear in a parameter's name", "\"box_yaw\""],
        );
        for good in ["occluder_x", "box_yaw", "θ-1"] {
            let text = format!("{MINI}\n[[param]]\nname = \"{good}\"\nkind = \"eta\"\nvalue = 1\n");
            assert!(load_text("good.toml", &text, &[], &[]).is_ok(), "{good}");
        }
        let text = mini_with("name = \"quad\"", "name = \"\"");
        expect_err(
            "empty.toml",
            &text,
            &[],
            &["shape[0]: field 'name'", "must not be empty"],
        );
    }

    #[test]
    fn unknown_references_list_what_exists() {
        let text = format!("{MINI}\n[[material]]\nname = \"red\"\ntype = \"diffuse\"\nalbedo = 0.1\n").replacen(
            "material = \"white\"",
            "material = \"whte\"",
            1,
        );
        expect_err(
            "ref.toml",
            &text,
            &[],
            &[
                "shape[0] \"quad\": field 'material'",
                "no material named \"whte\" (materials: white, red)",
            ],
        );
        let text = format!("{MINI}\n[[emitter]]\nname = \"area\"\ntype = \"area\"\nshape = \"qaud\"\nradiance = 1\n");
        expect_err(
            "eref.toml",
            &text,
            &[],
            &[
                "emitter[1] \"area\": field 'shape'",
                "no shape named \"qaud\" (shapes: quad)",
            ],
        );
        let text = mini_with("material = \"white\"\n", "");
        expect_err(
            "nomat.toml",
            &text,
            &[],
            &["shape[0] \"quad\": field 'material'", "missing", "materials: white"],
        );
    }
}
