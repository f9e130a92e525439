//! `subwave encode`: a semi-regular mesh into a progressive `.swv` stream.

use std::io::Write;
use std::time::Instant;

use anyhow::{bail, Result};
use clap::ValueEnum;
use subwave::codec::direct;
use subwave::codec::normal_line::SnapOptions;
use subwave::codec::prepare::{prepare_screened, PrepareOptions, Prepared, Quads};
use subwave::codec::progressive::{encode, inspect, EncodeOptions, Layout, StreamInfo, Wavelet};
use subwave::codec::quantize::ComponentMode;
use subwave::io::read_mesh;
use subwave::mesh::Mesh;
use subwave::subdivision::refine::Split;
use subwave::wavelet::triangle::DetailFrame;

use crate::print;
use crate::EncodeArgs;

/// `--wavelet`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum WaveletArg {
    /// Loop (PGC), triangle meshes.
    Loop,
    /// Modified butterfly, triangle meshes.
    Butterfly,
    /// Midpoint (linear), triangle meshes.
    Midpoint,
    /// Bertram's linear B-spline wavelet, quad meshes.
    Linear,
    /// Bertram's cubic B-spline wavelet, quad meshes.
    Cubic,
}

impl From<WaveletArg> for Wavelet {
    fn from(w: WaveletArg) -> Wavelet {
        match w {
            WaveletArg::Loop => Wavelet::Loop,
            WaveletArg::Butterfly => Wavelet::Butterfly,
            WaveletArg::Midpoint => Wavelet::Midpoint,
            WaveletArg::Linear => Wavelet::Linear,
            WaveletArg::Cubic => Wavelet::Cubic,
        }
    }
}

/// `--frames`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FramesArg {
    /// Local (normal, tangent, bitangent) frames of the predicted surface.
    Local,
    /// Global x, y, z.
    Global,
}

impl From<FramesArg> for DetailFrame {
    fn from(f: FramesArg) -> DetailFrame {
        match f {
            FramesArg::Local => DetailFrame::Local,
            FramesArg::Global => DetailFrame::Global,
        }
    }
}

/// `--layout`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LayoutArg {
    /// One chunk per bit plane: any prefix decodes to the best mesh for its bytes.
    Embedded,
    /// One chunk per tree with per-plane marks (view-dependent streaming).
    Trees,
}

/// `--components`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ComponentsArg {
    /// One quantization step for x, y, z (least significant bits aligned).
    Aligned,
    /// One step per component (MPEG-4 AFX).
    Independent,
}

/// The options of [`subwave::codec::prepare`] shared by `subwave encode` and `subwave eval`.
#[derive(Debug, clap::Args)]
pub struct PrepareArgs {
    /// Subdivision levels: of the remesh of an irregular input (default: the fewest whose
    /// finest level has twice the input's triangles, raised by up to two where that remesh
    /// stays below 80 dB from the input, up to 2^18 finest faces), or required of a
    /// semi-regular input
    /// (default: as many as it has).
    #[arg(long, value_name = "L", value_parser = clap::value_parser!(u32).range(1..=12))]
    pub levels: Option<u32>,
    /// Base faces of the remesh (irregular input only).
    #[arg(long, value_name = "N")]
    pub base_faces: Option<u32>,
    /// Feature edges of the remesh: dihedral angle in degrees (kept sharp as creases).
    /// Default: 40 when the edges sharper than that form a CAD-like crease network
    /// (`codec::prepare::detect_feature_angle`), else none.
    #[arg(long, value_name = "DEG", value_parser = crate::parse_angle)]
    pub sharp_angle: Option<f64>,
    /// Do not detect feature edges when --sharp-angle is not given.
    #[arg(long)]
    pub no_auto_features: bool,
    /// How an irregular input is remeshed: `normal` re-samples the MAPS remesh into a normal
    /// mesh (Guskov et al. 2000) coded with the unlifted butterfly wavelet, `maps` keeps it
    /// (lifted butterfly); `auto` is `normal` unless there are feature edges (given by
    /// --sharp-angle or detected).
    #[arg(long, value_enum, default_value_t = RemeshArg::Auto)]
    pub remesh: RemeshArg,
    /// Keep the remesh's vertices on the input: no least-squares offsets along their
    /// piercing lines or predicted normals (`remesh::normal_fit`, which brings the remesh
    /// closer to the input).
    #[arg(long)]
    pub on_surface: bool,
    /// Whether to code an irregular input as it is (a direct stream: the base-mesh coder at
    /// 8 bits, then one refinement plane per bit up to 14, or --bits with --direct always)
    /// instead of its remesh: auto (the default) keeps the direct stream where it is closer
    /// to the input than the remesh's stream at the same bytes at most of three budgets
    /// (about 64, 76 and 88 dB) — low-poly meshes such as suzanne, cow, beetle or teapot —
    /// and, with --lossless, where it takes no more bytes than the remesh's lossless stream
    /// (it then decodes to the input itself on the same grid).
    #[arg(long, value_enum, default_value_t = DirectArg::Auto)]
    pub direct: DirectArg,
}

