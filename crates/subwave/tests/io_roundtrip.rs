//! Round trips and corner cases of the mesh file readers and writers.

use std::path::Path;

use subwave::io::{self, Format};
use subwave::{DVec3, EdgeTag, Error, FaceVarying, Location, Mesh, VertexTag};

/// A small mixed mesh: a quad, a triangle, a pentagon, an unreferenced vertex, and positions
/// whose decimal forms are awkward (subnormals, huge values, -0.0, non-terminating binaries).
fn awkward_mesh() -> Mesh {
    let positions = vec![
        DVec3::new(0.1, 0.2, 0.3),
        DVec3::new(1.0 / 3.0, -2.0 / 7.0, std::f64::consts::PI),
        DVec3::new(-0.0, 1e-300, 5e-324),
        DVec3::new(1e300, -1.7976931348623157e308, 123_456_789.123_456_79),
        DVec3::new(0.5, 0.25, -0.125),
        DVec3::new(1e-7, 1e16, 9.999999999999998e15),
        DVec3::new(2.0, 3.0, 4.0),
        DVec3::new(7.0, 8.0, 9.0), // unreferenced
    ];
    let mut m = Mesh::from_faces(
        positions,
        [&[0u32, 1, 2, 3][..], &[3, 4, 5], &[0, 5, 4, 6, 1]],
    );
    m.edge_tags = vec![
        EdgeTag {
            vertices: [0, 1],
            sharpness: 2.5,
        },
        EdgeTag {
            vertices: [3, 4],
            sharpness: 10.0,
        },
    ];
    m.vertex_tags = vec![VertexTag {
        vertex: 6,
        sharpness: 0.1,
    }];
    m
}

fn with_colors(mut m: Mesh) -> Mesh {
    let n = m.num_vertices();
    m.colors = Some(
        (0..n)
            .map(|i| [i as f32 / 255.0, 1.0, (3 * i) as f32 / 255.0])
            .collect(),
    );
    m
}

fn write(m: &Mesh, f: Format) -> Vec<u8> {
    let mut out = Vec::new();
    io::write_mesh_to(m, f, &mut out).unwrap();
    out
}

fn read(bytes: &[u8], f: Format) -> Mesh {
    let m = io::read_mesh_bytes(bytes, f, "test").unwrap_or_else(|e| panic!("{e}"));
    m.check_indices().unwrap();
    m
}

fn bits(m: &Mesh) -> Vec<[u64; 3]> {
    m.positions
        .iter()
        .map(|p| p.to_array().map(f64::to_bits))
        .collect()
}

/// Reads `text` as `format` and returns the error message, asserting it is a parse error.
fn parse_error(text: &str, f: Format) -> (Location, String) {
    match io::read_mesh_bytes(text.as_bytes(), f, "bad") {
        Err(e @ Error::Parse { .. }) => {
            let Error::Parse { location, .. } = &e else {
                unreachable!()
            };
            (*location, e.to_string())
        }
        Err(e) => panic!("expected a parse error, got {e}"),
        Ok(m) => panic!(
            "expected a parse error, got a mesh with {} faces",
            m.num_faces()
        ),
    }
}

fn assert_error(text: &str, f: Format, needles: &[&str]) {
    let (_, msg) = parse_error(text, f);
    for n in needles {
        assert!(msg.contains(n), "error `{msg}` should contain `{n}`");
    }
}

// ---------------------------------------------------------------------------------------------
// Format API

#[test]
fn format_names_and_extensions() {
    for f in [
        Format::Obj,
        Format::Off,
        Format::Ply,
        Format::Stl,
        Format::Glb,
    ] {
        assert_eq!(Format::from_name(f.name()), Some(f));
        assert_eq!(Format::from_name(&f.name().to_uppercase()), Some(f));
        let p = format!("dir.x/mesh.{}", f.name().to_uppercase());
        assert_eq!(Format::from_path(Path::new(&p)), Some(f));
    }
    assert_eq!(Format::from_name("gltf"), None);
    assert_eq!(Format::from_path(Path::new("mesh")), None);
    assert_eq!(Format::from_path(Path::new("-")), None);
    assert_eq!(Format::from_path(Path::new("mesh.obj.gz")), None);
}

