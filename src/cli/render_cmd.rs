//! `dtr render`.

use super::output_set::{OutputSet, with_suffix};
use crate::film::{SteadyMode, Transient};
use crate::kernel::SampleSequence;
use crate::named::Named;
use crate::output::{self, FilmView};
use crate::render::{
    BoundaryMode, Lanes, RenderOptions, RenderStats, TimeEdgeMode, render, render_diff, render_strategies,
};
use crate::scene::{IntegratorKind, Scene};
use crate::temporal::{SPEED_OF_LIGHT_M_PER_S, TimeAxis};
use anyhow::{Context, bail};
use serde_json::json;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Scene description (.toml or .json, or a Mitsuba 3 .xml: scenes/README.md).
    pub scene: PathBuf,
    /// Output prefix: writes PREFIX.npy ([H, W, T, C] float32) and PREFIX.json. A trailing
    /// .npy is dropped; a folder (ending in /) gets the scene file's name. Outputs never
    /// replace an input and appear all at once.
    #[arg(short = 'o', long = "output", value_name = "PREFIX")]
    pub output: PathBuf,
    /// Samples per pixel (overrides the scene).
    #[arg(long, allow_negative_numbers = true)]
    pub spp: Option<i64>,
    /// Random seed (overrides the scene).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Override a parameter value: --set NAME=VALUE (repeatable; see `dtr info`), or any field
    /// of the description by its dotted path: --set film.bins=100, --set camera.resolution.0=128,
    /// --set nlos.scan=exhaustive, --set 'nlos.grid=[8, 8]' (values other than numbers as in TOML).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Also write PREFIX.exr: the steady image as the default layer and one layer per time bin (t0000, …), with the time axis in its header.
    #[arg(long)]
    pub exr: bool,
    /// Also write PREFIX.frames.png (contact sheet, frames labelled with their time, log scale), PREFIX.steady.png, PREFIX.steady.npy (the
    /// HDR time-integrated image, [H, W, C]), PREFIX.plot.png (radiance over time for the whole
    /// image and one pixel), PREFIX.flight.gif (light in flight, one frame per bin, log scale),
    /// PREFIX.streak.png (the --pixel row against time) and, with --diff, PREFIX.d_NAME.png
    /// (each derivative integrated over time, blue negative, red positive).
    #[arg(long)]
    pub preview: bool,
    /// Pixel for the preview plot and the streak image's row, as X,Y (default: the image centre).
    #[arg(long, value_name = "X,Y")]
    pub pixel: Option<String>,
    /// Display white of the light-in-flight animation and the contact sheet: one for the whole
    /// film (`global`, the default: frames compare) or one per frame (`frame`, every frame shows
    /// its structure). Needs --preview.
    #[arg(long, value_name = "global|frame", value_parser = ["global", "frame"])]
    pub normalise: Option<String>,
    /// Choose the time window (film.start_opl, film.bin_width_opl; the scene's bins kept) from a
    /// short pilot render that finds where the light arrives and decays (src/auto_window.rs).
    #[arg(long)]
    pub auto_window: bool,
    /// Also differentiate with respect to these parameters (comma-separated names from
    /// `dtr info`): writes PREFIX.d_NAME.npy, same shape as the transient.
    #[arg(long, value_delimiter = ',', value_name = "NAME[,NAME...]")]
    pub diff: Vec<String>,
    /// Integrator (overrides the scene's [integrator] kind): `path` (unidirectional, the
    /// default) or `bdpt` (bidirectional with MIS).
    #[arg(long, value_name = "path|bdpt", value_parser = IntegratorKind::from_name)]
    pub integrator: Option<IntegratorKind>,
    /// Also write one transient per BDPT strategy, PREFIX.s{S}_t{T}.npy (MIS-weighted
    /// contributions; they sum to the transient). Needs the bdpt integrator.
    #[arg(long)]
    pub strategies: bool,
    /// Boundary samples per pixel for --diff (default: the interior's spp): the secondary-edge
    /// pass draws this many boundary rays per film pixel.
    #[arg(long = "spp-boundary", allow_negative_numbers = true, value_name = "N")]
    pub spp_boundary: Option<i64>,
    /// Which parts of the gradient --diff estimates: full (interior + boundary), interior
    /// (Algorithm 1 alone: misses moving visibility), boundary (primal left zero), or one
    /// boundary term alone to see where a derivative's noise comes from: primary (silhouettes
    /// seen from the camera) or secondary (edges seen from path vertices). Default: full.
    #[arg(long, value_enum)]
    pub estimators: Option<BoundaryMode>,
    /// Guide the boundary rays with grids fitted by a pilot pass (1/8 of the boundary
    /// samples): lower mean error from ~16k samples on, heavier tails (see README).
    #[arg(long)]
    pub guiding: bool,
    /// Forward renders: trace in Embree's faster, non-watertight mode (a ray through exactly a
    /// shared edge may slip through, so light can leak out of closed objects now and then).
    #[arg(long = "fast-traversal")]
    pub fast_traversal: bool,
    /// The numbers paths draw (overrides the scene's [integrator] sampler, whose default is
    /// `sobol`): `sobol` (Owen-scrambled Sobol points, stratified over each pixel's samples:
    /// lower error per sample at about the same cost; see BENCHMARKS.md) or `independent`.
    #[arg(long, value_name = "independent|sobol", value_parser = SampleSequence::from_name)]
    pub sampler: Option<SampleSequence>,
    /// What the steady image (PREFIX.steady.png, the JSON's energy) integrates: `window`
    /// (default: the time window; paths end once they cannot reach it, the transient is
    /// unchanged) or `full` (all time: every path is traced to its last bounce).
    #[arg(long, value_enum, default_value = "window")]
    pub steady: Steady,
    /// How --diff's path tracer estimates the time term f·Ṡ_e·ḋ: `auto` (default: from light
    /// points drawn where a connection's OPL crosses a bin edge, with a box gate, for area
    /// emitters whose pulse is delta or at most half a bin wide (standard deviation): much
    /// lower variance there, and what makes a delta pulse's derivative possible) or `off`
    /// (from the ordinary next-event and emission contributions). Needs --diff.
    #[arg(long = "time-edges", value_enum)]
    pub time_edges: Option<TimeEdgeMode>,
    /// Render shard I of N (0-based): this shard's part of every estimator's samples,
    /// normalised so that the N shards add up to the whole render; `dtr merge` adds them.
    /// Also writes PREFIX.steady.npy (the steady image, for the merge).
    #[arg(long, value_name = "I/N", value_parser = parse_shard)]
    pub shard: Option<crate::shard::Shard>,
    /// Write the finished work to PREFIX.checkpoint every SECONDS (and on SIGINT/SIGTERM/SIGHUP), so
    /// that `--resume` continues an interrupted render to the same bytes.
    #[arg(long, value_name = "SECONDS")]
    pub checkpoint: Option<f64>,
    /// Continue the render saved in PREFIX.checkpoint (same scene, overrides and settings;
    /// any thread count). Keeps checkpointing (every --checkpoint seconds, default 300).
    #[arg(long)]
    pub resume: bool,
    /// Trace one path at a time instead of 8-wide packets (reference/debug).
    #[arg(long)]
    pub scalar: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Steady {
    Window,
    Full,
}

