//! Time labels drawn onto preview frames (contact sheet cells, animation frames): the bin's
//! centre as optical path length and as time of flight, in the plot font (`font.rs`) through
//! plotters' own text rendering.

use super::font::{FAMILY, ensure_font};
use crate::temporal::TimeAxis;
use plotters::prelude::*;

/// Height of a label strip in pixels, and the text size in it.
pub(crate) const LABEL_H: usize = 18;
const TEXT_PX: u32 = 13;

/// The label of bin `t`, as long as fits in `width` pixels: "3.69 m · 12.31 ns", else
/// "12.3 ns", else nothing.
pub(crate) fn bin_label(axis: &TimeAxis, t: usize, width: usize) -> Option<String> {
    let opl = axis.bin_centre(t);
    let ns = TimeAxis::time_ns_of_opl(opl);
    if width >= 130 {
        Some(format!("{opl:.2} m · {ns:.2} ns"))
    } else if width >= 56 {
        Some(format!("{ns:.1} ns"))
    } else {
        None
    }
}

/// The axis to label frames `width` pixels wide with: `axis` when it is this film's (`bins`
/// bins), a label fits and a font was found; else `None` (no label strip).
pub(crate) fn label_axis(axis: Option<&TimeAxis>, bins: usize, width: usize) -> Option<&TimeAxis> {
    axis.filter(|a| a.bins == bins && bin_label(a, 0, width).is_some() && labels_available())
}

/// Whether labels can be drawn (a font was found); says once why not.
pub(crate) fn labels_available() -> bool {
    match ensure_font() {
        Ok(_) => true,
        Err(why) => {
            static SAID: std::sync::Once = std::sync::Once::new();
            SAID.call_once(|| log::warn!("previews without time labels: {why}"));
            false
        }
    }
}

/// Draws `texts` (top-left corner in pixels, text) in white onto the RGB8 image `rgb` of
/// `w` × `h` pixels, each clipped to a box of `box_w` × [`LABEL_H`].
pub(crate) fn draw_labels(rgb: &mut [u8], w: usize, h: usize, box_w: usize, texts: &[((usize, usize), String)]) {
    let root = BitMapBackend::with_buffer(rgb, (w as u32, h as u32)).into_drawing_area();
    let style = (FAMILY, TEXT_PX).into_font().color(&WHITE);
    for ((x, y), text) in texts {
        let area = root
            .clone()
            .shrink((*x as u32, *y as u32), (box_w as u32, LABEL_H as u32));
        // drawing errors (a glyph the font lacks) leave the label out, not the picture
        let _ = area.draw(&Text::new(text.as_str(), (3, 2), style.clone()));
    }
    let _ = root.present();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_shrink_with_the_cell() {
        let axis = TimeAxis {
            start_opl: 3.6,
            bin_width_opl: 0.06,
            bins: 200,
        };
        assert_eq!(bin_label(&axis, 0, 200).unwrap(), "3.63 m · 12.11 ns");
        assert_eq!(bin_label(&axis, 0, 80).unwrap(), "12.1 ns");
        assert_eq!(bin_label(&axis, 0, 40), None);
    }

    #[test]
    fn text_is_drawn_inside_its_box() {
        assert!(labels_available(), "CI needs a font (fonts-dejavu-core)");
        let (w, h) = (120, 40);
        let mut px = vec![0u8; w * h * 3];
        draw_labels(&mut px, w, h, 60, &[((10, 5), "12.3 ns".into())]);
        let lit: Vec<(usize, usize)> = (0..w * h)
            .filter(|&i| px[i * 3] > 128)
            .map(|i| (i % w, i / w))
            .collect();
        assert!(lit.len() > 20, "no text drawn");
        assert!(
            lit.iter()
                .all(|&(x, y)| (10..70).contains(&x) && (5..5 + LABEL_H).contains(&y))
        );
    }
}
