//! `[nlos]`: a relay-wall capture. The wall is any shape; its sensor points are a regular grid
//! over the wall or explicit points, each projected onto the mesh along the wall's mean normal
//! (the side facing the SPAD, which is the camera position). The laser scans points on the
//! same wall: the sensor points themselves (confocal, and exhaustive by default) or a grid of
//! its own (exhaustive `laser_grid`).
//!
//! The film becomes the capture's: [ny, nx] sensor points (confocal) or [laser points, sensor
//! points] (exhaustive), so every film-shaped part of the renderer (tiles, memory checks,
//! checkpoints, shards, the adjoint) works on captures unchanged.

use super::context::{Ctx, Names, count, no_such};
use super::desc::{NlosScan, RelayLegs, SceneDesc};
use super::error::table_field;
use super::{Emitter, EmitterKind, Geometry, Material, NamedMaterial, SceneError, Shape};
use glam::{DVec3, Vec3};

/// Most sensor (or laser) points of one grid: 1024 × 1024.
pub const MAX_WALL_POINTS: i64 = 1 << 20;

/// A point on the relay wall: where it is, the wall's unit normal there (facing the SPAD's
/// side), and the triangle and barycentrics it lies on (p = p0 + u·(p1 − p0) + v·(p2 − p0)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallPoint {
    /// Position on the wall, metres relative to [`super::Scene::render_origin`].
    pub p: Vec3,
    /// Unit normal of the wall at `p`, on the SPAD's side.
    pub n: Vec3,
    /// Index of the triangle in [`super::Geometry::indices`].
    pub prim: u32,
    /// Barycentric coordinate along p1 − p0.
    pub u: f32,
    /// Barycentric coordinate along p2 − p0.
    pub v: f32,
}

/// Points on the wall in grid order (index iy · nx + ix; explicit points are one row).
#[derive(Clone, Debug, PartialEq)]
pub struct WallGrid {
    /// Points per row (grid columns).
    pub nx: usize,
    /// Rows (1 for explicit points).
    pub ny: usize,
    /// The points, `nx · ny` of them, index `iy · nx + ix`.
    pub points: Vec<WallPoint>,
    /// Explicit points (`nlos.points`), not a grid.
    pub explicit: bool,
}

impl WallGrid {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }
    /// Whether the grid has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Photon noise of a synthetic capture (`[nlos.noise]`): counts ~ Poisson(photons_per_unit ·
/// I + dark_counts) per bin, drawn from `seed` (`crate::sensor_noise`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct NoiseSpec {
    /// Expected photon count per unit of rendered intensity in a bin (> 0).
    pub photons_per_unit: f64,
    /// Expected background counts per bin (≥ 0).
    pub dark_counts: f64,
    /// Seed of the Poisson draws.
    pub seed: u64,
}

/// A resolved relay-wall capture.
#[derive(Clone, Debug)]
pub struct NlosSpec {
    /// Shape index of the wall.
    pub wall: u32,
    /// Emitter index of the laser.
    pub laser: u32,
    /// Confocal (laser at each sensor point) or exhaustive (every laser × sensor pair).
    pub scan: NlosScan,
    /// Whether the laser-to-wall and wall-to-SPAD legs count in the OPL.
    pub relay_legs: RelayLegs,
    /// The sensor points.
    pub sensors: WallGrid,
    /// The laser points (confocal: the sensor points).
    pub lasers: WallGrid,
    /// The wall's mean unit normal (towards the SPAD) and the grid's in-plane axes: `u`
    /// along grid columns (ix), `v` along rows (iy).
    pub frame: [Vec3; 3],
    /// Photon noise to add to the capture (`[nlos.noise]`), if any.
    pub noise: Option<NoiseSpec>,
    /// Paths aimed at the hidden shapes (`hidden_sampling`, `hidden_shapes`).
    pub hidden: HiddenSampling,
}

