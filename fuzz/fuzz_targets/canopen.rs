//! cargo-fuzz harness: [`survey_positioner_drivers::fuzz_targets::canopen`] on every input.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| survey_positioner_drivers::fuzz_targets::canopen(data));
