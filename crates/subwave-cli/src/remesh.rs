//! `subwave remesh MESH -o OUT --levels L`: remeshing to subdivision connectivity (MAPS, with
//! shrink-wrapping as the fallback), with the base mesh, the distance to the input and the
//! triangle quality; and `subwave bench remesh`.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use subwave::distance::distance;

/// Distance from the input to the remesh, as a fraction of the diagonal, beyond which the
/// remesh misses part of the input: `remesh` then redoes a remesh over the default base
/// faces over twice as many (up to `remesh::default_base::MAX_DEFAULT_BASE_FACES`), or warns.
/// Measured at 3 levels over 200 base faces: the cow's tail is cut off (8.9%; it takes 800
/// base faces to keep it, 0.99%) and cheburashka's ears are cut short (3.2%; 400 base faces:
/// 1.9%); the other corpus meshes stay at 0.7–2.2%.
const MISS_WARNING: f64 = 0.03;
use subwave::remesh::default_base::Outcome;
use subwave::remesh::{remesh_with_progress, MethodChoice, RemeshOptions, Remeshed};

use crate::print;

/// The remeshing method (`--method`).
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum MethodArg {
    /// MAPS; shrink-wrapping if the parameterization misses on a genus-0 input.
    Auto,
    /// MAPS only.
    Maps,
    /// Shrink-wrapping only.
    ShrinkWrap,
}

/// Arguments of `subwave remesh`.
#[derive(Debug, clap::Args)]
pub struct RemeshArgs {
    /// The input mesh (any polygon mesh).
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// The semi-regular output (format from the extension). Without it, only the report.
    #[arg(short, long, value_name = "OUT")]
    pub output: Option<PathBuf>,
    /// Subdivision levels over the base mesh.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=8))]
    pub levels: u32,
    /// Target number of base triangles [default: 200, raised to 400, then 800, where the
    /// remesh over fewer misses part of the input by over 3% of the diagonal, or leaves
    /// flipped or degenerate faces (for those up to 3200 and the input's triangles, while the
    /// remesh keeps at most 2^18 faces; the try with the fewest is kept); a given number is
    /// kept].
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    pub base_faces: Option<u64>,
    /// Build a quad hierarchy (three quads per base triangle, then Catmull-Clark splits), for
    /// Bertram's B-spline wavelets.
    #[arg(long)]
    pub quads: bool,
    /// Keep edges sharper than this dihedral angle (degrees) as creases on base edges.
    #[arg(long, value_name = "DEG", value_parser = crate::parse_angle)]
    pub sharp_angle: Option<f64>,
    /// Repair the input instead of failing: weld duplicated seams (boundary edges lying
    /// exactly on other boundary edges, as in a model tessellated patch by patch), stitch
    /// slits (boundary edges split at the T-junction vertices of another boundary chain a
    /// hair away, where that closes the crack), remove pocket lids, then cut non-manifold
    /// edges, split non-manifold vertices and orient each component consistently.
    #[arg(long)]
    pub repair: bool,
    /// The method.
    #[arg(long, value_enum, default_value = "auto")]
    pub method: MethodArg,
    /// Relaxation iterations on the finest level.
    #[arg(long, value_name = "N", default_value_t = 6)]
    pub relax: u32,
    /// Steps of the coarse-to-fine relaxation of the sampling in the base domain on each
    /// level from the third on (a third of them on levels over 65,536 faces, a sixth on the
    /// finest, none on levels over 262,144 faces; 0: dyadic sampling).
    #[arg(long, value_name = "N", default_value_t = 30)]
    pub param_relax: u32,
    /// Re-sample the remesh into a normal mesh (Guskov et al. 2000: each vertex of the third
    /// level on lies on the normal line of the butterfly prediction from its parents), as
    /// `subwave encode` does by default on inputs without feature edges. Triangles only.
    #[arg(long, conflicts_with = "quads")]
    pub normal: bool,
    /// Move the re-sampled vertices along their axes to the least-squares fit of the input
    /// (off the surface, closer to it in the L2 sense), as `subwave encode` does.
    #[arg(long, conflicts_with = "quads")]
    pub fit: bool,
    /// Put the re-sampled remesh on the lossless grid of B bits (`2^B − 1` steps over the
    /// longest side of its bounding box, the grid `subwave encode --lossless --bits B` finds
    /// in the written mesh), each normal vertex on the lossless coder's normal line, so that
    /// one integer places it (`codec::normal_line`; 1..=24). Needs --normal.
    #[arg(long, value_name = "B", requires = "normal", value_parser = clap::value_parser!(u32).range(1..=24))]
    pub grid_bits: Option<u32>,
    /// Where to write the base mesh (default: OUT with `.base` before the extension).
    #[arg(long, value_name = "PATH")]
    pub base_output: Option<PathBuf>,
    /// Area samples per surface for the distance to the input (0: skip the distance).
    #[arg(long, value_name = "N", default_value_t = 200_000)]
    pub samples: u64,
    /// Print JSON (keys method, base_faces, levels, vertices, faces, psnr, rms, max,
    /// max_relative, rms_relative, diagonal, min_angle, mean_angle, flipped, degenerate,
    /// param_misses, time_ms, search_ms, tries, timings, normal, normal_ms, snap, repair, missed,
    /// refolded, warnings, output, base_output). `time_ms` is the kept remesh's time,
    /// `search_ms` the wall time of all `tries` (without --base-faces, the remeshes over other
    /// base sizes that missed or folded, with their distances).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `subwave bench remesh`.
#[derive(Debug, clap::Args)]
pub struct BenchRemeshArgs {
    /// The input mesh.
    #[arg(value_name = "MESH")]
    pub mesh: PathBuf,
    /// Subdivision levels.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=8))]
    pub levels: u32,
    /// Target number of base triangles.
    #[arg(long, value_name = "N", default_value_t = 200)]
    pub base_faces: u64,
    /// Feature angle (degrees).
    #[arg(long, value_name = "DEG", value_parser = crate::parse_angle)]
    pub sharp_angle: Option<f64>,
    /// Repair the input as `subwave remesh --repair` does (duplicated seams welded, slits
    /// stitched, pocket lids removed, non-manifold edges cut and vertices split).
    #[arg(long)]
    pub repair: bool,
    /// Runs (the median is reported).
    #[arg(long, default_value_t = 3)]
    pub runs: u32,
    /// Print JSON (keys runs_ms, median_ms, stages of the median run).
    #[arg(long)]
    pub json: bool,
}

fn options(args: &RemeshArgs) -> RemeshOptions {
    RemeshOptions {
        levels: args.levels,
        base_faces: args
            .base_faces
            .map_or(subwave::remesh::default_base::DEFAULT_BASE_FACES, |n| {
                n as usize
            }),
        quads: args.quads,
        sharp_angle: args.sharp_angle,
        repair: args.repair,
        relax_iterations: args.relax,
        param_relax_iterations: args.param_relax,
        method: match args.method {
            MethodArg::Auto => MethodChoice::Auto,
            MethodArg::Maps => MethodChoice::Maps,
            MethodArg::ShrinkWrap => MethodChoice::ShrinkWrap,
        },
    }
}

/// [`remesh_with_progress`] under a progress bar on stderr (shown after a second).
fn run_with_bar(
    mesh: &subwave::Mesh,
    opts: &RemeshOptions,
    quiet: bool,
) -> subwave::Result<Remeshed> {
    crate::progress::with_bar("remesh", quiet, |cb| remesh_with_progress(mesh, opts, cb))
}

fn base_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("remesh");
    let name = match out.extension().and_then(|e| e.to_str()) {
        Some(ext) => format!("{stem}.base.{ext}"),
        None => format!("{stem}.base"),
    };
    out.with_file_name(name)
}

