//! `dtr import scene.xml -o scene.toml`: a Mitsuba 3 XML scene converted to our TOML
//! description (checked by loading it first), written atomically, or printed.

use crate::scene::{Format, Scene, mitsuba};
use anyhow::{Context, bail};
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ImportArgs {
    /// The Mitsuba 3 scene (.xml).
    pub scene: PathBuf,
    /// Where to write the TOML description (default: print it). Relative mesh file names
    /// are made absolute when it lies in another folder than the XML file.
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
    // the description must load as it is written: resolve it now (meshes read, values checked)
    let as_written = a.output.clone().unwrap_or_else(|| a.scene.clone());
    Scene::from_str(&imported.toml, Format::Toml, &as_written, &[]).map_err(|e| imported.annotate(e))?;
    match &a.output {
        None => std::io::stdout()
            .write_all(imported.toml.as_bytes())
            .or_else(|e| {
                if e.kind() == std::io::ErrorKind::BrokenPipe {
                    Ok(())
                } else {
                    Err(e)
                }
            })
            .context("writing to standard output")?,
        Some(out) => {
            if out.extension().and_then(|e| e.to_str()) != Some("toml") {
                bail!(
                    "{}: the output is a TOML description: expected a file ending in .toml",
                    out.display()
                );
            }
            if std::fs::canonicalize(out)
                .ok()
                .is_some_and(|o| Some(o) == std::fs::canonicalize(&a.scene).ok())
            {
                bail!("{}: the output would replace the input", out.display());
            }
            crate::output::write_atomic(out, |w| {
                w.write_all(imported.toml.as_bytes())
                    .map_err(|e| crate::output::OutputError::io(out, e))
            })?;
            eprintln!("wrote {}", out.display());
        }
    }
    Ok(())
}
