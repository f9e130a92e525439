//! End-to-end tests of the `subwave` executable: exit codes, error messages, `info --json` on
//! generated meshes and on the shared corpus, `convert` round trips and `demo`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use serde_json::Value;
use subwave::io::{write_mesh, Format};
use subwave::{generate, DVec3, Mesh};

/// Runs `subwave` with `args` (no standard input) and returns its output.
fn run(args: &[&str]) -> Output {
    run_in(None, args)
}

/// Runs `subwave` in `dir` (or the test's working directory).
fn run_in(dir: Option<&Path>, args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_subwave"));
    cmd.args(args).stdin(Stdio::null()).env_remove("RUST_LOG");
    if let Some(d) = dir {
        cmd.current_dir(d);
    }
    cmd.output().expect("cannot start the subwave executable")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts success and returns standard output.
fn ok(args: &[&str]) -> String {
    let o = run(args);
    assert_eq!(
        o.status.code(),
        Some(0),
        "subwave {args:?} failed:\n{}",
        stderr(&o)
    );
    stdout(&o)
}

/// Asserts that `subwave args` exits 1 with exactly one line `error: ...` on standard error,
/// and returns that line.
fn fails(args: &[&str]) -> String {
    let o = run(args);
    let err = stderr(&o);
    assert_eq!(
        o.status.code(),
        Some(1),
        "subwave {args:?}: expected exit 1, stderr:\n{err}"
    );
    assert!(
        !err.contains("panicked"),
        "subwave {args:?} panicked:\n{err}"
    );
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(
        lines.len(),
        1,
        "subwave {args:?}: expected one line on stderr, got:\n{err}"
    );
    assert!(lines[0].starts_with("error: "), "subwave {args:?}: {err}");
    lines[0].to_string()
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("cannot create a temporary folder")
}

/// Writes `contents` to `dir/name` and returns the path as a string.
fn file(dir: &Path, name: &str, contents: &[u8]) -> String {
    let p = dir.join(name);
    std::fs::write(&p, contents).unwrap();
    p.to_str().unwrap().to_string()
}

fn info_json(path: &str) -> Value {
    let out = ok(&["info", "--json", path]);
    serde_json::from_str(&out)
        .unwrap_or_else(|e| panic!("info --json {path}: not JSON ({e}):\n{out}"))
}

fn field(j: &Value, key: &str) -> i64 {
    j[key]
        .as_i64()
        .unwrap_or_else(|| panic!("no integer `{key}` in {j}"))
}

// ---------------------------------------------------------------------------------------------
// Bad input: exit 1, one line naming the element and, for text files, the line.

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

#[test]
fn obj_face_index_out_of_range_names_the_line() {
    let d = tmp();
    let p = file(
        d.path(),
        "bad.obj",
        format!("{TRIANGLE}f 1 2 4\n").as_bytes(),
    );
    let e = fails(&["info", &p]);
    assert!(e.contains("line 4"), "{e}");
    assert!(e.contains("bad.obj"), "{e}");
    assert!(e.contains("face") && e.contains('4'), "{e}");
    // convert checks the same way and writes nothing.
    let out = d.path().join("out.ply");
    fails(&["convert", &p, out.to_str().unwrap()]);
    assert!(!out.exists());
}

#[test]
fn obj_nan_coordinate() {
    let d = tmp();
    let p = file(
        d.path(),
        "nan.obj",
        b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n",
    );
    let e = fails(&["info", &p]);
    assert!(e.contains("line 2"), "{e}");
    assert!(e.contains("vertex"), "{e}");
}

#[test]
fn obj_face_with_two_vertices() {
    let d = tmp();
    let p = file(d.path(), "two.obj", format!("{TRIANGLE}f 1 2\n").as_bytes());
    let e = fails(&["info", &p]);
    assert!(e.contains("line 4"), "{e}");
    assert!(e.contains("face"), "{e}");
}

#[test]
fn off_garbage_line() {
    let d = tmp();
    let p = file(
        d.path(),
        "bad.off",
        b"OFF\n3 1 0\n0 0 0\n1 0 0\nhello world\n3 0 1 2\n",
    );
    let e = fails(&["info", &p]);
    assert!(e.contains("line 5"), "{e}");
    assert!(e.contains("vertex"), "{e}");
}

#[test]
fn truncated_binary_ply() {
    let d = tmp();
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
                      property float y\nproperty float z\nelement face 1\n\
                      property list uchar int vertex_indices\nend_header\n"
        .to_vec();
    bytes.extend_from_slice(&[0u8; 6]); // half a vertex
    let p = file(d.path(), "cut.ply", &bytes);
    let e = fails(&["info", &p]);
    assert!(e.contains("cut.ply"), "{e}");
    assert!(e.contains("vertex"), "{e}");
}

#[test]
fn empty_files() {
    let d = tmp();
    for ext in ["off", "ply", "stl"] {
        let p = file(d.path(), &format!("empty.{ext}"), b"");
        let e = fails(&["info", &p]);
        assert!(e.contains(&format!("empty.{ext}")), "{e}");
    }
}

/// A zero-byte OBJ is an empty file, not an empty mesh (needs the OBJ reader to reject it).
#[test]
fn empty_obj_file() {
    let d = tmp();
    let p = file(d.path(), "empty.obj", b"");
    let e = fails(&["info", &p]);
    assert!(e.contains("empty.obj"), "{e}");
}

/// Files that parse to nothing (zero bytes, binary junk in an OBJ, whose unknown statements
/// the reader skips) or to vertices only are refused by the commands that need content or
/// faces, instead of being written out as empty meshes.
#[test]
fn contentless_files_are_refused() {
    let d = tmp();
    let empty = file(d.path(), "empty.obj", b"");
    let mut junk_bytes: Vec<u8> = (0u32..3000)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    junk_bytes.retain(|&b| b != b'\n');
    let junk = file(d.path(), "junk.obj", &junk_bytes);
    let points = file(d.path(), "points.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    let out = d.path().join("out.obj");
    let out = out.to_str().unwrap();
    for p in [&empty, &junk] {
        for args in [
            vec!["subdivide", p, "-o", out, "--levels", "1"],
            vec!["bench", "subdivide", p, "--levels", "1"],
            vec!["convert", p, out],
            vec!["compress-base", p, "-o", out],
        ] {
            let e = fails(&args);
            assert!(
                e.contains(p.as_str()) && e.contains("no vertices and no faces"),
                "{args:?}: {e}"
            );
        }
    }
    for args in [
        vec!["subdivide", &points, "-o", out, "--levels", "1"],
        vec!["bench", "subdivide", &points, "--levels", "1"],
    ] {
        let e = fails(&args);
        assert!(
            e.contains("points.obj") && e.contains("no faces (3 vertices only)"),
            "{args:?}: {e}"
        );
    }
    assert!(!Path::new(out).exists(), "nothing is written");
    // A point cloud still converts.
    ok(&["convert", &points, out]);
}

/// A refinement too large for the memory (or for 32-bit indices) is refused before it
/// starts, naming the face count and asking for fewer levels, and a dihedral angle outside
/// 0–180 degrees (or not a number) is refused by the argument parser.
#[test]
fn oversized_refinement_and_bad_angles_are_refused() {
    let d = tmp();
    let p = put(d.path(), "sphere.obj", &generate::icosphere(2));
    let out = d.path().join("out.obj");
    let out = out.to_str().unwrap();
    // 320 faces: 12 levels are 5.4e9 faces.
    for args in [
        vec!["subdivide", &p, "-o", out, "--levels", "12"],
        vec!["bench", "subdivide", &p, "--levels", "12"],
    ] {
        let e = fails(&args);
        assert!(
            e.contains("sphere.obj")
                && e.contains("5368709120 faces")
                && e.contains("use fewer levels"),
            "{args:?}: {e}"
        );
    }
    assert!(!Path::new(out).exists());
    for angle in ["nan", "181", "inf"] {
        for cmd in ["subdivide", "remesh", "encode"] {
            let o = run(&[cmd, &p, "-o", out, "--sharp-angle", angle]);
            assert_eq!(o.status.code(), Some(2), "{cmd} --sharp-angle {angle}");
            assert!(stderr(&o).contains("from 0 to 180"), "{}", stderr(&o));
        }
    }
}

/// `compress-base` refuses a non-manifold mesh, naming the vertex; with `--repair` it codes
/// the mesh with the vertex split (one more vertex, decoded as a manifold mesh) and reports
/// the repair, and a manifold mesh is coded exactly as without `--repair`.
#[test]
fn compress_base_repairs_non_manifold_meshes_on_request() {
    let d = tmp();
    // Two fans of three triangles around vertex 0 (a double cone's waist pinched to a point).
    let mut text = String::from("v 0 0 0\n");
    for k in 0..3 {
        let a = k as f64 * 2.0944;
        text += &format!("v {} {} 1\n", a.cos(), a.sin());
    }
    for k in 0..3 {
        let a = k as f64 * 2.0944 + 0.5;
        text += &format!("v {} {} -1\n", a.cos(), a.sin());
    }
    text += "f 1 2 3\nf 1 3 4\nf 1 4 2\nf 1 6 5\nf 1 7 6\nf 1 5 7\n";
    let bowtie = file(d.path(), "bowtie.obj", text.as_bytes());
    let out = d.path().join("b.swb");
    let out = out.to_str().unwrap();
    let e = fails(&["compress-base", &bowtie, "-o", out]);
    assert!(
        e.contains("bowtie.obj") && e.contains("non-manifold") && e.contains("pass --repair"),
        "{e}"
    );
    let j: Value = serde_json::from_str(&ok(&[
        "compress-base",
        &bowtie,
        "-o",
        out,
        "--repair",
        "--json",
    ]))
    .unwrap();
    assert_eq!(j["input_vertices"], 7, "{j}");
    assert_eq!(j["vertices"], 8, "{j}");
    assert_eq!(j["repair"]["non_manifold_vertices"], 1, "{j}");
    let dec = d.path().join("b.obj");
    let dec = dec.to_str().unwrap();
    ok(&["decompress-base", out, "-o", dec]);
    let info = info_json(dec);
    assert_eq!(info["vertices"], 8, "{info}");
    assert_eq!(info["non_manifold_vertices"], 0, "{info}");
    // A manifold mesh: the same stream with or without --repair.
    let sphere = put(d.path(), "sphere.obj", &generate::icosphere(2));
    let (a, b) = (d.path().join("a.swb"), d.path().join("b2.swb"));
    ok(&["compress-base", &sphere, "-o", a.to_str().unwrap()]);
    let j: Value = serde_json::from_str(&ok(&[
        "compress-base",
        &sphere,
        "-o",
        b.to_str().unwrap(),
        "--repair",
        "--json",
    ]))
    .unwrap();
    assert!(j["repair"].is_null(), "{j}");
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn missing_file() {
    let d = tmp();
    let p = d.path().join("nowhere.obj");
    let e = fails(&["info", p.to_str().unwrap()]);
    assert!(e.contains("nowhere.obj"), "{e}");
    let e = fails(&[
        "convert",
        p.to_str().unwrap(),
        d.path().join("x.ply").to_str().unwrap(),
    ]);
    assert!(e.contains("nowhere.obj"), "{e}");
}

#[test]
fn unknown_extension() {
    let d = tmp();
    let p = file(d.path(), "mesh.xyz", TRIANGLE.as_bytes());
    let e = fails(&["info", &p]);
    assert!(e.contains("mesh.xyz") && e.contains("extension"), "{e}");
    // --format overrides the extension.
    let j: Value = serde_json::from_str(&ok(&["info", "--json", "--format", "obj", &p])).unwrap();
    assert_eq!(field(&j, "vertices"), 3);
    // Writing to an unknown extension fails too.
    let good = file(
        d.path(),
        "good.obj",
        format!("{TRIANGLE}f 1 2 3\n").as_bytes(),
    );
    fails(&["convert", &good, d.path().join("out.xyz").to_str().unwrap()]);
}

#[test]
fn standard_input_needs_a_format() {
    let e = fails(&["info", "-"]);
    assert!(e.contains("format"), "{e}");
}

#[test]
fn glb_is_write_only() {
    let d = tmp();
    let p = file(d.path(), "mesh.glb", b"glTF");
    let e = fails(&["info", &p]);
    assert!(e.contains("GLB"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Usage errors: exit 2 (clap).

#[test]
fn usage_errors_exit_2() {
    for args in [
        &["frobnicate"][..],
        &[],
        &["info"],
        &["convert", "a.obj"],
        &["info", "--format", "xyz", "a.obj"],
        &["info", "--bogus", "a.obj"],
        &["demo", "--levels", "99"],
        &["demo", "--levels", "many"],
    ] {
        let o = run(args);
        assert_eq!(
            o.status.code(),
            Some(2),
            "subwave {args:?}:\n{}",
            stderr(&o)
        );
        assert!(!stderr(&o).contains("panicked"));
    }
}

#[test]
fn help_and_version_exit_0() {
    let h = ok(&["--help"]);
    for cmd in ["info", "convert", "demo"] {
        assert!(h.contains(cmd), "{h}");
        ok(&[cmd, "--help"]);
    }
    assert!(ok(&["--version"]).contains(env!("CARGO_PKG_VERSION")));
}

// ---------------------------------------------------------------------------------------------
// info on generated meshes.

/// Writes `mesh` as `dir/name` (format from the extension) and returns the path.
fn write(dir: &Path, name: &str, mesh: &Mesh) -> String {
    let p = dir.join(name);
    write_mesh(mesh, &p, None).unwrap();
    p.to_str().unwrap().to_string()
}

#[test]
fn info_json_generated_meshes() {
    let d = tmp();
    // (file, mesh, V, F, E, boundary edges, loops, components, χ, genus, nm edges, nm vertices)
    let cases: Vec<(&str, Mesh, [i64; 10], Option<u64>)> = vec![
        (
            "cube.obj",
            generate::cube(),
            [8, 6, 12, 0, 0, 1, 2, 0, 0, 0],
            Some(0),
        ),
        (
            "torus.ply",
            generate::torus(1.0, 0.3, 8, 6, false),
            [48, 48, 96, 0, 0, 1, 0, 0, 0, 0],
            Some(1),
        ),
        (
            "bowtie.off",
            generate::bowtie(),
            [5, 2, 6, 6, 1, 1, 1, 0, 1, 0],
            None,
        ),
        (
            "fin.obj",
            generate::fin(),
            [5, 3, 7, 6, 1, 1, 1, 1, 0, 0],
            None,
        ),
        (
            "grid.obj",
            generate::grid(3, 2, false),
            [12, 6, 17, 10, 1, 1, 1, 0, 0, 0],
            Some(0),
        ),
    ];
    let keys = [
        "vertices",
        "faces",
        "edges",
        "boundary_edges",
        "boundary_loops",
        "components",
        "euler_characteristic",
        "non_manifold_edges",
        "non_manifold_vertices",
        "unreferenced_vertices",
    ];
    for (name, mesh, expected, genus) in cases {
        let p = write(d.path(), name, &mesh);
        let j = info_json(&p);
        let got: Vec<i64> = keys.iter().map(|k| field(&j, k)).collect();
        assert_eq!(got, expected, "{name}: fields {keys:?}\n{j:#}");
        assert_eq!(j["genus"].as_u64(), genus, "{name}: genus");
        for k in [
            "bbox_min",
            "bbox_max",
            "valence_histogram",
            "faces_by_arity",
            "tags",
        ] {
            assert!(!j[k].is_null(), "{name}: no `{k}`");
        }
    }
}

#[test]
fn info_human_table() {
    let d = tmp();
    let p = write(d.path(), "pyramid.obj", &generate::pyramid());
    let out = ok(&["info", &p]);
    for needle in [
        "pyramid.obj (obj)",
        "vertices",
        "5 (5 referenced, 0 unreferenced)",
        "5 (4 triangles, 1 quad)",
        "edges",
        "Euler characteristic",
        "genus",
        "valence histogram",
        "bounding box min",
        "(-1, -1, 0)",
    ] {
        assert!(out.contains(needle), "missing `{needle}` in:\n{out}");
    }
    // The values start in one column: after the label and at least two spaces.
    let cols: Vec<usize> = out
        .lines()
        .skip(1)
        .filter_map(|l| l.strip_prefix("  "))
        .filter(|l| !l.starts_with(' '))
        .map(|l| {
            let gap = l.find("  ").expect("no gap after the label");
            gap + l[gap..].len() - l[gap..].trim_start().len()
        })
        .collect();
    assert!(cols.len() > 10, "{out}");
    assert!(
        cols.iter().all(|&c| c == cols[0]),
        "values not aligned: {cols:?}\n{out}"
    );
}

// ---------------------------------------------------------------------------------------------
// The shared corpus: counts of ../shared/data/meshes/README.md.

fn corpus_dir() -> Option<PathBuf> {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/meshes");
    d.is_dir().then_some(d)
}

/// Expected counts of one corpus row; `None` where the table gives no exact value.
struct Row {
    file: &'static str,
    vertices: i64,
    unreferenced: i64,
    faces: i64,
    edges: i64,
    boundary_edges: i64,
    boundary_loops: Option<i64>,
    nm_edges: i64,
    nm_vertices: i64,
    components: i64,
    euler: i64,
}

#[rustfmt::skip]
const CORPUS: &[Row] = &[
    Row { file: "stanford-bunny.obj", vertices: 35_947, unreferenced: 1_113, faces: 69_451, edges: 104_288, boundary_edges: 223, boundary_loops: Some(5), nm_edges: 0, nm_vertices: 0, components: 1, euler: -3 },
    Row { file: "fandisk.obj", vertices: 6_475, unreferenced: 0, faces: 12_946, edges: 19_419, boundary_edges: 0, boundary_loops: Some(0), nm_edges: 0, nm_vertices: 0, components: 1, euler: 2 },
    Row { file: "rocker-arm.obj", vertices: 10_044, unreferenced: 0, faces: 20_088, edges: 30_132, boundary_edges: 0, boundary_loops: Some(0), nm_edges: 0, nm_vertices: 0, components: 1, euler: 0 },
    Row { file: "spot.obj", vertices: 2_930, unreferenced: 0, faces: 5_856, edges: 8_784, boundary_edges: 0, boundary_loops: Some(0), nm_edges: 0, nm_vertices: 0, components: 1, euler: 2 },
    Row { file: "suzanne.obj", vertices: 507, unreferenced: 0, faces: 500, edges: 1_005, boundary_edges: 42, boundary_loops: Some(4), nm_edges: 0, nm_vertices: 0, components: 3, euler: 2 },
    Row { file: "teapot.obj", vertices: 3_644, unreferenced: 0, faces: 6_320, edges: 9_998, boundary_edges: 1_036, boundary_loops: None, nm_edges: 0, nm_vertices: 38, components: 4, euler: -34 },
    Row { file: "cow.obj", vertices: 2_903, unreferenced: 0, faces: 5_804, edges: 8_706, boundary_edges: 0, boundary_loops: Some(0), nm_edges: 0, nm_vertices: 1, components: 1, euler: 1 },
    Row { file: "beetle.obj", vertices: 1_148, unreferenced: 0, faces: 2_053, edges: 3_204, boundary_edges: 296, boundary_loops: None, nm_edges: 47, nm_vertices: 0, components: 2, euler: -3 },
    Row { file: "woody.obj", vertices: 694, unreferenced: 0, faces: 1_267, edges: 1_960, boundary_edges: 119, boundary_loops: Some(1), nm_edges: 0, nm_vertices: 0, components: 1, euler: 1 },
    Row { file: "cheburashka.obj", vertices: 6_669, unreferenced: 0, faces: 13_334, edges: 20_001, boundary_edges: 0, boundary_loops: Some(0), nm_edges: 0, nm_vertices: 0, components: 1, euler: 2 },
];

#[test]
fn corpus_counts_match_the_readme_table() {
    let Some(dir) = corpus_dir() else {
        println!("note: no ../shared/data/meshes beside the checkout; corpus test skipped");
        return;
    };
    let mut mismatches = Vec::new();
    for row in CORPUS {
        let path = dir.join(row.file);
        let j = info_json(path.to_str().unwrap());
        let mut check = |key: &str, expected: i64| {
            let got = field(&j, key);
            if got != expected {
                mismatches.push(format!(
                    "{}: {key} expected {expected}, got {got} ({:+})",
                    row.file,
                    got - expected
                ));
            }
        };
        check("vertices", row.vertices);
        check("unreferenced_vertices", row.unreferenced);
        check("faces", row.faces);
        check("edges", row.edges);
        check("boundary_edges", row.boundary_edges);
        if let Some(loops) = row.boundary_loops {
            check("boundary_loops", loops);
        }
        check("non_manifold_edges", row.nm_edges);
        check("non_manifold_vertices", row.nm_vertices);
        check("components", row.components);
        check("euler_characteristic", row.euler);
        // The README's "duplicated seams": the teapot's patch rims, stored twice.
        check(
            "seam_vertices",
            if row.file == "teapot.obj" { 403 } else { 0 },
        );
        // The beetle's two slits between panels, two T-junctions each.
        check(
            "slit_vertices",
            if row.file == "beetle.obj" { 4 } else { 0 },
        );
        let loops = field(&j, "boundary_loops");
        match row.file {
            "teapot.obj" => {
                println!("teapot.obj: {loops} boundary loops (README: about 10)");
                if !(8..=12).contains(&loops) {
                    mismatches.push(format!(
                        "teapot.obj: boundary_loops expected 8..=12, got {loops}"
                    ));
                }
            }
            "beetle.obj" => println!("beetle.obj: {loops} boundary loops (README: not stated)"),
            _ => {}
        }
        if row.file == "suzanne.obj" {
            let arity = &j["faces_by_arity"];
            if (arity["4"].as_i64(), arity["3"].as_i64()) != (Some(468), Some(32)) {
                mismatches.push(format!(
                    "suzanne.obj: faces_by_arity expected 468 quads + 32 triangles, got {arity}"
                ));
            }
        }
    }
    assert!(
        mismatches.is_empty(),
        "corpus counts differ from the README table:\n{}",
        mismatches.join("\n")
    );
}

// ---------------------------------------------------------------------------------------------
// convert.

/// A pyramid (mixed quads and triangles) with one vertex no face uses.
fn pyramid_with_stray_vertex() -> Mesh {
    let mut m = generate::pyramid();
    m.positions.push(DVec3::new(5.0, 5.0, 5.0));
    m
}

#[test]
fn convert_round_trip_obj_ply_obj_preserves_counts() {
    let d = tmp();
    let src = write(
        d.path(),
        "src.obj",
        &generate::torus(1.0, 0.25, 12, 8, false),
    );
    let ply = d.path().join("mid.ply");
    let back = d.path().join("back.obj");
    let out = ok(&["convert", &src, ply.to_str().unwrap()]);
    assert!(out.contains("mid.ply"), "{out}");
    ok(&["convert", ply.to_str().unwrap(), back.to_str().unwrap()]);
    let (a, b) = (info_json(&src), info_json(back.to_str().unwrap()));
    for k in [
        "vertices",
        "faces",
        "edges",
        "boundary_edges",
        "components",
        "euler_characteristic",
    ] {
        assert_eq!(field(&a, k), field(&b, k), "{k}");
    }
    assert_eq!(a["faces_by_arity"], b["faces_by_arity"]);
    assert_eq!(a["genus"], b["genus"]);
    assert_eq!(a["bbox_min"], b["bbox_min"]);
}

#[test]
fn convert_corpus_mesh_round_trip() {
    let Some(dir) = corpus_dir() else {
        println!("note: no ../shared/data/meshes beside the checkout; corpus round trip skipped");
        return;
    };
    let d = tmp();
    let src = dir.join("suzanne.obj");
    let ply = d.path().join("suzanne.ply");
    let off = d.path().join("suzanne.off");
    ok(&["convert", src.to_str().unwrap(), ply.to_str().unwrap()]);
    ok(&["convert", ply.to_str().unwrap(), off.to_str().unwrap()]);
    let (a, b) = (
        info_json(src.to_str().unwrap()),
        info_json(off.to_str().unwrap()),
    );
    for k in [
        "vertices",
        "faces",
        "edges",
        "boundary_edges",
        "boundary_loops",
        "components",
    ] {
        assert_eq!(field(&a, k), field(&b, k), "{k}");
    }
}

#[test]
fn convert_warns_about_unreferenced_vertices_and_drops_them_on_request() {
    let d = tmp();
    let src = write(d.path(), "stray.obj", &pyramid_with_stray_vertex());
    let kept = d.path().join("kept.ply");
    let o = run(&["convert", &src, kept.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("WARN") && err.contains("1 unreferenced"),
        "{err}"
    );
    let j = info_json(kept.to_str().unwrap());
    assert_eq!(
        (field(&j, "vertices"), field(&j, "unreferenced_vertices")),
        (6, 1)
    );

    let dropped = d.path().join("dropped.off");
    let o = run(&[
        "convert",
        "--drop-unreferenced",
        &src,
        dropped.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stderr(&o).contains("WARN"), "{}", stderr(&o));
    let j = info_json(dropped.to_str().unwrap());
    assert_eq!(
        (
            field(&j, "vertices"),
            field(&j, "unreferenced_vertices"),
            field(&j, "faces")
        ),
        (5, 0, 5)
    );
}

#[test]
fn convert_explicit_formats_and_standard_output() {
    let d = tmp();
    let src = write(d.path(), "cube.obj", &generate::cube());
    // --from/--to override the extensions.
    let odd = d.path().join("cube.dat");
    ok(&["convert", "--to", "off", &src, odd.to_str().unwrap()]);
    assert!(std::fs::read_to_string(&odd).unwrap().starts_with("OFF"));
    let back = d.path().join("cube2.obj");
    ok(&[
        "convert",
        "--from",
        "off",
        odd.to_str().unwrap(),
        back.to_str().unwrap(),
    ]);
    assert_eq!(field(&info_json(back.to_str().unwrap()), "faces"), 6);
    // `-` writes the mesh, and only the mesh, to standard output.
    let o = run(&["convert", &src, "-", "--to", "off"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.starts_with("OFF"), "{text}");
    let e = fails(&["convert", &src, "-"]);
    assert!(e.contains("format"), "{e}");
    // Every output format, GLB included.
    for f in ["obj", "off", "ply", "stl", "glb"] {
        let p = d.path().join(format!("all.{f}"));
        ok(&["convert", &src, p.to_str().unwrap()]);
        assert!(std::fs::metadata(&p).unwrap().len() > 0, "{f}");
    }
    assert_eq!(Format::from_name("GLB"), Some(Format::Glb));
}

// ---------------------------------------------------------------------------------------------
// demo.

fn check_demo_folder(dir: &Path, vertices: i64) {
    for f in [
        "five-blobs.obj",
        "five-blobs.ply",
        "five-blobs.glb",
        "report.json",
    ] {
        let p = dir.join(f);
        let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        assert!(len > 0, "{} missing or empty", p.display());
    }
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(field(&report["mesh"], "vertices"), vertices, "{report:#}");
    assert_eq!(report["mesh"]["genus"].as_u64(), Some(0));
    // Three meshes, the stream, 8 decoded prefixes and the plot (report.json itself is
    // written after the list).
    assert_eq!(
        report["outputs"].as_array().map(Vec::len),
        Some(13),
        "{report:#}"
    );
    // The progressive stream: its prefixes decode to meshes of the input's size whose PSNR
    // grows with the bytes, up to near-lossless at the whole stream.
    let stream_len = std::fs::metadata(dir.join("five-blobs.swv")).unwrap().len();
    assert_eq!(report["stream"]["bytes"].as_u64(), Some(stream_len));
    let rd = report["rate_distortion"]
        .as_array()
        .expect("rate_distortion");
    assert_eq!(rd.len(), 8, "{report:#}");
    let psnr: Vec<f64> = rd.iter().map(|p| p["psnr"].as_f64().unwrap()).collect();
    assert!(psnr.windows(2).all(|w| w[1] >= w[0]), "{psnr:?}");
    assert!(psnr[7] > 90.0 && psnr[0] < psnr[7] - 30.0, "{psnr:?}");
    assert_eq!(rd[7]["bytes"].as_u64(), Some(stream_len));
    for p in rd {
        let name = format!("five-blobs-{:07}B.obj", p["bytes"].as_u64().unwrap());
        let j = info_json(dir.join(&name).to_str().unwrap());
        assert_eq!(field(&j, "vertices"), vertices, "{name}");
    }
    let svg = std::fs::read_to_string(dir.join("rate-distortion.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("polyline"), "{svg}");
    // The written mesh reads back with the same counts.
    let j = info_json(dir.join("five-blobs.obj").to_str().unwrap());
    assert_eq!(field(&j, "vertices"), vertices);
    let j = info_json(dir.join("five-blobs.ply").to_str().unwrap());
    assert_eq!(field(&j, "non_manifold_edges"), 0);
    // The wavelet step: Loop and lifted butterfly on the detected hierarchy, reconstructing
    // the mesh to rounding error, with details that shrink from level to level.
    let w = report["wavelets"].as_array().expect("wavelets section");
    assert_eq!(w.len(), 2, "{report:#}");
    for r in w {
        assert!(
            r["reconstruction_max_error"].as_f64().unwrap() < 1e-12,
            "{r:#}"
        );
        let levels = r["levels"].as_array().unwrap();
        assert!(levels.len() >= 3, "{r:#}");
        let first = levels[0]["mean_detail"].as_f64().unwrap();
        let last = levels[levels.len() - 2]["mean_detail"].as_f64().unwrap();
        assert!(last < first, "{r:#}");
    }
}

#[test]
fn demo_writes_its_files() {
    let d = tmp();
    let out_dir = d.path().join("nested/demo");
    let out = ok(&["demo", "--out", out_dir.to_str().unwrap(), "--levels", "2"]);
    for needle in [
        "generate",
        "validate",
        "five-blobs.glb",
        "report.json",
        "total",
        "genus",
        "five-blobs.swv",
        "progressive decoding",
    ] {
        assert!(out.contains(needle), "missing `{needle}` in:\n{out}");
    }
    check_demo_folder(&out_dir, 162);
}

#[test]
fn demo_without_arguments_uses_the_defaults() {
    let d = tmp();
    let o = run_in(Some(d.path()), &["demo"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    check_demo_folder(&d.path().join("subwave-demo"), 2562);
}

#[test]
fn demo_into_a_file_fails_cleanly() {
    let d = tmp();
    let f = file(d.path(), "not-a-folder", b"x");
    let e = fails(&["demo", "--out", &f, "--levels", "0"]);
    assert!(e.contains("not-a-folder"), "{e}");
}

/// Writes `mesh` as `name` into `dir` and returns the path as a string.
fn put(dir: &Path, name: &str, mesh: &Mesh) -> String {
    let path = dir.join(name);
    write_mesh(mesh, &path, None).expect("write a test mesh");
    path.to_string_lossy().into_owned()
}

#[test]
fn subdivide_writes_the_refined_mesh() {
    let dir = tmp();
    let input = put(dir.path(), "ico.obj", &generate::icosphere(1));
    let out = dir.path().join("out.obj");
    let o = out.to_string_lossy().into_owned();
    let text = ok(&[
        "subdivide",
        &input,
        "-o",
        &o,
        "--scheme",
        "loop",
        "--levels",
        "2",
    ]);
    assert!(text.contains("2 levels of loop"), "{text}");
    let m = subwave::io::read_mesh(&out, None).unwrap();
    // 80 faces -> 1280; V = 42 + 120 + 480 = 642.
    assert_eq!((m.num_vertices(), m.num_faces()), (642, 1280));
}

#[test]
fn subdivide_rejects_what_the_scheme_cannot_take() {
    let dir = tmp();
    let cube = put(dir.path(), "cube.obj", &generate::cube());
    let o = dir.path().join("o.obj").to_string_lossy().into_owned();
    let err = fails(&["subdivide", &cube, "-o", &o, "--scheme", "loop"]);
    assert!(
        err.contains("face") && err.contains("catmull-clark"),
        "{err}"
    );
    let fin = put(dir.path(), "fin.obj", &generate::fin());
    let err = fails(&["subdivide", &fin, "-o", &o, "--scheme", "catmull-clark"]);
    assert!(err.contains("edge"), "{err}");
}

#[test]
fn subdivide_boundary_none_drops_the_boundary_ring() {
    let dir = tmp();
    let grid = put(dir.path(), "grid.obj", &generate::grid(5, 5, false));
    let out = dir.path().join("none.obj");
    let o = out.to_string_lossy().into_owned();
    ok(&[
        "subdivide",
        &grid,
        "-o",
        &o,
        "--scheme",
        "catmull-clark",
        "--levels",
        "2",
        "--boundary",
        "none",
    ]);
    let m = subwave::io::read_mesh(&out, None).unwrap();
    assert_eq!(m.num_faces(), 9 * 16);
}

#[test]
fn bench_subdivide_prints_the_documented_json() {
    let dir = tmp();
    let input = put(
        dir.path(),
        "torus.obj",
        &generate::torus(1.0, 0.4, 8, 6, true),
    );
    let text = ok(&[
        "bench",
        "subdivide",
        &input,
        "--levels",
        "2",
        "--runs",
        "1",
        "--json",
    ]);
    let v: Value = serde_json::from_str(&text).expect("JSON");
    for key in [
        "topology_ms",
        "positions_ms",
        "total_ms",
        "reevaluate_ms",
        "peak_rss_mb",
        "vertices",
        "faces",
    ] {
        assert!(v.get(key).is_some(), "missing {key} in {text}");
    }
    // 96 triangles, 2 Loop levels.
    assert_eq!(v["faces"], 96 * 16);
    let text = ok(&["bench", "subdivide", &input, "--levels", "1", "--runs", "1"]);
    assert!(text.contains("re-evaluation"), "{text}");
}

#[test]
fn distance_prints_the_documented_json() {
    let dir = tmp();
    let a = generate::grid(4, 4, true);
    let mut b = a.clone();
    for p in &mut b.positions {
        p.z += 0.5;
    }
    let pa = put(dir.path(), "a.obj", &a);
    let pb = put(dir.path(), "b.ply", &b);
    let text = ok(&["distance", &pa, &pb, "--json", "--samples", "2000"]);
    let v: Value = serde_json::from_str(&text).expect("JSON");
    for key in ["rms", "max", "psnr", "rms_ab", "rms_ba"] {
        assert!(v.get(key).is_some(), "missing {key} in {text}");
    }
    assert!((v["rms"].as_f64().unwrap() - 0.5).abs() < 1e-12);
    let text = ok(&["distance", &pa, &pb]);
    assert!(text.contains("psnr"), "{text}");
    let empty = dir.path().join("empty.obj");
    std::fs::write(&empty, "v 0 0 0\n").unwrap();
    let err = fails(&["distance", &pa, &empty.to_string_lossy()]);
    assert!(err.contains("no faces"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// subdivide --scheme butterfly

#[test]
fn subdivide_butterfly() {
    let d = tmp();
    let sphere = write(d.path(), "ico.obj", &generate::icosphere(1));
    let out = d.path().join("out.obj");
    let out = out.to_str().unwrap();
    for scheme in ["butterfly", "butterfly-original"] {
        let said = ok(&[
            "subdivide",
            &sphere,
            "-o",
            out,
            "--scheme",
            scheme,
            "--levels",
            "2",
        ]);
        assert!(said.contains(&format!("2 levels of {scheme}")), "{said}");
        let j = info_json(out);
        // 42 vertices, 120 edges, 80 faces -> 162, 480, 320 -> 642 vertices, 1280 faces.
        assert_eq!(
            (field(&j, "vertices"), field(&j, "faces")),
            (642, 1280),
            "{j}"
        );
    }
    let quads = write(d.path(), "cube.obj", &generate::cube());
    let err = fails(&["subdivide", &quads, "-o", out, "--scheme", "butterfly"]);
    assert!(
        err.contains("butterfly") && err.contains("catmull-clark"),
        "{err}"
    );
}

#[test]
fn subdivide_limit_writes_limit_positions() {
    let d = tmp();
    let input = write(d.path(), "cube.obj", &generate::cube());
    let out = d.path().join("limit.obj");
    let out_s = out.to_str().unwrap();
    let args = [
        "subdivide",
        &input,
        "-o",
        out_s,
        "--scheme",
        "catmull-clark",
        "--levels",
        "2",
        "--limit",
    ];
    assert!(ok(&args).contains("at the limit"));
    let got = subwave::io::read_mesh(&out, None).unwrap();
    let opts = subwave::subdivision::SubdivideOptions {
        scheme: subwave::subdivision::Scheme::CatmullClark,
        levels: 2,
        ..Default::default()
    };
    let (expect, _) =
        subwave::subdivision::limit::subdivide_limit(&generate::cube(), &opts).unwrap();
    assert_eq!(got.num_vertices(), expect.num_vertices());
    for (a, b) in got.positions.iter().zip(&expect.positions) {
        assert!((*a - *b).length() < 1e-6, "{a} vs {b}");
    }
    // Without --limit the vertices differ (the limit test is not vacuous).
    ok(&args[..args.len() - 1]);
    let plain = subwave::io::read_mesh(&out, None).unwrap();
    assert!(plain.positions[0].distance(got.positions[0]) > 1e-3);
    let err = fails(&[
        "subdivide",
        &input,
        "-o",
        out_s,
        "--scheme",
        "midpoint",
        "--limit",
    ]);
    assert!(err.contains("midpoint"), "{err}");
}

#[test]
fn stability_report_shows_bertrams_observations() {
    let text = ok(&["stability", "--levels", "4"]);
    assert!(text.contains("linear: reduces the noise"), "{text}");
    assert!(text.contains("quintic: amplifies the noise"), "{text}");
    let j: Value = serde_json::from_str(&ok(&["stability", "--levels", "4", "--json"])).unwrap();
    let runs = j["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 3);
    let rel = |i: usize, k: usize| runs[i]["levels"][k]["relative"].as_f64().unwrap();
    assert!(rel(0, 3) < 0.1 * rel(0, 0));
    assert!(rel(2, 3) > 10.0 * rel(2, 0));
    let err = fails(&["stability", "--noise=-1"]);
    assert!(err.contains("noise"), "{err}");
}
