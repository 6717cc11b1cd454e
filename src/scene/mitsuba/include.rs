//! `<include filename="..."/>` at the top level of a scene: the children of the named file's
//! `<scene>` take its place, as in Mitsuba. The file name is relative to the folder of the
//! file that includes it; a file that includes itself, directly or through others, is
//! refused, naming the chain.

use super::ImportError;
use super::xml::Doc;
use crate::scene::SceneError;
use crate::scene::read::{MAX_SCENE_BYTES, read_regular_file};
use roxmltree::Node;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Most files one scene may consist of (itself and every inclusion, counted each time): a
/// bound on the work that a file including another several times, at several levels, asks for.
const MAX_FILES: usize = 256;

/// One file of the scene.
pub(super) struct Source {
    /// As named (the scene's own path, or joined to the including file's folder).
    pub path: PathBuf,
    /// Its folder relative to the scene file's folder.
    pub rel_dir: PathBuf,
    pub text: String,
    /// The file that includes it (`None` for the scene file).
    pub parent: Option<usize>,
}

/// The scene file (index 0) and every file it includes, and which file each `<include>`
/// names: `(including file, byte offset of the element) → included file`.
pub(super) struct Files {
    pub sources: Vec<Source>,
    pub links: HashMap<(usize, usize), usize>,
}

/// Reads every file that `text` (the scene file `source`) includes, and those they include.
pub(super) fn gather(text: &str, source: &Path) -> Result<Files, SceneError> {
    let mut files = Files {
        sources: vec![Source {
            path: source.to_path_buf(),
            rel_dir: PathBuf::new(),
            text: text.to_string(),
            parent: None,
        }],
        links: HashMap::new(),
    };
    let first = std::fs::canonicalize(source).unwrap_or_else(|_| source.to_path_buf());
    read_includes(&mut files, 0, &mut vec![first])?;
    Ok(files)
}

/// The `<include>`s of file `k` (`chain`: the canonical paths from the scene file to it).
fn read_includes(files: &mut Files, k: usize, chain: &mut Vec<PathBuf>) -> Result<(), SceneError> {
    let text = files.sources[k].text.clone();
    let path = files.sources[k].path.clone();
    let tree = super::parse(&text, &path)?;
    let mut doc = Doc::new(tree.root_element(), &text);
    if k > 0 {
        doc.included(path.clone(), files.sources[k].rel_dir.clone());
    }
    let invalid = |e: ImportError| SceneError::Invalid {
        path: e.file.unwrap_or_else(|| path.clone()),
        at: e.at,
        message: e.message,
    };
    let includes: Vec<Node> = doc
        .children(doc.root)
        .filter(|c| c.tag_name().name() == "include")
        .collect();
    for node in includes {
        let name = doc.req_attr(node, "filename").map_err(invalid)?;
        if let Some(other) = node.attributes().find(|a| a.name() != "filename") {
            return Err(invalid(
                doc.err(node, format!("<include> takes only filename (got {:?})", other.name())),
            ));
        }
        if doc.children(node).next().is_some() {
            return Err(invalid(doc.err(node, "<include> takes no children")));
        }
        if files.sources.len() >= MAX_FILES {
            return Err(invalid(
                doc.err(node, format!("more than {MAX_FILES} included files in one scene")),
            ));
        }
        let folder = path.parent().unwrap_or(Path::new(""));
        let target = folder.join(&name);
        let cannot = |e: std::io::Error| {
            invalid(doc.err(node, format!("cannot read the included file {}: {e}", target.display())))
        };
        let canon = std::fs::canonicalize(&target).map_err(cannot)?;
        if let Some(at) = chain.iter().position(|p| *p == canon) {
            let cycle: Vec<String> = chain[at..]
                .iter()
                .chain([&canon])
                .map(|p| p.display().to_string())
                .collect();
            return Err(invalid(
                doc.err(node, format!("an include cycle: {}", cycle.join(" includes "))),
            ));
        }
        let included = read_regular_file(&target, MAX_SCENE_BYTES).map_err(cannot)?;
        let rel_dir = files.sources[k]
            .rel_dir
            .join(Path::new(&name).parent().unwrap_or(Path::new("")));
        let j = files.sources.len();
        files.sources.push(Source {
            path: target,
            rel_dir,
            text: included,
            parent: Some(k),
        });
        files.links.insert((k, node.range().start), j);
        chain.push(canon);
        read_includes(files, j, chain)?;
        chain.pop();
    }
    Ok(())
}

/// The top-level elements of file `k` in order, each `<include>` replaced by the elements of
/// the file it names (recursively) and `<default>`s left out, each with its document.
pub(super) fn flatten<'d, 'a, 'input>(
    docs: &'d [Doc<'a, 'input>],
    links: &HashMap<(usize, usize), usize>,
    k: usize,
    out: &mut Vec<(&'d Doc<'a, 'input>, Node<'a, 'input>)>,
) -> Result<(), ImportError> {
    let doc = &docs[k];
    if k > 0 && doc.root.tag_name().name() != "scene" {
        return Err(doc.err(doc.root, "an included file's root element must be <scene>"));
    }
    for c in doc.children(doc.root) {
        match c.tag_name().name() {
            "default" => {}
            "include" => flatten(docs, links, links[&(k, c.range().start)], out)?,
            _ => out.push((doc, c)),
        }
    }
    Ok(())
}
