//! Error types. Each variant's documentation says how to fix the input.

use std::fmt;

/// Where in a file an error was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// A 1-based line number (text formats).
    Line(usize),
    /// A 0-based byte offset (binary formats).
    Byte(usize),
    /// The whole file (e.g. it ended too early, or a count is inconsistent).
    File,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(l) => write!(f, "line {l}"),
            Location::Byte(b) => write!(f, "byte {b}"),
            Location::File => write!(f, "file"),
        }
    }
}

/// A structural problem of a [`crate::Mesh`], naming the offending element.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// `face_offsets` does not start at 0, decreases, or does not end at `face_indices.len()`.
    /// Fix: build meshes with [`crate::Mesh::push_face`] or a reader.
    #[error("face offsets are inconsistent with the face index array")]
    BadOffsets,
    /// A face has fewer than three vertices. Fix: remove the face or add its missing vertices.
    #[error("face {face} has {arity} vertices; a face needs at least 3")]
    FaceTooSmall {
        /// The face (0-based).
        face: u32,
        /// Its number of vertices.
        arity: usize,
    },
    /// A face names a vertex that does not exist. Fix: correct the index or add the vertex.
    #[error("face {face} references vertex {index}, but the mesh has {vertices} vertices")]
    IndexOutOfRange {
        /// The face (0-based).
        face: u32,
        /// The bad vertex index (0-based).
        index: u32,
        /// Number of vertices in the mesh.
        vertices: usize,
    },
    /// A face visits the same vertex twice (a degenerate polygon). Fix: remove the duplicate.
    #[error("face {face} uses vertex {vertex} more than once")]
    RepeatedVertex {
        /// The face (0-based).
        face: u32,
        /// The repeated vertex (0-based).
        vertex: u32,
    },
    /// A coordinate is NaN or infinite. Fix: correct the vertex coordinates.
    #[error("vertex {vertex} has a NaN or infinite coordinate")]
    NonFinite {
        /// The vertex (0-based).
        vertex: u32,
    },
    /// A per-vertex or per-corner attribute array has the wrong length.
    #[error("attribute `{name}` has {len} entries, expected {expected}")]
    AttributeLength {
        /// Attribute name.
        name: &'static str,
        /// Its length.
        len: usize,
        /// The expected length.
        expected: usize,
    },
    /// A face-varying attribute index is out of range.
    #[error("attribute `{name}` index {index} is out of range ({len} values)")]
    AttributeIndex {
        /// Attribute name.
        name: &'static str,
        /// The bad index.
        index: u32,
        /// Number of values.
        len: usize,
    },
    /// A crease or corner tag names a vertex that does not exist. Fix: correct the tag line.
    #[error("a tag references vertex {vertex}, but the mesh has {vertices} vertices")]
    TagOutOfRange {
        /// The bad vertex index (0-based).
        vertex: u32,
        /// Number of vertices.
        vertices: usize,
    },
    /// The mesh has edges shared by more than two faces; subdivision and coding need a
    /// 2-manifold. Fix: split those edges (e.g. `subwave remesh --repair`) or remove faces.
    #[error("{} non-manifold edge(s) (shared by more than two faces): {}", .edges.len(), list_pairs(.edges))]
    NonManifoldEdges {
        /// The edges, as vertex pairs (0-based).
        edges: Vec<[u32; 2]>,
    },
    /// The mesh has vertices whose incident faces form several fans (pinched vertices).
    /// Fix: duplicate the vertex once per fan.
    #[error("{} non-manifold vertex(es) (faces around them form several fans): {}", .vertices.len(), list_ids(.vertices))]
    NonManifoldVertices {
        /// The vertices (0-based).
        vertices: Vec<u32>,
    },
    /// The mesh has non-manifold edges (on more than two faces) and/or non-manifold
    /// (pinched) vertices; both are listed. Fix: split them (`subwave remesh --repair`, which
    /// cuts such edges and duplicates such vertices once per fan) or edit the faces.
    #[error("not a 2-manifold: {} non-manifold edge(s): {}; {} non-manifold vertex(es): {}; rerun with --repair to split them", .edges.len(), list_pairs(.edges), .vertices.len(), list_ids(.vertices))]
    NonManifold {
        /// The non-manifold edges, as vertex pairs (0-based).
        edges: Vec<[u32; 2]>,
        /// The non-manifold vertices (0-based).
        vertices: Vec<u32>,
    },
    /// Neighbouring faces have opposite orientations across these edges. Fix: flip faces so
    /// that each interior edge is traversed once in each direction.
    #[error("inconsistent face orientation across {} edge(s): {}", .edges.len(), list_pairs(.edges))]
    InconsistentOrientation {
        /// The edges, as vertex pairs (0-based).
        edges: Vec<[u32; 2]>,
    },
    /// The scheme cannot take these faces (e.g. Loop on quads).
    #[error("scheme `{scheme}` needs {needs}, but {} face(s) are not: {}; {hint}", .faces.len(), list_ids(.faces))]
    UnsupportedFaces {
        /// The scheme's name.
        scheme: &'static str,
        /// What the scheme needs ("triangles", "quads").
        needs: &'static str,
        /// The offending faces (0-based).
        faces: Vec<u32>,
        /// What to use instead.
        hint: &'static str,
    },
}