/// Where the capture's paths aim their first segment (`integrator::nlos_aim`): with
/// probability `probability` at a point drawn by area on `shapes`, else cosine-sampled about
/// the wall's normal. A small hidden object then draws paths in proportion to the aiming,
/// not to the solid angle it covers from the wall.
#[derive(Clone, Debug, PartialEq)]
pub struct HiddenSampling {
    /// Share of the paths aimed, in [0, 1); 0 when there is nothing to aim at.
    pub probability: f32,
    /// Shape indices aimed at (every one has area when `probability` > 0).
    pub shapes: Vec<u32>,
}

/// Default share of the paths aimed at the hidden shapes.
pub const DEFAULT_HIDDEN_SAMPLING: f64 = 0.5;

impl NlosSpec {
    /// Whether the scan is exhaustive (laser points × sensor points).
    pub fn exhaustive(&self) -> bool {
        self.scan == NlosScan::Exhaustive
    }
    /// The film's (width, height): the sensor grid (confocal) or (sensor points, laser points).
    pub fn film_size(&self) -> (u32, u32) {
        match self.scan {
            NlosScan::Confocal => (self.sensors.nx as u32, self.sensors.ny as u32),
            NlosScan::Exhaustive => (self.sensors.len() as u32, self.lasers.len() as u32),
        }
    }
}

/// Resolves `[nlos]` against the built scene (the wall's world triangles, the emitters and
/// the camera position, which is the SPAD's).
#[allow(clippy::too_many_arguments)]
pub(super) fn resolve(
    desc: &SceneDesc,
    names: &Names,
    emitters: &[Emitter],
    shapes: &[Shape],
    geometry: &Geometry,
    materials: &[NamedMaterial],
    spad: Vec3,
    origin: DVec3,
    ctx: &Ctx,
) -> Result<Option<NlosSpec>, SceneError> {
    let Some(d) = &desc.nlos else {
        return Ok(None);
    };
    let at = |f: &str| table_field("nlos", f);
    let Some(wall) = names.shape(&d.wall) else {
        return Err(ctx.invalid(at("wall"), no_such("shape", "shapes", &d.wall, &names.shapes)));
    };
    let Some(laser) = names.emitters.iter().position(|n| n == &d.laser) else {
        return Err(ctx.invalid(at("laser"), no_such("emitter", "emitters", &d.laser, &names.emitters)));
    };
    if !matches!(emitters[laser].kind, EmitterKind::Laser { .. }) {
        return Err(ctx.invalid(
            at("laser"),
            format!("emitter {:?} is not a laser (type = \"laser\")", d.laser),
        ));
    }
    if let Some((i, e)) = emitters.iter().enumerate().find(|(i, _)| *i != laser) {
        return Err(ctx.invalid(
            format!("emitter[{i}] \"{}\"", e.name),
            "an NLOS capture is lit by its laser alone: remove the other emitters",
        ));
    }
    if desc.film.unwarp {
        return Err(ctx.invalid(
            table_field("film", "unwarp"),
            "does not apply to an NLOS capture: choose the time of flight with nlos.relay_legs",
        ));
    }
    let wall_material = &materials[shapes[wall].material as usize];
    if !matches!(wall_material.material, Material::Diffuse { .. }) {
        return Err(ctx.invalid(
            at("wall"),
            format!(
                "the relay wall must be diffuse: shape {:?} has material {:?} of type {}",
                d.wall,
                wall_material.name,
                wall_material.material.type_name()
            ),
        ));
    }
    let tris = shape_triangles(&shapes[wall], geometry);
    let frame = wall_frame(&tris, spad).ok_or_else(|| {
        ctx.invalid(
            at("wall"),
            format!("shape {:?} has no area to put sensor points on", d.wall),
        )
    })?;
    let sensors = match (&d.grid, &d.points) {
        (Some(g), None) => grid(ctx, "grid", *g, &tris, &frame)?,
        (None, Some(pts)) => explicit(ctx, pts, &tris, &frame, origin)?,
        (Some(_), Some(_)) => {
            return Err(ctx.invalid(
                at("points"),
                "give either grid = [nx, ny] or points = [[x, y, z], ...], not both",
            ));
        }
        (None, None) => {
            return Err(ctx.invalid(
                at("grid"),
                "missing: the sensor points, as grid = [nx, ny] over the wall or points = [[x, y, z], ...]",
            ));
        }
    };
    let lasers = match (d.scan, d.laser_grid) {
        (NlosScan::Confocal, Some(_)) => {
            return Err(ctx.invalid(
                at("laser_grid"),
                "does not apply to a confocal scan (its laser points are the sensor points)",
            ));
        }
        (NlosScan::Exhaustive, Some(g)) => grid(ctx, "laser_grid", g, &tris, &frame)?,
        _ => sensors.clone(),
    };
    for (i, s) in sensors.points.iter().enumerate() {
        if (spad - s.p).dot(s.n) <= 0.0 {
            return Err(ctx.invalid(
                at("grid"),
                format!(
                    "sensor point {i} at {:?} faces away from the SPAD (the camera position): the SPAD must see the wall's front",
                    s.p.to_array()
                ),
            ));
        }
    }
    let noise = match &d.noise {
        None => None,
        Some(n) => {
            let at = |f: &str| table_field("nlos.noise", f);
            if !(n.photons_per_unit.is_finite() && n.photons_per_unit > 0.0) {
                return Err(ctx.invalid(
                    at("photons_per_unit"),
                    format!("must be a finite number > 0 (got {})", n.photons_per_unit),
                ));
            }
            if !(n.dark_counts.is_finite() && n.dark_counts >= 0.0) {
                return Err(ctx.invalid(
                    at("dark_counts"),
                    format!("must be a finite number >= 0 (got {})", n.dark_counts),
                ));
            }
            Some(NoiseSpec {
                photons_per_unit: n.photons_per_unit,
                dark_counts: n.dark_counts,
                seed: n.seed,
            })
        }
    };
    let hidden = hidden_sampling(d, names, shapes, geometry, wall, ctx)?;
    Ok(Some(NlosSpec {
        wall: wall as u32,
        laser: laser as u32,
        scan: d.scan,
        relay_legs: d.relay_legs,
        sensors,
        lasers,
        frame,
        noise,
        hidden,
    }))
}

