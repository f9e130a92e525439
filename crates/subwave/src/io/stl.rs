//! Stereolithography (STL), ascii and binary.
//!
//! STL stores unconnected triangles; the reader welds vertices whose positions are exactly
//! equal (bit-equal after mapping `-0.0` to `0.0`) into one, so the result is an indexed mesh
//! whose topology can be built. Vertices are numbered in order of first appearance. Nothing is
//! welded that is merely close: use a remeshing step for that.
//!
//! A file is binary if its size is exactly `84 + 50 × n` bytes, where `n` is the triangle count
//! stored at bytes 80..84, even if its 80-byte header starts with `solid` (many binary
//! exporters write that); otherwise it is ascii if it starts with `solid`.

use std::collections::HashMap;
use std::io::{BufWriter, Write};

use glam::DVec3;

use super::{
    at_byte, at_file, at_line, check_writable, parse_f64, quote, strip_bom, write_err, Tokens,
};
use crate::{Mesh, Result};

/// Welds exactly coincident vertices while triangles are added.
struct Welder {
    map: HashMap<[u64; 3], u32>,
    mesh: Mesh,
}

impl Welder {
    fn new(triangles: usize) -> Self {
        let mut mesh = Mesh::new();
        // A closed triangle mesh has about half as many vertices as triangles.
        mesh.face_offsets.reserve_exact(triangles);
        mesh.face_indices.reserve_exact(3 * triangles);
        Welder {
            map: HashMap::with_capacity(triangles / 2 + 1),
            mesh,
        }
    }

    fn vertex(&mut self, p: [f64; 3]) -> u32 {
        // -0.0 == 0.0, so `x == 0.0` maps both zeros to +0.0.
        let key = p.map(|x| if x == 0.0 { 0u64 } else { x.to_bits() });
        let next = self.mesh.positions.len() as u32;
        let positions = &mut self.mesh.positions;
        *self.map.entry(key).or_insert_with(|| {
            positions.push(DVec3::from_array(p.map(|x| if x == 0.0 { 0.0 } else { x })));
            next
        })
    }

    /// Adds a triangle; `Err(())` if two of its corners weld to the same vertex.
    fn triangle(&mut self, corners: [[f64; 3]; 3]) -> std::result::Result<(), ()> {
        let [a, b, c] = corners.map(|p| self.vertex(p));
        if a == b || b == c || a == c {
            return Err(());
        }
        self.mesh.face_indices.extend_from_slice(&[a, b, c]);
        self.mesh
            .face_offsets
            .push(self.mesh.face_indices.len() as u32);
        Ok(())
    }
}

/// Reads an STL file (ascii or binary) from `bytes`; `path` is only used in error messages.
///
/// The result has one triangle per facet, in file order, and one vertex per distinct position
/// (see the [module docs](self)). Facet normals and binary attribute bytes are ignored.
///
/// # Errors
/// [`Error::Parse`](crate::Error::Parse) naming the facet (1-based): a NaN or infinite
/// coordinate, or a facet two of whose vertices are identical (`facet 12 has two identical
/// vertices`; such a facet is degenerate and is reported, not silently dropped), at the byte
/// offset of the facet (binary) or at its line (ascii); in ascii files also unexpected or
/// unparsable tokens and a missing `endsolid`. A file that is neither binary-sized nor starts
/// with `solid` is an error at `Location::File`.
pub fn read(bytes: &[u8], path: &str) -> Result<Mesh> {
    let declared = bytes
        .get(80..84)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    let binary_size = declared.map(|n| 84 + 50 * n as u64);
    if binary_size == Some(bytes.len() as u64) {
        return read_binary(bytes, path);
    }
    let mismatch = match (declared, binary_size) {
        (Some(n), Some(size)) => format!(
            "as binary STL its header declares {n} triangles ({size} bytes), but the file has \
             {} bytes",
            bytes.len()
        ),
        _ => format!(
            "the file is too short ({} bytes) for binary STL",
            bytes.len()
        ),
    };
    let bytes = strip_bom(bytes);
    let text = bytes.trim_ascii_start();
    if text.len() >= 5 && text[..5].eq_ignore_ascii_case(b"solid") {
        return read_ascii(bytes, path).map_err(|e| match e {
            crate::Error::Parse {
                path,
                location,
                message,
            } => crate::Error::Parse {
                path,
                location,
                message: format!(
                    "{message} (read as ascii STL because it starts with `solid`; {mismatch})"
                ),
            },
            other => other,
        });
    }
    Err(at_file(
        path,
        format!("not an STL file: it does not start with `solid` and {mismatch}"),
    ))
}

