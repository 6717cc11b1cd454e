//! Single-part, multi-layer OpenEXR that common viewers open: the default layer (channels
//! `R`, `G`, `B`, or `Y` for mono, without a prefix) is the steady (time-integrated) image,
//! and every time bin is a layer of the same part, `t0000.R`, `t0000.G`, `t0000.B` (`t0000.Y`
//! mono), `t0001.…`, …, f32, ZIP-compressed. Viewers that show only the first part of a
//! multi-part file, or only channels named `R`, `G`, `B`/`Y`, show the steady image; viewers
//! that list layers (tev, Nuke, Blender, exrdisplay) list one per bin. The time axis is in the
//! header (see [`write_exr_layers_with_axis`]).

use super::atomic::write_atomic;
use super::{FilmView, OutputError, SPEED_OF_LIGHT_M_PER_S, check_data};
use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::*;
use std::io::{Read, Seek, Write};
use std::path::Path;
use std::result::Result;

/// Writes `film` as a single-part OpenEXR file, atomically: the default layer holds the time
/// sum of the bins, layer `tNNNN` holds bin `NNNN` (four digits, more when there are more than
/// 10000 bins). The header carries `time_bins` (i32).
pub fn write_exr_layers(path: &Path, film: FilmView) -> Result<(), OutputError> {
    film.validate(path)?;
    let mut steady = vec![0.0f64; film.height * film.width * film.channels];
    for (i, s) in steady.iter_mut().enumerate() {
        let (p, c) = (i / film.channels, i % film.channels);
        let base = p * film.bins * film.channels + c;
        *s = (0..film.bins).map(|t| film.data[base + t * film.channels] as f64).sum();
    }
    let steady: Vec<f32> = steady.into_iter().map(|v| v as f32).collect();
    write(path, film, &steady, None)
}

/// [`write_exr_layers`] with the steady image given (`steady`: `[height, width, channels]`,
/// the render's own, e.g. all time with `--steady full`) as the default layer, and the time
/// axis `(start_opl, bin_width_opl)` (metres of optical path length) in the header: `start_opl`,
/// `bin_width_opl`, `end_opl` (f64), `time_bins` (i32), `start_time_ns`, `bin_width_ns` (f64),
/// `opl_units` = `metres` and `time_layers`, a sentence saying how a layer's name maps to its
/// interval. Bin `t` (layer `t{t:04}`) covers OPL `[start_opl + t·bin_width_opl,
/// start_opl + (t+1)·bin_width_opl)`.
pub fn write_exr_layers_with_axis(
    path: &Path,
    film: FilmView,
    steady: &[f32],
    axis: (f64, f64),
) -> Result<(), OutputError> {
    film.validate(path)?;
    let (start, width) = axis;
    if !start.is_finite() || !width.is_finite() || width <= 0.0 {
        return Err(OutputError::invalid(
            path,
            format!("time axis start_opl={start}, bin_width_opl={width} must be finite with a positive bin width"),
        ));
    }
    check_data(path, &[film.height, film.width, film.channels], steady)?;
    write(path, film, steady, Some(axis))
}

/// The most channels OpenEXR opens in one file (its reader refuses a header with more; the
/// writer wrote them, and `dtr render --exr` with 10 922 RGB bins made a file no viewer opens).
pub const MAX_CHANNELS: usize = 32767;

/// Why a film of `bins` time bins and `channels` colour channels cannot be written as an EXR
/// file: one EXR channel per bin and colour channel, and the steady image's. `None` if it can.
pub fn too_many_channels(bins: usize, channels: usize) -> Option<String> {
    let total = bins.saturating_add(1).saturating_mul(channels);
    (total > MAX_CHANNELS).then(|| {
        format!(
            "{bins} time bins of {channels} channel(s) make {total} EXR channels (one per bin and colour \
             channel, and the steady image's), more than the {MAX_CHANNELS} OpenEXR opens; leave out --exr \
             (the .npy holds every bin) or use at most {} bins",
            MAX_CHANNELS / channels.max(1) - 1
        )
    })
}

