//! Fuzz target: see `hw_bridge::fuzz_checks::wire_decoder` for the properties checked.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| hw_bridge::fuzz_checks::wire_decoder(data));
