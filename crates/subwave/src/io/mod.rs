//! Mesh file formats: OBJ, OFF, PLY and STL readers; OBJ, OFF, PLY, STL and GLB writers.
//!
//! | format | read | write | keeps |
//! |---|---|---|---|
//! | [`obj`] | yes | yes | positions, faces, per-vertex colours, face-varying `vt`, crease/corner tags |
//! | [`off`] | yes | yes | positions, faces, per-vertex colours (`COFF`), per-vertex uvs (`STOFF`) |
//! | [`ply`] | yes (ascii, binary LE/BE) | yes (binary LE) | positions, faces, per-vertex colours and uvs |
//! | [`stl`] | yes (ascii, binary) | yes (binary) | triangles, welded into an indexed mesh |
//! | [`glb`] | no | yes | triangulated positions, normals, colours |
//!
//! # Contract shared by every reader
//! - Readers never panic and never allocate from a count read in the file without first checking
//!   it against the number of bytes left: any input, however hostile, gives `Ok` or `Err`, and
//!   memory stays proportional to the input size.
//! - An `Ok` mesh satisfies every invariant of [`Mesh::check_indices`]: faces have at least three
//!   distinct vertices, indices are in range, positions are finite, attribute arrays have the
//!   right length. Readers check these while parsing (in `O(corners · log arity)`), so a file
//!   that violates one is an error naming the element, never a mesh that fails later.
//! - Errors are [`Error::Parse`] with a [`Location`]: `Location::Line` (1-based) for text
//!   formats, `Location::Byte` (0-based offset) for binary data, `Location::File` when the file
//!   ends too early. The message names the element. Element numbers in messages are 1-based
//!   ordinals in file order (`face 1` is the first face of the file, `vertex 7` the seventh
//!   vertex); vertex *indices* are quoted as the file writes them (1-based in OBJ, 0-based in
//!   OFF and PLY), with the valid range.
//!
//! # Contract shared by every writer
//! Writers first check the mesh structurally (the invariants of [`Mesh::check_indices`], in
//! `O(corners · log arity)`) and return [`Error::Mesh`] for an invalid mesh instead of writing a
//! file no reader accepts. I/O failures are [`Error::Io`]. Floating-point values are written with
//! the shortest representation that parses back to the same bits, so text formats round-trip
//! positions exactly.

use std::fmt;
use std::io::{Read, Write};
use std::path::Path;

use rayon::prelude::*;

use crate::{Error, Location, Mesh, MeshError, Result};

pub mod glb;
pub mod obj;
pub mod off;
pub mod ply;
pub mod stl;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// Wavefront OBJ (text), with OpenSubdiv's `t crease` / `t corner` tag lines.
    Obj,
    /// Object File Format (text; `OFF`, `COFF`, `NOFF`, `STOFF` and combinations).
    Off,
    /// Stanford polygon format (ascii, binary little- or big-endian).
    Ply,
    /// Stereolithography (ascii or binary); triangles only, vertices welded on reading.
    Stl,
    /// Binary glTF 2.0 (write only).
    Glb,
}

impl Format {
    /// Every format, in the order of the enum.
    const ALL: [Format; 5] = [
        Format::Obj,
        Format::Off,
        Format::Ply,
        Format::Stl,
        Format::Glb,
    ];

    /// The format named by `path`'s extension, compared case-insensitively (`mesh.OBJ` is
    /// [`Format::Obj`]); `None` for a missing or unknown extension (and for `-`).
    pub fn from_path(path: &Path) -> Option<Format> {
        Format::from_name(path.extension()?.to_str()?)
    }