/// `--direct`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DirectArg {
    /// The direct stream where it beats the remesh's (irregular input, embedded layout).
    Auto,
    /// Always a direct stream.
    Always,
    /// Never (the remesh, or the semi-regular input's own hierarchy).
    Never,
}

/// The direct stream of `mesh` at `bits` (repaired into a manifold if it must be), and what
/// the repair did.
fn code_directly(
    mesh: &subwave::Mesh,
    bits: u32,
) -> subwave::Result<(Vec<u8>, Option<subwave::remesh::RepairReport>)> {
    let (m, repair) = direct::codable(mesh)?;
    let opts = direct::DirectOptions {
        bits,
        input_vertices: Some(mesh.num_vertices() as u32),
        ..Default::default()
    };
    Ok((direct::encode(&m, &opts)?, repair))
}

/// The direct stream of `mesh` for `--direct always`, with a warning if the input had to be
/// repaired.
pub fn direct_stream(mesh: &subwave::Mesh, bits: u32, name: &str) -> Result<Vec<u8>> {
    let (bytes, repair) = code_directly(mesh, bits).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    if let Some(s) = repair.as_ref().and_then(|r| r.repair_summary()) {
        tracing::warn!("{name}: repaired the input into a manifold for the direct stream: {s}");
    }
    Ok(bytes)
}

/// The direct stream of `mesh` at `bits` for `--direct auto` (the remesh's own warnings
/// already say what the repair did); `None`, with a warning, if the input cannot be coded
/// as it is.
fn direct_stream_quiet(mesh: &subwave::Mesh, bits: u32, name: &str) -> Option<Vec<u8>> {
    match code_directly(mesh, bits) {
        Ok((b, _)) => Some(b),
        Err(e) => {
            tracing::warn!("{name}: not coded as it is ({e}); the remesh is kept");
            None
        }
    }
}

/// The direct stream of `mesh` (at [`direct::DEFAULT_BITS`]) and its comparison with the
/// wavelet stream `wavelet` (`--direct auto`); `None`, with a warning, if the input cannot be
/// coded as it is (the wavelet stream is then kept).
pub fn weigh_direct(
    mesh: &subwave::Mesh,
    wavelet: &[u8],
    name: &str,
) -> Option<(Vec<u8>, direct::Comparison)> {
    let bytes = direct_stream_quiet(mesh, direct::DEFAULT_BITS, name)?;
    match direct::compare(mesh, wavelet, &bytes) {
        Ok(c) => Some((bytes, c)),
        Err(e) => {
            tracing::warn!("{name}: the direct stream was not weighed ({e}); the remesh is kept");
            None
        }
    }
}

