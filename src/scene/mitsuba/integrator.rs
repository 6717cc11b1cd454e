//! `<integrator>`: mitransient's `transient_path` (or `transient_prbvolpath`, which without
//! media is the same estimator) → `[integrator]`.

use super::ImportError;
use super::xml::Doc;
use crate::scene::resolve::MAX_BOUNCES;
use roxmltree::Node;
use toml::Table;

/// Our `max_bounces` and `rr_depth` from Mitsuba's `max_depth` and `rr_depth`. Mitsuba's
/// `max_depth` counts the camera segment (1 = emitters seen directly, 2 = direct
/// illumination), so `max_bounces = max_depth − 1`; −1 (unbounded) becomes our largest
/// depth. A finite `max_depth` past it (max_bounces over [`MAX_BOUNCES`], which the TOML
/// loader refuses too) is refused rather than cut down to it: the scene asked for paths
/// we would not trace. Both count the first surface hit as depth 1 for Russian roulette; an
/// `rr_depth` past the last bounce never fires, and then none is written (no roulette). An
/// error names the property it is about and says why.
pub(crate) fn depths(max_depth: i64, rr_depth: i64) -> Result<(i64, Option<i64>), (&'static str, String)> {
    let max_bounces = match max_depth {
        -1 => MAX_BOUNCES,
        d if d >= 2 && d - 1 <= MAX_BOUNCES => d - 1,
        d if d >= 2 => {
            return Err((
                "max_depth",
                format!(
                    "max_depth {d} is more than dtr traces: expected 2..={} (max_bounces = max_depth - 1 \
                 is at most {MAX_BOUNCES}, as in a TOML scene), or -1 (unbounded, imported as \
                 max_bounces = {MAX_BOUNCES})",
                    MAX_BOUNCES + 1
                ),
            ));
        }
        d => {
            return Err((
                "max_depth",
                format!(
                    "max_depth {d} is not supported: expected 2..={} (2 = direct illumination), or -1 (unbounded)",
                    MAX_BOUNCES + 1
                ),
            ));
        }
    };
    if rr_depth < 1 {
        return Err(("rr_depth", format!("rr_depth must be at least 1 (got {rr_depth})")));
    }
    Ok((max_bounces, (rr_depth <= max_bounces).then_some(rr_depth)))
}

/// The `[integrator]` table without spp and seed, and whether the camera segment is left
/// out of the OPL (`camera_unwarp`).
pub(crate) fn integrator(doc: &Doc, node: Node) -> Result<(Table, bool), ImportError> {
    let ty = doc.req_attr(node, "type")?;
    match ty.as_str() {
        "transient_path" | "transient_prbvolpath" => {}
        "transient_nlos_path" => {
            return Err(doc.err(
                node,
                "transient_nlos_path is not supported: NLOS captures are written as our TOML [nlos] section",
            ));
        }
        other => {
            return Err(doc.err(
                node,
                format!("integrator {other:?} is not supported: use mitransient's \"transient_path\""),
            ));
        }
    }
    let p = doc.props(node);
    // Mitsuba's defaults for its differentiable integrators, which mitransient's extend
    let max_depth = p.integer(doc, "max_depth")?.unwrap_or(6);
    let rr_depth = p.integer(doc, "rr_depth")?.unwrap_or(5);
    // the error names the property it is about (an rr_depth of 0 was reported at max_depth)
    let (max_bounces, rr) = depths(max_depth, rr_depth).map_err(|(key, m)| match p.get(doc, key) {
        Ok(Some(n)) => doc.err(n, m),
        _ => doc.err(node, m),
    })?;
    let unwarp = p.boolean(doc, "camera_unwarp")?.unwrap_or(false);
    for k in ["discard_direct_light", "hide_emitters"] {
        if let Some(true) = p.boolean(doc, k)? {
            let at = p.get(doc, k)?.unwrap_or(node);
            return Err(doc.err(at, format!("{k} = true is not supported")));
        }
    }
    // read and ignored by mitransient itself
    p.ignore(doc, &["temporal_filter", "gaussian_stddev"])?;
    p.finish(
        doc,
        "max_depth, rr_depth, camera_unwarp, discard_direct_light and hide_emitters (false)",
    )?;
    let mut t = Table::new();
    t.insert("kind".into(), "path".into());
    t.insert("max_bounces".into(), max_bounces.into());
    if let Some(r) = rr {
        t.insert("rr_depth".into(), r.into());
    }
    Ok((t, unwarp))
}

#[cfg(test)]
mod tests {
    use super::depths;

    #[test]
    fn max_depth_counts_the_camera_segment() {
        assert_eq!(depths(9, 1000).unwrap(), (8, None));
        assert_eq!(depths(2, 5).unwrap(), (1, None));
        assert_eq!(depths(6, 5).unwrap(), (5, Some(5)));
        assert_eq!(depths(6, 6).unwrap(), (5, None));
        assert_eq!(depths(-1, 5).unwrap(), (1024, Some(5)));
        assert_eq!(depths(1025, 5).unwrap(), (1024, Some(5)));
        assert!(depths(1026, 5).unwrap_err().1.contains("max_depth 1026"));
        assert!(depths(i64::MAX, 5).unwrap_err().1.contains("2..=1025"));
        assert!(depths(1, 5).unwrap_err().1.contains("max_depth 1"));
        assert!(depths(0, 5).is_err());
        assert!(depths(-2, 5).is_err());
        let (key, why) = depths(5, 0).unwrap_err();
        assert!(key == "rr_depth" && why.contains("rr_depth"));
    }
}
