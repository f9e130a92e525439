//! `subwave wavelet`: multiresolution analysis of a semi-regular mesh
//! ([`subwave::wavelet::report::analyze_report`]), as a table or as JSON.

use std::io::Write;

use anyhow::Result;
use subwave::io::read_mesh;
use subwave::wavelet::report::{analyze_report_with, ReportOptions, WaveletKind, WaveletReport};
use subwave::wavelet::triangle::DetailFrame;

use crate::info::check;
use crate::print;
use crate::WaveletArgs;

/// The `--wavelet` names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum WaveletArg {
    /// Lazy midpoint wavelet (triangles).
    Midpoint,
    /// Midpoint wavelet with the update step (triangles).
    MidpointLifted,
    /// Butterfly prediction (triangles).
    Butterfly,
    /// Butterfly prediction with the update step (triangles).
    ButterflyLifted,
    /// Loop wavelet of PGC (triangles).
    Loop,
    /// Integer lifted midpoint wavelet (triangles, 20-bit quantized positions).
    MidpointInt,
    /// Integer lifted butterfly wavelet (triangles, 20-bit quantized positions).
    ButterflyInt,
    /// Bertram linear B-spline wavelet (quads).
    Linear,
    /// Bertram cubic B-spline wavelet (quads).
    Cubic,
    /// Bertram quintic B-spline wavelet (quads).
    Quintic,
    /// Integer linear B-spline wavelet (quads, 20-bit quantized positions).
    LinearInt,
    /// Integer cubic B-spline wavelet (quads).
    CubicInt,
    /// Integer quintic B-spline wavelet (quads).
    QuinticInt,
}

impl From<WaveletArg> for WaveletKind {
    fn from(w: WaveletArg) -> Self {
        match w {
            WaveletArg::Midpoint => WaveletKind::Midpoint,
            WaveletArg::MidpointLifted => WaveletKind::MidpointLifted,
            WaveletArg::Butterfly => WaveletKind::Butterfly,
            WaveletArg::ButterflyLifted => WaveletKind::ButterflyLifted,
            WaveletArg::Loop => WaveletKind::Loop,
            WaveletArg::MidpointInt => WaveletKind::MidpointInt,
            WaveletArg::ButterflyInt => WaveletKind::ButterflyInt,
            WaveletArg::Linear => WaveletKind::Linear,
            WaveletArg::Cubic => WaveletKind::Cubic,
            WaveletArg::Quintic => WaveletKind::Quintic,
            WaveletArg::LinearInt => WaveletKind::LinearInt,
            WaveletArg::CubicInt => WaveletKind::CubicInt,
            WaveletArg::QuinticInt => WaveletKind::QuinticInt,
        }
    }
}

/// The `--frames` names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FramesArg {
    /// Details in local (normal, tangent, bitangent) frames (triangle wavelets).
    Local,
    /// Details in global x, y, z.
    Global,
}

/// Reads, analyses, prints.
pub fn run(args: &WaveletArgs) -> Result<()> {
    let name = print::path(&args.mesh);
    let mesh = read_mesh(&args.mesh, args.format)?;
    check(&mesh, &name)?;
    let frame = match args.frames {
        FramesArg::Local => DetailFrame::Local,
        FramesArg::Global => DetailFrame::Global,
    };
    let opts = ReportOptions {
        frame,
        runs: args.runs as usize,
    };
    let rep = analyze_report_with(&mesh, args.wavelet.into(), &opts)
        .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let text = serde_json::to_string_pretty(&rep)?;
        writeln!(out, "{text}")?;
    } else {
        write_human(&mut out, &name, &rep)?;
    }
    out.flush()?;
    Ok(())
}

fn write_human(out: &mut dyn Write, name: &str, r: &WaveletReport) -> std::io::Result<()> {
    writeln!(
        out,
        "{name}: {} wavelet ({} frames), {} hierarchy, {} levels",
        r.wavelet, r.frames, r.split, r.num_levels
    )?;
    writeln!(
        out,
        "  base mesh: {} vertices, {} faces; finest: {} vertices, {} faces; diagonal {}",
        print::count(r.base_vertices),
        print::count(r.base_faces),
        print::count(r.vertices),
        print::count(r.faces),
        print::coord(r.diagonal)
    )?;
    if let Some(b) = r.quantization_bits {
        writeln!(out, "  integer transform on {b}-bit quantized positions")?;
    }
    writeln!(
        out,
        "  {:>5} {:>10} {:>12} {:>9} {:>12} {:>10} {:>12} {:>12}",
        "level",
        "vertices",
        "l2 error",
        "l2 %diag",
        "max error",
        "details",
        "mean detail",
        "max detail"
    )?;
    for l in &r.levels {
        writeln!(
            out,
            "  {:>5} {:>10} {:>12.4e} {:>9.4} {:>12.4e} {:>10} {:>12.4e} {:>12.4e}",
            l.level,
            l.vertices,
            l.l2_error,
            l.l2_percent,
            l.max_error,
            l.details,
            l.mean_detail,
            l.max_detail
        )?;
    }
    writeln!(
        out,
        "  reconstruction max error {:.3e}",
        r.reconstruction_max_error
    )?;
    writeln!(
        out,
        "  in place, median of {} run(s): forward {:.3} ms ({:.1} Mvert/s, fastest {:.3} ms), inverse {:.3} ms ({:.1} Mvert/s, fastest {:.3} ms); plan {:.3} ms",
        r.runs,
        r.forward_ms,
        r.forward_mvert_per_s,
        r.forward_min_ms,
        r.inverse_ms,
        r.inverse_mvert_per_s,
        r.inverse_min_ms,
        r.plan_ms
    )
}