fn write(path: &Path, film: FilmView, steady: &[f32], axis: Option<(f64, f64)>) -> Result<(), OutputError> {
    let (h, w, bins, ch) = (film.height, film.width, film.bins, film.channels);
    if i32::try_from(h).is_err() || i32::try_from(w).is_err() || i32::try_from(bins).is_err() {
        return Err(OutputError::invalid(
            path,
            format!("{h}x{w} with {bins} bins is too large for OpenEXR"),
        ));
    }
    if let Some(why) = too_many_channels(bins, ch) {
        return Err(OutputError::invalid(path, why));
    }
    let names: &[&str] = if ch == 1 { &["Y"] } else { &["R", "G", "B"] };
    let digits = (bins - 1).max(1).to_string().len().max(4);

    // One pass over the film in memory order, appending each value to its (bin, channel)
    // plane: linear in the bins, like the single header written once below.
    let pixels = h * w;
    let mut planes: Vec<Vec<f32>> = (0..bins * ch).map(|_| Vec::with_capacity(pixels)).collect();
    for pixel in film.data.chunks_exact(bins * ch) {
        for (plane, &v) in planes.iter_mut().zip(pixel) {
            plane.push(v);
        }
    }
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::with_capacity((bins + 1) * ch);
    for (c, name) in names.iter().enumerate() {
        let plane = steady.iter().skip(c).step_by(ch).copied().collect();
        channels.push(AnyChannel::new(*name, FlatSamples::F32(plane)));
    }
    for (k, plane) in planes.into_iter().enumerate() {
        let (t, c) = (k / ch, k % ch);
        let name = format!("t{t:0digits$}.{}", names[c]);
        channels.push(AnyChannel::new(name.as_str(), FlatSamples::F32(plane)));
    }

    let mut attributes = LayerAttributes {
        software_name: Some(Text::from(concat!("difftransient ", env!("CARGO_PKG_VERSION")))),
        ..Default::default()
    };
    let other = &mut attributes.other;
    other.insert(Text::from("time_bins"), AttributeValue::I32(bins as i32));
    if let Some((start, width)) = axis {
        let ns = 1e9 / SPEED_OF_LIGHT_M_PER_S;
        other.insert(Text::from("start_opl"), AttributeValue::F64(start));
        other.insert(Text::from("bin_width_opl"), AttributeValue::F64(width));
        other.insert(Text::from("end_opl"), AttributeValue::F64(start + bins as f64 * width));
        other.insert(Text::from("start_time_ns"), AttributeValue::F64(start * ns));
        other.insert(Text::from("bin_width_ns"), AttributeValue::F64(width * ns));
        other.insert(Text::from("opl_units"), AttributeValue::Text(Text::from("metres")));
        let last = bins - 1;
        let about = format!(
            "default layer: the steady image; layer t{:0digits$}..t{last:0digits$}: time bin t, \
             optical path length [start_opl + t*bin_width_opl, start_opl + (t+1)*bin_width_opl) metres",
            0
        );
        other.insert(
            Text::from("time_layers"),
            AttributeValue::Text(Text::from(about.as_str())),
        );
    }
    let layer = Layer::new(
        (w, h),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let image = Image::from_layer(layer);
    write_atomic(path, |out| {
        image.write().to_unbuffered(&mut *out).map_err(|e| exr_error(path, e))?;
        out.flush().map_err(|e| OutputError::io(path, e))?;
        sort_header_attributes(out.get_mut()).map_err(|e| OutputError::io(path, e))
    })
}

/// Puts the attributes of a single-part OpenEXR header (the file `file`, written whole) in
/// the order of their names, in place. The exr crate writes the attributes of its own
/// (`LayerAttributes::other`, a `HashMap`) in an order that changes from process to
/// process, so two renders of the same film differed in their header's bytes. The header
/// keeps its length (the same attributes, reordered), so the offset table and the pixels
/// after it stay where they are; OpenEXR reads attributes in any order.
fn sort_header_attributes(file: &mut (impl Read + Write + Seek)) -> std::io::Result<()> {
    use std::io::{Error, ErrorKind, SeekFrom};
    // magic number and version field; a header of this writer is under a few megabytes
    // (its channel list names every bin)
    file.seek(SeekFrom::Start(8))?;
    let mut head = Vec::new();
    Read::by_ref(file).take(64 << 20).read_to_end(&mut head)?;
    let bad = || Error::new(ErrorKind::InvalidData, "OpenEXR header not as written");
    let mut attributes: Vec<&[u8]> = Vec::new();
    let mut at = 0;
    loop {
        let name_len = head[at..].iter().position(|&b| b == 0).ok_or_else(bad)?;
        if name_len == 0 {
            break;
        }
        let type_len = head[at + name_len + 1..].iter().position(|&b| b == 0).ok_or_else(bad)?;
        let size_at = at + name_len + 1 + type_len + 1;
        let size = head.get(size_at..size_at + 4).ok_or_else(bad)?;
        let size = i32::from_le_bytes(size.try_into().map_err(|_| bad())?);
        let end = size_at + 4 + usize::try_from(size).map_err(|_| bad())?;
        attributes.push(head.get(at..end).ok_or_else(bad)?);
        at = end;
    }
    // names end at their first 0 byte, so ordering by the whole attribute orders by name
    attributes.sort_unstable();
    let sorted = attributes.concat();
    file.seek(SeekFrom::Start(8))?;
    file.write_all(&sorted)?;
    file.flush()
}

fn exr_error(path: &Path, e: exr::error::Error) -> OutputError {
    match e {
        exr::error::Error::Io(io) => OutputError::io(path, io),
        other => OutputError::encode(path, "OpenEXR", other),
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{coded_film, entries};
    use super::*;

    fn read_all(path: &Path) -> Image<Layers<AnyChannels<FlatSamples>>> {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_file(path)
            .unwrap()
    }

    fn sample(layer: &Layer<AnyChannels<FlatSamples>>, name: &str, x: usize, y: usize) -> f32 {
        let ch = layer.channel_data.list.iter().find(|c| c.name == *name).unwrap();
        match &ch.sample_data {
            FlatSamples::F32(v) => v[y * layer.size.0 + x],
            other => panic!("expected f32 samples, got {other:?}"),
        }
    }

    fn names(layer: &Layer<AnyChannels<FlatSamples>>) -> Vec<String> {
        layer.channel_data.list.iter().map(|c| c.name.to_string()).collect()
    }

    /// Two writes of one film give the same bytes. Before, the header's own attributes came
    /// in the order of the exr crate's `HashMap`, another at every write (found by an
    /// independent sweep: two identical renders, the same `.npy`, different `.exr`).
    #[test]
    fn the_same_film_writes_the_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let (h, w, t, c) = (2, 3, 5, 3);
        let data = coded_film(h, w, t, c);
        let steady = vec![1.0f32; h * w * c];
        let film = FilmView {
            data: &data,
            height: h,
            width: w,
            bins: t,
            channels: c,
        };
        let bytes: Vec<Vec<u8>> = (0..4)
            .map(|k| {
                let p = dir.path().join(format!("f{k}.exr"));
                write_exr_layers_with_axis(&p, film, &steady, (1.5, 0.25)).unwrap();
                std::fs::read(&p).unwrap()
            })
            .collect();
        assert!(bytes.iter().all(|b| *b == bytes[0]), "the four writes differ");
        let layer = &read_all(&dir.path().join("f0.exr")).layer_data[0];
        let other = &layer.attributes.other;
        assert_eq!(other.len(), 8, "{other:?}");
        assert!(matches!(
            other.get(&Text::from("time_bins")),
            Some(AttributeValue::I32(5))
        ));
        assert!(matches!(other.get(&Text::from("start_opl")), Some(AttributeValue::F64(v)) if *v == 1.5));
    }

    #[test]
    fn rgb_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("film.exr");
        let (h, w, t, c) = (3, 5, 4, 3);
        let data = coded_film(h, w, t, c);
        let steady: Vec<f32> = (0..h * w * c).map(|i| i as f32 * 0.5 - 3.0).collect();
        let film = FilmView {
            data: &data,
            height: h,
            width: w,
            bins: t,
            channels: c,
        };
        write_exr_layers_with_axis(&p, film, &steady, (1.5, 0.25)).unwrap();
        let img = read_all(&p);
        assert_eq!(img.layer_data.len(), 1, "one part");
        let layer = &img.layer_data[0];
        assert_eq!(layer.size, Vec2(w, h));
        let mut expected = vec!["B".to_string(), "G".into(), "R".into()];
        for b in 0..t {
            expected.extend(["B", "G", "R"].map(|n| format!("t{b:04}.{n}")));
        }
        assert_eq!(names(layer), expected);
        for (y, x) in [(0, 0), (2, 4), (1, 3)] {
            for (ci, n) in ["R", "G", "B"].iter().enumerate() {
                assert_eq!(
                    sample(layer, n, x, y),
                    steady[(y * w + x) * c + ci],
                    "steady ({x},{y}) {n}"
                );
                for b in 0..t {
                    assert_eq!(
                        sample(layer, &format!("t{b:04}.{n}"), x, y),
                        data[film.index(y, x, b, ci)],
                        "t{b} ({x},{y}) {n}"
                    );
                }
            }
        }
        let other = &layer.attributes.other;
        let get = |k: &str| other.get(&Text::from(k)).cloned();
        assert_eq!(get("time_bins"), Some(AttributeValue::I32(t as i32)));
        assert_eq!(get("start_opl"), Some(AttributeValue::F64(1.5)));
        assert_eq!(get("bin_width_opl"), Some(AttributeValue::F64(0.25)));
        assert_eq!(get("end_opl"), Some(AttributeValue::F64(2.5)));
        assert_eq!(get("opl_units"), Some(AttributeValue::Text(Text::from("metres"))));
        match get("bin_width_ns") {
            Some(AttributeValue::F64(ns)) => assert!((ns - 0.833_910_24).abs() < 1e-6, "{ns}"),
            other => panic!("bin_width_ns: {other:?}"),
        }
        assert_eq!(entries(dir.path()), vec!["film.exr"]);
    }

    #[test]
    fn mono_default_layer_is_the_time_sum() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("mono.exr");
        let (h, w, t) = (4, 2, 3);
        let data = coded_film(h, w, t, 1);
        let film = FilmView {
            data: &data,
            height: h,
            width: w,
            bins: t,
            channels: 1,
        };
        write_exr_layers(&p, film).unwrap();
        let img = read_all(&p);
        let layer = &img.layer_data[0];
        assert_eq!(names(layer), ["Y", "t0000.Y", "t0001.Y", "t0002.Y"]);
        assert_eq!(sample(layer, "t0002.Y", 1, 3), data[film.index(3, 1, 2, 0)]);
        assert_eq!(sample(layer, "t0000.Y", 0, 0), 0.25);
        // (3, 1): 3100.25 + 3110.25 + 3120.25
        assert_eq!(sample(layer, "Y", 1, 3), 9330.75);
        let other = &layer.attributes.other;
        assert_eq!(other.get(&Text::from("time_bins")), Some(&AttributeValue::I32(3)));
        assert_eq!(other.get(&Text::from("start_opl")), None, "no axis given");
    }

    #[test]
    fn many_bins_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("many.exr");
        let (h, w, t) = (17, 3, 10_003);
        let data = coded_film(h, w, t, 1);
        let film = FilmView {
            data: &data,
            height: h,
            width: w,
            bins: t,
            channels: 1,
        };
        write_exr_layers(&p, film).unwrap();
        let img = read_all(&p);
        let layer = &img.layer_data[0];
        assert_eq!(layer.channel_data.list.len(), t + 1);
        for b in [0, 1, 9_999, 10_002] {
            for (y, x) in [(0, 0), (16, 2), (9, 1)] {
                assert_eq!(
                    sample(layer, &format!("t{b:05}.Y"), x, y),
                    data[film.index(y, x, b, 0)],
                    "t{b} ({x},{y})"
                );
            }
        }
    }

    /// OpenEXR opens at most 32 767 channels: a film needing more (one per bin and colour
    /// channel, and the steady image's) is refused, and no file is left. Before, 10 922 RGB
    /// bins wrote a file OpenEXR 3.5 would not open (exit 0; found by an independent audit).
    #[test]
    fn films_of_more_channels_than_openexr_opens_are_refused() {
        assert!(too_many_channels(32_766, 1).is_none());
        assert!(too_many_channels(32_767, 1).is_some());
        assert!(too_many_channels(10_921, 3).is_none());
        let why = too_many_channels(10_922, 3).unwrap();
        assert!(
            why.contains("32769 EXR channels") && why.contains("at most 10921 bins"),
            "{why}"
        );
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("wide.exr");
        let data = vec![0.5f32; 10_922 * 3];
        let film = FilmView {
            data: &data,
            height: 1,
            width: 1,
            bins: 10_922,
            channels: 3,
        };
        let e = write_exr_layers(&p, film).unwrap_err().to_string();
        assert!(e.contains("more than the 32767 OpenEXR opens"), "{e}");
        assert!(!p.exists());
    }

    #[test]
    fn refuses_bad_films_without_leaving_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.exr");
        let mut data = coded_film(2, 2, 2, 1);
        data[3] = f32::NAN;
        let film = FilmView {
            data: &data,
            height: 2,
            width: 2,
            bins: 2,
            channels: 1,
        };
        let e = write_exr_layers(&p, film).unwrap_err();
        assert!(e.to_string().contains("1 of 8 values are not finite"), "{e}");
        let e = write_exr_layers(
            &p,
            FilmView {
                data: &[],
                height: 0,
                width: 0,
                bins: 0,
                channels: 1,
            },
        )
        .unwrap_err();
        assert!(matches!(e, OutputError::Empty { .. }), "{e}");
        let e = write_exr_layers(
            &p,
            FilmView {
                channels: 4,
                bins: 1,
                ..film
            },
        )
        .unwrap_err();
        assert!(matches!(e, OutputError::Channels { .. }), "{e}");
        let good = coded_film(2, 2, 2, 1);
        let film = FilmView { data: &good, ..film };
        let steady = [1.0f32; 4];
        let e = write_exr_layers_with_axis(&p, film, &steady, (0.0, 0.0)).unwrap_err();
        assert!(e.to_string().contains("bin width"), "{e}");
        let e = write_exr_layers_with_axis(&p, film, &steady[..3], (0.0, 1.0)).unwrap_err();
        assert!(matches!(e, OutputError::ShapeMismatch { .. }), "{e}");
        let e = write_exr_layers_with_axis(&p, film, &[1.0, f32::INFINITY, 0.0, 0.0], (0.0, 1.0)).unwrap_err();
        assert!(matches!(e, OutputError::NonFinite { .. }), "{e}");
        let e = write_exr_layers(&dir.path().join("missing/x.exr"), film).unwrap_err();
        assert!(matches!(e, OutputError::Io { .. }), "{e}");
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }
}
