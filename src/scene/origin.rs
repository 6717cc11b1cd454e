//! The render origin: where the f32 world of the renderer is centred.
//!
//! World positions in a scene file (shape `translate`, camera `position` and `look_at`, point
//! and laser `position`, OBJ vertices) are read as f64. The loader picks a render origin O in
//! f64, subtracts it in f64 and only then rounds to the f32 coordinates that Embree, the path
//! kernel and the boundary stage work in. Optical path lengths are differences of positions,
//! so they do not depend on O; precision then depends on the scene's size, not on where it
//! sits: a Cornell box 10⁶ m from the origin renders like one at the origin (an f32 world
//! coordinate of 10⁶ m is quantised to 6 cm, and the self-intersection offset of
//! `integrator::surface::offset_origin`, which scales with the coordinates, would be 3.8 m).
//!
//! O is where the scene's surface lies: the centre of its shapes' bounding boxes, each
//! weighted by its box's surface area, rounded to the nearest multiple of
//! g = 2^(⌈log₂ s⌉ + 1), s the boxes' (so weighted) mean distance from that centre plus their
//! half diagonals, so that
//! - the bulk of the surface lies within a few s of O (f32 keeps about 7 digits of its size),
//!   and a small object far from the rest moves O little: a 1 cm square left at the world
//!   origin beside a room 10 km away weighs as its box's area, where the centre of the
//!   bounding box put O at 0 and rendered the room in f32 at 10 km (1 mm steps, a 3.8 cm
//!   offset off surfaces: its energy came out 2.3 % high and its derivatives disagreed with
//!   finite differences);
//! - a scene whose surface's centre lies within 2 s of the world origin keeps O = 0, so the
//!   shipped scenes render as before;
//! - small moves do not shift O: it is computed from the scene as the file describes it, the
//!   params at their file values, so `--set` and finite differences never move it.
//!
//! Geometry whose boxes have no area (points, lines) takes the centre of its bounding box and
//! that box's largest side for s. A shape is weighted by its box, not its own area, so that
//! this costs one pass over the vertices, as the bounding box did (the triangles' areas cost
//! 13 ms per load of a 327 680-triangle ball).
//!
//! The camera and the point emitters do not take part: precision matters where rays meet
//! surfaces (shadows, self-intersection), and a camera far from a small target would pull O
//! away from it. Such a camera keeps its own distance to f32 precision (6·10⁻⁸ of it).

use glam::DVec3;

/// O stays at the world origin while the surface's centre lies within this many times its
/// mean distance from it: the surface's coordinates are then within a few of its sizes either way.
const NEAR: f64 = 2.0;

/// Where a scene's geometry lies, in world coordinates (f64).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Extent {
    /// The bounding box of every vertex.
    pub lo: DVec3,
    pub hi: DVec3,
    /// Where the surface lies: its shapes' boxes' centre and mean distance from it (plus half
    /// a diagonal), each weighted by its box's area (`shapes::world_extent`); `None` without
    /// area.
    pub bulk: Option<(DVec3, f64)>,
}

/// The render origin for geometry where `extent` says (`None`: no geometry, O = 0).
pub(crate) fn choose(extent: Option<&Extent>) -> DVec3 {
    let Some(e) = extent else {
        return DVec3::ZERO;
    };
    let (centre, size) = match e.bulk {
        Some((c, s)) if c.is_finite() && s.is_finite() && s > 0.0 => (c, s),
        _ => ((e.lo + e.hi) * 0.5, (e.hi - e.lo).max_element()),
    };
    // the world origin is as good as any point near the surface (and keeps a scene's bytes)
    if !(size.is_finite() && centre.is_finite()) || centre.abs().max_element() <= NEAR * size {
        return DVec3::ZERO;
    }
    let grid = if size > 0.0 {
        2f64.powi(size.log2().ceil() as i32 + 1)
    } else {
        1.0
    };
    let o = (centre / grid).round() * grid;
    // -0.0 prints oddly and means the same
    o + DVec3::ZERO
}

/// The length the renderer's offsets off surfaces are scaled to at least (see
/// `integrator::surface::self_intersection_eps` and `super::flush::lift`): 1 m, or the
/// scene's extent rounded up to a power of two where that is smaller. Offsets are a fixed
/// fraction of the coordinates' magnitude, and this floor keeps them from vanishing near the
/// render origin; a floor of 1 m in a scene of a few millimetres made them a sizeable part of
/// the scene (a light 0.1 mm from a wall moved off it, edges' boundary rays started 0.2 % of
/// the scene off their edge). Like the origin, it is taken from the scene as the file
/// describes it, so `--set` and finite differences never change it.
pub(crate) fn offset_scale(bounds: Option<(DVec3, DVec3)>) -> f32 {
    let Some((lo, hi)) = bounds else {
        return 1.0;
    };
    let extent = (hi - lo).max_element();
    if !(extent.is_finite() && extent > 0.0) {
        return 1.0;
    }
    2f64.powi(extent.log2().ceil() as i32).min(1.0) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_scale_down_with_small_scenes_only() {
        let cube = |e: f64| Some((DVec3::splat(5.0), DVec3::new(5.0 + e, 5.0 + e / 2.0, 5.0)));
        assert_eq!(offset_scale(None), 1.0);
        assert_eq!(offset_scale(cube(0.0)), 1.0);
        for (extent, want) in [
            (2.0, 1.0),
            (1.0, 1.0),
            (0.6, 1.0),
            (0.5, 0.5),
            (2e-3, 2f32.powi(-8)),
            (1e3, 1.0),
        ] {
            assert_eq!(offset_scale(cube(extent)), want, "extent {extent}");
        }
    }

    /// A box from `lo` to `hi` whose surface's centre is the box's and whose mean distance
    /// from it is `spread`.
    fn boxed(lo: DVec3, hi: DVec3, spread: f64) -> Extent {
        Extent {
            lo,
            hi,
            bulk: Some(((lo + hi) * 0.5, spread)),
        }
    }

    #[test]
    fn scenes_near_the_origin_keep_it() {
        // the Cornell box: x, z in [-1, 1], y in [0, 2]
        let (lo, hi) = (DVec3::new(-1.0, 0.0, -1.0), DVec3::new(1.0, 2.0, 1.0));
        assert_eq!(choose(Some(&boxed(lo, hi, 1.3))), DVec3::ZERO);
        let no_area = Extent { lo, hi, bulk: None };
        assert_eq!(choose(Some(&no_area)), DVec3::ZERO);
        assert_eq!(choose(None), DVec3::ZERO);
    }

    #[test]
    fn far_scenes_are_brought_within_their_own_size() {
        for d in [1e3, 1e4, 1e5, 1e6, 3.3e7] {
            let at = DVec3::new(d + 0.123, -0.37 * d + 0.31, 0.61 * d + 0.07);
            let (lo, hi) = (at - DVec3::new(1.0, 0.0, 1.0), at + DVec3::new(1.0, 2.0, 1.0));
            let o = choose(Some(&boxed(lo, hi, 1.3)));
            let extent = (hi - lo).max_element();
            for p in [lo, hi] {
                assert!((p - o).abs().max_element() <= 2.5 * extent, "{d}: {p} - {o}");
            }
            // a move much smaller than the grid leaves O alone
            assert_eq!(choose(Some(&boxed(lo + 1e-3, hi + 1e-3, 1.3))), o, "{d}");
        }
    }
}
