//! Shards on the command line: what makes two renders parts of one (`identity`), and
//! `dtr merge`, which adds the shards of a render (`dtr render --shard I/N`, [`crate::shard`])
//! into the output set one process would have written.
//!
//! The merged films equal the whole render's up to the order of floating-point additions:
//! one process sums each pixel's samples in sample order, in f32 for a primal tile (f64 for
//! a derivative tile), and the merge adds the N shards' films in f64. For a primal value of
//! `spp` samples the two differ by at most about `(2·spp + 8)·2⁻²⁴` of the value
//! (recursive summation of non-negative terms); tests/cli_shards.rs asserts that bound.

use super::digest::hex;
use super::npy_in::read_f32_hashed;
use super::output_set::{JSON_CAP, OutputSet, with_suffix};
use crate::film::Transient;
use crate::render::RenderOptions;
use crate::scene::Scene;
use crate::shard::FilmSum;
use crate::shard::Shard;
use anyhow::{Context, bail};
use serde_json::{Value, json};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// `--set NAME=VALUE` as an identity holds it: a number with its spaces dropped, a value
/// other than a number as the TOML value it is read as (`scene::field_set`), so that two
/// spellings of one setting (`[3, 3]`, `[3,3]`) match while strings that differ only in a
/// space (`["a b"]`, `["ab"]`) do not.
fn canonical_set(s: &str) -> String {
    match s.split_once('=') {
        Some((name, value)) if super::set_number(value).is_none() => {
            let value = crate::scene::field_set::text_value(value)
                .map(|v| v.to_string())
                .unwrap_or_else(|_| value.trim().to_string());
            format!("{}={value}", name.trim())
        }
        _ => s.replace(' ', ""),
    }
}

/// Everything that decides a render's numbers, as JSON: the contents of its input files,
/// the overrides, the sample counts, seed, estimators and modes. Two renders with the same
/// identity trace the same paths; shards of one render must share it (`dtr merge` and
/// `--resume` compare it field by field). The thread count and the outputs are not part of it.
pub fn identity(
    scene: &Scene,
    sets: &[String],
    diff: &[String],
    opts: &RenderOptions,
    spp: u32,
) -> anyhow::Result<Value> {
    let digest = inputs_sha256(scene)?;
    let mut sets: Vec<String> = sets.iter().map(|s| canonical_set(s)).collect();
    sets.sort();
    Ok(json!({
        "inputs_sha256": digest,
        "set": sets,
        // the window rendered, which `--auto-window` chooses beyond the inputs and the sets
        "time_axis": [scene.film.axis.start_opl, scene.film.axis.bin_width_opl, scene.film.axis.bins],
        "diff": diff,
        "spp": spp,
        "spp_boundary": if diff.is_empty() { None } else { Some(opts.spp_boundary.unwrap_or(spp)) },
        "seed": opts.seed.unwrap_or(scene.integrator.seed),
        "integrator": opts.integrator.unwrap_or(scene.integrator.kind),
        "sampler": scene.integrator.sampler.name(),
        "estimators": format!("{:?}", opts.boundary),
        "guiding": opts.guiding,
        "fast_traversal": opts.fast_traversal,
        "steady": opts.steady,
        "time_edges": opts.time_edges,
        "lanes": format!("{:?}", opts.lanes),
        "version": env!("CARGO_PKG_VERSION"),
    }))
}

/// The SHA-256 of the contents of a scene's input files (the description and the meshes it
/// reads), each preceded by its length: the identity's `inputs_sha256`.
pub(super) fn inputs_sha256(scene: &Scene) -> anyhow::Result<String> {
    let mut hash = Sha256::new();
    for input in &scene.inputs {
        let bytes =
            std::fs::read(input).with_context(|| format!("cannot read {} again to hash it", input.display()))?;
        hash.update((bytes.len() as u64).to_le_bytes());
        hash.update(&bytes);
    }
    Ok(hex(&hash.finalize()))
}

