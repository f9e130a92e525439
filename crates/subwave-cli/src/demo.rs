//! `subwave demo`: the main job on the embedded default input.
//!
//! The demo is a list of [`STEPS`] run in order over a shared [`Demo`] state. Each step does
//! one thing (generate, validate, write meshes, ...), may add a section to `report.json`
//! ([`Demo::sections`]) and files to the output folder ([`Demo::write_file`]), and returns a
//! one-line summary. To extend the demo (subdivision, wavelets, coding, ...), write a step
//! function and insert it in [`STEPS`] before `write report`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use serde_json::{json, Map, Value};
use subwave::io::{write_mesh, Format};
use subwave::validate::{self, MeshReport};
use subwave::{Error, Mesh, Topology};

use crate::print::{self, count};
use crate::DemoArgs;

/// Base name of the mesh files the demo writes.
const MESH_NAME: &str = "five-blobs";

/// One step of the demo.
struct Step {
    /// Shown in the progress lines.
    name: &'static str,
    /// Does the work and returns a one-line summary.
    run: fn(&mut Demo) -> Result<String>,
}

/// The steps, in order.
const STEPS: &[Step] = &[
    Step {
        name: "generate",
        run: generate,
    },
    Step {
        name: "validate",
        run: validate_mesh,
    },
    Step {
        name: "write meshes",
        run: write_meshes,
    },
    Step {
        name: "wavelets",
        run: wavelets,
    },
    Step {
        name: "encode",
        run: encode_stream,
    },
    Step {
        name: "decode + measure",
        run: decode_progressively,
    },
    Step {
        name: "write report",
        run: write_report,
    },
];

/// A file the demo wrote.
struct Written {
    path: PathBuf,
    bytes: u64,
    what: String,
}

/// The state the steps share.
struct Demo {
    out: PathBuf,
    levels: u32,
    mesh: Option<Mesh>,
    report: Option<MeshReport>,
    /// Top-level sections of `report.json` (written with sorted keys).
    sections: Map<String, Value>,
    files: Vec<Written>,
    /// The progressive stream of the mesh (step `encode`).
    stream: Option<Vec<u8>>,
    /// Its rate-distortion points (step `decode`).
    rd: Vec<subwave::codec::eval::RdPoint>,
}

impl Demo {
    fn mesh(&self) -> Result<&Mesh> {
        self.mesh
            .as_ref()
            .context("internal: the demo has no mesh yet (step order)")
    }

    /// Records a file written into the output folder.
    fn record(&mut self, path: PathBuf, what: impl Into<String>) -> Result<()> {
        let bytes = std::fs::metadata(&path)
            .with_context(|| {
                format!(
                    "{}: cannot read the size of the file just written",
                    path.display()
                )
            })?
            .len();
        self.files.push(Written {
            path,
            bytes,
            what: what.into(),
        });
        Ok(())
    }

    /// Writes `contents` to `name` in the output folder and records it.
    fn write_file(&mut self, name: &str, contents: &[u8], what: &str) -> Result<()> {
        let path = self.out.join(name);
        std::fs::write(&path, contents).map_err(|source| Error::Io {
            path: print::path(&path),
            source,
        })?;
        self.record(path, what)
    }
}

fn generate(d: &mut Demo) -> Result<String> {
    let mesh = subwave::generate::five_blobs(d.levels);
    let line = format!(
        "five blobs (Bertram §5.1), {} level(s): {} vertices, {} triangles",
        d.levels,
        count(mesh.num_vertices()),
        count(mesh.num_faces())
    );
    d.sections.insert(
        "input".to_string(),
        json!({
            "name": MESH_NAME,
            "generator": "subwave::generate::five_blobs",
            "levels": d.levels,
        }),
    );
    d.mesh = Some(mesh);
    Ok(line)
}

fn validate_mesh(d: &mut Demo) -> Result<String> {
    let mesh = d.mesh()?;
    mesh.check_indices().map_err(|source| Error::InvalidMesh {
        path: MESH_NAME.to_string(),
        source,
    })?;
    let topo = Topology::build(mesh);
    let rep = validate::report(mesh, &topo);
    validate::require_manifold(&topo).map_err(|source| Error::InvalidMesh {
        path: MESH_NAME.to_string(),
        source,
    })?;
    let line = format!("2-manifold; {}", print::report_line(&rep));
    d.sections
        .insert("mesh".to_string(), serde_json::to_value(&rep)?);
    d.report = Some(rep);
    Ok(line)
}

fn write_meshes(d: &mut Demo) -> Result<String> {
    let mut names = Vec::new();
    for format in [Format::Obj, Format::Ply, Format::Glb] {
        let name = format!("{MESH_NAME}.{}", format.name());
        let path = d.out.join(&name);
        write_mesh(d.mesh()?, &path, Some(format))?;
        d.record(path, format!("the mesh, {}", describe(format)))?;
        names.push(name);
    }
    Ok(names.join(", "))
}

