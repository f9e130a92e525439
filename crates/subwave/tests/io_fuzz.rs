//! Hostile input for every reader: random bytes, and valid files (built from small generated
//! meshes) with flipped bytes, truncation, inserted garbage and duplicated or deleted lines.
//! No reader may panic or allocate unboundedly; any `Ok` mesh must pass `check_indices`.

use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::Config;
use subwave::io::{self, Format};
use subwave::{DVec3, EdgeTag, Error, Mesh, VertexTag};

const CASES: u32 = 10_000;

fn config() -> Config {
    Config {
        cases: CASES,
        failure_persistence: None,
        ..Config::default()
    }
}

/// Reads `bytes`; an `Ok` mesh must be valid, an error must be a parse error.
fn check(format: Format, bytes: &[u8]) -> Option<Mesh> {
    match io::read_mesh_bytes(bytes, format, "fuzz") {
        Ok(m) => {
            if let Err(e) = m.check_indices() {
                panic!("{format} reader returned an invalid mesh: {e}");
            }
            Some(m)
        }
        Err(e @ Error::Parse { .. }) => {
            let msg = e.to_string();
            assert!(msg.len() < 1000, "overlong error message: {msg}");
            None
        }
        Err(e) => panic!("{format} reader returned a non-parse error: {e}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Random bytes

/// Bytes that text formats care about, so random text reaches deep into the parsers.
const ALPHABET: &[u8] = b"   \n\n\t\r0123456789--+..eE//#\\vftnaNiOFFCSTplyrxzsoidcel_";

fn random_bytes() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        prop::collection::vec(any::<u8>(), 0..400),
        prop::collection::vec(prop::sample::select(ALPHABET), 0..400),
    ]
}

const OBJ_PREFIXES: &[&str] = &[
    "",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\n",
    "v 0 0 0\nf ",
    "t crease ",
];
const OFF_PREFIXES: &[&str] = &["", "OFF\n", "COFF\n3 1 0\n", "STCNOFF\n", "OFF 3 1 0\n"];
const PLY_PREFIXES: &[&str] = &[
    "",
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
     property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n",
    "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
     property float y\nproperty float z\nelement face 1\nproperty list uchar int \
     vertex_indices\nend_header\n",
    "ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double x\n\
     property uchar y\nproperty int z\nproperty list int uchar junk\nelement face 2\n\
     property list int uint vertex_index\nend_header\n",
    "ply\nformat ascii 1.0\nelement ",
];
const STL_PREFIXES: &[&str] = &[
    "",
    "solid x\n",
    "solid x\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\n",
];

fn with_prefix(prefixes: &[&str], i: Index, rest: &[u8]) -> Vec<u8> {
    let mut b = prefixes[i.index(prefixes.len())].as_bytes().to_vec();
    b.extend_from_slice(rest);
    b
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn obj_random_bytes(i in any::<Index>(), rest in random_bytes()) {
        check(Format::Obj, &with_prefix(OBJ_PREFIXES, i, &rest));
    }

    #[test]
    fn off_random_bytes(i in any::<Index>(), rest in random_bytes()) {
        check(Format::Off, &with_prefix(OFF_PREFIXES, i, &rest));
    }

    #[test]
    fn ply_random_bytes(i in any::<Index>(), rest in random_bytes()) {
        check(Format::Ply, &with_prefix(PLY_PREFIXES, i, &rest));
    }

    #[test]
    fn stl_random_bytes(
        i in any::<Index>(),
        rest in random_bytes(),
        binary in any::<bool>(),
        n in 0usize..6,
        body in prop::collection::vec(any::<u8>(), 300),
    ) {
        if binary {
            // Exactly binary-sized, so the binary path sees random triangles (NaNs, repeats).
            let mut b = vec![0u8; 80];
            b.extend_from_slice(&(n as u32).to_le_bytes());
            b.extend_from_slice(&body[..50 * n]);
            check(Format::Stl, &b);
        } else {
            check(Format::Stl, &with_prefix(STL_PREFIXES, i, &rest));
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Mutated valid files

prop_compose! {
    /// A small valid mesh: distinct positions (distinct x), faces of 3..6 distinct vertices,
    /// optional colours and tags.
    fn small_mesh()(nv in 3usize..10)(
        ys in prop::collection::vec(-4i32..4, nv),
        zs in prop::collection::vec(-4i32..4, nv),
        faces in prop::collection::vec(prop::collection::vec(0..nv as u32, 3..7), 0..6),
        colors in any::<bool>(),
        tags in prop::collection::vec((0..nv as u32, 0..nv as u32, 0u8..12), 0..3),
    ) -> Mesh {
        let nv = ys.len();
        let positions = (0..nv)
            .map(|i| DVec3::new(i as f64 * 0.5, f64::from(ys[i]) / 3.0, f64::from(zs[i]) * 1e-3))
            .collect();
        let faces: Vec<Vec<u32>> = faces
            .into_iter()
            .map(|mut f| {
                let mut seen = Vec::new();
                f.retain(|v| !seen.contains(v) && { seen.push(*v); true });
                f
            })
            .filter(|f| f.len() >= 3)
            .collect();
        let mut m = Mesh::from_faces(positions, faces);
        if colors {
            m.colors = Some((0..nv).map(|i| [(i * 20) as f32 / 255.0, 0.5, 1.0]).collect());
        }
        for (a, b, s) in tags {
            if a != b {
                m.edge_tags.push(EdgeTag { vertices: [a, b], sharpness: f64::from(s) * 0.5 });
            } else {
                m.vertex_tags.push(VertexTag { vertex: a, sharpness: f64::from(s) });
            }
        }
        m
    }
}

#[derive(Clone, Debug)]
enum Mutation {
    Flip(Index, u8),
    Set(Index, u8),
    Truncate(Index),
    Insert(Index, Vec<u8>),
    DuplicateLine(Index),
    DeleteLine(Index),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let interesting = prop::sample::select(&b"\0\xff-0912 \n/#.e\\"[..]);
    prop_oneof![
        (any::<Index>(), 0u8..8).prop_map(|(i, b)| Mutation::Flip(i, b)),
        (any::<Index>(), interesting).prop_map(|(i, b)| Mutation::Set(i, b)),
        any::<Index>().prop_map(Mutation::Truncate),
        (
            any::<Index>(),
            random_bytes().prop_map(|mut v| {
                v.truncate(12);
                v
            })
        )
            .prop_map(|(i, v)| Mutation::Insert(i, v)),
        any::<Index>().prop_map(Mutation::DuplicateLine),
        any::<Index>().prop_map(Mutation::DeleteLine),
    ]
}

fn line_around(b: &[u8], at: usize) -> (usize, usize) {
    let start = b[..at]
        .iter()
        .rposition(|&c| c == b'\n')
        .map_or(0, |p| p + 1);
    let end = b[at..]
        .iter()
        .position(|&c| c == b'\n')
        .map_or(b.len(), |p| at + p + 1);
    (start, end)
}

fn mutate(mut b: Vec<u8>, muts: &[Mutation]) -> Vec<u8> {
    for m in muts {
        if b.is_empty() {
            break;
        }
        match m {
            Mutation::Flip(i, bit) => {
                let k = i.index(b.len());
                b[k] ^= 1 << bit;
            }
            Mutation::Set(i, v) => {
                let k = i.index(b.len());
                b[k] = *v;
            }
            Mutation::Truncate(i) => b.truncate(i.index(b.len())),
            Mutation::Insert(i, v) => {
                let k = i.index(b.len() + 1);
                b.splice(k..k, v.iter().copied());
            }
            Mutation::DuplicateLine(i) => {
                let (s, e) = line_around(&b, i.index(b.len()));
                let line = b[s..e].to_vec();
                b.splice(e..e, line);
            }
            Mutation::DeleteLine(i) => {
                let (s, e) = line_around(&b, i.index(b.len()));
                b.drain(s..e);
            }
        }
    }
    b
}

fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    prop::collection::vec(mutation(), 0..4)
}

fn written(m: &Mesh, f: Format) -> Vec<u8> {
    let mut out = Vec::new();
    io::write_mesh_to(m, f, &mut out).unwrap();
    out
}

fn ply_ascii(m: &Mesh) -> Vec<u8> {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\n",
        m.num_vertices()
    );
    if m.colors.is_some() {
        s += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    s += &format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.num_faces()
    );
    for (v, p) in m.positions.iter().enumerate() {
        s += &format!("{} {} {}", p.x, p.y, p.z);
        if let Some(c) = &m.colors {
            let q = c[v].map(|x| (x * 255.0).round() as u8);
            s += &format!(" {} {} {}", q[0], q[1], q[2]);
        }
        s += "\n";
    }
    for f in m.faces() {
        s += &f.len().to_string();
        for v in f {
            s += &format!(" {v}");
        }
        s += "\n";
    }
    s.into_bytes()
}

fn ply_big_endian(m: &Mesh) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_big_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list ushort int vertex_indices\nend_header\n",
        m.num_vertices(),
        m.num_faces()
    )
    .into_bytes();
    for p in &m.positions {
        for x in p.to_array() {
            b.extend_from_slice(&(x as f32).to_be_bytes());
        }
    }
    for f in m.faces() {
        b.extend_from_slice(&(f.len() as u16).to_be_bytes());
        for &v in f {
            b.extend_from_slice(&(v as i32).to_be_bytes());
        }
    }
    b
}