#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// The shards' output prefixes (as given to `dtr render -o`; a trailing .json or .npy is
    /// dropped): every shard I/N of one render, once each, in any order.
    #[arg(required = true)]
    pub shards: Vec<PathBuf>,
    /// Output prefix of the merged render (same rules as `dtr render -o`).
    #[arg(short = 'o', long = "output", value_name = "PREFIX")]
    pub output: PathBuf,
    /// Also write PREFIX.exr: the steady image as the default layer and one layer per time bin (t0000, …), with the time axis in its header.
    #[arg(long)]
    pub exr: bool,
    /// Also write the previews (contact sheet, steady image, plot), as `dtr render --preview`.
    #[arg(long)]
    pub preview: bool,
    /// The scene file the shards rendered, where the path their JSON records does not reach it
    /// from here. Only an NLOS capture's merge reads it: its HDF5 file and noisy copy are made
    /// from the scene's relay wall, laser and noise model. Its inputs must hash to what the
    /// shards rendered.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
}

/// One shard's output set, read back.
struct ShardFiles {
    prefix: PathBuf,
    meta: Value,
    shard: Shard,
}

fn strip_ext(p: &Path) -> PathBuf {
    match p.extension().and_then(|e| e.to_str()) {
        Some("json" | "npy") => p.with_extension(""),
        _ => p.to_path_buf(),
    }
}

fn read_shard(prefix: &Path) -> anyhow::Result<ShardFiles> {
    let path = with_suffix(prefix, "json");
    let text = crate::scene::read_regular_file(&path, JSON_CAP)
        .with_context(|| format!("{}: cannot read the shard's JSON", path.display()))?;
    let meta: Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not the JSON of a dtr render", path.display()))?;
    let field = |name: &str| {
        meta.get(name).with_context(|| {
            format!(
                "{}: no field {name:?}: not written by `dtr render --shard I/N` of this version",
                path.display()
            )
        })
    };
    let s = field("shard")?;
    let num = |k: &str| s.get(k).and_then(Value::as_u64).and_then(|v| u32::try_from(v).ok());
    let (Some(index), Some(count)) = (num("index"), num("count")) else {
        bail!(
            "{}: field \"shard\" needs integer \"index\" and \"count\"",
            path.display()
        );
    };
    let shard = Shard::new(index, count).with_context(|| format!("{}: field \"shard\"", path.display()))?;
    field("identity")?;
    check_tallies(&meta, &path)?;
    Ok(ShardFiles {
        prefix: prefix.to_path_buf(),
        meta,
        shard,
    })
}

/// The counts of a shard's JSON that the merge adds up.
const COUNTS: [&str; 6] = [
    "paths",
    "rays",
    "intersect_rays",
    "occluded_rays",
    "non_finite_samples",
    "boundary_samples",
];

/// The seconds of a shard's JSON that the merge adds up.
const SECONDS: [&str; 6] = [
    "wall_seconds",
    "cpu_seconds",
    "total_wall_seconds",
    "total_cpu_seconds",
    "boundary_seconds",
    "bvh_build_seconds",
];

/// The phases of a shard's `phase_seconds`.
const PHASES: [&str; 3] = ["tracing", "shading", "film"];

/// What a tally of a shard's JSON must be for the merge to add it up.
#[derive(Clone, Copy)]
enum Tally {
    /// paths, rays, samples: an integer >= 0
    Count,
    /// seconds, a primal energy (radiance is never negative): a number >= 0
    NonNegative,
    /// a derivative's energy: a number of either sign, or null where it was not measured
    NumberOrNull,
}

