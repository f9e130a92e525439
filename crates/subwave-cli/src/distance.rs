//! `subwave distance A B`: Metro-style symmetric surface distance and PSNR.

use std::io::Write;

use anyhow::Result;
use subwave::distance::distance;

use crate::print;
use crate::DistanceArgs;

/// Runs `subwave distance`.
pub fn run(args: &DistanceArgs) -> Result<()> {
    let a = subwave::io::read_mesh(&args.a, None)?;
    let b = subwave::io::read_mesh(&args.b, None)?;
    let d = distance(&a, &b, args.samples as usize)
        .map_err(|e| anyhow::anyhow!("{} vs {}: {e}", args.a.display(), args.b.display()))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        let text = serde_json::to_string_pretty(&d)?;
        writeln!(out, "{text}")?;
    } else {
        writeln!(
            out,
            "{} (A) vs {} (B), {} + {} samples",
            print::path(&args.a),
            print::path(&args.b),
            d.ab.samples,
            d.ba.samples
        )?;
        let rel = |x: f64| format!("{x:.6e}  ({:.3e} of A's diagonal)", x / d.diagonal);
        let mut t = print::Table::new();
        t.row("rms", rel(d.rms))
            .row("max (Hausdorff)", rel(d.max))
            .row("psnr", format!("{:.2} dB", d.psnr))
            .row("rms A→B", rel(d.rms_ab))
            .row("rms B→A", rel(d.rms_ba))
            .row(
                "max A→B",
                format!("{}  at {}", rel(d.ab.max), point(d.ab.farthest)),
            )
            .row(
                "max B→A",
                format!("{}  at {}", rel(d.ba.max), point(d.ba.farthest)),
            );
        t.write(&mut out, "  ")?;
    }
    out.flush()?;
    Ok(())
}

/// A point as `(x, y, z)` with 4 significant digits.
pub(crate) fn point(p: [f64; 3]) -> String {
    format!("({:.4e}, {:.4e}, {:.4e})", p[0], p[1], p[2])
}
