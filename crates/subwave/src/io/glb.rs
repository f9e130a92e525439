//! Binary glTF 2.0 (GLB) output, for viewers and the web.
//!
//! The JSON part is built with the `gltf-json` crate, whose typed structures make it hard to
//! write a misspelled property or an invalid enum value; the binary container (12-byte header,
//! a JSON chunk padded with spaces and a BIN chunk padded with zeros to 4 bytes) is written
//! here. There is no GLB reader.

use std::collections::BTreeMap;
use std::io::{BufWriter, Write};

use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;

use super::{check_writable, write_err};
use crate::{Error, Mesh, Result};

const MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Writes `mesh` as a GLB file: one scene, one node, one mesh with one indexed triangle
/// primitive.
///
/// Faces are fan-triangulated ([`Mesh::triangulate`]). Every vertex is written, in order, as
/// `f32` (`POSITION`, with the accessor `min`/`max` the specification requires), with the
/// area-weighted unit normal of [`Mesh::vertex_normals`] (`NORMAL`; `+Z` for a vertex no face
/// uses, since glTF normals must be unit length) and, if the mesh has colours, its colour
/// clamped to 0..1 (`COLOR_0`, `f32` RGB). Indices are `u32`. A mesh without faces gives a GLB
/// with an asset description and no scene. Tags and uvs are dropped.
///
/// # Errors
/// [`Error::Mesh`] if the mesh is invalid ([`Mesh::check_indices`]);
/// [`Error::InvalidArgument`] if a coordinate is beyond the `f32` range or the file would exceed
/// the 4 GiB GLB limit; [`Error::Io`] if writing fails.
pub fn write(mesh: &Mesh, w: &mut dyn Write) -> Result<()> {
    check_writable(mesh)?;
    let (json_bytes, bin) = build(mesh)?;
    let json_len = json_bytes.len().next_multiple_of(4);
    let bin_len = bin.len().next_multiple_of(4);
    let mut total = 12 + 8 + json_len;
    if !bin.is_empty() {
        total += 8 + bin_len;
    }
    let total = u32::try_from(total).map_err(|_| {
        Error::InvalidArgument(format!(
            "the GLB file would have {total} bytes; the format allows at most 4 GiB"
        ))
    })?;
    let mut w = BufWriter::with_capacity(1 << 16, w);
    let mut out = || -> std::io::Result<()> {
        w.write_all(MAGIC)?;
        w.write_all(&2u32.to_le_bytes())?;
        w.write_all(&total.to_le_bytes())?;
        w.write_all(&(json_len as u32).to_le_bytes())?;
        w.write_all(&CHUNK_JSON.to_le_bytes())?;
        w.write_all(&json_bytes)?;
        w.write_all(&b"   "[..json_len - json_bytes.len()])?;
        if !bin.is_empty() {
            w.write_all(&(bin_len as u32).to_le_bytes())?;
            w.write_all(&CHUNK_BIN.to_le_bytes())?;
            w.write_all(&bin)?;
            w.write_all(&[0u8; 3][..bin_len - bin.len()])?;
        }
        w.flush()
    };
    out().map_err(write_err)
}

fn f32_checked(x: f64, v: usize) -> Result<f32> {
    let y = x as f32;
    if y.is_finite() {
        Ok(y)
    } else {
        Err(Error::InvalidArgument(format!(
            "vertex {v}: coordinate {x} is beyond the f32 range of glTF"
        )))
    }
}