/// `hidden_sampling` and `hidden_shapes`: the share of aimed paths (default
/// [`DEFAULT_HIDDEN_SAMPLING`]) and the shapes they aim at (default every shape but the wall).
fn hidden_sampling(
    d: &super::desc::NlosDesc,
    names: &Names,
    shapes: &[Shape],
    geometry: &Geometry,
    wall: usize,
    ctx: &Ctx,
) -> Result<HiddenSampling, SceneError> {
    let at = |f: &str| table_field("nlos", f);
    let probability = d.hidden_sampling.unwrap_or(DEFAULT_HIDDEN_SAMPLING);
    if !(probability.is_finite() && (0.0..1.0).contains(&probability)) {
        return Err(ctx.invalid(
            at("hidden_sampling"),
            format!(
                "must be a number in [0, 1): the share of paths aimed at the hidden shapes, 0 for none (got {probability}); \
                 1 would leave the rest of the scene unsampled"
            ),
        ));
    }
    let chosen: Vec<u32> = match &d.hidden_shapes {
        None => (0..shapes.len() as u32).filter(|&s| s as usize != wall).collect(),
        Some(list) => {
            let mut out = Vec::with_capacity(list.len());
            for name in list {
                let Some(s) = names.shape(name) else {
                    return Err(ctx.invalid(at("hidden_shapes"), no_such("shape", "shapes", name, &names.shapes)));
                };
                if s == wall {
                    return Err(ctx.invalid(
                        at("hidden_shapes"),
                        format!("shape {name:?} is the relay wall: aim at the hidden scene, not at the wall"),
                    ));
                }
                if !out.contains(&(s as u32)) {
                    out.push(s as u32);
                }
            }
            out
        }
    };
    let area: f64 = chosen
        .iter()
        .flat_map(|&s| shape_triangles(&shapes[s as usize], geometry))
        .map(|(_, [a, b, c])| 0.5 * (b - a).cross(c - a).length())
        .sum();
    if !(area > 0.0) {
        if d.hidden_shapes.is_some() && probability > 0.0 {
            return Err(ctx.invalid(
                at("hidden_shapes"),
                "the shapes named have no area to aim at: name shapes with triangles, or set hidden_sampling = 0",
            ));
        }
        // nothing but the wall: every path is cosine-sampled
        return Ok(HiddenSampling {
            probability: 0.0,
            shapes: Vec::new(),
        });
    }
    Ok(HiddenSampling {
        probability: probability as f32,
        shapes: chosen,
    })
}

