//! Object File Format (OFF), as written by Geomview, CGAL, Meshlab and libigl.
//!
//! Layout: a header keyword `[ST][C][N]OFF` (texture coordinates, colours, normals), a counts
//! line `vertices faces [edges]` (it may share the header line), one line per vertex
//! `x y z [nx ny nz] [r g b [a]] [s t]`, then one line per face `n i0 .. i(n-1) [colour]` with
//! 0-based indices. `#` starts a comment; blank lines are skipped. Colours whose components are
//! all integers are on the 0..255 scale, otherwise on 0..1. Normals, alpha, face colours and
//! the edge count are ignored. Higher-dimensional (`4OFF`, `nOFF`) and `OFF BINARY` files are
//! rejected with a clear error.
//!
//! Each vertex and face must be on its own line (as every common writer does); this gives
//! errors a line number and lets a face carry optional trailing colour values.

use std::io::{BufWriter, Write};

use glam::DVec3;

use super::{
    at_file, at_line, check_writable, fits_u32, parse_f32, parse_f64, parse_int, quote,
    repeated_vertex, strip_bom, strip_comment, tokens, write_err, Lines, Num,
};
use crate::{Mesh, Result};

fn next_content<'a>(lines: &mut Lines<'a>) -> Option<(usize, &'a [u8])> {
    for (no, raw) in lines.by_ref() {
        let line = strip_comment(raw);
        if !line.is_empty() {
            return Some((no, line));
        }
    }
    None
}

