//! End-to-end tests of `subwave encode`, `subwave decode`, `subwave bench decode` and `subwave eval`.

use std::process::{Command, Output, Stdio};

use serde_json::Value;
use subwave::generate;
use subwave::io::{read_mesh, write_mesh};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_subwave"))
        .args(args)
        .stdin(Stdio::null())
        .env_remove("RUST_LOG")
        .output()
        .expect("cannot start the subwave executable")
}

fn ok(args: &[&str]) -> String {
    let o = run(args);
    assert_eq!(
        o.status.code(),
        Some(0),
        "subwave {args:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn fails(args: &[&str]) -> String {
    let o = run(args);
    assert_eq!(o.status.code(), Some(1), "subwave {args:?} should fail");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A semi-regular bumpy sphere (icosahedron split `levels` times), written in scrambled
/// vertex order to show that any order is detected.
fn write_semi_regular(path: &std::path::Path, levels: u32) -> usize {
    let mut m = generate::icosahedron();
    for _ in 0..levels {
        m = generate::midpoint_split(&m);
    }
    for p in &mut m.positions {
        let d = p.normalize();
        *p = d * (1.0 + 0.05 * (4.0 * d.x).sin() * (3.0 * d.z).cos());
    }
    // Reverse the vertex order.
    let n = m.positions.len() as u32;
    m.positions.reverse();
    for i in &mut m.face_indices {
        *i = n - 1 - *i;
    }
    write_mesh(&m, path, None).unwrap();
    m.positions.len()
}

#[test]
fn encode_decode_round_trip_and_prefixes() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("s.obj");
    let n = write_semi_regular(&mesh, 3);
    let swv = dir.path().join("s.swv");
    let out = ok(&[
        "encode",
        mesh.to_str().unwrap(),
        "-o",
        swv.to_str().unwrap(),
    ]);
    assert!(
        out.contains("3 levels over 12 base vertices / 20 faces"),
        "{out}"
    );
    let full = dir.path().join("full.ply");
    let out = ok(&[
        "decode",
        swv.to_str().unwrap(),
        "-o",
        full.to_str().unwrap(),
    ]);
    assert!(out.contains("(complete)"), "{out}");
    let m = read_mesh(&full, None).unwrap();
    assert_eq!(m.num_vertices(), n);
    // An embedded stream has no trees to choose.
    let e = fails(&[
        "decode",
        swv.to_str().unwrap(),
        "-o",
        full.to_str().unwrap(),
        "--trees",
        "0",
    ]);
    assert!(
        e.contains("--layout trees") && e.contains("embedded"),
        "{e}"
    );
    let low = dir.path().join("low.obj");
    let out = ok(&[
        "decode",
        swv.to_str().unwrap(),
        "-o",
        low.to_str().unwrap(),
        "--bpv",
        "12",
    ]);
    assert!(!out.contains("(complete)"), "{out}");
    assert_eq!(read_mesh(&low, None).unwrap().num_vertices(), n);
    // The distance of the prefix to the input is larger than the full decode's.
    let psnr = |a: &str, b: &str| {
        let j: Value =
            serde_json::from_str(&ok(&["distance", a, b, "--samples", "20000", "--json"])).unwrap();
        j["psnr"].as_f64().unwrap()
    };
    let (m0, f0, l0) = (
        mesh.to_str().unwrap(),
        full.to_str().unwrap(),
        low.to_str().unwrap(),
    );
    assert!(psnr(m0, f0) > psnr(m0, l0) + 3.0);
    let j: Value = serde_json::from_str(&ok(&[
        "bench",
        "decode",
        swv.to_str().unwrap(),
        "--json",
        "--runs",
        "2",
    ]))
    .unwrap();
    assert_eq!(j["vertices"].as_u64(), Some(n as u64));
    assert!(j["decode_ms"].as_f64().unwrap() > 0.0);
    // The coder against the entropy of its coefficients: one row per bit plane, the last
    // one's bytes those of every coefficient chunk.
    let j: Value =
        serde_json::from_str(&ok(&["bench", "entropy", swv.to_str().unwrap(), "--json"])).unwrap();
    let planes = j["planes"].as_array().unwrap();
    assert!(planes.len() >= 8, "{j}");
    assert_eq!(planes.last().unwrap()["plane"].as_u64(), Some(0));
    let coded = std::fs::metadata(&swv).unwrap().len();
    let last = planes.last().unwrap()["bytes"].as_u64().unwrap();
    assert!(last > 0 && last < coded, "{j}");
    for p in planes {
        assert!(p["parent_bytes"].as_f64().unwrap() <= p["order0_bytes"].as_f64().unwrap() + 1e-6);
    }
    let text = ok(&["bench", "entropy", swv.to_str().unwrap()]);
    assert!(
        text.contains("order 0") && text.contains("given parent"),
        "{text}"
    );
}

#[test]
fn lossless_trees_and_errors() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("s.obj");
    write_semi_regular(&mesh, 2);
    let swv = dir.path().join("l.swv");
    let out = ok(&[
        "encode",
        mesh.to_str().unwrap(),
        "-o",
        swv.to_str().unwrap(),
        "--lossless",
        "--bits",
        "14",
        "--wavelet",
        "midpoint",
        "--layout",
        "trees",
    ]);
    assert!(
        out.contains("lossless") && out.contains("trees layout"),
        "{out}"
    );
    let dec = dir.path().join("d.obj");
    ok(&["decode", swv.to_str().unwrap(), "-o", dec.to_str().unwrap()]);
    // Same surface up to the grid step (2/16383 of the longest side, half a step per axis).
    let j: Value = serde_json::from_str(&ok(&[
        "distance",
        mesh.to_str().unwrap(),
        dec.to_str().unwrap(),
        "--samples",
        "5000",
        "--json",
    ]))
    .unwrap();
    let step = 2.2 / 16383.0;
    assert!(j["max"].as_f64().unwrap() <= step, "{j}");
    // Some trees only.
    let out = ok(&[
        "decode",
        swv.to_str().unwrap(),
        "-o",
        dec.to_str().unwrap(),
        "--trees",
        "0,2-5",
    ]);
    assert!(!out.contains("(complete)"), "{out}");
    let e = fails(&[
        "decode",
        swv.to_str().unwrap(),
        "-o",
        dec.to_str().unwrap(),
        "--trees",
        "x",
    ]);
    assert!(e.contains("not a tree number"), "{e}");
    // No bit planes of one forest to weigh.
    let e = fails(&["bench", "entropy", swv.to_str().unwrap()]);
    assert!(e.contains("encode with --layout embedded"), "{e}");
    // Trees past the forest's are refused, not ignored (20 base faces: 30 base edges).
    let e = fails(&[
        "decode",
        swv.to_str().unwrap(),
        "-o",
        dec.to_str().unwrap(),
        "--trees",
        "2,30",
    ]);
    assert!(
        e.contains("no tree 30") && e.contains("30 trees (0-29)"),
        "{e}"
    );
    // Corrupt chunk.
    let mut bytes = std::fs::read(&swv).unwrap();
    let n = bytes.len();
    bytes[n - 3] ^= 0x40;
    let bad = dir.path().join("bad.swv");
    std::fs::write(&bad, &bytes).unwrap();
    let e = fails(&["decode", bad.to_str().unwrap(), "-o", dec.to_str().unwrap()]);
    assert!(
        e.contains("fails its checksum") && e.contains("(tree "),
        "{e}"
    );
    // Not a stream.
    let e = fails(&[
        "decode",
        mesh.to_str().unwrap(),
        "-o",
        dec.to_str().unwrap(),
    ]);
    assert!(e.contains("not a subwave stream"), "{e}");
    // Loop is not lossless.
    let e = fails(&[
        "encode",
        mesh.to_str().unwrap(),
        "-o",
        swv.to_str().unwrap(),
        "--lossless",
        "--wavelet",
        "loop",
    ]);
    assert!(e.contains("integer wavelet"), "{e}");
}

