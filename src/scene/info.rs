//! What `dtr info` shows: [`Scene::summary`] (JSON) and `Display` (readable lines).

use super::{EmitterKind, Material, ParamKind, PixelFilter, Scene, Transform};
use crate::params::resolve::{axis_name, channel_name};
use crate::temporal::{Gate, Pulse};
use serde_json::{Value, json};
use std::fmt;

fn transform_json(t: &Transform) -> Value {
    json!({
        "translate": t.translate.to_array(),
        "rotate_deg": t.rotate_deg.to_array(),
        "scale": t.scale.to_array(),
    })
}

fn pulse_json(p: &Pulse) -> Value {
    match *p {
        Pulse::Delta => json!({ "type": "delta" }),
        Pulse::Gaussian { sigma_opl } => json!({ "type": "gaussian", "sigma_opl": sigma_opl }),
        Pulse::Box { width_opl } => json!({ "type": "box", "width_opl": width_opl }),
    }
}

fn gate_json(g: &Gate) -> Value {
    match *g {
        Gate::Box => json!({ "type": "box" }),
        Gate::Gaussian { sigma_opl } => json!({ "type": "gaussian", "sigma_opl": sigma_opl }),
    }
}

fn filter_json(f: &PixelFilter) -> Value {
    match *f {
        PixelFilter::Box => json!({ "type": "box" }),
        PixelFilter::Tent { radius } => json!({ "type": "tent", "radius": radius }),
        PixelFilter::Gaussian { sigma, radius } => {
            json!({ "type": "gaussian", "sigma": sigma, "radius": radius })
        }
    }
}

impl ParamKind {
    /// The kind as written in the scene file (`translate`, ..., `pulse_offset`).
    pub fn name(&self) -> &'static str {
        match self {
            ParamKind::Translate { .. } => "translate",
            ParamKind::Rotate { .. } => "rotate",
            ParamKind::Scale { .. } => "scale",
            ParamKind::Albedo { .. } => "albedo",
            ParamKind::Radiance { .. } => "radiance",
            ParamKind::Eta => "eta",
            ParamKind::PulseOffset { .. } => "pulse_offset",
            ParamKind::Roughness { .. } => "roughness",
            ParamKind::Ior { .. } => "ior",
        }
    }
}

impl Scene {
    /// The controlled quantity of param `i` in words, e.g. `shape "occluder" translate.x`.
    pub fn param_target(&self, i: usize) -> String {
        let Some(p) = self.params.get(i) else {
            return String::new();
        };
        let shape = |s: u32| self.shapes.get(s as usize).map_or("?", |s| s.name.as_str());
        let emitter = |e: u32| self.emitters.get(e as usize).map_or("?", |e| e.name.as_str());
        let ch = |c: Option<usize>| c.map_or(String::new(), |c| format!(".{}", channel_name(c)));
        match &p.kind {
            ParamKind::Translate { shape: s, axis } => {
                format!("shape {:?} translate.{}", shape(*s), axis_name(*axis))
            }
            ParamKind::Rotate { shape: s, axis } => {
                format!("shape {:?} rotate.{}", shape(*s), axis_name(*axis))
            }
            ParamKind::Scale { shape: s, axis } => {
                format!("shape {:?} scale.{}", shape(*s), axis_name(*axis))
            }
            ParamKind::Albedo { material, channel } => format!(
                "material {:?} albedo{}",
                self.materials.get(*material as usize).map_or("?", |m| m.name.as_str()),
                ch(*channel)
            ),
            ParamKind::Radiance { emitter: e, channel } => {
                let field = match self.emitters.get(*e as usize).map(|e| &e.kind) {
                    Some(EmitterKind::Point { .. }) => "intensity",
                    Some(EmitterKind::Laser { .. }) => "power",
                    _ => "radiance",
                };
                format!("emitter {:?} {field}{}", emitter(*e), ch(*channel))
            }
            ParamKind::Eta => "medium eta".to_string(),
            ParamKind::PulseOffset { emitter: e } => {
                format!("emitter {:?} offset_opl", emitter(*e))
            }
            ParamKind::Roughness { material } => format!("material {:?} roughness", self.material_name(*material)),
            ParamKind::Ior { material } => format!("material {:?} int_ior", self.material_name(*material)),
        }
    }

    fn material_name(&self, m: u32) -> &str {
        self.materials.get(m as usize).map_or("?", |m| m.name.as_str())
    }