/// [`direct::screen`] of `mesh`'s direct stream against the wavelet stream `wavelet` of a
/// remesh about to be redone with more levels: the direct stream and the comparison if it
/// wins (the remesh is then not redone); `None` otherwise, with a warning if it could not
/// be measured.
pub fn screen_direct(
    mesh: &subwave::Mesh,
    wavelet: &[u8],
    name: &str,
) -> Option<(Vec<u8>, direct::Comparison)> {
    let direct = direct_stream_quiet(mesh, direct::DEFAULT_BITS, name)?;
    match direct::screen(mesh, wavelet, &direct) {
        Ok((true, c)) => Some((direct, c)),
        Ok((false, _)) => None,
        Err(e) => {
            tracing::warn!("{name}: the direct stream was not weighed ({e})");
            None
        }
    }
}

/// The line `subwave encode` and `subwave eval` print about the direct stream's comparison
/// with the remesh's.
pub fn comparison_line(c: &direct::Comparison, chosen: bool) -> String {
    let at: Vec<String> = c
        .bytes
        .iter()
        .zip(c.direct_psnr.iter().zip(&c.wavelet_psnr))
        .map(|(b, (d, w))| {
            let w = if w.is_finite() {
                format!("{w:.1} dB")
            } else {
                "nothing".to_string()
            };
            format!("{b} B: {d:.1} dB against {w}")
        })
        .collect();
    if chosen {
        format!(
            "direct: the input coded as it is is closer to it than its remesh at the same bytes ({}): direct stream kept (--direct never keeps the remesh)",
            at.join("; ")
        )
    } else {
        format!(
            "direct: the remesh is closer to the input than the input coded as it is at the same bytes ({}): remesh kept (--direct always codes the input as it is)",
            at.join("; ")
        )
    }
}

/// Removes what a `.swv` stream does not code from `mesh`, with a warning naming it:
/// vertices no face uses, texture coordinates and vertex colours (a stream holds positions,
/// faces and crease tags).
pub fn warn_uncoded(mesh: &mut Mesh, name: &str) {
    let before = mesh.num_vertices();
    mesh.remove_unreferenced();
    let unused = match before - mesh.num_vertices() {
        0 => None,
        1 => Some("1 vertex no face uses".to_string()),
        n => Some(format!("{n} vertices no face uses")),
    };
    warn_dropped(mesh, name, unused, "a .swv stream");
}

/// Removes the texture coordinates and vertex colours of `mesh`, which `stream` does not
/// code, with a warning naming them and `more` (something else not coded) on standard
/// error.
pub fn warn_dropped(mesh: &mut Mesh, name: &str, more: Option<String>, stream: &str) {
    let mut dropped: Vec<String> = more.into_iter().collect();
    if mesh.uvs.take().is_some() | mesh.face_uvs.take().is_some() {
        dropped.push("texture coordinates".to_string());
    }
    if mesh.colors.take().is_some() {
        dropped.push("vertex colours".to_string());
    }
    if !dropped.is_empty() {
        tracing::warn!(
            "{name}: not coded: {} ({stream} holds positions, faces and crease tags)",
            dropped.join(", ")
        );
    }
}

impl PrepareArgs {
    /// The hierarchy's split for `--wavelet`: quads for a quad wavelet (linear, cubic),
    /// triangles for a triangle one, and without one a semi-regular mesh of either split as
    /// it is (a Catmull-Clark one then gets the cubic wavelet, the default on quad meshes)
    /// and anything else remeshed into triangles.
    pub fn quads(wavelet: Option<WaveletArg>) -> Quads {
        match wavelet {
            Some(WaveletArg::Linear | WaveletArg::Cubic) => Quads::Yes,
            Some(_) => Quads::No,
            None => Quads::IfSemiRegular,
        }
    }

    /// The library options; `quads` is the hierarchy's split ([`PrepareArgs::quads`]).
    pub fn options(&self, quads: Quads) -> PrepareOptions {
        PrepareOptions {
            levels: self.levels,
            base_faces: self.base_faces.map(|n| n as usize),
            quads,
            sharp_angle: self.sharp_angle,
            detect_features: !self.no_auto_features,
            normal: self.remesh.into(),
            force_remesh: false,
            fit: !self.on_surface,
            raise_levels: true,
            snap: None,
        }
    }
}

