//! Random scenes through the whole CLI: every combination of integrator, sampler, film, gate,
//! pulse, material, shape, emitter and parameter that the generator draws must either render
//! with finite outputs (the transient and every derivative asked for) or be refused with
//! exit code 2, a message naming the scene file, and no output files. Never a panic, another
//! exit code, NaN or Inf. A third of them are relay-wall captures of the same room. The
//! scenes are small (at most 8 × 8 pixels or 4 × 4 sensor points, 4 spp); what they check is
//! that no mix of features reaches a code path that breaks, not the values (the FD and
//! forward tests do that).

use crate::common;
use std::fmt::Write as _;
use std::path::Path;

/// xorshift64*: enough to draw scenes, deterministic across platforms.
struct Draw(u64);

impl Draw {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    fn int(&mut self, lo: u64, hi: u64) -> u64 {
        lo + self.next() % (hi - lo + 1)
    }
    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.next() as usize % items.len()]
    }
    fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }
}

/// A value for an albedo-like field: a scalar, or (not on a mono film) a triple.
fn colour(d: &mut Draw, mono: bool) -> String {
    if !mono && d.chance(0.5) {
        let c: Vec<String> = (0..3).map(|_| format!("{:.3}", d.range(0.05, 0.95))).collect();
        format!("[{}]", c.join(", "))
    } else {
        format!("{:.3}", d.range(0.05, 0.95))
    }
}

fn material(d: &mut Draw, name: &str, closed: bool, mono: bool) -> (String, &'static str) {
    // smooth (Dirac) lobes are drawn less often: most parameters are refused with them
    let open = [
        "diffuse",
        "diffuse",
        "diffuse",
        "roughconductor",
        "roughconductor",
        "conductor",
    ];
    let all = [
        "diffuse",
        "diffuse",
        "roughconductor",
        "roughconductor",
        "roughdielectric",
        "roughdielectric",
        "conductor",
        "dielectric",
    ];
    let ty = *d.pick(if closed { &all[..] } else { &open[..] });
    let mut s = format!("[[material]]\nname = \"{name}\"\ntype = \"{ty}\"\n");
    match ty {
        "diffuse" => writeln!(s, "albedo = {}", colour(d, mono)).unwrap(),
        "roughconductor" | "conductor" => {
            if ty == "roughconductor" {
                writeln!(s, "roughness = {}", d.pick(&[0.01, 0.05, 0.3, 1.0])).unwrap();
            }
            if d.chance(0.5) {
                s += "eta = [0.2, 0.4, 1.4]\nk = [3.6, 2.4, 1.8]\n";
            }
        }
        _ => {
            if ty == "roughdielectric" {
                writeln!(s, "roughness = {}", d.pick(&[0.01, 0.05, 0.3, 1.0])).unwrap();
            }
            writeln!(s, "int_ior = {}", d.pick(&[1.01, 1.33, 1.5, 2.4])).unwrap();
        }
    }
    (s, ty)
}

