//! Coding: entropy coding, the base-mesh coder, the SPIHT coder of wavelet details and the
//! progressive stream container.
//!
//! - [`rangecoder`]: the adaptive binary range coder every bitstream of subwave uses, with
//!   exact prefix semantics (a truncated stream decodes exactly the symbols it fully
//!   determines).
//! - [`basemesh`]: the single-rate coder of base meshes and irregular meshes (valence-driven
//!   connectivity with Face Fixer polygons, parallelogram-predicted positions, run-length
//!   crease flags).

pub mod basemesh;
pub mod rangecoder;
