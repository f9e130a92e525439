//! `subwave subdivide`: plain subdivision of a mesh file.

use std::io::Write;
use std::time::Instant;

use anyhow::Result;
use subwave::subdivision::limit::subdivide_limit_positions;
use subwave::subdivision::loop_scheme::LoopWeights;
use subwave::subdivision::rules::Creasing;
use subwave::subdivision::{subdivide, BoundaryMode, Scheme, SubdivideOptions};

use crate::SubdivideArgs;

/// Scheme names on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SchemeArg {
    /// Loop (triangles), piecewise smooth with crease/dart/corner tags.
    Loop,
    /// Linear 1-to-4 on triangle meshes, bilinear on polygon meshes.
    Midpoint,
    /// Catmull-Clark (any polygons), sharp and semi-sharp creases.
    CatmullClark,
    /// Bilinear (any polygons, split into quads).
    Bilinear,
    /// Modified butterfly (triangles), interpolating, with crease/dart/corner tags.
    Butterfly,
    /// The original 8-point butterfly at every edge (triangles; MeshLab's butterfly).
    ButterflyOriginal,

    /// Kobbelt's sqrt(3) (triangles): faces triple per level, boundaries trisected every
    /// second level.
    Sqrt3,

    /// Quad/triangle (Stam & Loop 2003): triangles and quads, Loop on triangles,
    /// Catmull-Clark on quads, sharp and semi-sharp creases.
    QuadTri,

    /// Generalized bicubic B-splines (MLCA, Bertram et al.'s cubic wavelet synthesis).
    Bicubic,
    /// Generalized biquintic B-splines (Bertram et al.'s quintic wavelet synthesis).
    Biquintic,
}

/// Boundary treatment on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BoundaryArg {
    /// Boundaries are creases (Maret §3.5) with Biermann et al.'s Loop edge rules.
    Crease,
    /// OpenSubdiv's "edge only" boundary interpolation.
    Opensubdiv,
    /// OpenSubdiv's "edge and corner": boundary vertices of a single face are corners.
    OpensubdivCorners,
    /// OpenSubdiv's "none": Loop and Catmull-Clark drop the faces touching an untagged
    /// boundary (they only support their neighbours); linear schemes as "opensubdiv".
    None,
}

/// Creasing method on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CreasingArg {
    /// Semi-sharp sharpness decreases by one per level.
    Uniform,
    /// Chaikin's rule (OpenSubdiv's CREASE_CHAIKIN).
    Chaikin,
}

/// Loop β on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LoopWeightsArg {
    /// Loop's β (Maret eq. 3.7).
    Loop,
    /// Warren's β (Maret eq. 3.8).
    Warren,
}

/// The library's scheme of a command-line name.
pub fn scheme(arg: SchemeArg) -> Scheme {
    match arg {
        SchemeArg::Loop => Scheme::Loop,
        SchemeArg::Midpoint => Scheme::Midpoint,
        SchemeArg::CatmullClark => Scheme::CatmullClark,
        SchemeArg::Bilinear => Scheme::Bilinear,
        SchemeArg::Butterfly => Scheme::Butterfly,
        SchemeArg::ButterflyOriginal => Scheme::ButterflyOriginal,
        SchemeArg::Sqrt3 => Scheme::Sqrt3,
        SchemeArg::QuadTri => Scheme::QuadTri,
        SchemeArg::Bicubic => Scheme::Bicubic,
        SchemeArg::Biquintic => Scheme::Biquintic,
    }
}

/// The library's boundary mode of a command-line name.
pub fn boundary_mode(arg: BoundaryArg) -> BoundaryMode {
    match arg {
        BoundaryArg::Crease => BoundaryMode::Crease,
        BoundaryArg::Opensubdiv => BoundaryMode::OpenSubdiv,
        BoundaryArg::OpensubdivCorners => BoundaryMode::OpenSubdivCorners,
        BoundaryArg::None => BoundaryMode::None,
    }
}

/// The library's creasing method of a command-line name.
pub fn creasing(arg: CreasingArg) -> Creasing {
    match arg {
        CreasingArg::Uniform => Creasing::Uniform,
        CreasingArg::Chaikin => Creasing::Chaikin,
    }
}

/// Bytes of memory a refinement takes per output face, at its peak (input, the last two
/// levels, the output): measured 71–109 on the bunny's third level (Loop, butterfly,
/// Catmull-Clark, √3), rounded up.
const BYTES_PER_FACE: u64 = 128;

/// The memory the system has available (Linux `MemAvailable`), if known.
fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuses a refinement of `mesh` (read from `path`) whose output would not fit in the
/// memory available (about [`BYTES_PER_FACE`] per output face), before it starts, instead
/// of letting the system kill the process part way.
pub fn check_memory(
    mesh: &subwave::Mesh,
    opts: &SubdivideOptions,
    path: &std::path::Path,
) -> Result<()> {
    let faces = subwave::subdivision::output_faces(mesh, opts);
    let need = faces.saturating_mul(BYTES_PER_FACE);
    match available_memory() {
        Some(avail) if need > avail => anyhow::bail!(
            "{}: {} levels of {} on {} faces make {} faces, which need about {} of memory; {} \
             are available: use fewer levels",
            path.display(),
            opts.levels,
            opts.scheme.name(),
            mesh.num_faces(),
            faces,
            crate::print::size(need),
            crate::print::size(avail)
        ),
        _ => Ok(()),
    }
}

/// Runs `subwave subdivide`.
pub fn run(args: &SubdivideArgs) -> Result<()> {
    let mut mesh = subwave::io::read_mesh(&args.mesh, args.format)?;
    crate::info::require_faces(&mesh, &args.mesh, "subdivide")?;
    let unreferenced = mesh.referenced().iter().filter(|&&u| !u).count();
    if unreferenced > 0 {
        tracing::warn!(
            "{}: dropping {unreferenced} vertices that no face uses",
            args.mesh.display()
        );
        mesh.remove_unreferenced();
    }
    let opts = SubdivideOptions {
        scheme: scheme(args.scheme),
        levels: args.levels,
        boundary: boundary_mode(args.boundary),
        creasing: creasing(args.creasing),
        loop_weights: match args.loop_weights {
            LoopWeightsArg::Loop => LoopWeights::Loop,
            LoopWeightsArg::Warren => LoopWeights::Warren,
        },
        sharp_angle: args.sharp_angle,
    };
    check_memory(&mesh, &opts, &args.mesh)?;
    let t = Instant::now();
    let out = if args.limit {
        subdivide_limit_positions(&mesh, &opts)
    } else {
        subdivide(&mesh, &opts)
    }
    .map_err(|e| anyhow::anyhow!("{}: {e}", args.mesh.display()))?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    subwave::io::write_mesh(&out, &args.output, args.to)?;
    if args.output.as_os_str() != "-" {
        writeln!(
            std::io::stdout(),
            "{} levels of {}{}: {} vertices, {} faces -> {} vertices, {} faces in {ms:.1} ms; wrote {}",
            args.levels,
            opts.scheme.name(),
            if args.limit { " (at the limit)" } else { "" },
            mesh.num_vertices(),
            mesh.num_faces(),
            out.num_vertices(),
            out.num_faces(),
            args.output.display()
        )?;
    }
    Ok(())
}
