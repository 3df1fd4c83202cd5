//! Fuzz the FMU frame decoder and payload parser: any bytes, cut into
//! chunks whose sizes come from the input, must never panic, and the
//! decoder's counters must account for every byte.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    spinbench_wire::fmu::fuzz_check_decoder(data);
});