/// The JSON chunk and the (unpadded) binary chunk.
fn build(mesh: &Mesh) -> Result<(Vec<u8>, Vec<u8>)> {
    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("subwave {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        ..Default::default()
    };
    let (tris, _) = mesh.triangulate();
    if tris.is_empty() {
        let json = root
            .to_vec()
            .map_err(|e| Error::InvalidArgument(format!("cannot encode glTF JSON: {e}")))?;
        return Ok((json, Vec::new()));
    }
    let nv = mesh.num_vertices();
    let mut bin = Vec::with_capacity(nv * 36 + tris.len() * 12);

    // Positions, with their bounds.
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for (v, p) in mesh.positions.iter().enumerate() {
        for (k, &x) in p.to_array().iter().enumerate() {
            let y = f32_checked(x, v)?;
            lo[k] = lo[k].min(y);
            hi[k] = hi[k].max(y);
            bin.extend_from_slice(&y.to_le_bytes());
        }
    }
    let pos_range = 0..bin.len();
    for n in mesh.vertex_normals() {
        let n = if n == glam::DVec3::ZERO {
            glam::DVec3::Z
        } else {
            n
        };
        for x in n.to_array() {
            bin.extend_from_slice(&(x as f32).to_le_bytes());
        }
    }
    let nrm_range = pos_range.end..bin.len();
    let col_range = mesh.colors.as_ref().map(|colors| {
        let start = bin.len();
        for c in colors {
            for x in c {
                let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
                bin.extend_from_slice(&x.to_le_bytes());
            }
        }
        start..bin.len()
    });
    let idx_start = bin.len();
    for t in &tris {
        for v in t {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let idx_range = idx_start..bin.len();

    let buffer = root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        uri: None,
    });
    let view = |root: &mut json::Root, r: &std::ops::Range<usize>, target| {
        root.push(json::buffer::View {
            buffer,
            byte_length: USize64::from(r.len()),
            byte_offset: Some(USize64::from(r.start)),
            byte_stride: None,
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            target: Some(Valid(target)),
        })
    };
    let array = json::buffer::Target::ArrayBuffer;
    let pos_view = view(&mut root, &pos_range, array);
    let nrm_view = view(&mut root, &nrm_range, array);
    let col_view = col_range.map(|r| view(&mut root, &r, array));
    let idx_view = view(
        &mut root,
        &idx_range,
        json::buffer::Target::ElementArrayBuffer,
    );
    let accessor = |root: &mut json::Root,
                    view,
                    count: usize,
                    component: json::accessor::ComponentType,
                    type_: json::accessor::Type,
                    bounds: Option<([f32; 3], [f32; 3])>| {
        root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(type_),
            min: bounds.map(|(lo, _)| json::Value::from(lo.to_vec())),
            max: bounds.map(|(_, hi)| json::Value::from(hi.to_vec())),
            name: None,
            normalized: false,
            sparse: None,
        })
    };
    use json::accessor::{ComponentType, Type};
    let pos_acc = accessor(
        &mut root,
        pos_view,
        nv,
        ComponentType::F32,
        Type::Vec3,
        Some((lo, hi)),
    );
    let nrm_acc = accessor(
        &mut root,
        nrm_view,
        nv,
        ComponentType::F32,
        Type::Vec3,
        None,
    );
    let col_acc =
        col_view.map(|v| accessor(&mut root, v, nv, ComponentType::F32, Type::Vec3, None));
    let idx_acc = accessor(
        &mut root,
        idx_view,
        3 * tris.len(),
        ComponentType::U32,
        Type::Scalar,
        None,
    );

    let mut attributes = BTreeMap::new();
    attributes.insert(Valid(json::mesh::Semantic::Positions), pos_acc);
    attributes.insert(Valid(json::mesh::Semantic::Normals), nrm_acc);
    if let Some(c) = col_acc {
        attributes.insert(Valid(json::mesh::Semantic::Colors(0)), c);
    }
    let primitive = json::mesh::Primitive {
        attributes,
        extensions: Default::default(),
        extras: Default::default(),
        indices: Some(idx_acc),
        material: None,
        mode: Valid(json::mesh::Mode::Triangles),
        targets: None,
    };
    let gmesh = root.push(json::Mesh {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        primitives: vec![primitive],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(gmesh),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: vec![node],
    });
    root.scene = Some(scene);
    let json = root
        .to_vec()
        .map_err(|e| Error::InvalidArgument(format!("cannot encode glTF JSON: {e}")))?;
    Ok((json, bin))
}