fn describe(format: Format) -> &'static str {
    match format {
        Format::Obj => "Wavefront OBJ",
        Format::Off => "OFF",
        Format::Ply => "binary PLY",
        Format::Stl => "binary STL",
        Format::Glb => "binary glTF (opens in any glTF viewer)",
    }
}

/// Detects the five blobs' subdivision connectivity and runs the Loop and lifted butterfly
/// wavelets on it (local frames): per-level errors, detail sizes, reconstruction error.
fn wavelets(d: &mut Demo) -> Result<String> {
    use subwave::wavelet::report::{analyze_report, WaveletKind};
    use subwave::wavelet::triangle::DetailFrame;
    if d.levels == 0 {
        return Ok("skipped: the mesh has no subdivision level".to_string());
    }
    let mesh = d.mesh()?.clone();
    let mut reports = Vec::new();
    for kind in [WaveletKind::Loop, WaveletKind::ButterflyLifted] {
        reports.push(analyze_report(&mesh, kind, DetailFrame::Local)?);
    }
    let r = &reports[0];
    let mean = |j: usize| r.levels.get(j).map_or(0.0, |l| l.mean_detail);
    let last = r.num_levels.saturating_sub(1);
    let compaction = if mean(last) > 0.0 {
        mean(0) / mean(last)
    } else {
        f64::INFINITY
    };
    d.sections
        .insert("wavelets".to_string(), serde_json::to_value(&reports)?);
    Ok(format!(
        "{} levels over a {}-vertex base; Loop: details shrink {:.0}x from coarsest to finest, base RMS error {:.3}% of the diagonal, reconstruction {:.1e}; lifted butterfly: {:.1e}",
        r.num_levels,
        r.base_vertices,
        compaction,
        r.levels.first().map_or(0.0, |l| l.l2_percent),
        r.reconstruction_max_error,
        reports[1].reconstruction_max_error
    ))
}

/// Encodes the five blobs (semi-regular: detected, not remeshed) into an embedded progressive
/// stream with the default options (lifted butterfly wavelet, local frames, SPIHT).
fn encode_stream(d: &mut Demo) -> Result<String> {
    use subwave::codec::prepare::{prepare, PrepareOptions};
    use subwave::codec::progressive::{encode, inspect, EncodeOptions};
    if d.levels == 0 {
        return Ok("skipped: the mesh has no subdivision level".to_string());
    }
    let mesh = d.mesh()?.clone();
    let h = prepare(&mesh, &PrepareOptions::default(), &mut |_, _| {})?.hierarchy;
    let mut opts = EncodeOptions::for_hierarchy(&h);
    opts.input_vertices = Some(mesh.num_vertices() as u32);
    let bytes = encode(&h, &opts)?;
    let info = inspect(&bytes)?;
    let name = format!("{MESH_NAME}.swv");
    d.write_file(
        &name,
        &bytes,
        "progressive stream (embedded layout; `subwave decode` reads any prefix)",
    )?;
    d.sections.insert(
        "stream".to_string(),
        json!({
            "file": name,
            "bytes": bytes.len(),
            "header_bytes": info.header_bytes,
            "base_bytes": info.base_bytes,
            "wavelet": info.wavelet.name(),
            "levels": info.levels,
            "bit_planes": info.planes,
        }),
    );
    let line = format!(
        "{name}: {} bytes ({:.2} bits per vertex), {} wavelet, {} levels, {} bit planes",
        bytes.len(),
        8.0 * bytes.len() as f64 / mesh.num_vertices().max(1) as f64,
        info.wavelet.name(),
        info.levels,
        info.planes
    );
    d.stream = Some(bytes);
    Ok(line)
}

