//! Replays the fuzz corpus as an ordinary test, so CI checks on stable what
//! `cargo +nightly fuzz run decoder` found: the committed seeds in
//! `fuzz/seeds/decoder`, and `fuzz/corpus/decoder` when a local fuzzing run
//! has left one.

use std::path::Path;

#[test]
fn replay_decoder_corpus() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut replayed = 0;
    for dir in ["seeds/decoder", "corpus/decoder"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir)) else {
            continue;
        };
        for entry in entries.flatten() {
            let bytes = std::fs::read(entry.path()).expect("read corpus file");
            spinbench_wire::fmu::fuzz_check_decoder(&bytes);
            replayed += 1;
        }
    }
    assert!(
        replayed >= 5,
        "the committed seeds are missing ({replayed} files)"
    );
}
