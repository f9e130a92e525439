//! Direct streams (`codec::direct`): an irregular mesh coded as it is, progressively in
//! precision.

use subwave::codec::container;
use subwave::codec::direct::{self, codable, compare, Comparison, DirectOptions};
use subwave::codec::progressive::{decode, encode, inspect, DecodeOptions, EncodeOptions};
use subwave::codec::quantize::Grid;
use subwave::distance::distance;
use subwave::generate;
use subwave::mesh::Mesh;
use subwave::DVec3;

fn opts(bits: u32) -> DirectOptions {
    DirectOptions {
        bits,
        ..Default::default()
    }
}

fn prefix(s: &[u8], cut: usize) -> subwave::Result<subwave::codec::progressive::Decoded> {
    decode(
        s,
        &DecodeOptions {
            max_bytes: Some(cut),
            trees: None,
        },
    )
}

/// An irregular, bumpy torus (no subdivision connectivity), triangles.
fn bumpy_torus() -> Mesh {
    let mut m = generate::torus(1.0, 0.35, 23, 11, true);
    for (i, p) in m.positions.iter_mut().enumerate() {
        *p *= 1.0 + 0.02 * ((i * 7919) % 13) as f64 / 13.0;
    }
    m
}

/// The stream's grid for `m` at `bits` (its bounding box).
fn grid_of(m: &Mesh, bits: u32) -> Grid {
    let lo = m
        .positions
        .iter()
        .fold(DVec3::splat(f64::INFINITY), |a, &p| a.min(p));
    let hi = m
        .positions
        .iter()
        .fold(DVec3::splat(f64::NEG_INFINITY), |a, &p| a.max(p));
    Grid::new(lo, hi, bits)
}

/// The sorted grid points of `m`'s positions on `input`'s `bits` grid.
fn grid_points(m: &Mesh, input: &Mesh, bits: u32) -> Vec<[i32; 3]> {
    let g = grid_of(input, bits);
    let mut q: Vec<[i32; 3]> = m.positions.iter().map(|&p| g.quantize(p)).collect();
    q.sort_unstable();
    q
}

/// The full stream is the input on its `bits` grid, bit for bit: same grid points, same
/// faces; every refinement plane brings the mesh closer to the input.
#[test]
fn the_full_stream_is_the_input_on_its_grid_and_planes_refine_it() {
    let input = bumpy_torus();
    let s = direct::encode(&input, &opts(16)).unwrap();
    let info = inspect(&s).unwrap();
    assert!(info.direct && !info.lossless);
    assert_eq!((info.levels, info.bits, info.planes), (0, 16, 8));
    assert_eq!(info.chunks.len(), 1 + 8);
    let d = decode(&s, &DecodeOptions::default()).unwrap();
    assert!(d.complete);
    assert_eq!((d.planes_complete, d.planes), (8, 8));
    assert_eq!(
        grid_points(&d.mesh, &input, 16),
        grid_points(&input, &input, 16)
    );
    // Exactly on the grid.
    let g = grid_of(&input, 16);
    for p in &d.mesh.positions {
        let q = g.dequantize(g.quantize(*p).map(i64::from));
        assert!(p.distance(q) < 1e-9 * g.step, "{p} off the grid");
    }
    assert_eq!(d.mesh.num_faces(), input.num_faces());
    // Faces: each decoded vertex is the input vertex on the same grid point.
    let g = grid_of(&input, 16);
    let index: std::collections::HashMap<[i32; 3], u32> = input
        .positions
        .iter()
        .enumerate()
        .map(|(i, &p)| (g.quantize(p), i as u32))
        .collect();
    assert_eq!(index.len(), input.num_vertices(), "distinct grid points");
    let faces = |m: &Mesh, map: &dyn Fn(u32) -> u32| {
        let mut f: Vec<Vec<u32>> = m
            .faces()
            .map(|f| {
                let mut f: Vec<u32> = f.iter().map(|&v| map(v)).collect();
                f.sort_unstable();
                f
            })
            .collect();
        f.sort();
        f
    };
    let to_input = |v: u32| index[&g.quantize(d.mesh.positions[v as usize])];
    assert_eq!(faces(&d.mesh, &to_input), faces(&input, &|v| v));
    // Each complete plane halves the quantization error: about 6 dB per plane.
    let mut last = 0.0;
    for e in &info.chunks {
        let end = (e.offset + e.len as u64) as usize;
        let psnr = distance(&input, &prefix(&s, end).unwrap().mesh, 20_000)
            .unwrap()
            .psnr;
        assert!(psnr > last + 3.0, "{psnr} dB after {last} dB");
        last = psnr;
    }
    assert!(last > 95.0, "{last}");
}