/// Scene `seed` as TOML text, and the names of its parameters.
fn scene(seed: u64, meshes: &Path) -> (String, Vec<&'static str>, Vec<String>) {
    let d = &mut Draw::new(seed);
    let mut s = String::new();
    // a relay-wall capture of the room: the back wall relays, only the laser emits
    let capture = d.chance(0.3);
    let kind = *d.pick(&["path", "bdpt"]);
    writeln!(
        s,
        "[integrator]\nkind = \"{kind}\"\nmax_bounces = {}\nspp = 4\nseed = {}\nsampler = \"{}\"",
        d.int(1, 6),
        d.int(0, 99),
        d.pick(&["sobol", "independent"])
    )
    .unwrap();
    if d.chance(0.2) {
        writeln!(s, "rr_depth = {}", d.int(1, 4)).unwrap();
    }
    let eta = if d.chance(0.7) { 1.0 } else { d.range(1.0, 1.5) };
    writeln!(s, "[medium]\neta = {eta:.3}").unwrap();
    writeln!(
        s,
        "[camera]\nposition = [{:.2}, {:.2}, {:.2}]\nlook_at = [0.0, 0.5, 0.0]\nfov = {}\nresolution = [{}, {}]\nfilter = \"{}\"",
        d.range(-0.5, 0.5),
        d.range(0.2, 1.5),
        d.range(2.5, 4.0),
        d.pick(&[20, 40, 70]),
        d.int(2, 8),
        d.int(2, 8),
        d.pick(&["box", "tent", "gaussian"])
    )
    .unwrap();
    let channels = *d.pick(&["auto", "mono", "rgb"]);
    let mono = channels == "mono";
    let gate = if d.chance(0.7) {
        "\"box\"".to_string()
    } else {
        format!("{{ type = \"gaussian\", sigma_opl = {} }}", d.pick(&[0.01, 0.05, 0.2]))
    };
    writeln!(
        s,
        "[film]\nstart_opl = {:.2}\nbin_width_opl = {}\nbins = {}\ngate = {gate}\nchannels = \"{channels}\"\nunwarp = {}",
        d.range(0.0, 4.0),
        d.pick(&[0.01, 0.05, 0.2]),
        d.int(1, 80),
        !capture && d.chance(0.1)
    )
    .unwrap();
    let (floor_m, _) = material(d, "floor_m", false, mono);
    let (obj_m, obj_ty) = material(d, "obj_m", true, mono);
    s += &floor_m;
    s += "[[material]]\nname = \"white\"\ntype = \"diffuse\"\nalbedo = 0.7\n";
    s += &obj_m;
    s += "[[shape]]\nname = \"floor\"\ntype = \"rectangle\"\nmaterial = \"floor_m\"\nrotate = [-90, 0, 0]\nscale = 2.0\n";
    s += "[[shape]]\nname = \"back\"\ntype = \"rectangle\"\nmaterial = \"white\"\ntranslate = [0, 1, -1.5]\nscale = 2.0\n";
    let shape = *d.pick(&["cube", "sphere", "mesh"]);
    // resting on the floor (y = 0.3 for the cube), just above it, or in the air
    let y = *d.pick(&[0.3, 0.301, 0.31, 0.5]);
    let (x, z, yaw) = (d.range(-0.5, 0.5), d.range(-0.5, 0.5), d.int(0, 90));
    let mut files: Vec<String> = std::fs::read_dir(meshes)
        .unwrap()
        .map(|e| e.unwrap().path().to_string_lossy().into_owned())
        .filter(|p| p.ends_with(".obj") || p.ends_with(".ply"))
        .collect();
    files.sort();
    let (ty, y, extra) = match shape {
        "mesh" => {
            let f = d.pick(&files).clone();
            let ext = if f.ends_with(".ply") { "ply" } else { "obj" };
            (ext, 0.6, format!("file = {f:?}\n"))
        }
        "sphere" => ("sphere", y, format!("subdivisions = {}\n", d.int(0, 3))),
        _ => ("cube", y, String::new()),
    };
    writeln!(
        s,
        "[[shape]]\nname = \"obj\"\ntype = \"{ty}\"\nmaterial = \"obj_m\"\ntranslate = [{x:.2}, {y}, {z:.2}]\nscale = 0.3\nrotate = [0, {yaw}, 0]\n{extra}"
    )
    .unwrap();
    let pulse = *d.pick(&[
        "\"delta\"",
        "{ type = \"gaussian\", sigma_opl = 0.02 }",
        "{ type = \"gaussian\", sigma_opl = 0.05 }",
        "{ type = \"box\", width_opl = 0.05 }",
    ]);
    let emitter = if capture {
        "laser"
    } else {
        *d.pick(&["area", "point", "laser"])
    };
    match emitter {
        "area" => {
            s += "[[shape]]\nname = \"lamp_q\"\ntype = \"rectangle\"\nmaterial = \"white\"\nrotate = [90, 0, 0]\ntranslate = [0, 1.8, 0]\nscale = 0.3\n";
            writeln!(s, "[[emitter]]\nname = \"lamp\"\ntype = \"area\"\nshape = \"lamp_q\"\nradiance = 5.0\npulse = {pulse}\noffset_opl = {}", d.pick(&[0.0, 0.1])).unwrap();
        }
        "point" => writeln!(s, "[[emitter]]\nname = \"lamp\"\ntype = \"point\"\nposition = [0.3, 1.5, 0.5]\nintensity = 2.0\npulse = {pulse}\noffset_opl = {}", d.pick(&[0.0, 0.1])).unwrap(),
        _ => writeln!(s, "[[emitter]]\nname = \"lamp\"\ntype = \"laser\"\nposition = [0.3, 1.5, 1.0]\ndirection = [-0.2, -1, -0.5]\npower = 2.0\npulse = {pulse}").unwrap(),
    }
    if capture {
        let scan = *d.pick(&["confocal", "exhaustive"]);
        writeln!(
            s,
            "[nlos]\nwall = \"back\"\nlaser = \"lamp\"\nscan = \"{scan}\"\ngrid = [{}, {}]\nrelay_legs = \"{}\"\nhidden_sampling = {}",
            d.int(1, 4),
            d.int(1, 4),
            d.pick(&["excluded", "included"]),
            d.pick(&[0.0, 0.5, 0.9])
        )
        .unwrap();
        if scan == "exhaustive" && d.chance(0.5) {
            writeln!(s, "laser_grid = [{}, {}]", d.int(1, 3), d.int(1, 3)).unwrap();
        }
        if d.chance(0.3) {
            s += "hidden_shapes = [\"obj\"]\n";
        }
        if d.chance(0.3) {
            writeln!(
                s,
                "[nlos.noise]\nphotons_per_unit = 1e6\ndark_counts = {}\nseed = 3",
                d.pick(&[0.0, 0.01])
            )
            .unwrap();
        }
    }
    let mut params = Vec::new();
    let candidates: [(&str, &str, &str, f64); 7] = [
        ("ox", "translate", "shape = \"obj\"\naxis = \"x\"", x),
        ("oy", "translate", "shape = \"obj\"\naxis = \"y\"", y),
        ("ry", "rotate", "shape = \"obj\"\naxis = \"y\"", yaw as f64),
        ("sz", "scale", "shape = \"obj\"\naxis = \"z\"", 0.3),
        ("alb", "albedo", "material = \"white\"", 0.7),
        ("rad", "radiance", "emitter = \"lamp\"", 2.0),
        ("off", "pulse_offset", "emitter = \"lamp\"", 0.0),
    ];
    for (name, kind, target, value) in candidates {
        if d.chance(0.35) {
            writeln!(
                s,
                "[[param]]\nname = \"{name}\"\nkind = \"{kind}\"\n{target}\nvalue = {value}"
            )
            .unwrap();
            params.push(name);
        }
    }
    if obj_ty.starts_with("rough") && d.chance(0.5) {
        s += "[[param]]\nname = \"rough\"\nkind = \"roughness\"\nmaterial = \"obj_m\"\nvalue = 0.2\n";
        params.push("rough");
    }
    if obj_ty.ends_with("dielectric") && d.chance(0.5) {
        s += "[[param]]\nname = \"ior\"\nkind = \"ior\"\nmaterial = \"obj_m\"\nvalue = 1.4\n";
        params.push("ior");
    }
    if d.chance(0.2) {
        s += "[[param]]\nname = \"eta\"\nkind = \"eta\"\nvalue = 1.1\n";
        params.push("eta");
    }
    let mut args = Vec::new();
    // `--estimators` without `--diff` is refused (it would change nothing)
    if d.chance(0.3) && !params.is_empty() {
        args.push("--estimators".to_string());
        args.push(d.pick(&["interior", "boundary", "full"]).to_string());
    }
    (s, params, args)
}

