//! NLOS captures as HDF5 in y-tal's capture layout (the `HDF5_TAL` format its reader and
//! reconstructions open directly; y-tal also converts the Z-NLOS datasets into it), so that
//! a rendered capture goes straight into NLOS reconstruction code:
//!
//! | dataset | contents |
//! |---|---|
//! | `H` | float32 transient: confocal (T, Sx, Sy), exhaustive (T, Lx, Ly, Sx, Sy); with explicit points (T, Si) / (T, Li, Si); channels summed |
//! | `H_format` | int: 1 = T_Sx_Sy, 2 = T_Lx_Ly_Sx_Sy, 3 = T_Si, 4 = T_Li_Si |
//! | `sensor_xyz`, `laser_xyz` | (3,) the SPAD's and the laser's positions |
//! | `sensor_grid_xyz`, `sensor_grid_normals` | (Sx, Sy, 3) or (Si, 3) points on the wall and the wall's normals there |
//! | `laser_grid_xyz`, `laser_grid_normals` | the same for the laser points |
//! | `sensor_grid_format`, `laser_grid_format` | int: 1 = N_3, 2 = X_Y_3 |
//! | `delta_t`, `t_start` | bin width and the first bin's start, OPL metres |
//! | `t_accounts_first_and_last_bounces` | bool: the relay legs are in the time of flight |
//! | `scene_info` | YAML text: the writer, the scene file, the scan and the noise model |
//!
//! Positions are in the scene file's coordinates (the render origin added back in f64).
//! Grid index (ix, iy) runs along the wall frame's u and v axes (`scene::nlos`). Built with the
//! `hdf5` feature (on by default).

use super::OutputError;
use crate::film::Transient;
use crate::scene::{NlosSpec, Scene, WallGrid};
use std::path::Path;

/// The `H` array (and its shape and `H_format`) of `film`, in y-tal's axis order, whole in
/// memory (made a slab at a time, as [`write_nlos_h5`] writes it).
pub fn h_array(spec: &NlosSpec, film: &Transient) -> (Vec<usize>, Vec<f32>, i32) {
    h_array_in_slabs(spec, film, H_SLAB_BYTES)
}

/// [`h_array`], made in slabs of at most `budget` bytes where one index allows.
fn h_array_in_slabs(spec: &NlosSpec, film: &Transient, budget: usize) -> (Vec<usize>, Vec<f32>, i32) {
    let (shape, pixels, format) = h_layout(spec, film);
    let (t, n) = (shape[0], pixels.len());
    let mut h = vec![0.0f32; t * n];
    let whole = for_each_slab(&shape, &pixels, film, &|_, v| v, budget, |range, slab| {
        let len = range.len();
        for k in 0..t {
            h[k * n + range.start..][..len].copy_from_slice(&slab[k * len..(k + 1) * len]);
        }
        Ok::<(), std::convert::Infallible>(())
    });
    match whole {
        Ok(()) => (shape, h, format),
        Err(never) => match never {},
    }
}

/// `H`'s shape and `H_format`, and the film pixel of each entry of `H` after its time axis:
/// (sensor i, laser j) of an exhaustive scan, sensor point i of a confocal one at its place
/// on the grid.
fn h_layout(spec: &NlosSpec, film: &Transient) -> (Vec<usize>, Vec<(usize, usize)>, i32) {
    let t = film.axis.bins;
    let grids = !spec.sensors.explicit && !spec.lasers.explicit;
    let (s, l) = (&spec.sensors, &spec.lasers);
    let (sensor_order, laser_order) = (order(s, grids), order(l, grids));
    let pixels: Vec<(usize, usize)> = if spec.exhaustive() {
        laser_order
            .iter()
            .flat_map(|&j| sensor_order.iter().map(move |&i| (i, j)))
            .collect()
    } else {
        sensor_order.iter().map(|&i| (i % s.nx, i / s.nx)).collect()
    };
    let (shape, format) = match (spec.exhaustive(), grids) {
        (false, true) => (vec![t, s.nx, s.ny], 1),
        (true, true) => (vec![t, l.nx, l.ny, s.nx, s.ny], 2),
        (false, false) => (vec![t, s.len()], 3),
        (true, false) => (vec![t, l.len(), s.len()], 4),
    };
    (shape, pixels, format)
}