/// `--estimators` and `--time-edges` take the library's names ([`Named`]), the lists Python's
/// `estimators=` and `time_edges=` read too.
macro_rules! value_enum_by_name {
    ($($t:ty),*) => {$(
        impl clap::ValueEnum for $t {
            fn value_variants<'a>() -> &'a [Self] {
                <$t as Named>::ALL
            }

            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                Some(clap::builder::PossibleValue::new(self.name()))
            }
        }
    )*};
}
value_enum_by_name!(BoundaryMode, TimeEdgeMode);

/// A sample count given as `flag`: positive, and at most what the renderer counts in (u32).
fn sample_count(flag: &str, n: i64) -> anyhow::Result<u32> {
    if n <= 0 {
        bail!("{flag} must be a positive integer (got {n})");
    }
    u32::try_from(n).map_err(|_| anyhow::anyhow!("{flag} must be at most {} (got {n})", u32::MAX))
}

pub fn run(a: RenderArgs) -> anyhow::Result<()> {
    let super::Sets {
        numbers: mut overrides,
        texts,
    } = super::parse_sets(&a.set)?;
    let spp = a.spp.map(|n| sample_count("--spp", n)).transpose()?;
    let spp_boundary = a.spp_boundary.map(|n| sample_count("--spp-boundary", n)).transpose()?;
    if let Some(name) = first_repeat(a.diff.iter().map(|s| s.trim())) {
        bail!("--diff names {name} more than once");
    }
    if let Some(t) = a.threads.filter(|&t| t == 0 || t > crate::render::MAX_THREADS) {
        bail!("--threads {t}: expected 1 ..= {}", crate::render::MAX_THREADS);
    }
    if a.spp_boundary.is_some() && a.diff.is_empty() {
        bail!("--spp-boundary sets the boundary samples of a derivative render; it needs --diff");
    }
    refuse_settings_without_their_output(&a)?;
    let estimators = a.estimators.unwrap_or(BoundaryMode::Full);
    refuse_unused_boundary_samples(a.spp_boundary, estimators)?;
    if a.guiding && !estimators.stages().secondary {
        bail!(
            "--guiding guides the secondary boundary term's samples, which --estimators {} leaves out; drop one of them",
            estimators.name()
        );
    }
    let auto_window = if a.auto_window {
        if let Some((n, _)) = overrides
            .iter()
            .find(|(n, _)| n == "film.start_opl" || n == "film.bin_width_opl")
        {
            bail!("--auto-window chooses {n}; drop --set {n}=… or --auto-window");
        }
        let pilot = RenderOptions {
            seed: a.seed,
            threads: a.threads,
            fast_traversal: a.fast_traversal,
            ..Default::default()
        };
        let w = crate::auto_window::choose_window_with(&a.scene, &overrides, &pilot, |o| {
            Ok(Scene::load_with_text(&a.scene, o, &texts)?)
        })?;
        log::info!(
            "{}: auto window [{:.4}, {:.4}] m of OPL ({:.3} to {:.3} ns), {} bins of {:.5} m (pilot {}x{}, {} spp, {:.2} s)",
            a.scene.display(),
            w.start_opl,
            w.start_opl + w.bin_width_opl * w.bins as f64,
            TimeAxis::time_ns_of_opl(w.start_opl),
            TimeAxis::time_ns_of_opl(w.start_opl + w.bin_width_opl * w.bins as f64),
            w.bins,
            w.bin_width_opl,
            w.pilot_resolution[0],
            w.pilot_resolution[1],
            w.pilot_spp,
            w.pilot_seconds
        );
        overrides.extend(w.overrides());
        Some(w)
    } else {
        None
    };
    let mut scene = Scene::load_with_text(&a.scene, &overrides, &texts)?;
    if let Some(s) = a.sampler {
        scene.integrator.sampler = s;
    }
    let scene = scene;
    log::debug!(
        "{}: {} shapes, {} triangles, {} emitters, {} materials, {} parameters; film {}x{}x{} channel(s), {} bins of {} m from {} m; max_bounces {}",
        a.scene.display(),
        scene.shapes.len(),
        scene.geometry.indices.len(),
        scene.emitters.len(),
        scene.materials.len(),
        scene.params.len(),
        scene.film.width,
        scene.film.height,
        scene.film.channels,
        scene.film.axis.bins,
        scene.film.axis.bin_width_opl,
        scene.film.axis.start_opl,
        scene.integrator.max_bounces
    );
    let bounces = scene.integrator.max_bounces;
    if a.integrator.unwrap_or(scene.integrator.kind) == IntegratorKind::Bdpt && bounces > BDPT_WARN_BOUNCES {
        // every (s, t) split of every path length is joined: about (B + 2)(B + 3)/2 strategies
        log::warn!(
            "{}: BDPT with max_bounces = {bounces} joins about {} strategies per path (cost grows as \
             max_bounces³; 1 s per path at 1024); the path tracer (--integrator path) grows linearly",
            a.scene.display(),
            (bounces as u64 + 2) * (bounces as u64 + 3) / 2
        );
    }
    if matches!(estimators, BoundaryMode::InteriorOnly) {
        warn_interior_alone(&scene, &a.diff, &a.scene);
    }
    let pixel = match &a.pixel {
        Some(s) => Some(parse_pixel(s, &scene)?),
        None => None,
    };
    let opts = RenderOptions {
        spp,
        seed: a.seed,
        threads: a.threads,
        progress: super::logging::chatty(),
        lanes: if a.scalar { Lanes::Scalar } else { Lanes::Simd8 },
        integrator: a.integrator,
        spp_boundary,
        guiding: a.guiding,
        fast_traversal: a.fast_traversal,
        steady: match a.steady {
            Steady::Window => SteadyMode::Window,
            Steady::Full => SteadyMode::Full,
        },
        boundary: estimators,
        shard: a.shard.unwrap_or_default(),
        checkpoint: None,
        time_edges: a.time_edges.unwrap_or_default(),
        ..Default::default()
    };
    if let Some(t) = a.checkpoint {
        super::checkpoint_cmd::check_interval(t)?;
    }
    if (a.checkpoint.is_some() || a.resume) && a.strategies {
        bail!("--strategies cannot be checkpointed; render it without --checkpoint/--resume");
    }
    if a.shard.is_some() && a.strategies {
        bail!("--strategies cannot be sharded; render it in one process");
    }
    if a.strategies && !a.diff.is_empty() {
        bail!("--strategies writes primal transients only; run it without --diff");
    }
    // Everything about the outputs is checked before the render (src/cli/output_set.rs).
    let mut planned: Vec<String> = vec!["npy".into(), "json".into()];
    planned.extend(a.diff.iter().map(|n| format!("d_{n}.npy")));
    if a.exr {
        if let Some(why) = crate::output::too_many_channels(scene.film.axis.bins, scene.film.channels) {
            bail!("{}: --exr: {why}", a.scene.display());
        }
        planned.push("exr".into());
    }
    if a.preview {
        planned.extend(preview_files(&a.diff));
    } else if a.shard.is_some() {
        planned.push("steady.npy".into());
    }
    planned.extend(super::nlos_out::planned(&scene, a.shard.is_some()));
    let mut set = OutputSet::prepare(&a.output, &scene.inputs, &a.scene, &planned)?;
    let mut opts = opts;
    // what makes this render's numbers (for the JSON, `dtr merge` and `--resume`), hashed once
    let identity =
        super::shard_set::identity(&scene, &a.set, &a.diff, &opts, opts.spp.unwrap_or(scene.integrator.spp))?;
    let checkpoint = if a.checkpoint.is_some() || a.resume {
        let mut identity = identity.clone();
        // a checkpoint belongs to one shard of the render
        identity["shard"] = json!(opts.shard.to_string());
        let ck = super::checkpoint_cmd::prepare(&set, &scene, identity, a.checkpoint, a.resume)?;
        opts.checkpoint = Some(ck.clone());
        Some(ck)
    } else {
        None
    };
    let mut strategies = Vec::new();
    let (film, derivs, stats) = if a.strategies {
        let (f, per, s) = render_strategies(&scene, &opts)?;
        strategies = per;
        (f, Vec::new(), s)
    } else if a.diff.is_empty() {
        let (f, s) = render(&scene, &opts)?;
        (f, Vec::new(), s)
    } else {
        render_diff(&scene, &a.diff, &opts)?
    };
    let bad = film.non_finite_count()
        + derivs
            .iter()
            .chain(strategies.iter().map(|s| &s.1))
            .map(Transient::non_finite_count)
            .sum::<usize>();
    if bad > 0 {
        bail!("{}", non_finite_message(&scene, bad));
    }
    set.write("npy", |p| output::write_npy(p, &film.shape(), &film.data))?;
    for (name, d) in a.diff.iter().zip(&derivs) {
        set.write(&format!("d_{name}.npy"), |p| output::write_npy(p, &d.shape(), &d.data))?;
    }
    for ((s, t), f) in &strategies {
        set.write(&format!("s{s}_t{t}.npy"), |p| output::write_npy(p, &f.shape(), &f.data))?;
    }
    if a.exr {
        let axis = (film.axis.start_opl, film.axis.bin_width_opl);
        set.write("exr", |p| {
            output::write_exr_layers_with_axis(p, view(&film), &film.steady, axis)
        })?;
    }
    if a.preview {
        let normalise = match a.normalise.as_deref() {
            Some("frame") => output::Normalise::Frame,
            _ => output::Normalise::Global,
        };
        write_previews(&film, &a.diff, &derivs, &mut set, pixel, normalise)?;
    } else if a.shard.is_some() {
        write_steady_npy(&film, &mut set)?;
    }
    super::nlos_out::write(&scene, &film, &mut set, a.shard.is_some())?;
    let mut meta = metadata(&scene, &film, &stats, &a, set.prefix());
    if let Some(n) = super::nlos_out::describe(&scene, set.prefix(), a.shard.is_some()) {
        meta["nlos"] = n;
    }
    meta["identity"] = identity;
    meta["sampler"] = json!(scene.integrator.sampler.name());
    let shard = opts.shard;
    meta["shard"] = json!({
        "index": shard.index,
        "count": shard.count,
        "interior_samples": stats_range(&shard, stats.spp as u64),
        "about": "this render traced shard index of count of every estimator's samples (interior: samples [a, b) of spp per pixel), normalised by the whole render's sample counts: the shards' films add up to the whole render (dtr merge)",
    });
    // the set that belongs together; a later render to this prefix removes what it left out
    if let Some(w) = &auto_window {
        meta["auto_window"] = serde_json::to_value(w)?;
    }
    meta["files"] = serde_json::json!(set.names_with("json"));
    if a.shard.is_some() {
        // what `dtr merge` checks each file against before it reads it
        meta["files_sha256"] = serde_json::Value::Object(set.digests()?);
    }
    set.write("json", |p| output::write_json(p, &meta))?;
    let prefix_path = set.commit()?;
    if let Some(ck) = &checkpoint {
        // the render is whole: its checkpoint has served
        let _ = std::fs::remove_file(&ck.path);
    }
    let prefix = |ext: &str| with_suffix(&prefix_path, ext);
    // the primal is left zero on purpose by `--estimators boundary`
    // (a shard holds part of the energy; `dtr merge` checks the whole)
    let primal_rendered = (a.diff.is_empty() || estimators.interior()) && a.shard.is_none();
    if let Some(w) = stats.energy.warning(&film.axis).filter(|_| primal_rendered) {
        log::warn!("{}: {w}", a.scene.display());
    }
    if let Some(w) = dropped_samples_warning(stats.non_finite_samples) {
        log::warn!("{}: {w}", a.scene.display());
    }
    // the whole run: the interior pass, the boundary stage and the window-energy pilot
    let boundary = match &stats.boundary {
        Some(_) => format!("; boundary stage {:.2} s", stats.boundary_seconds),
        None => String::new(),
    };
    log::info!(
        "{}: {}x{}x{}x{} in {:.2} s (interior {:.2} s: {:.3e} paths/CPU-s, {:.3e} rays/s{boundary})",
        prefix("npy").display(),
        film.height,
        film.width,
        film.axis.bins,
        film.channels,
        stats.total_wall_seconds,
        stats.wall_seconds,
        stats.paths_per_cpu_second,
        stats.rays_per_second
    );
    Ok(())
}