fn stl_ascii(m: &Mesh) -> Vec<u8> {
    let (tris, _) = m.triangulate();
    let mut s = String::from("solid fuzz\n");
    for t in tris {
        s += "facet normal 0 0 1\n outer loop\n";
        for v in t {
            let p = m.positions[v as usize];
            s += &format!("  vertex {} {} {}\n", p.x, p.y, p.z);
        }
        s += " endloop\nendfacet\n";
    }
    (s + "endsolid fuzz\n").into_bytes()
}

/// Unmutated files must read back; mutated ones must not panic.
fn check_mutated(format: Format, original: Vec<u8>, muts: &[Mutation], m: &Mesh) {
    if muts.is_empty() {
        let back = check(format, &original).unwrap_or_else(|| {
            panic!(
                "valid {format} file rejected: {:?}",
                check_err(format, &original)
            )
        });
        if format != Format::Stl {
            assert_eq!(back.num_vertices(), m.num_vertices());
            assert_eq!(back.face_indices, m.face_indices);
        } else {
            assert_eq!(back.num_faces(), m.triangulate().0.len());
        }
    } else {
        check(format, &mutate(original, muts));
    }
}

fn check_err(format: Format, bytes: &[u8]) -> String {
    io::read_mesh_bytes(bytes, format, "fuzz")
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default()
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn obj_mutated(m in small_mesh(), muts in mutations()) {
        check_mutated(Format::Obj, written(&m, Format::Obj), &muts, &m);
    }

    #[test]
    fn off_mutated(m in small_mesh(), muts in mutations()) {
        check_mutated(Format::Off, written(&m, Format::Off), &muts, &m);
    }

    #[test]
    fn ply_mutated(m in small_mesh(), muts in mutations(), kind in 0u8..3) {
        let bytes = match kind {
            0 => written(&m, Format::Ply),
            1 => ply_ascii(&m),
            _ => ply_big_endian(&m),
        };
        check_mutated(Format::Ply, bytes, &muts, &m);
    }

    #[test]
    fn stl_mutated(m in small_mesh(), muts in mutations(), ascii in any::<bool>()) {
        let bytes = if ascii { stl_ascii(&m) } else { written(&m, Format::Stl) };
        check_mutated(Format::Stl, bytes, &muts, &m);
    }
}

