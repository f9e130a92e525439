//! Fuzzes the base-mesh decoder (`codec::basemesh`): any bytes must give a mesh or an
//! `Error`, never a panic, and never allocate out of proportion to the input. Both entry
//! points: `decode` (dequantized positions) and `decode_integers` (the exact integer grid of
//! lossless streams).
#![no_main]

use libfuzzer_sys::fuzz_target;
use subwave::codec::basemesh::{decode, decode_integers};

fuzz_target!(|data: &[u8]| {
    if let Ok(mesh) = decode(data) {
        // A decoded mesh is structurally valid.
        assert!(mesh.check_indices().is_ok());
    }
    if let Ok((mesh, q)) = decode_integers(data) {
        assert!(mesh.check_indices().is_ok());
        assert_eq!(q.len(), mesh.num_vertices());
    }
});
