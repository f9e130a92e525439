//! Stanford PLY: ascii, binary little-endian and binary big-endian.
//!
//! The reader is hand-written rather than built on `ply-rs-bw`: that crate builds a generic
//! property map per element (an allocation per vertex), reports neither line numbers nor byte
//! offsets, and trusts counts from the header, whereas this reader has to be panic-free on
//! hostile input, check every count against the bytes left before allocating, and name the
//! element and location of every error. PLY's grammar is small enough (a line-based header,
//! then fixed-layout records) that a direct reader is short and easy to audit.
//!
//! Read: element `vertex` with scalar properties `x y z` (any numeric type), optional
//! `red green blue` (integer types scaled by their maximum: `uchar` / 255, `ushort` / 65535;
//! float types as they are) and optional texture coordinates (`u v`, `s t`, `texture_u
//! texture_v` or `texture_s texture_t`); element `face` with a list property `vertex_indices`
//! (or `vertex_index`) of integers, 0-based. Every other element and property, lists included,
//! is skipped. Elements with no properties carry no data.

use std::io::{BufWriter, Write};

use glam::DVec3;
use rayon::prelude::*;

use super::{
    at_file, at_line, check_writable, fits_u32, parse_f64, parse_int, quote, repeated_vertex,
    tokens, write_err, Lines, Tokens,
};
use crate::{Error, Location, Mesh, Result};

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_int(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The divisor that maps a colour of this type to 0..1.
    fn color_scale(self) -> f32 {
        match self {
            Scalar::I16 | Scalar::U16 => 65535.0,
            Scalar::F32 | Scalar::F64 => 1.0,
            _ => 255.0,
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

struct Property<'a> {
    name: &'a [u8],
    kind: Kind,
    line: usize,
}

struct Element<'a> {
    name: &'a [u8],
    count: u64,
    props: Vec<Property<'a>>,
    line: usize,
}

impl Element<'_> {
    /// The fewest bytes one entry can take.
    fn min_size(&self, ascii: bool) -> usize {
        if ascii {
            // One token of at least one byte per property, plus a separator.
            return self.props.len().saturating_mul(2);
        }
        self.props
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => s.size(),
                Kind::List { count, .. } => count.size(),
            })
            .sum()
    }

    fn find(&self, name: &[u8]) -> Option<(usize, &Property<'_>)> {
        self.props.iter().enumerate().find(|(_, p)| p.name == name)
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

/// A failure while reading data, before the element context is added.
struct Fail {
    loc: Location,
    msg: String,
}

type R<T> = std::result::Result<T, Fail>;

fn eof() -> Fail {
    Fail {
        loc: Location::File,
        msg: "the file ends early".to_string(),
    }
}

/// The data section: a token stream (ascii) or a byte cursor (binary).
enum Data<'a> {
    Ascii(Tokens<'a>),
    Binary {
        bytes: &'a [u8],
        pos: usize,
        /// File offset of `bytes[0]`.
        base: usize,
        big: bool,
    },
}

enum Value {
    I(i64),
    F(f64),
}

macro_rules! read_as {
    ($bytes:expr, $pos:expr, $big:expr, $t:ty) => {{
        const N: usize = std::mem::size_of::<$t>();
        let s = $bytes.get(*$pos..*$pos + N).ok_or_else(eof)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        *$pos += N;
        if $big {
            <$t>::from_be_bytes(a)
        } else {
            <$t>::from_le_bytes(a)
        }
    }};
}

impl<'a> Data<'a> {
    /// Where the next value starts.
    fn loc(&mut self) -> Location {
        match self {
            Data::Ascii(t) => {
                t.skip_whitespace();
                Location::Line(t.line())
            }
            Data::Binary { pos, base, .. } => Location::Byte(*base + *pos),
        }
    }

    fn remaining(&self) -> usize {
        match self {
            Data::Ascii(t) => t.remaining(),
            Data::Binary { bytes, pos, .. } => bytes.len() - pos,
        }
    }

    fn token(t: &mut Tokens<'a>) -> R<&'a [u8]> {
        t.next_token().ok_or_else(eof)
    }

    fn value(&mut self, ty: Scalar) -> R<Value> {
        match self {
            Data::Ascii(t) => {
                let tok = Self::token(t)?;
                if let Some(i) = parse_int(tok) {
                    Ok(Value::I(i))
                } else if let Some(x) = parse_f64(tok) {
                    Ok(Value::F(x))
                } else {
                    Err(Fail {
                        loc: Location::Line(t.line()),
                        msg: format!("cannot parse `{}` as a number", quote(tok)),
                    })
                }
            }
            Data::Binary {
                bytes, pos, big, ..
            } => {
                let big = *big;
                Ok(match ty {
                    Scalar::I8 => Value::I(read_as!(bytes, pos, big, i8).into()),
                    Scalar::U8 => Value::I(read_as!(bytes, pos, big, u8).into()),
                    Scalar::I16 => Value::I(read_as!(bytes, pos, big, i16).into()),
                    Scalar::U16 => Value::I(read_as!(bytes, pos, big, u16).into()),
                    Scalar::I32 => Value::I(read_as!(bytes, pos, big, i32).into()),
                    Scalar::U32 => Value::I(read_as!(bytes, pos, big, u32).into()),
                    Scalar::F32 => Value::F(read_as!(bytes, pos, big, f32).into()),
                    Scalar::F64 => Value::F(read_as!(bytes, pos, big, f64)),
                })
            }
        }
    }

    fn float(&mut self, ty: Scalar) -> R<f64> {
        Ok(match self.value(ty)? {
            Value::I(i) => i as f64,
            Value::F(x) => x,
        })
    }

    /// An integer (list counts and indices). The header check guarantees `ty` is an integer
    /// type, so in binary data this never sees a float; in ascii data it rejects one.
    fn int(&mut self, ty: Scalar) -> R<i64> {
        let loc = self.loc();
        match self.value(ty)? {
            Value::I(i) => Ok(i),
            Value::F(x) => Err(Fail {
                loc,
                msg: format!("expected an integer, found {x}"),
            }),
        }
    }

    /// Checks that `n` values of `item` can still follow (so a hostile count cannot make the
    /// reader loop or allocate beyond the input).
    fn check_list(&mut self, n: i64, item: Scalar) -> R<usize> {
        let per = match self {
            Data::Ascii(_) => 2,
            Data::Binary { .. } => item.size(),
        };
        let remaining = self.remaining();
        match usize::try_from(n) {
            Ok(n) if n.saturating_mul(per) <= remaining + 1 => Ok(n),
            _ => Err(Fail {
                loc: self.loc(),
                msg: format!("list of {n} values, but only {remaining} bytes follow"),
            }),
        }
    }

    fn skip(&mut self, kind: Kind) -> R<()> {
        match kind {
            Kind::Scalar(s) => self.skip_scalars(s, 1),
            Kind::List { count, item } => {
                let loc = self.loc();
                let n = self.int(count)?;
                if n < 0 {
                    return Err(Fail {
                        loc,
                        msg: format!("negative list length {n}"),
                    });
                }
                let n = self.check_list(n, item)?;
                self.skip_scalars(item, n)
            }
        }
    }

    fn skip_scalars(&mut self, ty: Scalar, n: usize) -> R<()> {
        match self {
            Data::Ascii(t) => {
                for _ in 0..n {
                    Self::token(t)?;
                }
                Ok(())
            }
            Data::Binary { bytes, pos, .. } => {
                let end = n
                    .checked_mul(ty.size())
                    .and_then(|k| k.checked_add(*pos))
                    .filter(|&e| e <= bytes.len())
                    .ok_or_else(eof)?;
                *pos = end;
                Ok(())
            }
        }
    }
}

/// Header parse result.
struct Header<'a> {
    encoding: Encoding,
    elements: Vec<Element<'a>>,
    /// Offset of the first data byte, and the line it is on.
    data_start: usize,
    data_line: usize,
}

fn parse_header<'a>(bytes: &'a [u8], path: &str) -> Result<Header<'a>> {
    let mut lines = Lines::new(bytes);
    match lines.next() {
        Some((_, l)) if l.trim_ascii_end() == b"ply" => {}
        _ => {
            return Err(at_line(
                path,
                1,
                "not a PLY file: the first line must be `ply`",
            ))
        }
    }
    let mut encoding = None;
    let mut elements: Vec<Element<'a>> = Vec::new();
    for (no, line) in lines.by_ref() {
        let mut toks = tokens(line);
        let kw = toks.next().unwrap_or_default();
        match kw {
            b"" | b"comment" | b"obj_info" => {}
            b"format" => {
                if encoding.is_some() {
                    return Err(at_line(path, no, "a second `format` line"));
                }
                encoding = Some(match toks.next().unwrap_or_default() {
                    b"ascii" => Encoding::Ascii,
                    b"binary_little_endian" => Encoding::Little,
                    b"binary_big_endian" => Encoding::Big,
                    other => {
                        return Err(at_line(
                            path,
                            no,
                            format!(
                                "unknown format `{}`; expected ascii, binary_little_endian or \
                                 binary_big_endian",
                                quote(other)
                            ),
                        ))
                    }
                });
            }
            b"element" => {
                let (Some(name), Some(count), None) = (toks.next(), toks.next(), toks.next())
                else {
                    return Err(at_line(path, no, "expected `element <name> <count>`"));
                };
                let count = parse_int(count)
                    .and_then(|c| u64::try_from(c).ok())
                    .ok_or_else(|| {
                        at_line(
                            path,
                            no,
                            format!(
                                "element `{}`: cannot parse `{}` as a count",
                                quote(name),
                                quote(count)
                            ),
                        )
                    })?;
                elements.push(Element {
                    name,
                    count,
                    props: Vec::new(),
                    line: no,
                });
            }
            b"property" => {
                let Some(el) = elements.last_mut() else {
                    return Err(at_line(path, no, "a `property` line before any `element`"));
                };
                let ty = |t: Option<&[u8]>| {
                    let t = t.unwrap_or_default();
                    Scalar::from_name(t).ok_or_else(|| {
                        at_line(path, no, format!("unknown property type `{}`", quote(t)))
                    })
                };
                let first = toks.next();
                let kind = if first == Some(b"list") {
                    let count = ty(toks.next())?;
                    let item = ty(toks.next())?;
                    if !count.is_int() {
                        return Err(at_line(path, no, "a list's count type must be an integer"));
                    }
                    Kind::List { count, item }
                } else {
                    Kind::Scalar(ty(first)?)
                };
                let (Some(name), None) = (toks.next(), toks.next()) else {
                    return Err(at_line(
                        path,
                        no,
                        "expected `property <type> <name>` or `property list <count type> \
                         <item type> <name>`",
                    ));
                };
                el.props.push(Property {
                    name,
                    kind,
                    line: no,
                });
            }
            b"end_header" => {
                let encoding = encoding
                    .ok_or_else(|| at_line(path, no, "`end_header` before any `format` line"))?;
                return Ok(Header {
                    encoding,
                    elements,
                    data_start: bytes.len() - lines.remaining(),
                    data_line: no + 1,
                });
            }
            other => {
                return Err(at_line(
                    path,
                    no,
                    format!("unknown header keyword `{}`", quote(other)),
                ))
            }
        }
    }
    Err(at_file(path, "the header has no `end_header` line"))
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Role {
    Skip,
    Coord(usize),
    Color(usize),
    Uv(usize),
    Indices,
}

