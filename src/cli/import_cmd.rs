//! `dtr import scene.xml -o scene.toml`: a Mitsuba 3 XML scene converted to our TOML
//! description (checked by loading it first), written atomically, or printed.

use super::output_set::{input_metadata, make_output_folder, replaced_input};
use crate::scene::{Format, Scene, mitsuba};
use anyhow::bail;
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ImportArgs {
    /// The Mitsuba 3 scene (.xml).
    pub scene: PathBuf,
    /// Where to write the TOML description (default: print it); a missing folder is made.
    /// Relative mesh file names are made absolute when it lies in another folder than the
    /// XML file.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

pub fn run(a: ImportArgs) -> anyhow::Result<()> {
    if !mitsuba::is_xml(&a.scene) {
        bail!(
            "{}: dtr import reads Mitsuba 3 scenes: expected a file ending in .xml",
            a.scene.display()
        );
    }
    let out_dir = a.output.as_deref().map(|o| o.parent().unwrap_or(Path::new("")));
    let imported = mitsuba::import_for(&a.scene, out_dir)?;
    // The description must load as it is written: resolve it now (meshes read, values
    // checked). Its mesh names resolve from the XML file's folder as from the output's (they
    // are made absolute when the folders differ), so it is loaded as the XML file's: an
    // error names the file the user wrote, not the output that is not written yet.
    let scene = Scene::from_str(&imported.toml, Format::Toml, &a.scene, &[]).map_err(|e| imported.annotate(e))?;
    imported.check(&scene, &a.scene)?;
    match &a.output {
        None => super::write_stdout(imported.toml.as_bytes())?,
        Some(out) => {
            if out.extension().and_then(|e| e.to_str()) != Some("toml") {
                bail!(
                    "{}: the output is a TOML description: expected a file ending in .toml",
                    out.display()
                );
            }
            // the XML file, the files it includes and the meshes it names (as `dtr render` checks)
            let inputs: Vec<PathBuf> = scene.inputs.iter().chain(&imported.included).cloned().collect();
            if let Ok(meta) = std::fs::metadata(out)
                && let Some(input) = replaced_input(&meta, &input_metadata(&inputs))
            {
                bail!(
                    "{}: the output would replace the input {}; nothing was written. Choose another -o",
                    out.display(),
                    input.display()
                );
            }
            // only an earlier import is replaced: a file of the user's under that name is not
            // dtr's to overwrite (as `dtr render` replaces only its own sets)
            if std::fs::symlink_metadata(out).is_ok() && !is_earlier_import(out) {
                bail!(
                    "{}: the output exists and is not a description dtr import wrote (its first line does not \
                     begin \"{}\"); nothing was written. Move it away or choose another -o",
                    out.display(),
                    mitsuba::IMPORT_HEADER.trim_end()
                );
            }
            // a missing folder is made, as `dtr render -o` makes its output folder
            make_output_folder(out, out)?;
            crate::output::write_atomic(out, |w| {
                w.write_all(imported.toml.as_bytes())
                    .map_err(|e| crate::output::OutputError::io(out, e))
            })?;
            eprintln!("wrote {}", out.display());
        }
    }
    Ok(())
}

/// Whether `path` is a file an earlier `dtr import` wrote: its first line begins with
/// [`mitsuba::IMPORT_HEADER`].
fn is_earlier_import(path: &Path) -> bool {
    use std::io::Read;
    let mut head = vec![0u8; mitsuba::IMPORT_HEADER.len()];
    // (a FIFO there would block the open: it is no import)
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return false;
    }
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| head == mitsuba::IMPORT_HEADER.as_bytes())
}