    /// A material as JSON (for [`Self::summary`]).
    fn material_json(&self, m: &super::NamedMaterial) -> Value {
        let ty = m.material.type_name();
        match &m.material {
            Material::Diffuse { albedo } => {
                json!({ "name": m.name, "type": ty, "albedo": albedo, "one_sided": m.one_sided })
            }
            Material::Conductor {
                roughness,
                specular,
                ior,
            } => json!({
                "name": m.name, "type": ty, "roughness": roughness, "specular_reflectance": specular,
                "eta": ior.map(|i| i.0), "k": ior.map(|i| i.1), "one_sided": m.one_sided,
            }),
            Material::Dielectric {
                roughness,
                int_ior,
                exterior,
            } => json!({
                "name": m.name, "type": ty, "roughness": roughness, "int_ior": int_ior,
                "exterior": exterior.map(|e| self.material_name(e).to_string()),
            }),
        }
    }

    /// Everything about the resolved scene as JSON (for `dtr info --json`).
    pub fn summary(&self) -> Value {
        let shapes: Vec<Value> = self
            .shapes
            .iter()
            .map(|s| {
                json!({
                    "name": s.name,
                    "triangles": s.tri_count,
                    "vertices": s.vertex_count,
                    "material": self.materials.get(s.material as usize).map(|m| m.name.clone()),
                    "emitter": s.emitter.and_then(|e| self.emitters.get(e as usize)).map(|e| e.name.clone()),
                    "transform": transform_json(&s.transform),
                })
            })
            .collect();
        let materials: Vec<Value> = self.materials.iter().map(|m| self.material_json(m)).collect();
        let emitters: Vec<Value> = self
            .emitters
            .iter()
            .map(|e| {
                let mut v = match &e.kind {
                    EmitterKind::Area { shape, radiance } => json!({
                        "type": "area",
                        "shape": self.shapes.get(*shape as usize).map(|s| s.name.clone()),
                        "radiance": radiance,
                    }),
                    EmitterKind::Point { position, intensity } => {
                        json!({ "type": "point", "position": position.to_array(), "intensity": intensity })
                    }
                    EmitterKind::Laser {
                        position,
                        direction,
                        power,
                    } => json!({
                        "type": "laser",
                        "position": position.to_array(),
                        "direction": direction.to_array(),
                        "power": power,
                    }),
                };
                v["name"] = json!(e.name);
                v["pulse"] = pulse_json(&e.pulse);
                v["offset_opl"] = json!(e.offset_opl);
                v
            })
            .collect();
        let params: Vec<Value> = self
            .params
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let (axis, channel) = match &p.kind {
                    ParamKind::Translate { axis, .. }
                    | ParamKind::Rotate { axis, .. }
                    | ParamKind::Scale { axis, .. } => (Some(axis_name(*axis)), None),
                    ParamKind::Albedo { channel, .. } | ParamKind::Radiance { channel, .. } => {
                        (None, channel.map(channel_name))
                    }
                    _ => (None, None),
                };
                json!({
                    "name": p.name,
                    "kind": p.kind.name(),
                    "target": self.param_target(i),
                    "axis": axis,
                    "channel": channel,
                    "value": p.value,
                })
            })
            .collect();
        let f = &self.film;
        let c = &self.camera;
        let it = &self.integrator;
        json!({
            "source": self.source.display().to_string(),
            "triangles": self.geometry.indices.len(),
            "vertices": self.geometry.positions.len(),
            "dropped_degenerate_triangles": self.geometry.dropped_degenerate,
            // positions below are relative to it (src/scene/origin.rs)
            "render_origin": self.render_origin,
            "lifted_emitters": self.lifted_emitters,
            "shapes": shapes,
            "materials": materials,
            "emitters": emitters,
            "camera": {
                "position": c.position.to_array(),
                "look_at": c.look_at.to_array(),
                "up": c.up.to_array(),
                "fov_y_deg": c.fov_y_deg,
                "resolution": [f.width, f.height],
                "filter": filter_json(&f.filter),
            },
            "film": {
                "start_opl": f.axis.start_opl,
                "bin_width_opl": f.axis.bin_width_opl,
                "bins": f.axis.bins,
                "end_opl": f.axis.end_opl(),
                "gate": gate_json(&f.gate),
                "channels": if f.channels == 1 { "mono" } else { "rgb" },
                "unwarp": f.unwarp,
            },
            "eta": self.eta,
            "integrator": {
                "kind": it.kind,
                "max_bounces": it.max_bounces,
                "spp": it.spp,
                "seed": it.seed,
                "rr_depth": it.rr_depth,
                "sampler": it.sampler.name(),
            },
            "params": params,
            "nlos": self.nlos.as_ref().map(|n| {
                let mut v = super::nlos::describe(n);
                v["wall"] = serde_json::json!(self.shapes[n.wall as usize].name);
                v["laser"] = serde_json::json!(self.emitters[n.laser as usize].name);
                v
            }),
        })
    }
}

