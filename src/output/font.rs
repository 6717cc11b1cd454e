//! The font for plot text. plotters' `ab_glyph` backend draws only fonts registered from
//! bytes, so one TrueType file is read from the system once and registered as `sans-serif`.
//!
//! Search order: the file named by `DIFFTRANSIENT_FONT` (if set, it must work), then common
//! locations of DejaVu Sans (Debian/Ubuntu package `fonts-dejavu-core`), Liberation Sans,
//! FreeSans and Noto Sans on Linux, and Arial/Helvetica on macOS and Windows.

use std::path::PathBuf;
use std::sync::OnceLock;

/// Environment variable naming a TrueType/OpenType font file for plot text.
pub const FONT_ENV: &str = "DIFFTRANSIENT_FONT";

/// The font family name plot text uses.
pub(crate) const FAMILY: &str = "sans-serif";

const CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", // Debian/Ubuntu: fonts-dejavu-core
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf", // Fedora
    "/usr/share/fonts/TTF/DejaVuSans.ttf",               // Arch
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/liberation2/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/freefont/FreeSans.ttf",
    "/usr/share/fonts/truetype/noto/NotoSans-Regular.ttf",
    "/usr/share/fonts/noto/NotoSans-Regular.ttf",
    "/Library/Fonts/Arial.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

static REGISTERED: OnceLock<Result<PathBuf, String>> = OnceLock::new();

/// Registers the plot font on first use; afterwards returns the same outcome: the font file
/// used, or a message saying what to install.
pub(crate) fn ensure_font() -> Result<PathBuf, String> {
    REGISTERED.get_or_init(register).clone()
}

fn register() -> Result<PathBuf, String> {
    if let Some(p) = std::env::var_os(FONT_ENV).filter(|p| !p.is_empty()) {
        let p = PathBuf::from(p);
        return try_register(&p)
            .map(|()| p.clone())
            .map_err(|e| format!("{FONT_ENV}={}: {e}", p.display()));
    }
    let mut tried = Vec::new();
    for c in CANDIDATES {
        let p = PathBuf::from(c);
        if !p.is_file() {
            continue;
        }
        match try_register(&p) {
            Ok(()) => return Ok(p),
            Err(e) => tried.push(format!("{c}: {e}")),
        }
    }
    let mut msg = format!(
        "no font found for the plot's text: install the Debian/Ubuntu package fonts-dejavu-core \
         (it provides {}), or set {FONT_ENV} to a .ttf/.otf file",
        CANDIDATES[0]
    );
    if !tried.is_empty() {
        msg.push_str(&format!(" (unusable: {})", tried.join("; ")));
    }
    Err(msg)
}

fn try_register(path: &std::path::Path) -> Result<(), String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    // plotters keeps registered fonts for the life of the process and wants `'static` bytes;
    // this leaks one font file, once per process.
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font(FAMILY, plotters::style::FontStyle::Normal, bytes)
        .map_err(|_| "not a TrueType/OpenType font".to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_system_font_is_found() {
        // CI needs a font: on Debian, `apt-get install fonts-dejavu-core`.
        let p = ensure_font().unwrap_or_else(|e| panic!("{e}"));
        assert!(p.is_file());
    }

    #[test]
    fn garbage_is_not_a_font() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("fake.ttf");
        std::fs::write(&p, b"not a font at all").unwrap();
        assert!(try_register(&p).unwrap_err().contains("not a TrueType"));
        assert!(try_register(&dir.path().join("missing.ttf")).is_err());
    }
}
