//! Fuzzes the `.swv` decoder: any bytes, any prefix, any tree selection must give a mesh or
//! an `Error`, never a panic, and never allocate out of proportion to the input. The coder
//! efficiency report (`codec::entropy`, `subwave bench entropy`) decodes streams too.
//!
//! `cargo fuzz` builds with `--cfg fuzzing`, under which the container's checksums are not
//! enforced (`codec::container::crc_matches`), so mutations reach the decoders behind them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use subwave::codec::entropy::coder_efficiency;
use subwave::codec::progressive::{decode, inspect, DecodeOptions, TreeDecoder};

/// Streams declaring more finest-level vertices than this are only inspected: the decoder
/// accepts meshes up to about 1024 times the stream's size (legitimately slow to decode), and
/// decoding them would throttle the fuzzer to a few executions per second.
const MAX_FUZZ_VERTICES: u64 = 20_000;

/// Whether decoding `bytes` is worth the fuzzer's time: not a stream declaring a huge mesh.
fn small(bytes: &[u8]) -> bool {
    inspect(bytes).map_or(true, |info| info.vertices <= MAX_FUZZ_VERTICES)
}

fuzz_target!(|data: &[u8]| {
    if small(data) {
        let _ = decode(data, &DecodeOptions::default());
        let _ = coder_efficiency(data);
    }
    if let Some((&k, rest)) = data.split_first() {
        if !small(rest) {
            return;
        }
        let cut = rest.len() * k as usize / 255;
        let _ = decode(
            rest,
            &DecodeOptions {
                max_bytes: Some(cut),
                trees: Some(vec![k as u32, 0, 1]),
            },
        );
        if let Ok(mut td) = TreeDecoder::new(rest) {
            let _ = td.add_tree(k as u32, &rest[cut..]);
            td.remove_tree(0);
            let _ = td.mesh();
        }
    }
});
