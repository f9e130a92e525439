//! Wavefront OBJ, with OpenSubdiv's crease and corner tag lines.
//!
//! The reader is hand-written rather than built on `tobj`, which drops vertices no face uses,
//! renumbers the rest, reports no line numbers and ignores `t` tag lines: here every `v` line
//! becomes a vertex in file order, whether or not a face uses it, so vertex `i` of the mesh is
//! the file's vertex `i + 1`.
//!
//! Statements read:
//! - `v x y z`, `v x y z w` (`w` ignored) or `v x y z r g b` (colours kept only if every `v`
//!   line has them);
//! - `vt u [v [w]]` (`w` ignored);
//! - `f` with corners `v`, `v/vt`, `v//vn` or `v/vt/vn`, positive (1-based) or negative
//!   (relative) indices, any number of corners (at least 3, all distinct). Texture indices
//!   become [`Mesh::face_uvs`] only if every corner of every face has one; otherwise texture
//!   coordinates are dropped. Positive indices may refer forward (to `v` lines further down);
//!   they are checked against the final count, and an error still names the face's line;
//! - `t crease n/m a b .. s ..` (pairs of 0-based vertex indices; one sharpness for all pairs or
//!   one per pair) and `t corner n/m v .. s ..` (one sharpness, or one per vertex). Sharpness
//!   must be finite (values `<= 0` mean smooth and are kept as written). Other `t` tags are
//!   ignored.
//!
//! Every other statement (`vn`, `vp`, `o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`, ...), blank
//! line and `#` comment is ignored. A line ending in `\` continues on the next line.

use std::io::{BufWriter, Write};

use glam::DVec3;

use super::{
    at_line, check_writable, fits_u32, parse_f32, parse_f64, parse_int, quote, repeated_vertex,
    strip_bom, strip_comment, tokens, write_err, Lines, Num, Num32,
};
use crate::{EdgeTag, Error, FaceVarying, Mesh, Result, VertexTag};

/// Reads an OBJ file from `bytes`; `path` is only used in error messages.
///
/// Vertex count = number of `v` lines; face count = number of `f` lines. See the
/// [module docs](self) for the statements read.
///
/// # Errors
/// [`Error::Parse`] at `Location::Line(n)` (1-based; the first line of a continued statement)
/// naming the element: a number that does not parse (`vertex 7: cannot parse `1.2.3` as a
/// number`), a NaN or infinite coordinate, a `v` line with a wrong number of values, a face
/// index that is 0, malformed or out of range (`face 3: vertex index 9999 out of range
/// (1..=5000)`), a face with fewer than 3 or repeated vertices, a malformed or out-of-range
/// `crease`/`corner` tag, or more than `u32::MAX` vertices or face corners.
pub fn read(bytes: &[u8], path: &str) -> Result<Mesh> {
    let mut p = Parser::new(path);
    let mut lines = Lines::new(strip_bom(bytes));
    let mut joined = Vec::new();
    while let Some((no, raw)) = lines.next() {
        let line = strip_comment(raw);
        if line.last() != Some(&b'\\') {
            if !line.is_empty() {
                p.statement(line, no)?;
            }
            continue;
        }
        // A continued statement: join its lines into one buffer (rare; reused).
        joined.clear();
        let mut cur = line;
        loop {
            match cur.strip_suffix(b"\\") {
                Some(body) => {
                    joined.extend_from_slice(body);
                    joined.push(b' ');
                    match lines.next() {
                        Some((_, raw)) => cur = strip_comment(raw),
                        None => break,
                    }
                }
                None => {
                    joined.extend_from_slice(cur);
                    break;
                }
            }
        }
        p.statement(&joined, no)?;
    }
    p.finish()
}

/// A positive index beyond the elements defined so far, checked when the file is complete.
struct Forward {
    line: usize,
    face: usize,
    index: i64,
}

/// A crease or corner tag's vertex, checked when the file is complete.
struct TagRef {
    line: usize,
    kind: &'static str,
    vertex: u32,
}

