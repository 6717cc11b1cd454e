//! `<sensor type="perspective">` with mitransient's `transient_hdr_film`, its `rfilter` and a
//! `<sampler>` → `[camera]`, `[film]` and the sample count and seed.

use super::ImportError;
use super::transform;
use super::xml::Doc;
use roxmltree::Node;
use toml::{Table, Value};

/// What a sensor gives the scene.
pub(crate) struct Sensor {
    pub camera: Table,
    pub film: Table,
    pub spp: i64,
    pub seed: i64,
    /// `near_clip`, `far_clip` (Mitsuba's defaults where not given).
    pub clip: (f64, f64),
}

/// Our vertical field of view (degrees) from Mitsuba's `fov` along `fov_axis` on a
/// `width`×`height` film. Where the axis is the vertical one (or the film is square) the
/// value is copied as written.
pub(crate) fn vertical_fov(fov: f64, axis: &str, width: i64, height: i64) -> Result<f64, String> {
    let (w, h) = (width as f64, height as f64);
    let axis = match axis {
        "smaller" => {
            if w < h {
                "x"
            } else {
                "y"
            }
        }
        "larger" => {
            if w > h {
                "x"
            } else {
                "y"
            }
        }
        a @ ("x" | "y" | "diagonal") => a,
        other => {
            return Err(format!(
                "unknown fov_axis {other:?} (x, y, smaller, larger or diagonal)"
            ));
        }
    };
    let half = (fov * 0.5).to_radians().tan();
    Ok(match axis {
        "y" => fov,
        "x" if w == h => fov,
        "x" => 2.0 * (half * h / w).atan().to_degrees(),
        _ => 2.0 * (half * h / (w * w + h * h).sqrt()).atan().to_degrees(),
    })
}

pub(crate) fn sensor(doc: &Doc, node: Node) -> Result<Sensor, ImportError> {
    let ty = doc.req_attr(node, "type")?;
    if ty != "perspective" {
        let hint = if ty.contains("nlos") {
            ": NLOS captures are written as our TOML [nlos] section"
        } else {
            ""
        };
        return Err(doc.err(
            node,
            format!("sensor type {ty:?} is not supported (only \"perspective\"){hint}"),
        ));
    }
    let p = doc.props(node);
    let films = p.nested("film");
    let [film] = films.as_slice() else {
        return Err(doc.err(node, "the sensor needs one <film type=\"transient_hdr_film\">"));
    };
    let (film_table, width, height, filter) = film_of(doc, *film)?;
    // (with fov_axis x, a height of 0 made the vertical fov 0 and the error named `fov`)
    if width < 1 || height < 1 {
        return Err(doc.err(
            *film,
            format!("the film's width and height must be at least 1 (got width {width}, height {height})"),
        ));
    }
    let mut camera = Table::new();
    let fov = p.float(doc, "fov")?;
    if fov.is_none() {
        return Err(doc.err(
            node,
            "give the field of view as <float name=\"fov\"> (focal_length is not supported)",
        ));
    }
    let fov = fov.unwrap_or_default();
    let axis = match p.string(doc, "fov_axis")? {
        Some((a, _)) => a,
        None => "x".to_string(),
    };
    let fov_node = p.get(doc, "fov_axis")?.or(p.get(doc, "fov")?).unwrap_or(node);
    let vfov = vertical_fov(fov, &axis, width, height).map_err(|m| doc.err(fov_node, m))?;
    let ops = match p.transform(doc, "to_world")? {
        Some(t) => {
            let ops = transform::parse(doc, t)?;
            (ops, t)
        }
        None => return Err(doc.err(node, "the sensor needs a to_world transform (a <lookat>)")),
    };
    let (pos, target, up) = transform::camera(&ops.0).map_err(|m| doc.err(ops.1, m))?;
    let arr = |v: [f64; 3]| Value::Array(v.iter().map(|x| Value::Float(*x)).collect());
    camera.insert("position".into(), arr(pos));
    camera.insert("look_at".into(), arr(target));
    camera.insert("up".into(), arr(up));
    camera.insert("fov".into(), Value::Float(vfov));
    camera.insert("resolution".into(), Value::Array(vec![width.into(), height.into()]));
    camera.insert("filter".into(), filter);
    for k in ["principal_point_offset_x", "principal_point_offset_y"] {
        if let Some(v) = p.float(doc, k)?
            && v != 0.0
        {
            let at = p.get(doc, k)?.unwrap_or(node);
            return Err(doc.err(at, format!("{k} is not supported")));
        }
    }
    // Our camera rays start at the pinhole, not at the near-clip plane (Mitsuba's rays start
    // there, which shortens the camera segment's OPL by near_clip / cos θ); what the clip
    // planes hide is checked against the converted scene (`clip.rs`). Mitsuba's defaults.
    let near = p.float(doc, "near_clip")?.unwrap_or(1e-2);
    let far = p.float(doc, "far_clip")?.unwrap_or(1e4);
    if !(near > 0.0 && far > near && far.is_finite()) {
        let at = p.get(doc, "near_clip")?.or(p.get(doc, "far_clip")?).unwrap_or(node);
        return Err(doc.err(
            at,
            format!("expected 0 < near_clip < far_clip, finite (got {near}, {far})"),
        ));
    }
    let (spp, seed) = match p.nested("sampler").as_slice() {
        [] => (4, 0),
        [s] => sampler(doc, *s)?,
        _ => return Err(doc.err(node, "more than one <sampler>")),
    };
    p.finish(
        doc,
        "fov, fov_axis, to_world, near_clip and far_clip (where they hide nothing), principal_point_offset_x/y (0), <film>, <sampler>",
    )?;
    Ok(Sensor {
        camera,
        film: film_table,
        spp,
        seed,
        clip: (near, far),
    })
}