fn list_ids(v: &[u32]) -> String {
    let mut s: Vec<String> = v.iter().take(10).map(|x| x.to_string()).collect();
    if v.len() > 10 {
        s.push(format!("... ({} more)", v.len() - 10));
    }
    s.join(", ")
}

fn list_pairs(v: &[[u32; 2]]) -> String {
    let mut s: Vec<String> = v.iter().take(10).map(|[a, b]| format!("{a}-{b}")).collect();
    if v.len() > 10 {
        s.push(format!("... ({} more)", v.len() - 10));
    }
    s.join(", ")
}

/// Any error of the library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be opened, read or written. Fix: check the path and permissions.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A file is malformed. The message names the element; fix the file at that location.
    #[error("{path}:{location}: {message}")]
    Parse {
        /// The file (`-` for standard input).
        path: String,
        /// Where in the file.
        location: Location,
        /// What is wrong, naming the element.
        message: String,
    },
    /// The file's format is unknown or unsupported. Fix: use one of the listed extensions or
    /// pass `--format`.
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// The mesh read from `path` is structurally invalid.
    #[error("{path}: {source}")]
    InvalidMesh {
        /// The file (or a description of where the mesh came from).
        path: String,
        /// The problem.
        source: MeshError,
    },
    /// A structural problem of a mesh built in memory.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The mesh has no subdivision connectivity (or fewer levels of it than asked): the
    /// message names the coarsening step and the triangle that is not part of a 1-to-4
    /// group. Fix: remesh to subdivision connectivity, or ask for fewer levels.
    #[error("no subdivision connectivity: {0}")]
    Hierarchy(String),
    /// A stream (`.swv`, base-mesh chunk, ...) is malformed, corrupt or of an unsupported
    /// version: the message names the chunk or field. Fix: re-encode the mesh, or fetch the
    /// stream again if it was damaged in transit.
    #[error("corrupt or unsupported stream at byte {offset}: {message}")]
    Decode {
        /// Byte offset in the stream where the problem was found.
        offset: usize,
        /// What is wrong, naming the chunk or field.
        message: String,
    },
    /// A parameter is out of its range. The message says which and what is allowed.
    #[error("{0}")]
    InvalidArgument(String),
}

impl Error {
    /// Convenience constructor for [`Error::Parse`].
    pub fn parse(path: &str, location: Location, message: impl Into<String>) -> Self {
        Error::Parse {
            path: path.to_string(),
            location,
            message: message.into(),
        }
    }
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;