/// Emission at or above this, in any channel, can overflow 32-bit floats as light adds up.
const OVERFLOWING_EMISSION: f32 = 1e30;

/// What a render that dropped samples as not finite says: the transient lacks their light
/// (the kernel drops them so one bad sample cannot spoil a film; a render that dropped every
/// sample came out all zeros with nothing said but the JSON's count).
fn dropped_samples_warning(non_finite_samples: u64) -> Option<String> {
    (non_finite_samples > 0).then(|| {
        format!(
            "{non_finite_samples} samples came out not finite and were dropped, so the transient lacks their light \
             (non_finite_samples in the JSON); this is a defect of dtr or of an extreme scene value: please report it"
        )
    })
}

/// What a render whose numbers came out non-finite says (nothing is written). The kernel keeps
/// every sample finite (non-finite ones are counted and dropped), so what is left is sums past
/// the range of 32-bit floats: bad input when an emitter's strength is near that range (exit
/// 2, naming the emitter and its field), an internal error otherwise (exit 1).
fn non_finite_message(scene: &Scene, bad: usize) -> String {
    use crate::scene::EmitterKind;
    let strongest = scene
        .emitters
        .iter()
        .map(|e| {
            let (field, v) = match e.kind {
                EmitterKind::Area { radiance, .. } => ("radiance", radiance),
                EmitterKind::Point { intensity, .. } => ("intensity", intensity),
                EmitterKind::Laser { power, .. } => ("power", power),
            };
            (e, field, v.iter().fold(0.0f32, |a, &b| a.max(b.abs())))
        })
        .max_by(|a, b| a.2.total_cmp(&b.2));
    match strongest {
        Some((e, field, v)) if v >= OVERFLOWING_EMISSION => format!(
            "{}: emitter {:?}: field '{field}': {v:e} is too strong to add up in 32-bit floats: {bad} values of the transient overflowed, nothing written; scale the emission down (below {OVERFLOWING_EMISSION:e}) and the result up",
            scene.source.display(),
            e.name
        ),
        _ => format!("internal error: {bad} non-finite values in the transient; nothing written"),
    }
}

