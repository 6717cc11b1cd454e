//! `dtr render --preview` pictures of light in flight (issue 15): the animation has a frame
//! per bin in the film's display mapping, the streak image is the chosen row against time,
//! derivative previews carry the derivative's sign, and the HDR steady image is the time sum.

use crate::common;
use image::AnimationDecoder;
use image::codecs::gif::GifDecoder;
use std::path::Path;

const SCENE: &str = "shadow_hidden_occluder.toml";

/// Height of the time-label strip above each animation frame (`output/label.rs`).
const LABEL_STRIP: u32 = 18;

/// The animation's frames, whole (label strip and picture).
fn whole_frames(path: &Path) -> Vec<image::RgbaImage> {
    let dec = GifDecoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap())).unwrap();
    dec.into_frames()
        .collect_frames()
        .unwrap()
        .into_iter()
        .map(|f| f.into_buffer())
        .collect()
}

/// The animation's pictures, below their label strips.
fn frames(path: &Path) -> Vec<image::RgbaImage> {
    whole_frames(path)
        .into_iter()
        .map(|f| {
            let (w, h) = f.dimensions();
            image::imageops::crop_imm(&f, 0, LABEL_STRIP, w, h - LABEL_STRIP).to_image()
        })
        .collect()
}

fn render(dir: &Path, extra: &[&str]) -> std::path::PathBuf {
    let scene = common::scene_path(SCENE);
    let prefix = dir.join("p");
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "--spp",
        "16",
        "--preview",
        "-o",
        prefix.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = common::dtr(&args, dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    prefix
}

fn with(prefix: &Path, suffix: &str) -> std::path::PathBuf {
    prefix.with_file_name(format!("p.{suffix}"))
}

#[test]
fn previews_show_the_film_in_time_and_the_derivatives_sign() {
    let dir = tempfile::tempdir().unwrap();
    let prefix = render(dir.path(), &["--diff", "occluder_x", "--pixel", "16,20"]);
    let (shape, film) = common::npy(&with(&prefix, "npy"));
    let [h, w, bins, ch] = [shape[0], shape[1], shape[2], shape[3]].map(|v| v as usize);
    let at = |y: usize, x: usize, t: usize, c: usize| film[((y * w + x) * bins + t) * ch + c];

    // the animation: one frame per bin, the film enlarged; an empty bin is a black frame, and
    // the brightest value of the film reaches display white
    let gif = frames(&with(&prefix, "flight.gif"));
    assert_eq!(gif.len(), bins);
    let up = gif[0].width() as usize / w;
    assert!(up >= 1 && gif[0].height() as usize == h * up);
    // each frame's strip carries its time label: white text on black, different per bin
    let strips: Vec<Vec<u8>> = whole_frames(&with(&prefix, "flight.gif"))
        .iter()
        .map(|f| {
            image::imageops::crop_imm(f, 0, 0, f.width(), LABEL_STRIP)
                .to_image()
                .into_raw()
        })
        .collect();
    for (t, strip) in strips.iter().enumerate() {
        assert!(strip.chunks(4).filter(|p| p[0] > 200).count() > 30, "bin {t}: no label");
    }
    assert!(strips.windows(2).all(|p| p[0] != p[1]), "two bins share a label");
    let (mut peak_bin, mut peak) = (0, 0.0f32);
    for t in 0..bins {
        let max = (0..h * w).map(|p| at(p / w, p % w, t, 0)).fold(0.0f32, f32::max);
        let lit = gif[t].pixels().any(|p| p.0[0] > 0);
        if max == 0.0 {
            assert!(!lit, "bin {t} is empty but its frame is not black");
        }
        if max > peak {
            (peak_bin, peak) = (t, max);
        }
    }
    assert!(peak > 0.0);
    assert!(
        gif[peak_bin].pixels().any(|p| p.0[0] == 255),
        "the brightest bin does not reach white"
    );

    // the streak image: row 20, x across, one image row per bin; black where the film is 0
    let streak = image::open(with(&prefix, "streak.png")).unwrap().to_rgb8();
    assert_eq!((streak.width() as usize, streak.height() as usize), (w * up, bins));
    for t in 0..bins {
        for x in 0..w {
            let v = streak.get_pixel((x * up) as u32, t as u32).0[0];
            if at(20, x, t, 0) == 0.0 {
                assert_eq!(v, 0, "streak ({x}, {t}) is lit where the film is 0");
            }
        }
    }
    assert!(streak.pixels().any(|p| p.0[0] > 0));

    // the derivative preview: red where dI/dθ integrates positive, blue where negative
    let (_, d) = common::npy(&with(&prefix, "d_occluder_x.npy"));
    let sum = |p: usize| (0..bins).map(|t| d[p * bins + t] as f64).sum::<f64>();
    let (pmax, pmin) = (0..h * w).fold((0, 0), |(a, b), p| {
        (if sum(p) > sum(a) { p } else { a }, if sum(p) < sum(b) { p } else { b })
    });
    assert!(
        sum(pmax) > 0.0 && sum(pmin) < 0.0,
        "the shadow edge moves: both signs expected"
    );
    let dp = image::open(with(&prefix, "d_occluder_x.png")).unwrap().to_rgb8();
    let px = |p: usize| dp.get_pixel(((p % w) * up) as u32, ((p / w) * up) as u32).0;
    let (pos, neg) = (px(pmax), px(pmin));
    assert!(pos[0] == 255 && pos[2] < 255, "positive derivative not red: {pos:?}");
    assert!(neg[2] == 255 && neg[0] < 255, "negative derivative not blue: {neg:?}");

    // the HDR steady image is the time sum of the transient (window mode)
    let (sshape, steady) = common::npy(&with(&prefix, "steady.npy"));
    assert_eq!(sshape, vec![h as u64, w as u64, ch as u64]);
    for p in 0..h * w {
        let s: f64 = (0..bins).map(|t| at(p / w, p % w, t, 0) as f64).sum();
        assert!(
            (steady[p] as f64 - s).abs() <= 1e-5 * s.abs().max(1e-6),
            "pixel {p}: {} vs {s}",
            steady[p]
        );
    }
}

#[test]
fn per_frame_normalisation_brings_every_lit_frame_to_white() {
    let dir = tempfile::tempdir().unwrap();
    let prefix = render(dir.path(), &["--normalise", "frame"]);
    let (shape, film) = common::npy(&with(&prefix, "npy"));
    let [h, w, bins] = [shape[0], shape[1], shape[2]].map(|v| v as usize);
    let gif = frames(&with(&prefix, "flight.gif"));
    let mut lit_frames = 0;
    for t in 0..bins {
        let lit = (0..h * w).any(|p| film[p * bins + t] > 0.0);
        if lit {
            lit_frames += 1;
            assert!(
                gif[t].pixels().any(|p| p.0[0] == 255),
                "lit bin {t} does not reach white"
            );
        }
    }
    assert!(lit_frames >= 2);
    let bad = common::dtr(
        &[
            "render",
            common::scene_path(SCENE).to_str().unwrap(),
            "--preview",
            "--normalise",
            "some",
            "-o",
            "x",
        ],
        dir.path(),
    );
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("normalise"));
}

