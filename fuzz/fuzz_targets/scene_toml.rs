#![no_main]
//! The scene parser and resolver on arbitrary bytes (Toml): `difftransient::scene::fuzzing`.
use difftransient::scene::{Format, fuzzing};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| fuzzing::scene(data, Format::Toml));
