//! Reads the shared test corpus (`../shared/data/meshes` beside the checkout), if present.
//! Skipped silently where the folder is absent. Corpus files are never copied into the repo.

use std::path::PathBuf;
use std::time::Instant;

use subwave::io::{self, Format};
use subwave::Mesh;

fn corpus() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/meshes");
    dir.is_dir().then_some(dir)
}

/// (file, `v` lines, faces, quads) from the corpus README.
const EXPECTED: &[(&str, usize, usize, usize)] = &[
    ("stanford-bunny.obj", 35_947, 69_451, 0),
    ("suzanne.obj", 507, 500, 468),
    ("beetle.obj", 1_148, 2_053, 0),
    ("fandisk.obj", 6_475, 12_946, 0),
    ("rocker-arm.obj", 10_044, 20_088, 0),
    ("spot.obj", 2_930, 5_856, 0),
    ("teapot.obj", 3_644, 6_320, 0),
    ("cow.obj", 2_903, 5_804, 0),
    ("woody.obj", 694, 1_267, 0),
    ("cheburashka.obj", 6_669, 13_334, 0),
];

#[test]
fn corpus_objs_read_with_the_documented_counts() {
    let Some(dir) = corpus() else { return };
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("obj") {
            continue;
        }
        let m = io::read_mesh(&path, None).unwrap_or_else(|e| panic!("{e}"));
        m.check_indices().unwrap();
        let name = path.file_name().unwrap().to_str().unwrap();
        if let Some(&(_, v, f, quads)) = EXPECTED.iter().find(|e| e.0 == name) {
            assert_eq!((m.num_vertices(), m.num_faces()), (v, f), "{name}");
            let n4 = (0..m.num_faces()).filter(|&i| m.face_arity(i) == 4).count();
            let n3 = (0..m.num_faces()).filter(|&i| m.face_arity(i) == 3).count();
            assert_eq!((n4, n3), (quads, f - quads), "{name}");
            seen += 1;
        }
        // Every writer accepts a real mesh, and OBJ/PLY give it back exactly.
        for f in [Format::Obj, Format::Ply] {
            let mut bytes = Vec::new();
            io::write_mesh_to(&m, f, &mut bytes).unwrap();
            let back = io::read_mesh_bytes(&bytes, f, name).unwrap();
            assert_eq!(back.positions, m.positions, "{name} via {f}");
            assert_eq!(back.face_indices, m.face_indices, "{name} via {f}");
        }
    }
    assert!(seen >= 3, "expected the corpus files named in the README");
    let spot = io::read_mesh(&dir.join("spot.obj"), None).unwrap();
    let fv = spot
        .face_uvs
        .expect("spot.obj has texture coordinates on every corner");
    assert_eq!(fv.coords.len(), 3_225);
}

/// `cargo test --release -p subwave --test io_corpus -- --ignored --nocapture`
#[test]
#[ignore = "timing; run in release"]
fn bunny_parse_time() {
    let Some(dir) = corpus() else { return };
    let bytes = std::fs::read(dir.join("stanford-bunny.obj")).unwrap();
    let mut best = f64::INFINITY;
    let mut m = Mesh::new();
    for _ in 0..20 {
        let t = Instant::now();
        m = io::read_mesh_bytes(&bytes, Format::Obj, "bunny").unwrap();
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!(
        "bunny: {} vertices, {} faces, {} bytes, best of 20: {:.2} ms",
        m.num_vertices(),
        m.num_faces(),
        bytes.len(),
        best * 1e3
    );
}
