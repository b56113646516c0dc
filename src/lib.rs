//! poa: a slicer post-processor that prints overhangs on air.
//!
//! The library is a pipeline of stages, each its own module, dependencies pointing one way:
//! [`input`] (open, refuse what is not G-code, binary G-code via [`bgcode`]) -> [`gcode`]
//! (lossless syntax) -> [`machine`] (modal state -> moves) -> [`layers`] (dialects, layer
//! model; [`config`] the slicer's settings) -> [`geometry`] (the only module that touches
//! Clipper: printed areas, regions over air) -> passes behind [`pass::Pass`] ([`emit`]'s
//! Print-on-Air with the [`poa`] loop planner, [`ab`]'s A/B copy) and whole-stream
//! [`movemap`]s -> one G-code [`writer`] (typed speeds, the kinematics seam) -> finish
//! ([`progress`] M73, footer, [`output`]'s atomic writes); [`rewrite`] runs it for a file.
//! [`helix`] is the layer-less path: a vase-mode helix found, deformed by a move map
//! (expressions through [`expr`]), checked in 3D and finished like a rewrite. [`texture`] is
//! a move map too (speed modulation at constant extrusion, timed by [`estimate`]);
//! [`fiveaxis`] slices swept parts and writes joint G-code for table-tilting printers.
//! [`estimate`], [`check`], [`report`] and [`preview`] read the same stages for what a user
//! reads and sees; [`settings`] is the one table of poa's own settings. The binary `poa`
//! only parses arguments, calls [`rewrite`] and the reports, prints and maps errors to exit
//! codes.

pub mod ab;
pub mod assemble;
pub mod bgcode;
pub mod check;
pub mod config;
pub mod emit;
pub mod error;
pub mod estimate;
pub mod expr;
pub mod fiveaxis;
pub mod gcode;
pub mod geometry;
pub mod helix;
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
pub mod texture;
pub mod writer;

pub use error::Error;
