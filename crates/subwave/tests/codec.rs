//! End-to-end tests of the progressive geometry codec (`codec::progressive`).

use subwave::codec::progressive::{
    decode, encode, encode_with_info, inspect, DecodeOptions, EncodeOptions, Layout, TreeDecoder,
    Wavelet,
};
use subwave::codec::quantize::ComponentMode;
use subwave::generate;
use subwave::hierarchy::Hierarchy;
use subwave::subdivision::refine::Split;
use subwave::wavelet::triangle::DetailFrame;
use subwave::{DVec3, Error};

/// A bumpy sphere: icosahedron base, `levels` 1-to-4 splits, positions on a perturbed sphere.
fn bumpy(levels: u32) -> Hierarchy {
    let base = generate::icosahedron();
    let h = Hierarchy::new(&base, levels, Split::Triangles, None).unwrap();
    let positions = h
        .positions
        .iter()
        .map(|p| {
            let d = p.normalize();
            d * (1.0 + 0.05 * (5.0 * d.x).sin() * (3.0 * d.y).cos() + 0.02 * (11.0 * d.z).sin())
        })
        .collect();
    Hierarchy::new(&base, levels, Split::Triangles, Some(positions)).unwrap()
}

fn max_err(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length())
        .fold(0.0, f64::max)
}

