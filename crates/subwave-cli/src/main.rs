//! `subwave`: the command-line front end of the subwave library.
//!
//! This crate only parses arguments and prints; every algorithm lives in the `subwave` library.
//! Exit codes: 0 success, 1 bad input or any other runtime error (one line `error: ...` on
//! stderr), 2 usage error (clap's own exit code).

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod basemesh;
mod bench;
mod convert;
mod decode;
mod demo;
mod distance;
mod encode;
mod eval;
mod info;
mod print;
mod progress;
mod remesh;
mod stability;
mod subdivide;
mod svg;
mod wavelet;

use subwave::io::Format;

/// Large buffers in transparent huge pages (fewer first-touch page faults; `subwave::alloc`).
#[global_allocator]
static ALLOC: subwave::alloc::HugePages = subwave::alloc::HugePages;

/// Exit code for bad input and every other runtime error.
const EXIT_ERROR: u8 = 1;

/// Subdivision surfaces, wavelet subdivision surfaces and progressive mesh coding.
#[derive(Debug, Parser)]
#[command(name = "subwave", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print counts and measures of a mesh: vertices, faces, edges, boundaries, components,
    /// Euler characteristic, genus, non-manifold elements, duplicated seams and slit
    /// T-junctions (which `remesh --repair` welds and stitches), valences, bounding box, tags.
    Info(InfoArgs),
    /// Convert a mesh between formats (OBJ, OFF, PLY, STL in; OBJ, OFF, PLY, STL, GLB out).
    Convert(ConvertArgs),
    /// Build the embedded default mesh (Bertram's five blobs), validate it and write it with
    /// its report into a folder.
    Demo(DemoArgs),
    /// Subdivide a mesh: Loop, midpoint, Catmull-Clark, bilinear or butterfly, with
    /// crease/dart/corner tags from the file's `t crease` / `t corner` lines and from
    /// --sharp-angle.
    Subdivide(SubdivideArgs),
    /// Metro-style symmetric surface distance between two meshes: RMS both ways, Hausdorff,
    /// PSNR = 20 log10(diagonal of A / larger RMS).
    Distance(DistanceArgs),
    /// Wavelet analysis of a semi-regular mesh (detected 1-to-4 triangle or Catmull-Clark
    /// quad splits): per-level approximation errors, detail statistics, reconstruction
    /// error and forward/inverse times.
    Wavelet(WaveletArgs),
    /// Bertram et al.'s stability experiment (§5.2, Fig. 17): white noise added to a
    /// subdivided mesh, low-passed level by level by the linear, cubic and quintic B-spline
    /// wavelets; prints the noise left at each level.
    Stability(StabilityArgs),
    /// Remesh any mesh to subdivision connectivity (MAPS: QEM base domain, parameterization,
    /// resampling; shrink-wrapping fallback), writing the semi-regular mesh and its base mesh.
    Remesh(remesh::RemeshArgs),
    /// Benchmarks without file output (medians of several runs).
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Encode a semi-regular mesh into a progressive `.swv` stream (wavelet + SPIHT over the
    /// edge-offspring forest; embedded or per-tree layout; lossless integer mode).
    Encode(EncodeArgs),
    /// Decode a `.swv` stream, or a prefix of it (--bytes, --bpv), or some of its trees, into
    /// a mesh.
    Decode(DecodeArgs),
    /// Rate-distortion table of the progressive codec on a mesh (remeshed first if
    /// irregular): the stream cut at several byte budgets, each prefix decoded and measured
    /// against the input (RMS, Hausdorff, PSNR), with an SVG plot and optional peer curves.
    Eval(EvalArgs),
    /// Compress a mesh with the base-mesh coder (connectivity, quantized positions, crease
    /// and corner tags) and report bits per vertex of each part.
    CompressBase(CompressBaseArgs),
    /// Decompress a base-mesh stream written by `compress-base` into a mesh file.
    DecompressBase(DecompressBaseArgs),
}

