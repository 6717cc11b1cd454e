#![no_main]
//! The OBJ reader on arbitrary bytes: `difftransient::scene::fuzzing`.
use difftransient::scene::fuzzing;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| fuzzing::obj(data));
