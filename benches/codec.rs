//! Throughput of the drive protocol codec (MB/s of wire bytes): encoding full DATA frames (66
//! samples of `[u, y, i]`), and streaming decode of the same bytes fed in 64-byte chunks (as a
//! serial port delivers them).
//!
//! `cargo bench -p fracid-benches --bench codec`

use divan::counter::BytesCount;
use divan::{black_box, Bencher};
use drive::codec::{encode, StreamDecoder};
use drive::protocol::{DataBlock, Frame, Message, MAX_BLOCK_SAMPLES};

fn main() {
    divan::main();
}

const FRAMES: usize = 1000;

fn frames() -> Vec<Frame> {
    (0..FRAMES)
        .map(|f| {
            let samples = (0..MAX_BLOCK_SAMPLES as usize)
                .map(|k| {
                    let x = (f * 66 + k) as i32;
                    [(x % 4001 - 2000) as i16, (x * 7 % 30001 - 15000) as i16, 0]
                })
                .collect();
            Frame {
                seq: f as u16,
                msg: Message::Data(DataBlock {
                    run_id: 1,
                    first_index: (f * 66) as u32,
                    flags: 0,
                    samples,
                }),
            }
        })
        .collect()
}

/// Encode 1000 DATA frames (bytes = wire bytes produced).
#[divan::bench(sample_count = 20)]
fn encode_data(b: Bencher<'_, '_>) {
    let fr = frames();
    let bytes: usize = fr.iter().map(|f| encode(f).len()).sum();
    b.counter(BytesCount::new(bytes)).bench(|| {
        let mut n = 0;
        for f in black_box(&fr) {
            n += encode(f).len();
        }
        n
    });
}

/// Streaming decode of the wire bytes of 1000 DATA frames, fed in 64-byte chunks.
#[divan::bench(sample_count = 20)]
fn decode_stream(b: Bencher<'_, '_>) {
    let wire: Vec<u8> = frames().iter().flat_map(encode).collect();
    b.counter(BytesCount::new(wire.len())).bench(|| {
        let mut dec = StreamDecoder::new();
        let mut n = 0;
        for chunk in black_box(&wire).chunks(64) {
            dec.push_with(chunk, |_| n += 1);
        }
        assert_eq!(n, FRAMES);
        n
    });
}
