//! Printing helpers: aligned two-column tables, numbers, sizes and the mesh report.

use std::io::{self, Write};
use std::path::Path;
use std::time::Duration;

use subwave::validate::MeshReport;

/// Rows of `label  value`, printed with the values aligned. A value may span several lines;
/// continuation lines are indented to the value column.
#[derive(Debug, Default)]
pub struct Table {
    rows: Vec<(String, String)>,
}

impl Table {
    pub fn new() -> Self {
        Table::default()
    }

    pub fn row(&mut self, label: impl Into<String>, value: impl Into<String>) -> &mut Self {
        self.rows.push((label.into(), value.into()));
        self
    }

    /// Writes the table, each line starting with `indent`.
    pub fn write(&self, w: &mut dyn Write, indent: &str) -> io::Result<()> {
        let width = self
            .rows
            .iter()
            .map(|(l, _)| l.chars().count())
            .max()
            .unwrap_or(0);
        for (label, value) in &self.rows {
            let mut lines = value.lines();
            let first = lines.next().unwrap_or("");
            writeln!(w, "{indent}{label:<width$}  {first}")?;
            for more in lines {
                writeln!(w, "{indent}{:<width$}  {more}", "")?;
            }
        }
        Ok(())
    }
}

/// A count with thin grouping for readability: `104288` -> `104,288`.
pub fn count(n: usize) -> String {
    group(&n.to_string())
}

/// A signed count with grouping.
pub fn signed(n: i64) -> String {
    if n < 0 {
        format!("-{}", group(&n.unsigned_abs().to_string()))
    } else {
        group(&n.to_string())
    }
}

fn group(digits: &str) -> String {
    let mut rev = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().rev().enumerate() {
        if i > 0 && i % 3 == 0 {
            rev.push(',');
        }
        rev.push(c);
    }
    rev.chars().rev().collect()
}

