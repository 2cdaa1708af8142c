//! Measuring (feature `lab`): speed against accuracy for every method ([`bench`]), where
//! methods fail ([`stability`]), and the training of tables shipped in `kernels/`
//! ([`train`]). None of it is on the road from a file to a printer.
// Not in the Python or WebAssembly builds: the standard library's transcendental functions
// are allowed here (clippy.toml; the rest of the library calls `crate::fmath`).
#![allow(clippy::disallowed_methods)]

pub mod bench;
pub mod motion_bench;
pub mod panel_stability;
pub mod stability;
pub mod train;
