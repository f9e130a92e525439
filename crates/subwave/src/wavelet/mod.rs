//! Wavelet transforms on semi-regular meshes ([`crate::hierarchy::Hierarchy`]).
//!
//! Maret 2003 §4.2.3 (subdivision surfaces and wavelets, computation of details
//! coefficients) and §4.4.3 (details in local frames); the MPEG-4 AFX wavelet subdivision
//! surface node offers Loop, butterfly and midpoint wavelets, lifted or not, with details in
//! global or local coordinates (§4.5).
//! - [`triangle`]: triangle hierarchies (midpoint lifted or not, any interpolating scheme's
//!   prediction, Loop as in Khodakovsky–Schröder–Sweldens PGC);
//! - [`frames`]: the local frames of detail vectors.

pub mod frames;
pub mod triangle;