/// The first four tokens and the number of tokens.
fn first_four<'a>(toks: impl Iterator<Item = &'a [u8]>) -> ([&'a [u8]; 4], usize) {
    let mut out: [&[u8]; 4] = [&[]; 4];
    let mut n = 0;
    for t in toks {
        if n < out.len() {
            out[n] = t;
        }
        n += 1;
    }
    (out, n)
}

/// What the header keyword announces.
#[derive(Clone, Copy)]
struct Header {
    texture: bool,
    color: bool,
    normal: bool,
}

fn parse_keyword(kw: &[u8]) -> std::result::Result<Header, String> {
    let Some(prefix) = kw.strip_suffix(b"OFF") else {
        return Err(format!(
            "not an OFF file: expected the header `OFF` (or `COFF`, `NOFF`, `STOFF`, ...), \
             found `{}`",
            quote(kw)
        ));
    };
    let mut rest = prefix;
    let mut take = |p: &[u8]| match rest.strip_prefix(p) {
        Some(r) => {
            rest = r;
            true
        }
        None => false,
    };
    let texture = take(b"ST");
    let color = take(b"C");
    let normal = take(b"N");
    if rest.is_empty() {
        Ok(Header {
            texture,
            color,
            normal,
        })
    } else if rest.contains(&b'4') || rest.contains(&b'n') {
        Err(format!(
            "`{}`: 4-D and n-D OFF files are not supported; only 3-D vertices are",
            quote(kw)
        ))
    } else {
        Err(format!(
            "unknown OFF header `{}`; expected `[ST][C][N]OFF`",
            quote(kw)
        ))
    }
}

/// Reads an OFF file from `bytes`; `path` is only used in error messages.
///
/// Vertex and face counts are those of the counts line. Colours (`COFF`) fill
/// [`Mesh::colors`]; texture coordinates (`STOFF`) fill [`Mesh::uvs`].
///
/// # Errors
/// [`Error::Parse`](crate::Error::Parse) at the 1-based line, naming the element: a missing or unknown header, a
/// malformed counts line, counts larger than the rest of the file could hold (checked before
/// allocating), a vertex with too few or unparsable values or a NaN/infinite coordinate, a face
/// with fewer than 3 vertices, an index out of range (`0..=n-1`), a repeated vertex, or a file
/// that ends before all announced vertices and faces (`Location::File`).
pub fn read(bytes: &[u8], path: &str) -> Result<Mesh> {
    let mut lines = Lines::new(strip_bom(bytes));
    let (hl, header) = next_content(&mut lines)
        .ok_or_else(|| at_file(path, "the file is empty; expected an `OFF` header"))?;
    let mut toks = tokens(header);
    let kw = toks.next().unwrap_or_default();
    let h = parse_keyword(kw).map_err(|m| at_line(path, hl, m))?;
    let mut rest = toks.peekable();
    if rest.peek() == Some(&&b"BINARY"[..]) {
        return Err(at_line(
            path,
            hl,
            "binary OFF files are not supported; use ascii OFF",
        ));
    }
    let (mut count_toks, mut nc) = first_four(rest);
    let mut count_line = hl;
    if nc == 0 {
        let (cl, line) = next_content(&mut lines)
            .ok_or_else(|| at_file(path, "the file ends before the counts line"))?;
        count_line = cl;
        (count_toks, nc) = first_four(tokens(line));
    }
    if !(2..=3).contains(&nc) {
        return Err(at_line(
            path,
            count_line,
            format!("expected the counts line `vertices faces [edges]`, found {nc} values"),
        ));
    }
    let count = |tok: &[u8], what: &str| -> Result<usize> {
        parse_int(tok)
            .filter(|&n| n >= 0)
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| {
                at_line(
                    path,
                    count_line,
                    format!("cannot parse `{}` as the {what} count", quote(tok)),
                )
            })
    };
    let nv = count(count_toks[0], "vertex")?;
    let nf = count(count_toks[1], "face")?;
    if nc == 3 {
        count(count_toks[2], "edge")?;
    }
    // Every vertex and face takes a line of at least 2 bytes, except that the last line may
    // lack its newline. (A valid vertex line takes 6 bytes, "0 0 0\n", and a valid face 8,
    // "3 0 1 2\n": preallocation uses those bounds, so that invalid short lines still get an
    // error naming them.)
    let remaining = lines.remaining();
    let needed = nv.saturating_add(nf).saturating_mul(2).saturating_sub(1);
    if needed > remaining || !fits_u32(nv) {
        return Err(at_line(
            path,
            count_line,
            format!(
                "the counts line announces {nv} vertices and {nf} faces, but only {remaining} \
                 bytes follow"
            ),
        ));
    }

    let mut mesh = Mesh::new();
    let cap_v = nv.min(remaining / 6 + 1);
    mesh.positions.reserve_exact(cap_v);
    mesh.face_offsets.reserve_exact(nf.min(remaining / 8 + 1));
    let mut colors = Vec::with_capacity(if h.color { cap_v } else { 0 });
    let mut uvs = Vec::with_capacity(if h.texture { cap_v } else { 0 });
    let base = if h.normal { 6 } else { 3 };
    let need = base + if h.color { 3 } else { 0 } + if h.texture { 2 } else { 0 };
    let layout = format!(
        "x y z{}{}{}",
        if h.normal { " nx ny nz" } else { "" },
        if h.color { " r g b [a]" } else { "" },
        if h.texture { " s t" } else { "" }
    );
    for i in 1..=nv {
        let (ln, line) = next_content(&mut lines).ok_or_else(|| {
            at_file(
                path,
                format!("the file ends after {} of {nv} vertices", i - 1),
            )
        })?;
        let mut vals: [&[u8]; 12] = [&[]; 12];
        let mut k = 0;
        for t in tokens(line) {
            if k < vals.len() {
                vals[k] = t;
            }
            k += 1;
        }
        let bad_count = || {
            at_line(
                path,
                ln,
                format!("vertex {i}: expected `{layout}`, found {k} values"),
            )
        };
        if k < need || (h.color && h.texture && k > need + 1) {
            return Err(bad_count());
        }
        let num = |tok: &[u8]| -> Result<f64> {
            let x = parse_f64(tok).ok_or_else(|| {
                at_line(
                    path,
                    ln,
                    format!("vertex {i}: cannot parse `{}` as a number", quote(tok)),
                )
            })?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(at_line(
                    path,
                    ln,
                    format!("vertex {i}: value `{}` is not finite", quote(tok)),
                ))
            }
        };
        let p = DVec3::new(num(vals[0])?, num(vals[1])?, num(vals[2])?);
        mesh.positions.push(p);
        let mut next = base;
        if h.color {
            let c = [vals[base], vals[base + 1], vals[base + 2]];
            let rgb = if c.iter().all(|t| parse_int(t).is_some()) {
                c.map(|t| parse_int(t).unwrap_or(0) as f32 / 255.0)
            } else {
                let mut rgb = [0.0f32; 3];
                for (x, t) in rgb.iter_mut().zip(c) {
                    *x = parse_f32(t).filter(|x| x.is_finite()).ok_or_else(|| {
                        at_line(
                            path,
                            ln,
                            format!("vertex {i}: cannot parse colour `{}`", quote(t)),
                        )
                    })?;
                }
                rgb
            };
            colors.push(rgb);
            next += 3;
            if h.texture && k == need + 1 {
                next += 1; // alpha
            }
        }
        if h.texture {
            uvs.push([num(vals[next])?, num(vals[next + 1])?]);
        }
    }

    let mut scratch = Vec::new();
    for f in 1..=nf {
        let (ln, line) = next_content(&mut lines)
            .ok_or_else(|| at_file(path, format!("the file ends after {} of {nf} faces", f - 1)))?;
        let mut toks = tokens(line);
        let first = toks.next().unwrap_or_default();
        let n = parse_int(first).ok_or_else(|| {
            at_line(
                path,
                ln,
                format!(
                    "face {f}: cannot parse `{}` as the number of vertices",
                    quote(first)
                ),
            )
        })?;
        if n < 3 {
            return Err(at_line(
                path,
                ln,
                format!("face {f} has {n} vertices; a face needs at least 3"),
            ));
        }
        let start = mesh.face_indices.len();
        for j in 0..n {
            let tok = toks.next().ok_or_else(|| {
                at_line(
                    path,
                    ln,
                    format!("face {f}: announces {n} vertices but lists {j}"),
                )
            })?;
            let v = parse_int(tok).ok_or_else(|| {
                at_line(
                    path,
                    ln,
                    format!("face {f}: cannot parse `{}` as a vertex index", quote(tok)),
                )
            })?;
            if v < 0 || v as u64 >= nv as u64 {
                let range = if nv == 0 {
                    "the file has no vertices".to_string()
                } else {
                    format!("0..={}", nv - 1)
                };
                return Err(at_line(
                    path,
                    ln,
                    format!("face {f}: vertex index {v} out of range ({range})"),
                ));
            }
            mesh.face_indices.push(v as u32);
        }
        if let Some(v) = repeated_vertex(&mesh.face_indices[start..], &mut scratch) {
            return Err(at_line(
                path,
                ln,
                format!("face {f}: vertex {v} appears more than once"),
            ));
        }
        if !fits_u32(mesh.face_indices.len()) {
            return Err(at_line(
                path,
                ln,
                format!("face {f}: too many face corners"),
            ));
        }
        mesh.face_offsets.push(mesh.face_indices.len() as u32);
    }
    if h.color {
        mesh.colors = Some(colors);
    }
    if h.texture {
        mesh.uvs = Some(uvs);
    }
    Ok(mesh)
}

