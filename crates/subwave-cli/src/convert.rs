//! `subwave convert`: read, check, optionally drop unreferenced vertices, write.

use std::io::Write;

use anyhow::Result;
use subwave::io::{read_mesh, write_mesh, Format};

use crate::print::{self, count};
use crate::ConvertArgs;

pub fn run(args: &ConvertArgs) -> Result<()> {
    let in_name = print::path(&args.input);
    let mut mesh = read_mesh(&args.input, args.from)?;
    crate::info::require_content(&mesh, &args.input)?;
    crate::info::check(&mesh, &in_name)?;

    let unreferenced = mesh.referenced().iter().filter(|&&used| !used).count();
    if unreferenced > 0 {
        if args.drop_unreferenced {
            mesh.remove_unreferenced();
            tracing::info!(
                "{in_name}: dropped {} unreferenced vertices",
                count(unreferenced)
            );
        } else {
            tracing::warn!(
                "{in_name}: {} unreferenced vertices (no face uses them); kept, pass \
                 --drop-unreferenced to remove them",
                count(unreferenced)
            );
        }
    }

    write_mesh(&mesh, &args.output, args.to)?;

    // With the mesh on standard output, stay quiet there.
    if args.output.as_os_str() != "-" {
        let format = args.to.or_else(|| Format::from_path(&args.output));
        let mut out = std::io::stdout().lock();
        writeln!(
            out,
            "wrote {}{}: {} vertices, {} faces",
            print::path(&args.output),
            format.map_or_else(String::new, |f| format!(" ({f})")),
            count(mesh.num_vertices()),
            count(mesh.num_faces())
        )?;
        out.flush()?;
    }
    Ok(())
}