    /// The format with this name, case-insensitively: `"obj"`, `"off"`, `"ply"`, `"stl"` or
    /// `"glb"`; `None` otherwise.
    pub fn from_name(name: &str) -> Option<Format> {
        Format::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(name))
    }

    /// The format's name, which is also its usual file extension (lower case).
    pub fn name(self) -> &'static str {
        match self {
            Format::Obj => "obj",
            Format::Off => "off",
            Format::Ply => "ply",
            Format::Stl => "stl",
            Format::Glb => "glb",
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

const STDIO: &str = "-";

fn unknown_format(path: &str) -> Error {
    Error::Format {
        path: path.to_string(),
        message: "cannot tell the mesh format from the file name; use the extension .obj, .off, \
                  .ply, .stl or .glb, or name the format explicitly"
            .to_string(),
    }
}

/// Reads a mesh from the file at `path` (`-` reads standard input).
///
/// `format` overrides the format; `None` picks it from the extension ([`Format::from_path`]).
/// The whole file is read into memory and parsed by [`read_mesh_bytes`].
///
/// # Errors
/// - [`Error::Format`] if `format` is `None` and the extension is unknown, if `path` is `-`
///   and `format` is `None`, or if the format cannot be read (GLB);
/// - [`Error::Io`] if the file cannot be read;
/// - [`Error::Parse`] if the contents are malformed (see the [module docs](self)).
pub fn read_mesh(path: &Path, format: Option<Format>) -> Result<Mesh> {
    let name = path.to_string_lossy();
    if path.as_os_str() == STDIO {
        let format = format.ok_or_else(|| Error::Format {
            path: STDIO.to_string(),
            message: "reading a mesh from standard input needs an explicit format".to_string(),
        })?;
        let mut bytes = Vec::new();
        std::io::stdin()
            .lock()
            .read_to_end(&mut bytes)
            .map_err(|source| Error::Io {
                path: STDIO.to_string(),
                source,
            })?;
        return read_mesh_bytes(&bytes, format, STDIO);
    }
    let format = format
        .or_else(|| Format::from_path(path))
        .ok_or_else(|| unknown_format(&name))?;
    if format == Format::Glb {
        return read_mesh_bytes(&[], format, &name);
    }
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: name.to_string(),
        source,
    })?;
    read_mesh_bytes(&bytes, format, &name)
}

/// Parses a mesh in `format` from `bytes`; `path` is only used in error messages.
///
/// # Errors
/// [`Error::Parse`] naming the line (text) or byte offset (binary) and the element, or
/// [`Error::Format`] for [`Format::Glb`], which is write-only.
pub fn read_mesh_bytes(bytes: &[u8], format: Format, path: &str) -> Result<Mesh> {
    match format {
        Format::Obj => obj::read(bytes, path),
        Format::Off => off::read(bytes, path),
        Format::Ply => ply::read(bytes, path),
        Format::Stl => stl::read(bytes, path),
        Format::Glb => Err(Error::Format {
            path: path.to_string(),
            message: "reading GLB is not supported (GLB is an output format here); convert it \
                      to OBJ, OFF, PLY or STL first"
                .to_string(),
        }),
    }
}

/// Writes `mesh` to the file at `path` (`-` writes standard output), creating or truncating it.
///
/// `format` overrides the format; `None` picks it from the extension. See [`write_mesh_to`]
/// for what each format keeps.
///
/// # Errors
/// [`Error::Format`] if the format is unknown (or `path` is `-` and `format` is `None`),
/// [`Error::Mesh`] if the mesh is structurally invalid, [`Error::Io`] naming `path` if the file
/// cannot be created or written.
pub fn write_mesh(mesh: &Mesh, path: &Path, format: Option<Format>) -> Result<()> {
    let name = path.to_string_lossy();
    let with_path = |e: Error| match e {
        Error::Io { source, .. } => Error::Io {
            path: name.to_string(),
            source,
        },
        other => other,
    };
    if path.as_os_str() == STDIO {
        let format = format.ok_or_else(|| Error::Format {
            path: STDIO.to_string(),
            message: "writing a mesh to standard output needs an explicit format".to_string(),
        })?;
        let stdout = std::io::stdout();
        let mut lock = stdout.lock();
        return write_mesh_to(mesh, format, &mut lock).map_err(with_path);
    }
    let format = format
        .or_else(|| Format::from_path(path))
        .ok_or_else(|| unknown_format(&name))?;
    // Check before creating the file, so that an invalid mesh leaves no empty file behind.
    check_writable(mesh)?;
    let mut file = std::fs::File::create(path).map_err(|source| Error::Io {
        path: name.to_string(),
        source,
    })?;
    write_mesh_to(mesh, format, &mut file).map_err(with_path)
}

