//! Acceptance: random frame sequences, cut into random chunks, with random
//! corruption (bit flips, dropped and inserted bytes): every frame not
//! touched by corruption is decoded exactly once, in order, and the
//! decoder's counters add up.

use proptest::prelude::*;
use spinbench_wire::fmu::{Frame, FrameDecoder, encode_frame};

/// Bytes that matter to the decoder, often, and any byte otherwise.
fn tricky_byte() -> impl Strategy<Value = u8> {
    prop_oneof![
        Just(0x55u8),
        Just(0xAA),
        Just(0xFF),
        Just(0x00),
        any::<u8>()
    ]
}

#[derive(Debug, Clone)]
enum Corruption {
    Flip(u8),
    Drop,
    Insert(u8),
}

fn corruption() -> impl Strategy<Value = (f64, Corruption)> {
    (
        0.0f64..1.0,
        prop_oneof![
            (0u8..8).prop_map(Corruption::Flip),
            Just(Corruption::Drop),
            tricky_byte().prop_map(Corruption::Insert),
        ],
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn untouched_frames_survive_corruption_exactly_once_in_order(
        bodies in proptest::collection::vec(
            (any::<u8>(), proptest::collection::vec(tricky_byte(), 0..60)), 1..40),
        corruptions in proptest::collection::vec(corruption(), 0..12),
        noise_between in proptest::collection::vec(proptest::collection::vec(tricky_byte(), 0..6), 40),
        chunk_sizes in proptest::collection::vec(1usize..70, 1..50),
    ) {
        // Frames tagged with their index so each is unique.
        let frames: Vec<Frame> = bodies
            .iter()
            .enumerate()
            .map(|(i, (cmd, body))| {
                let mut data = (i as u32).to_le_bytes().to_vec();
                data.extend(body);
                Frame { cmd: *cmd, data }
            })
            .collect();
        let mut stream = Vec::new();
        let mut spans = Vec::new();
        for (i, f) in frames.iter().enumerate() {
            stream.extend(&noise_between[i % noise_between.len()]);
            let start = stream.len();
            encode_frame(f.cmd, &f.data, &mut stream).expect("fits");
            spans.push(start..stream.len());
        }

        // Apply corruptions at original byte positions.
        let mut ops: Vec<(usize, Corruption)> = corruptions
            .iter()
            .map(|(at, c)| (((*at * stream.len() as f64) as usize).min(stream.len() - 1), c.clone()))
            .collect();
        ops.sort_by_key(|(p, _)| *p);
        let mut touched = vec![false; frames.len()];
        for (p, c) in &ops {
            for (i, span) in spans.iter().enumerate() {
                let hit = match c {
                    Corruption::Insert(_) => span.start < *p && *p < span.end,
                    _ => span.contains(p),
                };
                touched[i] |= hit;
            }
        }
        let mut corrupted = Vec::with_capacity(stream.len() + ops.len());
        let mut next = 0;
        for (p, byte) in stream.iter().enumerate() {
            let mut b = Some(*byte);
            while next < ops.len() && ops[next].0 == p {
                match ops[next].1 {
                    Corruption::Flip(bit) => b = b.map(|v| v ^ (1 << bit)),
                    Corruption::Drop => b = None,
                    Corruption::Insert(x) => corrupted.push(x),
                }
                next += 1;
            }
            corrupted.extend(b);
        }

        // Feed in random chunks, then finish.
        let mut decoder = FrameDecoder::new();
        let mut decoded = Vec::new();
        let mut at = 0;
        let mut k = 0;
        while at < corrupted.len() {
            let n = chunk_sizes[k % chunk_sizes.len()].min(corrupted.len() - at);
            decoder.decode(&corrupted[at..at + n], |f| decoded.push(f.to_frame()));
            at += n;
            k += 1;
        }
        decoder.finish();
        while let Some(f) = decoder.next_frame() {
            decoded.push(f.to_frame());
        }

        // Every untouched frame exactly once, in order.
        let originals: Vec<&Frame> = decoded.iter().filter(|d| frames.contains(d)).collect();
        let indices: Vec<u32> = originals
            .iter()
            .map(|f| u32::from_le_bytes([f.data[0], f.data[1], f.data[2], f.data[3]]))
            .collect();
        prop_assert!(indices.windows(2).all(|w| w[0] < w[1]), "out of order or repeated: {:?}", indices);
        for (i, t) in touched.iter().enumerate() {
            if !t {
                prop_assert!(indices.contains(&(i as u32)), "untouched frame {} lost", i);
            }
        }
        // Counters add up.
        let s = decoder.stats();
        prop_assert_eq!(s.frames as usize, decoded.len());
        prop_assert_eq!(s.bytes_in as usize, corrupted.len());
        prop_assert_eq!(decoder.pending(), 0);
        prop_assert_eq!(s.bytes_in, s.frame_bytes + s.bytes_skipped);
        // Without corruption every frame comes through (noise between frames
        // may still hold false headers, which are rejected and counted).
        if ops.is_empty() {
            prop_assert_eq!(decoded.len(), frames.len());
        }
    }
}