struct Parser<'p> {
    path: &'p str,
    positions: Vec<DVec3>,
    colors: Vec<[f32; 3]>,
    colors_ok: bool,
    texcoords: Vec<[f64; 2]>,
    face_offsets: Vec<u32>,
    face_indices: Vec<u32>,
    uv_indices: Vec<u32>,
    uvs_ok: bool,
    /// Forward references whose index exceeds every earlier one (the first bad reference in
    /// file order is always such a record), for vertices and texture coordinates.
    forward: [Vec<Forward>; 2],
    max_forward: [i64; 2],
    edge_tags: Vec<EdgeTag>,
    vertex_tags: Vec<VertexTag>,
    tag_refs: Vec<TagRef>,
    scratch: Vec<u32>,
    tag_ints: Vec<u32>,
    tag_floats: Vec<f64>,
}

const VERTEX: usize = 0;
const TEXTURE: usize = 1;
const WHAT: [&str; 2] = ["vertex index", "texture coordinate index"];

impl<'p> Parser<'p> {
    fn new(path: &'p str) -> Self {
        Parser {
            path,
            positions: Vec::new(),
            colors: Vec::new(),
            colors_ok: true,
            texcoords: Vec::new(),
            face_offsets: vec![0],
            face_indices: Vec::new(),
            uv_indices: Vec::new(),
            uvs_ok: true,
            forward: [Vec::new(), Vec::new()],
            max_forward: [0, 0],
            edge_tags: Vec::new(),
            vertex_tags: Vec::new(),
            tag_refs: Vec::new(),
            scratch: Vec::new(),
            tag_ints: Vec::new(),
            tag_floats: Vec::new(),
        }
    }

    fn err(&self, line: usize, message: String) -> Error {
        at_line(self.path, line, message)
    }

    fn statement(&mut self, line: &[u8], no: usize) -> Result<()> {
        let mut toks = tokens(line);
        match toks.next() {
            Some(b"v") => self.vertex(toks, no),
            Some(b"vt") => self.texcoord(toks, no),
            Some(b"f") => self.face(toks, no),
            Some(b"t") => self.tag(toks, no),
            _ => Ok(()),
        }
    }

    fn number(&self, tok: &[u8], line: usize, what: &str, n: usize) -> Result<f64> {
        parse_f64(tok).ok_or_else(|| {
            self.err(
                line,
                format!("{what} {n}: cannot parse `{}` as a number", quote(tok)),
            )
        })
    }