/// Writes `mesh` in `format` to `w` (buffered internally; `w` is flushed at the end).
///
/// What each format keeps: OBJ everything (positions, faces, colours, uvs, tags); OFF and PLY
/// positions, faces, colours and per-vertex uvs (tags are dropped, PLY colours are quantized to
/// 8 bits); STL and GLB a fan triangulation (see [`stl::write`] and [`glb::write`]).
///
/// # Errors
/// [`Error::Mesh`] if the mesh is structurally invalid (see [`Mesh::check_indices`]),
/// [`Error::InvalidArgument`] if a value cannot be represented in the format (e.g. a GLB
/// coordinate beyond the `f32` range), [`Error::Io`] (with path `-`) if writing fails.
pub fn write_mesh_to(mesh: &Mesh, format: Format, w: &mut dyn Write) -> Result<()> {
    match format {
        Format::Obj => obj::write(mesh, w),
        Format::Off => off::write(mesh, w),
        Format::Ply => ply::write(mesh, w),
        Format::Stl => stl::write(mesh, w),
        Format::Glb => glb::write(mesh, w),
    }
}

// ---------------------------------------------------------------------------------------------
// Shared helpers (crate-private).

/// Converts an I/O error of a writer (whose path the caller does not know) to [`Error::Io`].
pub(crate) fn write_err(source: std::io::Error) -> Error {
    Error::Io {
        path: STDIO.to_string(),
        source,
    }
}

/// A token quoted for an error message: lossy UTF-8, control characters escaped, at most 40
/// characters.
pub(crate) fn quote(tok: &[u8]) -> String {
    const MAX: usize = 40;
    let s = String::from_utf8_lossy(&tok[..tok.len().min(4 * MAX)]);
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i == MAX {
            out.push_str("...");
            return out;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    if tok.len() > 4 * MAX {
        out.push_str("...");
    }
    out
}

/// `bytes` without a leading UTF-8 byte-order mark (some Windows tools write one).
#[inline]
pub(crate) fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes)
}

/// Parses a token as `f64` (Rust syntax: `1`, `-1.5e3`, `.5`, `inf`, `nan`).
#[inline]
pub(crate) fn parse_f64(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse::<f64>().ok()
}

/// Parses a token as `f32` directly (no double rounding through `f64`).
#[inline]
pub(crate) fn parse_f32(tok: &[u8]) -> Option<f32> {
    std::str::from_utf8(tok).ok()?.parse::<f32>().ok()
}

/// Parses a decimal integer with an optional sign; `None` on bad syntax or beyond `i64`.
#[inline]
pub(crate) fn parse_int(tok: &[u8]) -> Option<i64> {
    let (neg, digits) = match tok.first()? {
        b'-' => (true, &tok[1..]),
        b'+' => (false, &tok[1..]),
        _ => (false, tok),
    };
    if digits.is_empty() {
        return None;
    }
    let mut v: i64 = 0;
    for &b in digits {
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        v = v.checked_mul(10)?.checked_add(i64::from(d))?;
    }
    Some(if neg { -v } else { v })
}

/// Splits a line into whitespace-separated tokens, without allocating.
#[inline]
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
}

/// Removes a `#` comment and surrounding whitespace from a line.
#[inline]
pub(crate) fn strip_comment(line: &[u8]) -> &[u8] {
    let line = match line.iter().position(|&b| b == b'#') {
        Some(i) => &line[..i],
        None => line,
    };
    line.trim_ascii()
}

/// Iterates over the lines of `bytes` as `(1-based line number, line without "\n" or "\r\n")`.
pub(crate) struct Lines<'a> {
    rest: &'a [u8],
    line: usize,
    done: bool,
}

impl<'a> Lines<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Lines {
            rest: bytes,
            line: 0,
            done: bytes.is_empty(),
        }
    }

    /// Bytes not yet returned.
    pub(crate) fn remaining(&self) -> usize {
        self.rest.len()
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = (usize, &'a [u8]);

    #[inline]
    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        self.line += 1;
        let line = match self.rest.iter().position(|&b| b == b'\n') {
            Some(i) => {
                let (l, r) = self.rest.split_at(i);
                self.rest = &r[1..];
                l
            }
            None => {
                self.done = true;
                std::mem::take(&mut self.rest)
            }
        };
        Some((self.line, line.strip_suffix(b"\r").unwrap_or(line)))
    }
}