/// Pixels the time-major transpose reads whole before it writes them bin by bin: 256 time
/// series of 128 bins are 128 KiB, within a core's L2 cache.
const TRANSPOSE_BLOCK: usize = 256;

/// The most bytes of `H` held in memory at once while it is written: `H` goes to the file in
/// slabs of its first axis after time (at least one index each), so that a large capture
/// does not need a second film-sized array beside the film (a 32 × 32 exhaustive scan's film
/// is 512 MiB).
const H_SLAB_BYTES: usize = 32 << 20;

/// `out[k · n + p]` = pixel `pixels[p]`'s bin k, channels summed, of the film's values mapped
/// by `map(index in film.data, value)` (n = `pixels.len()`): the film's pixel-major series in
/// time-major order. Cache-blocked: a block of pixels' series is read whole (blocks in
/// parallel), then written as one run per bin. Read in output order, every value was a cache
/// miss (the film's pixels lie bins × channels floats apart): 38 % of the run of a 32 × 32
/// exhaustive scan at 16 spp, whose film is 512 MiB.
fn time_major<M: Fn(usize, f32) -> f32 + Sync>(film: &Transient, pixels: &[(usize, usize)], map: &M) -> Vec<f32> {
    use rayon::prelude::*;
    let (t, c, n) = (film.axis.bins, film.channels, pixels.len());
    let blocks: Vec<Vec<f32>> = pixels
        .par_chunks(TRANSPOSE_BLOCK)
        .map(|chunk| {
            let mut block = vec![0.0f32; chunk.len() * t];
            for (q, &(x, y)) in chunk.iter().enumerate() {
                let at = film.index(x, y, 0, 0);
                for (k, v) in block[q * t..(q + 1) * t].iter_mut().enumerate() {
                    let bin = at + k * c;
                    *v = (bin..bin + c).map(|i| map(i, film.data[i])).sum();
                }
            }
            block
        })
        .collect();
    let mut out = vec![0.0f32; t * n];
    for (b, block) in blocks.iter().enumerate() {
        let (p0, len) = (b * TRANSPOSE_BLOCK, block.len() / t.max(1));
        for k in 0..t {
            for (q, v) in out[k * n + p0..][..len].iter_mut().enumerate() {
                *v = block[q * t + k];
            }
        }
    }
    out
}

/// Indices of `H`'s second axis (the first after time) written per slab by [`write_h`]: as
/// many as fit in `budget` bytes, at least one, at most all `len`; `bytes_per_index` is one
/// index's share of `H` (all bins).
fn slab_len(budget: usize, bytes_per_index: usize, len: usize) -> usize {
    (budget / bytes_per_index.max(1)).clamp(1, len.max(1))
}

/// Calls `put(entries, slab)` for each slab of `H` (shape `shape`, entries after the time axis
/// at the film pixels `pixels`, values mapped by `map`) in order: the entries `a · m..b · m` of
/// the indices a..b of `H`'s second axis (m entries per index), as a time-major array of
/// `shape[0]` rows, each slab at most `budget` bytes where one index allows.
fn for_each_slab<M: Fn(usize, f32) -> f32 + Sync, E>(
    shape: &[usize],
    pixels: &[(usize, usize)],
    film: &Transient,
    map: &M,
    budget: usize,
    mut put: impl FnMut(std::ops::Range<usize>, &[f32]) -> Result<(), E>,
) -> Result<(), E> {
    let per_index: usize = shape[2..].iter().product();
    let step = slab_len(budget, per_index * shape[0] * std::mem::size_of::<f32>(), shape[1]);
    for a in (0..shape[1]).step_by(step) {
        let entries = a * per_index..(a + step).min(shape[1]) * per_index;
        let slab = time_major(film, &pixels[entries.clone()], map);
        put(entries, &slab)?;
    }
    Ok(())
}