fn read_binary(bytes: &[u8], path: &str) -> Result<Mesh> {
    let n = (bytes.len() - 84) / 50;
    if n > u32::MAX as usize / 3 {
        return Err(at_file(
            path,
            format!("{n} triangles are too many to index with u32"),
        ));
    }
    let mut w = Welder::new(n);
    for (i, rec) in bytes[84..].chunks_exact(50).enumerate() {
        let offset = 84 + 50 * i;
        let mut corners = [[0.0f64; 3]; 3];
        for (c, corner) in corners.iter_mut().enumerate() {
            for (k, x) in corner.iter_mut().enumerate() {
                let at = 12 + 12 * c + 4 * k;
                let v = f32::from_le_bytes([rec[at], rec[at + 1], rec[at + 2], rec[at + 3]]);
                if !v.is_finite() {
                    return Err(at_byte(
                        path,
                        offset + at,
                        format!(
                            "facet {}: vertex {} has a non-finite coordinate",
                            i + 1,
                            c + 1
                        ),
                    ));
                }
                *x = f64::from(v);
            }
        }
        if w.triangle(corners).is_err() {
            return Err(at_byte(
                path,
                offset,
                format!("facet {} has two identical vertices", i + 1),
            ));
        }
    }
    Ok(w.mesh)
}