/// The first item that occurs twice.
fn first_repeat<'a>(items: impl Iterator<Item = &'a str>) -> Option<&'a str> {
    let mut seen = std::collections::HashSet::new();
    items.into_iter().find(|&n| !seen.insert(n))
}

/// Above this many bounces `dtr render` warns that BDPT's cost per path grows as B³.
const BDPT_WARN_BOUNCES: u32 = 64;

fn parse_shard(s: &str) -> Result<crate::shard::Shard, String> {
    crate::shard::Shard::parse(s).map_err(|e| e.to_string())
}

/// `[a, b]` of a shard's part of `0..total`.
fn stats_range(shard: &crate::shard::Shard, total: u64) -> [u64; 2] {
    let r = shard.range(total);
    [r.start, r.end]
}

pub(super) fn view(film: &Transient) -> FilmView<'_> {
    FilmView {
        data: &film.data,
        height: film.height,
        width: film.width,
        bins: film.axis.bins,
        channels: film.channels,
    }
}

fn parse_pixel(s: &str, scene: &Scene) -> anyhow::Result<(usize, usize)> {
    let (x, y) = s.split_once(',').context("--pixel: expected X,Y")?;
    let x: usize = x.trim().parse().context("--pixel: X is not a non-negative integer")?;
    let y: usize = y.trim().parse().context("--pixel: Y is not a non-negative integer")?;
    if x >= scene.film.width as usize || y >= scene.film.height as usize {
        bail!(
            "--pixel {x},{y} is outside the {}x{} image",
            scene.film.width,
            scene.film.height
        );
    }
    Ok((x, y))
}

