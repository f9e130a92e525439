//! Progressive (and lossless) geometry coding of semi-regular meshes: the encode/decode API
//! of `.swv` streams.
//!
//! Maret 2003 ch. 4 (wavelet subdivision surfaces, §4.4 SPIHT coding, §4.5 MPEG-4 AFX and
//! its proposed extension) and Bertram et al. (B-spline wavelets on quad hierarchies, and
//! their integer lifting for lossless coding, §4.3):
//!
//! 1. the finest positions of a [`Hierarchy`] are transformed by a wavelet
//!    ([`Wavelet`]: midpoint / butterfly (lifted or not) / Loop on triangle hierarchies, in
//!    global or local frames; linear / cubic / quintic B-splines on quad hierarchies) into the
//!    base positions and one detail vector per odd vertex of each level;
//! 2. the base positions are quantized on a grid over the bounding box and coded in the
//!    base-mesh chunk with the base faces;
//! 3. the details are weighted per level and component (below), quantized (eqs. 4.7-4.9,
//!    [`super::quantize`]) and coded by SPIHT ([`super::spiht`]) over the offspring forest
//!    ([`super::forest`]);
//! 4. the container ([`super::container`]) stores the header, the base chunk and the
//!    coefficient chunks in one of two [`Layout`]s.
//!
//! # Level weights
//! SPIHT codes the largest magnitudes first, which minimises the squared error of the
//! coefficients, not of the surface: the wavelets here are not orthogonal, and a detail of
//! level `j` moves the surface over an area that shrinks by 4 per level (its basis
//! function's squared L2 norm). Each detail of level `j` is therefore multiplied by
//! `2^(−α·j)` before quantization and divided back when decoded
//! ([`EncodeOptions::level_exponent`], `α = 1` by default, stored in the header in
//! quarters): a bit plane then reduces the surface error about equally at every level, and
//! the coarse details are sent first. (Maret's eqs. 4.7-4.9 weigh every level alike, `α = 0`.) Measured with `subwave
//! eval`, bits per input vertex at equal PSNR against Draco 1.5 (cl 10) for `α` = 0 → 1:
//! stanford-bunny 0.45 → 0.36 at 75 dB, 0.60 → 0.51 at 78 dB, 0.78 → 0.65 at 80 dB; fandisk
//! 0.55 → 0.36 at 70 dB, 0.68 → 0.47 at 75 dB; rocker-arm 0.61 → 0.56 at 75 dB; a
//! quad remesh of the bunny (cubic B-splines) 0.79 → 0.60 bits per input vertex at 75 dB.
//! `α` = 0.75 was as good on the bunny, 1.25–1.5 slightly better on fandisk.
//!
//! In local frames the two tangential components are weighted `2^(−k)` more
//! ([`EncodeOptions::tangent_shift`], `k = 2` by default, stored in the header): sliding a
//! vertex along the surface moves the surface only to second order, so the tangential bits
//! come `k` planes after the normal ones. With both weights (`α = 1`, `k = 2`) against
//! neither: bunny 0.45 → 0.34 of Draco's bytes at 75 dB and 0.60 → 0.46 at 78 dB; fandisk
//! 0.68 → 0.36 at 75 dB and 1.01 → 0.48 at 80 dB; rocker-arm 0.61 → 0.52 at 75 dB (`k` = 3
//! was as good, 4 worse on fandisk).
//!
//! # Layouts
//! - [`Layout::Embedded`] (Maret §4.5.3): one chunk per bit plane of the whole forest, each
//!   an independent range-coder stream (the adaptive contexts carry over from plane to
//!   plane). **Any byte prefix** that holds the header, the index and the base chunk decodes:
//!   complete planes exactly, the cut plane up to the first decision that needs a missing
//!   byte. The decoded mesh is always the **finest** connectivity with the coefficients known
//!   so far (unknown coefficients are zero, known ones mid-interval, eqs. 4.11-4.12), which is
//!   the best estimate the bits give: a coarser level would drop the known fine coefficients.
//! - [`Layout::Trees`] (AFX view-dependent mode, §4.5.1): one chunk per tree (per base edge,
//!   and per base face for quads) holding all its bit planes, with per-plane prefix lengths
//!   in the index (a client can range-request `[offset, offset + mark_p)` to get planes
//!   `top..=p` of a tree). [`DecodeOptions::trees`] selects the trees to decode; the others
//!   keep zero details. [`TreeDecoder`] adds and removes trees while decoding (§5.1.2). A
//!   byte prefix of a trees stream decodes the trees (and tree prefixes) it contains.
//!
//! # Lossless mode
//! Positions are quantized on a grid of `2^bits` steps over the longest side of the
//! bounding box and transformed by an integer-to-integer wavelet (unlifted midpoint or
//! butterfly prediction chosen per level, [`crate::wavelet::triangle_int`]; Bertram's
//! integer B-spline lifting on quad hierarchies). With the embedded layout the stream is
//! [`super::lossless`]'s: the base chunk coded by the base-mesh coder's integer API, then
//! one chunk per level of context-modelled integer details (flags `F_LOSSLESS |
//! F_BASEMESH`). With the trees layout the integer coefficients are coded by SPIHT with
//! step 1 per tree (flag `F_LOSSLESS` alone, base by [`encode_base`]). Either way the full
//! stream reproduces the quantized positions bit for bit, and every prefix is a lossy
//! approximation.
//!
//! # Decoder safety
//! The decoder validates the header and index (checksums, counts) before allocating; the
//! finest mesh may have at most `1024 × stream bytes + 2^16` faces (a legitimate stream is
//! never that sparse), at most 12 levels. A complete chunk whose CRC fails is an error naming
//! the chunk; nothing is decoded from it.
//!
//! # Base-mesh chunk
//! Lossy streams code the base mesh (faces and the base wavelet coefficients as positions,
//! `base_bits` per coordinate) with the single-rate coder of [`super::basemesh`]
//! (valence-driven connectivity, parallelogram prediction). That coder renumbers vertices
//! and faces, so the encoder re-indexes the hierarchy onto the decoded base order (odd
//! vertices matched by their parent edges level by level) and transforms it again there.
//! Lossless embedded streams code the exact integer base positions with the same coder's
//! integer API ([`basemesh::encode_integers`]); lossless trees streams with the small
//! coder [`encode_base`]: per corner one adaptive bit "next new vertex" or the index as an
//! Elias-gamma integer, then per vertex the coordinate differences to the previous vertex.
//!
//! Position-dependent subdivision masks: the butterfly and Loop tables are built on the
//! decoded base mesh; they depend on positions only next to tagged corner vertices, which a
//! stream's base mesh never has (tags are not coded), so encoder and decoder agree.

use glam::DVec3;
use rayon::prelude::*;

use super::basemesh::{self, BaseMeshOptions};
use super::container::{self, ChunkKind, Container, Header};
use super::forest::Forest;
use super::lossless;
use super::quantize::{self, ComponentMode, Grid};
use super::rangecoder::{Bit, Decoder, Encoder, SInt, UInt};
use super::spiht::{
    self, Coefficients, Magnitudes, SpihtDecoder, SpihtEncoder, SpihtMemory, INSIGNIFICANT,
};
use crate::hierarchy::Hierarchy;
use crate::mesh::Mesh;
use crate::subdivision::refine::{child_faces, Split};
use crate::subdivision::{Scheme, SubdivideOptions};
use crate::topology::Topology;
use crate::wavelet::bertram::{BSplineWavelet, Degree};
use crate::wavelet::triangle::{DetailFrame, SynthesisScratch, TriangleWavelet};
use crate::wavelet::triangle_int::IntTriangleWavelet;
use crate::{Error, Result};

/// Most subdivision levels a stream may have.
pub const MAX_LEVELS: u32 = 12;

/// The wavelet of a stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wavelet {
    /// Midpoint (linear prediction), triangle hierarchies.
    Midpoint,
    /// Modified butterfly prediction, triangle hierarchies.
    Butterfly,
    /// Loop (PGC), triangle hierarchies (not in lossless mode).
    Loop,
    /// Bertram's linear B-spline wavelet, quad hierarchies.
    Linear,
    /// Bertram's cubic B-spline wavelet, quad hierarchies.
    Cubic,
    /// Bertram's quintic B-spline wavelet, quad hierarchies.
    Quintic,
}

impl Wavelet {
    fn id(self) -> u8 {
        match self {
            Wavelet::Midpoint => 0,
            Wavelet::Butterfly => 1,
            Wavelet::Loop => 2,
            Wavelet::Linear => 3,
            Wavelet::Cubic => 4,
            Wavelet::Quintic => 5,
        }
    }

    fn from_id(id: u8) -> Option<Wavelet> {
        Some(match id {
            0 => Wavelet::Midpoint,
            1 => Wavelet::Butterfly,
            2 => Wavelet::Loop,
            3 => Wavelet::Linear,
            4 => Wavelet::Cubic,
            5 => Wavelet::Quintic,
            _ => return None,
        })
    }

    /// The lower-case name (`midpoint`, `butterfly`, `loop`, `linear`, `cubic`, `quintic`).
    pub fn name(self) -> &'static str {
        match self {
            Wavelet::Midpoint => "midpoint",
            Wavelet::Butterfly => "butterfly",
            Wavelet::Loop => "loop",
            Wavelet::Linear => "linear",
            Wavelet::Cubic => "cubic",
            Wavelet::Quintic => "quintic",
        }
    }

    /// Whether the wavelet works on quad (Catmull-Clark connectivity) hierarchies.
    pub fn is_quad(self) -> bool {
        matches!(self, Wavelet::Linear | Wavelet::Cubic | Wavelet::Quintic)
    }

    fn degree(self) -> Degree {
        match self {
            Wavelet::Cubic => Degree::Cubic,
            Wavelet::Quintic => Degree::Quintic,
            _ => Degree::Linear,
        }
    }
}