/// Polygons stay polygons, and each keeps its input's fan triangulation (the diagonal of a
/// non-planar quad), which the distance and viewers use.
#[test]
fn polygons_keep_their_triangulation() {
    let mut input = generate::grid(9, 7, false);
    for (i, p) in input.positions.iter_mut().enumerate() {
        p.z = 0.3 * ((i * 37) % 11) as f64 / 11.0;
    }
    let s = direct::encode(&input, &opts(16)).unwrap();
    let d = decode(&s, &DecodeOptions::default()).unwrap();
    assert!(d.mesh.faces().all(|f| f.len() == 4));
    assert_eq!(d.mesh.num_faces(), input.num_faces());
    let dist = distance(&input, &d.mesh, 20_000).unwrap();
    assert!(dist.psnr > 90.0, "{dist:?}");
}

/// Every prefix decodes or says why not (a prefix ending before the base chunk does); a
/// longer prefix is never further from the input by more than noise.
#[test]
fn every_prefix_of_a_small_stream_decodes() {
    let input = generate::icosphere(2);
    let s = direct::encode(&input, &opts(14)).unwrap();
    let c = container::read(&s).unwrap();
    let first = (c.chunks[0].offset + c.chunks[0].len as u64) as usize;
    for cut in 0..=s.len() {
        match prefix(&s, cut) {
            Ok(d) => {
                assert!(cut >= first, "a {cut}-byte prefix decoded");
                assert_eq!(d.mesh.num_vertices(), input.num_vertices());
                assert!(d.mesh.positions.iter().all(|p| p.is_finite()));
                assert_eq!(d.complete, cut == s.len());
            }
            Err(e) => {
                assert!(cut < first, "{cut}: {e}");
                let e = e.to_string();
                assert!(e.contains("truncated") || e.contains("needs"), "{cut}: {e}");
            }
        }
    }
}

/// A corrupt chunk is named by its checksum; corrupt data behind valid checksums, bad
/// headers and truncations give errors or finite meshes, never a panic.
#[test]
fn corrupt_direct_streams_are_refused_or_decoded_safely() {
    let s = direct::encode(&bumpy_torus(), &opts(14)).unwrap();
    let info = inspect(&s).unwrap();
    let e = &info.chunks[2];
    let mut bad = s.clone();
    bad[e.offset as usize + e.len as usize / 2] ^= 0x20;
    let msg = decode(&bad, &DecodeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("chunk 2") && msg.contains("checksum"), "{msg}");
    let c = container::read(&s).unwrap();
    let mut x = 11u64;
    for _ in 0..1500 {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let i = (x >> 40) as usize % c.chunks.len();
        let chunks: Vec<_> = c
            .chunks
            .iter()
            .enumerate()
            .map(|(j, e)| {
                let mut data = s[e.offset as usize..e.offset as usize + e.len as usize].to_vec();
                if j == i && !data.is_empty() {
                    let k = (x >> 20) as usize % data.len();
                    data[k] ^= (x >> 8) as u8 | 1;
                }
                (e.kind, e.id, data, e.marks.clone())
            })
            .collect();
        let mut header = c.header.clone();
        match (x >> 5) % 8 {
            0 => header.bits = (x >> 12) as u8,
            1 => header.base_bits = (x >> 12) as u8,
            2 => header.levels = 1,
            3 => header.layout = 1,
            _ => {}
        }
        let m = container::write(&header, &chunks).unwrap();
        if let Ok(d) = decode(&m, &DecodeOptions::default()) {
            assert!(d.mesh.positions.iter().all(|p| p.is_finite()));
        }
        let cut = (x >> 3) as usize % (m.len() + 1);
        let _ = prefix(&m, cut);
    }
}