/// The files `--preview` adds to an output set, `dtr render`'s and `dtr merge`'s alike
/// ([`write_previews`]): the pictures, the steady image as numbers and one picture per
/// derivative in `diff`. (`dtr merge --preview` wrote the pictures only.)
pub(super) fn preview_files(diff: &[String]) -> Vec<String> {
    let mut files: Vec<String> = super::output_set::PREVIEWS.map(String::from).into();
    files.extend(diff.iter().map(|n| format!("d_{n}.png")));
    files.push("steady.npy".into());
    files
}

/// The steady (time-integrated) image as `PREFIX.steady.npy`, [H, W, C].
pub(super) fn write_steady_npy(film: &Transient, set: &mut OutputSet) -> anyhow::Result<()> {
    let shape = [film.height, film.width, film.channels];
    set.write("steady.npy", |p| output::write_npy(p, &shape, &film.steady))
}

/// Writes the files of [`preview_files`]: `derivs` are the derivatives named in `diff`.
pub(super) fn write_previews(
    film: &Transient,
    diff: &[String],
    derivs: &[Transient],
    set: &mut OutputSet,
    pixel: Option<(usize, usize)>,
    normalise: output::Normalise,
) -> anyhow::Result<()> {
    for (name, d) in diff.iter().zip(derivs) {
        set.write(&format!("d_{name}.png"), |p| output::write_derivative_png(p, view(d)))?;
    }
    write_steady_npy(film, set)?;
    let style = output::SheetStyle {
        axis: Some(film.axis),
        normalise,
        exposure: None,
    };
    set.write("frames.png", |p| output::write_contact_sheet(p, view(film), &style))?;
    set.write("flight.gif", |p| {
        output::write_flight_gif(p, view(film), normalise, Some(&film.axis))
    })?;
    set.write("steady.png", |p| {
        output::write_steady_png(p, &film.steady, film.height, film.width, film.channels)
    })?;
    let (px, py) = pixel.unwrap_or((film.width / 2, film.height / 2));
    set.write("streak.png", |p| output::write_streak_png(p, view(film), py))?;
    let series = vec![
        // in f64: finite film values near the top of f32 add up past it
        ("whole image".to_string(), film.bin_totals_f64()),
        (format!("pixel ({px}, {py})"), film.pixel_series_f64(px, py)),
    ];
    set.write("plot.png", |p| {
        output::write_time_plot(
            p,
            (
                film.axis.start_opl as f32,
                film.axis.bin_width_opl as f32,
                film.axis.bins,
            ),
            &series,
        )
    })?;
    Ok(())
}

