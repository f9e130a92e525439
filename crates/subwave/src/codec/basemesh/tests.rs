//! Unit tests of the base-mesh coder: round trips on generated meshes, maps, robustness.

use super::*;
use crate::generate;
use crate::mesh::{EdgeTag, VertexTag};

/// Checks that `enc.decoded` is `mesh` renumbered by the maps (faces up to rotation,
/// positions within half a quantization step) and that `decode` returns it.
pub(super) fn check_roundtrip(mesh: &Mesh, bits: u32) -> Encoded {
    let opts = BaseMeshOptions {
        position_bits: bits,
    };
    let e = encode_with_info(mesh, &opts).expect("encode");
    let d = decode(&e.bytes).expect("decode");
    assert_eq!(
        d, e.decoded,
        "decode differs from encode_with_info's decoded mesh"
    );
    let (dq, q, quant) = decode_quantized(&e.bytes).unwrap();
    assert_eq!(dq, d);
    assert_eq!(q, e.quantized);
    assert_eq!(quant, e.quantization);
    assert_eq!(d.num_vertices(), mesh.num_vertices());
    assert_eq!(d.num_faces(), mesh.num_faces());
    assert_eq!(e.vertex_map.len(), mesh.num_vertices());
    assert_eq!(e.face_map.len(), mesh.num_faces());
    let mut seen = vec![false; mesh.num_vertices()];
    for &v in &e.vertex_map {
        assert!(!seen[v as usize], "vertex map is a permutation");
        seen[v as usize] = true;
    }
    let mut seen = vec![false; mesh.num_faces()];
    for (i, &f) in e.face_map.iter().enumerate() {
        assert!(!seen[f as usize], "face map is a permutation");
        seen[f as usize] = true;
        let got: Vec<u32> = d
            .face(i)
            .iter()
            .map(|&v| e.vertex_map[v as usize])
            .collect();
        let want = mesh.face(f as usize);
        assert_eq!(got.len(), want.len(), "face {f} degree");
        let r = want.iter().position(|&x| x == got[0]).expect("face vertex");
        let rotated: Vec<u32> = (0..want.len())
            .map(|j| want[(r + j) % want.len()])
            .collect();
        assert_eq!(got, rotated, "face {f} (decoded {i})");
    }
    let step = e.quantization.step();
    for (i, &v) in e.vertex_map.iter().enumerate() {
        let err = (d.positions[i] - mesh.positions[v as usize])
            .abs()
            .max_element();
        assert!(
            err <= 0.5 * step * (1.0 + 1e-9) + 1e-12,
            "vertex {v}: error {err}"
        );
    }
    e
}

#[test]
fn roundtrip_closed_triangle_meshes() {
    for m in [
        generate::tetrahedron(),
        generate::icosahedron(),
        generate::icosphere(3),
        generate::torus(2.0, 0.5, 12, 8, true),
    ] {
        check_roundtrip(&m, 14);
    }
}

#[test]
fn roundtrip_open_and_polygon_meshes() {
    for m in [
        generate::grid(6, 5, true),
        generate::grid(6, 5, false),
        generate::disk(7),
        generate::triangle_grid(9),
        generate::cube(),
        generate::pyramid(),
        generate::torus(2.0, 0.5, 9, 7, false),
        generate::five_blobs(0),
    ] {
        check_roundtrip(&m, 12);
    }
}

#[test]
fn roundtrip_several_components_and_isolated_vertices() {
    let mut m = generate::icosphere(1);
    let t = generate::torus(3.0, 0.5, 8, 6, false);
    let off = m.num_vertices() as u32;
    m.positions
        .extend(t.positions.iter().map(|p| *p + DVec3::X * 5.0));
    for f in t.faces() {
        let g: Vec<u32> = f.iter().map(|&v| v + off).collect();
        m.push_face(&g);
    }
    let g = generate::grid(3, 2, true);
    let off = m.num_vertices() as u32;
    m.positions
        .extend(g.positions.iter().map(|p| *p - DVec3::Y * 4.0));
    for f in g.faces() {
        let h: Vec<u32> = f.iter().map(|&v| v + off).collect();
        m.push_face(&h);
    }
    // Unreferenced vertices, one in the middle of the numbering.
    m.positions.push(DVec3::new(9.0, 9.0, 9.0));
    m.positions.insert(0, DVec3::new(-1.0, 2.0, 3.0));
    for v in &mut m.face_indices {
        *v += 1;
    }
    let e = check_roundtrip(&m, 16);
    // Unreferenced vertices come last, in Morton order: (-1, 2, 3) before (9, 9, 9).
    let n = m.num_vertices();
    assert_eq!(&e.vertex_map[n - 2..], &[0, n as u32 - 1]);
}

#[test]
fn roundtrip_holes_and_genus() {
    // A torus with two faces removed: a hole, genus 1.
    let mut t = generate::torus(2.0, 0.6, 10, 8, true);
    let faces: Vec<Vec<u32>> = t.faces().map(|f| f.to_vec()).collect();
    t.face_offsets = vec![0];
    t.face_indices.clear();
    for (i, f) in faces.iter().enumerate() {
        if i != 17 && i != 40 && i != 41 {
            t.push_face(f);
        }
    }
    t.remove_unreferenced();
    check_roundtrip(&t, 14);
}