/// Creates `H` in `f` and writes it one slab of its second axis at a time ([`for_each_slab`]:
/// an HDF5 hyperslab [all bins, a..b, all, …] each); returns `H_format`. The file holds the
/// array [`h_array`] gives.
fn write_h<M: Fn(usize, f32) -> f32 + Sync>(
    f: &hdf5::File,
    spec: &NlosSpec,
    film: &Transient,
    map: &M,
    budget: usize,
) -> hdf5::Result<i32> {
    use hdf5::{Hyperslab, SliceOrIndex};
    let (shape, pixels, format) = h_layout(spec, film);
    let dataset = f.new_dataset::<f32>().shape(shape.as_slice()).create("H")?;
    let per_index: usize = shape[2..].iter().product();
    for_each_slab(&shape, &pixels, film, map, budget, |entries, slab| {
        if let Some(bad) = slab.iter().position(|v| !v.is_finite()) {
            let entry = entries.start + bad % entries.len();
            return Err(hdf5::Error::from(format!(
                "entry {entry} of H is not finite; refusing to write"
            )));
        }
        let (a, b) = (entries.start / per_index, entries.end / per_index);
        let mut slab_shape = shape.clone();
        slab_shape[1] = b - a;
        let view = ndarray::ArrayViewD::from_shape(ndarray::IxDyn(&slab_shape), slab)
            .map_err(|e| hdf5::Error::from(format!("H slab {a}..{b}: {e}")))?;
        let selection: Vec<SliceOrIndex> = [SliceOrIndex::from(..), SliceOrIndex::from(a..b)]
            .into_iter()
            .chain((2..shape.len()).map(|_| SliceOrIndex::from(..)))
            .collect();
        dataset.write_slice(view, Hyperslab::from(selection))
    })?;
    Ok(format)
}

/// The points of `g` in y-tal's order: ix major, iy minor (X, Y), or as listed (N).
fn order(g: &WallGrid, grids: bool) -> Vec<usize> {
    if grids {
        (0..g.nx)
            .flat_map(|ix| (0..g.ny).map(move |iy| iy * g.nx + ix))
            .collect()
    } else {
        (0..g.len()).collect()
    }
}

/// Grid positions and normals in y-tal's order ((X, Y, 3) or (N, 3)), file coordinates.
fn grid_arrays(g: &WallGrid, grids: bool, scene: &Scene) -> (Vec<usize>, Vec<f32>, Vec<f32>) {
    let order = order(g, grids);
    let mut xyz = Vec::with_capacity(order.len() * 3);
    let mut nrm = Vec::with_capacity(order.len() * 3);
    for &i in &order {
        let p = g.points[i];
        xyz.extend(scene.to_world(p.p.as_dvec3()).as_vec3().to_array());
        nrm.extend(p.n.to_array());
    }
    let shape = if grids { vec![g.nx, g.ny, 3] } else { vec![g.len(), 3] };
    (shape, xyz, nrm)
}

/// Writes `film` (a render of `scene`'s capture) to `path` in the layout above.
pub fn write_nlos_h5(path: &Path, scene: &Scene, film: &Transient, what: &str) -> Result<(), OutputError> {
    write_nlos_h5_mapped(path, scene, film, |_, v| v, what)
}