/// A whitespace-separated token stream over text that tracks line numbers (for formats such
/// as ascii PLY and ascii STL whose values may wrap across lines).
pub(crate) struct Tokens<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Tokens<'a> {
    /// A stream over `bytes` whose first byte is on line `first_line`.
    pub(crate) fn new(bytes: &'a [u8], first_line: usize) -> Self {
        Tokens {
            bytes,
            pos: 0,
            line: first_line,
        }
    }

    /// The line of the last token returned (or of the current position).
    pub(crate) fn line(&self) -> usize {
        self.line
    }

    /// Bytes not yet consumed.
    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    /// Skips whitespace, so that [`Tokens::line`] is the line of the next token.
    #[inline]
    pub(crate) fn skip_whitespace(&mut self) {
        while let Some(&b) = self.bytes.get(self.pos) {
            if !b.is_ascii_whitespace() {
                break;
            }
            if b == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
    }

    /// The next token, or `None` at the end.
    #[inline]
    pub(crate) fn next_token(&mut self) -> Option<&'a [u8]> {
        self.skip_whitespace();
        let start = self.pos;
        while let Some(&b) = self.bytes.get(self.pos) {
            if b.is_ascii_whitespace() {
                break;
            }
            self.pos += 1;
        }
        (self.pos > start).then(|| &self.bytes[start..self.pos])
    }

    /// Skips the rest of the current line (including its newline).
    pub(crate) fn skip_line(&mut self) {
        match self.bytes[self.pos..].iter().position(|&b| b == b'\n') {
            Some(i) => {
                self.pos += i + 1;
                self.line += 1;
            }
            None => self.pos = self.bytes.len(),
        }
    }
}

/// The first vertex that occurs twice in `face`, if any. `O(n²)` for small faces, `O(n log n)`
/// (using `scratch`) for large ones, so hostile huge polygons cannot make a reader quadratic.
#[inline]
pub(crate) fn repeated_vertex(face: &[u32], scratch: &mut Vec<u32>) -> Option<u32> {
    // Triangles and quads, the common faces, without the loops' overhead (same answer: the
    // first vertex, in face order, that repeats an earlier one).
    match *face {
        [a, b, c] => {
            return if b == a {
                Some(b)
            } else if c == a || c == b {
                Some(c)
            } else {
                None
            };
        }
        [a, b, c, d] => {
            return if b == a {
                Some(b)
            } else if c == a || c == b {
                Some(c)
            } else if d == a || d == b || d == c {
                Some(d)
            } else {
                None
            };
        }
        _ => {}
    }
    if face.len() <= 16 {
        for i in 1..face.len() {
            if face[..i].contains(&face[i]) {
                return Some(face[i]);
            }
        }
        None
    } else {
        scratch.clear();
        scratch.extend_from_slice(face);
        scratch.sort_unstable();
        scratch.windows(2).find(|w| w[0] == w[1]).map(|w| w[0])
    }
}