/// The chunk layout of a stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Layout {
    /// One chunk per bit plane of the whole forest (any prefix decodes).
    #[default]
    Embedded,
    /// One chunk per tree with per-plane marks (view-dependent).
    Trees,
}

/// Encoder options. The defaults (lifted butterfly, local frames, aligned components,
/// contexts on, 16 bit planes, 14-bit base grid) were chosen by measurement on the remeshed
/// Stanford bunny (5 levels over 400 base faces; PSNR against the input at 8, 14 and 25 KB):
/// lifted butterfly 60.6/63.6/64.8 dB; unlifted butterfly 59.4/62.8/64.4; lifted midpoint
/// 60.8/63.2/64.6; Loop 57.2/61.4/64.3; global frames −0.1 to −0.3 dB; independent
/// components within ±0.1 dB; raw bits (no contexts) −1 to −2.2 dB.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodeOptions {
    /// The wavelet (must match the hierarchy: triangle or quad).
    pub wavelet: Wavelet,
    /// Lifted (update step) midpoint/butterfly; ignored by the other wavelets and in
    /// lossless mode (always unlifted there) (default on).
    pub lifted: bool,
    /// Detail coordinates (triangle wavelets; quad wavelets are always global).
    pub frames: DetailFrame,
    /// Lossy: bit planes `N` of eq. 4.8 (1..=30). Lossless: bits of the position grid
    /// (1..=24).
    pub bits: u32,
    /// Bits of the base-mesh position grid (lossy mode; 4..=30).
    pub base_bits: u32,
    /// How the components share quantization steps.
    pub components: ComponentMode,
    /// Context-adaptive coding of the SPIHT decisions (else raw bits).
    pub contexts: bool,
    /// The chunk layout.
    pub layout: Layout,
    /// Lossless (integer) mode.
    pub lossless: bool,
    /// Vertices of the input the hierarchy stands for (recorded in the header for rates in
    /// bits per input vertex); `None`: the hierarchy's finest vertex count.
    pub input_vertices: Option<u32>,
    /// Lossy: code the fewest bit planes (at most [`EncodeOptions::bits`]) whose full
    /// decode reconstructs the finest positions within this RMS error (model units, over
    /// the vertices; found by bisection over the plane count, each candidate quantized and
    /// synthesised as the decoder would). Bits beyond it buy nothing when the hierarchy
    /// itself is only that close to the surface it stands for (a remesh): `None` (the
    /// default) codes all `bits` planes. Ignored in lossless mode.
    pub max_rms: Option<f64>,
    /// Lossy: the details of level `j` are weighted by `2^(−α·j)` before quantization
    /// (`α` this exponent, a multiple of 1/4 in `0..=8`; 0 weighs every level alike, as
    /// Maret's eqs. 4.7-4.9 do). A detail's share of the squared surface error is its
    /// squared magnitude times the area its basis function covers, which shrinks by 4 per
    /// level, so with `α = 1` (the default) a bit plane buys about the same error
    /// reduction at every level and the coarse details go first. Measured (bits per input
    /// vertex over Draco's at equal PSNR, `subwave eval`, `α` = 0 → 1 with
    /// [`EncodeOptions::tangent_shift`] 0): stanford-bunny 0.45 → 0.36 at
    /// 75 dB and 0.60 → 0.51 at 78 dB; fandisk 0.68 → 0.47 at 75 dB. Ignored in lossless
    /// mode.
    pub level_exponent: f64,
    /// Lossy, local frames: the two tangential components of every detail are weighted by
    /// `2^(−k)` (this `k`, 0..=8) before quantization, on top of the level weight. Moving a
    /// vertex along the surface moves the surface itself only to second order, so the
    /// tangential bits buy little of the surface distance; with `k = 2` (the default) they
    /// are sent two bit planes later than the normal ones. Measured (bits per input vertex
    /// over Draco's at equal PSNR, `subwave eval`, `k` = 0 → 2): fandisk 0.36 → 0.26 at 70 dB
    /// and 0.72 → 0.48 at 80 dB; stanford-bunny 0.27 → 0.23 at 70 dB, 0.51 → 0.46 at 78 dB;
    /// rocker-arm 0.56 → 0.52 at 75 dB. Ignored with global frames (quad wavelets) and in
    /// lossless mode; no effect with [`ComponentMode::Independent`], whose three steps
    /// follow each component's own largest detail.
    pub tangent_shift: u32,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions {
            wavelet: Wavelet::Butterfly,
            lifted: true,
            frames: DetailFrame::Local,
            bits: 16,
            base_bits: 14,
            components: ComponentMode::Aligned,
            contexts: true,
            layout: Layout::Embedded,
            lossless: false,
            input_vertices: None,
            max_rms: None,
            level_exponent: 1.0,
            tangent_shift: 2,
        }
    }
}

impl EncodeOptions {
    /// The default options for a hierarchy: [`Wavelet::Butterfly`] on triangles,
    /// [`Wavelet::Cubic`] (global frames) on quads.
    pub fn for_hierarchy(h: &Hierarchy) -> EncodeOptions {
        let mut o = EncodeOptions::default();
        if h.split == Split::Polygons {
            o.wavelet = Wavelet::Cubic;
            o.frames = DetailFrame::Global;
        }
        o
    }
}

/// Decoder options.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DecodeOptions {
    /// Decode only this many leading bytes of the stream (a prefix).
    pub max_bytes: Option<usize>,
    /// Trees layout: decode only these trees (others keep zero details). Ignored by the
    /// embedded layout.
    pub trees: Option<Vec<u32>>,
}

/// Working memory of [`decode_with`] kept from one decode to the next: a client that decodes
/// repeatedly (a progressive viewer decoding each longer prefix of a stream as it arrives, or
/// many streams in turn) keeps one and saves allocating and faulting in the coefficient
/// decoder's memory each time. Its contents never carry over: the result of a decode does
/// not depend on the buffers' history.
#[derive(Clone, Debug, Default)]
pub struct DecodeBuffers {
    coefficients: Coefficients,
    spiht: SpihtMemory,
}

/// A decoded mesh and what was used.
#[derive(Clone, Debug)]
pub struct Decoded {
    /// The finest level with the coefficients known so far (contract order).
    pub mesh: Mesh,
    /// Bytes of the stream used (header, base and the coefficient bytes read).
    pub bytes_used: usize,
    /// Bit planes decoded completely (embedded layout; for trees, those of every decoded
    /// tree).
    pub planes_complete: u32,
    /// Bit planes of the stream.
    pub planes: u32,
    /// Whether every coefficient bit of the stream was decoded (lossless: the positions are
    /// exact).
    pub complete: bool,
}

/// What a stream holds ([`inspect`]).
#[derive(Clone, Debug)]
pub struct StreamInfo {
    /// Format version.
    pub version: u16,
    /// The wavelet.
    pub wavelet: Wavelet,
    /// Lifted midpoint/butterfly.
    pub lifted: bool,
    /// Detail frames.
    pub frames: DetailFrame,
    /// Component quantization mode.
    pub components: ComponentMode,
    /// Context-adaptive coding.
    pub contexts: bool,
    /// Lossless mode.
    pub lossless: bool,
    /// A direct stream ([`super::direct`]): the input mesh itself, its planes refining the
    /// base chunk's positions (`bits` is then the full precision, `planes` the refinement
    /// planes).
    pub direct: bool,
    /// The layout.
    pub layout: Layout,
    /// Subdivision levels.
    pub levels: u32,
    /// Quantization bits.
    pub bits: u32,
    /// Base vertices.
    pub base_vertices: u32,
    /// Base faces.
    pub base_faces: u32,
    /// Trees.
    pub trees: u32,
    /// Bit planes.
    pub planes: u32,
    /// Header and index bytes.
    pub header_bytes: usize,
    /// Base-mesh chunk bytes.
    pub base_bytes: usize,
    /// Total stream bytes.
    pub total_bytes: u64,
    /// Vertices of the input mesh the stream stands for.
    pub input_vertices: u32,
    /// Vertices of the decoded (finest) mesh.
    pub vertices: u64,
    /// Faces of the decoded (finest) mesh.
    pub faces: u64,
    /// Bounding box of the encoded positions.
    pub bbox: [DVec3; 2],
    /// The chunk index.
    pub chunks: Vec<container::ChunkEntry>,
}

const F_LIFTED: u8 = 1;
const F_LOCAL: u8 = 2;
const F_ALIGNED: u8 = 4;
const F_CONTEXTS: u8 = 8;
const F_LOSSLESS: u8 = 16;
/// A direct stream ([`super::direct`]): the input mesh itself, no levels, with precision
/// refinement planes after its base chunk (version 10). Always with [`F_BASEMESH`] alone:
/// its base chunk holds a base-mesh stream behind its length, then the polygons' rotations.
const F_DIRECT: u8 = 128;
/// The base chunk is a [`super::basemesh`] stream (lossy mode).
const F_BASEMESH: u8 = 32;
/// Lossless streams: a Loop reference surface ([`super::lossless`]).
const F_REFERENCE: u8 = 64;