/// Arguments of `subwave eval`.
#[derive(Debug, clap::Args)]
pub struct EvalArgs {
    /// The mesh (any; an irregular one is remeshed first, as `subwave encode` does).
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// The input format, if the extension does not tell it.
    #[arg(short, long, value_name = "F", value_parser = parse_format)]
    pub format: Option<Format>,
    /// Levels, base faces, features and method of the remesh.
    #[command(flatten)]
    pub prep: encode::PrepareArgs,
    /// The wavelet (default: butterfly on triangle meshes, cubic on quad meshes).
    #[arg(long, value_enum)]
    pub wavelet: Option<encode::WaveletArg>,
    /// Bit planes of the coefficient quantization (eq. 4.8; default as `encode`), or with
    /// --direct always the precision of the direct stream (default 14, at least 8).
    #[arg(long, value_name = "B", value_parser = clap::value_parser!(u32).range(1..=30))]
    pub bits: Option<u32>,
    /// Level weight of the lossy details: level j's details are weighted by 2^(-EXP*j) before
    /// quantization, so that the bit planes follow the surface's squared error across levels
    /// (0: every level alike; a multiple of 0.25 up to 8).
    #[arg(long, value_name = "EXP", default_value_t = 1.0, value_parser = parse_level_exponent)]
    pub level_exponent: f64,
    /// Lossy, local frames: the tangential components of the details are weighted by 2^-K
    /// (sent K bit planes after the normal ones; they move the surface little).
    #[arg(long, value_name = "K", default_value_t = 2, value_parser = clap::value_parser!(u32).range(0..=8))]
    pub tangent_shift: u32,
    /// Detail coordinates (triangle wavelets; default local).
    #[arg(long, value_enum)]
    pub frames: Option<encode::FramesArg>,
    /// Unlifted midpoint/butterfly (no update step).
    #[arg(long)]
    pub unlifted: bool,
    /// Truncation points (byte budgets spaced geometrically from the base mesh to the whole
    /// stream).
    #[arg(long, value_name = "K", default_value_t = 10,
          value_parser = clap::value_parser!(u32).range(2..=100))]
    pub points: u32,
    /// Area samples per surface of the distance.
    #[arg(long, value_name = "S", default_value_t = subwave::distance::DEFAULT_SAMPLES)]
    pub samples: usize,
    /// A peer's rate-distortion points (lines `NAME ... bpv=X psnr=YdB`, the output of
    /// ../shared/peers/draco_rd.py), plotted and compared at equal PSNR; repeatable.
    #[arg(long, value_name = "FILE")]
    pub reference: Vec<PathBuf>,
    /// Write the plot (PSNR against bits per input vertex) as SVG.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Print JSON (`points`: list of {bytes, bpv, rms, max, psnr}).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `subwave encode`.
#[derive(Debug, clap::Args)]
pub struct EncodeArgs {
    /// The mesh: semi-regular (1-to-4 triangle or Catmull-Clark quad splits, any vertex
    /// order).
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// The output stream.
    #[arg(short, long, value_name = "OUT.swv")]
    pub output: PathBuf,
    /// The input format, if the extension does not tell it.
    #[arg(short, long, value_name = "F", value_parser = parse_format)]
    pub format: Option<Format>,
    /// Levels, base faces, features and method of the remesh.
    #[command(flatten)]
    pub prep: encode::PrepareArgs,
    /// The wavelet (default: butterfly on triangle meshes, cubic on quad meshes).
    #[arg(long, value_enum)]
    pub wavelet: Option<encode::WaveletArg>,
    /// Unlifted midpoint/butterfly (no update step; not with --lossless).
    #[arg(long)]
    pub unlifted: bool,
    /// Bit planes of the coefficient quantization (eq. 4.8; default 16, fewer for a remeshed
    /// input: only those that bring the stream closer to the input than a quarter of the
    /// remesh's own distance), or with --lossless the bits of the position grid (default 12),
    /// or with --direct always the precision of the direct stream (default 14, at least 8).
    #[arg(long, value_name = "B", value_parser = clap::value_parser!(u32).range(1..=30))]
    pub bits: Option<u32>,
    /// Level weight of the lossy details: level j's details are weighted by 2^(-EXP*j) before
    /// quantization, so that the bit planes follow the surface's squared error across levels
    /// (0: every level alike; a multiple of 0.25 up to 8).
    #[arg(long, value_name = "EXP", default_value_t = 1.0, value_parser = parse_level_exponent)]
    pub level_exponent: f64,
    /// Lossy, local frames: the tangential components of the details are weighted by 2^-K
    /// (sent K bit planes after the normal ones; they move the surface little).
    #[arg(long, value_name = "K", default_value_t = 2, value_parser = clap::value_parser!(u32).range(0..=8))]
    pub tangent_shift: u32,
    /// Detail coordinates (triangle wavelets; default local).
    #[arg(long, value_enum)]
    pub frames: Option<encode::FramesArg>,
    /// Quantization steps of the x/y/z components.
    #[arg(long, value_enum, default_value = "aligned")]
    pub components: encode::ComponentsArg,
    /// Chunk layout.
    #[arg(long, value_enum, default_value = "embedded")]
    pub layout: encode::LayoutArg,
    /// Lossless mode: integer wavelet on the position grid; decoding the whole stream gives
    /// the quantized positions bit for bit. An irregular input's normal remesh is put on
    /// that grid with its vertices on the coder's normal lines (one integer places each).
    #[arg(long)]
    pub lossless: bool,
    /// Code every SPIHT decision as a raw bit (no context modelling).
    #[arg(long)]
    pub no_contexts: bool,
}