/// How an irregular input is remeshed (`--remesh`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RemeshArg {
    /// `normal` unless `--sharp-angle` marks feature edges.
    Auto,
    /// MAPS, then re-sampled into a normal mesh (unlifted butterfly).
    Normal,
    /// MAPS only (lifted butterfly).
    Maps,
}

impl From<RemeshArg> for Option<bool> {
    fn from(r: RemeshArg) -> Self {
        match r {
            RemeshArg::Auto => None,
            RemeshArg::Normal => Some(true),
            RemeshArg::Maps => Some(false),
        }
    }
}

/// Bits of the position grid of a lossless stream without `--bits`.
const LOSSLESS_BITS: u32 = 12;

/// Runs `subwave encode`.
pub fn run(args: &EncodeArgs) -> Result<()> {
    let name = print::path(&args.mesh);
    if let (true, Some(b @ 25..)) = (args.lossless, args.bits) {
        bail!("--bits {b}: a lossless stream's position grid has at most 24 bits");
    }
    let mut mesh = read_mesh(&args.mesh, args.format)?;
    warn_uncoded(&mut mesh, &name);
    let input_vertices = mesh.num_vertices();
    let t0 = Instant::now();
    if args.prep.direct == DirectArg::Always {
        if args.layout == LayoutArg::Trees {
            bail!("{name}: a direct stream has no trees (--layout embedded, or --direct never)");
        }
        let bits = args.bits.unwrap_or(if args.lossless {
            LOSSLESS_BITS
        } else {
            direct::DEFAULT_BITS
        });
        if bits < direct::COARSE_BITS {
            bail!(
                "--bits {bits}: a direct stream has at least {} bits",
                direct::COARSE_BITS
            );
        }
        let bytes = direct_stream(&mesh, bits, &name)?;
        return write_direct(args, &bytes, input_vertices, t0);
    }
    // A semi-regular mesh is used as it is; anything else is remeshed first.
    let mut popts = args.prep.options(PrepareArgs::quads(args.wavelet));
    // A lossless stream codes every vertex of the remesh: more levels only make it larger;
    // its normal vertices go onto the lossless coder's normal lines of the stream's grid.
    popts.raise_levels = !args.lossless;
    if args.lossless {
        popts.snap = Some(SnapOptions {
            bits: args.bits.unwrap_or(LOSSLESS_BITS),
            ..SnapOptions::default()
        });
    }
    // `--direct auto` on an irregular input coded lossy and embedded: the direct stream is
    // weighed against the remesh's (`weigh_direct`); where it beats a remesh that would be
    // redone with more levels at its first two budgets already, that is not done.
    let weigh =
        args.prep.direct == DirectArg::Auto && !args.lossless && args.layout == LayoutArg::Embedded;
    let mut screened: Option<(Vec<u8>, direct::Comparison)> = None;
    let prepared = crate::progress::with_bar("remesh", false, |cb| {
        prepare_screened(&mesh, &popts, cb, &mut |p| {
            if !weigh {
                return Ok(true);
            }
            let wavelet = encode_options(args, p, input_vertices, &name)
                .map_err(|e| subwave::Error::InvalidArgument(e.to_string()))
                .and_then(|o| encode(&p.hierarchy, &o))?;
            screened = screen_direct(&mesh, &wavelet, &name);
            Ok(screened.is_none())
        })
    })
    .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    if let Some((direct, c)) = screened {
        println!(
            "{}; the remesh was not redone with more levels",
            comparison_line(&c, true)
        );
        return write_direct(args, &direct, input_vertices, t0);
    }
    let prepare_ms = t0.elapsed().as_secs_f64() * 1e3;
    let remeshed = prepared.remeshed.is_some();
    // Stage times of the remesh (and the normal re-sampling after it), for the final line.
    let stages = prepared.remeshed.as_ref().map(|r| {
        let t = &r.timings;
        format!(
            "remesh {:.0} ms (prepare {:.0}, simplify {:.0}, parameterize {:.0}, sampling relaxation {:.0}, resample {:.0}, relax {:.0}), {} {:.0} ms, distance {:.0} ms, ",
            t.total_ms,
            t.prepare_ms,
            t.simplify_ms,
            t.parameterize_ms,
            t.param_relax_ms,
            t.resample_ms,
            t.relax_ms,
            // What follows the remesh: the normal re-sampling, if it ran (and the remeshes
            // that missed part of the input before the one kept).
            match (
                prepared.normal.is_some(),
                prepared.missed.is_empty() && prepared.raised.is_none(),
            ) {
                (true, true) => "normal",
                (false, true) => "hand-over",
                (true, false) => "earlier remeshes and normal",
                (false, false) => "earlier remeshes and hand-over",
            },
            prepare_ms - t.total_ms - prepared.distance_ms,
            prepared.distance_ms
        )
    });
    if let Some(r) = &prepared.remeshed {
        for w in &r.warnings {
            tracing::warn!("{name}: {w}");
        }
    } else if args.prep.base_faces.is_some() {
        tracing::warn!("--base-faces only applies to remeshed (irregular) input; the detected base mesh is used");
    }
    if let Some(n) = &prepared.normal {
        println!("{}", print::normal_stats(n));
        if let Some(s) = &prepared.snap {
            println!("lossless grid: {}", print::snap_stats(s));
        }
    } else if let Some(f) = &prepared.fit {
        println!("MAPS remesh: {}", print::fit_stats(f));
    }
    if let (true, Some(a)) = (prepared.features_detected, prepared.sharp_angle) {
        println!(
            "features: edges sharper than {a}° form a crease network: kept as creases (--sharp-angle to choose the angle, --no-auto-features to ignore them)"
        );
    }
    if let Some(rms) = prepared.remesh_rms {
        println!(
            "{}",
            print::remesh_distance(rms, mesh.diagonal(), !args.lossless)
        );
    }
    if let Some(line) = print::input_distance(&prepared, mesh.diagonal()) {
        println!("{line}");
    }
    if let Some(d) = prepared.input_distance {
        if d.1 > subwave::codec::prepare::MISS_FRACTION * mesh.diagonal() {
            tracing::warn!(
                "{name}: the remesh misses part of the input (Hausdorff {:.1}% of the diagonal): raise --levels or --base-faces",
                100.0 * d.1 / mesh.diagonal()
            );
        }
    }
    let h = &prepared.hierarchy;
    let opts = encode_options(args, &prepared, input_vertices, &name)?;
    let t_code = Instant::now();
    let bytes = encode(h, &opts).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let code_ms = t_code.elapsed().as_secs_f64() * 1e3;
    // `--lossless --direct auto` on an irregular input: the input itself on the same grid,
    // exactly, where that takes no more bytes than the remesh (which is not the input).
    let bits = opts.bits;
    if args.prep.direct == DirectArg::Auto
        && args.lossless
        && remeshed
        && args.layout == LayoutArg::Embedded
        && bits >= direct::COARSE_BITS
    {
        if let Some(direct) = direct_stream_quiet(&mesh, bits, &name) {
            let chosen = direct.len() <= bytes.len();
            println!(
                "direct: the input coded as it is, exactly on the same {bits}-bit grid, takes {} bytes against the remesh's {}: {} (--direct always|never chooses)",
                direct.len(),
                bytes.len(),
                if chosen { "direct stream kept" } else { "remesh kept" }
            );
            if chosen {
                return write_direct(args, &direct, input_vertices, t0);
            }
        }
    }
    if weigh && remeshed {
        let t = Instant::now();
        if let Some((direct, c)) = weigh_direct(&mesh, &bytes, &name) {
            let chosen = c.prefer_direct();
            println!(
                "{} ({:.0} ms)",
                comparison_line(&c, chosen),
                t.elapsed().as_secs_f64() * 1e3
            );
            if chosen {
                return write_direct(args, &direct, input_vertices, t0);
            }
        }
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    std::fs::write(&args.output, &bytes)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.output.display()))?;
    let info = inspect(&bytes)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    writeln!(
        out,
        "{name}: {}{} levels over {} base vertices / {} faces -> {} vertices; {} wavelet{}{}, {} frames, {}, {} layout{}",
        if remeshed { "remeshed, " } else { "" },
        h.levels(),
        info.base_vertices,
        info.base_faces,
        h.positions.len(),
        info.wavelet.name(),
        if info.lifted { " (lifted)" } else { "" },
        if info.lossless { ", lossless" } else { "" },
        match info.frames {
            DetailFrame::Local => "local",
            DetailFrame::Global => "global",
        },
        if info.lossless {
            format!("{}-bit grid", info.bits)
        } else {
            format!("{} bit planes", info.planes)
        },
        match info.layout {
            Layout::Embedded => "embedded",
            Layout::Trees => "trees",
        },
        if info.contexts { "" } else { ", raw bits" },
    )?;
    writeln!(out, "{}", wrote(args, &info, input_vertices, ms))?;
    if let Some(stages) = stages {
        writeln!(out, "  {stages}coding {code_ms:.0} ms")?;
    }
    out.flush()?;
    Ok(())
}