/// A float wavelet transform of a hierarchy.
enum Transform<'h> {
    Tri(TriangleWavelet<'h>),
    Quad(BSplineWavelet, &'h [Topology]),
}

impl<'h> Transform<'h> {
    fn new(h: &'h Hierarchy, w: Wavelet, lifted: bool, frame: DetailFrame) -> Result<Self> {
        Ok(match w {
            Wavelet::Midpoint => {
                Transform::Tri(TriangleWavelet::midpoint(h, lifted)?.with_frame(frame))
            }
            Wavelet::Butterfly => {
                Transform::Tri(TriangleWavelet::butterfly(h, lifted)?.with_frame(frame))
            }
            Wavelet::Loop => Transform::Tri(
                TriangleWavelet::loop_pgc(h, &SubdivideOptions::default())?.with_frame(frame),
            ),
            _ => Transform::Quad(BSplineWavelet::new(w.degree()), &h.topologies[..h.levels()]),
        })
    }

    fn forward(&self, data: &mut [DVec3]) -> Result<()> {
        match self {
            Transform::Tri(t) => t.decompose_in_place(data),
            Transform::Quad(w, levels) => w.analyze(levels, data),
        }
    }

    fn inverse(&self, data: &mut [DVec3], scratch: &mut SynthesisScratch) -> Result<()> {
        match self {
            Transform::Tri(t) => t.reconstruct_in_place_with(data, scratch),
            Transform::Quad(w, levels) => w.synthesize(levels, data),
        }
    }

    /// The synthesis' scratch memory, its pages touched ([`SynthesisScratch::prepared`]).
    fn scratch(&self) -> SynthesisScratch {
        match self {
            Transform::Tri(t) => SynthesisScratch::prepared(t),
            Transform::Quad(..) => SynthesisScratch::default(),
        }
    }
}

/// An integer wavelet transform of a hierarchy (lossless mode).
enum IntTransform<'h> {
    Tri(IntTriangleWavelet<'h>),
    Quad(BSplineWavelet, &'h [Topology]),
}

impl<'h> IntTransform<'h> {
    fn new(h: &'h Hierarchy, w: Wavelet, lifted: bool) -> Result<Self> {
        Ok(match w {
            Wavelet::Midpoint => IntTransform::Tri(IntTriangleWavelet::midpoint(h, lifted)?),
            Wavelet::Butterfly => IntTransform::Tri(IntTriangleWavelet::from_scheme(
                h,
                &SubdivideOptions {
                    scheme: Scheme::Butterfly,
                    ..Default::default()
                },
                lifted,
            )?),
            Wavelet::Loop => {
                return Err(Error::InvalidArgument(
                    "lossless mode needs an integer wavelet: midpoint or butterfly (triangles), linear, cubic or quintic (quads); Loop has no finite integer lifting".into(),
                ))
            }
            _ => IntTransform::Quad(
                BSplineWavelet::new(w.degree()),
                &h.topologies[..h.levels()],
            ),
        })
    }

    fn forward(&self, data: &mut [[i64; 3]]) -> Result<()> {
        match self {
            IntTransform::Tri(t) => t.forward(data),
            IntTransform::Quad(w, levels) => w.analyze_int(levels, data),
        }
    }

    fn inverse(&self, data: &mut [[i64; 3]]) -> Result<()> {
        match self {
            IntTransform::Tri(t) => t.inverse(data),
            IntTransform::Quad(w, levels) => w.synthesize_int(levels, data),
        }
    }
}

/// The bounding box `[min, max]` of `p` (zero for no points).
pub(crate) fn bbox(p: &[DVec3]) -> [DVec3; 2] {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for x in p {
        lo = lo.min(*x);
        hi = hi.max(*x);
    }
    if p.is_empty() {
        [DVec3::ZERO, DVec3::ZERO]
    } else {
        [lo, hi]
    }
}

/// Encodes hierarchy `h` (its base faces and finest positions) into a `.swv` stream.
///
/// # Errors
/// [`Error::InvalidArgument`] if the wavelet does not match the hierarchy's split (triangle
/// wavelets on [`Split::Triangles`], B-spline wavelets on [`Split::Polygons`]), Loop in
/// lossless mode, more than [`MAX_LEVELS`] levels, bits out of range, non-finite positions,
/// or a mesh beyond [`spiht::MAX_NODES`] coefficients; errors of the wavelet transform.
pub fn encode(h: &Hierarchy, opts: &EncodeOptions) -> Result<Vec<u8>> {
    Ok(encode_with_info(h, opts)?.0)
}

/// [`encode`], also returning the hierarchy in the stream's order: the decoder's mesh is its
/// finest level (with decoded positions). Streams renumber the base mesh (the base-mesh
/// coder's traversal order), so this is `h` re-indexed.
///
/// # Errors
/// As [`encode`].
pub fn encode_with_info(h: &Hierarchy, opts: &EncodeOptions) -> Result<(Vec<u8>, Hierarchy)> {
    let l = h.levels();
    if l as u32 > MAX_LEVELS {
        return Err(Error::InvalidArgument(format!(
            "{l} levels: streams have at most {MAX_LEVELS}"
        )));
    }
    match (h.split, opts.wavelet.is_quad()) {
        (Split::Triangles, false) | (Split::Polygons, true) => {}
        _ => {
            return Err(Error::InvalidArgument(format!(
                "the {} wavelet does not fit a {} hierarchy (triangle hierarchies: midpoint, butterfly, loop; quad hierarchies: linear, cubic, quintic)",
                opts.wavelet.name(),
                if h.split == Split::Triangles { "triangle" } else { "quad/polygon" }
            )))
        }
    }
    if let Some(v) = h.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::InvalidArgument(format!(
            "vertex {v} has a non-finite coordinate"
        )));
    }
    let bits_max = if opts.lossless {
        24
    } else {
        quantize::MAX_PLANES
    };
    if opts.bits == 0 || opts.bits > bits_max {
        return Err(Error::InvalidArgument(format!(
            "bits {} out of range 1..={bits_max}",
            opts.bits
        )));
    }
    if !(4..=30).contains(&opts.base_bits) {
        return Err(Error::InvalidArgument(format!(
            "base bits {} out of range 4..=30",
            opts.base_bits
        )));
    }
    let frame = if opts.wavelet.is_quad() || opts.lossless {
        DetailFrame::Global
    } else {
        opts.frames
    };
    let lifted = opts.lifted && matches!(opts.wavelet, Wavelet::Midpoint | Wavelet::Butterfly);
    // Only local frames have tangential components.
    let tangent_shift = if frame == DetailFrame::Local && !opts.lossless {
        opts.tangent_shift as u8
    } else {
        0
    };
    let mut forest = Forest::new(h)?;
    if forest.num_nodes > spiht::MAX_NODES {
        return Err(Error::InvalidArgument(format!(
            "{} coefficients: streams hold at most {}",
            forest.num_nodes,
            spiht::MAX_NODES
        )));
    }
    let v0 = h.num_vertices(0);
    let bb = bbox(&h.positions);
    if opts.lossless && opts.layout == Layout::Embedded {
        // Pure interpolating prediction (no update step) codes smaller losslessly: 60.9 vs
        // 78.2 KB (Loop-subdivided spot), 61.3 vs 75.5 KB (butterfly-subdivided rocker arm),
        // 30.3 vs 30.3 KB (remeshed bunny), 12 bits.
        return encode_lossless(h, opts, bb, forest.num_trees);
    }
    let weight_code = if opts.lossless {
        0
    } else {
        level_weight_code(opts.level_exponent)?
    };
    if opts.tangent_shift > MAX_TANGENT_SHIFT {
        return Err(Error::InvalidArgument(format!(
            "tangent shift {} out of range 0..={MAX_TANGENT_SHIFT}",
            opts.tangent_shift
        )));
    }
    let mut bits = opts.bits;
    let mut base_chunk: Option<Vec<u8>> = None;
    let mut reindexed: Option<Hierarchy> = None;
    let (grid, base_q, mags, steps) = if opts.lossless {
        let grid = Grid::new(bb[0], bb[1], opts.bits);
        let mut data: Vec<[i64; 3]> = h
            .positions
            .iter()
            .map(|&p| grid.quantize(p).map(i64::from))
            .collect();
        IntTransform::new(h, opts.wavelet, lifted)?.forward(&mut data)?;
        let base_q = data[..v0].to_vec();
        let mut mag = Vec::with_capacity(3 * forest.num_nodes);
        let mut neg = Vec::with_capacity(3 * forest.num_nodes);
        for d in &data[v0..] {
            for &x in d {
                if x.unsigned_abs() >= 1 << quantize::MAX_PLANES {
                    return Err(Error::InvalidArgument(
                        "an integer wavelet coefficient exceeds 2^30; use fewer bits".into(),
                    ));
                }
                mag.push(x.unsigned_abs() as u32);
                neg.push(x < 0);
            }
        }
        (grid, base_q, Magnitudes::new(&forest, mag, neg), [1.0; 3])
    } else {
        // The base mesh coder renumbers the base: code the coarse positions first, then
        // re-index the hierarchy to the decoded base order and transform again there.
        let mut flat = h.positions.clone();
        Transform::new(h, opts.wavelet, lifted, frame)?.forward(&mut flat)?;
        // The crease and corner tags travel in the base chunk (the decoder's hierarchy has
        // them too, so both sides predict with the same rules).
        let mut coarse = h.base.clone();
        coarse.positions = flat[..v0].to_vec();
        let enc = basemesh::encode_with_info(
            &coarse,
            &BaseMeshOptions {
                position_bits: opts.base_bits.clamp(8, 30),
            },
        )?;
        let new_base = enc.decoded.clone();
        let nh = reindex(h, &new_base, &enc.vertex_map)?;
        let mut flat = nh.positions.clone();
        let transform = Transform::new(&nh, opts.wavelet, lifted, frame)?;
        transform.forward(&mut flat)?;
        let nforest = Forest::new(&nh)?;
        let gains = detail_scales(weight_code, tangent_shift, nh.levels());
        let weighted: Vec<DVec3> = flat[v0..]
            .iter()
            .zip(&nforest.level)
            .map(|(d, &l)| *d * gains[l as usize])
            .collect();
        if let Some(tol) = opts.max_rms {
            bits = planes_search(
                &transform,
                (&flat[..v0], &weighted, &nforest.level, &gains),
                &nh.positions,
                bits,
                opts.components,
                tol,
            )?;
        }
        drop(transform);
        base_chunk = Some(enc.bytes);
        reindexed = Some(nh);
        let grid = Grid::new(bb[0], bb[1], opts.base_bits);
        let details = &weighted[..];
        let steps = quantize::steps(details, bits, opts.components);
        let mut mag = Vec::with_capacity(3 * details.len());
        let mut neg = Vec::with_capacity(3 * details.len());
        for d in details {
            for c in 0..3 {
                let (m, s) = quantize::quantize(d[c], steps[c]);
                mag.push(m);
                neg.push(s);
            }
        }
        let m = Magnitudes::new(&nforest, mag, neg);
        forest = nforest;
        (grid, Vec::new(), m, steps)
    };
    // The hierarchy the coefficients follow (re-indexed to the base coder's order).
    let h = reindexed.as_ref().unwrap_or(h);
    let stream_hierarchy = h.clone();
    let base_bytes = match base_chunk {
        Some(b) => b,
        None => encode_base(&h.base, &base_q),
    };
    let mut chunks = vec![(ChunkKind::Base, 0u32, base_bytes, Vec::new())];
    let planes = spiht::num_planes(mags.top);
    match opts.layout {
        Layout::Embedded => {
            let roots: Vec<u32> = (0..forest.num_trees as u32).collect();
            let mut s = SpihtEncoder::new(&forest, &mags, &roots, opts.contexts);
            loop {
                let n = s.plane();
                let mut enc = Encoder::new();
                if !s.code_plane(&mut enc) {
                    break;
                }
                chunks.push((ChunkKind::Plane, n as u32, enc.finish(), Vec::new()));
            }
        }
        Layout::Trees => {
            for t in 0..forest.num_trees as u32 {
                let mut s = SpihtEncoder::new(&forest, &mags, &[t], opts.contexts);
                let mut enc = Encoder::new();
                let mut marks = Vec::with_capacity(planes as usize);
                while s.code_plane(&mut enc) {
                    marks.push(enc.size_bound() as u32);
                }
                let bytes = enc.finish();
                let len = bytes.len() as u32;
                for m in &mut marks {
                    *m = (*m).min(len);
                }
                chunks.push((ChunkKind::Tree, t, bytes, marks));
            }
        }
    }
    let mut flags = 0;
    if lifted {
        flags |= F_LIFTED;
    }
    if frame == DetailFrame::Local {
        flags |= F_LOCAL;
    }
    if opts.components == ComponentMode::Aligned {
        flags |= F_ALIGNED;
    }
    if opts.contexts {
        flags |= F_CONTEXTS;
    }
    if opts.lossless {
        flags |= F_LOSSLESS;
    } else {
        flags |= F_BASEMESH;
    }
    let header = Header {
        wavelet: opts.wavelet.id(),
        flags,
        split: if h.split == Split::Triangles { 0 } else { 1 },
        layout: match opts.layout {
            Layout::Embedded => 0,
            Layout::Trees => 1,
        },
        levels: l as u8,
        bits: bits as u8,
        base_bits: opts.base_bits as u8,
        level_weight: weight_code,
        top: mags.top.map(|t| t as i8),
        tangent_shift,
        input_vertices: opts
            .input_vertices
            .unwrap_or(h.positions.len().min(u32::MAX as usize) as u32),
        bbox: bb,
        steps,
        grid_origin: grid.origin,
        grid_step: grid.step,
        base_vertices: v0 as u32,
        base_faces: h.base.num_faces() as u32,
        base_corners: h.base.face_indices.len() as u32,
        num_trees: forest.num_trees as u32,
    };
    Ok((container::write(&header, &chunks)?, stream_hierarchy))
}