/// Arguments of `subwave decode`.
#[derive(Debug, clap::Args)]
pub struct DecodeArgs {
    /// The stream.
    #[arg(value_name = "IN.swv")]
    pub input: PathBuf,
    /// The output mesh (obj, ply, glb, off, stl).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// The output format, if the extension does not tell it.
    #[arg(long, value_name = "F", value_parser = parse_format)]
    pub to: Option<Format>,
    /// Decode only the first N bytes of the stream.
    #[arg(long, value_name = "N")]
    pub bytes: Option<u64>,
    /// Decode only X bits per input vertex (the input vertex count is in the header).
    #[arg(long, value_name = "X")]
    pub bpv: Option<f64>,
    /// Trees layout: decode only these trees (e.g. 0,3,7-12).
    #[arg(long, value_name = "LIST")]
    pub trees: Option<String>,
}

/// Arguments of `subwave bench decode`.
#[derive(Debug, clap::Args)]
pub struct BenchDecodeArgs {
    /// The stream.
    #[arg(value_name = "IN.swv")]
    pub stream: PathBuf,
    /// Runs per median.
    #[arg(long, value_name = "K", default_value_t = 11,
          value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Print JSON (keys decode_ms (decodes reusing their buffers), fresh_decode_ms (allocating afresh), vertices, faces, bytes, runs, min_ms).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `subwave bench entropy`.
#[derive(Debug, clap::Args)]
pub struct BenchEntropyArgs {
    /// The stream (embedded layout, not lossless, not direct).
    #[arg(value_name = "IN.swv")]
    pub stream: PathBuf,
    /// Print JSON (keys coefficients, planes: a list of {plane, bytes, order0_bytes, parent_bytes}).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `subwave compress-base`.
#[derive(Debug, clap::Args)]
pub struct CompressBaseArgs {
    /// The mesh (a consistently oriented 2-manifold, any face degrees).
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// The stream to write (`.swb`).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Quantization bits per coordinate.
    #[arg(long, value_name = "B", default_value_t = 14,
          value_parser = clap::value_parser!(u32).range(8..=30))]
    pub bits: u32,
    /// Code a mesh that is not a consistently oriented 2-manifold after repairing it as
    /// `remesh --repair` does (a manifold mesh is coded as it is): duplicated seams welded
    /// (boundary edges lying exactly on other boundary edges), slits stitched (boundary edges
    /// split at T-junctions where that closes a crack), pocket lids removed, non-manifold vertices and
    /// edges split (the decoded mesh has the split vertices as separate vertices at the same
    /// positions), orientations made
    /// consistent, polygons fanned into triangles, degenerate faces and unreferenced vertices
    /// dropped; vertex attributes and tags are not kept.
    #[arg(long)]
    pub repair: bool,
    /// Print JSON (keys vertices, faces, position_bits, bytes, connectivity_bits,
    /// positions_bits, crease_bits, header_bits, connectivity_bpv, positions_bpv, crease_bpv,
    /// total_bpv, encode_ms, decode_ms, input_vertices, connectivity_bpv_input, and repair:
    /// the repair's counts, or null if none was made).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `subwave decompress-base`.
#[derive(Debug, clap::Args)]
pub struct DecompressBaseArgs {
    /// The stream written by `compress-base`.
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// The mesh to write (format from the extension).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
}

/// Arguments of `subwave distance`.
#[derive(Debug, clap::Args)]
pub struct DistanceArgs {
    /// The reference mesh (its bounding-box diagonal scales the PSNR).
    #[arg(value_name = "A")]
    pub a: PathBuf,
    /// The mesh compared with it.
    #[arg(value_name = "B")]
    pub b: PathBuf,
    /// Area samples per surface (vertices are sampled too).
    #[arg(long, value_name = "N", default_value_t = 200_000,
          value_parser = clap::value_parser!(u64).range(1..=100_000_000))]
    pub samples: u64,
    /// Print JSON (keys rms, max, psnr, rms_ab, rms_ba, diagonal, ab, ba).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `subwave wavelet`.
