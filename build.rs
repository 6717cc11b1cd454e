//! Links Debian's Embree 3 (`libembree-dev`). Debian ships no pkg-config file for it (only a
//! CMake config), so we look for the header and the library ourselves and fail with an install
//! hint. `EMBREE_DIR` may point at another Embree 3 install (with `include/` and `lib/`).

use std::path::{Path, PathBuf};

const SYSTEM_LIB_DIRS: [&str; 4] = [
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib",
    "/usr/local/lib",
];
const SYSTEM_INCLUDE_DIRS: [&str; 2] = ["/usr/include", "/usr/local/include"];

fn main() {
    println!("cargo::rerun-if-changed=build.rs");
    println!("cargo::rerun-if-env-changed=EMBREE_DIR");

    let custom = std::env::var_os("EMBREE_DIR").map(PathBuf::from);
    let mut lib_dirs: Vec<PathBuf> = SYSTEM_LIB_DIRS.iter().map(PathBuf::from).collect();
    let mut inc_dirs: Vec<PathBuf> = SYSTEM_INCLUDE_DIRS.iter().map(PathBuf::from).collect();
    if let Some(dir) = &custom {
        lib_dirs.splice(0..0, [dir.join("lib"), dir.join("lib64")]);
        inc_dirs.insert(0, dir.join("include"));
    }

    let header = inc_dirs
        .iter()
        .map(|d| d.join("embree3/rtcore.h"))
        .find(|p| p.is_file());
    let lib_dir = lib_dirs.iter().find(|d| d.join("libembree3.so").exists());

    let (Some(header), Some(lib_dir)) = (&header, lib_dir) else {
        fail(header.is_none(), lib_dir.is_none(), &inc_dirs, &lib_dirs);
    };

    println!("cargo::rerun-if-changed={}", header.display());
    println!("cargo::rerun-if-changed={}", lib_dir.join("libembree3.so").display());
    println!("cargo::rustc-link-search=native={}", lib_dir.display());
    println!("cargo::rustc-link-lib=dylib=embree3");
    if !SYSTEM_LIB_DIRS.iter().any(|d| Path::new(d) == lib_dir) {
        // A custom install is not on the loader's path: let binaries and tests find it.
        println!("cargo::rustc-link-arg=-Wl,-rpath,{}", lib_dir.display());
    }
}

fn fail(no_header: bool, no_lib: bool, inc: &[PathBuf], lib: &[PathBuf]) -> ! {
    let list = |v: &[PathBuf]| v.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ");
    let mut missing = Vec::new();
    if no_header {
        missing.push(format!("the header embree3/rtcore.h (looked in {})", list(inc)));
    }
    if no_lib {
        missing.push(format!("the library libembree3.so (looked in {})", list(lib)));
    }
    println!("cargo::error=Embree 3 not found: missing {}.", missing.join(" and "));
    println!(
        "cargo::error=On Debian/Ubuntu run `apt-get update && apt-get install -y libembree-dev` \
         (Embree 3.13), or set EMBREE_DIR to an Embree 3 install with include/ and lib/."
    );
    std::process::exit(0) // cargo fails the build because of the errors above
}