// ---------------------------------------------------------------------------------------------
// Hostile counts and sizes

fn assert_fast_error(format: Format, bytes: &[u8]) {
    let t = Instant::now();
    assert!(
        check(format, bytes).is_none(),
        "{format}: expected an error"
    );
    assert!(
        t.elapsed() < Duration::from_secs(2),
        "{format}: took {:?}",
        t.elapsed()
    );
}

#[test]
fn huge_counts_are_rejected_before_allocating() {
    assert_fast_error(Format::Off, b"OFF\n4294967295 4294967295 0\n0 0 0\n");
    assert_fast_error(Format::Off, b"OFF\n99999999999999999999 1 0\n");
    assert_fast_error(
        Format::Ply,
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4294967295\nproperty float x\n\
          property float y\nproperty float z\nend_header\n\0\0\0\0",
    );
    assert_fast_error(
        Format::Ply,
        b"ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n\
          property float x\nproperty float y\nproperty float z\nend_header\n",
    );
    // An element without properties carries no data, whatever its count.
    let m = check(
        Format::Ply,
        b"ply\nformat ascii 1.0\nelement nothing 9223372036854775807\nend_header\n",
    )
    .unwrap();
    assert_eq!(m.num_vertices(), 0);
    // A list count far beyond the data.
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
                  property float y\nproperty float z\nelement junk 1\n\
                  property list uint double v\nend_header\n"
        .to_vec();
    b.extend_from_slice(&u32::MAX.to_le_bytes());
    assert_fast_error(Format::Ply, &b);
    // A binary STL declaring more triangles than it holds (and not starting with `solid`).
    let mut b = vec![0u8; 84];
    b[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    assert_fast_error(Format::Stl, &b);
}

#[test]
fn huge_polygons_are_not_quadratic() {
    let n = 200_000u32;
    let mut text = String::with_capacity(20 * n as usize);
    for i in 0..n {
        text += &format!("v {i} 0 0\n");
    }
    text += "f";
    for i in 1..=n {
        text += &format!(" {i}");
    }
    text += " 1\n";
    let t = Instant::now();
    assert!(check(Format::Obj, text.as_bytes()).is_none());
    assert!(
        t.elapsed() < Duration::from_secs(2),
        "took {:?}",
        t.elapsed()
    );
    // And the same face without the repeat is accepted and writable. (Not through `check`:
    // `Mesh::check_indices` itself is quadratic in the arity of a face.)
    let text = text.trim_end().strip_suffix(" 1").unwrap();
    let t = Instant::now();
    let m = io::read_mesh_bytes(text.as_bytes(), Format::Obj, "big").unwrap();
    assert_eq!(m.face_arity(0), n as usize);
    let ply = written(&m, Format::Ply);
    let back = io::read_mesh_bytes(&ply, Format::Ply, "big").unwrap();
    assert_eq!(back.face_arity(0), n as usize);
    assert!(
        t.elapsed() < Duration::from_secs(2),
        "took {:?}",
        t.elapsed()
    );
}

#[test]
fn deep_continuations_and_long_tokens() {
    let mut text = "v".to_string();
    for _ in 0..10_000 {
        text += " \\\n";
    }
    text += "0 0 0\n";
    let m = check(Format::Obj, text.as_bytes()).unwrap();
    assert_eq!(m.num_vertices(), 1);
    let long = format!("v {} 0 0\n", "9".repeat(1_000_000) + "x");
    let e = check_err(Format::Obj, long.as_bytes());
    assert!(e.len() < 300 && e.contains("line 1"), "{e}");
}