/// Decodes the stream progressively: prefixes at 8 byte budgets from the base mesh to the
/// whole stream, each written as a mesh and measured against the input; the plot as SVG.
fn decode_progressively(d: &mut Demo) -> Result<String> {
    use subwave::codec::eval::{budgets, rate_distortion};
    use subwave::codec::progressive::{decode, inspect, DecodeOptions};
    let Some(bytes) = d.stream.take() else {
        return Ok("skipped: no stream".to_string());
    };
    let mesh = d.mesh()?.clone();
    let info = inspect(&bytes)?;
    let cuts = budgets(info.header_bytes + info.base_bytes, bytes.len(), 8)?;
    let decode_at = |b: usize| {
        decode(
            &bytes,
            &DecodeOptions {
                max_bytes: Some(b),
                trees: None,
            },
        )
        .map(|x| x.mesh)
    };
    let rd = rate_distortion(&mesh, &cuts, 100_000, decode_at)?;
    for p in &rd {
        let name = format!("{MESH_NAME}-{:07}B.obj", p.bytes);
        let path = d.out.join(&name);
        write_mesh(&decode_at(p.bytes)?, &path, Some(Format::Obj))?;
        d.record(
            path,
            format!(
                "decoded from the first {} bytes: PSNR {:.1} dB",
                p.bytes, p.psnr
            ),
        )?;
    }
    let pts: Vec<(f64, f64)> = rd.iter().map(|p| (p.bpv, p.psnr)).collect();
    let svg = crate::svg::plot(
        "five blobs: progressive decoding",
        "bits per vertex",
        "PSNR (dB)",
        &[crate::svg::Series {
            name: "subwave (embedded stream)",
            points: &pts,
        }],
    );
    d.write_file(
        "rate-distortion.svg",
        svg.as_bytes(),
        "PSNR against bits per vertex of the decoded prefixes (SVG)",
    )?;
    d.sections
        .insert("rate_distortion".to_string(), serde_json::to_value(&rd)?);
    let (first, last) = (rd[0], rd[rd.len() - 1]);
    let line = format!(
        "{} prefixes: {} bytes -> {:.1} dB ... {} bytes -> {:.1} dB",
        rd.len(),
        first.bytes,
        first.psnr,
        last.bytes,
        last.psnr
    );
    d.rd = rd;
    d.stream = Some(bytes);
    Ok(line)
}

fn write_report(d: &mut Demo) -> Result<String> {
    let mut root = Map::new();
    root.insert(
        "subwave_version".to_string(),
        json!(env!("CARGO_PKG_VERSION")),
    );
    root.extend(std::mem::take(&mut d.sections));
    root.insert(
        "outputs".to_string(),
        Value::Array(
            d.files
                .iter()
                .map(|f| {
                    json!({
                        "file": f.path.file_name().map(|n| n.to_string_lossy().into_owned()),
                        "bytes": f.bytes,
                    })
                })
                .collect(),
        ),
    );
    let mut text = serde_json::to_vec_pretty(&Value::Object(root))?;
    text.push(b'\n');
    d.write_file(
        "report.json",
        &text,
        "the mesh report and the list of outputs (JSON)",
    )?;
    Ok("report.json".to_string())
}

pub fn run(args: &DemoArgs) -> Result<()> {
    let mut out = std::io::stdout().lock();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create the output folder {}", args.out.display()))?;
    let mut demo = Demo {
        out: args.out.clone(),
        levels: args.levels,
        mesh: None,
        report: None,
        sections: Map::new(),
        files: Vec::new(),
        stream: None,
        rd: Vec::new(),
    };
    writeln!(out, "subwave demo -> {}", display_dir(&args.out))?;
    let start = Instant::now();
    let mut timings: Vec<(&str, Duration)> = Vec::new();
    for (i, step) in STEPS.iter().enumerate() {
        let t = Instant::now();
        let line = (step.run)(&mut demo).with_context(|| format!("demo step `{}`", step.name))?;
        let took = t.elapsed();
        timings.push((step.name, took));
        writeln!(
            out,
            "[{}/{}] {:<16} {} ({})",
            i + 1,
            STEPS.len(),
            step.name,
            line,
            print::duration(took)
        )?;
        out.flush()?;
    }
    let total = start.elapsed();

    if let Some(rep) = &demo.report {
        writeln!(out, "\nmesh report")?;
        print::report_table(rep).write(&mut out, "  ")?;
    }
    if !demo.rd.is_empty() {
        writeln!(out, "\nprogressive decoding (PSNR against the input)")?;
        writeln!(
            out,
            "  {:>9} {:>7} {:>11} {:>11} {:>7}",
            "bytes", "bpv", "rms", "hausdorff", "psnr"
        )?;
        for p in &demo.rd {
            writeln!(
                out,
                "  {:>9} {:>7.3} {:>11.4e} {:>11.4e} {:>7.2}",
                p.bytes, p.bpv, p.rms, p.max, p.psnr
            )?;
        }
    }
    writeln!(out, "\nfiles")?;
    let mut files = print::Table::new();
    for f in &demo.files {
        files.row(
            print::path(&f.path),
            format!("{:>10}  {}", print::size(f.bytes), f.what),
        );
    }
    files.write(&mut out, "  ")?;
    writeln!(out, "\ntimings")?;
    let mut times = print::Table::new();
    for (name, took) in &timings {
        times.row(*name, format!("{:>10}", print::duration(*took)));
    }
    times.row("total", format!("{:>10}", print::duration(total)));
    times.write(&mut out, "  ")?;
    out.flush()?;
    Ok(())
}

fn display_dir(p: &Path) -> String {
    let s = print::path(p);
    if s.ends_with(std::path::MAIN_SEPARATOR) {
        s
    } else {
        format!("{s}{}", std::path::MAIN_SEPARATOR)
    }
}