#[derive(Debug, clap::Args)]
pub struct WaveletArgs {
    /// The semi-regular mesh (`-` reads standard input and needs --format).
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// The input format, if the extension does not tell it.
    #[arg(short, long, value_name = "F", value_parser = parse_format)]
    pub format: Option<Format>,
    /// The wavelet: midpoint, butterfly (and -lifted), loop, midpoint-int, butterfly-int
    /// (triangle meshes); linear, cubic, quintic and their -int integer versions (quad meshes).
    #[arg(long, value_enum)]
    pub wavelet: wavelet::WaveletArg,
    /// Coordinates of the detail vectors (local frames: triangle wavelets only).
    #[arg(long, value_enum, default_value = "global")]
    pub frames: wavelet::FramesArg,
    /// Print JSON (keys wavelet, levels [{level, vertices, l2_error, l2_percent, max_error,
    /// details, mean_detail, max_detail}], reconstruction_max_error, forward_ms, inverse_ms,
    /// base_vertices, base_faces, ...).
    #[arg(long)]
    pub json: bool,
    /// Timed runs of each direction of the in-place transform (the median is reported).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub runs: u64,
}

/// Arguments of `subwave stability`.
#[derive(Debug, clap::Args)]
pub struct StabilityArgs {
    /// The base mesh (any polygon mesh; default: a cube).
    #[arg(value_name = "MESH")]
    pub mesh: Option<PathBuf>,
    /// The input format, if the extension does not tell it.
    #[arg(short, long, value_name = "F", value_parser = parse_format)]
    pub format: Option<Format>,
    /// Subdivision levels.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub levels: u32,
    /// Noise amplitude, relative to the finest mean edge length.
    #[arg(long, default_value_t = 0.2)]
    pub noise: f64,
    /// Seed of the noise generator.
    #[arg(long, default_value_t = 9)]
    pub seed: u64,
    /// Print JSON (keys levels, noise, runs [{degree, levels [{level, vertices, rms_noise,
    /// relative, gain}]}]).
    #[arg(long)]
    pub json: bool,
}

/// What `subwave bench` measures.
#[derive(Debug, Subcommand)]
enum BenchCommand {
    /// Plain subdivision: topology, positions, total, cached re-evaluation, peak memory.
    Subdivide(BenchSubdivideArgs),
    /// Full decode of a `.swv` stream (median time, no file output).
    Decode(BenchDecodeArgs),
    /// SPIHT's bytes per bit plane of an embedded stream against the empirical entropy of
    /// its coefficients (order 0 per level and component, and given the parent).
    Entropy(BenchEntropyArgs),
    /// Remeshing to subdivision connectivity: total and per-stage times.
    Remesh(remesh::BenchRemeshArgs),
}

