//! `subwave subdivide --scheme quad-tri` end to end.

use std::process::{Command, Stdio};

use subwave::io::{read_mesh, write_mesh, Format};
use subwave::subdivision::{subdivide, Scheme, SubdivideOptions};
use subwave::{generate, DVec3, Mesh};

fn run(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_subwave"))
        .args(args)
        .stdin(Stdio::null())
        .env_remove("RUST_LOG")
        .output()
        .expect("cannot start the subwave executable")
}

/// The cube with its top face split into two triangles.
fn mixed_cube() -> Mesh {
    let c = generate::cube();
    let mut faces: Vec<Vec<u32>> = Vec::new();
    for (k, f) in c.faces().enumerate() {
        if k == 1 {
            faces.push(vec![f[0], f[1], f[2]]);
            faces.push(vec![f[0], f[2], f[3]]);
        } else {
            faces.push(f.to_vec());
        }
    }
    Mesh::from_faces(c.positions.clone(), faces)
}

#[test]
fn quad_tri_scheme() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("mixed.obj");
    let output = dir.path().join("out.obj");
    let m = mixed_cube();
    write_mesh(&m, &input, Some(Format::Obj)).unwrap();
    let o = run(&[
        "subdivide",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--scheme",
        "quad-tri",
        "--levels",
        "2",
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let out = read_mesh(&output, None).unwrap();
    let want = subdivide(
        &m,
        &SubdivideOptions {
            scheme: Scheme::QuadTri,
            levels: 2,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(out.face_indices, want.face_indices);
    let d = out
        .positions
        .iter()
        .zip(&want.positions)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    assert!(d < 1e-6, "{d}");

    // A pentagon: exit 1, the error names the face and suggests catmull-clark.
    let mut p = Mesh::new();
    for i in 0..5 {
        let a = std::f64::consts::TAU * i as f64 / 5.0;
        p.positions.push(DVec3::new(a.cos(), a.sin(), 0.0));
    }
    p.push_face(&[0, 1, 2, 3, 4]);
    let pent = dir.path().join("pent.obj");
    write_mesh(&p, &pent, Some(Format::Obj)).unwrap();
    let o = run(&[
        "subdivide",
        pent.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--scheme",
        "quad-tri",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("quad-tri") && err.contains("catmull-clark"),
        "{err}"
    );
}