#[test]
fn random_scenes_render_finite_or_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = common::scene_path("meshes");
    let (mut rendered, mut refused, mut captures) = (0, 0, 0);
    let count = 300;
    for seed in 0..count {
        let (text, params, extra) = scene(seed, &meshes);
        let capture = text.contains("[nlos]");
        let file = format!("s{seed}.toml");
        std::fs::write(dir.path().join(&file), &text).unwrap();
        let prefix = format!("o{seed}");
        let mut args = vec!["-q", "render", &file, "--threads", "2", "-o", &prefix];
        let diff = params.join(",");
        if !params.is_empty() {
            args.extend(["--diff", &diff]);
        }
        args.extend(extra.iter().map(String::as_str));
        let out = common::dtr(&args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        let written: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                p.file_name()
                    .unwrap()
                    .to_string_lossy()
                    .starts_with(&format!("{prefix}."))
            })
            .collect();
        assert!(!stderr.contains("panicked"), "scene {seed} panicked: {stderr}\n{text}");
        match out.status.code() {
            Some(0) => {
                rendered += 1;
                captures += u64::from(capture);
                let npys: Vec<_> = written
                    .iter()
                    .filter(|p| p.extension().is_some_and(|e| e == "npy"))
                    .collect();
                assert_eq!(
                    npys.len(),
                    1 + params.len() + usize::from(text.contains("[nlos.noise]")),
                    "scene {seed}: outputs {written:?}\n{text}"
                );
                for p in npys {
                    let (_, data) = common::npy(p);
                    let bad = data.iter().filter(|v| !v.is_finite()).count();
                    assert_eq!(
                        bad,
                        0,
                        "scene {seed}: {} holds {bad} non-finite values\n{text}",
                        p.display()
                    );
                }
                for p in &written {
                    std::fs::remove_file(p).unwrap();
                }
            }
            Some(2) => {
                refused += 1;
                assert!(
                    stderr.contains("error:") && stderr.contains(&file),
                    "scene {seed}: the refusal does not name the scene file: {stderr}\n{text}"
                );
                assert!(written.is_empty(), "scene {seed}: refused but wrote {written:?}");
            }
            code => panic!("scene {seed}: exit code {code:?}: {stderr}\n{text}"),
        }
    }
    eprintln!("{rendered} random scenes rendered ({captures} captures), {refused} refused");
    // the generator must reach the renderer, not only the refusals
    assert!(
        rendered >= count / 3 && captures >= count / 10,
        "only {rendered} of {count} random scenes rendered, {captures} of them captures ({refused} refused)"
    );
}