/// Writes a direct stream's container ([`super::direct::encode`]): `base` the decoded base
/// mesh (counts), `split` 0 for triangles, 1 for polygons, `bb` the positions' box, `grid`
/// the `opts.bits` grid, `chunks` the base chunk and the refinement planes.
pub(crate) fn write_direct(
    base: &Mesh,
    split: u8,
    opts: &super::direct::DirectOptions,
    bb: [DVec3; 2],
    grid: &Grid,
    vertices: usize,
    chunks: &[(ChunkKind, u32, Vec<u8>, Vec<u32>)],
) -> Result<Vec<u8>> {
    let header = Header {
        wavelet: if split == 0 {
            Wavelet::Butterfly.id()
        } else {
            Wavelet::Cubic.id()
        },
        flags: F_DIRECT | F_BASEMESH,
        split,
        layout: 0,
        levels: 0,
        bits: opts.bits as u8,
        base_bits: opts.coarse_bits as u8,
        level_weight: 0,
        top: [-1; 3],
        tangent_shift: 0,
        input_vertices: opts
            .input_vertices
            .unwrap_or(vertices.min(u32::MAX as usize) as u32),
        bbox: bb,
        steps: [grid.step; 3],
        grid_origin: grid.origin,
        grid_step: grid.step,
        base_vertices: base.num_vertices() as u32,
        base_faces: base.num_faces() as u32,
        base_corners: base.face_indices.len() as u32,
        num_trees: 0,
    };
    container::write(&header, chunks)
}

/// The RMS error over the vertices of the full decode of `N = bits` planes: the weighted
/// details `weighted` (of `transform`, which analysed `reference`; node `n` of level
/// `level[n]`, multiplied by `gains[level[n]]`, [`detail_scales`]) quantized with the steps
/// of eq. 4.8, reconstructed at mid-interval (eqs. 4.11-4.12) and unweighted as the decoder
/// does, the coarse positions `coarse` exact, then synthesised.
fn quantization_rms(
    transform: &Transform,
    (coarse, weighted, level, gains): (&[DVec3], &[DVec3], &[u8], &[DVec3]),
    reference: &[DVec3],
    bits: u32,
    components: ComponentMode,
) -> Result<f64> {
    let steps = quantize::steps(weighted, bits, components);
    let mut data = coarse.to_vec();
    data.par_extend(weighted.par_iter().zip(level).map(|(d, &l)| {
        let mut x = DVec3::ZERO;
        for c in 0..3 {
            let (q, neg) = quantize::quantize(d[c], steps[c]);
            if q != 0 {
                x[c] = quantize::reconstruct(q, 0, neg, steps[c]);
            }
        }
        x / gains[l as usize]
    }));
    transform.inverse(&mut data, &mut SynthesisScratch::default())?;
    // Fixed chunks summed in order: the result (and so the planes chosen) does not depend on
    // the threads' scheduling.
    let parts: Vec<f64> = data
        .par_chunks(8192)
        .zip(reference.par_chunks(8192))
        .map(|(a, b)| a.iter().zip(b).map(|(a, b)| a.distance_squared(*b)).sum())
        .collect();
    let sum: f64 = parts.into_iter().sum();
    Ok((sum / data.len().max(1) as f64).sqrt())
}

/// Largest [`EncodeOptions::tangent_shift`].
pub const MAX_TANGENT_SHIFT: u32 = 8;

/// Largest [`EncodeOptions::level_exponent`].
pub const MAX_LEVEL_EXPONENT: f64 = 8.0;

/// The header code (quarters) of a level exponent.
///
/// # Errors
/// [`Error::InvalidArgument`] unless `alpha` is a multiple of 1/4 in
/// `0..=`[`MAX_LEVEL_EXPONENT`].
fn level_weight_code(alpha: f64) -> Result<u8> {
    let q = alpha * 4.0;
    if !(0.0..=4.0 * MAX_LEVEL_EXPONENT).contains(&q) || q.fract() != 0.0 {
        return Err(Error::InvalidArgument(format!(
            "level exponent {alpha}: use a multiple of 0.25 between 0 and {MAX_LEVEL_EXPONENT}"
        )));
    }
    Ok(q as u8)
}

/// Per level `j`, the factors each component of its details is multiplied by before
/// quantization: `2^(−α·j)` (`α` = `code / 4`, [`EncodeOptions::level_exponent`]), and the
/// two tangential components of local frames `2^(−tangent_shift)` more
/// ([`EncodeOptions::tangent_shift`]; 0 for global frames).
fn detail_scales(code: u8, tangent_shift: u8, levels: usize) -> Vec<DVec3> {
    let alpha = f64::from(code) / 4.0;
    let t = (-f64::from(tangent_shift)).exp2();
    (0..levels.max(1))
        .map(|j| {
            let g = (-alpha * j as f64).exp2();
            DVec3::new(g, g * t, g * t)
        })
        .collect()
}

