//! `subwave eval`: the rate–distortion table of the progressive codec on a mesh — the stream
//! cut at several byte budgets, each prefix decoded and measured against the input — with an
//! SVG plot and, optionally, a peer's curve (Draco, from `../shared/peers/draco_rd.py`) for a
//! side-by-side comparison at equal PSNR.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::json;
use subwave::codec::direct;
use subwave::codec::eval::{self, bpv_at_psnr, RdPoint};
use subwave::codec::prepare::{prepare_screened, Prepared};
use subwave::codec::progressive::{decode, encode, inspect, DecodeOptions, EncodeOptions};
use subwave::io::read_mesh;

use crate::encode::DirectArg;
use crate::svg::{self, Series};
use crate::{print, progress, EvalArgs};

/// A reference curve read from a peer's output.
struct Reference {
    name: String,
    points: Vec<RdPoint>,
}

/// Parses `draco_rd.py`-style lines (`NAME V=.. draco qp=.. bytes=.. bpv=.. psnr=..dB ...`):
/// the lines whose first word is `mesh_file`, or all lines if they are all of one other mesh
/// (the mesh was renamed), sorted by rate.
fn parse_reference(text: &str, path: &Path, mesh_file: &str) -> Result<Reference> {
    let mut all = Vec::new();
    let mut mine = Vec::new();
    let mut meshes = std::collections::BTreeSet::new();
    let mut name = String::from("reference");
    for (i, line) in text.lines().enumerate() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let field = |key: &str| {
            words
                .iter()
                .find_map(|w| w.strip_prefix(key).and_then(|v| v.strip_prefix('=')))
        };
        let (Some(bpv), Some(psnr)) = (field("bpv"), field("psnr")) else {
            continue;
        };
        let num = |s: &str, what: &str| -> Result<f64> {
            s.trim_end_matches("dB")
                .parse::<f64>()
                .with_context(|| format!("{}:{}: bad {what} value `{s}`", path.display(), i + 1))
        };
        let p = RdPoint {
            bytes: match field("bytes") {
                Some(b) => num(b, "bytes")? as usize,
                None => 0,
            },
            bpv: num(bpv, "bpv")?,
            rms: f64::NAN,
            max: f64::NAN,
            psnr: num(psnr, "psnr")?,
        };
        if let Some(n) = words.get(2).filter(|w| !w.contains('=')) {
            name = n.to_string();
        }
        meshes.insert(words.first().copied().unwrap_or_default().to_string());
        if words.first() == Some(&mesh_file) {
            mine.push(p);
        }
        all.push(p);
    }
    if mine.is_empty() && meshes.len() > 1 {
        bail!(
            "{}: no line is about `{mesh_file}`, and the file has lines of {} meshes ({}): keep \
             the lines of this mesh only",
            path.display(),
            meshes.len(),
            meshes.into_iter().collect::<Vec<_>>().join(", ")
        );
    }
    let mut points = if mine.is_empty() { all } else { mine };
    if points.is_empty() {
        bail!(
            "{}: no rate-distortion line (`... bpv=X psnr=YdB ...`) found",
            path.display()
        );
    }
    points.sort_by(|a, b| a.bpv.total_cmp(&b.bpv));
    Ok(Reference { name, points })
}

fn options(args: &EvalArgs, prep: &Prepared) -> EncodeOptions {
    let mut o = prep.encode_options();
    if let Some(w) = args.wavelet {
        o.wavelet = w.into();
    }
    if let Some(f) = args.frames {
        o.frames = f.into();
    }
    if let Some(b) = args.bits {
        o.bits = b;
        o.max_rms = None;
    }
    o.lifted &= !args.unlifted;
    o.level_exponent = args.level_exponent;
    o.tangent_shift = args.tangent_shift;
    o
}