/// Any sampler's `sample_count` (default 4) and `seed` (default 0): we draw every sample
/// from our own counter-based generator, so the sampler's type changes nothing.
fn sampler(doc: &Doc, node: Node) -> Result<(i64, i64), ImportError> {
    let ty = doc.req_attr(node, "type")?;
    const SAMPLERS: [&str; 5] = ["independent", "stratified", "multijitter", "orthogonal", "ldsampler"];
    if !SAMPLERS.contains(&ty.as_str()) {
        // (accepted as any other until the forty-fourth session; Mitsuba finds no such plugin)
        return Err(doc.err(
            node,
            format!(
                "sampler type {ty:?} is not one of Mitsuba 3's ({})",
                SAMPLERS.join(", ")
            ),
        ));
    }
    let p = doc.props(node);
    let spp = p.integer(doc, "sample_count")?.unwrap_or(4);
    let seed = p.integer(doc, "seed")?.unwrap_or(0);
    // named at the property (a sample_count of 0 was reported at the integrator's spp)
    for (key, value, least) in [("sample_count", spp, 1), ("seed", seed, 0)] {
        if value < least {
            let at = p.get(doc, key)?.unwrap_or(node);
            return Err(doc.err(at, format!("{key} must be >= {least} (got {value})")));
        }
    }
    p.ignore(doc, &["jitter", "scramble_seed", "samples_per_wavefront"])?;
    p.finish(doc, "sample_count, seed")?;
    Ok((spp, seed))
}