/// The fewest bit planes `N ≤ max_bits` whose full decode is within `tol` RMS of
/// `reference` ([`quantization_rms`], which falls as `N` grows; bisection), or `max_bits`.
fn planes_search(
    transform: &Transform,
    details: (&[DVec3], &[DVec3], &[u8], &[DVec3]),
    reference: &[DVec3],
    max_bits: u32,
    components: ComponentMode,
    tol: f64,
) -> Result<u32> {
    if !(tol > 0.0 && tol.is_finite()) {
        return Ok(max_bits);
    }
    let (mut lo, mut hi) = (1u32, max_bits);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if quantization_rms(transform, details, reference, mid, components)? <= tol {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    Ok(hi)
}

/// The lossless encoder ([`super::lossless`]): base chunk by the base-mesh coder's integer
/// API, then one chunk per level.
fn encode_lossless(
    h: &Hierarchy,
    opts: &EncodeOptions,
    bb: [DVec3; 2],
    num_trees: usize,
) -> Result<(Vec<u8>, Hierarchy)> {
    if opts.wavelet == Wavelet::Loop {
        return Err(Error::InvalidArgument(
            "lossless mode needs an integer wavelet: midpoint or butterfly (triangles), linear, cubic or quintic (quads); Loop has no finite integer lifting".into(),
        ));
    }
    let mut coarse = h.base.clone();
    coarse.edge_tags.clear();
    coarse.vertex_tags.clear();
    let plain = basemesh::encode_with_info(&coarse, &BaseMeshOptions::default())?;
    let mut new_base = plain.decoded.clone();
    new_base.edge_tags.clear();
    new_base.vertex_tags.clear();
    let nh = reindex(h, &new_base, &plain.vertex_map)?;
    let grid = Grid::new(bb[0], bb[1], opts.bits);
    let e = lossless::encode(nh, &coarse, &plain.vertex_map, &grid, opts.wavelet.degree())?;
    let h = e.hierarchy;
    let mut chunks = vec![(ChunkKind::Base, 0u32, e.base, Vec::new())];
    for (j, c) in e.levels.into_iter().enumerate() {
        chunks.push((ChunkKind::Level, j as u32, c, Vec::new()));
    }
    let mut flags = F_LOSSLESS | F_BASEMESH | F_CONTEXTS;
    if e.reference {
        flags |= F_REFERENCE;
    }
    let header = Header {
        wavelet: opts.wavelet.id(),
        flags,
        split: if h.split == Split::Triangles { 0 } else { 1 },
        layout: 0,
        levels: h.levels() as u8,
        bits: opts.bits as u8,
        base_bits: opts.base_bits as u8,
        level_weight: 0,
        top: e.top.map(|t| t as i8),
        tangent_shift: 0,
        input_vertices: opts
            .input_vertices
            .unwrap_or(h.positions.len().min(u32::MAX as usize) as u32),
        bbox: bb,
        steps: [1.0; 3],
        grid_origin: grid.origin,
        grid_step: grid.step,
        base_vertices: h.num_vertices(0) as u32,
        base_faces: h.base.num_faces() as u32,
        base_corners: h.base.face_indices.len() as u32,
        num_trees: num_trees as u32,
    };
    Ok((container::write(&header, &chunks)?, h))
}

/// Hierarchy `h` re-indexed onto `base`, the same base mesh renumbered (new vertex `i` is
/// old vertex `vertex_map[i]`; faces reordered, possibly cyclically rotated): the finest
/// positions moved to the new contract order, matching odd vertices by their parent edge
/// (and, for polygon splits, face points by their parent face) level by level.
fn reindex(h: &Hierarchy, base: &Mesh, vertex_map: &[u32]) -> Result<Hierarchy> {
    let mut nh = Hierarchy::new(base, h.levels() as u32, h.split, None)?;
    let bad = || Error::InvalidArgument("re-indexing: the base meshes differ".into());
    if vertex_map.len() != h.num_vertices(0) || nh.num_vertices(h.levels()) != h.positions.len() {
        return Err(bad());
    }
    let mut map: Vec<u32> = vertex_map.to_vec();
    for j in 0..h.levels() {
        let (tn, to) = (nh.topology(j), h.topology(j));
        let (nv, onv) = (tn.num_vertices as usize, to.num_vertices as usize);
        let (ne, one) = (tn.num_edges(), to.num_edges());
        let mut next = map.clone();
        next.resize(nh.num_vertices(j + 1), u32::MAX);
        for e in 0..ne {
            let [a, b] = tn.edge_vertices[e];
            let oe = to
                .find_edge(map[a as usize], map[b as usize])
                .ok_or_else(bad)?;
            next[nv + e] = (onv + oe as usize) as u32;
        }
        if h.split == Split::Polygons {
            for f in 0..tn.num_faces() {
                let fv = tn.face_vertices(f);
                let (a, b) = (map[fv[0] as usize], map[fv[1] as usize]);
                let g = to
                    .vertex_faces(a as usize)
                    .iter()
                    .copied()
                    .find(|&g| {
                        let ov = to.face_vertices(g as usize);
                        ov.len() == fv.len()
                            && ov.contains(&b)
                            && fv.iter().all(|&x| ov.contains(&map[x as usize]))
                    })
                    .ok_or_else(bad)?;
                next[nv + ne + f] = (onv + one + g as usize) as u32;
            }
        }
        if next.contains(&u32::MAX) {
            return Err(bad());
        }
        map = next;
    }
    nh.positions = map.iter().map(|&o| h.positions[o as usize]).collect();
    Ok(nh)
}

/// Codes the base faces and integer positions (the base-mesh chunk; see the module
/// documentation).
pub fn encode_base(base: &Mesh, q: &[[i64; 3]]) -> Vec<u8> {
    let mut enc = Encoder::new();
    let mut arity: UInt = UInt::new();
    let mut new_ctx = Bit::new();
    let mut index: UInt = UInt::new();
    let polygons = !base.is_triangle_mesh();
    let mut next = 0u32;
    for f in base.faces() {
        if polygons {
            arity.encode(&mut enc, f.len() as u32 - 3);
        }
        for &v in f {
            let is_new = v == next;
            enc.bit(&mut new_ctx, is_new);
            if is_new {
                next += 1;
            } else {
                index.encode(&mut enc, v);
            }
        }
    }
    let mut coord: [SInt; 3] = [SInt::new(), SInt::new(), SInt::new()];
    let mut prev = [0i64; 3];
    for p in q {
        for c in 0..3 {
            coord[c].encode(&mut enc, p[c] - prev[c]);
        }
        prev = *p;
    }
    enc.finish()
}

/// Decodes a base-mesh chunk of `nv` vertices, `nf` faces and `corners` corners (from the
/// header, validated by the caller): the faces (as a mesh with zero positions) and the
/// integer positions.
///
/// # Errors
/// [`Error::Decode`] (at `offset`) if the chunk is too short, a face has fewer than 3 or
/// more corners than declared, or an index is out of range.
pub fn decode_base(
    bytes: &[u8],
    nv: usize,
    nf: usize,
    corners: usize,
    triangles: bool,
    offset: usize,
) -> Result<(Mesh, Vec<[i64; 3]>)> {
    let err = |m: String| Error::Decode {
        offset,
        message: format!("base mesh chunk: {m}"),
    };
    let mut dec = Decoder::new(bytes);
    let mut arity: UInt = UInt::new();
    let mut new_ctx = Bit::new();
    let mut index: UInt = UInt::new();
    let mut mesh = Mesh::new();
    mesh.face_offsets = Vec::with_capacity(nf + 1);
    mesh.face_offsets.push(0);
    mesh.face_indices = Vec::with_capacity(corners);
    let mut next = 0u32;
    for f in 0..nf {
        let n = if triangles {
            3
        } else {
            arity.decode(&mut dec) as usize + 3
        };
        if mesh.face_indices.len() + n > corners {
            return Err(err(format!(
                "face {f} exceeds the declared {corners} corners"
            )));
        }
        for _ in 0..n {
            let v = if dec.bit(&mut new_ctx) {
                next += 1;
                next - 1
            } else {
                index.decode(&mut dec)
            };
            if v as usize >= nv {
                return Err(err(format!(
                    "face {f} references vertex {v}, the base has {nv}"
                )));
            }
            mesh.face_indices.push(v);
        }
        mesh.face_offsets.push(mesh.face_indices.len() as u32);
        if dec.truncated() {
            return Err(err("truncated (corrupt)".into()));
        }
    }
    if mesh.face_indices.len() != corners {
        return Err(err(format!(
            "{} corners decoded, {corners} declared",
            mesh.face_indices.len()
        )));
    }
    let mut coord: [SInt; 3] = [SInt::new(), SInt::new(), SInt::new()];
    let mut q = Vec::with_capacity(nv);
    let mut prev = [0i64; 3];
    for _ in 0..nv {
        for c in 0..3 {
            prev[c] = prev[c].saturating_add(coord[c].decode(&mut dec));
        }
        q.push(prev);
    }
    if dec.truncated() {
        return Err(err("truncated (corrupt)".into()));
    }
    mesh.positions = vec![DVec3::ZERO; nv];
    Ok((mesh, q))
}

/// A parsed and validated stream, ready to decode coefficients.
struct Parsed {
    c: Container,
    wavelet: Wavelet,
    split: Split,
    layout: Layout,
    flags: u8,
    top: [i32; 3],
}

fn derr(offset: usize, message: impl Into<String>) -> Error {
    Error::Decode {
        offset,
        message: message.into(),
    }
}

fn parse(bytes: &[u8]) -> Result<Parsed> {
    parse_within(bytes, bytes.len())
}

/// [`parse`] of a prefix `bytes` of a stream of which the caller holds `available` bytes:
/// declared sizes are bounded in proportion to `available` (a prefix of an in-memory stream
/// may decode to a mesh far larger than the prefix itself).
fn parse_within(bytes: &[u8], available: usize) -> Result<Parsed> {
    let c = container::read(bytes)?;
    let h = &c.header;
    let wavelet = Wavelet::from_id(h.wavelet)
        .ok_or_else(|| derr(10, format!("unknown wavelet {}", h.wavelet)))?;
    let split = match h.split {
        0 => Split::Triangles,
        1 => Split::Polygons,
        s => return Err(derr(12, format!("unknown split {s}"))),
    };
    if wavelet.is_quad() != (split == Split::Polygons) {
        return Err(derr(10, "wavelet and split do not match"));
    }
    let layout = match h.layout {
        0 => Layout::Embedded,
        1 => Layout::Trees,
        x => return Err(derr(13, format!("unknown layout {x}"))),
    };
    if h.levels as u32 > MAX_LEVELS {
        return Err(derr(
            14,
            format!("{} levels (at most {MAX_LEVELS})", h.levels),
        ));
    }
    // Every flag bit has a meaning (version 10); a direct stream has no other flag than the
    // base-mesh one, no levels and the embedded layout.
    if h.flags & F_DIRECT != 0
        && (h.flags != F_DIRECT | F_BASEMESH || h.layout != 0 || h.levels != 0)
    {
        return Err(derr(
            11,
            format!(
                "flags {:#x}: a direct stream has no other flag, no levels and the embedded layout",
                h.flags
            ),
        ));
    }
    if h.level_weight as f64 > 4.0 * MAX_LEVEL_EXPONENT
        || (h.flags & F_LOSSLESS != 0 && h.level_weight != 0)
    {
        return Err(derr(
            17,
            format!("level weight {} out of range", h.level_weight),
        ));
    }
    if h.tangent_shift as u32 > MAX_TANGENT_SHIFT
        || (h.tangent_shift != 0 && (h.flags & F_LOSSLESS != 0 || h.flags & F_LOCAL == 0))
    {
        return Err(derr(
            21,
            format!(
                "tangent shift {} out of range (at most {MAX_TANGENT_SHIFT}, and only with local frames)",
                h.tangent_shift
            ),
        ));
    }
    let top = h.top.map(i32::from);
    if top
        .iter()
        .any(|&t| !(-1..quantize::MAX_PLANES as i32).contains(&t))
    {
        return Err(derr(18, "top bit planes out of range"));
    }
    // Sizes against the stream size, before allocating anything.
    let budget = 1024u64 * available.max(bytes.len()) as u64 + (1 << 16);
    let fine_faces = (h.base_corners as u64).saturating_mul(4u64.saturating_pow(h.levels as u32));
    if h.base_vertices as u64 > budget || h.base_corners as u64 > budget || fine_faces > budget {
        return Err(derr(
            10,
            format!(
                "declared sizes ({} base vertices, {} corners, {} levels) are out of proportion to the {} stream bytes",
                h.base_vertices,
                h.base_corners,
                h.levels,
                available.max(bytes.len())
            ),
        ));
    }
    let tri = split == Split::Triangles;
    if (tri && h.base_corners as u64 != 3 * h.base_faces as u64)
        || (h.base_corners as u64) < 3 * h.base_faces as u64
    {
        return Err(derr(10, "base corners do not match the base faces"));
    }
    match c.chunks.first() {
        Some(e) if e.kind == ChunkKind::Base => {}
        _ => return Err(derr(c.header_len, "the first chunk is not the base mesh")),
    }
    Ok(Parsed {
        wavelet,
        split,
        layout,
        flags: h.flags,
        top,
        c,
    })
}

/// Summarises a stream (header, index, sizes) without decoding coefficients.
///
/// # Errors
/// As [`decode`] for the header and index.
pub fn inspect(bytes: &[u8]) -> Result<StreamInfo> {
    let p = parse(bytes)?;
    let h = &p.c.header;
    Ok(StreamInfo {
        version: container::VERSION,
        wavelet: p.wavelet,
        lifted: p.flags & F_LIFTED != 0,
        frames: if p.flags & F_LOCAL != 0 {
            DetailFrame::Local
        } else {
            DetailFrame::Global
        },
        components: if p.flags & F_ALIGNED != 0 {
            ComponentMode::Aligned
        } else {
            ComponentMode::Independent
        },
        contexts: p.flags & F_CONTEXTS != 0,
        lossless: p.flags & F_LOSSLESS != 0,
        direct: p.flags & F_DIRECT != 0,
        layout: p.layout,
        levels: h.levels as u32,
        bits: h.bits as u32,
        base_vertices: h.base_vertices,
        base_faces: h.base_faces,
        trees: h.num_trees,
        planes: if p.flags & F_DIRECT != 0 {
            (h.bits as u32).saturating_sub(h.base_bits as u32)
        } else {
            spiht::num_planes(p.top)
        },
        header_bytes: p.c.header_len,
        base_bytes: p.c.chunks[0].len as usize,
        total_bytes: p.c.total_len(),
        input_vertices: h.input_vertices,
        vertices: fine_vertices(h, p.split),
        faces: fine_faces(h, p.split),
        bbox: h.bbox,
        chunks: p.c.chunks.clone(),
    })
}

/// Finest faces of a stream's hierarchy.
fn fine_faces(h: &Header, split: Split) -> u64 {
    let l = h.levels as u32;
    match split {
        Split::Polygons if l > 0 => h.base_corners as u64 * 4u64.pow(l - 1),
        _ => h.base_faces as u64 * 4u64.pow(l),
    }
}

/// Finest vertices of a stream's hierarchy, by Euler's formula per level (`V' = V + E + F`
/// for polygon splits, `V + E` for triangles), with `E` from the base's corners assuming a
/// closed manifold (`2E = corners`; an open mesh has a few more edges, so this is a lower
/// bound there).
fn fine_vertices(h: &Header, split: Split) -> u64 {
    let (mut v, mut e, mut f, mut c) = (
        h.base_vertices as u64,
        h.base_corners as u64 / 2,
        h.base_faces as u64,
        h.base_corners as u64,
    );
    for _ in 0..h.levels {
        match split {
            Split::Triangles => {
                let v2 = v + e;
                let e2 = 2 * e + 3 * f;
                (v, e, f, c) = (v2, e2, 4 * f, 12 * f);
            }
            _ => {
                let v2 = v + e + f;
                let e2 = 2 * e + c;
                (v, e, f, c) = (v2, e2, c, 4 * c);
            }
        }
    }
    let _ = c;
    v
}

/// The decoded base mesh, hierarchy and forest of a stream.
struct Setup {
    hierarchy: Hierarchy,
    forest: Forest,
    /// Integer base coefficients (lossless mode).
    base_q: Vec<[i64; 3]>,
    /// Base coefficients (lossy mode).
    base_positions: Vec<DVec3>,
}

fn setup(p: &Parsed, bytes: &[u8]) -> Result<Setup> {
    let (hierarchy, base_q, base_positions) = setup_base(p, bytes)?;
    let forest = setup_forest(p, &hierarchy)?;
    Ok(Setup {
        hierarchy,
        forest,
        base_q,
        base_positions,
    })
}

/// The base mesh and hierarchy of a stream (see [`Setup`]).
type Base = (Hierarchy, Vec<[i64; 3]>, Vec<DVec3>);

/// The base mesh of a stream (positions dequantized in lossy mode) and its integer
/// coefficients (lossless mode without the base-mesh coder).
fn setup_base_mesh(p: &Parsed, bytes: &[u8]) -> Result<(Mesh, Vec<[i64; 3]>)> {
    let h = &p.c.header;
    let data = p.c.base_chunk(bytes)?;
    let off = p.c.chunks[0].offset as usize;
    let (base, base_q) = if p.flags & F_BASEMESH != 0 {
        let m = basemesh::decode(data)
            .map_err(|e| derr(off, format!("{}: {e}", p.c.chunks[0].name(0))))?;
        p.c.check_base_counts(m.num_vertices(), m.num_faces(), m.face_indices.len())?;
        (m, Vec::new())
    } else {
        let (mut m, q) = decode_base(
            data,
            h.base_vertices as usize,
            h.base_faces as usize,
            h.base_corners as usize,
            p.split == Split::Triangles,
            off,
        )?;
        let grid = Grid {
            origin: h.grid_origin,
            step: h.grid_step,
        };
        if p.flags & F_LOSSLESS == 0 {
            m.positions = q.iter().map(|&q| grid.dequantize(q)).collect();
        }
        (m, q)
    };
    Ok((base, base_q))
}

/// The hierarchy, integer base coefficients and base positions of a stream ([`Setup`]
/// without the forest).
fn setup_base(p: &Parsed, bytes: &[u8]) -> Result<Base> {
    let (base, base_q) = setup_base_mesh(p, bytes)?;
    let base_positions = base.positions.clone();
    // Connectivity only: the decoder never reads the finest level's edge and vertex tables.
    let hierarchy = Hierarchy::skeleton(&base, p.c.header.levels as u32, p.split).map_err(|e| {
        derr(
            p.c.chunks[0].offset as usize,
            format!("base mesh chunk: {e}"),
        )
    })?;
    Ok((hierarchy, base_q, base_positions))
}

/// The offspring forest of a stream's hierarchy, checked against the header.
/// The stream's hierarchy over the decoded `base`, its coarse levels only (the finest faces
/// are only the output's).
fn setup_skeleton(p: &Parsed, base: &Mesh) -> Result<Hierarchy> {
    Hierarchy::skeleton_without_finest_faces(base, p.c.header.levels as u32, p.split).map_err(|e| {
        derr(
            p.c.chunks[0].offset as usize,
            format!("base mesh chunk: {e}"),
        )
    })
}

fn setup_forest(p: &Parsed, hierarchy: &Hierarchy) -> Result<Forest> {
    let h = &p.c.header;
    let forest = Forest::new(hierarchy)?;
    if forest.num_trees != h.num_trees as usize {
        return Err(derr(
            10,
            format!(
                "the header declares {} trees, the base mesh has {}",
                h.num_trees, forest.num_trees
            ),
        ));
    }
    if forest.num_nodes > spiht::MAX_NODES {
        return Err(derr(10, "too many coefficients"));
    }
    Ok(forest)
}

/// Decodes a `.swv` stream, or a prefix of it (`opts.max_bytes`), into the finest mesh with
/// the coefficients known so far (see the module documentation).
///
/// # Errors
/// [`Error::Decode`]: not a stream, unsupported version, a prefix shorter than the header,
/// index and base chunk, a chunk failing its checksum (named), declared sizes out of
/// proportion to the stream, a corrupt base mesh.
pub fn decode(bytes: &[u8], opts: &DecodeOptions) -> Result<Decoded> {
    decode_with(bytes, opts, &mut DecodeBuffers::default())
}

/// [`decode`] in the working memory `buffers` (same result, see [`DecodeBuffers`]).
///
/// # Errors
/// As [`decode`].
pub fn decode_with(
    bytes: &[u8],
    opts: &DecodeOptions,
    buffers: &mut DecodeBuffers,
) -> Result<Decoded> {
    // Run on a worker of the thread pool: the parallel steps inside then share work by
    // stealing instead of each being injected into the pool from outside (a wake-up and a
    // wait per step).
    rayon::scope(|_| decode_in_pool(bytes, opts, buffers))
}

fn decode_in_pool(
    bytes: &[u8],
    opts: &DecodeOptions,
    buffers: &mut DecodeBuffers,
) -> Result<Decoded> {
    let available = bytes.len();
    let limit = opts.max_bytes.map_or(available, |m| m.min(available));
    let bytes = &bytes[..limit];
    let p = parse_within(bytes, available)?;
    if p.flags & F_DIRECT != 0 {
        let params = super::direct::Params {
            bits: p.c.header.bits as u32,
            coarse_bits: p.c.header.base_bits as u32,
        };
        let d = super::direct::decode(&p.c, &params, bytes)?;
        return Ok(Decoded {
            mesh: d.mesh,
            bytes_used: d.bytes_used,
            planes_complete: d.planes_complete,
            planes: d.planes,
            complete: d.complete,
        });
    }
    if p.flags & F_LOSSLESS != 0 && p.flags & F_BASEMESH != 0 {
        let d = lossless::decode(
            &p.c,
            p.split,
            p.wavelet.degree(),
            p.flags & F_REFERENCE != 0,
            bytes,
        )?;
        return Ok(Decoded {
            mesh: d.mesh,
            bytes_used: d.bytes_used,
            planes_complete: d.levels_complete,
            planes: p.c.header.levels as u32,
            complete: d.complete,
        });
    }
    let (base, base_q) = setup_base_mesh(&p, bytes)?;
    let hierarchy = setup_skeleton(&p, &base)?;
    let base_positions = base.positions;
    // The forest and coefficients on one side (the longest chain); on the other the synthesis
    // tables, the finest faces and the positions' buffer (its pages touched here, off the
    // critical path): they are independent, so they are built in parallel.
    let num_vertices = hierarchy.num_vertices(hierarchy.levels());
    let (coded, (t, finest, (buffer, mut scratch))) = rayon::join(
        || -> Result<_> {
            let forest = setup_forest(&p, &hierarchy)?;
            let coded = decode_coefficients(&p, &forest, bytes, opts, buffers)?;
            Ok((forest, coded))
        },
        || {
            let t = transform(&p, &hierarchy);
            let finest = match hierarchy.topologies.len() {
                n if n >= 2 => child_faces(&hierarchy.topologies[n - 2], p.split),
                _ => (base.face_offsets, base.face_indices),
            };
            let buffer = if p.flags & F_LOSSLESS == 0 {
                let mut b = Vec::with_capacity(num_vertices);
                b.resize(num_vertices, DVec3::ZERO);
                b
            } else {
                Vec::new()
            };
            let scratch = match &t {
                Ok(AnyTransform::Float(t)) => t.scratch(),
                _ => SynthesisScratch::default(),
            };
            (t, finest, (buffer, scratch))
        },
    );
    let (forest, (coefs, used, planes_complete, planes, complete)) = coded?;
    let positions = reconstruct_with(
        &p,
        (&base_q, &base_positions),
        forest.num_nodes,
        &coefs,
        &t?,
        (buffer, &mut scratch),
        &forest.level,
    );
    buffers.coefficients = coefs;
    let positions = positions?;
    let (face_offsets, face_indices) = finest;
    let mesh = Mesh {
        positions,
        face_offsets,
        face_indices,
        ..Mesh::new()
    };
    Ok(Decoded {
        mesh,
        bytes_used: used.min(limit),
        planes_complete,
        planes,
        complete,
    })
}

/// A whole embedded stream's forest, final coefficients and `(plane, bytes)` per bit-plane
/// chunk ([`embedded_coefficients`]).
pub(crate) type EmbeddedCoefficients = (Forest, Coefficients, Vec<(u32, u64)>);

/// The coefficients of a whole embedded wavelet stream as its decoder ends with them (exact
/// magnitudes and signs), with its forest and each bit plane's chunk size in coding order
/// (`(plane, bytes)`): what [`super::entropy`] weighs the coder against.
///
/// # Errors
/// [`Error::Decode`] for a damaged or truncated stream, [`Error::InvalidArgument`] for a
/// lossless, direct or per-tree stream (their chunks are not the bit planes of one forest).
pub(crate) fn embedded_coefficients(bytes: &[u8]) -> Result<EmbeddedCoefficients> {
    let p = parse(bytes)?;
    let refused = if p.flags & F_DIRECT != 0 {
        Some("a direct stream (the input coded as it is) has no wavelet coefficients; encode with --direct never")
    } else if p.layout == Layout::Trees {
        Some("a per-tree (trees layout) stream codes each tree's bit planes apart; encode with --layout embedded")
    } else if p.flags & F_LOSSLESS != 0 {
        Some("a lossless stream codes integer details level by level, not in bit planes; encode without --lossless")
    } else {
        None
    };
    if let Some(why) = refused {
        return Err(Error::InvalidArgument(why.into()));
    }
    let (base, _) = setup_base_mesh(&p, bytes)?;
    let hierarchy = setup_skeleton(&p, &base)?;
    let forest = setup_forest(&p, &hierarchy)?;
    let mut buffers = DecodeBuffers::default();
    let (coefs, _, _, _, complete) =
        decode_coefficients(&p, &forest, bytes, &DecodeOptions::default(), &mut buffers)?;
    if !complete {
        return Err(derr(
            bytes.len(),
            "the stream ends before its last bit plane",
        ));
    }
    let planes =
        p.c.chunks
            .iter()
            .filter(|e| e.kind == ChunkKind::Plane)
            .map(|e| (e.id, e.len as u64))
            .collect();
    Ok((forest, coefs, planes))
}

/// Decodes the coefficient chunks: the coefficients, bytes used, complete planes, planes and
/// whether everything was decoded.
fn decode_coefficients(
    p: &Parsed,
    forest: &Forest,
    bytes: &[u8],
    opts: &DecodeOptions,
    buffers: &mut DecodeBuffers,
) -> Result<(Coefficients, usize, u32, u32, bool)> {
    let limit = bytes.len();
    let mut coefs = std::mem::take(&mut buffers.coefficients);
    coefs.reset(forest);
    let contexts = p.flags & F_CONTEXTS != 0;
    let planes = spiht::num_planes(p.top);
    let mut planes_complete = planes;
    let mut complete = true;
    let mut used = p.c.chunks[0].offset as usize + p.c.chunks[0].len as usize;
    match p.layout {
        Layout::Embedded => {
            let roots: Vec<u32> = (0..forest.num_trees as u32).collect();
            let memory = std::mem::take(&mut buffers.spiht);
            let mut d = SpihtDecoder::in_memory(forest, &roots, p.top, contexts, memory);
            let mut i = 1;
            while d.plane() >= 0 {
                let Some(e) = p.c.chunks.get(i) else {
                    return Err(derr(
                        p.c.header_len,
                        format!("plane {} has no chunk", d.plane()),
                    ));
                };
                if e.kind != ChunkKind::Plane || e.id as i32 != d.plane() {
                    return Err(derr(
                        p.c.header_len,
                        format!("{} is not bit plane {}", e.name(i), d.plane()),
                    ));
                }
                let (data, whole) = p.c.chunk(bytes, i)?;
                used = e.offset as usize + data.len();
                let mut dec = Decoder::new(data);
                if !d.decode_plane(&mut dec, &mut coefs) || !whole {
                    break;
                }
                i += 1;
            }
            if d.plane() >= 0 {
                planes_complete = (planes as i32 - 1 - d.plane()).max(0) as u32;
                complete = false;
            }
            buffers.spiht = d.into_memory();
        }
        Layout::Trees => {
            let wanted = opts.trees.as_ref().map(|t| {
                let mut w = vec![false; forest.num_trees];
                for &x in t {
                    if let Some(b) = w.get_mut(x as usize) {
                        *b = true;
                    }
                }
                w
            });
            let mut seen = vec![false; forest.num_trees];
            for (i, e) in p.c.chunks.iter().enumerate().skip(1) {
                if e.kind != ChunkKind::Tree || e.id as usize >= forest.num_trees {
                    return Err(derr(
                        p.c.header_len,
                        format!("{} is not a tree chunk of this forest", e.name(i)),
                    ));
                }
                let t = e.id as usize;
                if std::mem::replace(&mut seen[t], true) {
                    return Err(derr(
                        p.c.header_len,
                        format!("{}: tree {t} appears twice", e.name(i)),
                    ));
                }
                if wanted.as_ref().is_some_and(|w| !w[t]) {
                    complete = false;
                    continue;
                }
                let (data, _) = p.c.chunk(bytes, i)?;
                if data.is_empty() {
                    complete = false;
                    planes_complete = 0;
                    continue;
                }
                used = used.max(e.offset as usize + data.len());
                let mut d = SpihtDecoder::new(forest, &[t as u32], p.top, contexts);
                let mut dec = Decoder::new(data);
                while d.decode_plane(&mut dec, &mut coefs) {}
                if d.plane() >= 0 {
                    complete = false;
                    planes_complete =
                        planes_complete.min((planes as i32 - 1 - d.plane()).max(0) as u32);
                }
            }
            if seen.iter().any(|&x| !x) {
                complete = false;
            }
        }
    }
    Ok((coefs, used.min(limit), planes_complete, planes, complete))
}

/// The inverse transform of a stream, float or integer.
enum AnyTransform<'h> {
    Float(Transform<'h>),
    Int(IntTransform<'h>),
}

fn transform<'h>(p: &Parsed, hier: &'h Hierarchy) -> Result<AnyTransform<'h>> {
    let lifted = p.flags & F_LIFTED != 0;
    if p.flags & F_LOSSLESS != 0 {
        Ok(AnyTransform::Int(IntTransform::new(
            hier, p.wavelet, lifted,
        )?))
    } else {
        let frame = if p.flags & F_LOCAL != 0 {
            DetailFrame::Local
        } else {
            DetailFrame::Global
        };
        Ok(AnyTransform::Float(Transform::new(
            hier, p.wavelet, lifted, frame,
        )?))
    }
}