/// Arguments of `subwave bench subdivide`.
#[derive(Debug, clap::Args)]
pub struct BenchSubdivideArgs {
    /// The input mesh (unreferenced vertices are dropped).
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// The input format, if the extension does not tell it.
    #[arg(short, long, value_name = "F", value_parser = parse_format)]
    pub format: Option<Format>,
    /// The scheme.
    #[arg(long, value_enum, default_value = "loop")]
    pub scheme: subdivide::SchemeArg,
    /// Number of levels.
    #[arg(long, value_name = "N", default_value_t = 3,
          value_parser = clap::value_parser!(u32).range(0..=12))]
    pub levels: u32,
    /// Edges whose dihedral angle exceeds DEG degrees become infinitely sharp creases.
    #[arg(long, value_name = "DEG", value_parser = parse_angle)]
    pub sharp_angle: Option<f64>,
    /// Boundary treatment (OpenSubdiv's "edge only" by default, to compare with it).
    #[arg(long, value_enum, default_value = "opensubdiv")]
    pub boundary: subdivide::BoundaryArg,
    /// How semi-sharp creases relax.
    #[arg(long, value_enum, default_value = "uniform")]
    pub creasing: subdivide::CreasingArg,
    /// Runs per median (each phase runs once more first, untimed, as a warm-up).
    #[arg(long, value_name = "K", default_value_t = 5,
          value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Print JSON (keys topology_ms, positions_ms, total_ms, reevaluate_ms, peak_rss_mb,
    /// vertices, faces, ...).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `subwave subdivide`.
#[derive(Debug, clap::Args)]
pub struct SubdivideArgs {
    /// The input mesh (`-` reads standard input and needs --format).
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// The output mesh (obj keeps crease tags; off, ply, stl, glb).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// The input format, if the extension does not tell it.
    #[arg(short, long, value_name = "F", value_parser = parse_format)]
    pub format: Option<Format>,
    /// The output format, if the extension does not tell it.
    #[arg(long, value_name = "F", value_parser = parse_format)]
    pub to: Option<Format>,
    /// The scheme.
    #[arg(long, value_enum, default_value = "loop")]
    pub scheme: subdivide::SchemeArg,
    /// Number of levels.
    #[arg(long, value_name = "N", default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(0..=12))]
    pub levels: u32,
    /// Edges whose dihedral angle exceeds DEG degrees become infinitely sharp creases.
    #[arg(long, value_name = "DEG", value_parser = parse_angle)]
    pub sharp_angle: Option<f64>,
    /// Boundary treatment.
    #[arg(long, value_enum, default_value = "crease")]
    pub boundary: subdivide::BoundaryArg,
    /// How semi-sharp creases relax.
    #[arg(long, value_enum, default_value = "uniform")]
    pub creasing: subdivide::CreasingArg,
    /// β of Loop's smooth vertex rule.
    #[arg(long, value_enum, default_value = "loop")]
    pub loop_weights: subdivide::LoopWeightsArg,
    /// Move the finest level's vertices to their limit positions (loop and catmull-clark;
    /// Maret §3.4, OpenSubdiv's limit masks). Only positions are written: the mesh formats
    /// here carry no normals (glb computes its own from the faces).
    #[arg(long)]
    pub limit: bool,
}

/// Arguments of `subwave info`.
#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    /// The mesh file (`-` reads standard input and needs --format).
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// The file format, if the extension does not tell it: obj, off, ply or stl.
    #[arg(short, long, value_name = "F", value_parser = parse_format)]
    pub format: Option<Format>,
    /// Print the report as JSON (the keys are the fields of `subwave::validate::MeshReport`).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `subwave convert`.
#[derive(Debug, clap::Args)]
pub struct ConvertArgs {
    /// The input mesh (`-` reads standard input and needs --from).
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// The output mesh (`-` writes standard output and needs --to).
    #[arg(value_name = "OUT")]
    pub output: PathBuf,
    /// The input format, if the extension does not tell it: obj, off, ply or stl.
    #[arg(long, value_name = "F", value_parser = parse_format)]
    pub from: Option<Format>,
    /// The output format, if the extension does not tell it: obj, off, ply, stl or glb.
    #[arg(long, value_name = "F", value_parser = parse_format)]
    pub to: Option<Format>,
    /// Remove vertices that no face uses (by default they are kept, with a warning).
    #[arg(long)]
    pub drop_unreferenced: bool,
}

/// Arguments of `subwave demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// The folder to write into (created if missing).
    #[arg(long, value_name = "DIR", default_value = "subwave-demo")]
    pub out: PathBuf,
    /// Midpoint-subdivision levels of the five blobs (10·4^N + 2 vertices).
    #[arg(long, value_name = "N", default_value_t = 4,
          value_parser = clap::value_parser!(u32).range(0..=8))]
    pub levels: u32,
}
/// A level exponent: a multiple of 0.25 in 0..=8.
fn parse_level_exponent(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|e| format!("{s}: {e}"))?;
    let q = x * 4.0;
    if (0.0..=32.0).contains(&q) && q.fract() == 0.0 {
        Ok(x)
    } else {
        Err(format!("{s}: use a multiple of 0.25 between 0 and 8"))
    }
}

/// Parses a dihedral angle in degrees for clap: a number from 0 to 180.
pub fn parse_angle(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|e| format!("{s}: {e}"))?;
    if (0.0..=180.0).contains(&x) {
        Ok(x)
    } else {
        Err(format!(
            "{s}: a dihedral angle is a number of degrees from 0 to 180"
        ))
    }
}