#[test]
fn irregular_input_is_remeshed() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("t.obj");
    write_mesh(&generate::torus(1.0, 0.4, 25, 13, true), &mesh, None).unwrap();
    let swv = dir.path().join("t.swv");
    let out = ok(&[
        "encode",
        mesh.to_str().unwrap(),
        "-o",
        swv.to_str().unwrap(),
        "--levels",
        "2",
        "--base-faces",
        "64",
        "--direct",
        "never",
    ]);
    assert!(out.contains("remeshed, 2 levels"), "{out}");
    let dec = dir.path().join("t.glb");
    ok(&[
        "decode",
        swv.to_str().unwrap(),
        "-o",
        dec.to_str().unwrap(),
        "--bytes",
        "2000",
    ]);
}

/// The remesh's vertices are offset off the input to its least-squares fit by default, which
/// brings the remesh closer to the input; `--on-surface` keeps them on it.
#[test]
fn least_squares_offsets_and_on_surface() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("t.obj");
    write_mesh(&generate::torus(1.0, 0.4, 45, 23, true), &mesh, None).unwrap();
    let swv = dir.path().join("t.swv");
    let encode = |extra: &[&str]| {
        let mut args = vec![
            "encode",
            mesh.to_str().unwrap(),
            "-o",
            swv.to_str().unwrap(),
            "--levels",
            "3",
            "--base-faces",
            "64",
        ];
        args.extend_from_slice(extra);
        let out = ok(&args);
        // "remesh: 61.23 dB from the remesh to the input ..."
        let db: f64 = out
            .lines()
            .find_map(|l| l.strip_prefix("remesh: "))
            .and_then(|l| l.split(' ').next())
            .and_then(|x| x.parse().ok())
            .unwrap_or_else(|| panic!("no remesh distance in {out}"));
        (out, db)
    };
    let (fitted, fitted_db) = encode(&[]);
    assert!(
        fitted.contains("least-squares offsets off the input"),
        "{fitted}"
    );
    let (on, on_db) = encode(&["--on-surface"]);
    assert!(!on.contains("least-squares"), "{on}");
    assert!(
        fitted_db > on_db + 1.0,
        "fitted {fitted_db} dB, on the surface {on_db} dB"
    );
}

