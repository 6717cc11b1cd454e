//! What `dtr render` writes for an NLOS capture besides PREFIX.npy and PREFIX.json:
//! PREFIX.h5 (y-tal's capture layout, `output::nlos_h5`) and, with `[nlos.noise]`, a noisy
//! copy as photon counts (PREFIX.noisy.npy and PREFIX.noisy.h5; `crate::sensor_noise`); the
//! noiseless transient stays in PREFIX.npy. A shard writes none of them: its film is a part of
//! the render, so `dtr merge` writes them from the shards' sum (`shard_set::capture_scene`
//! loads the scene they rendered for it).

use super::output_set::{OutputSet, with_suffix};
use crate::film::Transient;
use crate::scene::Scene;
use serde_json::json;
use std::path::Path;

/// Whether this build writes HDF5.
const HDF5: bool = cfg!(feature = "hdf5");

/// The extra outputs of a render of `scene` (none unless it is an unsharded NLOS capture).
pub(super) fn planned(scene: &Scene, sharded: bool) -> Vec<String> {
    let Some(n) = scene.nlos.as_ref().filter(|_| !sharded) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    if HDF5 {
        out.push("h5".to_string());
    }
    if n.noise.is_some() {
        out.push("noisy.npy".to_string());
        if HDF5 {
            out.push("noisy.h5".to_string());
        }
    }
    out
}

/// Writes the outputs of [`planned`] into the staged set.
pub(super) fn write(scene: &Scene, film: &Transient, set: &mut OutputSet, sharded: bool) -> anyhow::Result<()> {
    let Some(n) = scene.nlos.as_ref().filter(|_| !sharded) else {
        return Ok(());
    };
    #[cfg(feature = "hdf5")]
    set.write("h5", |p| {
        crate::output::write_nlos_h5(p, scene, film, "noiseless transient (radiance)")
    })?;
    if let Some(noise) = &n.noise {
        // counts a float32 file cannot hold are refused by the fields that set them, before
        // any is written (`--set laser_power=1e38` ended in exit 1 naming a staging file)
        let brightest = film.data.iter().fold(0.0f32, |m, &v| m.max(v)) as f64;
        let most = noise.photons_per_unit * brightest + noise.dark_counts;
        if !(most < f32::MAX as f64) {
            anyhow::bail!(
                "{}: the capture's brightest bin ({brightest:e}) expects {most:e} photons (nlos.noise.photons_per_unit = {} times it, plus dark_counts), beyond what a float32 count holds (3.4e38): lower nlos.noise.photons_per_unit or the laser's power",
                scene.source.display(),
                noise.photons_per_unit
            );
        }
        // the counts are made as each file is written, never held whole beside the film
        let count = |i: usize, v: f32| crate::sensor_noise::photon_count(noise, i, v);
        set.write("noisy.npy", |p| {
            crate::output::write_npy_mapped(p, &film.shape(), &film.data, count)
        })?;
        #[cfg(feature = "hdf5")]
        set.write("noisy.h5", |p| {
            crate::output::write_nlos_h5_mapped(p, scene, film, count, "photon counts (noise model in noise)")
        })?;
    }
    Ok(())
}

/// The JSON's `nlos` block: the capture, its axes and conventions, and the extra files.
pub(super) fn describe(scene: &Scene, prefix: &Path, sharded: bool) -> Option<serde_json::Value> {
    let n = scene.nlos.as_ref()?;
    let file = |ext: &str| with_suffix(prefix, ext).display().to_string();
    let mut v = crate::scene::nlos::describe(n);
    v["layout"] = json!(if n.exhaustive() {
        "PREFIX.npy is [laser points, sensor points, bins, channels]: laser point j = jy * laser_grid[0] + jx, sensor point i = iy * sensor_grid[0] + ix (explicit points: their order)"
    } else {
        "PREFIX.npy is [sensor_grid[1], sensor_grid[0], bins, channels] = [iy, ix, t, c] (explicit points: [1, points, bins, channels]); the laser point is the sensor point"
    });
    v["measures"] = json!(
        "radiance leaving each sensor point towards the SPAD (the camera position), W sr^-1 m^-2 per unit laser power scale"
    );
    v["time_of_flight"] = json!(match n.relay_legs {
        crate::scene::RelayLegs::Excluded =>
            "relay_legs = excluded (default): OPL from the laser spot to the sensor point; the laser-to-wall and wall-to-SPAD legs are left out",
        crate::scene::RelayLegs::Included =>
            "relay_legs = included: OPL from the laser to the SPAD, the laser-to-wall and wall-to-SPAD legs counted",
    });
    v["files"] = if sharded {
        json!({"about": "a shard writes no HDF5 or noisy copy; dtr merge writes them from the shards' sum"})
    } else {
        json!({
            "hdf5": if HDF5 { json!(file("h5")) } else { json!(null) },
            "hdf5_layout": "y-tal's capture layout (HDF5_TAL: H, H_format, sensor/laser_xyz, *_grid_xyz, *_grid_normals, *_grid_format, delta_t, t_start, t_accounts_first_and_last_bounces, scene_info)",
            "noisy_npy": n.noise.map(|_| file("noisy.npy")),
            "noisy_hdf5": n.noise.filter(|_| HDF5).map(|_| file("noisy.h5")),
        })
    };
    Some(v)
}