/// A shape's world triangles with their indices in the scene (the wall's, the hidden shapes').
fn shape_triangles(shape: &Shape, geo: &Geometry) -> Vec<(u32, [DVec3; 3])> {
    (shape.first_tri..shape.first_tri + shape.tri_count)
        .map(|t| (t, geo.indices[t as usize].map(|i| geo.positions[i as usize].as_dvec3())))
        .collect()
}

/// The wall's area-weighted mean normal (of its triangles' winding), turned towards the SPAD,
/// and in-plane axes u, v
/// (u ⟂ world Y when possible, so v points up on an upright wall).
fn wall_frame(tris: &[(u32, [DVec3; 3])], spad: Vec3) -> Option<[Vec3; 3]> {
    let mut sum = DVec3::ZERO;
    let mut centre = DVec3::ZERO;
    let mut area = 0.0;
    for (_, [a, b, c]) in tris {
        let cr = (*b - *a).cross(*c - *a);
        sum += cr;
        let ar = 0.5 * cr.length();
        centre += (*a + *b + *c) / 3.0 * ar;
        area += ar;
    }
    // the winding's mean normal, turned towards the SPAD's side of the wall
    let mut n = sum.normalize_or_zero();
    if (spad.as_dvec3() - centre / area.max(1e-300)).dot(n) < 0.0 {
        n = -n;
    }
    if n == DVec3::ZERO || !(area > 0.0) {
        return None;
    }
    let up = if n.y.abs() < 0.99 { DVec3::Y } else { DVec3::Z };
    let u = up.cross(n).normalize();
    let v = n.cross(u);
    Some([n.as_vec3(), u.as_vec3(), v.as_vec3()])
}

/// The first point of the wall met by the line through `q` along −n (coming from the SPAD's
/// side), in f64 (Möller–Trumbore), with its triangle and barycentrics.
fn project(q: DVec3, n: DVec3, tris: &[(u32, [DVec3; 3])], reach: f64) -> Option<WallPoint> {
    let o = q + n * reach;
    let d = -n;
    let mut best: Option<(f64, WallPoint)> = None;
    for (t, [a, b, c]) in tris {
        let (e1, e2) = (*b - *a, *c - *a);
        let pv = d.cross(e2);
        let det = e1.dot(pv);
        if det.abs() < 1e-300 {
            continue;
        }
        let inv = 1.0 / det;
        let tv = o - *a;
        let u = tv.dot(pv) * inv;
        let qv = tv.cross(e1);
        let v = d.dot(qv) * inv;
        let s = e2.dot(qv) * inv;
        let inside = (-1e-9..=1.0 + 1e-9).contains(&u) && v >= -1e-9 && u + v <= 1.0 + 1e-9;
        if !inside || s < 0.0 || best.as_ref().is_some_and(|(bs, _)| *bs <= s) {
            continue;
        }
        let (u, v) = (u.clamp(0.0, 1.0), v.clamp(0.0, 1.0 - u.clamp(0.0, 1.0)));
        let mut normal = e1.cross(e2).normalize();
        if normal.dot(n) < 0.0 {
            normal = -normal;
        }
        let p = *a + e1 * u + e2 * v;
        best = Some((
            s,
            WallPoint {
                p: p.as_vec3(),
                n: normal.as_vec3(),
                prim: *t,
                u: u as f32,
                v: v as f32,
            },
        ));
    }
    best.map(|b| b.1)
}

/// The wall's extent along the frame's axes: (min, max) of u and v, and of n.
fn extent(tris: &[(u32, [DVec3; 3])], frame: &[Vec3; 3]) -> [(f64, f64); 3] {
    let mut e = [(f64::INFINITY, f64::NEG_INFINITY); 3];
    for (_, t) in tris {
        for p in t {
            for (k, axis) in frame.iter().enumerate() {
                let x = p.dot(axis.as_dvec3());
                e[k] = (e[k].0.min(x), e[k].1.max(x));
            }
        }
    }
    e
}