/// A low-poly input is served better as it is than by its remesh: `encode` and `eval` weigh
/// both and keep the direct stream (the coarse torus: 325 vertices); `--direct always` codes
/// any input so, at `--bits` precision, and refuses what a direct stream cannot be; every
/// direct stream decodes, its prefixes from the base chunk on.
#[test]
fn low_poly_input_is_coded_as_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("t.obj");
    let torus = generate::torus(1.0, 0.4, 25, 13, true);
    write_mesh(&torus, &mesh, None).unwrap();
    let swv = dir.path().join("t.swv");
    let (m, o) = (mesh.to_str().unwrap(), swv.to_str().unwrap());
    let out = ok(&["encode", m, "-o", o]);
    assert!(
        out.contains("direct stream kept") && out.contains("coded as it is (direct stream)"),
        "{out}"
    );
    // Its remesh at the default levels tops out low: it would be redone with more levels,
    // but the direct stream already beats it at the first two budgets.
    assert!(
        out.contains("the remesh was not redone with more levels"),
        "{out}"
    );
    let full = std::fs::read(&swv).unwrap().len();
    let dec = dir.path().join("d.obj");
    let d = dec.to_str().unwrap();
    ok(&["decode", o, "-o", d]);
    let back = subwave::io::read_mesh(&dec, None).unwrap();
    assert_eq!(back.num_vertices(), torus.num_vertices());
    assert_eq!(back.num_faces(), torus.num_faces());
    let dist = subwave::distance::distance(&torus, &back, 5_000).unwrap();
    assert!(dist.psnr > 90.0, "{dist:?}");
    // A prefix before the base chunk ends is refused; one after decodes, further away.
    let e = fails(&["decode", o, "-o", d, "--bytes", "100"]);
    assert!(e.contains("truncated"), "{e}");
    ok(&["decode", o, "-o", d, "--bytes", &(full - 200).to_string()]);
    let cut = subwave::io::read_mesh(&dec, None).unwrap();
    let dcut = subwave::distance::distance(&torus, &cut, 5_000).unwrap();
    assert!(dcut.psnr < dist.psnr - 3.0, "{dcut:?} {dist:?}");
    // Forced, at 10 bits: smaller.
    let out = ok(&["encode", m, "-o", o, "--direct", "always", "--bits", "10"]);
    assert!(
        out.contains("10 bits, the first 8 in the base chunk, then 2 refinement planes"),
        "{out}"
    );
    assert!(std::fs::read(&swv).unwrap().len() < full);
    let e = fails(&["encode", m, "-o", o, "--direct", "always", "--bits", "6"]);
    assert!(e.contains("at least 8 bits"), "{e}");
    let e = fails(&[
        "encode", m, "-o", o, "--direct", "always", "--layout", "trees",
    ]);
    assert!(e.contains("no trees"), "{e}");
    // Lossless: the input itself on the 12-bit grid, exactly, is smaller than its remesh.
    let out = ok(&["encode", m, "-o", o, "--lossless"]);
    assert!(
        out.contains("exactly on the same 12-bit grid") && out.contains("direct stream kept"),
        "{out}"
    );
    ok(&["decode", o, "-o", d]);
    let back = subwave::io::read_mesh(&dec, None).unwrap();
    let (lo, hi) = torus.positions.iter().fold(
        (
            subwave::DVec3::splat(f64::INFINITY),
            subwave::DVec3::splat(f64::NEG_INFINITY),
        ),
        |(a, b), &p| (a.min(p), b.max(p)),
    );
    let step = (hi - lo).max_element() / 4095.0;
    let grid = |m: &subwave::Mesh| {
        let mut q: Vec<[i64; 3]> = m
            .positions
            .iter()
            .map(|&p| ((p - lo) / step).round().to_array().map(|x| x as i64))
            .collect();
        q.sort_unstable();
        q
    };
    assert_eq!(grid(&back), grid(&torus));
    // eval weighs the same and measures the direct stream.
    let out = ok(&["eval", m, "--samples", "5000", "--points", "6", "--json"]);
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["direct"], true, "{v}");
    assert!(v["direct_comparison"]["bytes"].is_array(), "{v}");
    let points = v["points"].as_array().unwrap();
    let psnr = |p: &Value| p["psnr"].as_f64().unwrap();
    assert!(
        psnr(&points[points.len() - 1]) > psnr(&points[0]) + 20.0,
        "{v}"
    );
    assert_eq!(v["stream_bytes"].as_u64().unwrap() as usize, full, "{v}");
}

