//! Multi-layer OpenEXR: one layer (EXR part) per time bin, named `t0000`, `t0001`, ...,
//! with channel `Y` (mono) or `R`, `G`, `B` (RGB) as f32 samples.

use super::atomic::write_atomic;
use super::{FilmView, OutputError, SPEED_OF_LIGHT_M_PER_S};
use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::*;
use std::path::Path;
use std::result::Result;

/// Writes `film` as a multi-layer OpenEXR file, one layer per time bin, atomically.
///
/// Layers are named `t0000`, `t0001`, ... (more digits when there are more than 10000 bins),
/// each with channel `Y` (mono) or `R`, `G`, `B` (RGB), f32, ZIP-compressed. Every layer
/// carries the custom attribute `time_bin` (i32).
pub fn write_exr_layers(path: &Path, film: FilmView) -> Result<(), OutputError> {
    write_exr_layers_with_axis(path, film, None)
}

/// [`write_exr_layers`], plus the time axis as custom attributes when `axis` is
/// `Some((start_opl, bin_width_opl))` (metres of optical path length): on every layer
/// `start_opl`, `bin_width_opl` and this bin's `opl_begin`/`opl_end` and `time_begin_ns`
/// (f64, like the time axis everywhere) and the text `opl_units` = `metres`.
pub fn write_exr_layers_with_axis(path: &Path, film: FilmView, axis: Option<(f64, f64)>) -> Result<(), OutputError> {
    film.validate(path)?;
    if let Some((start, width)) = axis
        && (!start.is_finite() || !width.is_finite() || width <= 0.0)
    {
        return Err(OutputError::invalid(
            path,
            format!("time axis start_opl={start}, bin_width_opl={width} must be finite with a positive bin width"),
        ));
    }
    let (h, w, bins, ch) = (film.height, film.width, film.bins, film.channels);
    if i32::try_from(h).is_err() || i32::try_from(w).is_err() || i32::try_from(bins).is_err() {
        return Err(OutputError::invalid(
            path,
            format!("{h}x{w} with {bins} bins is too large for OpenEXR"),
        ));
    }
    let names: &[&str] = if ch == 1 { &["Y"] } else { &["R", "G", "B"] };
    let digits = (bins - 1).max(1).to_string().len().max(4);

    let mut layers = Vec::with_capacity(bins);
    for t in 0..bins {
        let channels: Vec<AnyChannel<FlatSamples>> = names
            .iter()
            .enumerate()
            .map(|(c, name)| {
                let mut samples = Vec::with_capacity(h * w);
                for y in 0..h {
                    for x in 0..w {
                        samples.push(film.data[film.index(y, x, t, c)]);
                    }
                }
                AnyChannel::new(*name, FlatSamples::F32(samples))
            })
            .collect();
        let mut attributes = LayerAttributes::named(format!("t{t:0digits$}").as_str());
        let other = &mut attributes.other;
        other.insert(Text::from("time_bin"), AttributeValue::I32(t as i32));
        if let Some((start, width)) = axis {
            let begin = start + t as f64 * width;
            other.insert(Text::from("start_opl"), AttributeValue::F64(start));
            other.insert(Text::from("bin_width_opl"), AttributeValue::F64(width));
            other.insert(Text::from("opl_begin"), AttributeValue::F64(begin));
            other.insert(Text::from("opl_end"), AttributeValue::F64(begin + width));
            other.insert(
                Text::from("time_begin_ns"),
                AttributeValue::F64(begin / SPEED_OF_LIGHT_M_PER_S * 1e9),
            );
            other.insert(Text::from("opl_units"), AttributeValue::Text(Text::from("metres")));
        }
        attributes.software_name = Some(Text::from(concat!("difftransient ", env!("CARGO_PKG_VERSION"))));
        layers.push(Layer::new(
            (w, h),
            attributes,
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(channels.into()),
        ));
    }
    let image = Image::from_layers(ImageAttributes::new(IntegerBounds::from_dimensions((w, h))), layers);

    // The exr crate's parallel compressor clones the headers of every layer for each block it
    // queues: O(bins²) with one layer per bin (2000 bins took 5.5 s, 4000 bins 22 s). The
    // sequential writer touches each header once, so the file is written in time linear in
    // the bins; only small layer counts keep the parallel compressor.
    let writer = image.write();
    let writer = if bins > PARALLEL_MAX_LAYERS {
        writer.non_parallel()
    } else {
        writer
    };
    write_atomic(path, |out| {
        writer.to_unbuffered(&mut *out).map_err(|e| exr_error(path, e))
    })
}