/// One remesh of the base-face search: the remesh, its re-sampling (stats and
/// milliseconds) and its distance to the input.
struct Attempt {
    r: Remeshed,
    resampled: Option<(subwave::remesh::normal::NormalStats, f64)>,
    snapped: Option<subwave::codec::normal_line::SnapStats>,
    d: Option<subwave::distance::Distance>,
}

impl Outcome for Attempt {
    fn flipped(&self) -> usize {
        self.r.quality.flipped
    }
    fn degenerate(&self) -> usize {
        self.r.quality.degenerate
    }
    fn misses(&self) -> bool {
        self.d.is_some_and(|d| d.ab.max > MISS_WARNING * d.diagonal)
    }
}

/// Runs `subwave remesh`.
pub fn run(args: &RemeshArgs) -> Result<()> {
    let mesh = subwave::io::read_mesh(&args.mesh, None)?;
    let mut opts = options(args);
    // Without --base-faces, a remesh over the default that misses part of the input or
    // leaves folds is redone over more base faces (`remesh::default_base`).
    // The input's triangles (polygons fanned), which bound the base faces tried for folds.
    let input_faces = (0..mesh.num_faces())
        .map(|f| mesh.face(f).len().saturating_sub(2))
        .sum();
    let search_start = std::time::Instant::now();
    let searched = subwave::remesh::default_base::search(
        opts.base_faces,
        opts.levels,
        input_faces,
        args.base_faces.is_none(),
        |base_faces| {
            let o = RemeshOptions {
                base_faces,
                ..opts.clone()
            };
            let mut r = run_with_bar(&mesh, &o, false)
                .with_context(|| format!("remeshing {}", args.mesh.display()))?;
            let resampled = if args.normal || args.fit {
                let t = std::time::Instant::now();
                let stats = subwave::remesh::normal::resample_remesh(
                    &mut r,
                    &mesh,
                    args.normal,
                    args.fit,
                    &Default::default(),
                )
                .with_context(|| format!("re-sampling the remesh of {}", args.mesh.display()))?;
                Some((stats, t.elapsed().as_secs_f64() * 1e3))
            } else {
                None
            };
            let snapped = match args.grid_bits {
                Some(bits) => Some(
                    subwave::codec::normal_line::snap_remesh(
                        &mut r,
                        &mesh,
                        &subwave::codec::normal_line::SnapOptions {
                            bits,
                            ..Default::default()
                        },
                    )
                    .with_context(|| {
                        format!("snapping the remesh of {} to the grid", args.mesh.display())
                    })?,
                ),
                None => None,
            };
            let d = if args.samples > 0 {
                Some(distance(&mesh, &r.mesh, args.samples as usize)?)
            } else {
                None
            };
            Ok::<_, anyhow::Error>(Attempt {
                r,
                resampled,
                snapped,
                d,
            })
        },
    )?;
    // Every try's remesh, re-sampling and distance, not only the kept one's.
    let search_ms = search_start.elapsed().as_secs_f64() * 1e3;
    opts.base_faces = searched.base_faces;
    let (missed, refolded) = (searched.missed, searched.refolded);
    let tries = 1 + missed.len() + refolded.len();
    let misses = searched.kept.misses();
    let Attempt {
        r,
        resampled,
        snapped,
        d,
    } = searched.kept;
    // Printed once, by the log (stderr, shown at its default level); JSON also lists them.
    let mut warnings = r.warnings.clone();
    if !missed.is_empty() {
        let list: Vec<String> = missed.iter().map(|m| m.base_faces.to_string()).collect();
        warnings.push(format!(
            "remeshed over {} base faces: over {} the remesh missed part of the input (by over {:.0}% of the diagonal)",
            opts.base_faces,
            list.join(" and "),
            100.0 * MISS_WARNING
        ));
    }
    if !refolded.is_empty() {
        let list: Vec<String> = refolded
            .iter()
            .map(|t| {
                format!(
                    "{} base faces: {} flipped, {} degenerate",
                    t.base_faces, t.flipped, t.degenerate
                )
            })
            .collect();
        warnings.push(format!(
            "remeshed over {} base faces, the try that left the fewest flipped and degenerate faces ({} and {}); the others: {}",
            opts.base_faces,
            r.quality.flipped,
            r.quality.degenerate,
            list.join(", ")
        ));
    }
    if let Some(d) = d.filter(|_| misses) {
        warnings.push(format!(
            "the remesh misses part of the input: the input's point {} is {:.2}% of the diagonal from it (a thin part the base mesh of {} faces cuts off?); more --base-faces keep such parts",
            crate::distance::point(d.ab.farthest),
            100.0 * d.ab.max / d.diagonal,
            r.base.num_faces()
        ));
    }
    for w in &warnings {
        tracing::warn!("{w}");
    }
    let mut base_output = None;
    if let Some(out) = &args.output {
        subwave::io::write_mesh(&r.mesh, out, None)?;
        let bp = args.base_output.clone().unwrap_or_else(|| base_path(out));
        subwave::io::write_mesh(&r.base, &bp, None)?;
        base_output = Some(bp);
    } else if let Some(bp) = &args.base_output {
        subwave::io::write_mesh(&r.base, bp, None)?;
        base_output = Some(bp.clone());
    }
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let v = serde_json::json!({
            "input": args.mesh.display().to_string(),
            "method": r.method.name(),
            "base_faces": r.base.num_faces(),
            "base_vertices": r.base.num_vertices(),
            "levels": args.levels,
            "quads": args.quads,
            "vertices": r.mesh.num_vertices(),
            "faces": r.mesh.num_faces(),
            "psnr": d.map(|d| d.psnr),
            "rms": d.map(|d| d.rms),
            "max": d.map(|d| d.max),
            "rms_relative": d.map(|d| d.rms / d.diagonal),
            "max_relative": d.map(|d| d.max / d.diagonal),
            "diagonal": d.map(|d| d.diagonal),
            "min_angle": r.quality.min_angle,
            "mean_angle": r.quality.mean_angle,
            "flipped": r.quality.flipped,
            "degenerate": r.quality.degenerate,
            "param_misses": r.param_misses,
            "time_ms": r.timings.total_ms,
            "search_ms": search_ms,
            "tries": tries,
            "timings": r.timings,
            "normal": resampled.as_ref().map(|x| &x.0),
            "normal_ms": resampled.as_ref().map(|x| x.1),
            "snap": snapped,
            "repair": r.repair,
            "missed": missed,
            "refolded": refolded,
            "warnings": warnings,
            "output": args.output.as_ref().map(|p| p.display().to_string()),
            "base_output": base_output.as_ref().map(|p| p.display().to_string()),
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(
            out,
            "{} → semi-regular, method {}",
            print::path(&args.mesh),
            r.method.name()
        )?;
        let mut t = print::Table::new();
        t.row(
            "base",
            format!(
                "{} faces, {} vertices",
                r.base.num_faces(),
                r.base.num_vertices()
            ),
        )
        .row(
            "levels",
            format!(
                "{} ({} split)",
                args.levels,
                if args.quads { "quad" } else { "triangle" }
            ),
        )
        .row(
            "result",
            format!(
                "{} faces, {} vertices",
                r.mesh.num_faces(),
                r.mesh.num_vertices()
            ),
        );
        if let Some(d) = d {
            t.row("psnr", format!("{:.2} dB", d.psnr))
                .row(
                    "rms",
                    format!("{:.4e} ({:.3e} of diagonal)", d.rms, d.rms / d.diagonal),
                )
                .row(
                    "max (Hausdorff)",
                    format!(
                        "{:.4e} ({:.3}% of diagonal)",
                        d.max,
                        100.0 * d.max / d.diagonal
                    ),
                );
        }
        t.row(
            "angles",
            format!(
                "min {:.2}°, mean of minima {:.2}°",
                r.quality.min_angle, r.quality.mean_angle
            ),
        )
        .row(
            "flipped / degenerate",
            format!("{} / {}", r.quality.flipped, r.quality.degenerate),
        )
        .row(
            "time",
            if tries > 1 {
                format!(
                    "{:.0} ms; {tries} tries over base sizes, {:.0} ms in all",
                    r.timings.total_ms, search_ms
                )
            } else {
                format!("{:.0} ms", r.timings.total_ms)
            },
        );
        if let Some((stats, ms)) = &resampled {
            let what = match (&stats.fit, args.normal) {
                (Some(f), false) => {
                    format!("{}{}", print::fit_stats(f), print::repaired(stats))
                }
                _ => print::normal_stats(stats),
            };
            t.row(
                "re-sampled",
                format!(
                    "{what}; {} vertices put back where they folded faces ({ms:.0} ms)",
                    stats.unfolded
                ),
            );
        }
        if let Some(s) = &snapped {
            t.row("grid", print::snap_stats(s));
        }
        if let Some(o) = &args.output {
            t.row("wrote", print::path(o));
        }
        if let Some(b) = &base_output {
            t.row("base mesh", print::path(b));
        }
        t.write(&mut out, "  ")?;
    }
    out.flush()?;
    Ok(())
}

/// Runs `subwave bench remesh`.
pub fn bench(args: &BenchRemeshArgs) -> Result<()> {
    let mesh = subwave::io::read_mesh(&args.mesh, None)?;
    let opts = RemeshOptions {
        levels: args.levels,
        base_faces: args.base_faces as usize,
        sharp_angle: args.sharp_angle,
        repair: args.repair,
        ..RemeshOptions::default()
    };
    let mut runs = Vec::new();
    for _ in 0..args.runs.max(1) {
        let r = run_with_bar(&mesh, &opts, true)?;
        runs.push(r.timings);
    }
    let mut sorted: Vec<_> = runs.iter().map(|t| t.total_ms).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let med_run = runs
        .iter()
        .find(|t| t.total_ms == median)
        .copied()
        .unwrap_or_default();
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let v = serde_json::json!({
            "mesh": args.mesh.display().to_string(),
            "levels": args.levels,
            "threads": rayon_threads(),
            "runs_ms": sorted,
            "median_ms": median,
            "stages": med_run,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    } else {
        writeln!(
            out,
            "remesh {} at {} levels, {} runs",
            print::path(&args.mesh),
            args.levels,
            sorted.len()
        )?;
        let mut t = print::Table::new();
        t.row("median", format!("{median:.0} ms"))
            .row("prepare", format!("{:.0} ms", med_run.prepare_ms))
            .row("simplify", format!("{:.0} ms", med_run.simplify_ms))
            .row("parameterize", format!("{:.0} ms", med_run.parameterize_ms))
            .row(
                "sampling relaxation",
                format!("{:.0} ms", med_run.param_relax_ms),
            )
            .row("resample", format!("{:.0} ms", med_run.resample_ms))
            .row("relax", format!("{:.0} ms", med_run.relax_ms));
        t.write(&mut out, "  ")?;
    }
    out.flush()?;
    Ok(())
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}
