//! Fuzz the streaming frame decoder: arbitrary bytes in arbitrary chunks must never panic, every
//! frame it accepts must re-encode to a frame that decodes to the same value, and feeding the same
//! bytes in one piece or split must give the same frames.
//!
//! Run (nightly): `cd crates/drive/fuzz && cargo +nightly fuzz run stream_decoder -- -max_total_time=60`
#![no_main]

use drive::codec::{decode_encoded, encode, StreamDecoder};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.is_empty() {
        return;
    }
    // The first byte chooses the split point.
    let split = data[0] as usize % data.len();
    let bytes = &data[1..];
    let whole = StreamDecoder::new().push(bytes);
    let mut dec = StreamDecoder::new();
    let (a, b) = bytes.split_at(split.min(bytes.len()));
    let mut parts = dec.push(a);
    parts.extend(dec.push(b));
    assert_eq!(whole, parts, "splitting the input changed the frames");
    for f in whole {
        let enc = encode(&f);
        let again = decode_encoded(&enc[1..enc.len() - 1]).expect("a re-encoded frame decodes");
        assert_eq!(again, f);
    }
});
