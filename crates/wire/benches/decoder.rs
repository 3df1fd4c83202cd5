//! Decoder throughput on one core: a stream of reciprocal-count frames (12
//! inputs, 82 bytes each) fed in 4 KiB chunks. Target ≥ 300 MB/s, over 200×
//! the combined line rate of 16 ports at 921,600 baud (1.47 MB/s).
//! Prints `bench: <name> = <value> <unit>` lines.
//!
//! Run: `cargo bench -p spinbench-wire --bench decoder`

use spinbench_wire::fmu::{FrameDecoder, Message, ReciprocalCount};
use std::time::Instant;

fn main() {
    let measuring = std::env::args().any(|a| a == "--bench");
    let target_bytes = if measuring { 64 << 20 } else { 1 << 20 };
    let mut stream = Vec::with_capacity(target_bytes + 100);
    let mut seq = 0u16;
    while stream.len() < target_bytes {
        let inputs = (0..12u32)
            .map(|i| ReciprocalCount {
                periods: 75 + (i % 3) as u16,
                span: 250_000 + i * 17 + u32::from(seq) % 97,
            })
            .collect();
        Message::ReciprocalCounts {
            seq,
            status: 0,
            inputs,
        }
        .encode(&mut stream)
        .expect("fits");
        seq = seq.wrapping_add(1);
    }

    let repeats = if measuring { 5 } else { 1 };
    let mut best = f64::INFINITY;
    let mut best_parse = f64::INFINITY;
    for _ in 0..repeats {
        let mut decoder = FrameDecoder::new();
        let mut frames = 0u64;
        let start = Instant::now();
        for chunk in stream.chunks(4096) {
            decoder.decode(chunk, |_| frames += 1);
        }
        best = best.min(start.elapsed().as_secs_f64());
        assert_eq!(decoder.stats().bytes_skipped, 0);
        assert_eq!(frames, stream.len() as u64 / 82);

        let mut decoder = FrameDecoder::new();
        let mut periods = 0u64;
        let start = Instant::now();
        for chunk in stream.chunks(4096) {
            decoder.decode(chunk, |f| {
                if let Ok(Message::ReciprocalCounts { inputs, .. }) = Message::decode(f) {
                    periods += u64::from(inputs[0].periods);
                }
            });
        }
        best_parse = best_parse.min(start.elapsed().as_secs_f64());
        assert!(periods > 0);
    }
    if !measuring {
        println!(
            "decoder bench smoke run: {} bytes decoded (no figures outside `cargo bench`)",
            stream.len()
        );
        return;
    }
    let mb = stream.len() as f64 / 1e6;
    println!("stream: {mb:.1} MB of 82-byte frames in 4 KiB chunks, best of {repeats}");
    println!("bench: fmu_decoder_throughput = {:.0} MB/s", mb / best);
    println!(
        "bench: fmu_decoder_frames_per_second = {:.2e} frames/s",
        (stream.len() / 82) as f64 / best
    );
    println!(
        "bench: fmu_decode_and_parse_throughput = {:.0} MB/s",
        mb / best_parse
    );
    println!(
        "bench: fmu_decoder_margin_over_16x921600_baud = {:.0} x",
        (mb / best) / (16.0 * 92_160.0 / 1e6)
    );
}
