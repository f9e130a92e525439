//! Coding: entropy coding, the base-mesh coder, the SPIHT coder of wavelet details and the
//! progressive stream container.
//!
//! - [`rangecoder`]: the adaptive binary range coder every bitstream of subwave uses, with
//!   exact prefix semantics (a truncated stream decodes exactly the symbols it fully
//!   determines);
//! - [`basemesh`]: the single-rate coder of base meshes and irregular meshes (valence-driven
//!   connectivity with Face Fixer polygons, parallelogram-predicted positions, run-length
//!   crease flags);
//! - [`direct`]: direct streams, an irregular mesh coded as it is (the base-mesh coder at a
//!   coarse precision, then refinement planes) where a remesh does not pay;
//! - [`eval`]: rate–distortion curves of progressive streams against the input mesh;
//! - [`entropy`]: the bytes SPIHT spends per bit plane against the empirical entropy of the
//!   coefficients it codes (`subwave bench entropy`);
//! - [`forest`]: the edge-offspring forest (MPEG-4 AFX) and the quad vertex/face forest;
//! - [`quantize`]: coefficient and position quantization (Maret eqs. 4.7-4.12);
//! - [`spiht`]: the SPIHT coder of the detail coefficients (Maret Algorithm 1);
//! - [`container`]: the `.swv` stream format (header, chunk index, checksums);
//! - [`prepare`]: any input mesh to the hierarchy the codec takes (detection or remeshing);
//! - [`progressive`]: the encode/decode API of progressive and lossless streams;
//! - [`normal_line`]: the lossless coder's normal lines, and a normal remesh snapped onto
//!   them (one integer per vertex);
//! - [`lossless`]: the lossless mode's level-by-level context-modelled coding of integer
//!   wavelet details.

pub mod basemesh;
pub mod container;
pub mod direct;
pub mod entropy;
pub mod eval;
pub mod forest;
pub mod lossless;
pub mod normal_line;
pub mod prepare;
pub mod progressive;
pub mod quantize;
pub mod rangecoder;
pub mod spiht;