fn metadata(scene: &Scene, film: &Transient, stats: &RenderStats, a: &RenderArgs, prefix: &Path) -> serde_json::Value {
    let axis = film.axis;
    let ns = |opl: f64| opl / SPEED_OF_LIGHT_M_PER_S * 1e9;
    let params: serde_json::Map<String, serde_json::Value> =
        scene.params.iter().map(|p| (p.name.clone(), json!(p.value))).collect();
    let mut meta = json!({
        "scene": a.scene.display().to_string(),
        "shape": film.shape(),
        "layout": "[height, width, bins, channels], float32, radiance averaged over samples",
        "channels": if film.channels == 1 { "mono" } else { "rgb" },
        "time_axis": {
            "start_opl": axis.start_opl,
            "bin_width_opl": axis.bin_width_opl,
            "bins": axis.bins,
            "units": "metres of optical path length (OPL); time = OPL / c",
            "start_ns": ns(axis.start_opl),
            "bin_width_ns": ns(axis.bin_width_opl),
            "speed_of_light_m_per_s": SPEED_OF_LIGHT_M_PER_S,
        },
        "unwarp": scene.film.unwarp,
        "integrator": a.integrator.unwrap_or(scene.integrator.kind),
        "eta": scene.eta,
        "params": params,
        // the file's coordinates minus this (in f64) are what was rendered (scene/origin.rs)
        "render_origin": scene.render_origin,
        "derivatives": a.diff.iter().map(|n| json!({"param": n, "file": format!("{}.d_{n}.npy", prefix.display()), "estimator": if stats.boundary.is_some() { "interior (Algorithm 1) + boundary (Algorithm 2: secondary edges; primary edges)" } else { "interior (Algorithm 1)" }})).collect::<Vec<_>>(),
        "spp": stats.spp,
        "seed": stats.seed,
        "threads": stats.threads,
        // derivative renders always run the 8-wide Dual8 kernel (render.rs, dispatch!)
        "lanes": if a.scalar && a.diff.is_empty() { 1 } else { 8 },
        "wall_seconds": stats.wall_seconds,
        "cpu_seconds": stats.cpu_seconds,
        "paths": stats.paths,
        "paths_per_second": stats.paths as f64 / stats.wall_seconds.max(1e-9),
        "paths_per_cpu_second": stats.paths_per_cpu_second,
        "rays": stats.intersect_rays + stats.occluded_rays,
        "intersect_rays": stats.intersect_rays,
        "occluded_rays": stats.occluded_rays,
        "rays_per_second": stats.rays_per_second,
        "rays_per_cpu_second": stats.rays_per_cpu_second,
        "bvh_build_seconds": stats.bvh_build_seconds,
        "non_finite_samples": stats.non_finite_samples,
        "phase_seconds": stats.phase_seconds,
        "boundary_samples": stats.boundary_samples,
        "boundary_seconds": stats.boundary_seconds,
        "boundary": stats.boundary,
        "opl_precision": {
            "about": "f64_paths: each path's OPL was also summed in f64 from f64 hit points (rebuilt from Embree's f32 barycentrics), because the film's finest time scale (bin width, pulse or gate width) is under 4096 f32 steps at the largest OPL or coordinate; else the kernel's f32 OPL is binned. The time axis is f64 either way.",
            "f64_paths": stats.opl.f64_paths,
            "time_scale_opl": stats.opl.time_scale_opl,
            "f32_step_opl": stats.opl.f32_step_opl,
        },
        "energy": {
            "about": "time integral of the whole image (sum over pixels and channels): total = every path; before / after = the part that arrived before bin 0 / after the last bin; inside = sum of the transient. With steady = window nothing past the window was traced: after is then estimated by an uncut pilot of after_pilot_paths paths (after_standard_error: its Monte Carlo noise) and total = before + inside + after; a derivative's outside is null",
            "primal": stats.energy,
            "derivatives": a.diff.iter().zip(&stats.deriv_energy).map(|(n, e)| json!({"param": n, "total": e.total, "inside": e.inside, "outside": e.outside})).collect::<Vec<_>>(),
            "warning": stats.energy.warning(&film.axis),
        },
        "version": env!("CARGO_PKG_VERSION"),
    });
    meta["traversal"] = json!(stats.traversal);
    // the whole render: interior + boundary stage + the window-energy pilot
    meta["total_wall_seconds"] = json!(stats.total_wall_seconds);
    meta["total_cpu_seconds"] = json!(stats.total_cpu_seconds);
    // the instruction set of this build (src/simd.rs)
    meta["simd"] = json!(crate::simd::compiled_for());
    meta["time_edges"] = json!({
        "about": "used: the path tracer estimated each derivative's time term f·dS_e/dd·(dd/dθ) from light points drawn where a connection's OPL crosses a bin edge (box gate, area emitters with delta pulses or pulses of standard deviation at most half a bin, a parameter that shifts paths in time; a delta pulse's time term, a Dirac on each bin edge, comes from them alone); else from its ordinary next-event and emission contributions (--time-edges off, or where the draws do not apply)",
        "used": stats.time_edges,
    });
    meta["steady"] = json!({
        "about": "what the steady image integrates: window = the time window (paths were traced only as far as their OPL could still reach a bin, opl_cut metres; the transient is the same as without the cut), full = all time (--steady full: every path traced to its last bounce)",
        "mode": stats.steady,
        "opl_cut": stats.opl_cut,
    });
    meta
}