/// Checks the invariants of [`Mesh::check_indices`] (same errors, first offence) without its
/// quadratic cost on huge polygons; every writer calls it first.
pub(crate) fn check_writable(mesh: &Mesh) -> Result<()> {
    let nv = mesh.positions.len();
    let offs = &mesh.face_offsets;
    // Faces and vertices checked in parallel chunks (a refined mesh has millions of faces),
    // reporting the first offence.
    const CHUNK: usize = 1 << 14;
    let consistent = if offs.is_empty() {
        mesh.face_indices.is_empty()
    } else {
        offs[0] == 0
            && offs[offs.len() - 1] as usize == mesh.face_indices.len()
            && offs.par_chunks(CHUNK).enumerate().all(|(c, w)| {
                w.windows(2).all(|w| w[0] <= w[1]) && (c == 0 || offs[c * CHUNK - 1] <= w[0])
            })
    };
    if !consistent {
        return Err(MeshError::BadOffsets.into());
    }
    if nv > u32::MAX as usize {
        return Err(Error::InvalidArgument(format!(
            "the mesh has {nv} vertices; at most {} can be indexed",
            u32::MAX
        )));
    }
    // The first offence of face `f`, if any (a shortcut for valid triangles).
    let face_error = |f: usize, scratch: &mut Vec<u32>| -> Option<MeshError> {
        let fv = &mesh.face_indices[offs[f] as usize..offs[f + 1] as usize];
        let face = f as u32;
        if let [a, b, c] = *fv {
            if (a.max(b).max(c) as usize) < nv && a != b && b != c && c != a {
                return None;
            }
        }
        if fv.len() < 3 {
            return Some(MeshError::FaceTooSmall {
                face,
                arity: fv.len(),
            });
        }
        if let Some(&index) = fv.iter().find(|&&v| v as usize >= nv) {
            return Some(MeshError::IndexOutOfRange {
                face,
                index,
                vertices: nv,
            });
        }
        repeated_vertex(fv, scratch).map(|vertex| MeshError::RepeatedVertex { face, vertex })
    };
    let nf = offs.len().saturating_sub(1);
    if let Some(e) = (0..nf.div_ceil(CHUNK)).into_par_iter().find_map_first(|c| {
        let mut scratch = Vec::new();
        (c * CHUNK..((c + 1) * CHUNK).min(nf)).find_map(|f| face_error(f, &mut scratch))
    }) {
        return Err(e.into());
    }
    if let Some(v) = mesh
        .positions
        .par_chunks(CHUNK)
        .enumerate()
        .find_map_first(|(c, ps)| Some(c * CHUNK + ps.iter().position(|p| !p.is_finite())?))
    {
        return Err(MeshError::NonFinite { vertex: v as u32 }.into());
    }
    let per_vertex = |name: &'static str, len: usize| {
        if len != nv {
            Err(Error::from(MeshError::AttributeLength {
                name,
                len,
                expected: nv,
            }))
        } else {
            Ok(())
        }
    };
    if let Some(c) = &mesh.colors {
        per_vertex("colors", c.len())?;
    }
    if let Some(t) = &mesh.uvs {
        per_vertex("uvs", t.len())?;
    }
    if let Some(fv) = &mesh.face_uvs {
        if fv.indices.len() != mesh.face_indices.len() {
            return Err(MeshError::AttributeLength {
                name: "face_uvs",
                len: fv.indices.len(),
                expected: mesh.face_indices.len(),
            }
            .into());
        }
        if let Some(&index) = fv.indices.iter().find(|&&i| i as usize >= fv.coords.len()) {
            return Err(MeshError::AttributeIndex {
                name: "face_uvs",
                index,
                len: fv.coords.len(),
            }
            .into());
        }
    }
    let tag_vertices = mesh
        .edge_tags
        .iter()
        .flat_map(|t| t.vertices)
        .chain(mesh.vertex_tags.iter().map(|t| t.vertex));
    for vertex in tag_vertices {
        if vertex as usize >= nv {
            return Err(MeshError::TagOutOfRange {
                vertex,
                vertices: nv,
            }
            .into());
        }
    }
    Ok(())
}

