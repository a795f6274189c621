#![no_main]
//! libFuzzer target: the `obj` property of `harness.rs`.

// Each target uses one of the harness's properties; the others belong to the other targets.
#[allow(dead_code)]
#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::obj(data));