fn reconstruct(p: &Parsed, s: &Setup, coefs: &Coefficients) -> Result<Mesh> {
    let positions = reconstruct_with(
        p,
        (&s.base_q, &s.base_positions),
        s.forest.num_nodes,
        coefs,
        &transform(p, &s.hierarchy)?,
        (Vec::new(), &mut SynthesisScratch::default()),
        &s.forest.level,
    )?;
    let hier = &s.hierarchy;
    Ok(hier.level_mesh(hier.levels(), positions))
}

/// The finest positions from the coefficients of the `num_nodes` forest nodes, the base
/// (integer base coefficients in lossless mode, base positions otherwise; [`Setup`]) and
/// the inverse transform. `buffer` is the memory of the result (any contents; its capacity
/// is used if it suffices), `scratch` the synthesis' scratch memory.
fn reconstruct_with(
    p: &Parsed,
    (base_q, base_positions): (&[[i64; 3]], &[DVec3]),
    num_nodes: usize,
    coefs: &Coefficients,
    t: &AnyTransform,
    (buffer, scratch): (Vec<DVec3>, &mut SynthesisScratch),
    level: &[u8],
) -> Result<Vec<DVec3>> {
    let h = &p.c.header;
    let v0 = base_positions.len().max(base_q.len());
    let grid = Grid {
        origin: h.grid_origin,
        step: h.grid_step,
    };
    let positions = match t {
        AnyTransform::Int(t) => {
            let mut data = base_q.to_vec();
            data.reserve(num_nodes);
            for n in 0..num_nodes {
                let mut d = [0i64; 3];
                for (c, x) in d.iter_mut().enumerate() {
                    let e = 3 * n + c;
                    let w = coefs.width[e];
                    if w != INSIGNIFICANT {
                        let m = coefs.lo[e] as i64 + ((1i64 << w) >> 1);
                        *x = if coefs.neg[e] { -m } else { m };
                    }
                }
                data.push(d);
            }
            t.inverse(&mut data)
                .map_err(|e| derr(0, format!("integer synthesis: {e}")))?;
            data.iter().map(|&q| grid.dequantize(q)).collect()
        }
        AnyTransform::Float(t) => {
            let mut flat = buffer;
            flat.clear();
            flat.reserve(v0 + num_nodes);
            flat.extend_from_slice(base_positions);
            let gains = detail_scales(h.level_weight, h.tangent_shift, h.levels as usize);
            flat.par_extend((0..num_nodes).into_par_iter().with_min_len(8192).map(|n| {
                let mut d = DVec3::ZERO;
                for c in 0..3 {
                    let e = 3 * n + c;
                    let w = coefs.width[e];
                    if w != INSIGNIFICANT {
                        d[c] =
                            quantize::reconstruct(coefs.lo[e], w as u32, coefs.neg[e], h.steps[c]);
                    }
                }
                d / gains[level[n] as usize]
            }));
            t.inverse(&mut flat, scratch)?;
            flat
        }
    };
    Ok(positions)
}