#[test]
fn roundtrip_tags() {
    let mut m = generate::cube();
    m.edge_tags = vec![
        EdgeTag {
            vertices: [0, 1],
            sharpness: 10.0,
        },
        EdgeTag {
            vertices: [3, 1],
            sharpness: 2.5,
        },
        EdgeTag {
            vertices: [0, 7],
            sharpness: 3.0,
        }, // not an edge: dropped
    ];
    m.vertex_tags = vec![
        VertexTag {
            vertex: 3,
            sharpness: 10.0,
        },
        VertexTag {
            vertex: 5,
            sharpness: 0.0,
        }, // smooth: dropped
    ];
    let e = check_roundtrip(&m, 12);
    let d = &e.decoded;
    assert_eq!(d.edge_tags.len(), 2);
    let mut got: Vec<([u32; 2], f64)> = d
        .edge_tags
        .iter()
        .map(|t| {
            let [a, b] = t.vertices.map(|v| e.vertex_map[v as usize]);
            ([a.min(b), a.max(b)], t.sharpness)
        })
        .collect();
    got.sort_by_key(|a| a.0);
    assert_eq!(got, vec![([0, 1], 10.0), ([1, 3], 2.5)]);
    assert_eq!(d.vertex_tags.len(), 1);
    assert_eq!(e.vertex_map[d.vertex_tags[0].vertex as usize], 3);
    assert_eq!(d.vertex_tags[0].sharpness, 10.0);
}

#[test]
fn empty_and_vertex_only_meshes() {
    check_roundtrip(&Mesh::new(), 12);
    let m = Mesh {
        positions: vec![DVec3::ONE, DVec3::ZERO, DVec3::new(0.5, 2.0, -1.0)],
        ..Mesh::new()
    };
    check_roundtrip(&m, 12);
}

#[test]
fn non_manifold_input_is_a_mesh_error() {
    for m in [
        generate::bowtie(),
        generate::fin(),
        generate::flipped_tetrahedron(),
    ] {
        match encode(&m, &BaseMeshOptions::default()) {
            Err(Error::Mesh(_)) => {}
            other => panic!("expected a mesh error, got {other:?}"),
        }
    }
}

#[test]
fn bad_options_are_rejected() {
    let m = generate::tetrahedron();
    for bits in [0, 7, 31, 64] {
        assert!(matches!(
            encode(
                &m,
                &BaseMeshOptions {
                    position_bits: bits
                }
            ),
            Err(Error::InvalidArgument(_))
        ));
    }
}

#[test]
fn every_prefix_errors_or_decodes() {
    let mut m = generate::torus(2.0, 0.5, 6, 5, false);
    m.edge_tags.push(EdgeTag {
        vertices: [0, 1],
        sharpness: 10.0,
    });
    let bytes = encode(&m, &BaseMeshOptions::default()).unwrap();
    for cut in 0..bytes.len() {
        match decode(&bytes[..cut]) {
            Err(Error::Decode { .. }) => {}
            Ok(d) => d.check_indices().unwrap(),
            Err(e) => panic!("cut {cut}: unexpected error {e}"),
        }
    }
}

#[test]
fn random_corruptions_never_panic() {
    let m = generate::icosphere(2);
    let bytes = encode(&m, &BaseMeshOptions::default()).unwrap();
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    for _ in 0..2000 {
        let mut b = bytes.clone();
        for _ in 0..1 + rnd() % 4 {
            let i = (rnd() % b.len() as u64) as usize;
            b[i] ^= 1 << (rnd() % 8);
        }
        match decode(&b) {
            Err(Error::Decode { .. }) => {}
            Ok(d) => d.check_indices().unwrap(),
            Err(e) => panic!("unexpected error {e}"),
        }
    }
}

#[test]
fn context_thresholds_count_what_the_decoder_knows() {
    // Referenced vertices + holes just below and at the threshold, with unreferenced
    // vertices on top (the decoder's count excludes them).
    let t = connectivity::VALENCE_CONTEXT_VERTICES as u32;
    assert_eq!(t, 16_384);
    for (nx, ny) in [(1, 8190), (128, 126)] {
        let mut m = generate::grid(nx, ny, true);
        assert!(m.num_vertices() as u32 + 1 >= t - 1);
        for i in 0..40 {
            m.positions.push(DVec3::new(i as f64, -3.0, 1.0));
        }
        check_roundtrip(&m, 12);
    }
}

#[test]
fn integer_positions_round_trip_exactly() {
    let mesh = generate::icosphere(2);
    let mut s = 7u64;
    let q: Vec<[i64; 3]> = mesh
        .positions
        .iter()
        .map(|p| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let noise = ((s >> 40) % 5) as i64 - 2;
            [p.x, p.y, p.z].map(|x| (x * 3000.0).round() as i64 - 70_000 + noise)
        })
        .collect();
    let e = encode_integers(&mesh, &q).unwrap();
    let (d, dq) = decode_integers(&e.bytes).unwrap();
    assert_eq!(d.face_indices, e.decoded.face_indices);
    for (i, &v) in e.vertex_map.iter().enumerate() {
        assert_eq!(dq[i], q[v as usize], "vertex {i}");
    }
    // The decoded order depends on the faces only.
    let plain = encode_with_info(&mesh, &BaseMeshOptions::default()).unwrap();
    assert_eq!(plain.vertex_map, e.vertex_map);
    // A float stream is not an integer stream; bad inputs are errors.
    assert!(decode_integers(&plain.bytes).is_err());
    assert!(encode_integers(&mesh, &q[1..]).is_err());
    let mut far = q.clone();
    far[0][0] = 1 << 31;
    assert!(encode_integers(&mesh, &far).is_err());
    for cut in [0, 5, e.bytes.len() / 2, e.bytes.len() - 1] {
        let _ = decode_integers(&e.bytes[..cut]);
    }
}
