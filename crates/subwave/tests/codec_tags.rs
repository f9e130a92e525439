//! The progressive codec on hierarchies whose base mesh carries crease tags (as the
//! remesher's feature chains give): every wavelet must round-trip to the quantization error.

use subwave::codec::progressive::{
    decode, encode_with_info, DecodeOptions, EncodeOptions, Wavelet,
};
use subwave::hierarchy::Hierarchy;
use subwave::mesh::{EdgeTag, SHARPNESS_INFINITE};
use subwave::subdivision::refine::Split;
use subwave::wavelet::triangle::DetailFrame;
use subwave::{generate, DVec3};

/// An octahedron-like bumpy sphere over the icosahedron with a ring of infinitely sharp
/// crease edges on its base mesh.
fn creased(levels: u32) -> Hierarchy {
    let mut base = generate::icosahedron();
    let faces: Vec<Vec<u32>> = base.faces().map(|f| f.to_vec()).collect();
    // Tag the three edges of two faces.
    for f in faces.iter().take(2) {
        for k in 0..3 {
            base.edge_tags.push(EdgeTag {
                vertices: [f[k], f[(k + 1) % 3]],
                sharpness: SHARPNESS_INFINITE,
            });
        }
    }
    let h = Hierarchy::new(&base, levels, Split::Triangles, None).unwrap();
    let positions = h
        .positions
        .iter()
        .map(|p| {
            let d = p.normalize();
            d * (1.0 + 0.05 * (5.0 * d.x).sin() * (3.0 * d.y).cos())
        })
        .collect();
    Hierarchy::new(&base, levels, Split::Triangles, Some(positions)).unwrap()
}

#[test]
fn creased_base_round_trips_with_every_triangle_wavelet() {
    let h = creased(3);
    assert!(h.topology(0).edge_sharpness.iter().any(|&s| s > 0.0));
    for (wavelet, lifted, frames) in [
        (Wavelet::Butterfly, true, DetailFrame::Local),
        (Wavelet::Butterfly, false, DetailFrame::Local),
        (Wavelet::Butterfly, true, DetailFrame::Global),
        (Wavelet::Midpoint, true, DetailFrame::Local),
        (Wavelet::Loop, false, DetailFrame::Local),
    ] {
        let opts = EncodeOptions {
            wavelet,
            lifted,
            frames,
            bits: 16,
            ..Default::default()
        };
        // The decoded vertices follow the stream's hierarchy (the base coder's order).
        let (bytes, hs) = encode_with_info(&h, &opts).unwrap();
        assert!(hs.topology(0).edge_sharpness.iter().any(|&s| s > 0.0));
        let d = decode(&bytes, &DecodeOptions::default()).unwrap();
        let err = d
            .mesh
            .positions
            .iter()
            .zip(&hs.positions)
            .map(|(a, b): (&DVec3, &DVec3)| a.distance(*b))
            .fold(0.0, f64::max);
        assert!(
            err < 1e-3,
            "{wavelet:?} lifted={lifted} {frames:?}: max error {err:e}"
        );
    }
}