/// A view-dependent decoder of a trees-layout stream (Maret §4.5.1, §5.1.2): trees are added
/// (decoded from their chunk bytes, which may be a prefix of the chunk) and removed (their
/// details reset to zero) at any time, and [`TreeDecoder::mesh`] reconstructs the current
/// mesh.
pub struct TreeDecoder {
    p: Parsed,
    s: Setup,
    coefs: Coefficients,
    tree_of: Vec<u32>,
    active: Vec<bool>,
}

impl TreeDecoder {
    /// Parses the header, index and base mesh of a trees-layout stream (`bytes` must hold at
    /// least those).
    ///
    /// # Errors
    /// As [`decode`]; [`Error::InvalidArgument`] for an embedded stream.
    pub fn new(bytes: &[u8]) -> Result<TreeDecoder> {
        let p = parse(bytes)?;
        if p.layout != Layout::Trees {
            return Err(Error::InvalidArgument(
                "a tree decoder needs a stream encoded with the trees layout".into(),
            ));
        }
        let s = setup(&p, bytes)?;
        let coefs = Coefficients::new(&s.forest);
        let tree_of = s.forest.tree_of();
        let active = vec![false; s.forest.num_trees];
        Ok(TreeDecoder {
            p,
            s,
            coefs,
            tree_of,
            active,
        })
    }