/// Parses a format name for clap; the message lists the valid names.
fn parse_format(s: &str) -> Result<Format, String> {
    Format::from_name(s)
        .ok_or_else(|| format!("unknown format `{s}`; expected obj, off, ply, stl or glb"))
}

fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    // `try_init` only fails if a subscriber is already installed; ignore that.
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .without_time()
        .with_ansi(std::io::stderr().is_terminal())
        .try_init();
}

/// True if the error is a closed pipe on standard output (e.g. `subwave info x | head -1`).
fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|cause| {
        if let Some(e) = cause.downcast_ref::<std::io::Error>() {
            return e.kind() == std::io::ErrorKind::BrokenPipe;
        }
        if let Some(subwave::Error::Io { source, .. }) = cause.downcast_ref::<subwave::Error>() {
            return source.kind() == std::io::ErrorKind::BrokenPipe;
        }
        false
    })
}

/// The error as one line: the context chain joined by `: `, skipping causes that an outer
/// message already quotes (the library's errors print their source themselves), with inner
/// line breaks replaced.
fn one_line(err: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in err.chain() {
        let part = cause.to_string();
        if text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text.split(['\n', '\r'])
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("; ")
}

fn main() -> ExitCode {
    // Usage errors, --help and --version exit here with clap's codes (2 for usage errors).
    let cli = Cli::parse();
    init_logging();
    // Only refinement writes buffers large and full enough to gain from transparent huge
    // pages; for the rest (remeshing above all) they cost more kernel time than they save
    // (`subwave::alloc::disable_huge_pages`). A refusal is not an error: only slower.
    let refines = matches!(
        cli.command,
        Command::Subdivide(_) | Command::Bench(BenchCommand::Subdivide(_))
    );
    if !refines {
        if let Err(e) = subwave::alloc::disable_huge_pages() {
            tracing::debug!("transparent huge pages stay enabled: {e}");
        }
    }
    let result = match cli.command {
        Command::Info(args) => info::run(&args),
        Command::Convert(args) => convert::run(&args),
        Command::Demo(args) => demo::run(&args),
        Command::Subdivide(args) => subdivide::run(&args),
        Command::Distance(args) => distance::run(&args),
        Command::Wavelet(args) => wavelet::run(&args),
        Command::Stability(args) => stability::run(&args),
        Command::Eval(args) => eval::run(&args),
        Command::Bench(BenchCommand::Subdivide(args)) => bench::subdivide(&args),
        Command::Bench(BenchCommand::Decode(args)) => bench::decode(&args),
        Command::Bench(BenchCommand::Entropy(args)) => bench::entropy(&args),
        Command::Encode(args) => encode::run(&args),
        Command::Decode(args) => decode::run(&args),
        Command::Remesh(args) => remesh::run(&args),
        Command::Bench(BenchCommand::Remesh(args)) => remesh::bench(&args),
        Command::CompressBase(args) => basemesh::compress(&args),
        Command::DecompressBase(args) => basemesh::decompress(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if is_broken_pipe(&err) => ExitCode::SUCCESS,
        Err(err) => {
            let mut stderr = std::io::stderr().lock();
            let _ = writeln!(stderr, "error: {}", one_line(&err));
            ExitCode::from(EXIT_ERROR)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context;

    #[test]
    fn one_line_skips_repeated_sources() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory");
        let err = anyhow::Error::from(subwave::Error::Io {
            path: "a.obj".to_string(),
            source: io,
        });
        assert_eq!(one_line(&err), "a.obj: No such file or directory");
    }

    #[test]
    fn one_line_joins_context_and_line_breaks() {
        let err: anyhow::Result<()> = Err(anyhow::anyhow!("first\nsecond"));
        let err = err.context("outer").unwrap_err();
        assert_eq!(one_line(&err), "outer: first; second");
    }

    #[test]
    fn broken_pipe_is_detected() {
        let err = anyhow::Error::from(std::io::Error::from(std::io::ErrorKind::BrokenPipe));
        assert!(is_broken_pipe(&err));
        let err = anyhow::Error::from(std::io::Error::from(std::io::ErrorKind::NotFound));
        assert!(!is_broken_pipe(&err));
    }

    #[test]
    fn format_names() {
        assert_eq!(parse_format("PLY"), Ok(Format::Ply));
        assert!(parse_format("xyz")
            .unwrap_err()
            .contains("obj, off, ply, stl or glb"));
    }

    #[test]
    fn cli_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