    fn vertex<'a>(&mut self, toks: impl Iterator<Item = &'a [u8]>, line: usize) -> Result<()> {
        let n = self.positions.len() + 1;
        let mut vals: [&[u8]; 7] = [&[]; 7];
        let mut k = 0;
        for t in toks {
            if k == vals.len() {
                k += 1;
                break;
            }
            vals[k] = t;
            k += 1;
        }
        if !matches!(k, 3 | 4 | 6) {
            let found = if k > 7 {
                "more than 7".to_string()
            } else {
                k.to_string()
            };
            return Err(self.err(
                line,
                format!(
                    "vertex {n}: expected `v x y z`, `v x y z w` or `v x y z r g b`, \
                     found {found} values"
                ),
            ));
        }
        let mut xyz = [0.0; 3];
        for (x, tok) in xyz.iter_mut().zip(vals) {
            *x = self.number(tok, line, "vertex", n)?;
            if !x.is_finite() {
                return Err(self.err(
                    line,
                    format!("vertex {n}: coordinate `{}` is not finite", quote(tok)),
                ));
            }
        }
        if k == 4 {
            self.number(vals[3], line, "vertex", n)?;
        }
        if k == 6 {
            let mut rgb = [0.0f32; 3];
            for (c, &tok) in rgb.iter_mut().zip(&vals[3..6]) {
                *c = parse_f32(tok).ok_or_else(|| {
                    self.err(
                        line,
                        format!(
                            "vertex {n}: cannot parse colour `{}` as a number",
                            quote(tok)
                        ),
                    )
                })?;
                if !c.is_finite() {
                    return Err(self.err(
                        line,
                        format!("vertex {n}: colour `{}` is not finite", quote(tok)),
                    ));
                }
            }
            if self.colors_ok {
                self.colors.push(rgb);
            }
        } else if self.colors_ok {
            self.colors_ok = false;
            self.colors = Vec::new();
        }
        if !fits_u32(n) {
            return Err(self.err(line, format!("vertex {n}: too many vertices")));
        }
        self.positions.push(DVec3::from_array(xyz));
        Ok(())
    }

    fn texcoord<'a>(&mut self, toks: impl Iterator<Item = &'a [u8]>, line: usize) -> Result<()> {
        let n = self.texcoords.len() + 1;
        let mut uv = [0.0; 2];
        let mut k = 0;
        for tok in toks {
            if k == 3 {
                return Err(self.err(
                    line,
                    format!(
                        "texture coordinate {n}: expected `vt u [v [w]]`, found more than 3 values"
                    ),
                ));
            }
            let x = self.number(tok, line, "texture coordinate", n)?;
            if !x.is_finite() {
                return Err(self.err(
                    line,
                    format!("texture coordinate {n}: `{}` is not finite", quote(tok)),
                ));
            }
            if k < 2 {
                uv[k] = x;
            }
            k += 1;
        }
        if k == 0 {
            return Err(self.err(
                line,
                format!("texture coordinate {n}: expected `vt u [v [w]]`, found no values"),
            ));
        }
        if !fits_u32(n) {
            return Err(self.err(line, format!("texture coordinate {n}: too many")));
        }
        self.texcoords.push(uv);
        Ok(())
    }

    /// Resolves a face corner's index (`kind` [`VERTEX`] or [`TEXTURE`]) to 0-based.
    fn index(&mut self, tok: &[u8], kind: usize, line: usize, face: usize) -> Result<u32> {
        let what = WHAT[kind];
        let defined = if kind == VERTEX {
            self.positions.len()
        } else {
            self.texcoords.len()
        } as i64;
        let i = parse_int(tok).ok_or_else(|| {
            self.err(
                line,
                format!("face {face}: cannot parse `{}` as a {what}", quote(tok)),
            )
        })?;
        if i == 0 {
            return Err(self.err(
                line,
                format!("face {face}: {what} 0 is invalid (OBJ indices start at 1)"),
            ));
        }
        if i < 0 {
            if i < -defined {
                return Err(self.err(
                    line,
                    format!(
                        "face {face}: relative {what} {i} out of range (only {defined} defined \
                         before this line)"
                    ),
                ));
            }
            return Ok((defined + i) as u32);
        }
        if i > u32::MAX as i64 {
            return Err(self.err(
                line,
                format!("face {face}: {what} {i} out of range (beyond any possible count)"),
            ));
        }
        if i > defined && i > self.max_forward[kind] {
            self.max_forward[kind] = i;
            self.forward[kind].push(Forward {
                line,
                face,
                index: i,
            });
        }
        Ok((i - 1) as u32)
    }

    fn face<'a>(&mut self, toks: impl Iterator<Item = &'a [u8]>, line: usize) -> Result<()> {
        let f = self.face_offsets.len();
        let start = self.face_indices.len();
        for tok in toks {
            let mut parts = tok.split(|&b| b == b'/');
            let v = parts.next().unwrap_or_default();
            let vt = parts.next();
            let vn = parts.next();
            if parts.next().is_some() {
                return Err(self.err(
                    line,
                    format!(
                        "face {f}: malformed corner `{}`; expected v, v/vt, v//vn or v/vt/vn",
                        quote(tok)
                    ),
                ));
            }
            let vi = self.index(v, VERTEX, line, f)?;
            self.face_indices.push(vi);
            match vt {
                Some(t) if !t.is_empty() => {
                    let ti = self.index(t, TEXTURE, line, f)?;
                    if self.uvs_ok {
                        self.uv_indices.push(ti);
                    }
                }
                _ => {
                    if self.uvs_ok {
                        self.uvs_ok = false;
                        self.uv_indices = Vec::new();
                    }
                }
            }
            if let Some(n) = vn {
                if !n.is_empty() && parse_int(n).is_none() {
                    return Err(self.err(
                        line,
                        format!("face {f}: cannot parse `{}` as a normal index", quote(n)),
                    ));
                }
            }
        }
        let arity = self.face_indices.len() - start;
        if arity < 3 {
            return Err(self.err(
                line,
                format!("face {f} has {arity} vertices; a face needs at least 3"),
            ));
        }
        if let Some(v) = repeated_vertex(&self.face_indices[start..], &mut self.scratch) {
            return Err(self.err(
                line,
                format!(
                    "face {f}: vertex {} (1-based) appears more than once",
                    u64::from(v) + 1
                ),
            ));
        }
        if !fits_u32(self.face_indices.len()) {
            return Err(self.err(line, format!("face {f}: too many face corners in the file")));
        }
        self.face_offsets.push(self.face_indices.len() as u32);
        Ok(())
    }

    fn tag<'a>(&mut self, mut toks: impl Iterator<Item = &'a [u8]>, line: usize) -> Result<()> {
        let kind = match toks.next() {
            Some(b"crease") => "crease",
            Some(b"corner") => "corner",
            Some(_) => return Ok(()),
            None => {
                return Err(self.err(line, "malformed tag line: missing the tag name".into()));
            }
        };
        let bad = |p: &Self, msg: String| {
            p.err(
                line,
                format!(
                    "{kind} tag: {msg} (expected `t crease 2/1 a b sharpness` or \
                     `t corner 1/1 v sharpness`, 0-based vertex indices)"
                ),
            )
        };
        let counts = toks
            .next()
            .ok_or_else(|| bad(self, "missing the argument counts".into()))?;
        let mut ncount = [0usize; 3];
        let mut parts = 0;
        for part in counts.split(|&b| b == b'/') {
            let n = parse_int(part).filter(|&n| n >= 0).ok_or_else(|| {
                bad(
                    self,
                    format!("malformed argument counts `{}`", quote(counts)),
                )
            })?;
            if parts == 3 {
                return Err(bad(
                    self,
                    format!("malformed argument counts `{}`", quote(counts)),
                ));
            }
            ncount[parts] = n as usize;
            parts += 1;
        }
        if parts < 2 {
            return Err(bad(
                self,
                format!("malformed argument counts `{}`", quote(counts)),
            ));
        }
        let [ni, nf, ns] = ncount;
        self.tag_ints.clear();
        self.tag_floats.clear();
        let mut found = 0usize;
        for tok in toks {
            if found < ni {
                let v = parse_int(tok)
                    .filter(|&v| (0..=u32::MAX as i64).contains(&v))
                    .ok_or_else(|| {
                        bad(
                            self,
                            format!("cannot parse `{}` as a vertex index", quote(tok)),
                        )
                    })?;
                self.tag_ints.push(v as u32);
            } else if found - ni < nf {
                let s = parse_f64(tok).ok_or_else(|| {
                    bad(
                        self,
                        format!("cannot parse `{}` as a sharpness", quote(tok)),
                    )
                })?;
                if !s.is_finite() {
                    return Err(bad(
                        self,
                        format!("sharpness `{}` is not finite", quote(tok)),
                    ));
                }
                self.tag_floats.push(s);
            }
            found += 1;
        }
        let expected = ni.saturating_add(nf).saturating_add(ns);
        if found != expected {
            return Err(bad(
                self,
                format!(
                    "`{}` announces {expected} values, found {found}",
                    quote(counts)
                ),
            ));
        }
        let (group, ok) = if kind == "crease" {
            (2, ni >= 2 && ni % 2 == 0 && (nf == 1 || nf == ni / 2))
        } else {
            (1, ni >= 1 && (nf == 1 || nf == ni))
        };
        if !ok {
            let want = if group == 2 {
                "an even number (>= 2) of vertex indices and 1 sharpness or one per pair"
            } else {
                "at least 1 vertex index and 1 sharpness or one per vertex"
            };
            return Err(bad(self, format!("needs {want}, found {ni}/{nf}")));
        }
        for (k, vs) in self.tag_ints.chunks_exact(group).enumerate() {
            let sharpness = self.tag_floats[if nf == 1 { 0 } else { k }];
            if group == 2 {
                self.edge_tags.push(EdgeTag {
                    vertices: [vs[0], vs[1]],
                    sharpness,
                });
            } else {
                self.vertex_tags.push(VertexTag {
                    vertex: vs[0],
                    sharpness,
                });
            }
            if let Some(&vertex) = vs.iter().max() {
                if vertex as usize >= self.positions.len() {
                    self.tag_refs.push(TagRef { line, kind, vertex });
                }
            }
        }
        Ok(())
    }

    fn finish(self) -> Result<Mesh> {
        let totals = [self.positions.len() as i64, self.texcoords.len() as i64];
        let mut first: Option<(usize, String)> = None;
        let mut consider = |line: usize, message: String| {
            let earlier = match &first {
                Some((l, _)) => line < *l,
                None => true,
            };
            if earlier {
                first = Some((line, message));
            }
        };
        for kind in [VERTEX, TEXTURE] {
            let total = totals[kind];
            if let Some(r) = self.forward[kind].iter().find(|r| r.index > total) {
                let range = if total == 0 {
                    "the file defines none".to_string()
                } else {
                    format!("1..={total}")
                };
                consider(
                    r.line,
                    format!(
                        "face {}: {} {} out of range ({range})",
                        r.face, WHAT[kind], r.index
                    ),
                );
            }
        }
        let nv = self.positions.len();
        if let Some(t) = self.tag_refs.iter().find(|t| t.vertex as usize >= nv) {
            let range = if nv == 0 {
                "the file defines no vertices".to_string()
            } else {
                format!("0..={}; tag indices are 0-based", nv - 1)
            };
            consider(
                t.line,
                format!(
                    "{} tag: vertex index {} out of range ({range})",
                    t.kind, t.vertex
                ),
            );
        }
        if let Some((line, message)) = first {
            return Err(at_line(self.path, line, message));
        }
        let colors = (self.colors_ok && nv > 0).then_some(self.colors);
        let face_uvs = (self.uvs_ok && !self.face_indices.is_empty()).then_some(FaceVarying {
            coords: self.texcoords,
            indices: self.uv_indices,
        });
        Ok(Mesh {
            positions: self.positions,
            face_offsets: self.face_offsets,
            face_indices: self.face_indices,
            edge_tags: self.edge_tags,
            vertex_tags: self.vertex_tags,
            colors,
            uvs: None,
            face_uvs,
        })
    }
}