/// The mesh's file name (the key of its lines in a peer's points).
fn file_name(args: &EvalArgs) -> String {
    args.mesh
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Runs `subwave eval`.
pub fn run(args: &EvalArgs) -> Result<()> {
    let name = print::path(&args.mesh);
    let mut mesh = read_mesh(&args.mesh, args.format)?;
    crate::encode::warn_uncoded(&mut mesh, &name);
    let references = args
        .reference
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).with_context(|| p.display().to_string())?;
            parse_reference(&text, p, &file_name(args))
        })
        .collect::<Result<Vec<_>>>()?;
    let t0 = Instant::now();
    if args.prep.direct == DirectArg::Always {
        let bits = args.bits.unwrap_or(direct::DEFAULT_BITS);
        if bits < direct::COARSE_BITS {
            bail!(
                "--bits {bits}: a direct stream has at least {} bits",
                direct::COARSE_BITS
            );
        }
        let bytes = crate::encode::direct_stream(&mesh, bits, &name)?;
        let encode_ms = t0.elapsed().as_secs_f64() * 1e3;
        return report(args, &mesh, &references, None, &bytes, encode_ms, None);
    }
    let quads = crate::encode::PrepareArgs::quads(args.wavelet);
    // `--direct auto`, as `subwave encode` weighs it: where the direct stream beats a remesh
    // that would be redone with more levels at its first two budgets, that is not done.
    let auto = args.prep.direct == DirectArg::Auto;
    let mut screened: Option<(Vec<u8>, direct::Comparison)> = None;
    let prep = progress::with_bar("prepare", args.json, |cb| {
        prepare_screened(&mesh, &args.prep.options(quads), cb, &mut |p| {
            if !auto {
                return Ok(true);
            }
            let mut o = options(args, p);
            o.input_vertices = Some(mesh.num_vertices() as u32);
            let wavelet = encode(&p.hierarchy, &o)?;
            screened = crate::encode::screen_direct(&mesh, &wavelet, &name);
            Ok(screened.is_none())
        })
    })
    .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    if let Some((direct, c)) = screened {
        if !args.json {
            println!(
                "{}; the remesh was not redone with more levels",
                crate::encode::comparison_line(&c, true)
            );
        }
        let encode_ms = t0.elapsed().as_secs_f64() * 1e3;
        return report(args, &mesh, &references, None, &direct, encode_ms, Some(c));
    }
    if let Some(line) = print::input_distance(&prep, mesh.diagonal()).filter(|_| !args.json) {
        println!("{line}");
    }
    if let (Some(n), false) = (&prep.normal, args.json) {
        println!("{}", print::normal_stats(n));
    } else if let (Some(f), false) = (&prep.fit, args.json) {
        println!("MAPS remesh: {}", print::fit_stats(f));
    }
    let mut opts = options(args, &prep);
    opts.input_vertices = Some(mesh.num_vertices() as u32);
    let bytes = encode(&prep.hierarchy, &opts).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    // `--direct auto`: the direct stream where it serves the input better.
    let weighed = if args.prep.direct == DirectArg::Auto && prep.remeshed.is_some() {
        crate::encode::weigh_direct(&mesh, &bytes, &name)
    } else {
        None
    };
    let encode_ms = t0.elapsed().as_secs_f64() * 1e3;
    let chosen = weighed.as_ref().is_some_and(|(_, c)| c.prefer_direct());
    if let (Some((_, c)), false) = (&weighed, args.json) {
        println!("{}", crate::encode::comparison_line(c, chosen));
    }
    match weighed {
        Some((direct, c)) if chosen => {
            report(args, &mesh, &references, None, &direct, encode_ms, Some(c))
        }
        w => report(
            args,
            &mesh,
            &references,
            Some((&prep, &opts)),
            &bytes,
            encode_ms,
            w.map(|(_, c)| c),
        ),
    }
}