#[test]
fn stdio_needs_a_format() {
    assert!(matches!(
        io::read_mesh(Path::new("-"), None),
        Err(Error::Format { .. })
    ));
    assert!(matches!(
        io::write_mesh(&Mesh::new(), Path::new("-"), None),
        Err(Error::Format { .. })
    ));
    assert!(matches!(
        io::read_mesh(Path::new("mesh.unknown"), None),
        Err(Error::Format { .. })
    ));
    assert!(matches!(
        io::read_mesh_bytes(b"", Format::Glb, "x.glb"),
        Err(Error::Format { .. })
    ));
}

#[test]
fn files_on_disk() {
    let dir = std::env::temp_dir().join(format!("subwave-io-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let m = awkward_mesh();
    for f in [Format::Obj, Format::Off, Format::Ply] {
        let path = dir.join(format!("m.{}", f.name()));
        io::write_mesh(&m, &path, None).unwrap();
        let back = io::read_mesh(&path, None).unwrap();
        assert_eq!(bits(&back), bits(&m), "{f}");
        assert_eq!(back.face_indices, m.face_indices);
        // An explicit format overrides the extension.
        let other = dir.join(format!("m-{}.dat", f.name()));
        io::write_mesh(&m, &other, Some(f)).unwrap();
        assert_eq!(
            io::read_mesh(&other, Some(f)).unwrap().face_offsets,
            m.face_offsets
        );
    }
    let missing = dir.join("missing.obj");
    match io::read_mesh(&missing, None) {
        Err(Error::Io { path, .. }) => assert!(path.contains("missing.obj")),
        other => panic!("expected an I/O error, got {other:?}"),
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn writers_reject_invalid_meshes() {
    let mut bad = Mesh::from_triangles(vec![DVec3::ZERO; 3], &[[0, 1, 5]]);
    for f in [
        Format::Obj,
        Format::Off,
        Format::Ply,
        Format::Stl,
        Format::Glb,
    ] {
        assert!(matches!(
            io::write_mesh_to(&bad, f, &mut Vec::new()),
            Err(Error::Mesh(_))
        ));
    }
    bad.face_indices = vec![0, 1, 1];
    assert!(matches!(
        io::write_mesh_to(&bad, Format::Obj, &mut Vec::new()),
        Err(Error::Mesh(_))
    ));
    bad.face_offsets = vec![0, 4];
    assert!(matches!(
        io::write_mesh_to(&bad, Format::Ply, &mut Vec::new()),
        Err(Error::Mesh(_))
    ));
}

#[test]
fn empty_meshes() {
    for f in [Format::Obj, Format::Off, Format::Ply, Format::Stl] {
        let bytes = write(&Mesh::new(), f);
        let m = read(&bytes, f);
        assert_eq!((m.num_vertices(), m.num_faces()), (0, 0), "{f}");
    }
    let glb = write(&Mesh::new(), Format::Glb);
    let g = gltf::Gltf::from_slice(&glb).unwrap();
    assert_eq!(g.meshes().count(), 0);
}

// ---------------------------------------------------------------------------------------------
// OBJ

#[test]
fn obj_round_trip_is_exact() {
    let mut m = with_colors(awkward_mesh());
    m.face_uvs = Some(FaceVarying {
        coords: vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [0.1, 0.7],
            [1e-9, 0.3333333333333333],
        ],
        indices: vec![0, 1, 2, 3, 3, 2, 1, 0, 1, 2, 3, 0],
    });
    let text = write(&m, Format::Obj);
    let back = read(&text, Format::Obj);
    assert_eq!(bits(&back), bits(&m));
    assert_eq!(back, m);
    // And the text is stable.
    assert_eq!(write(&back, Format::Obj), text);
}

#[test]
fn obj_per_vertex_uvs_become_face_varying() {
    let mut m = awkward_mesh();
    m.uvs = Some(
        (0..m.num_vertices())
            .map(|i| [i as f64 * 0.5, 1.0])
            .collect(),
    );
    let back = read(&write(&m, Format::Obj), Format::Obj);
    let fv = back.face_uvs.unwrap();
    for (c, &v) in m.face_indices.iter().enumerate() {
        assert_eq!(
            fv.coords[fv.indices[c] as usize],
            m.uvs.as_ref().unwrap()[v as usize]
        );
    }
}

#[test]
fn obj_corner_cases() {
    let text = "\
# a comment
mtllib scene.mtl
o thing
g group
s 1
usemtl red
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0   # trailing comment
v 5 5 5
vt 0 0
vt 1 0
vt 1 1 0
vt 0 1
vn 0 0 1
vp 0.5
f 1/1/1 2/2/1 3/3/1 4/4/1
f -5/-4/-1 -3/-2/-1 -1/-3/-1
l 1 2
p 1
t crease 2/1 0 1 3.5
t corner 1/1 2 10
t holes 1/0 0
t interpolateboundary 1/0/0 1
";
    let m = read(text.as_bytes(), Format::Obj);
    assert_eq!(m.num_vertices(), 5, "the unreferenced vertex is kept");
    assert_eq!(m.face(0), &[0, 1, 2, 3]);
    assert_eq!(m.face(1), &[0, 2, 4]);
    let fv = m.face_uvs.as_ref().unwrap();
    assert_eq!(fv.indices, vec![0, 1, 2, 3, 0, 2, 1]);
    assert_eq!(fv.coords[2], [1.0, 1.0]);
    assert_eq!(
        m.edge_tags,
        vec![EdgeTag {
            vertices: [0, 1],
            sharpness: 3.5
        }]
    );
    assert_eq!(
        m.vertex_tags,
        vec![VertexTag {
            vertex: 2,
            sharpness: 10.0
        }]
    );
    assert!(m.colors.is_none());
}

#[test]
fn obj_normals_only_and_mixed_uvs_drop_uvs() {
    let m = read(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n",
        Format::Obj,
    );
    assert_eq!(m.face(0), &[0, 1, 2]);
    assert!(m.face_uvs.is_none());
    let m = read(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 2 4 3\n",
        Format::Obj,
    );
    assert_eq!(m.num_faces(), 2);
    assert!(m.face_uvs.is_none());
}

#[test]
fn obj_colours_only_when_every_vertex_has_them() {
    let m = read(
        b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n",
        Format::Obj,
    );
    assert_eq!(
        m.colors,
        Some(vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    );
    let m = read(
        b"v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 0 0 1\nf 1 2 3\n",
        Format::Obj,
    );
    assert!(m.colors.is_none());
    // `v x y z w`: w ignored.
    let m = read(b"v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n", Format::Obj);
    assert_eq!(m.positions[1], DVec3::X);
}

#[test]
fn obj_forward_references_crlf_and_continuations() {
    let m = read(
        b"f 1 2 \\\r\n 3 4\r\nv 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\n",
        Format::Obj,
    );
    assert_eq!(m.num_vertices(), 4);
    assert_eq!(m.face(0), &[0, 1, 2, 3]);
    let m = read(b"v 0 0 0\nv \\\n 1 0 0\nv 0 1 0\nf 1 2 3", Format::Obj);
    assert_eq!(m.positions[1], DVec3::X);
}

#[test]
fn byte_order_marks_are_skipped() {
    let m = read(
        b"\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        Format::Obj,
    );
    assert_eq!((m.num_vertices(), m.num_faces()), (3, 1));
    let m = read(
        b"\xEF\xBB\xBFOFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
        Format::Off,
    );
    assert_eq!((m.num_vertices(), m.num_faces()), (3, 1));
}

#[test]
fn obj_large_polygon() {
    let n = 1000;
    let mut text = String::new();
    for i in 0..n {
        let a = i as f64 / n as f64 * std::f64::consts::TAU;
        text += &format!("v {} {} 0\n", a.cos(), a.sin());
    }
    text += "f";
    for i in 1..=n {
        text += &format!(" {i}");
    }
    let m = read(text.as_bytes(), Format::Obj);
    assert_eq!(m.face_arity(0), n);
    text += " 7";
    assert_error(&text, Format::Obj, &["line 1001", "face 1", "vertex 7"]);
}

#[test]
fn obj_errors_name_line_and_element() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases: &[(&str, &[&str])] = &[
        (
            "v 0 0 0\nv 1.2.3 0 0\n",
            &["line 2", "vertex 2", "`1.2.3`", "number"],
        ),
        (
            "v 0 0 0\nv 1 nan 0\n",
            &["line 2", "vertex 2", "not finite"],
        ),
        (
            "v 0 0 0\nv 1 1e999 0\n",
            &["line 2", "vertex 2", "not finite"],
        ),
        ("v 0 0\n", &["line 1", "vertex 1", "found 2 values"]),
        ("v 0 0 0 1 1\n", &["line 1", "vertex 1", "found 5 values"]),
        (
            &format!("{tri}f 1 2 9\n"),
            &["line 4", "face 1", "vertex index 9 out of range (1..=3)"],
        ),
        (
            &format!("{tri}f 1 2 3\nf 1 2 0\n"),
            &["line 5", "face 2", "0"],
        ),
        (&format!("{tri}f 1 2 -4\n"), &["line 4", "face 1", "-4"]),
        (
            &format!("{tri}f 1 2\n"),
            &["line 4", "face 1", "2 vertices"],
        ),
        (&format!("{tri}f\n"), &["line 4", "face 1", "0 vertices"]),
        (
            &format!("{tri}f 1 2 1\n"),
            &["line 4", "face 1", "vertex 1", "more than once"],
        ),
        (
            &format!("{tri}f 1 -3 3\n"),
            &["line 4", "face 1", "more than once"],
        ),
        (&format!("{tri}f 1 2 x\n"), &["line 4", "face 1", "`x`"]),
        (
            &format!("{tri}f 1/1/1/1 2 3\n"),
            &["line 4", "face 1", "malformed corner"],
        ),
        (
            &format!("{tri}vt 0 0\nf 1/2 2/1 3/1\n"),
            &["line 5", "face 1", "texture coordinate index 2"],
        ),
        ("vt 0 x\n", &["line 1", "texture coordinate 1", "`x`"]),
        (
            &format!("{tri}t crease 2/1 0 1\n"),
            &["line 4", "crease tag", "announces 3 values, found 2"],
        ),
        (
            &format!("{tri}t crease 2/1 0 x 1\n"),
            &["line 4", "crease tag", "`x`"],
        ),
        (
            &format!("{tri}t crease 2/1 0 1 inf\n"),
            &["line 4", "crease tag", "not finite"],
        ),
        (
            &format!("{tri}t crease 1/1 0 1\n"),
            &["line 4", "crease tag", "even"],
        ),
        (
            &format!("{tri}t crease two 0 1 1\n"),
            &["line 4", "crease tag", "counts"],
        ),
        (
            &format!("{tri}t corner 1/1 3 1\n"),
            &["line 4", "corner tag", "vertex index 3 out of range"],
        ),
        (
            &format!("{tri}t crease 2/1 0 7 1\nv 0 0 1\n"),
            &["line 4", "crease tag", "7"],
        ),
        (&format!("{tri}t\n"), &["line 4", "tag"]),
    ];
    for (text, needles) in cases {
        assert_error(text, Format::Obj, needles);
    }
    // The earliest bad line wins when several are only detected at the end.
    let (loc, _) = parse_error(&format!("{tri}t corner 1/1 9 1\nf 1 2 9\n"), Format::Obj);
    assert_eq!(loc, Location::Line(4));
    let (loc, msg) = parse_error(&format!("{tri}f 1 2 9\nt corner 1/1 9 1\n"), Format::Obj);
    assert_eq!(loc, Location::Line(4));
    assert!(msg.contains("face 1"));
}

#[test]
fn obj_error_for_vertex_index_in_big_file_matches_brief() {
    let mut text = String::new();
    for i in 0..5000 {
        text += &format!("v {i} 0 0\n");
    }
    for _ in 0..2 {
        text += "f 1 2 3\n";
    }
    text += "f 1 2 9999\n";
    let (_, msg) = parse_error(&text, Format::Obj);
    assert!(
        msg.ends_with("line 5003: face 3: vertex index 9999 out of range (1..=5000)"),
        "{msg}"
    );
}

// ---------------------------------------------------------------------------------------------
// OFF

#[test]
fn off_round_trip() {
    let m = awkward_mesh();
    let back = read(&write(&m, Format::Off), Format::Off);
    assert_eq!(bits(&back), bits(&m));
    assert_eq!(back.face_offsets, m.face_offsets);
    assert_eq!(back.face_indices, m.face_indices);
    assert!(back.edge_tags.is_empty(), "OFF has no tags");

    let mut m = with_colors(awkward_mesh());
    m.uvs = Some(
        (0..m.num_vertices())
            .map(|i| [i as f64 / 3.0, -1.0])
            .collect(),
    );
    m.edge_tags.clear();
    m.vertex_tags.clear();
    let text = write(&m, Format::Off);
    assert!(text.starts_with(b"STCOFF\n"));
    assert_eq!(read(&text, Format::Off), m);
}

#[test]
fn off_variants() {
    let m = read(
        b"OFF 3 1 0\n# comment\n0 0 0\n1 0 0\n\n0 1 0\n3 0 1 2 255 0 0\n",
        Format::Off,
    );
    assert_eq!((m.num_vertices(), m.num_faces()), (3, 1));
    let m = read(
        b"COFF\n3 1 3\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n",
        Format::Off,
    );
    assert_eq!(m.colors.as_ref().unwrap()[1], [0.0, 1.0, 0.0]);
    let m = read(
        b"NOFF\n3 1 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n",
        Format::Off,
    );
    assert_eq!(m.positions[1], DVec3::X);
    let m = read(
        b"CNOFF\n3 1 3\n0 0 0 0 0 1 0.5 0.5 0.5 1\n1 0 0 0 0 1 1 1 1 1\n0 1 0 0 0 1 0.0 0 0 1\n3 0 1 2\n",
        Format::Off,
    );
    assert_eq!(m.colors.as_ref().unwrap()[0], [0.5, 0.5, 0.5]);
    assert_eq!(m.colors.as_ref().unwrap()[2], [0.0, 0.0, 0.0]);
}

#[test]
fn off_errors() {
    let cases: &[(&str, &[&str])] = &[
        ("", &["file", "empty"]),
        ("PLY\n", &["line 1", "not an OFF file"]),
        ("4OFF\n", &["line 1", "not supported"]),
        ("OFF BINARY\n", &["line 1", "binary"]),
        ("OFF\n3\n", &["line 2", "counts"]),
        ("OFF\n3 x 0\n", &["line 2", "`x`"]),
        (
            "OFF\n1000000000 1 0\n0 0 0\n",
            &["line 2", "1000000000 vertices"],
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1.0 0.0\n0 1 0\n3 0 1 2\n",
            &["line 4", "vertex 2", "found 2 values"],
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1 0 x\n0 1 0\n3 0 1 2\n",
            &["line 4", "vertex 2", "`x`"],
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n",
            &["line 4", "vertex 2", "not finite"],
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
            &["line 6", "face 1", "index 3 out of range (0..=2)"],
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n",
            &["line 6", "face 1", "-1"],
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n",
            &["line 6", "face 1", "2 vertices"],
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n",
            &["line 6", "face 1", "lists 3"],
        ),
        (
            "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 1\n",
            &["line 6", "face 1", "more than once"],
        ),
        (
            "OFF\n3 30 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
            &["line 2", "30 faces"],
        ),
        (
            "OFF\n3 2 0\n0.000000 0 0\n1.000000 0 0\n0.000000 1 0\n3 0 1 2\n",
            &["file", "1 of 2 faces"],
        ),
    ];
    for (text, needles) in cases {
        assert_error(text, Format::Off, needles);
    }
}

// ---------------------------------------------------------------------------------------------
// PLY

#[test]
fn ply_round_trip() {
    let mut m = with_colors(awkward_mesh());
    m.edge_tags.clear();
    m.vertex_tags.clear();
    m.uvs = Some(
        (0..m.num_vertices())
            .map(|i| [i as f64 * 0.1, 0.7])
            .collect(),
    );
    let bytes = write(&m, Format::Ply);
    let back = read(&bytes, Format::Ply);
    assert_eq!(bits(&back), bits(&m));
    assert_eq!(back, m);
}

/// More vertices and faces than one serialization chunk (16,384), triangles and quads mixed,
/// with colours: the parallel writer keeps the order.
#[test]
fn ply_round_trip_across_chunks() {
    let n = 40_000u32;
    let positions = (0..2 * n + 2)
        .map(|i| {
            DVec3::new(
                f64::from(i) * 0.25,
                f64::from(i % 2),
                f64::from(i % 7) / 3.0,
            )
        })
        .collect();
    let faces: Vec<Vec<u32>> = (0..n)
        .map(|i| {
            let a = 2 * i;
            if i % 5 == 0 {
                vec![a, a + 1, a + 3, a + 2]
            } else {
                vec![a, a + 1, a + 2]
            }
        })
        .collect();
    let mut m = Mesh::from_faces(positions, faces);
    m.colors = Some(
        (0..m.num_vertices())
            .map(|i| [(i % 256) as f32 / 255.0, 1.0, (i * 7 % 256) as f32 / 255.0])
            .collect(),
    );
    let bytes = write(&m, Format::Ply);
    let back = read(&bytes, Format::Ply);
    assert_eq!(bits(&back), bits(&m));
    assert_eq!(back, m);
}

#[test]
fn ply_wide_faces_use_uint_counts() {
    let n = 300u32;
    let positions = (0..n).map(|i| DVec3::new(f64::from(i), 0.0, 0.0)).collect();
    let face: Vec<u32> = (0..n).collect();
    let m = Mesh::from_faces(positions, [face]);
    let bytes = write(&m, Format::Ply);
    let needle = b"property list uint uint vertex_indices";
    assert!(bytes.windows(needle.len()).any(|w| w == needle));
    assert_eq!(read(&bytes, Format::Ply), m);
}

const ASCII_PLY: &str = "\
ply
format ascii 1.0
comment a square and a triangle
element vertex 5
property float x
property float y
property float z
property uchar red
property uchar green
property uchar blue
property float nx
element edge 1
property int vertex1
property int vertex2
element face 2
property uchar flags
property list uchar int vertex_indices
property list uchar float texcoord
end_header
0 0 0 255 0 0 1
1 0 0 0 255 0 1
1 1 0 0 0 255 1
0 1 0 0 0 0 1
2 2 2 255 255 255 1
0 1
7 4 0 1 2 3 0
9 3 2 1 4 6 0 0 1 1 0.5 0.5
";

#[test]
fn ply_ascii_with_skipped_elements_and_lists() {
    let m = read(ASCII_PLY.as_bytes(), Format::Ply);
    assert_eq!((m.num_vertices(), m.num_faces()), (5, 2));
    assert_eq!(m.face(0), &[0, 1, 2, 3]);
    assert_eq!(m.face(1), &[2, 1, 4]);
    assert_eq!(m.colors.as_ref().unwrap()[2], [0.0, 0.0, 1.0]);
}

#[test]
fn ply_binary_big_endian_and_varied_types() {
    let mut b = b"ply\r\nformat binary_big_endian 1.0\r\nelement vertex 3\r\nproperty short x\r\n\
property double y\r\nproperty float z\r\nproperty float red\r\nproperty float green\r\n\
property float blue\r\nelement face 1\r\nproperty list int ushort vertex_index\r\nend_header\r\n"
        .to_vec();
    for (i, (x, y, z)) in [(0i16, 0.0f64, 0.0f32), (1, 0.0, 0.0), (0, 1.5, -2.0)]
        .into_iter()
        .enumerate()
    {
        b.extend_from_slice(&x.to_be_bytes());
        b.extend_from_slice(&y.to_be_bytes());
        b.extend_from_slice(&z.to_be_bytes());
        for c in [0.25f32, 0.5, i as f32] {
            b.extend_from_slice(&c.to_be_bytes());
        }
    }
    b.extend_from_slice(&3i32.to_be_bytes());
    for v in [0u16, 1, 2] {
        b.extend_from_slice(&v.to_be_bytes());
    }
    let m = read(&b, Format::Ply);
    assert_eq!(m.positions[2], DVec3::new(0.0, 1.5, -2.0));
    assert_eq!(m.colors.as_ref().unwrap()[1], [0.25, 0.5, 1.0]);
    assert_eq!(m.face(0), &[0, 1, 2]);
}

#[test]
fn ply_errors() {
    let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let verts = "0 0 0\n1 0 0\n0 1 0\n";
    let cases: Vec<(String, Vec<&str>)> = vec![
        ("plyx\n".into(), vec!["line 1", "not a PLY file"]),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n".into(), vec!["end_header"]),
        ("ply\nformat utf8 1.0\nend_header\n".into(), vec!["line 2", "unknown format"]),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n".into(), vec!["line 4", "quad"]),
        ("ply\nformat ascii 1.0\nproperty float x\nend_header\n".into(), vec!["line 3", "before any `element`"]),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n".into(), vec!["line 3", "`z`"]),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar float vertex_indices\nend_header\n".into(), vec!["line 8", "integer"]),
        (format!("{head}0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n"), vec!["line 11", "vertex 2", "`x`"]),
        (format!("{head}0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n"), vec!["line 11", "vertex 2", "not finite"]),
        (format!("{head}{verts}3 0 1 3\n"), vec!["line 13", "face 1", "index 3 out of range (0..=2)"]),
        (format!("{head}{verts}2 0 1\n"), vec!["line 13", "face 1", "2 vertices"]),
        (format!("{head}{verts}3 0 1 1\n"), vec!["line 13", "face 1", "more than once"]),
        (format!("{head}{verts}3 0 1\n"), vec!["file", "face 1", "ends early"]),
        (format!("{head}0 0 0\n1 0 0\n"), vec!["line 3", "vertex", "announces 3 entries"]),
        (head.replace("vertex 3", "vertex 3000"), vec!["line 3", "vertex", "3000 entries"]),
    ];
    for (text, needles) in &cases {
        assert_error(text, Format::Ply, needles);
    }
}

#[test]
fn ply_binary_errors_give_byte_offsets() {
    let m = Mesh::from_triangles(vec![DVec3::ZERO, DVec3::X, DVec3::Y], &[[0, 1, 2]]);
    let mut bytes = write(&m, Format::Ply);
    let n = bytes.len();
    // The last index (u32 LE) is the last 4 bytes; make it out of range.
    bytes[n - 4] = 7;
    match io::read_mesh_bytes(&bytes, Format::Ply, "b.ply") {
        Err(Error::Parse {
            location: Location::Byte(off),
            message,
            ..
        }) => {
            assert_eq!(off, n - 4);
            assert!(
                message.contains("face 1") && message.contains("7"),
                "{message}"
            );
        }
        other => panic!("{other:?}"),
    }
    // A huge list count is caught before reading or allocating.
    let header_end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let face_at = header_end + 3 * 24;
    bytes[face_at] = 255;
    let e = io::read_mesh_bytes(&bytes, Format::Ply, "b.ply").unwrap_err();
    assert!(
        e.to_string().contains(&format!("byte {}", face_at + 1)) || e.to_string().contains("list"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------------
// STL

const CUBE: [[u32; 3]; 12] = [
    [0, 1, 2],
    [0, 2, 3],
    [4, 5, 6],
    [4, 6, 7],
    [0, 1, 5],
    [0, 5, 4],
    [1, 2, 6],
    [1, 6, 5],
    [2, 3, 7],
    [2, 7, 6],
    [3, 0, 4],
    [3, 4, 7],
];

fn cube() -> Mesh {
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    Mesh::from_triangles(
        vec![
            p(0.0, 0.0, 0.0),
            p(1.0, 0.0, 0.0),
            p(1.0, 1.0, 0.0),
            p(0.0, 1.0, 0.0),
            p(0.0, 0.0, 1.0),
            p(1.0, 0.0, 1.0),
            p(1.0, 1.0, 1.0),
            p(0.0, 1.0, 1.0),
        ],
        &CUBE,
    )
}

fn ascii_stl(m: &Mesh) -> String {
    let mut s = String::from("solid cube exported\n");
    for f in m.faces() {
        s += "  facet normal 0 0 0\n    outer loop\n";
        for &v in f {
            let p = m.positions[v as usize];
            // Write zeros as -0 on odd vertices: they must still weld.
            let z = |x: f64| {
                if x == 0.0 && v % 2 == 1 {
                    "-0".to_string()
                } else {
                    format!("{x:e}")
                }
            };
            s += &format!("      vertex {} {} {}\n", z(p.x), z(p.y), z(p.z));
        }
        s += "    endloop\n  endfacet\n";
    }
    s + "endsolid cube exported\n"
}

#[test]
fn stl_ascii_and_binary_weld_a_cube() {
    let m = cube();
    let a = read(ascii_stl(&m).as_bytes(), Format::Stl);
    assert_eq!((a.num_vertices(), a.num_faces()), (8, 12));
    assert_eq!(a, m, "vertices in order of first appearance");
    let mut b = write(&m, Format::Stl);
    assert_eq!(b.len(), 84 + 50 * 12);
    let back = read(&b, Format::Stl);
    assert_eq!((back.num_vertices(), back.num_faces()), (8, 12));
    assert_eq!(back, m);
    // A binary header that starts with "solid" is still binary, by its size.
    b[..5].copy_from_slice(b"solid");
    assert_eq!(read(&b, Format::Stl), m);
    // Upper case keywords and two solids in one file.
    let two = ascii_stl(&m).to_uppercase() + &ascii_stl(&m);
    let t = read(two.as_bytes(), Format::Stl);
    assert_eq!((t.num_vertices(), t.num_faces()), (8, 24));
}

#[test]
fn stl_errors() {
    let facet = |a: &str, b: &str, c: &str| {
        format!("facet normal 0 0 1\nouter loop\nvertex {a}\nvertex {b}\nvertex {c}\nendloop\nendfacet\n")
    };
    let good = facet("0 0 0", "1 0 0", "0 1 0");
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            format!(
                "solid x\n{good}{}endsolid x\n",
                facet("0 0 0", "1 0 0", "-0 0 0")
            ),
            vec!["line 9", "facet 2 has two identical vertices"],
        ),
        (
            format!("solid x\n{}endsolid\n", facet("0 0 0", "1 nan 0", "0 1 0")),
            vec!["line 5", "facet 1", "non-finite"],
        ),
        (
            format!("solid x\n{}endsolid\n", facet("0 0 0", "1 y 0", "0 1 0")),
            vec!["line 5", "facet 1", "`y`"],
        ),
        (
            format!("solid x\n{good}"),
            vec!["line 9", "`endsolid`", "end of the file"],
        ),
        (
            "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n".into(),
            vec!["line 6", "facet 1", "`endloop`"],
        ),
        (
            format!(
                "solid x\n{}",
                good.replace("endloop", "vertex 1 1 1\nendloop")
            ),
            vec!["line 7", "facet 1", "more than 3"],
        ),
        ("hello".into(), vec!["file", "not an STL file"]),
    ];
    for (text, needles) in &cases {
        assert_error(text, Format::Stl, needles);
    }
    let mut b = write(&cube(), Format::Stl);
    // Make facet 3's second vertex equal to its first.
    let f3 = 84 + 2 * 50;
    let first: Vec<u8> = b[f3 + 12..f3 + 24].to_vec();
    b[f3 + 24..f3 + 36].copy_from_slice(&first);
    match io::read_mesh_bytes(&b, Format::Stl, "c.stl") {
        Err(Error::Parse {
            location: Location::Byte(off),
            message,
            ..
        }) => {
            assert_eq!(off, f3);
            assert!(message.contains("facet 3 has two identical vertices"));
        }
        other => panic!("{other:?}"),
    }
    // Truncated binary that does not start with `solid`.
    let e = io::read_mesh_bytes(&b[..500], Format::Stl, "c.stl").unwrap_err();
    assert!(e.to_string().contains("12 triangles"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// GLB

#[test]
fn glb_parses_back_with_the_gltf_crate() {
    let mut m = with_colors(awkward_mesh());
    // Keep coordinates within f32 range for GLB.
    for p in &mut m.positions {
        *p = p.clamp(DVec3::splat(-1e6), DVec3::splat(1e6));
    }
    let bytes = write(&m, Format::Glb);
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(u32::from_le_bytes(bytes[4..8].try_into().unwrap()), 2);
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
        bytes.len()
    );
    assert_eq!(bytes.len() % 4, 0);
    let g = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = g.blob.clone().unwrap();
    assert_eq!(g.scenes().count(), 1);
    assert_eq!(g.nodes().count(), 1);
    let mesh = g.meshes().next().unwrap();
    let prim = mesh.primitives().next().unwrap();
    assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
    let pos = prim.get(&gltf::Semantic::Positions).unwrap();
    assert_eq!(pos.count(), m.num_vertices());
    assert!(pos.min().is_some() && pos.max().is_some());
    let reader = prim.reader(|_| Some(&blob[..]));
    let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    for (a, b) in positions.iter().zip(&m.positions) {
        assert_eq!(*a, b.to_array().map(|x| x as f32));
    }
    let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
    assert_eq!(normals.len(), m.num_vertices());
    for n in &normals {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5, "{n:?}");
    }
    let colors: Vec<[f32; 3]> = reader.read_colors(0).unwrap().into_rgb_f32().collect();
    assert_eq!(colors, *m.colors.as_ref().unwrap());
    let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    let (tris, _) = m.triangulate();
    assert_eq!(indices, tris.iter().flatten().copied().collect::<Vec<_>>());
    assert_eq!(indices.len(), 3 * (2 + 1 + 3));
}

#[test]
fn glb_rejects_coordinates_beyond_f32() {
    let m = awkward_mesh();
    assert!(matches!(
        io::write_mesh_to(&m, Format::Glb, &mut Vec::new()),
        Err(Error::InvalidArgument(_))
    ));
}