/// The encoder options for `prepared` with the command line's choices (`name` for errors).
fn encode_options(
    args: &EncodeArgs,
    prepared: &Prepared,
    input_vertices: usize,
    name: &str,
) -> Result<EncodeOptions> {
    let mut opts = prepared.encode_options();
    let h = &prepared.hierarchy;
    if let Some(w) = args.wavelet {
        opts.wavelet = w.into();
    }
    if opts.wavelet.is_quad() != (h.split == Split::Polygons) {
        bail!(
            "{name}: the {} wavelet does not fit this {} mesh (triangles: loop, butterfly, midpoint; quads: linear, cubic)",
            opts.wavelet.name(),
            if h.split == Split::Triangles { "triangle" } else { "quad" }
        );
    }
    if let Some(f) = args.frames {
        opts.frames = f.into();
    }
    opts.components = match args.components {
        ComponentsArg::Aligned => ComponentMode::Aligned,
        ComponentsArg::Independent => ComponentMode::Independent,
    };
    opts.layout = match args.layout {
        LayoutArg::Embedded => Layout::Embedded,
        LayoutArg::Trees => Layout::Trees,
    };
    opts.lossless = args.lossless;
    if args.lossless && opts.wavelet == Wavelet::Loop {
        bail!("--lossless needs an integer wavelet: butterfly or midpoint (triangles), linear or cubic (quads)");
    }
    opts.lifted = args.lossless || (opts.lifted && !args.unlifted);
    opts.contexts = !args.no_contexts;
    if let Some(b) = args.bits {
        opts.bits = b;
        opts.max_rms = None;
    } else if args.lossless {
        opts.bits = LOSSLESS_BITS;
    }
    opts.input_vertices = Some(input_vertices as u32);
    opts.level_exponent = args.level_exponent;
    opts.tangent_shift = args.tangent_shift;
    Ok(opts)
}