/// Most layers (time bins) written with the exr crate's parallel compressor.
const PARALLEL_MAX_LAYERS: usize = 64;

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

    #[test]
    fn rgb_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("film.exr");
        let (h, w, t, c) = (3, 5, 4, 3);
        let data = coded_film(h, w, t, c);
        let film = FilmView {
            data: &data,
            height: h,
            width: w,
            bins: t,
            channels: c,
        };
        write_exr_layers_with_axis(&p, film, Some((1.5, 0.25))).unwrap();
        let img = read_all(&p);
        assert_eq!(img.layer_data.len(), t);
        for (b, layer) in img.layer_data.iter().enumerate() {
            assert_eq!(
                layer.attributes.layer_name,
                Some(Text::from(format!("t{b:04}").as_str()))
            );
            assert_eq!(layer.size, Vec2(w, h));
            let names: Vec<String> = layer.channel_data.list.iter().map(|c| c.name.to_string()).collect();
            assert_eq!(names, vec!["B", "G", "R"]);
            for (y, x) in [(0, 0), (2, 4), (1, 3)] {
                for (ci, n) in ["R", "G", "B"].iter().enumerate() {
                    assert_eq!(
                        sample(layer, n, x, y),
                        data[film.index(y, x, b, ci)],
                        "t{b} ({x},{y}) {n}"
                    );
                }
            }
            let other = &layer.attributes.other;
            assert_eq!(other.get(&Text::from("time_bin")), Some(&AttributeValue::I32(b as i32)));
            assert_eq!(
                other.get(&Text::from("opl_begin")),
                Some(&AttributeValue::F64(1.5 + 0.25 * b as f64))
            );
        }
        assert_eq!(entries(dir.path()), vec!["film.exr"]);
    }

    #[test]
    fn mono_round_trip() {
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
        assert_eq!(img.layer_data.len(), 3);
        let last = &img.layer_data[2];
        assert_eq!(last.attributes.layer_name, Some(Text::from("t0002")));
        assert_eq!(last.channel_data.list.len(), 1);
        assert_eq!(sample(last, "Y", 1, 3), data[film.index(3, 1, 2, 0)]);
        assert_eq!(sample(&img.layer_data[0], "Y", 0, 0), 0.25);
    }

    #[test]
    fn many_bins_round_trip_through_the_sequential_writer() {
        // more layers than PARALLEL_MAX_LAYERS: the sequential compressor writes them
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("many.exr");
        let (h, w, t) = (17, 3, PARALLEL_MAX_LAYERS * 2 + 5);
        let data = coded_film(h, w, t, 1);
        let film = FilmView {
            data: &data,
            height: h,
            width: w,
            bins: t,
            channels: 1,
        };
        write_exr_layers_with_axis(&p, film, Some((0.0, 0.5))).unwrap();
        let img = read_all(&p);
        assert_eq!(img.layer_data.len(), t);
        for (b, layer) in img.layer_data.iter().enumerate() {
            assert_eq!(
                layer.attributes.layer_name,
                Some(Text::from(format!("t{b:04}").as_str()))
            );
            for (y, x) in [(0, 0), (16, 2), (9, 1)] {
                assert_eq!(sample(layer, "Y", x, y), data[film.index(y, x, b, 0)], "t{b} ({x},{y})");
            }
        }
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
        let e = write_exr_layers_with_axis(&p, film, Some((0.0, 0.0))).unwrap_err();
        assert!(e.to_string().contains("bin width"), "{e}");
        let e = write_exr_layers(&dir.path().join("missing/x.exr"), film).unwrap_err();
        assert!(matches!(e, OutputError::Io { .. }), "{e}");
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }
}
