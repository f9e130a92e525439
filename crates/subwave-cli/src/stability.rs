//! `subwave stability [MESH]`: Bertram et al.'s noise experiment (§5.2, Fig. 17) for the
//! linear, cubic and quintic B-spline wavelets
//! ([`subwave::wavelet::stability::stability`]), as a table or as JSON.

use std::io::Write;

use anyhow::Result;
use subwave::generate;
use subwave::io::read_mesh;
use subwave::wavelet::bertram::Degree;
use subwave::wavelet::stability::{stability, StabilityReport};

use crate::info::check;
use crate::print;
use crate::StabilityArgs;

/// Runs the experiment on MESH (default: a cube) and prints it.
pub fn run(args: &StabilityArgs) -> Result<()> {
    let (name, mesh) = match &args.mesh {
        Some(p) => {
            let name = print::path(p);
            let mesh = read_mesh(p, args.format)?;
            check(&mesh, &name)?;
            (name, mesh)
        }
        None => ("cube".to_string(), generate::cube()),
    };
    let rep = stability(&mesh, &Degree::ALL, args.levels, args.noise, args.seed)
        .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&rep)?)?;
    } else {
        write_human(&mut out, &name, &rep)?;
    }
    out.flush()?;
    Ok(())
}

fn write_human(out: &mut dyn Write, name: &str, r: &StabilityReport) -> std::io::Result<()> {
    writeln!(
        out,
        "{name}: {} levels, uniform noise of {} × the finest mean edge length, low-passed level by level",
        r.levels, r.noise
    )?;
    writeln!(
        out,
        "  noise RMS / mean edge length of the level (gain: noise RMS / finest noise RMS)"
    )?;
    let mut header = format!("  {:>5} {:>10}", "level", "vertices");
    for run in &r.runs {
        header.push_str(&format!(" {:>10} {:>10}", run.degree, "gain"));
    }
    writeln!(out, "{header}")?;
    let rows = r.runs.first().map_or(0, |run| run.levels.len());
    for i in 0..rows {
        let l0 = &r.runs[0].levels[i];
        let mut line = format!("  {:>5} {:>10}", l0.level, print::count(l0.vertices));
        for run in &r.runs {
            let l = &run.levels[i];
            line.push_str(&format!(" {:>10.4} {:>10.4}", l.relative, l.gain));
        }
        writeln!(out, "{line}")?;
    }
    for run in &r.runs {
        let first = run.levels.first().map_or(0.0, |l| l.relative);
        // After three low-pass steps (or all there are), as the paper's Fig. 17 compares.
        let last = run
            .levels
            .get(3.min(run.levels.len().saturating_sub(1)))
            .map_or(0.0, |l| l.relative);
        let verdict = if last < 0.5 * first {
            "reduces the noise"
        } else if last <= 2.0 * first {
            "keeps the relative noise roughly constant"
        } else {
            "amplifies the noise (unstable)"
        };
        writeln!(
            out,
            "  {}: {verdict} (after {} low-pass steps)",
            run.degree,
            3.min(run.levels.len().saturating_sub(1))
        )?;
    }
    Ok(())
}