/// `subwave eval` end to end: the rate-distortion points (JSON keys, bytes rising to the whole
/// stream, bits per input vertex, PSNR not below the first point's), the remedies (none
/// with given levels), the SVG plot and a peer's points compared at equal PSNR.
#[test]
fn eval_reports_points_plot_and_peer_ratios() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("t.obj");
    let torus = generate::torus(1.0, 0.4, 25, 13, true);
    write_mesh(&torus, &mesh, None).unwrap();
    let reference = dir.path().join("peer.txt");
    std::fs::write(
        &reference,
        "t.obj V=325 draco qp=6 bytes=300 bpv=7.4 psnr=35.0dB decode=0.1ms\n\
         t.obj V=325 draco qp=8 bytes=900 bpv=22.2 psnr=47.0dB decode=0.1ms\n\
         t.obj V=325 draco qp=10 bytes=1500 bpv=36.9 psnr=59.0dB decode=0.1ms\n\
         t.obj V=325 draco qp=14 bytes=2700 bpv=66.5 psnr=83.0dB decode=0.1ms\n",
    )
    .unwrap();
    let svg = dir.path().join("rd.svg");
    let out = ok(&[
        "eval",
        mesh.to_str().unwrap(),
        "--levels",
        "2",
        "--base-faces",
        "64",
        "--direct",
        "never",
        "--samples",
        "5000",
        "--points",
        "8",
        "--json",
        "--svg",
        svg.to_str().unwrap(),
        "--reference",
        reference.to_str().unwrap(),
    ]);
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["levels"], 2, "{v}");
    assert_eq!(v["remeshed"], true, "{v}");
    // Given levels: neither redone finer nor raised.
    assert_eq!(v["missed"], serde_json::json!([]), "{v}");
    assert!(v["raised"].is_null(), "{v}");
    let points = v["points"].as_array().unwrap();
    assert_eq!(points.len(), 8, "{v}");
    let nv = torus.num_vertices() as f64;
    let mut last_bytes = 0;
    for p in points {
        for key in ["bytes", "bpv", "rms", "max", "psnr"] {
            assert!(p[key].is_number(), "{key} in {p}");
        }
        let bytes = p["bytes"].as_u64().unwrap();
        assert!(bytes > last_bytes, "{v}");
        last_bytes = bytes;
        let bpv = p["bpv"].as_f64().unwrap();
        assert!((bpv - 8.0 * bytes as f64 / nv).abs() < 1e-9, "{p}");
        assert!(
            p["rms"].as_f64().unwrap() <= p["max"].as_f64().unwrap(),
            "{p}"
        );
    }
    assert_eq!(last_bytes, v["stream_bytes"].as_u64().unwrap());
    let psnr = |p: &Value| p["psnr"].as_f64().unwrap();
    assert!(psnr(&points[7]) > psnr(&points[0]) + 10.0, "{v}");
    // The peer's points, and our bytes over its own at each of our PSNRs within its range.
    let r = &v["references"][0];
    assert_eq!(r["points"].as_array().unwrap().len(), 4, "{v}");
    let ratios = r["ratios"].as_array().unwrap();
    assert_eq!(ratios.len(), 8);
    assert!(
        ratios.iter().any(|x| x.as_f64().is_some_and(|x| x > 0.0)),
        "{v}"
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(
        text.starts_with("<svg") && text.matches("<polyline").count() >= 2,
        "{text}"
    );
}

