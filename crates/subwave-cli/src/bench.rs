//! `subwave bench ...`: timings without file output (medians of several runs).

use std::io::Write;

use anyhow::Result;
use subwave::subdivision::loop_scheme::LoopWeights;
use subwave::subdivision::profile::profile_subdivide;
use subwave::subdivision::SubdivideOptions;

use crate::print;
use crate::subdivide::{boundary_mode, creasing, scheme};
use crate::BenchSubdivideArgs;

/// Runs `subwave bench subdivide`.
pub fn subdivide(args: &BenchSubdivideArgs) -> Result<()> {
    let name = print::path(&args.mesh);
    let mut mesh = subwave::io::read_mesh(&args.mesh, args.format)?;
    crate::info::require_faces(&mesh, &args.mesh, "subdivide")?;
    mesh.remove_unreferenced();
    let opts = SubdivideOptions {
        scheme: scheme(args.scheme),
        levels: args.levels,
        boundary: boundary_mode(args.boundary),
        creasing: creasing(args.creasing),
        loop_weights: LoopWeights::Loop,
        sharp_angle: args.sharp_angle,
    };
    crate::subdivide::check_memory(&mesh, &opts, &args.mesh)?;
    let p = profile_subdivide(&mesh, &opts, args.runs as usize)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.mesh.display()))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let text = serde_json::to_string_pretty(&p)?;
        writeln!(out, "{text}")?;
    } else {
        let mb = |x: Option<f64>| x.map_or("n/a".to_string(), |x| format!("{x:.0} MiB"));
        writeln!(
            out,
            "{name}: {} levels of {} ({} vertices, {} faces -> {} vertices, {} faces), median of {} runs",
            args.levels,
            opts.scheme.name(),
            mesh.num_vertices(),
            mesh.num_faces(),
            p.vertices,
            p.faces,
            p.runs
        )?;
        let mut t = print::Table::new();
        let ms = |x: Option<f64>| x.map_or("n/a".to_string(), |x| format!("{x:.1} ms"));
        t.row("topology", ms(p.topology_ms))
            .row("positions", ms(p.positions_ms))
            .row("total", format!("{:.1} ms", p.total_ms))
            .row("peak memory", mb(p.peak_rss_mb))
            .row(
                "stencils",
                format!(
                    "{} to build, {:.0} MiB",
                    ms(p.stencil_build_ms),
                    p.stencil_mb
                ),
            )
            .row("re-evaluation", ms(p.reevaluate_ms))
            .row("peak with stencils", mb(p.peak_rss_reevaluate_mb));
        t.write(&mut out, "  ")?;
    }
    out.flush()?;
    Ok(())
}

/// Runs `subwave bench decode`: the median of full decodes (no file output), alternating
/// decodes in one kept [`DecodeBuffers`](subwave::codec::progressive::DecodeBuffers) (as a
/// progressive viewer decoding prefix after prefix does; the headline figure) with decodes
/// allocating everything afresh (`decode`).
pub fn decode(args: &crate::BenchDecodeArgs) -> Result<()> {
    use subwave::codec::progressive::{decode, decode_with, DecodeBuffers, DecodeOptions};
    let name = print::path(&args.stream);
    let bytes = std::fs::read(&args.stream).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let mut times = Vec::with_capacity(args.runs as usize);
    let mut fresh = Vec::with_capacity(args.runs as usize);
    let mut vertices = 0;
    let mut faces = 0;
    let mut buffers = DecodeBuffers::default();
    for _ in 0..args.runs {
        let t = std::time::Instant::now();
        let d = decode_with(&bytes, &DecodeOptions::default(), &mut buffers)
            .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
        vertices = d.mesh.num_vertices();
        faces = d.mesh.num_faces();
        drop(d);
        let t = std::time::Instant::now();
        let d = decode(&bytes, &DecodeOptions::default())
            .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
        fresh.push(t.elapsed().as_secs_f64() * 1e3);
        drop(d);
    }
    fresh.sort_by(f64::total_cmp);
    let fresh_median = fresh[fresh.len() / 2];
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let v = serde_json::json!({
            "decode_ms": median,
            "vertices": vertices,
            "faces": faces,
            "bytes": bytes.len(),
            "runs": args.runs,
            "min_ms": times[0],
            "fresh_decode_ms": fresh_median,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(
            out,
            "{name}: full decode of {} bytes -> {vertices} vertices, {faces} faces: median {median:.2} ms (min {:.2} ms, {} runs; {fresh_median:.2} ms allocating afresh)",
            bytes.len(),
            times[0],
            args.runs
        )?;
    }
    out.flush()?;
    Ok(())
}

/// Runs `subwave bench entropy`: each bit plane's cumulative coefficient bytes against the
/// empirical entropy of the quantization it completes
/// ([`subwave::codec::entropy::coder_efficiency`]).
pub fn entropy(args: &crate::BenchEntropyArgs) -> Result<()> {
    let name = print::path(&args.stream);
    let bytes = std::fs::read(&args.stream).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let r = subwave::codec::entropy::coder_efficiency(&bytes)
        .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let planes: Vec<_> = r
            .planes
            .iter()
            .map(|p| {
                serde_json::json!({
                    "plane": p.plane,
                    "bytes": p.bytes,
                    "order0_bytes": p.order0_bytes,
                    "parent_bytes": p.parent_bytes,
                })
            })
            .collect();
        let v = serde_json::json!({ "coefficients": r.coefficients, "planes": planes });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(
            out,
            "{name}: {} coefficients; bytes of the coefficient chunks to the end of each bit plane against the empirical entropy of the coefficients known to that plane (order 0 per level and component; given the parent's magnitude)",
            print::count(r.coefficients)
        )?;
        writeln!(
            out,
            "{:>6} {:>10} {:>10} {:>7} {:>12} {:>7}",
            "plane", "bytes", "order 0", "ratio", "given parent", "ratio"
        )?;
        for p in &r.planes {
            let ratio = |h: f64| {
                if h > 0.0 {
                    format!("{:.3}", p.bytes as f64 / h)
                } else {
                    "-".to_string()
                }
            };
            writeln!(
                out,
                "{:>6} {:>10} {:>10.0} {:>7} {:>12.0} {:>7}",
                p.plane,
                p.bytes,
                p.order0_bytes,
                ratio(p.order0_bytes),
                p.parent_bytes,
                ratio(p.parent_bytes)
            )?;
        }
    }
    out.flush()?;
    Ok(())
}