/// An nx × ny grid of cell centres over the wall's extent in (u, v), projected onto the wall.
fn grid(
    ctx: &Ctx,
    field: &str,
    g: [i64; 2],
    tris: &[(u32, [DVec3; 3])],
    frame: &[Vec3; 3],
) -> Result<WallGrid, SceneError> {
    let at = &table_field("nlos", field);
    let nx = count(
        ctx,
        table_field("nlos", &format!("{field}[0]")),
        g[0],
        1,
        MAX_WALL_POINTS,
    )? as usize;
    let ny = count(
        ctx,
        table_field("nlos", &format!("{field}[1]")),
        g[1],
        1,
        MAX_WALL_POINTS,
    )? as usize;
    if (nx * ny) as i64 > MAX_WALL_POINTS {
        return Err(ctx.invalid(at, format!("{nx} × {ny} points is more than {MAX_WALL_POINTS}")));
    }
    let [en, eu, ev] = extent(tris, frame);
    let [n, u, v] = frame.map(|a| a.as_dvec3());
    let reach = 2.0 * (en.1 - en.0) + 1.0;
    let mut points = Vec::with_capacity(nx * ny);
    for iy in 0..ny {
        for ix in 0..nx {
            let a = eu.0 + (ix as f64 + 0.5) / nx as f64 * (eu.1 - eu.0);
            let b = ev.0 + (iy as f64 + 0.5) / ny as f64 * (ev.1 - ev.0);
            let q = u * a + v * b + n * en.1;
            let p = project(q, n, tris, reach).ok_or_else(|| {
                ctx.invalid(
                    at,
                    format!(
                        "grid point ({ix}, {iy}) misses the wall: the grid spans the wall's bounding box, so the wall must cover it seen along its mean normal"
                    ),
                )
            })?;
            points.push(p);
        }
    }
    Ok(WallGrid {
        nx,
        ny,
        points,
        explicit: false,
    })
}

/// Explicit points (file coordinates), each projected onto the wall along its mean normal.
fn explicit(
    ctx: &Ctx,
    pts: &[Vec<f64>],
    tris: &[(u32, [DVec3; 3])],
    frame: &[Vec3; 3],
    origin: DVec3,
) -> Result<WallGrid, SceneError> {
    let at = |i: usize| table_field("nlos", &format!("points[{i}]"));
    if pts.is_empty() || pts.len() as i64 > MAX_WALL_POINTS {
        return Err(ctx.invalid(
            table_field("nlos", "points"),
            format!("expected 1 to {MAX_WALL_POINTS} points (got {})", pts.len()),
        ));
    }
    let [en, ..] = extent(tris, frame);
    let n = frame[0].as_dvec3();
    let mut points = Vec::with_capacity(pts.len());
    for (i, p) in pts.iter().enumerate() {
        let [x, y, z] = p[..] else {
            return Err(ctx.invalid(at(i), format!("expected [x, y, z], got {} numbers", p.len())));
        };
        let q = DVec3::new(x, y, z) - origin;
        if !q.is_finite() {
            return Err(ctx.invalid(at(i), "must be finite"));
        }
        // start the projection in front of the whole wall
        let front = q + n * (en.1 - q.dot(n));
        let reach = 2.0 * (en.1 - en.0) + 1.0;
        let w = project(front, n, tris, reach)
            .ok_or_else(|| ctx.invalid(at(i), "misses the wall seen along its mean normal"))?;
        points.push(w);
    }
    Ok(WallGrid {
        nx: points.len(),
        ny: 1,
        points,
        explicit: true,
    })
}

/// The `[nlos]` table's fields as the JSON metadata reports them.
pub fn describe(spec: &NlosSpec) -> serde_json::Value {
    serde_json::json!({
        "scan": spec.scan,
        "relay_legs": spec.relay_legs,
        "sensor_grid": [spec.sensors.nx, spec.sensors.ny],
        "laser_grid": [spec.lasers.nx, spec.lasers.ny],
        "noise": spec.noise,
        "hidden_sampling": spec.hidden.probability,
    })
}
