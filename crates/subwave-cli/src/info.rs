//! `subwave info`: the mesh report, as an aligned table or as JSON.

use std::io::Write;

use anyhow::Result;
use subwave::io::{read_mesh, Format};
use subwave::validate::{report, MeshReport};
use subwave::{Error, Mesh, Topology};

use crate::print;
use crate::InfoArgs;

/// Checks a mesh the way every command needs before building its topology.
pub fn check(mesh: &Mesh, path: &str) -> Result<(), Error> {
    mesh.check_indices().map_err(|source| Error::InvalidMesh {
        path: path.to_string(),
        source,
    })
}

/// Fails unless `mesh` (read from `path`) holds something: vertices or faces. A file that
/// parses to nothing (an empty file, or bytes in no statement the reader knows) is refused
/// rather than converted or reported as an empty mesh.
pub fn require_content(mesh: &Mesh, path: &std::path::Path) -> Result<()> {
    if mesh.num_vertices() == 0 && mesh.num_faces() == 0 {
        anyhow::bail!(
            "{}: the file holds no vertices and no faces (is it a mesh in this format?)",
            path.display()
        );
    }
    Ok(())
}

/// Fails unless `mesh` (read from `path`) has faces, for commands that `task` them (a point
/// cloud or an empty file has nothing to subdivide or code: refused rather than written
/// out as an empty mesh).
pub fn require_faces(mesh: &Mesh, path: &std::path::Path, task: &str) -> Result<()> {
    require_content(mesh, path)?;
    if mesh.num_faces() == 0 {
        anyhow::bail!(
            "{}: the mesh has no faces ({} vertices only): nothing to {task}",
            path.display(),
            mesh.num_vertices()
        );
    }
    Ok(())
}

/// Reads, checks and reports.
pub fn run(args: &InfoArgs) -> Result<()> {
    let name = print::path(&args.mesh);
    let mesh = read_mesh(&args.mesh, args.format)?;
    require_content(&mesh, &args.mesh)?;
    check(&mesh, &name)?;
    let rep = report(&mesh, &Topology::build(&mesh));
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        // Serialize first: a closed pipe must surface as an `io::Error` (see `is_broken_pipe`).
        let text = serde_json::to_string_pretty(&rep)?;
        writeln!(out, "{text}")?;
    } else {
        let format = args.format.or_else(|| Format::from_path(&args.mesh));
        write_human(&mut out, &name, format, &rep)?;
    }
    out.flush()?;
    Ok(())
}

fn write_human(
    out: &mut dyn Write,
    name: &str,
    format: Option<Format>,
    rep: &MeshReport,
) -> std::io::Result<()> {
    match format {
        Some(f) => writeln!(out, "{name} ({f})")?,
        None => writeln!(out, "{name}")?,
    }
    print::report_table(rep).write(out, "  ")
}