/// Refuses settings whose output or stage this render does not make: they would be taken
/// without a word and change nothing (`--pixel` or `--normalise` without `--preview`;
/// `--estimators`, `--time-edges` or `--guiding` without `--diff`).
fn refuse_settings_without_their_output(a: &RenderArgs) -> anyhow::Result<()> {
    let without_preview = [("--pixel", a.pixel.is_some()), ("--normalise", a.normalise.is_some())];
    if let Some((flag, _)) = without_preview.iter().find(|(_, set)| *set && !a.preview) {
        bail!(
            "{flag} sets how the previews are drawn (the plot's pixel and the streak image's row, or the animation's white); it needs --preview"
        );
    }
    let without_diff = [
        ("--estimators", a.estimators.is_some()),
        ("--time-edges", a.time_edges.is_some()),
        ("--guiding", a.guiding),
    ];
    if let Some((flag, _)) = without_diff.iter().find(|(_, set)| *set && a.diff.is_empty()) {
        bail!("{flag} sets how derivatives are estimated; it needs --diff");
    }
    Ok(())
}

/// Refuses boundary samples (`--spp-boundary`) with `--estimators interior`, which leaves
/// the boundary term out: they were taken without a word and never drawn.
pub(super) fn refuse_unused_boundary_samples(
    spp_boundary: Option<impl std::fmt::Display>,
    estimators: BoundaryMode,
) -> anyhow::Result<()> {
    if let (Some(n), BoundaryMode::InteriorOnly) = (spp_boundary, estimators) {
        bail!(
            "--spp-boundary {n} sets the boundary term's samples, which --estimators interior leaves out; drop one of them"
        );
    }
    Ok(())
}