/// `transient_hdr_film`: width and height (Mitsuba's defaults 768 × 576), temporal_bins,
/// start_opl, bin_width_opl (mitransient's defaults 2048, 0, 0.003), rfilter. Box binning
/// in time, as mitransient's film does.
fn film_of(doc: &Doc, node: Node) -> Result<(Table, i64, i64, Value), ImportError> {
    let ty = doc.req_attr(node, "type")?;
    if ty != "transient_hdr_film" {
        return Err(doc.err(
            node,
            format!(
                "film type {ty:?} is not supported: dtr renders transients, use mitransient's \"transient_hdr_film\""
            ),
        ));
    }
    let p = doc.props(node);
    let width = p.integer(doc, "width")?.unwrap_or(768);
    let height = p.integer(doc, "height")?.unwrap_or(576);
    let mut t = Table::new();
    t.insert("bins".into(), p.integer(doc, "temporal_bins")?.unwrap_or(2048).into());
    t.insert(
        "start_opl".into(),
        Value::Float(p.float(doc, "start_opl")?.unwrap_or(0.0)),
    );
    t.insert(
        "bin_width_opl".into(),
        Value::Float(p.float(doc, "bin_width_opl")?.unwrap_or(0.003)),
    );
    t.insert("gate".into(), "box".into());
    t.insert("channels".into(), "rgb".into());
    for k in ["crop_width", "crop_height", "crop_offset_x", "crop_offset_y"] {
        if let Some(n) = p.get(doc, k)? {
            return Err(doc.err(n, "crop windows are not supported: render the full film"));
        }
    }
    if let Some(true) = p.boolean(doc, "sample_border")? {
        return Err(doc.err(node, "sample_border is not supported"));
    }
    // output formats: the film's values are ours whatever the file type; an image of other
    // channels than RGB is refused, and names Mitsuba does not know (accepted until the
    // forty-fourth session, helper 41)
    for (k, known) in [
        ("pixel_format", &["rgb", "rgba"][..]),
        ("component_format", &["float16", "float32", "uint32"][..]),
        (
            "file_format",
            &["openexr", "exr", "rgbe", "hdr", "pfm", "png", "jpeg", "jpg", "ppm"][..],
        ),
    ] {
        if let Some((v, n)) = p.string(doc, k)?
            && !known.contains(&v.trim().to_ascii_lowercase().as_str())
        {
            return Err(doc.err(
                n,
                format!("{k} {v:?} is not supported here (supported: {})", known.join(", ")),
            ));
        }
    }
    let filter = match p.nested("rfilter").as_slice() {
        [] => gaussian(0.5),
        [f] => rfilter(doc, *f)?,
        _ => return Err(doc.err(node, "more than one <rfilter>")),
    };
    p.finish(
        doc,
        "width, height, temporal_bins, start_opl, bin_width_opl, rfilter, pixel_format/component_format (ignored)",
    )?;
    Ok((t, width, height, filter))
}

/// Mitsuba's Gaussian filter: standard deviation σ, cut at 4σ, the value at the cut
/// subtracted (ours has the same form).
fn gaussian(stddev: f64) -> Value {
    let mut t = Table::new();
    t.insert("type".into(), "gaussian".into());
    t.insert("sigma".into(), Value::Float(stddev));
    t.insert("radius".into(), Value::Float(4.0 * stddev));
    Value::Table(t)
}

fn rfilter(doc: &Doc, node: Node) -> Result<Value, ImportError> {
    let ty = doc.req_attr(node, "type")?;
    let p = doc.props(node);
    let v = match ty.as_str() {
        "box" => Value::String("box".into()),
        "tent" => {
            let mut t = Table::new();
            t.insert("type".into(), "tent".into());
            t.insert("radius".into(), Value::Float(p.float(doc, "radius")?.unwrap_or(1.0)));
            Value::Table(t)
        }
        "gaussian" => gaussian(p.float(doc, "stddev")?.unwrap_or(0.5)),
        other => {
            return Err(doc.err(
                node,
                format!("rfilter {other:?} is not supported (box, tent, gaussian)"),
            ));
        }
    };
    p.finish(doc, "radius (tent), stddev (gaussian)")?;
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::vertical_fov;

    #[test]
    fn fov_axes() {
        let t = |deg: f64| (deg * 0.5).to_radians().tan();
        // 2:1 film, 60° horizontally → tan(v/2) = tan(30°) / 2
        let v = vertical_fov(60.0, "x", 200, 100).unwrap();
        assert!((t(v) - t(60.0) / 2.0).abs() < 1e-12);
        assert_eq!(vertical_fov(60.0, "y", 200, 100).unwrap(), 60.0);
        assert_eq!(vertical_fov(60.0, "smaller", 200, 100).unwrap(), 60.0);
        assert_eq!(vertical_fov(60.0, "larger", 200, 100).unwrap(), v);
        assert_eq!(
            vertical_fov(60.0, "smaller", 100, 200).unwrap(),
            vertical_fov(60.0, "x", 100, 200).unwrap()
        );
        // portrait film: x is the smaller axis, so tan(v/2) = 2 tan(30°)
        let p = vertical_fov(60.0, "x", 100, 200).unwrap();
        assert!((t(p) - 2.0 * t(60.0)).abs() < 1e-12);
        // diagonal of a 4:3 film: tan(v/2) = tan(d/2) · 3/5
        let d = vertical_fov(50.0, "diagonal", 400, 300).unwrap();
        assert!((t(d) - t(50.0) * 0.6).abs() < 1e-12);
        // square films copy the value exactly
        assert_eq!(vertical_fov(39.3, "x", 64, 64).unwrap(), 39.3);
        assert!(vertical_fov(39.3, "z", 64, 64).is_err());
    }
}