/// Measures the stream `bytes` of `mesh` at the budgets of `args` and prints the table (or
/// JSON) and the plot: a wavelet stream with what `prep` made of the input and its options,
/// or (`prep` `None`) a direct stream; `comparison`: how the direct stream compared with the
/// remesh's, if it was weighed.
fn report(
    args: &EvalArgs,
    mesh: &subwave::Mesh,
    references: &[Reference],
    prep: Option<(&Prepared, &EncodeOptions)>,
    bytes: &[u8],
    encode_ms: f64,
    comparison: Option<direct::Comparison>,
) -> Result<()> {
    let name = print::path(&args.mesh);
    let file_name = file_name(args);
    let info = inspect(bytes)?;
    let first = info.header_bytes + info.base_bytes;
    let budgets = eval::budgets(first.max(1), bytes.len(), args.points as usize)?;
    let points = eval::rate_distortion(mesh, &budgets, args.samples, |b| {
        let d = decode(
            bytes,
            &DecodeOptions {
                max_bytes: Some(b),
                trees: None,
            },
        )?;
        Ok(d.mesh)
    })
    .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    // Each point's bytes beside the reference's rate at the same PSNR.
    let ratio = |r: &Reference, p: &RdPoint| bpv_at_psnr(&r.points, p.psnr).map(|x| p.bpv / x);

    if let Some(svg_path) = &args.svg {
        let mine: Vec<(f64, f64)> = points.iter().map(|p| (p.bpv, p.psnr)).collect();
        let refs: Vec<Vec<(f64, f64)>> = references
            .iter()
            .map(|r| r.points.iter().map(|p| (p.bpv, p.psnr)).collect())
            .collect();
        let label = match prep {
            Some((_, opts)) => format!("subwave ({})", opts.wavelet.name()),
            None => "subwave (direct)".to_string(),
        };
        let mut series = vec![Series {
            name: &label,
            points: &mine,
        }];
        for (r, pts) in references.iter().zip(&refs) {
            series.push(Series {
                name: &r.name,
                points: pts,
            });
        }
        let text = svg::plot(
            &format!("{file_name}: rate-distortion"),
            "bits per input vertex",
            "PSNR (dB)",
            &series,
        );
        std::fs::write(svg_path, text).with_context(|| svg_path.display().to_string())?;
    }

    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let refs = references
            .iter()
            .map(|r| json!({
                "name": r.name,
                "points": r.points.iter().map(|p| json!({"bytes": p.bytes, "bpv": p.bpv, "psnr": p.psnr})).collect::<Vec<_>>(),
                "ratios": points.iter().map(|p| ratio(r, p)).collect::<Vec<_>>(),
            }))
            .collect::<Vec<_>>();
        // The keys of every stream, then those of a wavelet or a direct stream.
        let mut v = json!({
            "input": args.mesh.display().to_string(),
            "input_vertices": mesh.num_vertices(),
            "direct": prep.is_none(),
            "direct_comparison": comparison,
            "stream_bytes": bytes.len(),
            "header_bytes": info.header_bytes,
            "base_bytes": info.base_bytes,
            "encode_ms": encode_ms,
            "points": points,
            "references": refs,
        });
        let more = match prep {
            Some((prep, opts)) => {
                let h = &prep.hierarchy;
                json!({
                    "remeshed": prep.remeshed.is_some(),
                    "method": prep.remeshed.as_ref().map(|r| r.method.name()),
                    "normal_mesh": prep.normal.is_some(),
                    "fit": prep.fit,
                    "sharp_angle": prep.sharp_angle,
                    "features_detected": prep.features_detected,
                    "remesh_rms": prep.remesh_rms,
                    "input_rms": prep.input_distance.map(|d| d.0),
                    "input_max": prep.input_distance.map(|d| d.1),
                    "missed": prep.missed,
                    "raised": prep.raised,
                    "levels": h.levels(),
                    "base_faces": h.base.num_faces(),
                    "coded_vertices": h.positions.len(),
                    "wavelet": opts.wavelet.name(),
                })
            }
            None => json!({
                "remeshed": false,
                "levels": 0,
                "coded_vertices": info.base_vertices,
                "bits": info.bits,
                "planes": info.planes,
            }),
        };
        if let (Some(v), serde_json::Value::Object(more)) = (v.as_object_mut(), more) {
            v.extend(more);
        }
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(());
    }
    match prep {
        Some((prep, opts)) => {
            let h = &prep.hierarchy;
            writeln!(
                out,
                "{name}: {} vertices; {}{} levels over {} base faces -> {} vertices; {} wavelet; {} bytes in {:.0} ms",
                mesh.num_vertices(),
                match &prep.remeshed {
                    Some(r) => format!(
                        "remeshed ({}{}{}), ",
                        r.method.name(),
                        if prep.normal.is_some() {
                            ", normal mesh"
                        } else {
                            ""
                        },
                        match (prep.sharp_angle, prep.features_detected) {
                            (Some(a), true) => format!(", creases above {a}° detected"),
                            (Some(a), false) => format!(", creases above {a}°"),
                            _ => String::new(),
                        }
                    ),
                    None => String::new(),
                },
                h.levels(),
                h.base.num_faces(),
                h.positions.len(),
                opts.wavelet.name(),
                bytes.len(),
                encode_ms
            )?;
        }
        None => writeln!(
            out,
            "{name}: {} vertices; coded as it is (direct stream: {} bits, {} refinement planes); {} bytes in {:.0} ms",
            mesh.num_vertices(),
            info.bits,
            info.planes,
            bytes.len(),
            encode_ms
        )?,
    }
    let mut header = format!(
        "  {:>9} {:>7} {:>11} {:>11} {:>7}",
        "bytes", "bpv", "rms", "hausdorff", "psnr"
    );
    for r in references {
        header.push_str(&format!(
            " {:>12} {:>6}",
            format!("{} bpv", r.name),
            "ratio"
        ));
    }
    writeln!(out, "{header}")?;
    for p in &points {
        let mut line = format!(
            "  {:>9} {:>7.3} {:>11.4e} {:>11.4e} {:>7.2}",
            p.bytes, p.bpv, p.rms, p.max, p.psnr
        );
        for r in references {
            match bpv_at_psnr(&r.points, p.psnr) {
                Some(x) => line.push_str(&format!(" {:>12.3} {:>6.2}", x, p.bpv / x)),
                None => line.push_str(&format!(" {:>12} {:>6}", "-", "-")),
            }
        }
        writeln!(out, "{line}")?;
    }
    if let Some(p) = &args.svg {
        writeln!(out, "wrote {}", p.display())?;
    }
    out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draco_lines_are_parsed_and_filtered_by_mesh() {
        let text = "\
stanford-bunny.obj V=34834 draco qp=10 bytes=35273 bpv=8.10 psnr=78.1dB decode=11.30ms
stanford-bunny.obj V=34834 draco qp=8 bytes=23892 bpv=5.49 psnr=65.9dB decode=15.59ms
fandisk.obj V=6475 draco qp=8 bytes=5476 bpv=6.77 psnr=63.5dB decode=3.24ms
";
        let r = parse_reference(text, Path::new("d.txt"), "stanford-bunny.obj").unwrap();
        assert_eq!(r.name, "draco");
        assert_eq!(r.points.len(), 2);
        assert_eq!((r.points[0].bytes, r.points[0].bpv), (23892, 5.49));
        assert_eq!(r.points[1].psnr, 78.1);
        let e = parse_reference(text, Path::new("d.txt"), "other.obj")
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("lines of 2 meshes"), "{e}");
        let one = text.lines().take(2).collect::<Vec<_>>().join("\n");
        let r = parse_reference(&one, Path::new("d.txt"), "bunny-copy.obj").unwrap();
        assert_eq!(r.points.len(), 2);
        let e = parse_reference("nothing here\n", Path::new("d.txt"), "x")
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("d.txt") && e.contains("no rate-distortion line"),
            "{e}"
        );
        let e = parse_reference("m bpv=x psnr=3dB\n", Path::new("d.txt"), "m")
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("d.txt:1: bad bpv value `x`"), "{e}");
    }
}