/// The direct stream's bytes are pinned: a change of its encoder's output fails here (bump
/// `container::VERSION` if the format changed; regenerate with
/// `SUBWAVE_BLESS=1 cargo test -p subwave --test direct golden`).
#[test]
fn golden_bytes_of_a_small_direct_stream() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/torus_direct.swv");
    let s = direct::encode(&generate::torus(1.0, 0.4, 12, 6, false), &opts(12)).unwrap();
    if std::env::var_os("SUBWAVE_BLESS").is_some() {
        std::fs::write(path, &s).unwrap();
    }
    let golden = std::fs::read(path).expect(path);
    assert_eq!(
        u16::from_le_bytes([golden[4], golden[5]]),
        container::VERSION,
        "the golden direct stream has another version: regenerate it"
    );
    assert!(
        s == golden,
        "the direct encoder's output changed ({} bytes, golden {})",
        s.len(),
        golden.len()
    );
    let d = decode(&golden, &DecodeOptions::default()).unwrap();
    assert!(d.complete && d.mesh.faces().all(|f| f.len() == 4));
}

/// Bad options and meshes are refused with the reason; a non-manifold mesh is made codable
/// by [`codable`]'s repair.
#[test]
fn bad_input_is_refused_or_repaired() {
    let m = generate::icosphere(1);
    for (bits, coarse) in [(7, 8), (31, 8), (12, 13), (12, 7)] {
        let e = direct::encode(
            &m,
            &DirectOptions {
                bits,
                coarse_bits: coarse,
                input_vertices: None,
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("precision"), "{e}");
    }
    let mut nan = m.clone();
    nan.positions[3].y = f64::NAN;
    let e = direct::encode(&nan, &opts(12)).unwrap_err().to_string();
    assert!(e.contains("vertex 3"), "{e}");
    // Two tetrahedra sharing one vertex: a non-manifold vertex, split by the repair.
    let bowtie = generate::bowtie();
    assert!(direct::encode(&bowtie, &opts(12)).is_err());
    let (fixed, report) = codable(&bowtie).unwrap();
    assert!(report.is_some());
    let s = direct::encode(&fixed, &opts(12)).unwrap();
    let d = decode(&s, &DecodeOptions::default()).unwrap();
    assert!(distance(&bowtie, &d.mesh, 5_000).unwrap().psnr > 70.0);
}

/// The choice between a wavelet stream and the direct one: a coarse polyhedron (a cube)
/// is served better as it is than by any remesh of it; the comparison's majority rule.
#[test]
fn a_coarse_polyhedron_prefers_the_direct_stream() {
    use subwave::codec::prepare::{prepare, PrepareOptions};
    let input = generate::cube();
    let mut input = Mesh::from_triangles(input.positions.clone(), &input.triangulate().0);
    input.remove_unreferenced();
    let prep = prepare(&input, &PrepareOptions::default(), &mut |_, _| {}).unwrap();
    assert!(prep.remeshed.is_some());
    let mut o: EncodeOptions = prep.encode_options();
    o.input_vertices = Some(input.num_vertices() as u32);
    let wavelet = encode(&prep.hierarchy, &o).unwrap();
    let (direct, c, _) = direct::encode_and_compare(&input, &wavelet, &opts(14)).unwrap();
    assert!(c.prefer_direct(), "{c:?}");
    assert!(direct.len() < wavelet.len());
    assert_eq!(c, compare(&input, &wavelet, &direct).unwrap());
    // The screen before a raise: both of the first two budgets won.
    let (wins, s) = direct::screen(&input, &wavelet, &direct).unwrap();
    assert!(wins, "{s:?}");
    assert_eq!((s.planned, s.bytes.len()), (2, 2));
    assert!(s
        .direct_psnr
        .iter()
        .zip(&s.wavelet_psnr)
        .all(|(d, w)| d > w));
    // Against itself (a direct stream is no wavelet stream, but any stream decodes the
    // same): no budget is won.
    let (wins, s) = direct::screen(&input, &direct, &direct).unwrap();
    assert!(!wins && s.bytes.len() == 1, "{s:?}");

    let at = |w: &[f64], d: &[f64]| Comparison {
        bytes: vec![1; w.len()],
        wavelet_psnr: w.to_vec(),
        direct_psnr: d.to_vec(),
        planned: 3,
    };
    assert!(at(&[60.0, 70.0], &[61.0, 71.0]).prefer_direct());
    assert!(!at(&[60.0, 70.0], &[59.0, 69.0]).prefer_direct());
    assert!(at(&[62.0, 70.0, 75.0], &[61.0, 71.0, 80.0]).prefer_direct());
    assert!(!at(&[62.0, 72.0, 75.0], &[61.0, 71.0, 80.0]).prefer_direct());
    assert!(!at(&[f64::NEG_INFINITY, 72.0, 75.0], &[61.0, 71.0, 70.0]).prefer_direct());
}