/// Writes `mesh` as OBJ text.
///
/// Writes a comment header, one `v x y z` line per vertex (`v x y z r g b` with colours), `vt`
/// lines, one `f` line per face with 1-based indices (`f a/ta b/tb ..` with texture
/// coordinates), then `t crease 2/1 a b s` and `t corner 1/1 v s` lines (0-based, as
/// OpenSubdiv writes them). Numbers use the shortest digits that parse back to the same bits,
/// so [`read`] gives back the same positions, faces, tags, colours and face-varying uvs.
/// Per-vertex [`Mesh::uvs`] are written as one `vt` per vertex (read back as
/// [`Mesh::face_uvs`]); if both are present only `face_uvs` is written.
///
/// # Errors
/// [`Error::Mesh`] if the mesh is invalid ([`Mesh::check_indices`]); [`Error::Io`] if writing
/// fails.
pub fn write(mesh: &Mesh, w: &mut dyn Write) -> Result<()> {
    check_writable(mesh)?;
    let mut w = BufWriter::with_capacity(1 << 16, w);
    write_inner(mesh, &mut w).map_err(write_err)?;
    w.flush().map_err(write_err)
}

fn write_inner(mesh: &Mesh, w: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        w,
        "# subwave OBJ: {} vertices, {} faces",
        mesh.num_vertices(),
        mesh.num_faces()
    )?;
    for (v, p) in mesh.positions.iter().enumerate() {
        write!(w, "v {} {} {}", Num(p.x), Num(p.y), Num(p.z))?;
        if let Some(c) = &mesh.colors {
            let [r, g, b] = c[v];
            write!(w, " {} {} {}", Num32(r), Num32(g), Num32(b))?;
        }
        w.write_all(b"\n")?;
    }
    let (coords, uv_index): (&[[f64; 2]], Option<&[u32]>) = match (&mesh.face_uvs, &mesh.uvs) {
        (Some(fv), _) => (&fv.coords, Some(&fv.indices)),
        (None, Some(uvs)) => (uvs, None),
        (None, None) => (&[], None),
    };
    for [u, v] in coords {
        writeln!(w, "vt {} {}", Num(*u), Num(*v))?;
    }
    let with_uvs = mesh.face_uvs.is_some() || mesh.uvs.is_some();
    for f in 0..mesh.num_faces() {
        let (a, b) = (
            mesh.face_offsets[f] as usize,
            mesh.face_offsets[f + 1] as usize,
        );
        w.write_all(b"f")?;
        for c in a..b {
            let v = u64::from(mesh.face_indices[c]) + 1;
            if with_uvs {
                let t = uv_index.map_or(v, |ix| u64::from(ix[c]) + 1);
                write!(w, " {v}/{t}")?;
            } else {
                write!(w, " {v}")?;
            }
        }
        w.write_all(b"\n")?;
    }
    for t in &mesh.edge_tags {
        let [a, b] = t.vertices;
        writeln!(w, "t crease 2/1 {a} {b} {}", Num(t.sharpness))?;
    }
    for t in &mesh.vertex_tags {
        writeln!(w, "t corner 1/1 {} {}", t.vertex, Num(t.sharpness))?;
    }
    Ok(())
}
