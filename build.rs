//! Links Debian's Embree 3 (`libembree-dev`). Debian ships no pkg-config file for it, so we
//! look for the header and the library ourselves and fail with an install hint.

use std::path::{Path, PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    let mut lib_dirs: Vec<PathBuf> = [
        "/usr/lib/x86_64-linux-gnu",
        "/usr/lib/aarch64-linux-gnu",
        "/usr/lib",
        "/usr/local/lib",
    ]
    .iter()
    .map(PathBuf::from)
    .collect();
    let mut inc_dirs: Vec<PathBuf> = vec![PathBuf::from("/usr/include"), PathBuf::from("/usr/local/include")];
    if let Ok(dir) = std::env::var("EMBREE_DIR") {
        lib_dirs.insert(0, Path::new(&dir).join("lib"));
        inc_dirs.insert(0, Path::new(&dir).join("include"));
    }
    let header = inc_dirs.iter().map(|d| d.join("embree3/rtcore.h")).find(|p| p.exists());
    let lib = lib_dirs.iter().find(|d| d.join("libembree3.so").exists());
    match (header, lib) {
        (Some(_), Some(dir)) => {
            println!("cargo:rustc-link-search=native={}", dir.display());
            println!("cargo:rustc-link-lib=embree3");
        }
        (h, l) => {
            let missing = match (h.is_none(), l.is_none()) {
                (true, true) => "the header embree3/rtcore.h and the library libembree3.so",
                (true, false) => "the header embree3/rtcore.h",
                _ => "the library libembree3.so",
            };
            panic!(
                "\n\nEmbree 3 not found: missing {missing}.\n\
                 On Debian/Ubuntu run:  apt-get update && apt-get install -y libembree-dev\n\
                 (or set EMBREE_DIR to an Embree 3 install with include/ and lib/).\n\n"
            );
        }
    }
}
