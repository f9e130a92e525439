//! # subwave
//!
//! Subdivision surfaces, wavelet subdivision surfaces, progressive coding and view-dependent
//! refinement. See `ARCHITECTURE.md` at the repository root for the layers and data flow.
//!
//! The layers, bottom up:
//! - [`mesh`]: the polygon mesh (flat `u32` face tables, `f64` positions, tags, attributes);
//! - [`topology`]: edges, ordered 1-rings, boundary loops, components and tags, as flat tables;
//! - [`validate`]: the report behind `subwave info` and the checks behind every algorithm;
//! - [`codec`]: entropy coding, base-mesh coding, SPIHT and the stream container;
//! - [`io`]: OBJ, OFF, PLY, STL readers; OBJ, OFF, PLY, GLB writers;
//! - [`generate`]: meshes the tests and the demo build themselves;
//! - [`distance`]: Metro-style surface distance (RMS, Hausdorff, PSNR);
//! - [`hierarchy`]: semi-regular meshes (subdivision connectivity, its detection);
//! - [`remesh`]: any mesh to subdivision connectivity (MAPS, shrink-wrapping), repair;
//! - [`wavelet`]: wavelet transforms on semi-regular meshes (triangle wavelets of Maret ch. 4,
//!   Bertram et al.'s B-spline wavelets);
//! - [`alloc`]: a global allocator putting large buffers in transparent huge pages, for
//!   binaries that opt in.
#![warn(missing_docs)]

pub mod alloc;
pub mod codec;
pub mod distance;
pub mod error;
pub mod generate;
pub mod hierarchy;
pub mod io;
pub mod mesh;
mod par;
pub mod remesh;
pub mod subdivision;
pub mod topology;
pub mod validate;
pub mod wavelet;

pub use error::{Error, Location, MeshError, Result};
pub use glam::DVec3;
pub use mesh::{EdgeTag, FaceVarying, Mesh, VertexTag, SHARPNESS_INFINITE};
pub use topology::Topology;