    /// Number of trees (base edges, and base faces for quads).
    pub fn num_trees(&self) -> usize {
        self.s.forest.num_trees
    }

    /// The byte range `[offset, offset + len)` of tree `t`'s chunk in the stream, and its
    /// per-plane prefix lengths (for range requests).
    pub fn tree_range(&self, t: u32) -> Option<(u64, u32, &[u32])> {
        self.p
            .c
            .chunks
            .iter()
            .find(|e| e.kind == ChunkKind::Tree && e.id == t)
            .map(|e| (e.offset, e.len, &e.marks[..]))
    }

    /// Decodes tree `t` from `chunk`, its chunk bytes (the whole chunk, checked against its
    /// CRC, or a prefix of it). Replaces what was decoded of the tree before.
    ///
    /// # Errors
    /// [`Error::Decode`] if `t` is not a tree of the stream or the whole chunk fails its CRC.
    pub fn add_tree(&mut self, t: u32, chunk: &[u8]) -> Result<()> {
        let Some((i, e)) = self
            .p
            .c
            .chunks
            .iter()
            .enumerate()
            .find(|(_, e)| e.kind == ChunkKind::Tree && e.id == t)
        else {
            return Err(derr(0, format!("tree {t} is not in the stream")));
        };
        if chunk.len() > e.len as usize
            || (chunk.len() == e.len as usize && !container::crc_matches(chunk, e.crc))
        {
            return Err(derr(
                e.offset as usize,
                format!("{} fails its checksum (corrupt data)", e.name(i)),
            ));
        }
        self.remove_tree(t);
        let contexts = self.p.flags & F_CONTEXTS != 0;
        let mut d = SpihtDecoder::new(&self.s.forest, &[t], self.p.top, contexts);
        let mut dec = Decoder::new(chunk);
        while d.decode_plane(&mut dec, &mut self.coefs) {}
        self.active[t as usize] = true;
        Ok(())
    }

    /// Removes tree `t` (its details become zero). No effect for an unknown tree.
    pub fn remove_tree(&mut self, t: u32) {
        if !self.active.get(t as usize).copied().unwrap_or(false) {
            return;
        }
        let tree_of = &self.tree_of;
        self.coefs
            .clear_nodes((0..tree_of.len()).filter(|&n| tree_of[n] == t));
        self.active[t as usize] = false;
    }

    /// The trees currently decoded.
    pub fn active_trees(&self) -> Vec<u32> {
        (0..self.active.len() as u32)
            .filter(|&t| self.active[t as usize])
            .collect()
    }

    /// The mesh with the trees decoded so far.
    ///
    /// # Errors
    /// As the wavelet synthesis.
    pub fn mesh(&self) -> Result<Mesh> {
        reconstruct(&self.p, &self.s, &self.coefs)
    }
}