/// Reads a PLY file from `bytes`; `path` is only used in error messages.
///
/// Vertex and face counts are those of the `vertex` and `face` elements; a file without a
/// `face` element gives a mesh without faces. Colours fill [`Mesh::colors`] and texture
/// coordinates [`Mesh::uvs`] when all their components are present.
///
/// # Errors
/// [`Error::Parse`] naming the element: in the header and in ascii data at the 1-based line,
/// in binary data at the 0-based byte offset of the offending value. Header errors (missing
/// `ply`/`format`/`end_header`, unknown types, no `x y z`, indices of a float type), element
/// counts larger than the remaining bytes could hold (checked before allocating), unparsable
/// ascii values, NaN or infinite coordinates, faces with fewer than 3 vertices, indices out of
/// range (`0..=n-1`) or repeated, and data that ends early (`Location::File`).
pub fn read(bytes: &[u8], path: &str) -> Result<Mesh> {
    let header = parse_header(bytes, path)?;
    let ascii = header.encoding == Encoding::Ascii;
    let elements = &header.elements;

    // Find the vertex and face elements and the role of each of their properties.
    let mut vertex_el = None;
    let mut face_el = None;
    for (i, el) in elements.iter().enumerate() {
        let slot = match el.name {
            b"vertex" => &mut vertex_el,
            b"face" => &mut face_el,
            _ => continue,
        };
        if slot.is_some() {
            return Err(at_line(
                path,
                el.line,
                format!("a second `{}` element", quote(el.name)),
            ));
        }
        *slot = Some(i);
    }
    let mut vroles = Vec::new();
    let mut has_color = false;
    let mut has_uv = false;
    let nv = match vertex_el {
        Some(i) => {
            let el = &elements[i];
            vroles = vec![Role::Skip; el.props.len()];
            let scalar = |name: &[u8]| {
                el.find(name)
                    .filter(|(_, p)| matches!(p.kind, Kind::Scalar(_)))
                    .map(|(k, _)| k)
            };
            for (c, name) in [b"x", b"y", b"z"].into_iter().enumerate() {
                let k = scalar(name).ok_or_else(|| {
                    at_line(
                        path,
                        el.line,
                        format!("element `vertex` has no scalar property `{}`", quote(name)),
                    )
                })?;
                vroles[k] = Role::Coord(c);
            }
            if let (Some(r), Some(g), Some(b)) = (scalar(b"red"), scalar(b"green"), scalar(b"blue"))
            {
                has_color = true;
                for (c, k) in [r, g, b].into_iter().enumerate() {
                    vroles[k] = Role::Color(c);
                }
            }
            let uv_names: [(&[u8], &[u8]); 4] = [
                (b"u", b"v"),
                (b"s", b"t"),
                (b"texture_u", b"texture_v"),
                (b"texture_s", b"texture_t"),
            ];
            for (un, vn) in uv_names {
                if let (Some(u), Some(v)) = (scalar(un), scalar(vn)) {
                    has_uv = true;
                    vroles[u] = Role::Uv(0);
                    vroles[v] = Role::Uv(1);
                    break;
                }
            }
            if el.count > u64::from(u32::MAX) {
                return Err(at_line(
                    path,
                    el.line,
                    format!("element `vertex`: {} vertices is too many", el.count),
                ));
            }
            el.count as usize
        }
        None => 0,
    };
    let mut froles = Vec::new();
    if let Some(i) = face_el {
        let el = &elements[i];
        froles = vec![Role::Skip; el.props.len()];
        let found = el
            .find(b"vertex_indices")
            .or_else(|| el.find(b"vertex_index"));
        let (k, p) = found.ok_or_else(|| {
            at_line(
                path,
                el.line,
                "element `face` has no property `vertex_indices`",
            )
        })?;
        match p.kind {
            Kind::List { item, .. } if item.is_int() => froles[k] = Role::Indices,
            _ => {
                return Err(at_line(
                    path,
                    p.line,
                    "`vertex_indices` must be a list of an integer type",
                ))
            }
        }
    }

    let data_bytes = bytes.get(header.data_start..).unwrap_or_default();
    let mut data = match header.encoding {
        Encoding::Ascii => Data::Ascii(Tokens::new(data_bytes, header.data_line)),
        enc => Data::Binary {
            bytes: data_bytes,
            pos: 0,
            base: header.data_start,
            big: enc == Encoding::Big,
        },
    };

    let mut mesh = Mesh::new();
    let mut colors = Vec::new();
    let mut uvs = Vec::new();
    let mut scratch = Vec::new();
    for (ei, el) in elements.iter().enumerate() {
        let min = el.min_size(ascii);
        if min == 0 || el.count == 0 {
            continue; // no data
        }
        let remaining = data.remaining();
        let count = usize::try_from(el.count)
            .ok()
            .filter(|&c| c.saturating_mul(min) <= remaining + 1)
            .ok_or_else(|| {
                at_line(
                    path,
                    el.line,
                    format!(
                        "element `{}` announces {} entries of at least {min} bytes each, but \
                         only {remaining} bytes of data are left",
                        quote(el.name),
                        el.count
                    ),
                )
            })?;
        // `what` is formatted only when an error occurs (not once per value read).
        fn wrap<'a>(
            path: &'a str,
            what: &'a dyn Fn() -> String,
        ) -> impl FnOnce(Fail) -> Error + 'a {
            move |f: Fail| Error::parse(path, f.loc, format!("{}: {}", what(), f.msg))
        }
        if Some(ei) == vertex_el {
            mesh.positions.reserve_exact(count);
            if has_color {
                colors.reserve_exact(count);
            }
            if has_uv {
                uvs.reserve_exact(count);
            }
            for i in 1..=count {
                let ctx = || format!("vertex {i} (of {count})");
                let mut xyz = [0.0; 3];
                let mut rgb = [0.0f32; 3];
                let mut uv = [0.0; 2];
                for (p, &role) in el.props.iter().zip(&vroles) {
                    let (Role::Coord(_) | Role::Color(_) | Role::Uv(_), Kind::Scalar(ty)) =
                        (role, p.kind)
                    else {
                        data.skip(p.kind).map_err(wrap(path, &ctx))?;
                        continue;
                    };
                    let loc = data.loc();
                    let x = data.float(ty).map_err(wrap(path, &ctx))?;
                    if !x.is_finite() {
                        return Err(Error::parse(
                            path,
                            loc,
                            format!(
                                "{}: property `{}` is not finite ({x})",
                                ctx(),
                                quote(p.name)
                            ),
                        ));
                    }
                    match role {
                        Role::Coord(c) => xyz[c] = x,
                        // In f32, so that `k / 255` is exactly what `k as f32 / 255.0` gives.
                        Role::Color(c) => rgb[c] = x as f32 / ty.color_scale(),
                        Role::Uv(c) => uv[c] = x,
                        _ => {}
                    }
                }
                mesh.positions.push(DVec3::from_array(xyz));
                if has_color {
                    colors.push(rgb);
                }
                if has_uv {
                    uvs.push(uv);
                }
            }
        } else if Some(ei) == face_el {
            mesh.face_offsets.reserve_exact(count);
            for f in 1..=count {
                let ctx = || format!("face {f} (of {count})");
                for (p, &role) in el.props.iter().zip(&froles) {
                    let (Role::Indices, Kind::List { count: cty, item }) = (role, p.kind) else {
                        data.skip(p.kind).map_err(wrap(path, &ctx))?;
                        continue;
                    };
                    let loc = data.loc();
                    let n = data.int(cty).map_err(wrap(path, &ctx))?;
                    if n < 3 {
                        return Err(Error::parse(
                            path,
                            loc,
                            format!("face {f} has {n} vertices; a face needs at least 3"),
                        ));
                    }
                    let n = data.check_list(n, item).map_err(wrap(path, &ctx))?;
                    let start = mesh.face_indices.len();
                    for _ in 0..n {
                        let loc = data.loc();
                        let v = data.int(item).map_err(wrap(path, &ctx))?;
                        if v < 0 || v as u64 >= nv as u64 {
                            let range = if nv == 0 {
                                "the file has no vertices".to_string()
                            } else {
                                format!("0..={}", nv - 1)
                            };
                            return Err(Error::parse(
                                path,
                                loc,
                                format!("face {f}: vertex index {v} out of range ({range})"),
                            ));
                        }
                        mesh.face_indices.push(v as u32);
                    }
                    if let Some(v) = repeated_vertex(&mesh.face_indices[start..], &mut scratch) {
                        return Err(Error::parse(
                            path,
                            loc,
                            format!("face {f}: vertex {v} appears more than once"),
                        ));
                    }
                    if !fits_u32(mesh.face_indices.len()) {
                        return Err(Error::parse(path, loc, "too many face corners"));
                    }
                }
                mesh.face_offsets.push(mesh.face_indices.len() as u32);
            }
        } else {
            for i in 1..=count {
                for p in &el.props {
                    data.skip(p.kind)
                        .map_err(wrap(path, &|| format!("element `{}` {i}", quote(el.name))))?;
                }
            }
        }
    }
    if has_color {
        mesh.colors = Some(colors);
    }
    if has_uv {
        mesh.uvs = Some(uvs);
    }
    Ok(mesh)
}

