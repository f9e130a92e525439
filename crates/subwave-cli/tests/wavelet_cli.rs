//! `subwave wavelet` end to end: every wavelet on a Loop-subdivided icosphere (triangles) or a
//! Catmull-Clark cube (quads), JSON keys and values, and the errors on other meshes.

use std::path::Path;
use std::process::{Command, Stdio};

use subwave::io::{write_mesh, Format};
use subwave::subdivision::{subdivide, Scheme, SubdivideOptions};
use subwave::{generate, Mesh};

fn run(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_subwave"))
        .args(args)
        .stdin(Stdio::null())
        .env_remove("RUST_LOG")
        .output()
        .expect("cannot start the subwave executable")
}

fn sub(m: &Mesh, scheme: Scheme, levels: u32) -> Mesh {
    subdivide(
        m,
        &SubdivideOptions {
            scheme,
            levels,
            ..SubdivideOptions::default()
        },
    )
    .unwrap()
}

fn write(dir: &Path, name: &str, m: &Mesh) -> String {
    let p = dir.join(name);
    write_mesh(m, &p, Some(Format::Obj)).unwrap();
    p.to_str().unwrap().to_string()
}

fn json(args: &[&str]) -> serde_json::Value {
    let o = run(args);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Checks the common keys; returns the report.
fn check(
    path: &str,
    wavelet: &str,
    frames: &str,
    levels: usize,
    base: (u64, u64),
    finest: u64,
) -> serde_json::Value {
    let v = json(&[
        "wavelet",
        path,
        "--wavelet",
        wavelet,
        "--frames",
        frames,
        "--json",
    ]);
    assert_eq!(v["wavelet"], wavelet);
    assert_eq!(v["base_vertices"].as_u64(), Some(base.0), "{wavelet}");
    assert_eq!(v["base_faces"].as_u64(), Some(base.1), "{wavelet}");
    let lv = v["levels"].as_array().unwrap();
    assert_eq!(lv.len(), levels + 1, "{wavelet}");
    for (j, l) in lv.iter().enumerate() {
        assert_eq!(l["level"].as_u64(), Some(j as u64));
        for k in ["vertices", "l2_error", "max_error", "mean_detail"] {
            assert!(l[k].is_number(), "{wavelet}: level {j} key {k}");
        }
    }
    assert_eq!(lv[0]["vertices"].as_u64(), Some(base.0));
    assert_eq!(lv[levels]["vertices"].as_u64(), Some(finest));
    // The finest level is the mesh itself; coarser levels approximate it.
    assert_eq!(lv[levels]["l2_error"].as_f64(), Some(0.0));
    assert!(lv[0]["l2_error"].as_f64().unwrap() >= lv[levels - 1]["l2_error"].as_f64().unwrap());
    for k in ["forward_ms", "inverse_ms", "reconstruction_max_error"] {
        assert!(v[k].as_f64().unwrap() >= 0.0, "{wavelet}: {k}");
    }
    let diag = v["diagonal"].as_f64().unwrap();
    let rec = v["reconstruction_max_error"].as_f64().unwrap();
    if wavelet.ends_with("-int") {
        assert_eq!(rec, 0.0, "{wavelet}");
    } else {
        assert!(rec <= 1e-9 * diag, "{wavelet}: {rec}");
    }
    v
}

#[test]
fn triangle_wavelets() {
    let dir = tempfile::tempdir().unwrap();
    // icosphere(1) is itself a 1-to-4 split of the icosahedron: 4 levels in all.
    let m = sub(&generate::icosphere(1), Scheme::Loop, 3);
    let path = write(dir.path(), "sphere.obj", &m);
    for w in [
        "midpoint",
        "midpoint-lifted",
        "butterfly",
        "butterfly-lifted",
        "loop",
    ] {
        for frames in ["global", "local"] {
            let v = check(&path, w, frames, 4, (12, 20), m.num_vertices() as u64);
            assert_eq!(v["split"], "triangles");
        }
    }
    // The Loop wavelet sees no detail in Loop levels 1..3 (the mesh is Loop subdivision of
    // level 1), the midpoint wavelet does.
    let v = check(
        &path,
        "loop",
        "global",
        4,
        (12, 20),
        m.num_vertices() as u64,
    );
    let lv = v["levels"].as_array().unwrap();
    for (j, l) in lv.iter().enumerate().take(4).skip(1) {
        assert!(l["max_detail"].as_f64().unwrap() < 1e-7, "loop level {j}");
        assert!(l["max_error"].as_f64().unwrap() < 1e-7, "loop level {j}");
    }
    let v = check(
        &path,
        "midpoint",
        "global",
        4,
        (12, 20),
        m.num_vertices() as u64,
    );
    assert!(v["levels"][3]["mean_detail"].as_f64().unwrap() > 1e-4);
    // Human-readable table.
    let o = run(&["wavelet", &path, "--wavelet", "butterfly"]);
    assert_eq!(o.status.code(), Some(0));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("butterfly wavelet") && text.contains("reconstruction max error"),
        "{text}"
    );
    // Header (2 lines), table head, 5 levels, reconstruction error, timings.
    assert_eq!(text.lines().count(), 2 + 1 + 5 + 1 + 1, "{text}");
    assert!(text.contains("median of 1 run(s)"), "{text}");
    // Several timed runs: the median, runs and throughputs in the JSON.
    let o = run(&[
        "wavelet",
        &path,
        "--wavelet",
        "butterfly-lifted",
        "--runs",
        "3",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["runs"].as_u64(), Some(3));
    for k in ["plan_ms", "forward_mvert_per_s", "inverse_mvert_per_s"] {
        assert!(v[k].as_f64().unwrap() >= 0.0, "{k}");
    }
}

#[test]
fn quad_wavelets() {
    let dir = tempfile::tempdir().unwrap();
    let m = sub(&generate::cube(), Scheme::CatmullClark, 3);
    let path = write(dir.path(), "cube.obj", &m);
    for w in [
        "linear",
        "cubic",
        "quintic",
        "linear-int",
        "cubic-int",
        "quintic-int",
    ] {
        let v = check(&path, w, "global", 3, (8, 6), m.num_vertices() as u64);
        assert_eq!(v["split"], "quads");
        assert_eq!(v["levels"][1]["vertices"].as_u64(), Some(26));
        assert_eq!(v["levels"][2]["vertices"].as_u64(), Some(98));
        assert_eq!(v["levels"][1]["details"].as_u64(), Some(98 - 26));
    }
}

#[test]
fn errors_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    // Tetrahedron with one face split 1-to-3: no subdivision connectivity.
    let t = generate::tetrahedron();
    let mut faces: Vec<Vec<u32>> = t.faces().skip(1).map(|f| f.to_vec()).collect();
    let f0 = t.face(0).to_vec();
    let mut pos = t.positions.clone();
    pos.push((pos[f0[0] as usize] + pos[f0[1] as usize] + pos[f0[2] as usize]) / 3.0);
    for i in 0..3 {
        faces.push(vec![f0[i], f0[(i + 1) % 3], 4]);
    }
    let bad = write(dir.path(), "bad.obj", &Mesh::from_faces(pos, faces));
    let o = run(&["wavelet", &bad, "--wavelet", "loop"]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("subdivision connectivity") && err.contains("bad.obj"),
        "{err}"
    );
    // Wavelet/mesh mismatch names the wavelets that fit.
    let cube = write(
        dir.path(),
        "cube.obj",
        &sub(&generate::cube(), Scheme::CatmullClark, 2),
    );
    let o = run(&["wavelet", &cube, "--wavelet", "loop"]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("linear, cubic, quintic, linear-int"), "{err}");
    let sphere = write(
        dir.path(),
        "s.obj",
        &sub(&generate::icosahedron(), Scheme::Loop, 2),
    );
    let o = run(&["wavelet", &sphere, "--wavelet", "cubic-int"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("midpoint, midpoint-lifted, butterfly"));
    // Local frames with a B-spline wavelet.
    let o = run(&["wavelet", &cube, "--wavelet", "cubic", "--frames", "local"]);
    assert_eq!(o.status.code(), Some(1));
    // An unknown wavelet is a usage error.
    let o = run(&["wavelet", &cube, "--wavelet", "haar"]);
    assert_eq!(o.status.code(), Some(2));
}