/// [`write_nlos_h5`] of the film's values mapped by `map(index in film.data, value)`, made as
/// `H` is written, so that no second film-sized array is held (a noisy copy,
/// `crate::sensor_noise::photon_count`). `film` and every mapped value must be finite.
pub fn write_nlos_h5_mapped(
    path: &Path,
    scene: &Scene,
    film: &Transient,
    map: impl Fn(usize, f32) -> f32 + Sync,
    what: &str,
) -> Result<(), OutputError> {
    let spec = scene.nlos.as_ref().expect("an NLOS scene");
    if let Some(bad) = film.data.iter().position(|v| !v.is_finite()) {
        return Err(OutputError::invalid(
            path,
            format!("value {bad} of the transient is not finite; refusing to write"),
        ));
    }
    // written beside the destination and renamed into place, like every writer here
    let tmp = path.with_extension("h5.partial");
    let result = write(&tmp, scene, spec, film, &map, what).map_err(|e| hdf5_error(path, e));
    match result.and_then(|()| std::fs::rename(&tmp, path).map_err(|e| OutputError::io(path, e))) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// An HDF5 failure in writing `path` as the error it is. Where the file system refused a
/// call, HDF5's file driver puts the system's error number in its message (`errno = 28`); that
/// is [`OutputError::Io`] naming `path` (exit status 3, as a refused npy), not the temporary
/// file. Before, every failure was an encoding failure (exit 1, "internal") whose message
/// named `h5.h5.partial`. Anything else stays an encoding failure.
fn hdf5_error(path: &Path, e: hdf5::Error) -> OutputError {
    let text = e.to_string();
    let errno = text
        .split("errno = ")
        .nth(1)
        .and_then(|t| t.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|n| n.parse::<i32>().ok())
        .filter(|&n| n > 0);
    match errno {
        Some(n) => OutputError::io(path, std::io::Error::from_raw_os_error(n)),
        None => OutputError::encode(path, "HDF5", e),
    }
}

fn write<M: Fn(usize, f32) -> f32 + Sync>(
    path: &Path,
    scene: &Scene,
    spec: &NlosSpec,
    film: &Transient,
    map: &M,
    what: &str,
) -> hdf5::Result<()> {
    use hdf5::types::VarLenUnicode;
    let f = hdf5::File::create(path)?;
    let format = write_h(&f, spec, film, map, H_SLAB_BYTES)?;
    let grids = format == 1 || format == 2;
    let array = |name: &str, shape: &[usize], data: &[f32]| -> hdf5::Result<()> {
        f.new_dataset::<f32>().shape(shape).create(name)?.write_raw(data)
    };
    let int = |name: &str, v: i32| -> hdf5::Result<()> { f.new_dataset::<i32>().create(name)?.write_scalar(&v) };
    let float = |name: &str, v: f64| -> hdf5::Result<()> { f.new_dataset::<f64>().create(name)?.write_scalar(&v) };
    int("H_format", format)?;
    let world = |p: glam::Vec3| -> [f32; 3] { scene.to_world(p.as_dvec3()).as_vec3().to_array() };
    array("sensor_xyz", &[3], &world(scene.camera.position))?;
    let crate::scene::EmitterKind::Laser { position, .. } = scene.emitters[spec.laser as usize].kind else {
        unreachable!("scene::nlos checks that the scan's emitter is a laser")
    };
    array("laser_xyz", &[3], &world(position))?;
    for (name, g) in [("sensor", &spec.sensors), ("laser", &spec.lasers)] {
        let (gs, xyz, nrm) = grid_arrays(g, grids, scene);
        array(&format!("{name}_grid_xyz"), &gs, &xyz)?;
        array(&format!("{name}_grid_normals"), &gs, &nrm)?;
        int(&format!("{name}_grid_format"), if grids { 2 } else { 1 })?;
    }
    float("delta_t", film.axis.bin_width_opl)?;
    float("t_start", film.axis.start_opl)?;
    f.new_dataset::<bool>()
        .create("t_accounts_first_and_last_bounces")?
        .write_scalar(&(spec.relay_legs == crate::scene::RelayLegs::Included))?;
    let info = format!(
        "original_format: difftransient\ncontents: {what}\nscene: {:?}\nscan: {}\nrelay_legs: {}\nnoise: {}\n",
        scene.source.display().to_string(),
        if spec.exhaustive() { "exhaustive" } else { "confocal" },
        if spec.relay_legs == crate::scene::RelayLegs::Included {
            "included"
        } else {
            "excluded"
        },
        match &spec.noise {
            Some(n) => format!(
                "{{photons_per_unit: {}, dark_counts: {}, seed: {}}}",
                n.photons_per_unit, n.dark_counts, n.seed
            ),
            None => "null".into(),
        }
    );
    let text: VarLenUnicode = info.parse().map_err(|e| hdf5::Error::from(format!("{e}")))?;
    f.new_dataset::<VarLenUnicode>()
        .create("scene_info")?
        .write_scalar(&text)?;
    f.close()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::temporal::TimeAxis;

    /// A film of `w` × `h` pixels whose values all differ (RGB when `channels` is 3).
    fn numbered_film(w: usize, h: usize, bins: usize, channels: usize) -> Transient {
        let axis = TimeAxis {
            start_opl: 1.0,
            bin_width_opl: 0.01,
            bins,
        };
        let mut film = Transient::zeros(w, h, axis, channels);
        for (i, v) in film.data.iter_mut().enumerate() {
            *v = ((i * 2_654_435_761) % 1_000_003) as f32 * 1e-3 - 300.0;
        }
        film
    }

    /// Opens a file this test process wrote and closed, for reading, without HDF5's file lock.
    ///
    /// HDF5 opens files without close-on-exec, so a child process that another test spawns
    /// while a file is open here (`npy::tests::numpy_reads_it` runs python3) inherits the
    /// descriptor and with it the writer's exclusive lock, which outlives our close; a locked
    /// reopen then fails with EAGAIN (seen once in a CI rehearsal). The file is complete and
    /// nothing writes it, so the read needs no lock.
    fn open_written(path: &std::path::Path) -> hdf5::File {
        hdf5::File::with_options()
            .with_fapl(|p| p.file_locking(false))
            .open(path)
            .unwrap()
    }

    /// The lock a spawned child inherits blocks a locked reopen, not [`open_written`].
    #[test]
    fn a_written_file_reads_back_while_a_child_holds_its_descriptor() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("held.h5");
        let f = hdf5::File::create(&path).unwrap();
        f.new_dataset::<f32>()
            .shape(3)
            .create("H")
            .unwrap()
            .write_raw(&[1.0f32, 2.0, 3.0])
            .unwrap();
        let Ok(mut child) = std::process::Command::new("sleep").arg("5").spawn() else {
            return;
        };
        f.close().unwrap();
        let locked = hdf5::File::open(&path).map(|_| ());
        let got: Vec<f32> = open_written(&path).dataset("H").unwrap().read_raw().unwrap();
        let _ = child.kill();
        let _ = child.wait();
        // (unless the environment turns HDF5's locking off)
        if std::env::var_os("HDF5_USE_FILE_LOCKING").is_none() {
            assert!(
                locked.is_err(),
                "the child's inherited lock should block a locked reopen"
            );
        }
        assert_eq!(got, vec![1.0, 2.0, 3.0]);
    }

    /// The blocked transpose gives each value as the per-value formula does, to the bit: RGB
    /// summed over channels, a film whose pixel count crosses several blocks and ends inside
    /// one, pixels taken in a scrambled order and some twice.
    #[test]
    fn time_major_matches_the_value_by_value_order() {
        let (w, h, bins) = (41, 17, 37);
        let film = numbered_film(w, h, bins, 3);
        let pixels: Vec<(usize, usize)> = (0..w * h + 50)
            .map(|p| {
                let q = (p * 7919) % (w * h);
                (q % w, q / w)
            })
            .collect();
        assert!(pixels.len() > 2 * TRANSPOSE_BLOCK && !pixels.len().is_multiple_of(TRANSPOSE_BLOCK));
        let got = time_major(&film, &pixels, &|_, v| v);
        let n = pixels.len();
        assert_eq!(got.len(), bins * n);
        for k in 0..bins {
            for (p, &(x, y)) in pixels.iter().enumerate() {
                let want: f32 = (0..3).map(|ch| film.at(x, y, k, ch)).sum();
                assert_eq!(got[k * n + p].to_bits(), want.to_bits(), "bin {k}, entry {p}");
            }
        }
    }

    /// `H` written a slab at a time (slabs of one index of its second axis, of two with a
    /// partial last one, and all at once) reads back as the array `h_array` holds, to the
    /// bit, for a confocal scan and an exhaustive one, and so does `h_array` made in those
    /// slabs; with a map, as `h_array` of the mapped film; a map that gives a NaN is refused.
    #[test]
    fn h_written_in_slabs_reads_back_whole() {
        use crate::scene::testutil::{load_text, scene_text};
        let text = scene_text("nlos_occluder.toml").replace("grid = [16, 16]", "grid = [5, 4]");
        let confocal = load_text("co.toml", &text, &[], &[]).unwrap();
        let text = text.replace("scan = \"confocal\"", "scan = \"exhaustive\"\nlaser_grid = [3, 2]");
        let exhaustive = load_text("ex.toml", &text, &[], &[]).unwrap();
        let dir = tempfile::tempdir().unwrap();
        for (name, scene, format) in [("confocal", &confocal, 1), ("exhaustive", &exhaustive, 2)] {
            let spec = scene.nlos.as_ref().unwrap();
            let (w, h) = if spec.exhaustive() {
                (spec.sensors.len(), spec.lasers.len())
            } else {
                (spec.sensors.nx, spec.sensors.ny)
            };
            let film = numbered_film(w, h, 13, 1);
            let (shape, whole, want_format) = h_array(spec, &film);
            assert_eq!(want_format, format);
            // a budget of one index per slab, of two (5 = 2 + 2 + 1 and 3 = 2 + 1), and all
            let per_index = whole.len() / shape[1];
            assert!(shape[1] % 2 == 1, "{name}: {shape:?}");
            for budget in [1, 2 * per_index * 4, usize::MAX / 2] {
                let (_, pieced, _) = h_array_in_slabs(spec, &film, budget);
                assert!(
                    pieced.iter().zip(&whole).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{name}: h_array in slabs of {budget} bytes"
                );
                let path = dir.path().join(format!("{name}_{budget}.h5"));
                let f = hdf5::File::create(&path).unwrap();
                assert_eq!(write_h(&f, spec, &film, &|_, v| v, budget).unwrap(), format);
                f.close().unwrap();
                let dataset = open_written(&path).dataset("H").unwrap();
                assert_eq!(dataset.shape(), shape, "{name}");
                let got: Vec<f32> = dataset.read_raw().unwrap();
                assert!(
                    got.iter().zip(&whole).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{name}, budget {budget}"
                );
            }
            // values mapped as they are written: H of the mapped film, to the bit
            let map = |i: usize, v: f32| v * 2.0 + (i % 7) as f32;
            let mut mapped = film.clone();
            mapped.data.iter_mut().enumerate().for_each(|(i, v)| *v = map(i, *v));
            let (_, want, _) = h_array(spec, &mapped);
            let path = dir.path().join(format!("{name}_mapped.h5"));
            let f = hdf5::File::create(&path).unwrap();
            write_h(&f, spec, &film, &map, 2 * per_index * 4).unwrap();
            f.close().unwrap();
            let got: Vec<f32> = open_written(&path).dataset("H").unwrap().read_raw().unwrap();
            assert!(
                got.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()),
                "{name}, mapped"
            );
            // a map that gives a NaN is refused, whichever slab it lands in
            let f = hdf5::File::create(dir.path().join(format!("{name}_nan.h5"))).unwrap();
            let last = film.data.len() - 1;
            let nan = |i: usize, v: f32| if i == last { f32::NAN } else { v };
            let err = write_h(&f, spec, &film, &nan, 2 * per_index * 4).unwrap_err();
            assert!(err.to_string().contains("not finite"), "{name}: {err}");
        }
    }
}