/// Writes `mesh` as binary little-endian PLY.
///
/// Vertices are `double x y z`, plus `uchar red green blue` with colours (quantized:
/// `round(clamp(c, 0, 1) * 255)`) and `double u v` with per-vertex [`Mesh::uvs`]. Faces are
/// `list uchar uint vertex_indices`, or `list uint uint vertex_indices` if a face has more than
/// 255 vertices. Positions round-trip bit-exactly through [`read`]; tags and face-varying uvs
/// are not representable and are dropped.
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

/// Writes the bytes that `serialize(range, out)` appends for the elements `0..n`, serialized
/// in parallel chunks of [`WRITE_CHUNK`] elements, [`WRITE_BATCH`] chunks at a time.
fn write_batched(
    w: &mut impl Write,
    n: usize,
    serialize: impl Fn(std::ops::Range<usize>, &mut Vec<u8>) + Sync,
) -> std::io::Result<()> {
    let chunks = n.div_ceil(WRITE_CHUNK);
    for batch in (0..chunks).step_by(WRITE_BATCH) {
        let bytes: Vec<Vec<u8>> = (batch..(batch + WRITE_BATCH).min(chunks))
            .into_par_iter()
            .map(|c| {
                let mut out = Vec::new();
                serialize(c * WRITE_CHUNK..((c + 1) * WRITE_CHUNK).min(n), &mut out);
                out
            })
            .collect();
        for b in &bytes {
            w.write_all(b)?;
        }
    }
    Ok(())
}