/// `--exr` is one part whose default layer is the steady image (here all time, so it is not
/// just the sum of the bins) and whose layer `tNNNN` is bin NNNN of the .npy, with the film's
/// time axis (f64 metres of OPL and ns) in the header, as the JSON has it.
#[test]
fn exr_holds_the_steady_image_every_bin_and_the_time_axis() {
    use exr::meta::attribute::{AttributeValue, Text};
    use exr::prelude::{FlatSamples, ReadChannels, ReadLayers};
    let dir = tempfile::tempdir().unwrap();
    let scene = common::scene_path(SCENE);
    let prefix = dir.path().join("p");
    let out = common::dtr(
        &[
            "render",
            scene.to_str().unwrap(),
            "--spp",
            "1",
            "--exr",
            "--preview",
            "--steady",
            "full",
            "--set",
            "film.start_opl=4.0000001",
            "-o",
            prefix.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(with(&prefix, "json")).unwrap()).unwrap();
    let width = json["time_axis"]["bin_width_opl"].as_f64().unwrap();
    assert_eq!(json["time_axis"]["start_opl"].as_f64(), Some(4.0000001));
    let (shape, film) = common::npy(&with(&prefix, "npy"));
    let (_, steady) = common::npy(&with(&prefix, "steady.npy"));
    let [h, w, bins, c] = [0, 1, 2, 3].map(|i| shape[i] as usize);
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(with(&prefix, "exr"))
        .unwrap();
    assert_eq!(image.layer_data.len(), 1, "a single part");
    let layer = &image.layer_data[0];
    let get = |k: &str| layer.attributes.other.get(&Text::from(k)).cloned();
    assert_eq!(get("start_opl"), Some(AttributeValue::F64(4.0000001)));
    assert_eq!(get("bin_width_opl"), Some(AttributeValue::F64(width)));
    assert_eq!(
        get("end_opl"),
        Some(AttributeValue::F64(4.0000001 + bins as f64 * width))
    );
    assert_eq!(get("time_bins"), Some(AttributeValue::I32(bins as i32)));
    assert_eq!(get("opl_units"), Some(AttributeValue::Text(Text::from("metres"))));
    let names: &[&str] = if c == 1 { &["Y"] } else { &["R", "G", "B"] };
    assert_eq!(layer.channel_data.list.len(), (bins + 1) * c);
    let plane = |name: &str| -> &Vec<f32> {
        let ch = layer
            .channel_data
            .list
            .iter()
            .find(|ch| ch.name == *name)
            .unwrap_or_else(|| panic!("{name}"));
        match &ch.sample_data {
            FlatSamples::F32(v) => v,
            other => panic!("{name}: f32 expected, got {other:?}"),
        }
    };
    let mut binned_sum = 0.0f64;
    for (ci, n) in names.iter().enumerate() {
        let default: Vec<f32> = (0..h * w).map(|p| steady[p * c + ci]).collect();
        assert_eq!(plane(n), &default, "default layer {n} = steady.npy");
        for t in 0..bins {
            let bin: Vec<f32> = (0..h * w).map(|p| film[(p * bins + t) * c + ci]).collect();
            binned_sum += bin.iter().map(|&v| v as f64).sum::<f64>();
            assert_eq!(plane(&format!("t{t:04}.{n}")), &bin, "bin {t} channel {n}");
        }
    }
    let steady_sum: f64 = steady.iter().map(|&v| v as f64).sum();
    assert!(
        binned_sum > 0.0 && steady_sum > binned_sum,
        "full steady {steady_sum} vs window {binned_sum}"
    );
}