/// Refuses a tally of the shard JSON `path` that the merge would add up into nonsense (a
/// negative count of paths, a negative energy, a string) or that is missing (every render
/// writes all of them; [`merged_metadata`] would count it 0), naming the file and the field:
/// a damaged or edited JSON is refused rather than merged.
fn check_tallies(meta: &Value, path: &Path) -> anyhow::Result<()> {
    use Tally::*;
    let mut tallies: Vec<(String, Tally)> = COUNTS.iter().map(|k| (k.to_string(), Count)).collect();
    tallies.extend(SECONDS.iter().map(|k| (k.to_string(), NonNegative)));
    tallies.extend(PHASES.iter().map(|k| (format!("phase_seconds.{k}"), NonNegative)));
    tallies.extend(["before", "inside", "after", "total"].map(|k| (format!("energy.primal.{k}"), NonNegative)));
    tallies.push(("energy.primal.after_pilot_paths".into(), Count));
    // one energy record per derivative the render wrote
    let derivatives = meta["derivatives"].as_array().map_or(0, Vec::len);
    match meta.pointer("/energy/derivatives") {
        Some(Value::Array(a)) if a.len() == derivatives => {}
        v => bail!(
            "{}: field \"energy.derivatives\": {}: the shard's JSON was changed or damaged",
            path.display(),
            match v {
                None => "missing".to_string(),
                Some(v) => format!(
                    "expected a list of {derivatives} (one per entry of \"derivatives\"), got {}",
                    v.as_array().map_or(v.to_string(), |a| format!("{} entries", a.len()))
                ),
            }
        ),
    }
    for k in 0..derivatives {
        tallies.extend(["total", "inside", "outside"].map(|f| (format!("energy.derivatives.{k}.{f}"), NumberOrNull)));
    }
    for (field, tally) in tallies {
        let Some(v) = meta.pointer(&format!("/{}", field.replace('.', "/"))) else {
            bail!(
                "{}: field \"{field}\": missing: the shard's JSON was changed or damaged",
                path.display()
            );
        };
        let (ok, expected) = match tally {
            Count => (v.as_u64().is_some(), "a count (an integer >= 0)"),
            NonNegative => (
                v.as_f64().is_some_and(|x| x.is_finite() && x >= 0.0),
                "a finite number >= 0",
            ),
            NumberOrNull => (
                v.is_null() || v.as_f64().is_some_and(f64::is_finite),
                "a finite number or null",
            ),
        };
        if !ok {
            bail!(
                "{}: field \"{field}\": expected {expected}, got {v}: the shard's JSON was changed or damaged",
                path.display()
            );
        }
    }
    Ok(())
}

/// The shards, checked to be exactly the shards 0..N of one render.
fn check_complete(shards: &mut [ShardFiles]) -> anyhow::Result<()> {
    let first = &shards[0];
    let json0 = with_suffix(&first.prefix, "json");
    for s in shards.iter().skip(1) {
        let path = with_suffix(&s.prefix, "json");
        if s.shard.count != first.shard.count {
            bail!(
                "{} is shard {} but {} is shard {}: not shards of one split",
                path.display(),
                s.shard,
                json0.display(),
                first.shard
            );
        }
        let (a, b) = (&first.meta["identity"], &s.meta["identity"]);
        if a != b {
            let keys: Vec<String> = a.as_object().map(|o| o.keys().cloned().collect()).unwrap_or_default();
            let key = keys.into_iter().find(|k| a.get(k) != b.get(k)).unwrap_or_default();
            bail!(
                "{} and {} are not shards of one render: identity.{key} differs ({} vs {})",
                json0.display(),
                path.display(),
                a.get(&key).unwrap_or(a),
                b.get(&key).unwrap_or(b),
            );
        }
    }
    shards.sort_by_key(|s| s.shard.index);
    for pair in shards.windows(2) {
        if pair[0].shard.index == pair[1].shard.index {
            bail!(
                "shard {} is given twice ({} and {}): the shards overlap",
                pair[0].shard,
                pair[0].prefix.display(),
                pair[1].prefix.display()
            );
        }
    }
    let n = shards[0].shard.count;
    let have: Vec<u32> = shards.iter().map(|s| s.shard.index).collect();
    let missing: Vec<String> = (0..n)
        .filter(|i| !have.contains(i))
        .map(|i| format!("{i}/{n}"))
        .collect();
    if !missing.is_empty() {
        bail!(
            "missing shard(s) {}: the merge needs every shard of the render",
            missing.join(", ")
        );
    }
    Ok(())
}

fn shape_of(meta: &Value, path: &Path) -> anyhow::Result<[usize; 4]> {
    let v: Vec<usize> = meta["shape"]
        .as_array()
        .map(|a| a.iter().filter_map(|d| d.as_u64().map(|d| d as usize)).collect())
        .unwrap_or_default();
    v.try_into()
        .map_err(|_| anyhow::anyhow!("{}: field \"shape\" should be [H, W, T, C]", path.display()))
}

pub(super) fn axis_of(meta: &Value, path: &Path) -> anyhow::Result<crate::temporal::TimeAxis> {
    serde_json::from_value(meta["time_axis"].clone()).with_context(|| {
        format!(
            "{}: field \"time_axis\" should hold start_opl, bin_width_opl, bins",
            path.display()
        )
    })
}

/// What the shard's .npy files are, in messages.
const FILM: &str = "the shard's film (its JSON gives the shape)";