fn read_ascii(bytes: &[u8], path: &str) -> Result<Mesh> {
    let mut t = Tokens::new(bytes, 1);
    // About 7 lines and 250 bytes per facet.
    let mut w = Welder::new(bytes.len() / 256);
    let mut facet = 0usize;
    // `facet` is the current facet (0 outside facets), for the error message.
    let unexpected = |t: &Tokens, tok: Option<&[u8]>, want: &str, facet: usize| {
        let found = match tok {
            Some(tok) => format!("`{}`", quote(tok)),
            None => "the end of the file".to_string(),
        };
        let prefix = if facet > 0 {
            format!("facet {facet}: ")
        } else {
            String::new()
        };
        at_line(
            path,
            t.line(),
            format!("{prefix}expected {want}, found {found}"),
        )
    };
    let keyword = |t: &mut Tokens, want: &str, facet: usize| -> Result<()> {
        match t.next_token() {
            Some(tok) if tok.eq_ignore_ascii_case(want.as_bytes()) => Ok(()),
            other => Err(unexpected(t, other, &format!("`{want}`"), facet)),
        }
    };
    // `solid [name]`
    keyword(&mut t, "solid", 0)?;
    t.skip_line();
    loop {
        let tok = t.next_token();
        match tok {
            Some(k) if k.eq_ignore_ascii_case(b"facet") => {}
            Some(k) if k.eq_ignore_ascii_case(b"endsolid") => {
                t.skip_line();
                match t.next_token() {
                    None => break,
                    Some(k) if k.eq_ignore_ascii_case(b"solid") => {
                        t.skip_line();
                        continue;
                    }
                    other => {
                        return Err(unexpected(&t, other, "`solid` or the end of the file", 0))
                    }
                }
            }
            other => return Err(unexpected(&t, other, "`facet` or `endsolid`", 0)),
        }
        facet += 1;
        let line = t.line();
        keyword(&mut t, "normal", facet)?;
        for _ in 0..3 {
            let tok = t.next_token().unwrap_or_default();
            // Normals are ignored, but must be numbers (NaN is tolerated: exporters write it).
            if parse_f64(tok).is_none() {
                return Err(at_line(
                    path,
                    t.line(),
                    format!(
                        "facet {facet}: cannot parse `{}` as a normal component",
                        quote(tok)
                    ),
                ));
            }
        }
        keyword(&mut t, "outer", facet)?;
        keyword(&mut t, "loop", facet)?;
        let mut corners = [[0.0f64; 3]; 3];
        for (c, corner) in corners.iter_mut().enumerate() {
            let tok = t.next_token();
            if !tok.is_some_and(|k| k.eq_ignore_ascii_case(b"vertex")) {
                return Err(at_line(
                    path,
                    t.line(),
                    format!(
                        "facet {facet}: expected `vertex` (a facet has 3), found {}",
                        match tok {
                            Some(k) => format!("`{}` after {c} vertices", quote(k)),
                            None => "the end of the file".to_string(),
                        }
                    ),
                ));
            }
            for x in corner.iter_mut() {
                let tok = t.next_token().unwrap_or_default();
                *x = parse_f64(tok).ok_or_else(|| {
                    at_line(
                        path,
                        t.line(),
                        format!("facet {facet}: cannot parse `{}` as a number", quote(tok)),
                    )
                })?;
                if !x.is_finite() {
                    return Err(at_line(
                        path,
                        t.line(),
                        format!(
                            "facet {facet}: vertex {} has a non-finite coordinate",
                            c + 1
                        ),
                    ));
                }
            }
        }
        match t.next_token() {
            Some(k) if k.eq_ignore_ascii_case(b"endloop") => {}
            Some(k) if k.eq_ignore_ascii_case(b"vertex") => {
                return Err(at_line(
                    path,
                    t.line(),
                    format!("facet {facet} has more than 3 vertices; STL facets are triangles"),
                ))
            }
            other => return Err(unexpected(&t, other, "`endloop`", facet)),
        }
        keyword(&mut t, "endfacet", facet)?;
        if w.triangle(corners).is_err() {
            return Err(at_line(
                path,
                line,
                format!("facet {facet} has two identical vertices"),
            ));
        }
        if w.mesh.face_indices.len() > u32::MAX as usize - 3 {
            return Err(at_line(path, line, "too many facets"));
        }
    }
    Ok(w.mesh)
}

/// Writes `mesh` as binary STL: an 80-byte header, the triangle count, then per triangle its
/// unit normal (zero if degenerate), three `f32` corners and a zero attribute word.
///
/// Faces are fan-triangulated ([`Mesh::triangulate`]); positions are rounded to `f32`.
/// Colours, uvs and tags are dropped.
///
/// # Errors
/// [`Error::Mesh`](crate::Error::Mesh) if the mesh is invalid,
/// [`Error::InvalidArgument`](crate::Error::InvalidArgument) if it has more than `u32::MAX`
/// triangles, [`Error::Io`](crate::Error::Io) if writing fails.
pub fn write(mesh: &Mesh, w: &mut dyn Write) -> Result<()> {
    check_writable(mesh)?;
    let (tris, _) = mesh.triangulate();
    let n = u32::try_from(tris.len()).map_err(|_| {
        crate::Error::InvalidArgument(format!(
            "{} triangles do not fit in binary STL (at most {})",
            tris.len(),
            u32::MAX
        ))
    })?;
    let mut w = BufWriter::with_capacity(1 << 16, w);
    let mut write = || -> std::io::Result<()> {
        let mut header = [b' '; 80];
        let title = b"binary STL written by subwave";
        header[..title.len()].copy_from_slice(title);
        w.write_all(&header)?;
        w.write_all(&n.to_le_bytes())?;
        for t in &tris {
            let [a, b, c] = t.map(|v| mesh.positions[v as usize]);
            let normal = (b - a).cross(c - a).normalize_or_zero();
            for p in [normal, a, b, c] {
                for x in p.to_array() {
                    w.write_all(&(x as f32).to_le_bytes())?;
                }
            }
            w.write_all(&[0, 0])?;
        }
        w.flush()
    };
    write().map_err(write_err)
}
