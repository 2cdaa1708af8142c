//! The print-server door (feature `serve`): IPP Everywhere print queues that halftone what
//! they receive with the library and send it to a printer in its own language.
//!
//! - [`config`]: queues from a TOML file (`[queue.NAME]` tables) or one set of flags; every
//!   queue's options go through [`Settings`](crate::options::Settings), as every door's do.
//! - [`printer`]: IPP/2.0 requests in, responses out ([`Printer::handle`]); jobs kept and
//!   processed ([`Printer::wait_for_job`], [`Printer::process`]).
//! - [`attributes`]: what a queue reports (RFC 8011, PWG 5100.14), and job attributes
//!   mapped to option names (`print-quality`, `print-color-mode`, `halftone-*`).
//! - [`backend`]: a folder, a device file, an AppSocket printer or another IPP printer.
//! - [`client`]: the IPP client (`halftone print`, the `ipp://` backend).
//! - [`dnssd`]: each queue advertised over DNS-SD as an IPP Everywhere printer.
//! - [`spool`]: every acknowledged job on disk until it ends, taken back after a restart.
//!
//! The HTTP server, its threads and signals are the binary's (`halftone serve`).

pub mod attributes;
pub mod backend;
pub mod client;
pub mod config;
pub mod dnssd;
pub mod document;
pub mod printer;
pub mod spool;
pub mod wire;

pub use config::{Backend, Config, Queue};
pub use printer::{JobState, Limits, Printer, Response};