/// Reads one shard's films: the transient with its steady image, then each derivative.
fn read_films(s: &ShardFiles, diff: &[String]) -> anyhow::Result<(Transient, Vec<Transient>)> {
    let json = with_suffix(&s.prefix, "json");
    let [h, w, t, c] = shape_of(&s.meta, &json)?;
    let axis = axis_of(&s.meta, &json)?;
    if axis.bins != t {
        bail!(
            "{}: time_axis.bins {} but shape has {t} bins",
            json.display(),
            axis.bins
        );
    }
    // films of what the files hold, never allocated from the JSON's shape before a file
    // has been found to hold it (an edited shape of [4096, 4096, 20000, 3] aborted the merge)
    let film = |data: Vec<f32>, steady: Vec<f32>| Transient {
        width: w,
        height: h,
        axis,
        channels: c,
        data,
        steady,
    };
    let read = |suffix: &str, shape: &[usize]| {
        let path = with_suffix(&s.prefix, suffix);
        read_f32_hashed(&path, shape, FILM, |got| check_digest(s, &json, &path, got))
    };
    let data = read("npy", &[h, w, t, c])?;
    refuse_negative(&with_suffix(&s.prefix, "npy"), &data)?;
    let steady = read("steady.npy", &[h, w, c])?;
    refuse_negative(&with_suffix(&s.prefix, "steady.npy"), &steady)?;
    let transient = film(data, steady);
    let mut derivs = Vec::new();
    for name in diff {
        let data = read(&format!("d_{name}.npy"), &[h, w, t, c])?;
        derivs.push(film(data, vec![0.0; transient.steady.len()]));
    }
    Ok((transient, derivs))
}

/// Refuses shards whose films (`suffix`: `npy`, `d_NAME.npy`), each finite, add up to `sum`
/// with values past the largest 32-bit float, before anything is written: no render's films
/// come near it (an emitter's strength is at most 10¹⁸, `scene::limits::MAX_EMISSION`), so
/// the shards were changed. Before, two shards of 3·10³⁸ everywhere (their hashes recomputed)
/// failed writing the merged .npy with exit 1, an internal failure.
fn refuse_overflowing_sum(shards: &[ShardFiles], suffix: &str, sum: &Transient) -> anyhow::Result<()> {
    let bad = sum.non_finite_count();
    if bad > 0 {
        let files: Vec<String> = shards
            .iter()
            .map(|s| with_suffix(&s.prefix, suffix).display().to_string())
            .collect();
        bail!(
            "{}: the shards' films add up past the largest 32-bit float (3.4e38) at {bad} of {} values; \
             expected films a render writes, which stay far below it: the shards were changed or damaged",
            files.join(", "),
            sum.data.len() + sum.steady.len()
        );
    }
    Ok(())
}

/// Refuses a shard's transient or steady image (`path`, read into `data`) that holds a
/// negative value: light arrives or it does not, so no render writes one (its derivatives may
/// be negative, and are only checked finite). Before, a shard whose .npy was rewritten with
/// -1 everywhere and its SHA-256 recorded again merged with exit 0 (independent audit).
fn refuse_negative(path: &Path, data: &[f32]) -> anyhow::Result<()> {
    let bad = data.iter().filter(|&&v| v < 0.0).count();
    if bad > 0 {
        let lowest = data.iter().copied().fold(0.0f32, f32::min);
        bail!(
            "{}: {bad} of {} values of {FILM} are negative (the lowest is {lowest:e}); expected values >= 0, \
             as a render writes them (light never subtracts): the shard was changed or damaged",
            path.display(),
            data.len()
        );
    }
    Ok(())
}

