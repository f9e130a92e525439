//! Fuzzes the base-mesh decoder (`codec::basemesh`): any bytes must give a mesh or an
//! `Error`, never a panic, and never allocate out of proportion to the input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use subwave::codec::basemesh::decode;

fuzz_target!(|data: &[u8]| {
    if let Ok(mesh) = decode(data) {
        // A decoded mesh is structurally valid.
        assert!(mesh.check_indices().is_ok());
    }
});