/// With default levels, a remesh that tops out below 80 dB from the input is redone with more
/// levels (a coarse torus over 40 base faces: 3 levels, 63 dB, raised to 5) for a lossy
/// stream, not for a lossless one, which codes every vertex of the remesh exactly.
#[test]
fn default_levels_are_raised_for_lossy_streams_only() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("t.obj");
    write_mesh(&generate::torus(1.0, 0.4, 25, 13, true), &mesh, None).unwrap();
    let swv = dir.path().join("t.swv");
    let encode = |lossless: bool| {
        let mut args = vec![
            "encode",
            mesh.to_str().unwrap(),
            "-o",
            swv.to_str().unwrap(),
            "--base-faces",
            "40",
            "--direct",
            "never",
        ];
        if lossless {
            args.push("--lossless");
        }
        ok(&args)
    };
    let lossy = encode(false);
    assert!(
        lossy.contains("levels raised: the remesh at 3 levels over 40 base faces")
            && lossy.contains("remeshed, 5 levels"),
        "{lossy}"
    );
    let lossless = encode(true);
    assert!(
        !lossless.contains("levels raised") && lossless.contains("remeshed, 3 levels"),
        "{lossless}"
    );
}

/// `remesh --normal --grid-bits B` writes a normal remesh on the lossless grid with most odd
/// vertices on their normal lines; `encode --lossless --bits B` of that mesh finds the same
/// grid and decodes to the written positions; `encode --lossless` of the irregular input
/// snaps its own remesh. Bad combinations are refused with a message.
#[test]
fn snapped_remeshes_code_losslessly_on_their_grid() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("t.obj");
    let mut torus = generate::torus(1.0, 0.4, 40, 20, true);
    for p in &mut torus.positions {
        p.z *= 1.0 + 0.2 * (3.0 * p.x).sin();
    }
    write_mesh(&torus, &mesh, None).unwrap();
    let (m, remesh) = (mesh.to_str().unwrap(), dir.path().join("r.obj"));
    let r = remesh.to_str().unwrap();
    let args = [
        "remesh",
        m,
        "-o",
        r,
        "--levels",
        "3",
        "--normal",
        "--grid-bits",
        "12",
        "--json",
    ];
    let v: Value = serde_json::from_str(&ok(&args)).unwrap();
    let snap = &v["snap"];
    let sum = |key: &str| -> u64 {
        let counts = snap[key].as_array().unwrap();
        counts.iter().map(|x| x.as_u64().unwrap()).sum()
    };
    let (on, odd) = (sum("on_line"), sum("odd"));
    assert!(on * 2 > odd, "{snap}");
    // Within the default reach (4 grid steps) of the line, plus the rounding.
    assert!(snap["max_move"].as_f64().unwrap() <= 5.5, "{snap}");
    let swv = dir.path().join("r.swv");
    let s = swv.to_str().unwrap();
    let out = ok(&["encode", r, "-o", s, "--lossless", "--bits", "12"]);
    assert!(out.contains("12-bit grid"), "{out}");
    let back = dir.path().join("back.obj");
    ok(&["decode", s, "-o", back.to_str().unwrap()]);
    let (a, b) = (
        read_mesh(&remesh, None).unwrap(),
        read_mesh(&back, None).unwrap(),
    );
    let mut pa: Vec<[i64; 3]> = a
        .positions
        .iter()
        .map(|p| p.to_array().map(|c| (c * 1e9).round() as i64))
        .collect();
    let mut pb: Vec<[i64; 3]> = b
        .positions
        .iter()
        .map(|p| p.to_array().map(|c| (c * 1e9).round() as i64))
        .collect();
    pa.sort_unstable();
    pb.sort_unstable();
    assert_eq!(pa, pb, "the decoded mesh is the written remesh");
    let own = ok(&[
        "encode",
        m,
        "-o",
        s,
        "--lossless",
        "--levels",
        "3",
        "--direct",
        "never",
    ]);
    assert!(
        own.contains("lossless grid: ") && own.contains("on their normal lines"),
        "{own}"
    );
    let e = fails(&["encode", m, "-o", s, "--lossless", "--bits", "25"]);
    assert!(e.contains("at most 24 bits"), "{e}");
    let o = run(&["remesh", m, "-o", r, "--grid-bits", "12"]);
    assert_eq!(o.status.code(), Some(2), "--grid-bits needs --normal");
}