/// Formats an `f64` with the shortest digits that parse back to the same bits, in plain
/// notation for ordinary magnitudes and in exponent notation for very large or small ones
/// (Rust's `{}` never uses an exponent, which would spell `1e300` with 301 digits).
pub(crate) struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0.abs();
        if a == 0.0 || (1e-5..1e16).contains(&a) || !a.is_finite() {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

/// [`Num`] for `f32` values (shortest digits that parse back to the same `f32`).
pub(crate) struct Num32(pub f32);

impl fmt::Display for Num32 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0.abs();
        if a == 0.0 || (1e-5..1e16).contains(&a) || !a.is_finite() {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

/// A parse error at a line.
#[inline]
pub(crate) fn at_line(path: &str, line: usize, message: impl Into<String>) -> Error {
    Error::parse(path, Location::Line(line), message)
}

/// A parse error at a byte offset.
#[inline]
pub(crate) fn at_byte(path: &str, offset: usize, message: impl Into<String>) -> Error {
    Error::parse(path, Location::Byte(offset), message)
}

/// A parse error about the whole file (e.g. it ends too early).
#[inline]
pub(crate) fn at_file(path: &str, message: impl Into<String>) -> Error {
    Error::parse(path, Location::File, message)
}

/// Checks that a count of corners or vertices fits the `u32` indices of [`Mesh`].
#[inline]
pub(crate) fn fits_u32(n: usize) -> bool {
    n <= u32::MAX as usize
}

#[cfg(test)]
mod tests {
    use super::{check_writable, repeated_vertex};
    use crate::{Error, Mesh, MeshError};
    use glam::DVec3;

    /// A strip of `n` triangles over `n + 2` vertices.
    fn strip(n: u32) -> Mesh {
        let positions = (0..n + 2)
            .map(|i| DVec3::new(i as f64, (i % 2) as f64, 0.0))
            .collect();
        let tris: Vec<[u32; 3]> = (0..n).map(|i| [i, i + 1, i + 2]).collect();
        Mesh::from_triangles(positions, &tris)
    }

    fn mesh_error(m: &Mesh) -> Option<MeshError> {
        match check_writable(m) {
            Ok(()) => None,
            Err(Error::Mesh(e)) => Some(e),
            Err(e) => panic!("unexpected error {e}"),
        }
    }

    /// The parallel chunked scan reports the first offence, as the serial checks would, in any
    /// chunk (the chunks hold 16,384 faces or vertices).
    #[test]
    fn check_writable_reports_the_first_offence() {
        let n = 100_000u32;
        assert!(mesh_error(&strip(n)).is_none());
        for bad in [0u32, 16_383, 16_384, 70_001, n - 1] {
            let mut m = strip(n);
            m.face_indices[3 * bad as usize + 1] = m.face_indices[3 * bad as usize];
            // A later face is out of range: the earlier repeated vertex is reported.
            if bad + 5 < n {
                m.face_indices[3 * (bad as usize + 5)] = n + 2;
            }
            match mesh_error(&m) {
                Some(MeshError::RepeatedVertex { face, vertex }) => {
                    assert_eq!((face, vertex), (bad, bad))
                }
                e => panic!("face {bad}: {e:?}"),
            }
            let mut m = strip(n);
            m.face_indices[3 * bad as usize + 2] = n + 2;
            assert!(
                matches!(mesh_error(&m), Some(MeshError::IndexOutOfRange { face, .. }) if face == bad),
                "face {bad}"
            );
            let mut m = strip(n);
            m.positions[bad as usize + 1].y = f64::NAN;
            m.positions[n as usize].z = f64::INFINITY;
            assert!(
                matches!(mesh_error(&m), Some(MeshError::NonFinite { vertex }) if vertex == bad + 1),
                "vertex {}",
                bad + 1
            );
        }
        let mut m = strip(n);
        m.face_offsets[40_000] = m.face_offsets[40_001] + 1;
        assert!(matches!(mesh_error(&m), Some(MeshError::BadOffsets)));
        let mut m = strip(n);
        m.face_offsets[16_384] = m.face_offsets[16_383] - 1;
        assert!(matches!(mesh_error(&m), Some(MeshError::BadOffsets)));
    }

    /// The triangle and quad shortcuts answer as the general scan does: the first vertex, in
    /// face order, that repeats an earlier one (every face over a 4-letter alphabet).
    #[test]
    fn repeated_vertex_shortcuts_match_the_scan() {
        fn scan(face: &[u32]) -> Option<u32> {
            (1..face.len())
                .find(|&i| face[..i].contains(&face[i]))
                .map(|i| face[i])
        }
        let mut scratch = Vec::new();
        for len in [3u32, 4] {
            for code in 0..4u32.pow(len) {
                let face: Vec<u32> = (0..len).map(|k| code / 4u32.pow(k) % 4).collect();
                assert_eq!(
                    repeated_vertex(&face, &mut scratch),
                    scan(&face),
                    "{face:?}"
                );
            }
        }
        let big: Vec<u32> = (0..40).chain([7]).collect();
        assert_eq!(repeated_vertex(&big, &mut scratch), Some(7));
    }
}