/// Refuses a shard's file whose bytes are not those its render wrote (damaged on disk, or
/// another render's file copied over it): its SHA-256 `got`, hashed as the file was read
/// (`npy_in::read_f32_hashed`), against the one the shard's JSON records (`files_sha256`). Before, a float flipped to 3.4·10³⁸ or another seed's .npy
/// merged with exit 0.
/// The record is keyed by the file names the render wrote; shards renamed since (collected
/// from nodes under new names, same bytes) are looked up by their suffix under the name the
/// JSON's `files` gives the render's own JSON (before, they were refused as "not written by
/// this version").
fn check_digest(s: &ShardFiles, json: &Path, path: &Path, got: &str) -> anyhow::Result<()> {
    let name = path.file_name().unwrap_or_default().to_string_lossy().into_owned();
    let stem = s.prefix.file_name().unwrap_or_default().to_string_lossy().into_owned();
    let written = s.meta["files"].as_array().and_then(|f| {
        f.iter()
            .filter_map(|v| v.as_str())
            .find_map(|f| f.strip_suffix(".json"))
    });
    let name = match (name.strip_prefix(&format!("{stem}.")), written) {
        (Some(suffix), Some(written)) => format!("{written}.{suffix}"),
        _ => name,
    };
    let Some(want) = s.meta["files_sha256"][name.as_str()].as_str() else {
        bail!(
            "{}: no field \"files_sha256.{name}\": not written by `dtr render --shard I/N` of this version",
            json.display()
        );
    };
    if got != want {
        bail!(
            "{}: not the file this shard's render wrote (its SHA-256 is {got}, {} records {want}): damaged, or another render's",
            path.display(),
            json.display()
        );
    }
    Ok(())
}