/// `--estimators interior` on parameters that move geometry: the derivative written is the
/// interior term alone, without the boundary term of the silhouettes and shadows that move
/// with it (also those seen through smooth glass, whose boundary term is refused with a
/// pointer to this option: an independent sweep measured a wall's motion behind a glass slab
/// 45 % off from the interior alone). Said once, naming those parameters.
pub(super) fn warn_interior_alone(scene: &Scene, params: &[String], source: &Path) {
    let Ok(motion) = crate::params::lanes::Motion::build(scene, params) else {
        return;
    };
    let moving: Vec<&str> = params
        .iter()
        .zip(&motion.fields)
        .filter(|(_, f)| !f.is_empty())
        .map(|(n, _)| n.as_str())
        .collect();
    if !moving.is_empty() {
        log::warn!(
            "{}: --estimators interior: the derivatives of {} are the interior term alone; they move geometry, so \
             silhouettes and shadows move with them (also those seen through glass), a boundary term this run leaves out",
            source.display(),
            moving.join(", ")
        );
    }
}

#[cfg(test)]
mod tests {
    /// Dropped samples are said on stderr, with how many, never only counted in the JSON.
    #[test]
    fn dropped_samples_are_said() {
        assert_eq!(super::dropped_samples_warning(0), None);
        let w = super::dropped_samples_warning(39979).unwrap();
        assert!(
            w.starts_with("39979 samples came out not finite and were dropped"),
            "{w}"
        );
    }
}
