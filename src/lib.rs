//! poa: a slicer post-processor that prints overhangs on air.
//!
//! The library is a pipeline of stages, each its own module, dependencies pointing one way:
//! [`gcode`] (lossless syntax) -> [`machine`] (modal state, absolute moves) -> [`layers`]
//! (dialects, layer model) -> [`geometry`] (printed areas, regions over air) -> [`report`] and
//! [`preview`] (what a user reads and sees). The binary `poa` only parses
//! arguments, does file I/O and maps errors to exit codes.

pub mod ab;
pub mod bgcode;
pub mod check;
pub mod config;
pub mod emit;
pub mod error;
pub mod estimate;
pub mod gcode;
pub mod geometry;
pub mod input;
pub mod layers;
pub mod machine;
pub mod movemap;
pub mod output;
pub mod pass;
pub mod poa;
pub mod preview;
pub mod progress;
pub mod report;
pub mod rewrite;
pub mod settings;
pub mod writer;

pub use error::Error;