/// Writes `mesh` as ascii OFF.
///
/// The header is `OFF`, or `COFF` with colours (written as `r g b 1.0` on the 0..1 scale, with a
/// decimal point so readers do not take them for 0..255 integers), prefixed by `ST` with
/// per-vertex [`Mesh::uvs`]. Faces are `n i0 .. i(n-1)` with 0-based indices; the edge count is
/// written as 0. Numbers use the shortest digits that parse back to the same bits. Tags and
/// face-varying uvs are not representable in OFF and are dropped.
///
/// # Errors
/// [`Error::Mesh`](crate::Error::Mesh) if the mesh is invalid ([`Mesh::check_indices`]);
/// [`Error::Io`](crate::Error::Io) if writing
/// fails.
pub fn write(mesh: &Mesh, w: &mut dyn Write) -> Result<()> {
    check_writable(mesh)?;
    let mut w = BufWriter::with_capacity(1 << 16, w);
    write_inner(mesh, &mut w).map_err(write_err)?;
    w.flush().map_err(write_err)
}

fn write_inner(mesh: &Mesh, w: &mut impl Write) -> std::io::Result<()> {
    let st = if mesh.uvs.is_some() { "ST" } else { "" };
    let c = if mesh.colors.is_some() { "C" } else { "" };
    writeln!(w, "{st}{c}OFF")?;
    writeln!(w, "{} {} 0", mesh.num_vertices(), mesh.num_faces())?;
    for (v, p) in mesh.positions.iter().enumerate() {
        write!(w, "{} {} {}", Num(p.x), Num(p.y), Num(p.z))?;
        if let Some(colors) = &mesh.colors {
            let [r, g, b] = colors[v];
            write!(w, " {r:?} {g:?} {b:?} 1.0")?;
        }
        if let Some(uvs) = &mesh.uvs {
            let [s, t] = uvs[v];
            write!(w, " {} {}", Num(s), Num(t))?;
        }
        w.write_all(b"\n")?;
    }
    for fv in mesh.faces() {
        write!(w, "{}", fv.len())?;
        for v in fv {
            write!(w, " {v}")?;
        }
        w.write_all(b"\n")?;
    }
    Ok(())
}
