//! `subwave decode`: a `.swv` stream (or a prefix of it) into a mesh file.

use std::io::Write;

use anyhow::{bail, Result};
use subwave::codec::progressive::{decode, inspect, DecodeOptions, Layout};
use subwave::io::write_mesh;

use crate::print;
use crate::DecodeArgs;

/// Parses `--trees 0,3,7-12`.
pub fn parse_trees(s: &str) -> Result<Vec<u32>, String> {
    let mut out = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let num = |x: &str| {
            x.trim()
                .parse::<u32>()
                .map_err(|_| format!("`{x}` is not a tree number (expected e.g. 0,3,7-12)"))
        };
        if let Some((a, b)) = part.split_once('-') {
            let (a, b) = (num(a)?, num(b)?);
            if a > b || b - a > 10_000_000 {
                return Err(format!("bad tree range `{part}`"));
            }
            out.extend(a..=b);
        } else {
            out.push(num(part)?);
        }
    }
    Ok(out)
}

/// Runs `subwave decode`.
pub fn run(args: &DecodeArgs) -> Result<()> {
    let name = print::path(&args.input);
    let bytes = std::fs::read(&args.input).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let info = inspect(&bytes).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let max_bytes = match (args.bytes, args.bpv) {
        (Some(_), Some(_)) => bail!("give --bytes or --bpv, not both"),
        (Some(b), None) => Some(b as usize),
        (None, Some(x)) => {
            if !(x.is_finite() && x > 0.0) {
                bail!("--bpv must be a positive number");
            }
            Some((x * info.input_vertices as f64 / 8.0).floor() as usize)
        }
        (None, None) => None,
    };
    let trees = match &args.trees {
        Some(t) => Some(parse_trees(t).map_err(anyhow::Error::msg)?),
        None => None,
    };
    if let Some(t) = &trees {
        if info.layout != Layout::Trees {
            bail!(
                "{name}: --trees needs a stream of the trees layout (encode with --layout trees); \
                 this one is embedded, its bit planes span all trees"
            );
        }
        if let Some(&bad) = t.iter().find(|&&x| x >= info.trees) {
            bail!(
                "{name}: there is no tree {bad}: the stream has {} trees (0-{})",
                info.trees,
                info.trees.saturating_sub(1)
            );
        }
    }
    let opts = DecodeOptions { max_bytes, trees };
    let d = decode(&bytes, &opts).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    write_mesh(&d.mesh, &args.output, args.to)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    writeln!(
        out,
        "{name}: {} of {} bytes ({:.2} bits per input vertex), {}/{} {}{} -> {} vertices, {} faces in {}",
        d.bytes_used,
        bytes.len(),
        8.0 * d.bytes_used as f64 / info.input_vertices.max(1) as f64,
        d.planes_complete,
        d.planes,
        if info.direct {
            "refinement planes of a direct stream"
        } else {
            "bit planes"
        },
        if d.complete { " (complete)" } else { "" },
        d.mesh.num_vertices(),
        d.mesh.num_faces(),
        args.output.display()
    )?;
    out.flush()?;
    Ok(())
}