fn v3(v: glam::Vec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

fn rgb(c: &[f32; 3]) -> String {
    if c[0] == c[1] && c[1] == c[2] {
        format!("{}", c[0])
    } else {
        format!("[{}, {}, {}]", c[0], c[1], c[2])
    }
}

fn pulse_text(p: &Pulse) -> String {
    match *p {
        Pulse::Delta => "delta".to_string(),
        Pulse::Gaussian { sigma_opl } => format!("gaussian (sigma {sigma_opl} m OPL)"),
        Pulse::Box { width_opl } => format!("box (width {width_opl} m OPL)"),
    }
}

impl fmt::Display for Scene {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        let f = &self.film;
        let c = &self.camera;
        let it = &self.integrator;
        writeln!(out, "scene {}", self.source.display())?;
        writeln!(
            out,
            "  geometry: {} shapes, {} triangles, {} vertices ({} zero-area triangles dropped)",
            self.shapes.len(),
            self.geometry.indices.len(),
            self.geometry.positions.len(),
            self.geometry.dropped_degenerate
        )?;
        if self.render_origin != [0.0; 3] {
            let [x, y, z] = self.render_origin;
            writeln!(
                out,
                "  render origin: [{x}, {y}, {z}] (far from 0: positions below are relative to it)"
            )?;
        }
        for s in &self.shapes {
            let t = &s.transform;
            let mat = self.materials.get(s.material as usize).map_or("?", |m| m.name.as_str());
            write!(
                out,
                "    shape {:?}: {} triangles, material {:?}, translate {}, rotate {} deg, scale {}",
                s.name,
                s.tri_count,
                mat,
                v3(t.translate),
                v3(t.rotate_deg),
                v3(t.scale)
            )?;
            if let Some(e) = s.emitter.and_then(|e| self.emitters.get(e as usize)) {
                write!(out, ", emitter {:?}", e.name)?;
            }
            writeln!(out)?;
        }
        writeln!(out, "  materials:")?;
        for m in &self.materials {
            match &m.material {
                Material::Diffuse { albedo } => writeln!(out, "    {:?}: diffuse, albedo {}", m.name, rgb(albedo))?,
                Material::Conductor {
                    roughness, specular, ..
                } => writeln!(
                    out,
                    "    {:?}: {}, roughness {roughness}, specular reflectance {}",
                    m.name,
                    m.material.type_name(),
                    rgb(specular)
                )?,
                Material::Dielectric {
                    roughness,
                    int_ior,
                    exterior,
                } => writeln!(
                    out,
                    "    {:?}: {}, roughness {roughness}, int_ior {int_ior}, exterior {}",
                    m.name,
                    m.material.type_name(),
                    exterior.map_or("the medium".to_string(), |e| format!("{:?}", self.material_name(e)))
                )?,
            }
        }
        writeln!(out, "  emitters:")?;
        for e in &self.emitters {
            let what = match &e.kind {
                EmitterKind::Area { shape, radiance } => format!(
                    "area on shape {:?}, radiance {}",
                    self.shapes.get(*shape as usize).map_or("?", |s| s.name.as_str()),
                    rgb(radiance)
                ),
                EmitterKind::Point { position, intensity } => {
                    format!("point at {}, intensity {}", v3(*position), rgb(intensity))
                }
                EmitterKind::Laser {
                    position,
                    direction,
                    power,
                } => {
                    format!(
                        "laser at {} towards {}, power {}",
                        v3(*position),
                        v3(*direction),
                        rgb(power)
                    )
                }
            };
            writeln!(
                out,
                "    {:?}: {what}, pulse {}, offset {} m OPL",
                e.name,
                pulse_text(&e.pulse),
                e.offset_opl
            )?;
        }
        let filter = match f.filter {
            PixelFilter::Box => "box".to_string(),
            PixelFilter::Tent { radius } => format!("tent (radius {radius} px)"),
            PixelFilter::Gaussian { sigma, radius } => {
                format!("gaussian (sigma {sigma} px, radius {radius} px)")
            }
        };
        writeln!(
            out,
            "  camera: at {} looking at {}, up {}, fov {} deg, {}x{} px, {} filter",
            v3(c.position),
            v3(c.look_at),
            v3(c.up),
            c.fov_y_deg,
            f.width,
            f.height,
            filter
        )?;
        let gate = match f.gate {
            Gate::Box => "box".to_string(),
            Gate::Gaussian { sigma_opl } => format!("gaussian (sigma {sigma_opl} m OPL)"),
        };
        writeln!(
            out,
            "  film: OPL {} .. {} m in {} bins of {} m, {} gate, {}{}",
            f.axis.start_opl,
            f.axis.end_opl(),
            f.axis.bins,
            f.axis.bin_width_opl,
            gate,
            if f.channels == 1 { "mono" } else { "rgb" },
            if f.unwarp { ", unwarped" } else { "" }
        )?;
        writeln!(out, "  medium: eta {}", self.eta)?;
        writeln!(
            out,
            "  integrator: {}, max {} bounces, {} spp, seed {}, {} sampler, russian roulette {}",
            match it.kind {
                super::IntegratorKind::Path => "path",
                super::IntegratorKind::Bdpt => "bdpt (bidirectional, MIS)",
            },
            it.max_bounces,
            it.spp,
            it.seed,
            it.sampler.name(),
            it.rr_depth.map_or("off".to_string(), |d| format!("from bounce {d}"))
        )?;
        if let Some(n) = &self.nlos {
            writeln!(
                out,
                "  nlos: {} scan on shape {:?}: {} sensor point(s) ({}), {} laser point(s) of laser {:?}; the SPAD is the camera position; relay legs {} the time of flight; paths of up to {} bounces from laser to SPAD (max_bounces counts those between a sensor point and a laser spot); {}{}",
                if n.exhaustive() { "exhaustive" } else { "confocal" },
                self.shapes[n.wall as usize].name,
                n.sensors.len(),
                if n.sensors.explicit {
                    "explicit".to_string()
                } else {
                    format!("grid {}x{}", n.sensors.nx, n.sensors.ny)
                },
                n.lasers.len(),
                self.emitters[n.laser as usize].name,
                if n.relay_legs == super::RelayLegs::Included {
                    "in"
                } else {
                    "out of"
                },
                it.max_bounces + 2,
                if n.hidden.probability > 0.0 {
                    format!(
                        "{:.0}% of paths aimed at {:?}",
                        100.0 * n.hidden.probability,
                        n.hidden
                            .shapes
                            .iter()
                            .map(|&s| self.shapes[s as usize].name.as_str())
                            .collect::<Vec<_>>()
                    )
                } else {
                    "no paths aimed at hidden shapes".to_string()
                },
                n.noise.map_or(String::new(), |z| format!(
                    ", noise: Poisson({} photons per unit + {} dark counts), seed {}",
                    z.photons_per_unit, z.dark_counts, z.seed
                ))
            )?;
        }
        if self.params.is_empty() {
            writeln!(out, "  params: none")?;
        } else {
            writeln!(out, "  params:")?;
            for (i, p) in self.params.iter().enumerate() {
                writeln!(
                    out,
                    "    {} = {} ({}: {})",
                    p.name,
                    p.value,
                    p.kind.name(),
                    self.param_target(i)
                )?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;

    #[test]
    fn summary_lists_everything() {
        let s = load_scene("cornell_box.toml");
        let j = s.summary();
        assert_eq!(j["triangles"], 36);
        assert_eq!(j["shapes"].as_array().unwrap().len(), 8);
        let light = j["shapes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|x| x["name"] == "light_quad")
            .unwrap();
        assert_eq!(light["triangles"], 2);
        assert_eq!(light["emitter"], "light");
        assert_eq!(light["transform"]["rotate_deg"], serde_json::json!([90.0, 0.0, 0.0]));
        assert_eq!(j["emitters"][0]["pulse"]["type"], "delta");
        assert_eq!(j["emitters"][0]["type"], "area");
        assert_eq!(j["film"]["bins"], 200);
        assert_eq!(j["film"]["channels"], "rgb");
        assert_eq!(j["film"]["gate"]["type"], "box");
        assert_eq!(j["camera"]["resolution"], serde_json::json!([64, 64]));
        assert_eq!(j["integrator"]["kind"], "path");
        assert_eq!(j["integrator"]["spp"], 16);
        assert_eq!(j["eta"], 1.0);
        assert_eq!(j["materials"].as_array().unwrap().len(), 3);
    }

    #[test]
    fn summary_has_every_param() {
        for name in ["confocal_plane.toml", "obj_mesh.toml", "occluder_shadow.toml"] {
            let s = load_scene(name);
            let j = s.summary();
            let ps = j["params"].as_array().unwrap();
            assert_eq!(ps.len(), s.params.len());
            assert!(!ps.is_empty(), "{name}");
            for (p, q) in ps.iter().zip(&s.params) {
                assert_eq!(p["name"], q.name.as_str());
                assert_eq!(p["kind"], q.kind.name());
                assert_eq!(p["value"], q.value);
                assert!(!p["target"].as_str().unwrap().is_empty());
            }
            let text = s.to_string();
            for q in &s.params {
                assert!(text.contains(&q.name), "{text}");
            }
            for sh in &s.shapes {
                assert!(text.contains(&sh.name), "{text}");
            }
        }
        let s = load_scene("occluder_shadow.toml");
        let p = &s.summary()["params"][0];
        assert_eq!(p["kind"], "translate");
        assert_eq!(p["target"], "shape \"occluder\" translate.x");
        assert_eq!(p["axis"], "x");
        assert_eq!(p["value"], 0.1, "params keep the f64 value of the file");
        assert_eq!(s.summary()["emitters"][0]["pulse"]["type"], "gaussian");
        assert_eq!(s.summary()["film"]["channels"], "mono");
    }
}