/// Elements per serialized chunk of [`write_batched`].
const WRITE_CHUNK: usize = 1 << 14;
/// Chunks serialized between two writes of [`write_batched`] (about 1M elements).
const WRITE_BATCH: usize = 64;

fn write_inner(mesh: &Mesh, w: &mut impl Write) -> std::io::Result<()> {
    let wide = mesh.face_offsets.windows(2).any(|o| o[1] - o[0] > 255);
    writeln!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment written by subwave"
    )?;
    writeln!(w, "element vertex {}", mesh.num_vertices())?;
    w.write_all(b"property double x\nproperty double y\nproperty double z\n")?;
    if mesh.colors.is_some() {
        w.write_all(b"property uchar red\nproperty uchar green\nproperty uchar blue\n")?;
    }
    if mesh.uvs.is_some() {
        w.write_all(b"property double u\nproperty double v\n")?;
    }
    writeln!(w, "element face {}", mesh.num_faces())?;
    let count_type = if wide { "uint" } else { "uchar" };
    writeln!(
        w,
        "property list {count_type} uint vertex_indices\nend_header"
    )?;
    // The body is serialized in parallel, a batch of chunks at a time (bounded extra memory).
    let nv = mesh.num_vertices();
    let stride = 24 + 3 * mesh.colors.is_some() as usize + 16 * mesh.uvs.is_some() as usize;
    write_batched(w, nv, |range, out| {
        out.reserve_exact(range.len() * stride);
        for v in range {
            let p = mesh.positions[v];
            let mut xyz = [0u8; 24];
            xyz[..8].copy_from_slice(&p.x.to_le_bytes());
            xyz[8..16].copy_from_slice(&p.y.to_le_bytes());
            xyz[16..].copy_from_slice(&p.z.to_le_bytes());
            out.extend_from_slice(&xyz);
            if let Some(c) = &mesh.colors {
                out.extend(c[v].map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8));
            }
            if let Some(uvs) = &mesh.uvs {
                for x in uvs[v] {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
    })?;
    let offs = &mesh.face_offsets;
    write_batched(w, mesh.num_faces(), |range, out| {
        let corners = (offs[range.end] - offs[range.start]) as usize;
        out.reserve_exact(range.len() * if wide { 4 } else { 1 } + 4 * corners);
        for f in range {
            let fv = &mesh.face_indices[offs[f] as usize..offs[f + 1] as usize];
            if let ([a, b, c], false) = (fv, wide) {
                let mut t = [3u8; 13];
                t[1..5].copy_from_slice(&a.to_le_bytes());
                t[5..9].copy_from_slice(&b.to_le_bytes());
                t[9..].copy_from_slice(&c.to_le_bytes());
                out.extend_from_slice(&t);
                continue;
            }
            if wide {
                out.extend_from_slice(&(fv.len() as u32).to_le_bytes());
            } else {
                out.push(fv.len() as u8);
            }
            for &v in fv {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    })?;
    Ok(())
}