/// A semi-regular all-quad (Catmull-Clark) mesh is coded as it is with the cubic wavelet
/// when no wavelet is given (the documented default on quad meshes), not remeshed into
/// triangles nor coded as an irregular mesh; an irregular quad mesh still is.
#[test]
fn catmull_clark_meshes_are_coded_as_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let cube = dir.path().join("cube.obj");
    write_mesh(&generate::cube(), &cube, None).unwrap();
    let cc = dir.path().join("cc.obj");
    ok(&[
        "subdivide",
        cube.to_str().unwrap(),
        "-o",
        cc.to_str().unwrap(),
        "--scheme",
        "catmull-clark",
        "--levels",
        "3",
    ]);
    let swv = dir.path().join("cc.swv");
    let out = ok(&["encode", cc.to_str().unwrap(), "-o", swv.to_str().unwrap()]);
    assert!(
        out.contains("3 levels over 8 base vertices / 6 faces") && out.contains("cubic wavelet"),
        "{out}"
    );
    assert!(
        !out.contains("remeshed") && !out.contains("direct"),
        "{out}"
    );
    let dec = dir.path().join("d.obj");
    ok(&["decode", swv.to_str().unwrap(), "-o", dec.to_str().unwrap()]);
    let d = read_mesh(&dec, None).unwrap();
    let m = read_mesh(&cc, None).unwrap();
    assert_eq!(
        (d.num_vertices(), d.num_faces()),
        (m.num_vertices(), m.num_faces())
    );
    assert!(d.is_quad_mesh());
    // Lossless too, with the same default.
    let out = ok(&[
        "encode",
        cc.to_str().unwrap(),
        "-o",
        swv.to_str().unwrap(),
        "--lossless",
    ]);
    assert!(out.contains("cubic wavelet, lossless"), "{out}");
    // The cube itself is no hierarchy: coded as an irregular mesh.
    let out = ok(&[
        "encode",
        cube.to_str().unwrap(),
        "-o",
        swv.to_str().unwrap(),
    ]);
    assert!(!out.contains("cubic wavelet"), "{out}");
}

/// What a stream does not code is named on standard error, and the stream is still made:
/// unused vertices, texture coordinates.
#[test]
fn uncoded_attributes_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = generate::midpoint_split(&generate::icosahedron());
    m.positions.push(subwave::DVec3::new(5.0, 0.0, 0.0));
    m.uvs = Some(vec![[0.25, 0.5]; m.positions.len()]);
    let mesh = dir.path().join("uv.obj");
    write_mesh(&m, &mesh, None).unwrap();
    let back = read_mesh(&mesh, None).unwrap();
    assert!(
        back.uvs.is_some() || back.face_uvs.is_some(),
        "the OBJ keeps its uvs"
    );
    // Standard error of a command that must succeed.
    let warnings = |cmd: &str, input: &std::path::Path, out: &str| {
        let out = dir.path().join(out);
        let o = run(&[cmd, input.to_str().unwrap(), "-o", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(0), "{cmd}");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = warnings("encode", &mesh, "uv.swv");
    assert!(
        e.contains("not coded: 1 vertex no face uses, texture coordinates"),
        "{e}"
    );
    let e = warnings("compress-base", &mesh, "uv.swb");
    assert!(
        e.contains("not coded: texture coordinates (a base-mesh stream"),
        "{e}"
    );
    // A mesh with nothing to drop gets no such line.
    let plain = dir.path().join("plain.obj");
    let m = generate::midpoint_split(&generate::icosahedron());
    write_mesh(&m, &plain, None).unwrap();
    assert!(!warnings("encode", &plain, "plain.swv").contains("not coded"));
}