/// Writes the direct stream `bytes` and prints what it is.
fn write_direct(args: &EncodeArgs, bytes: &[u8], input_vertices: usize, t0: Instant) -> Result<()> {
    let name = print::path(&args.mesh);
    std::fs::write(&args.output, bytes)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.output.display()))?;
    let info = inspect(bytes)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    writeln!(
        out,
        "{name}: coded as it is (direct stream): {} vertices, {} faces; {} bits, the first {} in the base chunk, then {} refinement planes",
        info.base_vertices,
        info.base_faces,
        info.bits,
        info.bits - info.planes,
        info.planes
    )?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    writeln!(out, "{}", wrote(args, &info, input_vertices, ms))?;
    out.flush()?;
    Ok(())
}

/// The `wrote OUT: N bytes (...)` line of the stream `info` written in `ms`.
fn wrote(args: &EncodeArgs, info: &StreamInfo, input_vertices: usize, ms: f64) -> String {
    let bytes = info.total_bytes;
    format!(
        "wrote {}: {} bytes ({:.2} bits per input vertex; header {} B, base {} B), {:.0} ms",
        args.output.display(),
        bytes,
        8.0 * bytes as f64 / input_vertices.max(1) as f64,
        info.header_bytes,
        info.base_bytes,
        ms
    )
}
