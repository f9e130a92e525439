//! `subwave compress-base` and `subwave decompress-base`: the base-mesh coder
//! (`subwave::codec::basemesh`) on a mesh file.

use std::io::Write;
use std::time::Instant;

use anyhow::{Context, Result};
use subwave::codec::basemesh::{self, BaseMeshOptions};

use crate::print;
use crate::{CompressBaseArgs, DecompressBaseArgs};

/// The sizes `compress-base --json` prints.
#[derive(serde::Serialize)]
struct Report {
    vertices: u64,
    faces: u64,
    position_bits: u32,
    bytes: usize,
    connectivity_bits: u64,
    positions_bits: u64,
    crease_bits: u64,
    header_bits: u64,
    connectivity_bpv: f64,
    positions_bpv: f64,
    crease_bpv: f64,
    total_bpv: f64,
    encode_ms: f64,
    decode_ms: f64,
    /// The input file's vertices: a repair codes more (split) or fewer (unreferenced ones
    /// dropped).
    input_vertices: usize,
    /// Connectivity bits per input vertex.
    connectivity_bpv_input: f64,
    /// What `--repair` changed, if it was given and the mesh needed it.
    repair: Option<subwave::remesh::RepairReport>,
}

/// Runs `subwave compress-base`.
pub fn compress(args: &CompressBaseArgs) -> Result<()> {
    let mut mesh = subwave::io::read_mesh(&args.mesh, None)?;
    crate::info::require_content(&mesh, &args.mesh)?;
    crate::encode::warn_dropped(
        &mut mesh,
        &crate::print::path(&args.mesh),
        None,
        "a base-mesh stream",
    );
    let input_vertices = mesh.num_vertices();
    // Only a mesh the coder refuses as it is gets repaired (a manifold one is coded as is).
    let needs_repair = args.repair
        && mesh.num_faces() > 0
        && subwave::remesh::repair::prepare(&mesh, false).is_err();
    let repair = if needs_repair {
        let (pos, tris, report) = subwave::remesh::repair::prepare(&mesh, true)
            .with_context(|| format!("{}", args.mesh.display()))?;
        if !mesh.edge_tags.is_empty() || !mesh.vertex_tags.is_empty() {
            tracing::warn!(
                "{}: --repair drops the crease and corner tags",
                args.mesh.display()
            );
        }
        mesh = subwave::Mesh::from_triangles(pos, &tris);
        Some(report)
    } else {
        None
    };
    let opts = BaseMeshOptions {
        position_bits: args.bits,
    };
    let t0 = Instant::now();
    let e = basemesh::encode_with_info(&mesh, &opts).map_err(|e| {
        // A mesh the repair would make codable: say so.
        let hint = if !args.repair
            && mesh.num_faces() > 0
            && subwave::remesh::repair::prepare(&mesh, false).is_err()
            && subwave::remesh::repair::prepare(&mesh, true).is_ok()
        {
            " (pass --repair to code it with its non-manifold vertices and edges split)"
        } else {
            ""
        };
        anyhow::anyhow!("{}: {e}{hint}", args.mesh.display())
    })?;
    let encode_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t0 = Instant::now();
    basemesh::decode(&e.bytes)?;
    let decode_ms = t0.elapsed().as_secs_f64() * 1e3;
    std::fs::write(&args.output, &e.bytes).with_context(|| format!("{}", args.output.display()))?;
    let s = e.stats;
    let nv = (s.vertices as f64).max(1.0);
    let r = Report {
        vertices: s.vertices,
        faces: s.faces,
        position_bits: args.bits,
        bytes: e.bytes.len(),
        connectivity_bits: s.connectivity_bits,
        positions_bits: s.position_bits,
        crease_bits: s.crease_bits,
        header_bits: s.header_bits,
        connectivity_bpv: s.connectivity_bits as f64 / nv,
        positions_bpv: s.position_bits as f64 / nv,
        crease_bpv: s.crease_bits as f64 / nv,
        total_bpv: 8.0 * e.bytes.len() as f64 / nv,
        encode_ms,
        decode_ms,
        input_vertices,
        connectivity_bpv_input: s.connectivity_bits as f64 / (input_vertices as f64).max(1.0),
        repair,
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&r)?)?;
    } else {
        writeln!(
            out,
            "{} -> {} ({} bits per coordinate)",
            print::path(&args.mesh),
            print::path(&args.output),
            args.bits
        )?;
        if let Some(rep) = &r.repair {
            writeln!(
                out,
                "  repaired: {} non-manifold vertices and {} edges split ({} vertices added), {} faces flipped, {} degenerate and {} duplicate faces and {} unreferenced vertices dropped",
                rep.non_manifold_vertices,
                rep.non_manifold_edges,
                rep.added_vertices,
                rep.flipped_faces,
                rep.degenerate_faces,
                rep.duplicate_faces,
                rep.unreferenced_vertices
            )?;
        }
        let mut t = print::Table::new();
        t.row("vertices", print::count(r.vertices as usize))
            .row("faces", print::count(r.faces as usize))
            .row("size", print::size(r.bytes as u64))
            .row(
                "connectivity",
                if r.vertices as usize == r.input_vertices {
                    format!("{:.3} bits/vertex", r.connectivity_bpv)
                } else {
                    format!(
                        "{:.3} bits/vertex ({:.3} per input vertex)",
                        r.connectivity_bpv, r.connectivity_bpv_input
                    )
                },
            )
            .row("positions", format!("{:.3} bits/vertex", r.positions_bpv))
            .row("creases", format!("{:.3} bits/vertex", r.crease_bpv))
            .row("total", format!("{:.3} bits/vertex", r.total_bpv))
            .row("encode", format!("{encode_ms:.2} ms"))
            .row("decode", format!("{decode_ms:.2} ms"));
        t.write(&mut out, "  ")?;
    }
    out.flush()?;
    Ok(())
}

/// Runs `subwave decompress-base`.
pub fn decompress(args: &DecompressBaseArgs) -> Result<()> {
    let bytes = std::fs::read(&args.input).with_context(|| format!("{}", args.input.display()))?;
    let mesh = basemesh::decode(&bytes).with_context(|| format!("{}", args.input.display()))?;
    subwave::io::write_mesh(&mesh, &args.output, None)?;
    Ok(())
}