pub fn run(a: MergeArgs) -> anyhow::Result<()> {
    let mut shards = a
        .shards
        .iter()
        .map(|p| read_shard(&strip_ext(p)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    check_complete(&mut shards)?;
    let diff: Vec<String> = serde_json::from_value(shards[0].meta["identity"]["diff"].clone())
        .context("the shards' identity.diff should be a list of parameter names")?;
    let capture = capture_scene(&shards[0], a.scene.as_deref())?;
    // every file of every shard is an input: the merge never replaces one
    let mut inputs = Vec::new();
    for s in &shards {
        inputs.extend(["json", "npy", "steady.npy"].iter().map(|e| with_suffix(&s.prefix, e)));
        inputs.extend(diff.iter().map(|n| with_suffix(&s.prefix, &format!("d_{n}.npy"))));
    }
    let scene_path = PathBuf::from(shards[0].meta["scene"].as_str().unwrap_or("merged"));
    let mut planned: Vec<String> = vec!["npy".into(), "json".into()];
    planned.extend(diff.iter().map(|n| format!("d_{n}.npy")));
    if let Some(scene) = &capture {
        inputs.extend(scene.inputs.iter().cloned());
        planned.extend(super::nlos_out::planned(scene, false));
    }
    if a.exr {
        let json = with_suffix(&shards[0].prefix, "json");
        let [_, _, bins, channels] = shape_of(&shards[0].meta, &json)?;
        if let Some(why) = crate::output::too_many_channels(bins, channels) {
            bail!("{}: --exr: {why}", json.display());
        }
        planned.push("exr".into());
    }
    if a.preview {
        planned.extend(super::render_cmd::preview_files(&diff));
    }
    let mut set = OutputSet::prepare(&a.output, &inputs, &scene_path, &planned)?;
    // one shard's films in memory at a time, added in shard order (`shard::FilmSum`)
    let mut sums: Option<(FilmSum, Vec<FilmSum>)> = None;
    for (i, s) in shards.iter().enumerate() {
        let (f, d) = read_films(s, &diff)?;
        let (film_sum, deriv_sums) =
            sums.get_or_insert_with(|| (FilmSum::like(&f), d.iter().map(FilmSum::like).collect()));
        film_sum.add(i, &f)?;
        for (sum, d) in deriv_sums.iter_mut().zip(&d) {
            sum.add(i, d)?;
        }
    }
    let (film_sum, deriv_sums) = sums.context("no shards to merge")?;
    let film = film_sum.finish();
    let derivs: Vec<Transient> = deriv_sums.into_iter().map(FilmSum::finish).collect();
    refuse_overflowing_sum(&shards, "npy", &film)?;
    for (name, d) in diff.iter().zip(&derivs) {
        refuse_overflowing_sum(&shards, &format!("d_{name}.npy"), d)?;
    }
    set.write("npy", |p| crate::output::write_npy(p, &film.shape(), &film.data))?;
    for (name, d) in diff.iter().zip(&derivs) {
        set.write(&format!("d_{name}.npy"), |p| {
            crate::output::write_npy(p, &d.shape(), &d.data)
        })?;
    }
    if let Some(scene) = &capture {
        super::nlos_out::write(scene, &film, &mut set, false)?;
    }
    if a.exr {
        let axis = (film.axis.start_opl, film.axis.bin_width_opl);
        set.write("exr", |p| {
            crate::output::write_exr_layers_with_axis(p, super::render_cmd::view(&film), &film.steady, axis)
        })?;
    }
    if a.preview {
        super::render_cmd::write_previews(&film, &diff, &derivs, &mut set, None, crate::output::Normalise::Global)?;
    }
    let mut meta = merged_metadata(&shards, set.prefix(), &diff);
    if let Some(n) = capture
        .as_ref()
        .and_then(|scene| super::nlos_out::describe(scene, set.prefix(), false))
    {
        meta["nlos"] = n;
    }
    meta["files"] = json!(set.names_with("json"));
    let warning = meta["energy"]["warning"].as_str().map(str::to_string);
    set.write("json", |p| crate::output::write_json(p, &meta))?;
    let prefix = set.commit()?;
    if let Some(w) = warning {
        log::warn!("{}: {w}", scene_path.display());
    }
    log::info!(
        "{}: {} shards merged ({}x{}x{}x{})",
        with_suffix(&prefix, "npy").display(),
        shards.len(),
        film.height,
        film.width,
        film.axis.bins,
        film.channels
    );
    Ok(())
}

/// The scene an NLOS capture's shards rendered, loaded with their `--set`s, for the merged
/// capture's HDF5 file and noisy copy (`nlos_out`), which the relay wall, the laser and the
/// noise model make; `None` for any other render. Refused, naming the file, where the scene
/// does not load (give `--scene`) or its inputs no longer hash to what the shards rendered.
fn capture_scene(first: &ShardFiles, given: Option<&Path>) -> anyhow::Result<Option<Scene>> {
    if first.meta["nlos"].is_null() {
        return Ok(None);
    }
    let json = with_suffix(&first.prefix, "json");
    let identity = &first.meta["identity"];
    let path = match (given, first.meta["scene"].as_str()) {
        (Some(p), _) => p.to_path_buf(),
        (None, Some(p)) => PathBuf::from(p),
        (None, None) => bail!(
            "{}: an NLOS capture without its field \"scene\": give the scene it rendered with --scene FILE",
            json.display()
        ),
    };
    let sets: Vec<String> = serde_json::from_value(identity["set"].clone()).with_context(|| {
        format!(
            "{}: field \"identity.set\" should be a list of NAME=VALUE",
            json.display()
        )
    })?;
    let super::Sets { numbers, texts } =
        super::parse_sets(&sets).with_context(|| format!("{}: field \"identity.set\"", json.display()))?;
    let scene = Scene::load_with_text(&path, &numbers, &texts).with_context(|| {
        format!(
            "{}: the merged capture's HDF5 file and noisy copy are made from the scene the shards rendered ({}), which does not load here; give it with --scene FILE",
            json.display(),
            path.display()
        )
    })?;
    let digest = inputs_sha256(&scene)?;
    let want = identity["inputs_sha256"].as_str().unwrap_or("");
    if digest != want {
        bail!(
            "{}: not the scene the shards rendered: its input files hash to {digest}, {} records {want} (edited since?); give the scene as rendered with --scene FILE",
            path.display(),
            json.display()
        );
    }
    Ok(Some(scene))
}

/// The merged render's JSON: the first shard's, with the additive tallies summed over the
/// shards, the energy report recombined, and each shard's own record under `shards`.
fn merged_metadata(shards: &[ShardFiles], prefix: &Path, diff: &[String]) -> Value {
    let mut meta = shards[0].meta.clone();
    let sum = |k: &str| -> f64 { shards.iter().map(|s| s.meta[k].as_f64().unwrap_or(0.0)).sum() };
    for k in COUNTS {
        meta[k] = json!(sum(k) as u64);
    }
    for k in SECONDS {
        meta[k] = json!(sum(k));
    }
    for k in PHASES {
        meta["phase_seconds"][k] = json!(
            shards
                .iter()
                .map(|s| s.meta["phase_seconds"][k].as_f64().unwrap_or(0.0))
                .sum::<f64>()
        );
    }
    let (paths, rays, cpu, wall) = (
        sum("paths"),
        sum("rays"),
        sum("cpu_seconds").max(1e-9),
        sum("wall_seconds").max(1e-9),
    );
    meta["paths_per_cpu_second"] = json!(paths / cpu);
    meta["rays_per_cpu_second"] = json!(rays / cpu);
    meta["paths_per_second"] = json!(paths / wall);
    meta["rays_per_second"] = json!(rays / wall);
    meta["threads"] = Value::Null;
    meta["boundary"] = Value::Null;
    meta["derivatives"] = json!(
        diff.iter()
            .zip(meta["derivatives"].as_array().cloned().unwrap_or_default())
            .map(|(n, mut d)| {
                d["file"] = json!(format!("{}.d_{n}.npy", prefix.display()));
                d
            })
            .collect::<Vec<_>>()
    );
    meta["energy"] = merged_energy(shards);
    // a shard's own records: the merged set is a render, which has neither (the digests
    // were shard 0's files', under their names, until the forty-third session)
    if let Some(o) = meta.as_object_mut() {
        o.remove("shard");
        o.remove("files_sha256");
    }
    meta["merged"] = json!({
        "about": "dtr merge: the films are the sums of the shards' films (added in f64); paths, rays and seconds are summed over the shards (per-second rates divide by the summed seconds); threads and the boundary record are per shard, under shards",
        "shards": shards.iter().map(|s| json!({
            "prefix": s.prefix.display().to_string(),
            "shard": s.meta["shard"],
            "threads": s.meta["threads"],
            "wall_seconds": s.meta["wall_seconds"],
            "cpu_seconds": s.meta["cpu_seconds"],
            "boundary": s.meta["boundary"],
        })).collect::<Vec<_>>(),
    });
    meta
}

/// The energy report of the whole render from its shards': before and inside add up; after
/// adds up too, unless an uncut pilot estimated it (every shard runs the same pilot, so any
/// one of them holds the whole render's estimate).
fn merged_energy(shards: &[ShardFiles]) -> Value {
    let e = |s: &ShardFiles, k: &str| s.meta["energy"]["primal"][k].as_f64().unwrap_or(0.0);
    let sum = |k: &str| shards.iter().map(|s| e(s, k)).sum::<f64>();
    let pilot = shards[0].meta["energy"]["primal"]["after_pilot_paths"]
        .as_u64()
        .unwrap_or(0);
    let (before, inside) = (sum("before"), sum("inside"));
    let (after, total) = if pilot > 0 {
        let after = e(&shards[0], "after");
        (after, before + inside + after)
    } else {
        (sum("after"), sum("total"))
    };
    let primal = crate::film::WindowEnergy {
        total,
        before,
        inside,
        after,
        inside_fraction: if total > 0.0 { inside / total } else { 0.0 },
        after_pilot_paths: pilot,
        // the pilot's, as its `after` (any shard's; none when measured on every path)
        after_standard_error: shards[0].meta["energy"]["primal"]["after_standard_error"]
            .as_f64()
            .filter(|_| pilot > 0),
    };
    let mut energy = shards[0].meta["energy"].clone();
    let axis = axis_of(&shards[0].meta, Path::new("shard 0")).ok();
    energy["primal"] = json!(primal);
    energy["warning"] = json!(axis.and_then(|a| primal.warning(&a)));
    let derivs = energy["derivatives"].as_array().cloned().unwrap_or_default();
    energy["derivatives"] = json!(derivs
        .iter()
        .enumerate()
        .map(|(k, d)| {
            let part = |f: &str| -> Option<f64> {
                shards.iter().map(|s| s.meta["energy"]["derivatives"][k][f].as_f64()).sum()
            };
            json!({"param": d["param"], "total": part("total"), "inside": part("inside"), "outside": part("outside")})
        })
        .collect::<Vec<_>>());
    energy
}

#[cfg(test)]
mod tests {
    use super::canonical_set;

    #[test]
    fn settings_are_compared_as_what_they_set() {
        assert_eq!(canonical_set("x = 1"), canonical_set("x=1"));
        assert_eq!(canonical_set("nlos.grid=[3, 3]"), canonical_set("nlos.grid=[3,3]"));
        assert_eq!(
            canonical_set("nlos.scan=exhaustive"),
            canonical_set("nlos.scan = \"exhaustive\"")
        );
        assert_ne!(
            canonical_set("nlos.hidden_shapes=[\"a b\"]"),
            canonical_set("nlos.hidden_shapes=[\"ab\"]")
        );
        assert_ne!(
            canonical_set("nlos.scan=exhaustive"),
            canonical_set("nlos.scan=confocal")
        );
    }
}
