//! Coding: entropy coding, the base-mesh coder, the SPIHT coder of wavelet details and the
//! progressive stream container.
//!
//! - [`rangecoder`]: the adaptive binary range coder every bitstream of subwave uses, with
//!   exact prefix semantics (a truncated stream decodes exactly the symbols it fully
//!   determines).

pub mod forest;
pub mod quantize;
pub mod rangecoder;
pub mod spiht;