/// A coordinate with 6 significant digits, in plain notation for ordinary magnitudes.
pub fn coord(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 {
        "0".to_string()
    } else if !(1e-4..1e7).contains(&a) {
        format!("{x:.5e}")
    } else {
        let decimals = (5 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{x:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    }
}

/// A point as `(x, y, z)`.
pub fn point(p: [f64; 3]) -> String {
    format!("({}, {}, {})", coord(p[0]), coord(p[1]), coord(p[2]))
}

/// A byte size: `512 B`, `12.3 KiB`, `4.56 MiB`.
pub fn size(bytes: u64) -> String {
    const K: f64 = 1024.0;
    let b = bytes as f64;
    if b < K {
        format!("{bytes} B")
    } else if b < K * K {
        format!("{:.1} KiB", b / K)
    } else if b < K * K * K {
        format!("{:.2} MiB", b / (K * K))
    } else {
        format!("{:.2} GiB", b / (K * K * K))
    }
}

/// A duration in milliseconds or seconds.
pub fn duration(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s < 1.0 {
        format!("{:.1} ms", s * 1e3)
    } else {
        format!("{s:.2} s")
    }
}

/// A path for messages.
pub fn path(p: &Path) -> String {
    p.display().to_string()
}

/// The name of faces of `arity` corners.
fn arity_name(arity: usize, n: usize) -> String {
    let s = if n == 1 { "" } else { "s" };
    match arity {
        3 => format!("triangle{s}"),
        4 => format!("quad{s}"),
        a => format!("{a}-gon{s}"),
    }
}

/// `500 (468 quads, 32 triangles)`.
pub fn faces(r: &MeshReport) -> String {
    let parts: Vec<String> = r
        .faces_by_arity
        .iter()
        .map(|(&a, &n)| format!("{} {}", count(n), arity_name(a, n)))
        .collect();
    if parts.is_empty() {
        count(r.faces)
    } else {
        format!("{} ({})", count(r.faces), parts.join(", "))
    }
}

/// The valence histogram as `valence:count` pairs, `per_line` to a line.
fn valences(r: &MeshReport, per_line: usize) -> String {
    if r.valence_histogram.is_empty() {
        return "none".to_string();
    }
    let pairs: Vec<String> = r
        .valence_histogram
        .iter()
        .map(|(v, n)| format!("{v}:{}", count(*n)))
        .collect();
    pairs
        .chunks(per_line)
        .map(|c| c.join("  "))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Genus, or why it is undefined.
pub fn genus(r: &MeshReport) -> String {
    match r.genus {
        Some(g) => g.to_string(),
        None => "undefined (not a consistently oriented 2-manifold)".to_string(),
    }
}

/// The full report as a table: every field of [`MeshReport`].
pub fn report_table(r: &MeshReport) -> Table {
    let mut t = Table::new();
    t.row(
        "vertices",
        format!(
            "{} ({} referenced, {} unreferenced)",
            count(r.vertices),
            count(r.referenced_vertices),
            count(r.unreferenced_vertices)
        ),
    );
    t.row("faces", faces(r));
    t.row("edges", count(r.edges));
    t.row("boundary edges", count(r.boundary_edges));
    t.row("boundary loops", count(r.boundary_loops));
    t.row("components", count(r.components));
    t.row("Euler characteristic", signed(r.euler_characteristic));
    t.row("genus", genus(r));
    t.row("non-manifold edges", count(r.non_manifold_edges));
    t.row("non-manifold vertices", count(r.non_manifold_vertices));
    t.row(
        "inconsistently oriented edges",
        count(r.inconsistent_orientation_edges),
    );
    // What the repair would fix, with how.
    let fixable = |n: usize, how: &str| {
        if n > 0 {
            format!("{} (remesh --repair {how} them)", count(n))
        } else {
            count(0)
        }
    };
    t.row(
        "duplicated seam vertices",
        fixable(r.seam_vertices, "welds"),
    );
    t.row("slit T-junctions", fixable(r.slit_vertices, "stitches"));
    t.row("crease edges", count(r.crease_edges));
    t.row(
        "vertex tags",
        format!(
            "smooth {}, dart {}, crease {}, corner {}",
            count(r.tags.smooth),
            count(r.tags.dart),
            count(r.tags.crease),
            count(r.tags.corner)
        ),
    );
    t.row("valence histogram", valences(r, 8));
    t.row("bounding box min", point(r.bbox_min));
    t.row("bounding box max", point(r.bbox_max));
    t.row("bounding box diagonal", coord(r.bbox_diagonal));
    t
}

/// A one-line summary of a report, e.g. for the demo.
pub fn report_line(r: &MeshReport) -> String {
    format!(
        "{} vertices, {} faces, {} edges, {} component(s), χ = {}, genus {}",
        count(r.vertices),
        count(r.faces),
        count(r.edges),
        count(r.components),
        signed(r.euler_characteristic),
        r.genus
            .map_or_else(|| "undefined".to_string(), |g| g.to_string())
    )
}

/// One line on a normal re-sampling: how many odd vertices were pierced or projected.
pub fn normal_stats(n: &subwave::remesh::normal::NormalStats) -> String {
    let odd: usize = n.odd.iter().sum();
    let pierced: usize = n.normal.iter().sum();
    let projected: usize = n.projected.iter().sum();
    let pc = |k: usize| 100.0 * k as f64 / odd.max(1) as f64;
    let fit = n
        .fit
        .map_or_else(String::new, |f| format!("; {}", fit_stats(&f)));
    let repaired = repaired(n);
    format!(
        "normal mesh: {pierced} of {odd} odd vertices pierced ({:.1}%), {projected} projected ({:.1}%), {} kept{fit}{repaired}",
        pc(pierced),
        pc(projected),
        odd - pierced - projected
    )
}

/// A snap to the lossless grid, as `"N of M odd vertices on their normal lines (P%), moved
/// by A steps on average, at most B (step S)"` and the vertices only rounded, if any.
pub fn snap_stats(s: &subwave::codec::normal_line::SnapStats) -> String {
    let odd: usize = s.odd.iter().sum();
    let on: usize = s.on_line.iter().sum();
    format!(
        "{on} of {odd} odd vertices on their normal lines ({:.1}%), moved by {:.2} grid steps on average, at most {:.2} (step {:.3e}){}",
        100.0 * s.on_line_fraction(),
        s.mean_move,
        s.max_move,
        s.grid_step,
        match s.reverted {
            0 => String::new(),
            n => format!("; {n} only rounded, where the move turned a face over"),
        }
    )
}

/// The repair of the faces a re-sampling folded, as `"; B folded or degenerate faces
/// repaired, A left"`; empty if there were none.
pub fn repaired(n: &subwave::remesh::normal::NormalStats) -> String {
    match n.repaired {
        [0, _] => String::new(),
        [b, a] => format!("; {b} folded or degenerate faces repaired, {a} left"),
    }
}

/// The least-squares offsets off the input (`remesh::normal_fit`), in a few words.
pub fn fit_stats(f: &subwave::remesh::normal_fit::FitStats) -> String {
    format!(
        "least-squares offsets off the input on {} vertices (mean {:.3} edge lengths, {} clamped)",
        f.movable, f.mean_offset, f.clamped
    )
}

/// The line `subwave encode` prints for the distance from the remesh to the input (with
/// `lossy`, and which bit planes that distance leaves uncoded).
pub fn remesh_distance(rms: f64, diagonal: f64, lossy: bool) -> String {
    let planes = if lossy {
        format!(
            "; bit planes below a quantization error of {:.0}% of it are not coded",
            100.0 * subwave::codec::prepare::QUANTIZATION_SHARE
        )
    } else {
        String::new()
    };
    format!(
        "remesh: {:.2} dB from the remesh to the input (one-sided RMS {rms:.4e}){planes}",
        subwave::distance::psnr(diagonal, rms),
    )
}

/// The line on the distance from the input to its remesh (if it was measured), on the
/// remeshes that missed part of the input before it and on the one redone with more levels
/// because it topped out below the ceiling; `None` when there is none of these.
pub fn input_distance(p: &subwave::codec::prepare::Prepared, diagonal: f64) -> Option<String> {
    let (distance, missed, raised) = (p.input_distance, &p.missed, p.raised.as_ref());
    if distance.is_none() && missed.is_empty() && raised.is_none() {
        return None;
    }
    let mut s = String::from("remesh: ");
    if let Some((rms, max)) = distance {
        s += &format!(
            "{:.2} dB from the input to the remesh (one-sided RMS {rms:.4e}, Hausdorff {:.3}% of the diagonal)",
            subwave::distance::psnr(diagonal, rms),
            100.0 * max / diagonal
        );
    }
    if !missed.is_empty() {
        let list: Vec<String> = missed
            .iter()
            .map(|m| format!("{} levels over {} base faces", m.levels, m.base_faces))
            .collect();
        if distance.is_some() {
            s += "; ";
        }
        s += &format!(
            "remeshed finer after {} missed part of the input (Hausdorff from the input over {:.1}% of the diagonal)",
            list.join(", then "),
            100.0 * subwave::codec::prepare::MISS_FRACTION
        );
    }
    if let Some(r) = raised {
        if distance.is_some() || !missed.is_empty() {
            s += "; ";
        }
        s += &format!(
            "levels raised: the remesh at {} levels over {} base faces topped out at {:.1} dB, below {:.0} dB",
            r.levels,
            r.base_faces,
            r.psnr,
            subwave::codec::prepare::CEILING_DB
        );
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grouping() {
        assert_eq!(count(0), "0");
        assert_eq!(count(999), "999");
        assert_eq!(count(1000), "1,000");
        assert_eq!(count(104288), "104,288");
        assert_eq!(signed(-34), "-34");
        assert_eq!(signed(-1234), "-1,234");
    }

    #[test]
    fn coordinates() {
        assert_eq!(coord(0.0), "0");
        assert_eq!(coord(1.0), "1");
        assert_eq!(coord(-0.5), "-0.5");
        assert_eq!(coord(1.234567891), "1.23457");
        assert_eq!(coord(123456.7), "123457");
        assert_eq!(coord(1e-9), "1.00000e-9");
    }

    #[test]
    fn sizes() {
        assert_eq!(size(12), "12 B");
        assert_eq!(size(2048), "2.0 KiB");
        assert_eq!(size(3 * 1024 * 1024), "3.00 MiB");
    }

    #[test]
    fn table_alignment() {
        let mut t = Table::new();
        t.row("a", "1").row("long label", "2\n3");
        let mut out = Vec::new();
        t.write(&mut out, "  ").unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "  a           1\n  long label  2\n              3\n"
        );
    }
}
