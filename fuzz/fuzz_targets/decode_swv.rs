//! Fuzzes the `.swv` decoder: any bytes, any prefix, any tree selection must give a mesh or
//! an `Error`, never a panic, and never allocate out of proportion to the input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use subwave::codec::progressive::{decode, inspect, DecodeOptions, TreeDecoder};

fuzz_target!(|data: &[u8]| {
    let _ = inspect(data);
    let _ = decode(data, &DecodeOptions::default());
    if let Some((&k, rest)) = data.split_first() {
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
