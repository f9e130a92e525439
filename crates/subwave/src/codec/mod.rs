//! Coding: entropy coding, the base-mesh coder, the SPIHT coder of wavelet details and the
//! progressive stream container.
//!
//! - [`rangecoder`]: the adaptive binary range coder every bitstream of subwave uses, with
//!   exact prefix semantics (a truncated stream decodes exactly the symbols it fully
//!   determines);
//! - [`eval`]: rate–distortion curves of progressive streams against the input mesh.

pub mod eval;
pub mod rangecoder;