fn rms(a: &[DVec3], b: &[DVec3]) -> f64 {
    (a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

fn full(bytes: &[u8]) -> subwave::codec::progressive::Decoded {
    decode(bytes, &DecodeOptions::default()).unwrap()
}

#[test]
fn every_wavelet_round_trips_to_the_quantization_error() {
    let h = bumpy(3);
    for (wavelet, lifted, frames) in [
        (Wavelet::Midpoint, false, DetailFrame::Global),
        (Wavelet::Midpoint, true, DetailFrame::Local),
        (Wavelet::Butterfly, false, DetailFrame::Local),
        (Wavelet::Butterfly, true, DetailFrame::Global),
        (Wavelet::Loop, false, DetailFrame::Local),
    ] {
        for components in [ComponentMode::Aligned, ComponentMode::Independent] {
            let opts = EncodeOptions {
                wavelet,
                lifted,
                frames,
                components,
                bits: 16,
                ..Default::default()
            };
            let (s, hs) = encode_with_info(&h, &opts).unwrap();
            let d = full(&s);
            assert!(d.complete);
            assert_eq!(d.mesh.num_vertices(), h.positions.len());
            assert_eq!(d.mesh.face_indices, hs.topology(3).face_vertices);
            let e = max_err(&d.mesh.positions, &hs.positions);
            assert!(
                e < 2e-4,
                "{wavelet:?} lifted {lifted} {frames:?} {components:?}: {e}"
            );
            let info = inspect(&s).unwrap();
            assert_eq!(info.wavelet, wavelet);
            assert_eq!(info.total_bytes, s.len() as u64);
        }
    }
}

#[test]
fn prefixes_improve_and_all_prefixes_of_a_small_stream_decode() {
    let (s, h) = encode_with_info(&bumpy(2), &EncodeOptions::default()).unwrap();
    let info = inspect(&s).unwrap();
    let min = info.header_bytes + info.base_bytes;
    let mut errors = Vec::new();
    for cut in 0..=s.len() {
        let r = decode(
            &s,
            &DecodeOptions {
                max_bytes: Some(cut),
                trees: None,
            },
        );
        if cut < min {
            assert!(matches!(r, Err(Error::Decode { .. })), "cut {cut}");
        } else {
            let d = r.unwrap();
            assert_eq!(d.mesh.num_vertices(), h.positions.len());
            errors.push(rms(&d.mesh.positions, &h.positions));
        }
    }
    // The error at the full stream is far below the error of the base alone, and the
    // error never grows by more than a little when a byte is added (mid-interval estimates).
    assert!(errors[errors.len() - 1] < errors[0] / 20.0, "{errors:?}");
    let quarter = errors[errors.len() / 4];
    assert!(quarter < errors[0] && errors[errors.len() * 3 / 4] < quarter);
}

#[test]
fn random_prefixes_of_a_large_stream_decode() {
    let h = bumpy(5);
    let s = encode(&h, &EncodeOptions::default()).unwrap();
    let info = inspect(&s).unwrap();
    let min = info.header_bytes + info.base_bytes;
    let mut x = 12345u64;
    for _ in 0..1000 {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let cut = min + (x >> 33) as usize % (s.len() - min + 1);
        // Only decode the coefficients (fast path check of prefix safety); reconstruct a few.
        let d = decode(
            &s,
            &DecodeOptions {
                max_bytes: Some(cut),
                trees: None,
            },
        )
        .unwrap();
        assert!(d.bytes_used <= cut);
    }
}

#[test]
fn a_corrupt_chunk_is_named_and_never_decoded() {
    let h = bumpy(3);
    let s = encode(&h, &EncodeOptions::default()).unwrap();
    let info = inspect(&s).unwrap();
    let c = &info.chunks[3];
    let mut bad = s.clone();
    bad[c.offset as usize + c.len as usize / 2] ^= 0x10;
    let e = decode(&bad, &DecodeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("chunk 3 (bit plane {}) fails its checksum", c.id)),
        "{e}"
    );
    // Base chunk.
    let mut bad = s.clone();
    bad[info.chunks[0].offset as usize] ^= 1;
    let e = decode(&bad, &DecodeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("chunk 0 (base mesh) fails its checksum"), "{e}");
    // Header.
    let mut bad = s.clone();
    bad[30] ^= 1;
    assert!(decode(&bad, &DecodeOptions::default()).is_err());
}

#[test]
fn garbage_and_mutations_never_panic() {
    let h = bumpy(2);
    let s = encode(&h, &EncodeOptions::default()).unwrap();
    let mut x = 99u64;
    for i in 0..2000 {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut m = s.clone();
        let k = (x >> 33) as usize % m.len();
        m[k] ^= (x >> 13) as u8 | 1;
        if i % 2 == 0 {
            // Recompute nothing: the checksums must catch it (or the header checks).
            let _ = decode(&m, &DecodeOptions::default());
        } else {
            let _ = decode(&m[..k], &DecodeOptions::default());
        }
    }
    for len in [0usize, 3, 10, 100] {
        let g: Vec<u8> = (0..len).map(|i| (i * 37 % 251) as u8).collect();
        assert!(decode(&g, &DecodeOptions::default()).is_err());
    }
}

#[test]
fn lossless_mode_reproduces_the_quantized_positions() {
    let h = bumpy(3);
    for wavelet in [Wavelet::Midpoint, Wavelet::Butterfly] {
        let opts = EncodeOptions {
            wavelet,
            lifted: true,
            lossless: true,
            bits: 12,
            ..Default::default()
        };
        let s = encode(&h, &opts).unwrap();
        let d = full(&s);
        assert!(d.complete);
        // The grid: 2^12 - 1 steps over the longest side of the box.
        let info = inspect(&s).unwrap();
        let [lo, hi] = info.bbox;
        let step = (hi - lo).max_element() / 4095.0;
        for (a, b) in d.mesh.positions.iter().zip(&h.positions) {
            let q = ((*b - lo) / step).round();
            let want = lo + q * step;
            assert_eq!(*a, want);
        }
        // A prefix is lossy but decodes.
        let p = decode(
            &s,
            &DecodeOptions {
                max_bytes: Some(s.len() * 2 / 3),
                trees: None,
            },
        )
        .unwrap();
        assert!(!p.complete);
    }
    let e = encode(
        &h,
        &EncodeOptions {
            wavelet: Wavelet::Loop,
            lossless: true,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("Loop"));
}

#[test]
fn quad_hierarchies_round_trip_lossy_and_lossless() {
    let base = generate::cube();
    let h0 = Hierarchy::new(&base, 3, Split::Polygons, None).unwrap();
    let positions: Vec<DVec3> = h0
        .positions
        .iter()
        .map(|p| p.normalize() * (1.0 + 0.03 * (7.0 * p.x).sin()))
        .collect();
    let h = Hierarchy::new(&base, 3, Split::Polygons, Some(positions)).unwrap();
    for wavelet in [Wavelet::Linear, Wavelet::Cubic] {
        let (s, hs) = encode_with_info(
            &h,
            &EncodeOptions {
                wavelet,
                ..EncodeOptions::for_hierarchy(&h)
            },
        )
        .unwrap();
        let d = full(&s);
        assert!(max_err(&d.mesh.positions, &hs.positions) < 1e-4);
        let s = encode(
            &h,
            &EncodeOptions {
                wavelet,
                lossless: true,
                bits: 14,
                ..EncodeOptions::for_hierarchy(&h)
            },
        )
        .unwrap();
        let d = full(&s);
        let step = 2.0 / 16383.0;
        assert!(max_err(&d.mesh.positions, &h.positions) <= step);
    }
    assert!(encode(&h, &EncodeOptions::default()).is_err()); // butterfly on quads
}

#[test]
fn trees_layout_selects_and_adds_trees() {
    let opts = EncodeOptions {
        layout: Layout::Trees,
        ..Default::default()
    };
    let (s, h) = encode_with_info(&bumpy(3), &opts).unwrap();
    let info = inspect(&s).unwrap();
    assert_eq!(info.layout, Layout::Trees);
    assert_eq!(info.chunks.len(), 1 + 30);
    let all = full(&s);
    let embedded = full(&encode(&bumpy(3), &EncodeOptions::default()).unwrap());
    assert!(all.complete);
    assert!(max_err(&all.mesh.positions, &embedded.mesh.positions) < 1e-12);
    // Only trees 0..5: vertices far from those base edges keep the base-only positions.
    let some = decode(
        &s,
        &DecodeOptions {
            max_bytes: None,
            trees: Some(vec![0, 1, 2, 3, 4]),
        },
    )
    .unwrap();
    assert!(!some.complete);
    let none = decode(
        &s,
        &DecodeOptions {
            max_bytes: None,
            trees: Some(vec![]),
        },
    )
    .unwrap();
    let e_some = rms(&some.mesh.positions, &h.positions);
    let e_none = rms(&none.mesh.positions, &h.positions);
    let e_all = rms(&all.mesh.positions, &h.positions);
    assert!(
        e_all < e_some && e_some < e_none,
        "{e_all} {e_some} {e_none}"
    );
    // The tree decoder: add every tree, then remove some, equals the selective decode.
    let mut td = TreeDecoder::new(&s).unwrap();
    for t in 0..td.num_trees() as u32 {
        let (off, len, marks) = td.tree_range(t).unwrap();
        assert_eq!(*marks.last().unwrap(), len);
        let chunk = s[off as usize..off as usize + len as usize].to_vec();
        td.add_tree(t, &chunk).unwrap();
    }
    assert!(max_err(&td.mesh().unwrap().positions, &all.mesh.positions) < 1e-12);
    for t in 5..30 {
        td.remove_tree(t);
    }
    assert_eq!(td.active_trees(), vec![0, 1, 2, 3, 4]);
    assert!(max_err(&td.mesh().unwrap().positions, &some.mesh.positions) < 1e-12);
    // A plane mark gives a decodable prefix of a tree.
    let (off, _, marks) = td.tree_range(7).unwrap();
    let m = marks[marks.len() / 2];
    let chunk = s[off as usize..off as usize + m as usize].to_vec();
    td.add_tree(7, &chunk).unwrap();
}

/// The reference stream of the golden test: a bumpy sphere, 2 levels, default options.
fn golden_stream() -> Vec<u8> {
    let h = bumpy(2);
    encode(
        &h,
        &EncodeOptions {
            bits: 10,
            ..Default::default()
        },
    )
    .unwrap()
}

const GOLDEN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/bumpy2.swv");

/// The stream format is pinned: a change of the encoder's output (or of the format) fails
/// here. If the change is intended, bump `container::VERSION` when the format changed, and
/// regenerate the file with `SUBWAVE_BLESS=1 cargo test -p subwave --test codec golden`.
#[test]
fn golden_bytes_of_a_small_reference_stream() {
    let s = golden_stream();
    if std::env::var_os("SUBWAVE_BLESS").is_some() {
        std::fs::write(GOLDEN, &s).unwrap();
    }
    let golden = std::fs::read(GOLDEN).expect("tests/golden/bumpy2.swv");
    assert_eq!(
        u16::from_le_bytes([golden[4], golden[5]]),
        subwave::codec::container::VERSION,
        "the golden stream has another version: regenerate it (see the test's doc)"
    );
    assert!(
        s == golden,
        "the encoder's output changed ({} bytes, golden {})",
        s.len(),
        golden.len()
    );
    let d = full(&golden);
    assert!(d.complete);
    let (_, hs) = encode_with_info(&bumpy(2), &EncodeOptions::default()).unwrap();
    assert!(max_err(&d.mesh.positions, &hs.positions) < 1e-2);
}

#[test]
fn open_meshes_round_trip() {
    // A disk-like patch: boundary edges have three offspring, the base coder closes the hole.
    let base = generate::triangle_grid(4);
    let h0 = Hierarchy::new(&base, 3, Split::Triangles, None).unwrap();
    let positions: Vec<DVec3> = h0
        .positions
        .iter()
        .map(|p| DVec3::new(p.x, p.y, 0.1 * (3.0 * p.x).sin() * (2.0 * p.y).cos()))
        .collect();
    let h = Hierarchy::new(&base, 3, Split::Triangles, Some(positions)).unwrap();
    for layout in [Layout::Embedded, Layout::Trees] {
        let s = encode(
            &h,
            &EncodeOptions {
                layout,
                ..Default::default()
            },
        )
        .unwrap();
        let d = full(&s);
        // The base coder renumbers: compare as point sets through the nearest neighbour.
        let e = d
            .mesh
            .positions
            .iter()
            .map(|p| {
                h.positions
                    .iter()
                    .map(|q| (*p - *q).length())
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max);
        assert!(e < 1e-3, "{layout:?}: {e}");
        assert_eq!(d.mesh.num_faces(), h.topology(3).num_faces());
    }
}
